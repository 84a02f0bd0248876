// Each fluid particle's relative density rate at the velocities v (TVCG 2017, eq. 7, in
// volumes): r_i = v_i·g_i − V Σ_j v_j·∇W_ij − f_i, with g_i from the density pass and f_i the
// walls' flux (`dfsph::solver::density_rates`).
@group(0) @binding(1) var<storage, read> fluid: array<vec2<f32>>;
@group(0) @binding(2) var<storage, read> fluid_sorted: array<u32>;
@group(0) @binding(3) var<storage, read> fluid_starts: array<u32>;
@group(0) @binding(4) var<storage, read> densities: array<vec4<f32>>;
@group(0) @binding(5) var<storage, read> velocity: array<vec2<f32>>;
// (f_i, neighbour count): `neighbour_flux.wgsl`.
@group(0) @binding(6) var<storage, read> flux: array<vec2<f32>>;
@group(0) @binding(7) var<storage, read_write> rate: array<f32>;

@compute @workgroup_size(64)
fn density_rate(@builtin(global_invocation_id) id: vec3<u32>) {
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
        for (var s = fluid_starts[cell]; s < fluid_starts[cell + 1u]; s++) {
            let j = fluid_sorted[s];
            let d = x - fluid[j];
            let r2 = dot(d, d);
            if r2 < h2 && j != i {
                sum += dot(velocity[j], grad_w(d, sqrt(r2)));
            }
        }
    }
    rate[i] = dot(velocity[i], densities[i].zw) - params.volume * sum - flux[i].x;
}
