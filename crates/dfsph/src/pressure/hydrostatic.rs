//! The pressure of water at rest, the density solve's first guess.

use glam::Vec2;

/// p/ρ0 of fluid at rest under `gravity` (pointing down the y axis; zero otherwise):
/// `|g|·(y_s − y)`, where the free surface `y_s` lies half a spacing above the top particle of
/// the unbroken run of particles above each particle in its column of width `d` (a gap of more
/// than 2.5 spacings, wider than the hexagonal lattice's two rows, breaks a run: a drop above a
/// pool does not weigh on it).
pub fn hydrostatic_pressure(position: &[Vec2], gravity: Vec2, d: f32) -> Vec<f32> {
    let mut out = vec![0.0; position.len()];
    if gravity.x != 0.0 || gravity.y >= 0.0 {
        return out;
    }
    let mut columns = std::collections::HashMap::<i64, Vec<usize>>::new();
    for (i, p) in position.iter().enumerate() {
        columns.entry((p.x / d).floor() as i64).or_default().push(i);
    }
    for (_, mut idx) in columns {
        idx.sort_by(|&a, &b| position[b].y.total_cmp(&position[a].y));
        let mut surface = f32::NAN;
        let mut last = f32::INFINITY;
        for i in idx {
            let y = position[i].y;
            if last - y > 2.5 * d {
                surface = y + 0.5 * d;
            }
            last = y;
            out[i] = -gravity.y * (surface - y);
        }
    }
    out
}
