// A conjugate-gradient iteration's step length, one workgroup: pᵀAp = −Δt·Σ a p q from the
// rate pass's partial sums (a fixed order), α = r·z / pᵀAp. A pᵀAp that is not positive and
// finite ends the solve without a step.
@group(0) @binding(0) var<uniform> solve: CgSolve;
@group(0) @binding(1) var<uniform> clock: Control;
@group(0) @binding(2) var<storage, read> partials: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read_write> state: CgState;

@compute @workgroup_size(256)
fn cg_alpha(@builtin(local_invocation_id) lid: vec3<u32>) {
    let t = lid.x;
    let s = cg_fold(t);
    if t != 0u || state.running == 0u {
        return;
    }
    let pq = -clock.dt * s.x;
    if !(pq > 0.0 && pq < 3.0e38) {
        state.running = 0u;
        return;
    }
    state.alpha = state.rz / pq;
}
