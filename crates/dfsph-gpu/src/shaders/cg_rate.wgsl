// A search direction's rate change, per fluid particle: q_i = Δv_i·g_i − V Σ_j Δv_j·∇W_ij
// for its velocity change Δv (`cg_push`; `dfsph::solver::density_rates` without the walls'
// flux), and per workgroup (Σ a_i p_i q_i, 0, Σ a_i p_i e_i, 0): `cg_alpha.wgsl` makes
// pᵀAp = −Δt·Σ a p q of it, `coarse_first.wgsl` the deflated start's step as well.
@group(0) @binding(1) var<storage, read> fluid: array<vec2<f32>>;
@group(0) @binding(2) var<storage, read> fluid_sorted: array<u32>;
@group(0) @binding(3) var<storage, read> fluid_starts: array<u32>;
@group(0) @binding(4) var<storage, read> densities: array<vec4<f32>>;
// The direction's velocity change.
@group(0) @binding(5) var<storage, read> velocity: array<vec2<f32>>;
@group(0) @binding(6) var<storage, read> direction: array<f32>;
@group(0) @binding(7) var<storage, read> carries: array<f32>;
@group(0) @binding(8) var<storage, read_write> rate: array<f32>;
@group(0) @binding(9) var<storage, read_write> partials: array<vec4<f32>>;
@group(0) @binding(10) var<storage, read> residual: array<f32>;

@compute @workgroup_size(256)
fn cg_rate(
    @builtin(global_invocation_id) id: vec3<u32>,
    @builtin(local_invocation_id) lid: vec3<u32>,
    @builtin(workgroup_id) wid: vec3<u32>,
) {
    let i = id.x;
    var sums = vec4<f32>(0.0);
    if i < params.n {
        let q = dot(velocity[i], densities[i].zw) - params.volume * velocity_sum(i, fluid[i]);
        rate[i] = q;
        let ap = direction[i] * carries[i];
        sums = vec4<f32>(ap * q, 0.0, ap * residual[i], 0.0);
    }
    let s = cg_tree_sum(lid.x, sums);
    if lid.x == 0u {
        partials[wid.x] = s;
    }
}
