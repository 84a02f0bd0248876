// Write the indirect dispatch sizes of the conjugate-gradient iteration `next`, into the
// slot `next / 2` of the buffer of its parity (`dispatch`, declared by the caller with
// `solve` and `state`): first what the previous iteration's next direction needs
// (`deflate`: the coarse restriction and solve, when deflating; `direction`: the direction
// pass, which is also the take-back of a step), then the iteration's five passes (`run`):
// push, rate, step length, step and control. Zero sizes dispatch nothing.
fn cg_sizes(next: u32, deflate: u32, direction: u32, run: u32) {
    let at = next / 2u * 24u;
    let sizes = array<u32, 8>(
        state.coarse_groups * deflate,
        min(state.coarse_groups, 1u) * deflate,
        solve.groups * direction,
        solve.groups * run,
        solve.partials * run,
        run,
        solve.partials * run,
        run,
    );
    for (var k = 0u; k < 8u; k++) {
        dispatch[at + 3u * k] = sizes[k];
        dispatch[at + 3u * k + 1u] = 1u;
        dispatch[at + 3u * k + 2u] = 1u;
    }
}

// Whether the solve goes on after `iterations` with errors `avg` and `max_err` (percent)
// (`SolveLimits::unmet` and the velocity rule): r·z above round-off, and either an error
// above its tolerance, the velocity still to correct (the last four energies, RMS) above
// the tolerance, or fewer than the minimum of iterations; never past the maximum.
fn cg_goes_on(state: CgState, avg: f32, max_err: f32, dt: f32) -> bool {
    var velocity_tolerance = solve.density_speed / dt;
    let from_gravity = solve.gravity_impulse * dt;
    if from_gravity > 0.0 {
        velocity_tolerance = min(velocity_tolerance, from_gravity);
    }
    var velocity_unmet = true;
    if state.energies >= 4u {
        let e = state.energy;
        let velocity_error = sqrt((e.x + e.y + e.z + e.w) / (dt * state.n_active));
        velocity_unmet = velocity_error > velocity_tolerance;
    }
    let unmet = avg > solve.tolerance_pct || max_err > solve.max_error_pct || velocity_unmet
        || state.iterations < solve.min_iterations;
    return unmet && state.iterations < solve.max_iterations && state.rz > state.round_off;
}
