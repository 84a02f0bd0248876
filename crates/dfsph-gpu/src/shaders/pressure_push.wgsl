// The velocity change a stiffness field κ gives each fluid particle:
// Δv_i = −κ_i g_i − V Σ_j κ_j ∇W_ij (TVCG 2017, eq. 9 and 12 in volumes, the walls' share in
// g_i: `dfsph::solver::apply_pressure`); the sum is `push_sum.wgsl`'s.
@group(0) @binding(1) var<storage, read> fluid: array<vec2<f32>>;
@group(0) @binding(2) var<storage, read> fluid_sorted: array<u32>;
@group(0) @binding(3) var<storage, read> fluid_starts: array<u32>;
@group(0) @binding(4) var<storage, read> densities: array<vec4<f32>>;
@group(0) @binding(5) var<storage, read> kappa: array<f32>;
@group(0) @binding(6) var<storage, read_write> dv: array<vec2<f32>>;

@compute @workgroup_size(64)
fn pressure_push(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if i >= params.n {
        return;
    }
    let sum = kappa_sum(i, fluid[i]);
    dv[i] = -kappa[i] * densities[i].zw - params.volume * sum;
}
