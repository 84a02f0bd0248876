// The walls' slots in the k-th (0 ≤ k < 9) of the 3 × 3 cells around `home`:
// `wall_sorted[r.x..r.y]`, none outside the grid. Added to a pair shader that calls it
// (`Gpu::pipeline`), which declares `wall_starts`.
fn wall_slots(home: vec2<i32>, k: u32) -> vec2<u32> {
    let c = neighbour_cell(home, k);
    if c < 0 {
        return vec2<u32>(0u);
    }
    return vec2<u32>(wall_starts[u32(c)], wall_starts[u32(c) + 1u]);
}
