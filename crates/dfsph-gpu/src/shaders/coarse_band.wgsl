// The coarse matrix E = Wᵀ A W, symmetrised, into band storage, one invocation per
// aggregate (row) r: E(r, c) = ½ (T(r, c − r) + T(c, r − c)) for the cells c around it
// numbered at most r, T(r, 0) on the diagonal (also kept apart, for the factorisation's
// rule for dropped pivots), zero elsewhere in the row. Row r holds columns r − band ..= r.
@group(0) @binding(0) var<storage, read> coarse: Coarse;
@group(0) @binding(1) var<storage, read> rows: array<f32>;
@group(0) @binding(2) var<storage, read_write> band: array<f32>;
@group(0) @binding(3) var<storage, read_write> diagonal: array<f32>;

@compute @workgroup_size(64)
fn coarse_band(@builtin(global_invocation_id) id: vec3<u32>) {
    let r = id.x;
    if r >= coarse.count {
        return;
    }
    let width = coarse.band + 1u;
    for (var j = 0u; j < width; j++) {
        band[r * width + j] = 0.0;
    }
    let home = vec2<i32>(coarse_cell(r));
    let cells = vec2<i32>(coarse.cells);
    for (var k = 0; k < 9; k++) {
        let o = vec2<i32>(k % 3 - 1, k / 3 - 1);
        let c = home + o;
        if c.x < 0 || c.y < 0 || c.x >= cells.x || c.y >= cells.y {
            continue;
        }
        let key = coarse_key(vec2<u32>(c));
        if key > r {
            continue;
        }
        var value = rows[r * 9u + u32(k)];
        if key != r {
            let back = (1 - o.y) * 3 + (1 - o.x);
            value = 0.5 * (value + rows[key * 9u + u32(back)]);
        } else {
            diagonal[r] = value;
        }
        band[r * width + key + coarse.band - r] = value;
    }
}
