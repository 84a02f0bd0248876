// A step of α along the search direction, per fluid particle: κ += α p, v += α Δv, and the
// error e += α Δt q (none once the solve has ended); per workgroup (Σ|a e|, max |a e|,
// Σ a (factor/Δt) e², Σ a) for `cg_control.wgsl` (and `cg_start.wgsl` after a deflated
// start).
@group(0) @binding(1) var<uniform> clock: Control;
@group(0) @binding(2) var<storage, read> state: CgState;
@group(0) @binding(3) var<storage, read> densities: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read> direction: array<f32>;
@group(0) @binding(5) var<storage, read> change: array<vec2<f32>>;
@group(0) @binding(6) var<storage, read> rate: array<f32>;
@group(0) @binding(7) var<storage, read> carries: array<f32>;
@group(0) @binding(8) var<storage, read_write> total: array<f32>;
@group(0) @binding(9) var<storage, read_write> velocity: array<vec2<f32>>;
@group(0) @binding(10) var<storage, read_write> residual: array<f32>;
@group(0) @binding(11) var<storage, read_write> partials: array<vec4<f32>>;

@compute @workgroup_size(256)
fn cg_step(
    @builtin(global_invocation_id) id: vec3<u32>,
    @builtin(local_invocation_id) lid: vec3<u32>,
    @builtin(workgroup_id) wid: vec3<u32>,
) {
    let i = id.x;
    let alpha = state.alpha;
    let going = state.running == 1u;
    var sums = vec4<f32>(0.0);
    if i < params.n {
        var e = residual[i];
        if going {
            total[i] += alpha * direction[i];
            velocity[i] += alpha * change[i];
            e += alpha * clock.dt * rate[i];
            residual[i] = e;
        }
        let a = carries[i];
        sums = vec4<f32>(abs(a * e), abs(a * e), a * densities[i].y / clock.dt * e * e, a);
    }
    let s = cg_tree_sum(lid.x, sums);
    if lid.x == 0u {
        partials[wid.x] = s;
    }
}
