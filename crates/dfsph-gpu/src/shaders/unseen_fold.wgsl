// The largest unseen compression of the step (`unseen_walls.wgsl`'s partial maxima), one
// workgroup, into `control.unseen`.
@group(0) @binding(0) var<uniform> consts: StepConsts;
@group(0) @binding(1) var<storage, read> partials: array<vec2<f32>>;
@group(0) @binding(2) var<storage, read_write> control: Control;

@compute @workgroup_size(256)
fn unseen_fold(@builtin(local_invocation_id) lid: vec3<u32>) {
    let t = lid.x;
    var m = 0.0;
    for (var k = t; k < consts.partials; k += 256u) {
        m = max(m, partials[k].x);
    }
    let largest = workgroup_max(t, m);
    if t == 0u {
        control.unseen = largest;
    }
}
