// Which particles the conjugate-gradient solve solves for (`density_solve` of
// `dfsph::pressure::conjugate_gradient`): a particle with at least `solve.min_neighbours`
// neighbours (fluid and walls) is full; a full particle less than `SURFACE_DEFICIT` (2 %)
// below ρ0 is inside the water. Added to a shader that calls it, which declares `solve`.
fn cg_full(neighbours: f32) -> bool {
    return neighbours >= solve.min_neighbours;
}

fn cg_inside(density: f32, neighbours: f32) -> bool {
    return cg_full(neighbours) && density >= 1.0 - 0.02;
}
