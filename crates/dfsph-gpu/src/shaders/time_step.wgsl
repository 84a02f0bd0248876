// The step's Δt on the device, one workgroup (`CpuBackend::cfl_time_step`): the CFL
// condition λ·d/v_max over the fluid (after the divergence solve) and the walls, at most
// √(λ·d/|g|), clamped to the scene's bounds and the host's upper bound (the viscosity's
// and the deep water's), then at most the step that keeps every particle's travel,
// |v|·Δt + ½|a|·Δt², within `reach` (`dfsph::displacement::step_displacement_bound`);
// then at most `dt_cap` (a retry's).
@group(0) @binding(0) var<uniform> consts: StepConsts;
@group(0) @binding(1) var<storage, read> partials: array<vec2<f32>>;
@group(0) @binding(2) var<storage, read_write> control: Control;

@compute @workgroup_size(256)
fn time_step(@builtin(local_invocation_id) lid: vec3<u32>) {
    let t = lid.x;
    var m = 0.0;
    for (var k = t; k < consts.partials; k += 256u) {
        m = max(m, partials[k].x);
    }
    let largest = workgroup_max(t, m);
    if t != 0u {
        return;
    }
    let fluid_max = sqrt(largest);
    let v_max = max(fluid_max, consts.wall_speed);
    var dt = consts.dt_upper;
    if v_max > 0.0 {
        dt = consts.cfl * consts.spacing / v_max;
    }
    let g = length(consts.gravity);
    if g > 0.0 {
        dt = min(dt, sqrt(consts.cfl * consts.spacing / g));
    }
    dt = clamp(dt, min(consts.dt_min, consts.dt_upper), consts.dt_upper);
    var accel = consts.accel;
    if consts.pulls == 1u {
        accel += 4.0 * fluid_max;
    }
    let speed = fluid_max + consts.wall_speed;
    let denominator = speed + sqrt(speed * speed + 2.0 * accel * consts.reach);
    if denominator > 0.0 {
        dt = min(dt, 2.0 * consts.reach / denominator);
    }
    control.cfl_dt = dt;
    control.dt = min(dt, consts.dt_cap);
}
