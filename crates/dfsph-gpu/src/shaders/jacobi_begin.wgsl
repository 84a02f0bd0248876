// A Jacobi solve's start, per fluid particle (`dfsph::pressure::jacobi::divergence_solve`
// and `density_solve`): the residual's constant part, the warm start, the running total.
//
// The residual is e_i = max(source_i + s·(v_i·g_i − V Σ_j v_j·∇W_ij − f_i), 0) with s = 1
// (divergence) or Δt (density); `jac.x` holds source_i − s·f_i, the part that does not
// change within the solve. Divergence: source 0, or −∞ for a particle with fewer neighbours
// than `min_neighbours`. Density: the existing compression ρ_i/ρ0 − 1, at most
// max_correction_speed·Δt/d. The warm start `jac.y` is a share of the previous step's
// stiffness, negative part dropped (κᵛ, or κ = Δt·p/ρ0).
@group(0) @binding(1) var<uniform> solve: Solve;
@group(0) @binding(2) var<uniform> clock: Control;
@group(0) @binding(3) var<storage, read> densities: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read> flux: array<vec2<f32>>;
// κᵛ (divergence) or p/ρ0 (density) of the previous step.
@group(0) @binding(5) var<storage, read> stored: array<f32>;
// (source − s·f, warm start, running total, last residual).
@group(0) @binding(6) var<storage, read_write> jac: array<vec4<f32>>;

@compute @workgroup_size(64)
fn jacobi_begin(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if i >= params.n {
        return;
    }
    var source = 0.0;
    var scale = 1.0;
    var warm = max(stored[i], 0.0) * solve.warm_share;
    if solve.density == 1u {
        scale = clock.dt;
        source = min(densities[i].x - 1.0, solve.max_correction_rate * clock.dt);
        warm *= clock.dt;
    } else if flux[i].y < solve.min_neighbours {
        source = -3.0e38;
    }
    jac[i] = vec4<f32>(source - scale * flux[i].x, warm, 0.0, 0.0);
}
