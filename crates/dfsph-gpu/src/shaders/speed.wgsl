// The largest |v|² of each workgroup's 256 fluid particles, for `time_step.wgsl`.
@group(0) @binding(1) var<storage, read> velocity: array<vec2<f32>>;
@group(0) @binding(2) var<storage, read_write> partials: array<vec2<f32>>;

@compute @workgroup_size(256)
fn speed(
    @builtin(global_invocation_id) id: vec3<u32>,
    @builtin(local_invocation_id) lid: vec3<u32>,
    @builtin(workgroup_id) wid: vec3<u32>,
) {
    let t = lid.x;
    var v2 = 0.0;
    if id.x < params.n {
        let v = velocity[id.x];
        v2 = dot(v, v);
    }
    let m = workgroup_max(t, v2);
    if t == 0u {
        partials[wid.x] = vec2<f32>(m, 0.0);
    }
}
