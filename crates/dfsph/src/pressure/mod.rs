//! Pressure solvers, one per file, behind `PressureSolver`: the paper's DFSPH by Jacobi
//! iterations ([`jacobi`]), its density solve by conjugate gradients
//! (`conjugate_gradient`), and the WCSPH baseline (`wcsph`). The scene's `solver.method`
//! and `solver.pressure_solve` choose one (`for_scene`); a new solver is its file and a line
//! there.
//!
//! Every solver works on the step's cached pressure terms (`crate::solver`): the density rate
//! `Dρ_i/Dt/ρ0` (`solver::density_rates`) and the velocity change of a stiffness field κ
//! (`solver::apply_pressure`).

use crate::scene::{Method, PressureSolve, Scene};

pub(crate) mod conjugate_gradient;
mod deflation;
mod hydrostatic;
pub mod jacobi;
mod solve;
pub(crate) mod wcsph;

pub use deflation::MIN_CELL_SUPPORTS;
pub use hydrostatic::hydrostatic_pressure;
pub(crate) use solve::PressureSolver;
pub use solve::SolveReport;

/// The solver the scene's `solver.method` and `solver.pressure_solve` name. `gradient_consistency`
/// is the lattice's ([`crate::packing::gradient_consistency`]).
pub(crate) fn for_scene(scene: &Scene, gradient_consistency: f32) -> Box<dyn PressureSolver> {
    match (scene.solver.method, scene.solver.pressure_solve) {
        (Method::Dfsph, PressureSolve::Jacobi) => Box::new(jacobi::Jacobi::default()),
        (Method::Dfsph, PressureSolve::ConjugateGradient) => Box::new(
            conjugate_gradient::ConjugateGradient::new(gradient_consistency),
        ),
        (Method::Wcsph, _) => Box::new(wcsph::Wcsph::from_scene(scene)),
    }
}
