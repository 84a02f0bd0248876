// The conjugate-gradient solve's first residual, per fluid particle, after the warm start:
// the rate r_i = v_i·g_i − V Σ_j v_j·∇W_ij − f_i (`dfsph::solver::density_rates`), the error
// e_i = clamp(ρ_i/ρ0 − 1 − dead band, 0, max correction) + Δt·r_i, whether the particle
// carries pressure (inside the water, or full and compressed, with a factor), the first
// search direction z_i = a_i·(factor_i/Δt)·e_i, and per workgroup (Σ|a e|, max |a e|, Σ z e,
// Σ a) for `cg_start.wgsl`, and the bounds of the particles that carry pressure for
// `coarse_layout.wgsl`.
@group(0) @binding(1) var<uniform> solve: CgSolve;
@group(0) @binding(2) var<uniform> clock: Control;
@group(0) @binding(3) var<storage, read> fluid: array<vec2<f32>>;
@group(0) @binding(4) var<storage, read> fluid_sorted: array<u32>;
@group(0) @binding(5) var<storage, read> fluid_starts: array<u32>;
@group(0) @binding(6) var<storage, read> densities: array<vec4<f32>>;
@group(0) @binding(7) var<storage, read> flux: array<vec2<f32>>;
@group(0) @binding(8) var<storage, read> velocity: array<vec2<f32>>;
@group(0) @binding(9) var<storage, read_write> residual: array<f32>;
@group(0) @binding(10) var<storage, read_write> carries: array<f32>;
@group(0) @binding(11) var<storage, read_write> direction: array<f32>;
@group(0) @binding(12) var<storage, read_write> partials: array<vec4<f32>>;
@group(0) @binding(13) var<storage, read_write> bounds: array<vec4<f32>>;

@compute @workgroup_size(256)
fn cg_residual(
    @builtin(global_invocation_id) id: vec3<u32>,
    @builtin(local_invocation_id) lid: vec3<u32>,
    @builtin(workgroup_id) wid: vec3<u32>,
) {
    let i = id.x;
    var sums = vec4<f32>(0.0);
    var box = vec4<f32>(3.0e38, 3.0e38, -3.0e38, -3.0e38);
    if i < params.n {
        let dens = densities[i];
        let fl = flux[i];
        let rate = dot(velocity[i], dens.zw) - params.volume * velocity_sum(i, fluid[i]) - fl.x;
        let most = max(solve.max_correction_rate * clock.dt, 0.0);
        let e = clamp(dens.x - 1.0 - solve.dead_band, 0.0, most) + clock.dt * rate;
        let on = cg_inside(dens.x, fl.y) || (cg_full(fl.y) && e > 0.0);
        var a = 0.0;
        if on && dens.y > 0.0 {
            a = 1.0;
        }
        residual[i] = e;
        carries[i] = a;
        let z = a * dens.y / clock.dt * e;
        direction[i] = z;
        sums = vec4<f32>(abs(a * e), abs(a * e), z * e, a);
        if a > 0.0 {
            box = vec4<f32>(fluid[i], fluid[i]);
        }
    }
    let s = cg_tree_sum(lid.x, sums);
    let b = cg_bounds_tree(lid.x, box);
    if lid.x == 0u {
        partials[wid.x] = s;
        bounds[wid.x] = b;
    }
}
