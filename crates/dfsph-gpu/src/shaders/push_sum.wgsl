// Σ_j κ_j ∇W_ij over fluid particle i's neighbours j ≠ i (at x, in the 3 × 3 cells around
// it): the neighbours' share of the push a stiffness field κ gives i (TVCG 2017, eq. 9 and
// 12, in volumes, times V). The shader that calls it (`Gpu::pipeline` adds this file) declares `fluid`, `fluid_sorted`,
// `fluid_starts` and `kappa`.
fn kappa_sum(i: u32, x: vec2<f32>) -> vec2<f32> {
    let home = cell_of(x);
    let h2 = params.h * params.h;
    var sum = vec2<f32>(0.0);
    for (var k = 0u; k < 9u; k++) {
        let fluid_range = fluid_slots(home, k);
        for (var s = fluid_range.x; s < fluid_range.y; s++) {
            let j = fluid_sorted[s];
            let d = x - fluid[j];
            let r2 = dot(d, d);
            if r2 < h2 && j != i {
                sum += kappa[j] * grad_w(d, sqrt(r2));
            }
        }
    }
    return sum;
}
