// The non-pressure accelerations of every fluid particle (`dfsph::forces`): gravity, XSPH
// (V·(c/Δt)·Σ_j W_ij (v_j − v_i)), the Laplacian viscosity (V·8ν·Σ_j ∇W_ij
// (v_ij·x_ij)/(|x_ij|² + 0.01h²), Morris et al. 1997) and the user's pointer (a push or a pull
// fading to zero at its reach; a pull also damps the motion relative to it). The walls'
// friction is `wall_friction.wgsl`.
@group(0) @binding(1) var<uniform> consts: StepConsts;
@group(0) @binding(2) var<uniform> clock: Control;
@group(0) @binding(3) var<storage, read> fluid: array<vec2<f32>>;
@group(0) @binding(4) var<storage, read> fluid_sorted: array<u32>;
@group(0) @binding(5) var<storage, read> fluid_starts: array<u32>;
@group(0) @binding(6) var<storage, read> velocity: array<vec2<f32>>;
@group(0) @binding(7) var<storage, read_write> acceleration: array<vec2<f32>>;

@compute @workgroup_size(64)
fn forces(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if i >= params.n {
        return;
    }
    let x = fluid[i];
    let v = velocity[i];
    var acc = consts.gravity;
    if consts.xsph > 0.0 || consts.laplace > 0.0 {
        let home = cell_of(x);
        let h2 = params.h * params.h;
        var xsph_sum = vec2<f32>(0.0);
        var laplace_sum = vec2<f32>(0.0);
        for (var k = 0u; k < 9u; k++) {
            let fluid_range = fluid_slots(home, k);
            for (var s = fluid_range.x; s < fluid_range.y; s++) {
                let j = fluid_sorted[s];
                let d = x - fluid[j];
                let r2 = dot(d, d);
                if r2 < h2 && j != i {
                    let r = sqrt(r2);
                    let vij = v - velocity[j];
                    xsph_sum -= vij * w(r);
                    laplace_sum += grad_w(d, r) * (dot(vij, d) / (r2 + consts.eps2));
                }
            }
        }
        acc += params.volume * (consts.xsph / clock.dt * xsph_sum);
        acc += params.volume * (consts.laplace * laplace_sum);
    }
    if consts.pointer_radius > 0.0 && consts.pointer_strength != 0.0 {
        let r = x - consts.pointer_at;
        let dist = length(r);
        if dist < consts.pointer_radius {
            let fade = 1.0 - dist / consts.pointer_radius;
            var dir = vec2<f32>(0.0);
            if dist > 1.0e-6 {
                dir = r / dist;
            }
            acc += dir * consts.pointer_strength * fade;
            if consts.pointer_strength < 0.0 {
                acc -= v * (fade * 4.0);
            }
        }
    }
    acceleration[i] = acc;
}
