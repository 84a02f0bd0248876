// For a pair pass (`params`) that gathers particles by region.
// The fine grid's cells (`params`) that cover the box from `lo` to `hi` (m), clamped to the
// grid as the particles are: (x first, x last, y first, y last).
fn fine_cells(lo: vec2<f32>, hi: vec2<f32>) -> vec4<u32> {
    let top = vec2<f32>(f32(params.nx - 1u), f32(params.ny - 1u));
    let a = vec2<u32>(clamp(floor((lo - params.origin) * params.inv_cell), vec2<f32>(0.0), top));
    let b = vec2<u32>(clamp(floor((hi - params.origin) * params.inv_cell), vec2<f32>(0.0), top));
    return vec4<u32>(a.x, b.x, a.y, b.y);
}
