// The deflated start's step, one workgroup (`density_solve` of
// `dfsph::pressure::conjugate_gradient`): along p = W E⁻¹ Wᵀ(a e), the line search
// α = pᵀ(a e) / pᵀAp from the rate pass's partial sums (Σ a p q and Σ a p e), taken (and
// counted as an iteration) when pᵀAp is positive and both are finite. `cg_step.wgsl` takes
// it; the next direction starts afresh (β = 0).
@group(0) @binding(0) var<uniform> solve: CgSolve;
@group(0) @binding(1) var<uniform> clock: Control;
@group(0) @binding(2) var<storage, read> partials: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read_write> state: CgState;

@compute @workgroup_size(256)
fn coarse_first(@builtin(local_invocation_id) lid: vec3<u32>) {
    let t = lid.x;
    let s = cg_fold(t);
    if t != 0u {
        return;
    }
    let pq = -clock.dt * s.x;
    let rp = s.z;
    var next = state;
    next.beta = 0.0;
    next.take_back = 0u;
    if pq > 0.0 && pq < 3.0e38 && abs(rp) < 3.0e38 {
        next.alpha = rp / pq;
        next.running = 1u;
        next.iterations = 1u;
    } else {
        next.running = 0u;
        next.iterations = 0u;
    }
    state = next;
}
