// W y at every fluid particle: its aggregate's value, 0 without one (`CoarseSpace::
// prolong`), as the deflated start's search direction.
@group(0) @binding(1) var<storage, read> aggregate: array<u32>;
@group(0) @binding(2) var<storage, read> y: array<f32>;
@group(0) @binding(3) var<storage, read_write> direction: array<f32>;

@compute @workgroup_size(64)
fn coarse_prolong(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if i >= params.n {
        return;
    }
    let a = aggregate[i];
    var v = 0.0;
    if a != 0xffffffffu {
        v = y[a];
    }
    direction[i] = v;
}
