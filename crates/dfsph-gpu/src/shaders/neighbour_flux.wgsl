// Per fluid particle, the walls' share of its density rate at the walls' velocities,
// f_i = w Σ_b Ψ_b v_b·∇W_ib (`PairCache::wall_flux` of the CPU solver), and its neighbour
// count within the support, fluid (itself excluded) and walls: the divergence solve leaves
// out particles with too few (`SolverSettings::divergence_min_neighbors`).
@group(0) @binding(1) var<storage, read> fluid: array<vec2<f32>>;
@group(0) @binding(2) var<storage, read> fluid_sorted: array<u32>;
@group(0) @binding(3) var<storage, read> fluid_starts: array<u32>;
@group(0) @binding(4) var<storage, read> walls: array<vec2<f32>>;
// (Ψ_b, v_b, 0) per wall particle.
@group(0) @binding(5) var<storage, read> wall_data: array<vec4<f32>>;
@group(0) @binding(6) var<storage, read> wall_sorted: array<u32>;
@group(0) @binding(7) var<storage, read> wall_starts: array<u32>;
// (f_i, neighbour count).
@group(0) @binding(8) var<storage, read_write> out: array<vec2<f32>>;

@compute @workgroup_size(64)
fn neighbour_flux(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if i >= params.n {
        return;
    }
    let x = fluid[i];
    let home = cell_of(x);
    let h2 = params.h * params.h;
    var sum = 0.0;
    var count = 0u;
    for (var k = 0u; k < 9u; k++) {
        let fluid_range = fluid_slots(home, k);
        for (var s = fluid_range.x; s < fluid_range.y; s++) {
            let j = fluid_sorted[s];
            let d = x - fluid[j];
            if dot(d, d) < h2 && j != i {
                count += 1u;
            }
        }
        let wall_range = wall_slots(home, k);
        for (var s = wall_range.x; s < wall_range.y; s++) {
            let b = wall_sorted[s];
            let d = x - walls[b];
            let r2 = dot(d, d);
            if r2 < h2 {
                count += 1u;
                let data = wall_data[b];
                sum += data.x * dot(data.yz, grad_w(d, sqrt(r2)));
            }
        }
    }
    out[i] = vec2<f32>(params.wall_weight * sum, f32(count));
}
