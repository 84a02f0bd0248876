// The conjugate-gradient solve's first stopping test, one workgroup: fold the first
// residual's partial sums (`cg_residual`, or `cg_step` after a deflated start) in a fixed
// order into the average and largest error (percent), r·z and the particles that carry
// pressure; set the solve's state (the iterations so far kept: one after a deflated start),
// report its errors, and write the first iteration's dispatch sizes (none when the solve
// has nothing to do).
@group(0) @binding(0) var<uniform> solve: CgSolve;
@group(0) @binding(1) var<uniform> clock: Control;
@group(0) @binding(2) var<storage, read> partials: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read_write> state: CgState;
@group(0) @binding(4) var<storage, read_write> control: Control;
@group(0) @binding(5) var<storage, read_write> dispatch: array<u32>;

@compute @workgroup_size(256)
fn cg_start(@builtin(local_invocation_id) lid: vec3<u32>) {
    let t = lid.x;
    let s = cg_fold(t);
    if t != 0u {
        return;
    }
    var next = state;
    next.rz = s.z;
    // Below this r·z is single precision's round-off of the one the solve started from
    // (`conjugate_gradient::ROUND_OFF`).
    next.round_off = s.z * 1.0e-12;
    next.n_active = max(s.w, 1.0);
    next.avg = s.x / f32(max(solve.n, 1u)) * 100.0;
    next.max_err = s.y * 100.0;
    next.energies = 0u;
    next.take_back = 0u;
    let run = cg_goes_on(next, next.avg, next.max_err, clock.dt);
    next.running = u32(run);
    state = next;
    control.den_iterations = next.iterations;
    control.den_avg = next.avg;
    control.den_max = next.max_err;
    cg_sizes(0u, 0u, 0u, u32(run));
}
