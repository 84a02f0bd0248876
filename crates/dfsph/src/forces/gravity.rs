//! Gravity: the same acceleration on every particle.

use glam::Vec2;

use super::model::{AccelerationModel, Particle};

/// A uniform body force per unit mass, m/s².
pub(crate) struct Gravity(pub Vec2);

impl AccelerationModel for Gravity {
    fn add_to(&self, _: &Particle, acc: &mut Vec2) {
        *acc += self.0;
    }
}
