//! Retries of unsound steps: a step whose density solve left it unsound is redone from the
//! divergence-free velocities with half the Δt, a few times at most, and when every attempt is
//! unsound the least bad is taken. (Not in the paper; the safeguards are those of
//! [`SolverSettings`].) Every backend redoes its steps by these rules.

use crate::par::prelude::*;
use crate::parallel::LIGHT_PASS_MIN_ITEMS;
use glam::Vec2;

use crate::particles::FluidParticles;
use crate::pressure::{PressureSolver, SolveReport};
use crate::settings::SolverSettings;
use crate::solver;
use crate::step::StepContext;

/// The attempt a step takes.
#[derive(Clone, Copy, Debug)]
pub struct DensityStep {
    /// Its Δt, s.
    pub dt: f32,
    /// The density solve's report.
    pub report: SolveReport,
    /// How often the step was redone before.
    pub retries: u32,
}

/// What the checks of one attempt found.
#[derive(Clone, Copy, Debug)]
pub struct AttemptCheck {
    /// The solve reached its iteration cap with a particle compressed by more than
    /// [`SolverSettings::retry_density_error_pct`]. A solve that is merely slow to converge (a
    /// deep column building up its pressure) is not unsound: a smaller Δt cannot help it, since
    /// the compression it carries from earlier steps would be corrected over the shorter step
    /// with a proportionally larger velocity.
    pub overcompressed: bool,
    /// The largest compression the step's real positions carry beyond the solve's linear
    /// prediction, percent (`solver::unseen_compression`; 0 for a solver that predicts none).
    pub unseen_pct: f64,
    /// The largest distance a particle moves in the step, in particle spacings (infinite for a
    /// non-finite velocity).
    pub displacement: f32,
}

impl AttemptCheck {
    /// Check the attempt whose density solve `pressure` reported `report` and left its
    /// velocities in `fluid`.
    pub(crate) fn of(
        step: &StepContext,
        report: &SolveReport,
        pressure: &dyn PressureSolver,
        fluid: &FluidParticles,
    ) -> Self {
        let settings = step.settings;
        let rates = pressure.density_rates();
        Self {
            overcompressed: rates.is_some()
                && report.iterations >= settings.density.max_iterations
                && report.max_error_pct > settings.retry_density_error_pct,
            unseen_pct: rates.map_or(0.0, |rates| {
                100.0 * solver::unseen_compression(step, fluid, rates) as f64
            }),
            displacement: max_displacement(&fluid.velocity, step.dt, step.spacing),
        }
    }
}

/// The attempts at one step, and the rule that decides whether to redo it.
#[derive(Clone, Debug)]
pub struct Attempts {
    /// Δt of the current attempt, s.
    pub dt: f32,
    /// How often the step was redone so far.
    pub retries: u32,
    /// The scene's `time_step.min`, s.
    min_dt: f32,
    /// The unseen compression of the attempt before, percent.
    previous_unseen_pct: f64,
    /// (largest displacement in spacings, Δt) of the least bad unsound attempt.
    best: (f32, f32),
    /// Set for the last attempt, which is taken whatever its checks say.
    settle: bool,
}

impl Attempts {
    /// The first attempt at `dt`, s, in a scene whose shortest step is `min_dt`, s.
    pub fn new(dt: f32, min_dt: f32) -> Self {
        Self {
            dt,
            retries: 0,
            min_dt,
            previous_unseen_pct: f64::INFINITY,
            best: (f32::INFINITY, dt),
            settle: false,
        }
    }

    /// Whether the current attempt is taken whatever its checks say (the least bad of the
    /// unsound ones, redone).
    pub fn is_last(&self) -> bool {
        self.settle
    }

    /// Whether the attempt that `check` describes must be redone; if so, [`Self::dt`] is the
    /// next attempt's.
    ///
    /// It is unsound when the solve is overcompressed at its cap, when its unseen compression
    /// is above [`SolverSettings::max_unseen_compression_pct`] while each halving of Δt still
    /// cuts it (a particle pushed apart to undo compression it already carries moves about as
    /// far in a shorter step, its correction speed growing as Δt shrinks, so its share does not
    /// shrink), or when a particle would move more than
    /// [`SolverSettings::max_step_displacement`] spacings. Such a step is redone with half the
    /// Δt, but not below the scene's minimum unless it is the displacement that fails (a leak
    /// through a wall is worse than a short step), and at most
    /// [`SolverSettings::max_step_retries`] times; then the least bad attempt is taken.
    pub fn redo(&mut self, check: &AttemptCheck, settings: &SolverSettings) -> bool {
        let unseen = check.unseen_pct > settings.max_unseen_compression_pct
            && check.unseen_pct < settings.unseen_retry_gain * self.previous_unseen_pct;
        self.previous_unseen_pct = check.unseen_pct;
        let reach = settings.max_step_displacement;
        if !check.overcompressed && !unseen && check.displacement <= reach {
            return false;
        }
        if check.displacement < self.best.0 {
            self.best = (check.displacement, self.dt);
        }
        let floor = if check.displacement > reach {
            0.0
        } else {
            self.min_dt
        };
        if self.retries >= settings.max_step_retries || self.dt <= floor {
            if self.best.1 == self.dt {
                return false;
            }
            // Redo the least bad attempt: one more solve on this rare path rather than a copy
            // of the velocities and pressures of every attempt (12 bytes per particle, which
            // the 320k benchmark's memory budget does not have).
            self.dt = self.best.1;
            self.settle = true;
        } else {
            self.retries += 1;
            self.dt = (0.5 * self.dt).max(floor);
        }
        true
    }
}

/// The largest distance a particle moving at `velocity` travels in a step of `dt`, in
/// particle spacings `spacing` (infinite for a non-finite velocity). CFL keeps a normal step
/// at a fraction of a spacing; more than [`SolverSettings::max_step_displacement`] means the
/// pressure solve produced a kick the step size cannot carry.
pub fn max_displacement(velocity: &[Vec2], dt: f32, spacing: f32) -> f32 {
    let max2 = velocity
        .par_iter()
        .with_min_len(LIGHT_PASS_MIN_ITEMS)
        .map(|v| {
            if v.is_finite() {
                v.length_squared()
            } else {
                f32::INFINITY
            }
        })
        .reduce(|| 0.0, f32::max);
    max2.sqrt() * dt / spacing
}
