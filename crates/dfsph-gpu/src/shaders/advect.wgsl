// Advection x += Δt·v (TVCG 2017, Algorithm 1, line 10) and the last-resort containment of
// `CpuBackend::enforce_tank`: a particle whose centre crossed the centre line of the tank's
// first wall layer is put back on the interior's edge, its outward velocity relative to the
// tank removed; a non-finite particle is put at rest at the tank's centre. Both are counted
// (`counts`: clamped, non-finite) and should stay zero. The boxes are the tank's as it stands
// after this step's move (`consts` holds them before it; the tank moves at `wall_v`).
@group(0) @binding(1) var<uniform> consts: StepConsts;
@group(0) @binding(2) var<uniform> clock: Control;
@group(0) @binding(3) var<storage, read_write> fluid: array<vec2<f32>>;
@group(0) @binding(4) var<storage, read_write> velocity: array<vec2<f32>>;
@group(0) @binding(5) var<storage, read_write> counts: array<atomic<u32>, 2>;

fn finite(a: vec2<f32>) -> bool {
    return abs(a.x) <= 3.4e38 && abs(a.y) <= 3.4e38;
}

@compute @workgroup_size(64)
fn advect(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if i >= params.n {
        return;
    }
    let shift = clock.dt * consts.wall_v;
    let lo = consts.tank_lo + shift;
    let hi = consts.tank_hi + shift;
    let outer_lo = consts.outer_lo + shift;
    let outer_hi = consts.outer_hi + shift;
    var v = velocity[i];
    var x = fluid[i] + clock.dt * v;
    if !(finite(x) && finite(v)) {
        fluid[i] = 0.5 * (lo + hi);
        velocity[i] = vec2<f32>(0.0);
        atomicAdd(&counts[1], 1u);
        return;
    }
    let inside = x.x >= outer_lo.x && x.x <= outer_hi.x && x.y >= outer_lo.y && x.y <= outer_hi.y;
    if !inside {
        x = clamp(x, lo, hi);
        let wv = consts.wall_v;
        if (x.x <= lo.x && v.x < wv.x) || (x.x >= hi.x && v.x > wv.x) {
            v.x = wv.x;
        }
        if (x.y <= lo.y && v.y < wv.y) || (x.y >= hi.y && v.y > wv.y) {
            v.y = wv.y;
        }
        velocity[i] = v;
        atomicAdd(&counts[0], 1u);
    }
    fluid[i] = x;
}
