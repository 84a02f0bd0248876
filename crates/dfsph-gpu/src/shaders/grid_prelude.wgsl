// What the grid's passes share: the grid as they read it (`GridLayout` in src/grid.rs).
struct Grid {
    origin: vec2<f32>,
    inv_cell: f32,
    n: u32,
    nx: u32,
    ny: u32,
    cells: u32,
    pad: u32,
}

@group(0) @binding(0) var<uniform> grid: Grid;
