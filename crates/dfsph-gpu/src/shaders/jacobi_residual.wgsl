// One Jacobi residual pass, per fluid particle (`ResidualTerms` of the CPU solver): the
// residual e_i = max(jac.x + s·(v_i·g_i − V Σ_j v_j·∇W_ij), 0) at the velocities as they
// are, the next stiffness increment Δκ_i = e_i·a_i·t (s = 1, t = 1 for the divergence
// solve; s = Δt, t = 1/Δt for the density solve), and per workgroup the sum and the largest
// of the residuals, for `jacobi_control.wgsl` (a fixed tree: the same bits on every run).
@group(0) @binding(1) var<uniform> solve: Solve;
@group(0) @binding(2) var<uniform> clock: Control;
@group(0) @binding(3) var<storage, read> fluid: array<vec2<f32>>;
@group(0) @binding(4) var<storage, read> fluid_sorted: array<u32>;
@group(0) @binding(5) var<storage, read> fluid_starts: array<u32>;
@group(0) @binding(6) var<storage, read> densities: array<vec4<f32>>;
@group(0) @binding(7) var<storage, read> velocity: array<vec2<f32>>;
@group(0) @binding(8) var<storage, read_write> jac: array<vec4<f32>>;
@group(0) @binding(9) var<storage, read_write> increment: array<f32>;
@group(0) @binding(10) var<storage, read_write> partials: array<vec2<f32>>;

var<workgroup> sums: array<vec2<f32>, 256>;

@compute @workgroup_size(256)
fn jacobi_residual(
    @builtin(global_invocation_id) id: vec3<u32>,
    @builtin(local_invocation_id) lid: vec3<u32>,
    @builtin(workgroup_id) wid: vec3<u32>,
) {
    let i = id.x;
    let t = lid.x;
    var e = 0.0;
    if i < params.n {
        let sum = velocity_sum(i, fluid[i]);
        let dens = densities[i];
        let rate = dot(velocity[i], dens.zw) - params.volume * sum;
        var scale = 1.0;
        var inc_scale = 1.0;
        if solve.density == 1u {
            scale = clock.dt;
            inc_scale = 1.0 / clock.dt;
        }
        var state = jac[i];
        e = max(state.x + scale * rate, 0.0);
        state.w = e;
        jac[i] = state;
        increment[i] = e * dens.y * inc_scale;
    }
    sums[t] = vec2<f32>(e, e);
    workgroupBarrier();
    for (var half = 128u; half > 0u; half /= 2u) {
        if t < half {
            let a = sums[t];
            let b = sums[t + half];
            sums[t] = vec2<f32>(a.x + b.x, max(a.y, b.y));
        }
        workgroupBarrier();
    }
    if t == 0u {
        partials[wid.x] = sums[0];
    }
}
