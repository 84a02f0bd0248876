// Apply one set of stiffness increments, per fluid particle (`apply_blocks` of the CPU
// solver, TVCG 2017 eq. 9 and 12 in volumes): v_i += −Δκ_i g_i − V Σ_j Δκ_j ∇W_ij, and add
// Δκ_i to the running total. Bound in two modes: as the solve's step, and as the take-back
// of an iteration that made the error grow (`slot.mode` 1), which applies the negated
// increments of the buffer `jacobi_control.wgsl` named, and does nothing otherwise.
@group(0) @binding(1) var<uniform> slot: Slot;
@group(0) @binding(2) var<storage, read> control: Control;
@group(0) @binding(3) var<storage, read> fluid: array<vec2<f32>>;
@group(0) @binding(4) var<storage, read> fluid_sorted: array<u32>;
@group(0) @binding(5) var<storage, read> fluid_starts: array<u32>;
@group(0) @binding(6) var<storage, read> densities: array<vec4<f32>>;
// The increments Δκ.
@group(0) @binding(7) var<storage, read> kappa: array<f32>;
@group(0) @binding(8) var<storage, read_write> velocity: array<vec2<f32>>;
@group(0) @binding(9) var<storage, read_write> jac: array<vec4<f32>>;

@compute @workgroup_size(64)
fn jacobi_apply(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if i >= params.n {
        return;
    }
    var sign = 1.0;
    if slot.mode == 1u {
        if control.take_back == 0u || control.take_back_parity != slot.parity {
            return;
        }
        sign = -1.0;
    }
    let sum = kappa_sum(i, fluid[i]);
    let own = kappa[i];
    velocity[i] += sign * (-own * densities[i].zw - params.volume * sum);
    jac[i].z += sign * own;
}
