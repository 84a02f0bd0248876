// Each fluid particle's relative density rate at the velocities v (TVCG 2017, eq. 7, in
// volumes): r_i = v_i·g_i − V Σ_j v_j·∇W_ij − f_i, with g_i from the density pass and f_i the
// walls' flux (`dfsph::solver::density_rates`); the sum is `rate_sum.wgsl`'s.
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
    let sum = velocity_sum(i, fluid[i]);
    rate[i] = dot(velocity[i], densities[i].zw) - params.volume * sum - flux[i].x;
}
