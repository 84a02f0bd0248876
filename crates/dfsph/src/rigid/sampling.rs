//! Boundary particles on a rigid body, in the body's own frame (Akinci et al. 2012, §3): as
//! many layers inside the outline as the walls have ([`crate::boundary::wall_layers`]), at
//! d/2, 3d/2, … from it (layers that would pass the body's middle are left out), so that
//! fluid pressed against the body
//! has its centres d/2 outside the outline, as it has against the tank's walls. The volumes
//! Ψ_b come from the body's own samples ([`crate::boundary::volumes`]'s rule), so they do not
//! change as the body moves.

use glam::Vec2;

use crate::boundary::{volumes, wall_layers, wall_volume_correction};
use crate::kernel::Kernel;
use crate::neighbors::Grid;

use super::spec::BodySpec;

/// The body's boundary particles in its frame (relative to its position, unrotated) and
/// their volumes Ψ_b, m².
pub fn sample(spec: &BodySpec, d: f32, kernel: &Kernel) -> (Vec<Vec2>, Vec<f32>) {
    let mut local = Vec::new();
    for layer in 0..wall_layers(kernel, d) {
        let depth = (layer as f32 + 0.5) * d;
        match spec.polygon() {
            Some(outline) => {
                let outline: Vec<Vec2> = outline
                    .iter()
                    .map(|p| Vec2::new(p[0] as f32, p[1] as f32))
                    .collect();
                let inner = inset(&outline, depth);
                // Past the middle the moved edges turn round: the body is thinner there.
                if layer > 0 && !same_turn(&outline, &inner) {
                    break;
                }
                sample_polygon(&inner, d, &mut local);
            }
            None => {
                let r = spec.radius.unwrap_or(0.0) as f32 - depth;
                if layer > 0 && r < 0.0 {
                    break;
                }
                let count = ((std::f32::consts::TAU * r / d).round() as usize).max(3);
                for k in 0..count {
                    let a = std::f32::consts::TAU * k as f32 / count as f32;
                    local.push(r * Vec2::new(a.cos(), a.sin()));
                }
            }
        }
    }
    let mut grid = Grid::new(kernel.support());
    let order = grid.build(&local).to_vec();
    let mut volume = vec![0.0; local.len()];
    volumes(
        &grid,
        kernel,
        wall_volume_correction(kernel, d),
        &mut volume,
    );
    // The grid sorted the particles: put the volumes back in sampling order.
    let mut by_sample = vec![0.0; local.len()];
    for (sorted, &original) in order.iter().enumerate() {
        by_sample[original as usize] = volume[sorted];
    }
    (local, by_sample)
}

/// A convex counter-clockwise polygon moved inwards by `depth` (each edge along its inward
/// normal; the vertices where the moved edges meet).
fn inset(outline: &[Vec2], depth: f32) -> Vec<Vec2> {
    let n = outline.len();
    let normal = |k: usize| {
        let e = (outline[(k + 1) % n] - outline[k]).normalize_or_zero();
        Vec2::new(-e.y, e.x)
    };
    (0..n)
        .map(|k| {
            let (n1, n2) = (normal((k + n - 1) % n), normal(k));
            outline[k] + depth * (n1 + n2) / (1.0 + n1.dot(n2)).max(1.0e-3)
        })
        .collect()
}

/// Whether no edge of `inner` runs against the same edge of `outline` (an inset polygon that
/// has not passed the outline's middle; one that reaches it exactly, a body three spacings
/// thick, collapses to a line and is kept).
fn same_turn(outline: &[Vec2], inner: &[Vec2]) -> bool {
    let n = outline.len();
    (0..n).all(|k| {
        let e = outline[(k + 1) % n] - outline[k];
        let f = inner[(k + 1) % n] - inner[k];
        e.dot(f) >= -1.0e-3 * e.length_squared()
    })
}

/// Particles along a closed polygon at spacing ≈ d, one on every vertex.
fn sample_polygon(polygon: &[Vec2], d: f32, out: &mut Vec<Vec2>) {
    let n = polygon.len();
    for k in 0..n {
        let (a, b) = (polygon[k], polygon[(k + 1) % n]);
        let count = ((b - a).length() / d).round().max(1.0) as usize;
        for s in 0..count {
            out.push(a + (b - a) * (s as f32 / count as f32));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_box_is_two_layers_inside_its_outline_at_the_spacing() {
        let d = 0.02;
        let kernel = Kernel::cubic_spline(2.0 * d);
        let spec = BodySpec::new_box([0.4, 0.2], 500.0, [1.0, 1.0]);
        let (local, volume) = sample(&spec, d, &kernel);
        // Outer layer: a 0.38 x 0.18 rectangle, 19 + 9 + 19 + 9 samples; inner: 0.34 x 0.14.
        assert_eq!(local.len(), 56 + 48);
        for p in &local {
            let inside = 0.2 - p.x.abs();
            let inside_y = 0.1 - p.y.abs();
            let depth = inside.min(inside_y);
            assert!(
                (depth - 0.5 * d).abs() < 1e-5 || (depth - 1.5 * d).abs() < 1e-5,
                "{p} at depth {depth}"
            );
        }
        // Along a straight side the volume is the fluid's, d² (within the lattice's rounding).
        let mid = local
            .iter()
            .position(|p| p.y < -0.08 && p.x.abs() < 0.011)
            .unwrap();
        assert!(
            (volume[mid] / (d * d) - 1.0).abs() < 0.05,
            "{}",
            volume[mid]
        );
    }

    #[test]
    fn a_circle_has_rings_at_half_and_one_and_a_half_spacings_in() {
        let d = 0.01;
        let kernel = Kernel::cubic_spline(2.0 * d);
        let spec = BodySpec::new_circle(0.1, 250.0, [1.0, 1.0]);
        let (local, volume) = sample(&spec, d, &kernel);
        let outer = local
            .iter()
            .filter(|p| (p.length() - 0.095).abs() < 1e-5)
            .count();
        let inner = local
            .iter()
            .filter(|p| (p.length() - 0.085).abs() < 1e-5)
            .count();
        assert_eq!(outer + inner, local.len());
        assert_eq!(outer, (std::f32::consts::TAU * 0.095 / d).round() as usize);
        assert!(volume.iter().all(|&v| v > 0.5 * d * d && v < 1.5 * d * d));
    }
}
