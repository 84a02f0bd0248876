// The deflation's coarse cells (`dfsph::pressure::deflation::CoarseSpace`) for a pass that
// declares `coarse`: where a point lies, a cell's number, its colour in the 2 × 2
// checkerboard, and the cell of each colour within the reach of `A` from a point. Added to
// a shader that calls one of them (`Gpu::pipeline`).
const COARSE_NONE: u32 = 0xffffffffu;

struct CoarsePlace {
    cell: vec2<u32>,
    // Where in the cell, in [0, 1)² (beyond where the point was clamped into the grid).
    frac: vec2<f32>,
}

// The cell a point lies in, clamped to the grid.
fn coarse_place(p: vec2<f32>) -> CoarsePlace {
    let f = max((p - coarse.origin) / coarse.cell, vec2<f32>(0.0));
    let c = min(vec2<u32>(floor(f)), coarse.cells - vec2<u32>(1u));
    return CoarsePlace(c, f - vec2<f32>(c));
}

// A cell's number: along the shorter side first.
fn coarse_key(c: vec2<u32>) -> u32 {
    if coarse.cells.x <= coarse.cells.y {
        return c.y * coarse.cells.x + c.x;
    }
    return c.x * coarse.cells.y + c.y;
}

fn coarse_colour_of(c: vec2<u32>) -> u32 {
    return c.x % 2u + 2u * (c.y % 2u);
}

// Along one axis: the cell of parity `parity` within reach, from cell `c` at `f` in it;
// -1 for none.
fn coarse_pick(c: u32, f: f32, parity: u32, cells: u32) -> i32 {
    if c % 2u == parity {
        return i32(c);
    }
    if f >= 0.5 {
        if c + 1u < cells {
            return i32(c + 1u);
        }
        return -1;
    }
    return i32(c) - 1;
}

// The number of the colour-k cell within reach of a point at `place`, or COARSE_NONE.
fn coarse_target(place: CoarsePlace, k: u32) -> u32 {
    let x = coarse_pick(place.cell.x, place.frac.x, k & 1u, coarse.cells.x);
    let y = coarse_pick(place.cell.y, place.frac.y, k >> 1u, coarse.cells.y);
    if x < 0 || y < 0 {
        return COARSE_NONE;
    }
    return coarse_key(vec2<u32>(u32(x), u32(y)));
}

// The cell with number `key`.
fn coarse_cell(key: u32) -> vec2<u32> {
    if coarse.cells.x <= coarse.cells.y {
        return vec2<u32>(key % coarse.cells.x, key / coarse.cells.x);
    }
    return vec2<u32>(key / coarse.cells.y, key % coarse.cells.y);
}

// The coarse matrix's size (aggregates, half bandwidth) as every invocation of a
// one-workgroup pass holds it, uniform (a loop over it may wait at barriers). Called in
// uniform control flow; `t` is the local index.
var<workgroup> coarse_shape_shared: vec2<u32>;

fn coarse_shape(t: u32) -> vec2<u32> {
    if t == 0u {
        coarse_shape_shared = vec2<u32>(coarse.count, coarse.band);
    }
    return workgroupUniformLoad(&coarse_shape_shared);
}

// Where the band storage keeps E(r, c), r − band ≤ c ≤ r: row r holds columns
// r − band ..= r.
fn band_at(r: u32, c: u32, b: u32) -> u32 {
    return r * (b + 1u) + c + b - r;
}
