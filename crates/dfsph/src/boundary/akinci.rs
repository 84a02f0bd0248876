//! Akinci et al. (2012)'s wall term: a wall particle feels the fluid particle's own pressure
//! once, `Δv_i = −κ_i Σ_b Ψ_b ∇W_ib`. The paper's Jacobi solve and WCSPH use it.

use super::model::BoundaryModel;

/// Walls that feel each fluid particle's own pressure once (Akinci et al. 2012, eq. 10).
#[derive(Clone, Copy, Debug, Default)]
pub struct AkinciWalls;

impl BoundaryModel for AkinciWalls {
    fn gradient_weight(&self) -> f32 {
        1.0
    }
}
