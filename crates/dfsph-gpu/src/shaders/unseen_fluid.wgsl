// The compression a step would carry beyond the density solve's linear prediction, first
// part (`dfsph::solver::unseen_compression`), per fluid particle at the velocities the
// solve left: the kernel sum over its fluid neighbours (those within the support at the
// step's start) at the positions x + Δt·v the step moves them to, itself included, and the
// solve's prediction ρ_i/ρ0 + Δt·(v_i·g_i − V Σ_j v_j·∇W_ij − f_i), the sum
// `rate_sum.wgsl`'s. `unseen_walls.wgsl`
// adds the walls and takes the largest excess.
@group(0) @binding(1) var<uniform> clock: Control;
@group(0) @binding(2) var<storage, read> fluid: array<vec2<f32>>;
@group(0) @binding(3) var<storage, read> fluid_sorted: array<u32>;
@group(0) @binding(4) var<storage, read> fluid_starts: array<u32>;
@group(0) @binding(5) var<storage, read> velocity: array<vec2<f32>>;
@group(0) @binding(6) var<storage, read> densities: array<vec4<f32>>;
@group(0) @binding(7) var<storage, read> flux: array<vec2<f32>>;
// (the fluid's advected kernel sum, the prediction).
@group(0) @binding(8) var<storage, read_write> advected: array<vec2<f32>>;

@compute @workgroup_size(64)
fn unseen_fluid(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if i >= params.n {
        return;
    }
    let dt = clock.dt;
    let x = fluid[i];
    let v = velocity[i];
    let moved = x + dt * v;
    let home = cell_of(x);
    let h2 = params.h * params.h;
    var sum = w(0.0);
    for (var k = 0u; k < 9u; k++) {
        let fluid_range = fluid_slots(home, k);
        for (var s = fluid_range.x; s < fluid_range.y; s++) {
            let j = fluid_sorted[s];
            let d = x - fluid[j];
            let r2 = dot(d, d);
            if r2 < h2 && j != i {
                sum += w(length(moved - (fluid[j] + dt * velocity[j])));
            }
        }
    }
    let dens = densities[i];
    let rate = dot(v, dens.zw) - params.volume * velocity_sum(i, x) - flux[i].x;
    advected[i] = vec2<f32>(params.volume * sum, dens.x + dt * rate);
}
