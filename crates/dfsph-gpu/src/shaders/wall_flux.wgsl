// The walls' share of each fluid particle's density rate at the walls' velocities,
// f_i = w Σ_b Ψ_b v_b·∇W_ib (`PairCache::wall_flux` of the CPU solver).
@group(0) @binding(1) var<storage, read> fluid: array<vec2<f32>>;
@group(0) @binding(2) var<storage, read> walls: array<vec2<f32>>;
@group(0) @binding(3) var<storage, read> wall_volume: array<f32>;
@group(0) @binding(4) var<storage, read> wall_velocity: array<vec2<f32>>;
@group(0) @binding(5) var<storage, read> wall_sorted: array<u32>;
@group(0) @binding(6) var<storage, read> wall_starts: array<u32>;
@group(0) @binding(7) var<storage, read_write> flux: array<f32>;

@compute @workgroup_size(64)
fn wall_flux(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if i >= params.n {
        return;
    }
    let x = fluid[i];
    let home = cell_of(x);
    let h2 = params.h * params.h;
    var sum = 0.0;
    for (var k = 0u; k < 9u; k++) {
        let c = neighbour_cell(home, k);
        if c < 0 {
            continue;
        }
        let cell = u32(c);
        for (var s = wall_starts[cell]; s < wall_starts[cell + 1u]; s++) {
            let b = wall_sorted[s];
            let d = x - walls[b];
            let r2 = dot(d, d);
            if r2 < h2 {
                sum += wall_volume[b] * dot(wall_velocity[b], grad_w(d, sqrt(r2)));
            }
        }
    }
    flux[i] = params.wall_weight * sum;
}
