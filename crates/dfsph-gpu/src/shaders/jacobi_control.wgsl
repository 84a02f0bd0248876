// A Jacobi solve's stopping rule on the device (`SolveLimits::unmet` and `jacobi_solve` of
// the CPU solver), one workgroup: fold the residual pass's partial sums and maxima in a
// fixed order, turn them into the average and largest error in percent, decide whether the
// solve goes on, and write the next iteration's workgroup counts, its own included (zero
// once it ends), so that the iterations recorded after it cost empty dispatches. Bound in two modes:
// after the first residual pass (`slot.mode` 1), and after each iteration, when an average
// error that grew past `growth` times the one before (plus the tolerance), or is not a
// number, marks the increments just applied (`slot.parity`) to be taken back and ends the
// solve.
@group(0) @binding(0) var<uniform> solve: Solve;
@group(0) @binding(1) var<uniform> slot: Slot;
@group(0) @binding(2) var<uniform> clock: Control;
@group(0) @binding(3) var<storage, read> partials: array<vec2<f32>>;
@group(0) @binding(4) var<storage, read_write> control: Control;
// The next iteration's indirect dispatch sizes: the apply pass's (64 particles a workgroup),
// the residual pass's (256) and this pass's own (one workgroup; none once the solve has
// ended). Iteration k reads slot k/2 of the buffer of its parity, written by the control
// pass before it (a pass cannot write the buffer it is dispatched from); the host clears
// both buffers before the solve, so that the slots after the last one written dispatch
// nothing.
@group(0) @binding(5) var<storage, read_write> dispatch: array<u32>;

var<workgroup> sums: array<vec2<f32>, 256>;

fn unmet(avg: f32, max_err: f32, iterations: u32) -> bool {
    return (avg > solve.tolerance_pct || max_err > solve.max_error_pct
        || iterations < solve.min_iterations) && iterations < solve.max_iterations;
}

@compute @workgroup_size(256)
fn jacobi_control(@builtin(local_invocation_id) lid: vec3<u32>) {
    let first = slot.mode == 1u;
    let t = lid.x;
    var acc = vec2<f32>(0.0);
    for (var k = t; k < solve.partials; k += 256u) {
        let p = partials[k];
        acc = vec2<f32>(acc.x + p.x, max(acc.y, p.y));
    }
    sums[t] = acc;
    workgroupBarrier();
    for (var half = 128u; half > 0u; half /= 2u) {
        if t < half {
            let a = sums[t];
            let b = sums[t + half];
            sums[t] = vec2<f32>(a.x + b.x, max(a.y, b.y));
        }
        workgroupBarrier();
    }
    // A solve that has ended dispatches no more control passes (their sizes are zero); the
    // test stands after the barriers, which every invocation must reach (uniformity).
    if t != 0u || (!first && control.running == 0u) {
        return;
    }
    // The error in percent: of ρ0 (density), or of the density's change over one step of
    // the previous Δt (divergence).
    var to_pct = 100.0;
    if solve.density == 0u {
        to_pct = 100.0 * clock.last_dt;
    }
    var avg = sums[0].x / f32(max(solve.n, 1u)) * to_pct;
    var max_err = sums[0].y * to_pct;
    var running = 1u;
    if first {
        control.iterations = 0u;
        control.take_back = 0u;
    } else {
        control.iterations += 1u;
        if !(avg <= solve.growth * control.prev_avg + solve.tolerance_pct) {
            // Growing (or not a number): take the increments just applied back.
            control.take_back = 1u;
            control.take_back_parity = slot.parity;
            avg = control.prev_avg;
            max_err = control.prev_max;
            running = 0u;
        }
    }
    if running == 1u && !unmet(avg, max_err, control.iterations) {
        running = 0u;
    }
    control.running = running;
    control.avg = avg;
    control.max_err = max_err;
    control.prev_avg = avg;
    control.prev_max = max_err;
    if solve.density == 1u {
        control.den_iterations = control.iterations;
        control.den_avg = avg;
        control.den_max = max_err;
    } else {
        control.div_iterations = control.iterations;
        control.div_avg = avg;
    }
    // The next iteration is iteration `control.iterations`.
    let at = control.iterations / 2u * 9u;
    dispatch[at] = solve.groups * running;
    dispatch[at + 1u] = 1u;
    dispatch[at + 2u] = 1u;
    dispatch[at + 3u] = solve.partials * running;
    dispatch[at + 4u] = 1u;
    dispatch[at + 5u] = 1u;
    dispatch[at + 6u] = running;
    dispatch[at + 7u] = 1u;
    dispatch[at + 8u] = 1u;
}
