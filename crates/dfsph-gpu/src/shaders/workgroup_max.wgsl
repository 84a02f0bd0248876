// The largest of the 256 values `v` the invocations of a workgroup hold (`t`: the local
// index), by a fixed tree (the same bits on every run); every invocation gets it. Called in
// uniform control flow by all 256.
var<workgroup> maxima: array<f32, 256>;

fn workgroup_max(t: u32, v: f32) -> f32 {
    maxima[t] = v;
    workgroupBarrier();
    for (var half = 128u; half > 0u; half /= 2u) {
        if t < half {
            maxima[t] = max(maxima[t], maxima[t + half]);
        }
        workgroupBarrier();
    }
    let m = maxima[0];
    workgroupBarrier();
    return m;
}
