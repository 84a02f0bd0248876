// The conjugate-gradient passes' sums, (Σ x, max y, Σ z, Σ w) of vec4 values, by a fixed
// tree over a workgroup of 256 (the same bits on every run); every invocation gets the
// result. Called in uniform control flow by all 256. Added to a shader that calls it
// (`Gpu::pipeline`).
var<workgroup> cg_tree: array<vec4<f32>, 256>;

fn cg_combine(a: vec4<f32>, b: vec4<f32>) -> vec4<f32> {
    return vec4<f32>(a.x + b.x, max(a.y, b.y), a.z + b.z, a.w + b.w);
}

fn cg_tree_sum(t: u32, v: vec4<f32>) -> vec4<f32> {
    cg_tree[t] = v;
    workgroupBarrier();
    for (var half = 128u; half > 0u; half /= 2u) {
        if t < half {
            cg_tree[t] = cg_combine(cg_tree[t], cg_tree[t + half]);
        }
        workgroupBarrier();
    }
    let s = cg_tree[0];
    workgroupBarrier();
    return s;
}

// The bounds (min x, min y, max x, max y) of the points the invocations hold, by the same
// kind of tree.
var<workgroup> cg_bounds: array<vec4<f32>, 256>;

fn cg_bounds_combine(a: vec4<f32>, b: vec4<f32>) -> vec4<f32> {
    return vec4<f32>(min(a.xy, b.xy), max(a.zw, b.zw));
}

fn cg_bounds_tree(t: u32, v: vec4<f32>) -> vec4<f32> {
    cg_bounds[t] = v;
    workgroupBarrier();
    for (var half = 128u; half > 0u; half /= 2u) {
        if t < half {
            cg_bounds[t] = cg_bounds_combine(cg_bounds[t], cg_bounds[t + half]);
        }
        workgroupBarrier();
    }
    let s = cg_bounds[0];
    workgroupBarrier();
    return s;
}
