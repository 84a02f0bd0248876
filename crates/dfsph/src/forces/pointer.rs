//! The user's pointer: a force field around a point that pushes fluid away or pulls it in.

use glam::Vec2;
use serde::{Deserialize, Serialize};

use super::model::{AccelerationModel, Particle};

/// A force field around a point that the user drags: it pushes fluid away from `at`
/// (`strength > 0`) or pulls it in (`strength < 0`), fading linearly to zero at `radius`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct PointerForce {
    /// Centre, m.
    pub at: Vec2,
    /// Reach, m.
    pub radius: f32,
    /// Peak acceleration at the centre, m/s² (positive pushes, negative pulls).
    pub strength: f32,
}

/// The largest pointer acceleration the simulation accepts, m/s² (about 8 g): strong enough to
/// throw water across the tank, weak enough that the CFL step stays reasonable.
pub const MAX_POINTER_ACCELERATION: f32 = 80.0;

impl PointerForce {
    /// Whether it acts at all (a reach and a strength).
    pub fn acts(&self) -> bool {
        self.radius > 0.0 && self.strength != 0.0
    }
}

impl AccelerationModel for PointerForce {
    fn add_to(&self, p: &Particle, acc: &mut Vec2) {
        let r = p.position - self.at;
        let dist = r.length();
        if dist < self.radius {
            let fade = 1.0 - dist / self.radius;
            let dir = if dist > 1.0e-6 { r / dist } else { Vec2::ZERO };
            let strength = self
                .strength
                .clamp(-MAX_POINTER_ACCELERATION, MAX_POINTER_ACCELERATION);
            *acc += dir * strength * fade;
            // A pull also damps the motion relative to the pointer, so water gathers under
            // the cursor instead of orbiting it.
            if strength < 0.0 {
                *acc -= p.velocity * (fade * 4.0);
            }
        }
    }
}
