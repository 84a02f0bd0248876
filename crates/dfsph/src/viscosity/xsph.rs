//! XSPH velocity smoothing (Monaghan 1989), as an acceleration over the step as in
//! SPlisHSPlasH: `a_i += (c/Δt) Σ_j V_j (v_j − v_i) W_ij`, c dimensionless (0 = off,
//! typically 0.01–0.1). It pulls each particle's velocity a share c of the way towards its
//! neighbours' kernel average each step, which damps particle-scale noise; fluid–fluid pairs
//! only.

use glam::Vec2;

use super::model::ViscosityModel;
use crate::forces::model::{AccelerationModel, Particle};
use crate::scene::ViscosityParams;

/// XSPH smoothing with coefficient c.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Xsph {
    /// c, dimensionless (the scene's `viscosity.xsph`).
    pub coefficient: f32,
}

impl Xsph {
    pub fn from_scene(params: &ViscosityParams) -> Self {
        Self {
            coefficient: params.xsph as f32,
        }
    }
}

impl ViscosityModel for Xsph {
    /// `c/Δt`, 1/s, times `V Σ_j (v_j − v_i) W_ij`.
    fn pair_scale(&self, dt: f32) -> f32 {
        self.coefficient / dt
    }
}

impl AccelerationModel for Xsph {
    /// `V·(c/Δt)·Σ_j (v_j − v_i) W_ij`, from the step's fluid pair sums.
    fn add_to(&self, p: &Particle, acc: &mut Vec2) {
        *acc += p.step.volume * (self.pair_scale(p.step.dt) * p.smooth);
    }
}
