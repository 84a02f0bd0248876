// What every pair pass shares: its parameters (one layout for all, `Params` in
// src/pairs.rs), the 2D cubic spline of support h (`dfsph::kernel::Kernel`), and the 3 × 3
// cells around a point in the grid both particle sets are sorted into (`grid_*.wgsl`, cells
// of side h).
struct Params {
    origin: vec2<f32>,
    inv_cell: f32,
    n: u32,
    nx: u32,
    ny: u32,
    h: f32,
    k: f32,
    volume: f32,
    wall_weight: f32,
    max_factor: f32,
    eps: f32,
}

@group(0) @binding(0) var<uniform> params: Params;

// The cubic spline W(r), 1/m² (k = 40 / (7π h²)).
fn w(r: f32) -> f32 {
    let q = r / params.h;
    if q <= 0.5 {
        let q2 = q * q;
        return params.k * (6.0 * q2 * q - 6.0 * q2 + 1.0);
    }
    if q < 1.0 {
        let a = 1.0 - q;
        return 2.0 * params.k * a * a * a;
    }
    return 0.0;
}

// ∇_i W(x_i − x_j) for the offset d = x_i − x_j at distance r > 0: dW/dq / h · d / r.
fn grad_w(d: vec2<f32>, r: f32) -> vec2<f32> {
    let q = r / params.h;
    if r <= 1.0e-9 || q >= 1.0 {
        return vec2<f32>(0.0);
    }
    var dw = 0.0;
    if q <= 0.5 {
        dw = params.k * (18.0 * q * q - 12.0 * q);
    } else {
        let a = 1.0 - q;
        dw = -6.0 * params.k * a * a;
    }
    return d * (dw / params.h / r);
}

// The grid cell of `x`, clamped to the grid.
fn cell_of(x: vec2<f32>) -> vec2<i32> {
    let c = floor((x - params.origin) * params.inv_cell);
    return vec2<i32>(
        i32(clamp(c.x, 0.0, f32(params.nx - 1u))),
        i32(clamp(c.y, 0.0, f32(params.ny - 1u))),
    );
}

// The k-th (0 ≤ k < 9) of the 3 × 3 cells around `home`, row by row from the lower left,
// or −1 where it lies outside the grid.
fn neighbour_cell(home: vec2<i32>, k: u32) -> i32 {
    let c = home + vec2<i32>(i32(k % 3u) - 1, i32(k / 3u) - 1);
    if c.x < 0 || c.y < 0 || c.x >= i32(params.nx) || c.y >= i32(params.ny) {
        return -1;
    }
    return c.y * i32(params.nx) + c.x;
}
