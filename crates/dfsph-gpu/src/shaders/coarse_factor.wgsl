// The Cholesky factor of the coarse matrix in its band, in place, one workgroup
// (`CoarseSpace::cholesky`, column by column): each pivot, the column below it divided by
// it, then the rows below updated. A pivot that has lost all but a 1e-10 share of its
// diagonal marks an aggregate whose stiffness the others already fix (or an empty cell): it
// is dropped, and its column is zero.
@group(0) @binding(0) var<storage, read> coarse: Coarse;
@group(0) @binding(1) var<storage, read> diagonal: array<f32>;
@group(0) @binding(2) var<storage, read_write> band: array<f32>;


@compute @workgroup_size(256)
fn coarse_factor(@builtin(local_invocation_id) lid: vec3<u32>) {
    let t = lid.x;
    let shape = coarse_shape(t);
    let count = shape.x;
    let b = shape.y;
    for (var c = 0u; c < count; c++) {
        if t == 0u {
            let d = band[band_at(c, c, b)];
            var pivot = 0.0;
            if d > 1.0e-10 * diagonal[c] {
                pivot = sqrt(d);
            }
            band[band_at(c, c, b)] = pivot;
        }
        storageBarrier();
        let pivot = band[band_at(c, c, b)];
        let last = min(c + b, count - 1u);
        for (var r = c + 1u + t; r <= last; r += 256u) {
            var l = 0.0;
            if pivot > 0.0 {
                l = band[band_at(r, c, b)] / pivot;
            }
            band[band_at(r, c, b)] = l;
        }
        storageBarrier();
        for (var r = c + 1u; r <= last; r++) {
            let lr = band[band_at(r, c, b)];
            for (var k = c + 1u + t; k <= r; k += 256u) {
                band[band_at(r, k, b)] -= lr * band[band_at(k, c, b)];
            }
        }
        storageBarrier();
    }
}
