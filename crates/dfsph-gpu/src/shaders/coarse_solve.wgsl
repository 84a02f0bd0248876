// y = E⁻¹ y with the coarse matrix's Cholesky factor in its band, in place, one workgroup
// (`CoarseSpace::solve`): forward and back substitution, column by column; a dropped pivot
// gives 0.
@group(0) @binding(0) var<storage, read> coarse: Coarse;
@group(0) @binding(1) var<storage, read> band: array<f32>;
@group(0) @binding(2) var<storage, read_write> y: array<f32>;


@compute @workgroup_size(256)
fn coarse_solve(@builtin(local_invocation_id) lid: vec3<u32>) {
    let t = lid.x;
    let shape = coarse_shape(t);
    let count = shape.x;
    let b = shape.y;
    // L x = y, column by column.
    for (var c = 0u; c < count; c++) {
        if t == 0u {
            let pivot = band[band_at(c, c, b)];
            var v = 0.0;
            if pivot > 0.0 {
                v = y[c] / pivot;
            }
            y[c] = v;
        }
        storageBarrier();
        let v = y[c];
        let last = min(c + b, count - 1u);
        for (var r = c + 1u + t; r <= last; r += 256u) {
            y[r] -= band[band_at(r, c, b)] * v;
        }
        storageBarrier();
    }
    // Lᵀ y = x, row by row from the last.
    for (var k = 0u; k < count; k++) {
        let r = count - 1u - k;
        if t == 0u {
            let pivot = band[band_at(r, r, b)];
            var v = 0.0;
            if pivot > 0.0 {
                v = y[r] / pivot;
            }
            y[r] = v;
        }
        storageBarrier();
        let v = y[r];
        var first = 0u;
        if r > b {
            first = r - b;
        }
        for (var c = first + t; c < r; c += 256u) {
            y[c] -= band[band_at(r, c, b)] * v;
        }
        storageBarrier();
    }
}
