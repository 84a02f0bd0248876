//! The one thing every wall model answers: how wall particles enter the pressure terms
//! ([`super::AkinciWalls`], [`super::MirroredWalls`]).

use glam::Vec2;

/// How wall particles enter the pressure terms of the fluid next to them. Their share of the
/// density, `Σ_b Ψ_b W_ib`, is the same in every model.
pub trait BoundaryModel: Send + Sync {
    /// What multiplies the walls' share of the gradient sum `Σ_b Ψ_b ∇W_ib` and of the wall
    /// flux `Σ_b Ψ_b v_b·∇W_ib` (dimensionless): the density rate, the pressure push and the
    /// DFSPH factor alike, so the pressure operator stays symmetric whatever the weight.
    fn gradient_weight(&self) -> f32;

    /// The gradient of p/ρ0 (m/s²) that the walls' ghost particles add to the fluid
    /// particle's own pressure, `p_b = p_i + ρ0·g_p·(x_b − x_i)`, under `gravity`; `None` when
    /// the ghosts carry the particle's pressure alone.
    fn hydrostatic_ghost_gradient(&self, gravity: Vec2) -> Option<Vec2> {
        let _ = gravity;
        None
    }
}
