// The one-workgroup passes' fold of the per-workgroup partial sums (`cg_tree_sum`'s
// (Σ, max, Σ, Σ), in a fixed order), for a shader that declares `solve` and `partials`.
// Called in uniform control flow by all 256 invocations; every one gets the result.
fn cg_fold(t: u32) -> vec4<f32> {
    var acc = vec4<f32>(0.0);
    for (var k = t; k < solve.partials; k += 256u) {
        acc = cg_combine(acc, partials[k]);
    }
    return cg_tree_sum(t, acc);
}
