// A conjugate-gradient iteration's stopping test, one workgroup (`density_solve` of
// `dfsph::pressure::conjugate_gradient`): fold the step pass's partial sums in a fixed
// order into the average and largest error (percent) and the new r·z. A step that made the
// largest error grow past `growth` times the one before (plus `max_error_pct`), or not a
// number, is taken back and ends the solve. Otherwise the iteration counts: its energy
// α·(r·z) is recorded for the velocity rule, β = r·z_new / r·z, and the solve goes on while
// `cg_goes_on` says so. Writes the next slot's dispatch sizes (`cg_sizes`) into the buffer
// of the next iteration's parity.
@group(0) @binding(0) var<uniform> solve: CgSolve;
@group(0) @binding(1) var<uniform> clock: Control;
@group(0) @binding(2) var<storage, read> partials: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read_write> state: CgState;
@group(0) @binding(4) var<storage, read_write> control: Control;
@group(0) @binding(5) var<storage, read_write> dispatch: array<u32>;

@compute @workgroup_size(256)
fn cg_control(@builtin(local_invocation_id) lid: vec3<u32>) {
    let t = lid.x;
    let s = cg_fold(t);
    // Stopped by `cg_alpha`: no step was taken, and the next slot stays empty.
    if t != 0u || state.running == 0u {
        return;
    }
    var next = state;
    // This iteration's place in the recorded loop: the iterations it counted (a deflated
    // start counts one before the loop).
    let this_iteration = next.energies;
    let avg = s.x / f32(max(solve.n, 1u)) * 100.0;
    let max_err = s.y * 100.0;
    if !(max_err <= solve.growth * next.max_err + solve.max_error_pct) {
        next.take_back = 1u;
        next.running = 0u;
        state = next;
        cg_sizes(this_iteration + 1u, 0u, 1u, 0u);
        return;
    }
    let energy = next.alpha * next.rz;
    let slot = next.energies % 4u;
    if slot == 0u {
        next.energy.x = energy;
    } else if slot == 1u {
        next.energy.y = energy;
    } else if slot == 2u {
        next.energy.z = energy;
    } else {
        next.energy.w = energy;
    }
    next.energies += 1u;
    next.beta = s.z / next.rz;
    next.rz = s.z;
    next.avg = avg;
    next.max_err = max_err;
    next.iterations += 1u;
    let run = u32(cg_goes_on(next, avg, max_err, clock.dt));
    next.running = run;
    state = next;
    control.den_iterations = next.iterations;
    control.den_avg = avg;
    control.den_max = max_err;
    cg_sizes(this_iteration + 1u, run, run, run);
}
