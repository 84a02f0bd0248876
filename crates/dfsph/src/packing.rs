//! The hexagonal lattice that fluid blocks and tank walls are sampled on with
//! `"packing": "hexagonal"` (see [`crate::scene::Packing`]).
//!
//! Why hexagonal. Under pressure a square lattice of SPH particles is not a stable
//! arrangement: each particle sits on top of the one below, with no restoring force against
//! sliding sideways into the gap, so a tank at rest rearranges itself into the hexagonal packing
//! and sloshes for seconds while it does (docs/deep-columns.md). The hexagonal lattice is the
//! packing pressure forces hold in place.
//!
//! The lattice has the same area per particle as the square lattice of spacing d, d², so the
//! same volume of fluid holds the same number of particles: spacing `s = d·√(2/√3) ≈ 1.0746 d`
//! along a row, rows `s·√3/2 ≈ 0.9306 d` apart, odd rows shifted by `s/2`. Its first row lies
//! `d/2` above the anchor (the tank's lower-left corner) and even rows start `d/2` right of
//! it. The tank's walls are the sites of the same lattice outside the tank's interior, so the
//! fluid next to a wall sees the lattice continue (the wall is ragged by half a spacing along
//! the sides).

use glam::Vec2;

/// Spacing along a row, in units of d: `√(2/√3)`.
pub const ROW_SPACING: f64 = 1.074_569_931_823_542;
/// Distance between rows, in units of d: `ROW_SPACING·√3/2`.
pub const ROW_DISTANCE: f64 = 0.930_604_859_102_099_7;

/// One row of lattice sites inside a box: `count` sites from `(x0, y)` in steps of the row
/// spacing.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Row {
    pub y: f64,
    pub x0: f64,
    pub count: usize,
    /// The row's index (0 is the first row above the anchor) and its first site's index
    /// along the row: a lattice site is the pair (row, index).
    pub j: i64,
    pub i0: i64,
}

/// The rows of the hexagonal lattice of spacing `d` anchored at `anchor` that have sites in
/// the closed box `[lo, hi]` (widened by `tolerance` on every side, for rounding in scene
/// files).
pub fn rows(anchor: [f64; 2], lo: [f64; 2], hi: [f64; 2], d: f64, tolerance: f64) -> Vec<Row> {
    let (s, dy) = (ROW_SPACING * d, ROW_DISTANCE * d);
    let (lo_x, lo_y) = (lo[0] - tolerance, lo[1] - tolerance);
    let (hi_x, hi_y) = (hi[0] + tolerance, hi[1] + tolerance);
    let first = anchor[1] + 0.5 * d;
    let j0 = ((lo_y - first) / dy).ceil() as i64;
    let j1 = ((hi_y - first) / dy).floor() as i64;
    (j0..=j1)
        .filter_map(|j| {
            let y = first + j as f64 * dy;
            let offset = anchor[0] + 0.5 * d + 0.5 * s * j.rem_euclid(2) as f64;
            let i0 = ((lo_x - offset) / s).ceil() as i64;
            let i1 = ((hi_x - offset) / s).floor() as i64;
            (i1 >= i0).then(|| Row {
                y,
                x0: offset + i0 as f64 * s,
                count: (i1 - i0 + 1) as usize,
                j,
                i0,
            })
        })
        .collect()
}

/// The sites of [`rows`], as positions.
pub fn sites(anchor: [f64; 2], lo: [f64; 2], hi: [f64; 2], d: f64, tolerance: f64) -> Vec<Vec2> {
    rows(anchor, lo, hi, d, tolerance)
        .into_iter()
        .flat_map(|r| row_sites(r, d))
        .collect()
}

/// The sites of several boxes `[lo, hi]` (closed, widened by `tolerance`), each lattice site
/// once, as (the index of the box it belongs to, the row the box holds it in, its index along
/// that row): a site inside more than one box belongs to the first that holds it. Fluid blocks
/// may overlap by less than a spacing (`Scene::validate`), and two blocks that share an edge
/// both reach the sites on it; taken twice, the two particles would sit on top of each
/// other, where the kernel's gradient vanishes and no pressure can part them (two blocks
/// overlapping by a third of a spacing were thrown apart at 5 m/s in their first step).
pub fn rows_of_boxes(
    anchor: [f64; 2],
    boxes: &[([f64; 2], [f64; 2])],
    d: f64,
    tolerance: f64,
) -> Vec<(usize, Row)> {
    let s = ROW_SPACING * d;
    // The site intervals [first, last] taken so far, by row.
    let mut taken: std::collections::HashMap<i64, Vec<(i64, i64)>> = Default::default();
    let mut out = Vec::new();
    for (k, (lo, hi)) in boxes.iter().enumerate() {
        for row in rows(anchor, *lo, *hi, d, tolerance) {
            let last = row.i0 + row.count as i64 - 1;
            let claimed = taken.entry(row.j).or_default();
            claimed.sort_unstable();
            // The parts of [row.i0, last] outside every claimed interval.
            let mut next = row.i0;
            for &(a, b) in claimed.iter() {
                if a > next {
                    let end = (a - 1).min(last);
                    if end >= next {
                        out.push((k, sub_row(&row, next, end, s)));
                    }
                }
                next = next.max(b + 1);
                if next > last {
                    break;
                }
            }
            if next <= last {
                out.push((k, sub_row(&row, next, last, s)));
            }
            claimed.push((row.i0, last));
        }
    }
    out
}

/// The sites `first..=last` (indices along the row) of `row`, whose sites are `s` apart.
fn sub_row(row: &Row, first: i64, last: i64, s: f64) -> Row {
    Row {
        y: row.y,
        x0: row.x0 + (first - row.i0) as f64 * s,
        count: (last - first + 1) as usize,
        j: row.j,
        i0: first,
    }
}

/// The positions of a row's sites.
pub fn row_sites(row: Row, d: f64) -> impl Iterator<Item = Vec2> {
    let s = ROW_SPACING * d;
    (0..row.count).map(move |i| Vec2::new((row.x0 + i as f64 * s) as f32, row.y as f32))
}

/// `Σ_j W(x_i − x_j)` over the infinite hexagonal lattice of [`rows`] (the particle itself
/// included): the reciprocal of the volume that puts the lattice at rest density.
pub fn kernel_sum(kernel: &crate::kernel::Kernel, d: f32) -> f32 {
    let reach = (kernel.support() / (ROW_DISTANCE as f32 * d)).ceil() as i32 + 1;
    lattice_offsets(d, reach)
        .map(|x| kernel.w(x.length()) as f64)
        .sum::<f64>() as f32
}

/// The hexagonal lattice's sites around one at the origin, out to `reach` rows.
fn lattice_offsets(d: f32, reach: i32) -> impl Iterator<Item = Vec2> {
    let (s, dy) = (ROW_SPACING as f32 * d, ROW_DISTANCE as f32 * d);
    (-reach..=reach).flat_map(move |j| {
        (-reach..=reach)
            .map(move |i| Vec2::new((i as f32 + 0.5 * j.rem_euclid(2) as f32) * s, j as f32 * dy))
    })
}

/// How much of a linear field's gradient the SPH gradient `Σ_j V (p_j − p_i) ∇W_ij` recovers
/// on an infinite lattice of particle volume `volume`: it gives `c·∇p`, with
/// `c = −½ Σ_j V |x_ij| W'(|x_ij|)` (isotropic on the hexagonal and the square lattice), where
/// `offsets` are the lattice sites around one at the origin. On the hexagonal lattice at
/// h = 2d, c = 0.981: a pressure field pushes 1.9 % less than its gradient says, so the
/// solve's stiffness field at rest is 1/c times ρ0·g·(H − y) (docs/deep-columns.md).
pub fn gradient_consistency(
    kernel: &crate::kernel::Kernel,
    volume: f32,
    offsets: impl Iterator<Item = Vec2>,
) -> f32 {
    let sum: f64 = offsets
        .map(|x| -(volume as f64) * x.dot(kernel.grad_w(x)) as f64)
        .sum();
    (0.5 * sum) as f32
}

/// [`gradient_consistency`] of the hexagonal lattice of spacing `d`.
pub fn hexagonal_gradient_consistency(kernel: &crate::kernel::Kernel, d: f32, volume: f32) -> f32 {
    let reach = (kernel.support() / (ROW_DISTANCE as f32 * d)).ceil() as i32 + 1;
    gradient_consistency(kernel, volume, lattice_offsets(d, reach))
}

/// [`gradient_consistency`] of the square lattice of spacing `d`.
pub fn square_gradient_consistency(kernel: &crate::kernel::Kernel, d: f32, volume: f32) -> f32 {
    let reach = (kernel.support() / d).ceil() as i32 + 1;
    let offsets = (-reach..=reach)
        .flat_map(|j| (-reach..=reach).map(move |i| Vec2::new(i as f32 * d, j as f32 * d)));
    gradient_consistency(kernel, volume, offsets)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_sph_gradient_recovers_98_percent_of_a_linear_field_on_the_lattice() {
        let d = 0.01;
        let kernel = crate::kernel::Kernel::cubic_spline(2.0 * d);
        let volume = 1.0 / kernel_sum(&kernel, d);
        let c = hexagonal_gradient_consistency(&kernel, d, volume);
        // Against a direct sum of the SPH gradient of p = x and p = y at a lattice site.
        let reach = 4;
        let (gx, gy) = lattice_offsets(d, reach).fold((Vec2::ZERO, Vec2::ZERO), |(gx, gy), x| {
            let grad = kernel.grad_w(-x);
            (gx + volume * x.x * grad, gy + volume * x.y * grad)
        });
        assert!(
            (gx.x - c).abs() < 1e-4 && (gy.y - c).abs() < 1e-4,
            "{gx} {gy} {c}"
        );
        assert!(gx.y.abs() < 1e-4 && gy.x.abs() < 1e-4, "{gx} {gy}");
        assert!((0.975..0.985).contains(&c), "{c}");
    }

    #[test]
    fn the_constants_give_the_square_lattices_area_per_particle() {
        assert!((ROW_SPACING * ROW_DISTANCE - 1.0).abs() < 1e-12);
        assert!((ROW_DISTANCE / ROW_SPACING - 3f64.sqrt() / 2.0).abs() < 1e-12);
    }

    #[test]
    fn a_block_holds_about_its_area_over_d_squared() {
        let d = 0.02;
        let n: usize = rows([0.0, 0.0], [0.0, 0.0], [1.0, 2.0], d, 1e-9)
            .iter()
            .map(|r| r.count)
            .sum();
        // 5,000 sites of area d² fill 2 m²; the edges cost at most a row and a column.
        assert!((4850..=5050).contains(&n), "{n}");
        let pts = sites([0.0, 0.0], [0.0, 0.0], [1.0, 2.0], d, 1e-9);
        assert_eq!(pts.len(), n);
        let (s, dy) = ((ROW_SPACING * d) as f32, (ROW_DISTANCE * d) as f32);
        // Nearest neighbours one row spacing away, along the row and on the rows above.
        let p = pts[60];
        let mut near: Vec<f32> = pts
            .iter()
            .map(|q| (*q - p).length())
            .filter(|&r| r > 0.0)
            .collect();
        near.sort_by(f32::total_cmp);
        assert!(
            (near[0] - s).abs() < 1e-5 && (near[5] - s).abs() < 1e-5,
            "{near:?}"
        );
        assert!(pts
            .iter()
            .all(|q| q.x >= 0.0 && q.x <= 1.0 && q.y >= 0.0 && q.y <= 2.0));
        assert!((pts[0].y - 0.5 * d as f32).abs() < 1e-6 && dy > 0.0);
    }

    #[test]
    fn blocks_that_share_an_edge_or_overlap_take_each_site_once() {
        let d = 0.02;
        let all = |boxes: &[([f64; 2], [f64; 2])]| -> Vec<Vec2> {
            rows_of_boxes([0.0, 0.0], boxes, d, 1e-9)
                .into_iter()
                .flat_map(|(_, r)| row_sites(r, d))
                .collect()
        };
        let one = all(&[([0.0, 0.0], [1.0, 0.5])]);
        assert_eq!(one, sites([0.0, 0.0], [0.0, 0.0], [1.0, 0.5], d, 1e-9));
        // The same water as two blocks sharing the edge x = 0.5 (where sites lie), three
        // blocks overlapping by a third of a spacing, or a block inside another.
        for boxes in [
            vec![([0.0, 0.0], [0.5, 0.5]), ([0.5, 0.0], [1.0, 0.5])],
            vec![
                ([0.0, 0.0], [0.5, 0.5]),
                ([0.4933, 0.0], [1.0, 0.5]),
                ([0.0, 0.4933], [1.0, 0.5]),
            ],
            vec![([0.0, 0.0], [1.0, 0.5]), ([0.2, 0.1], [0.3, 0.2])],
        ] {
            let mut got = all(&boxes);
            assert_eq!(got.len(), one.len(), "{boxes:?}");
            got.sort_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
            assert!(
                got.windows(2)
                    .all(|w| (w[1] - w[0]).length() > 0.5 * d as f32),
                "{boxes:?}"
            );
        }
        // The first block that holds a site keeps it.
        let owners = rows_of_boxes(
            [0.0, 0.0],
            &[([0.0, 0.0], [1.0, 0.5]), ([0.2, 0.1], [0.3, 0.2])],
            d,
            1e-9,
        );
        assert!(owners.iter().all(|(k, _)| *k == 0));
    }
}
