// The compression a step would carry beyond the density solve's linear prediction, second
// part: the walls (those within the support at the step's start, moved over Δt) added to
// `unseen_fluid.wgsl`'s sum, the excess min(s̃ − ŝ, s̃ − 1) of the advected density s̃ over
// the prediction ŝ, and the largest excess of each workgroup of 256 for `unseen_fold.wgsl`.
@group(0) @binding(1) var<uniform> clock: Control;
@group(0) @binding(2) var<storage, read> fluid: array<vec2<f32>>;
@group(0) @binding(3) var<storage, read> velocity: array<vec2<f32>>;
@group(0) @binding(4) var<storage, read> walls: array<vec2<f32>>;
// (Ψ_b, v_b, 0) per wall particle.
@group(0) @binding(5) var<storage, read> wall_data: array<vec4<f32>>;
@group(0) @binding(6) var<storage, read> wall_sorted: array<u32>;
@group(0) @binding(7) var<storage, read> wall_starts: array<u32>;
@group(0) @binding(8) var<storage, read> advected: array<vec2<f32>>;
@group(0) @binding(9) var<storage, read_write> partials: array<vec2<f32>>;

@compute @workgroup_size(256)
fn unseen_walls(
    @builtin(global_invocation_id) id: vec3<u32>,
    @builtin(local_invocation_id) lid: vec3<u32>,
    @builtin(workgroup_id) wid: vec3<u32>,
) {
    let i = id.x;
    let t = lid.x;
    var unseen = 0.0;
    if i < params.n {
        let dt = clock.dt;
        let x = fluid[i];
        let moved = x + dt * velocity[i];
        let home = cell_of(x);
        let h2 = params.h * params.h;
        var sum = advected[i].x;
        for (var k = 0u; k < 9u; k++) {
            let wall_range = wall_slots(home, k);
            for (var s = wall_range.x; s < wall_range.y; s++) {
                let b = wall_sorted[s];
                let d = x - walls[b];
                let moved_wall = walls[b] + dt * wall_data[b].yz;
                let r2 = dot(d, d);
                if r2 < h2 {
                    let r = length(moved - moved_wall);
                    if r < params.h {
                        sum += wall_data[b].x * w(r);
                    }
                }
            }
        }
        unseen = max(min(sum - advected[i].y, sum - 1.0), 0.0);
    }
    let m = workgroup_max(t, unseen);
    if t == 0u {
        partials[wid.x] = vec2<f32>(m, 0.0);
    }
}
