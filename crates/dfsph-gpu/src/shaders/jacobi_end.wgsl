// A Jacobi solve's end, per fluid particle: its running total becomes the stored stiffness
// the next step's warm start reads: κᵛ (divergence) or p/ρ0 = κ/Δt (density; it does not
// depend on Δt, so it carries over when Δt changes).
@group(0) @binding(1) var<uniform> solve: Solve;
@group(0) @binding(2) var<uniform> clock: Control;
@group(0) @binding(3) var<storage, read> jac: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read_write> stored: array<f32>;

@compute @workgroup_size(64)
fn jacobi_end(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if i >= params.n {
        return;
    }
    var total = jac[i].z;
    if solve.density == 1u {
        total /= clock.dt;
    }
    stored[i] = total;
}
