// The deflation's coarse grid for this solve, one workgroup (`CoarseSpace::aggregate`):
// fold the residual pass's bounds of the particles that carry pressure, and lay square cells
// `solve.coarse_cell` wide from their lower corner, doubled while the grid would have more
// than four cells per particle (4n + 16). Writes the per-aggregate passes' dispatch size
// and their workgroups into the solve's state.
@group(0) @binding(0) var<uniform> solve: CgSolve;
@group(0) @binding(1) var<storage, read> bounds: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read_write> coarse: Coarse;
@group(0) @binding(3) var<storage, read_write> state: CgState;
@group(0) @binding(4) var<storage, read_write> sizes: array<u32>;

@compute @workgroup_size(256)
fn coarse_layout(@builtin(local_invocation_id) lid: vec3<u32>) {
    let t = lid.x;
    var acc = vec4<f32>(3.0e38, 3.0e38, -3.0e38, -3.0e38);
    for (var k = t; k < solve.partials; k += 256u) {
        acc = cg_bounds_combine(acc, bounds[k]);
    }
    let b = cg_bounds_tree(t, acc);
    if t != 0u {
        return;
    }
    var grid: Coarse;
    let lo = b.xy;
    let hi = b.zw;
    if lo.x > hi.x {
        // Nothing carries pressure: one empty cell.
        grid.origin = vec2<f32>(0.0);
        grid.cell = solve.coarse_cell;
        grid.cells = vec2<u32>(1u);
    } else {
        var cell = solve.coarse_cell;
        let most = 4.0 * f32(solve.n) + 16.0;
        loop {
            let c = floor((hi - lo) / cell) + 1.0;
            if c.x * c.y <= most {
                break;
            }
            cell *= 2.0;
        }
        grid.origin = lo;
        grid.cell = cell;
        grid.cells = vec2<u32>(floor((hi - lo) / cell)) + vec2<u32>(1u);
    }
    grid.count = grid.cells.x * grid.cells.y;
    grid.band = min(grid.cells.x, grid.cells.y) + 1u;
    coarse = grid;
    let groups = (grid.count + 63u) / 64u;
    state.coarse_groups = groups;
    sizes[0] = groups;
    sizes[1] = 1u;
    sizes[2] = 1u;
}
