//! How far one step may carry a particle: the bound every step obeys and the scene
//! validator checks before any simulation exists.

/// Largest displacement in one step, in particle spacings, before the step is redone. Fluid
/// at rest sits d/2 inside the tank, and the wall's first layer d/2 outside: a step longer
/// than d/2 can carry a particle from next to the wall into the wall. At 1 d, `dfsph2d stress
/// --seed 0` leaked at step 5,202 (a particle thrown into the floor at 19 m/s, 0.69 d in its
/// last step); at d/2 it passes 20,000 steps. Normal flows rarely come near it (one retry in
/// 1.5 s of the default dam break, none in the 5k benchmark). A constant as well as a setting:
/// the scene validator bounds `time_step.min` with it before any simulation exists
/// ([`step_displacement_bound`]).
pub const MAX_STEP_DISPLACEMENT: f32 = 0.5;

/// The longest Δt in which a particle moving at `speed` (m/s) under an `acceleration` (m/s²)
/// travels at most [`MAX_STEP_DISPLACEMENT`] particle spacings (`spacing` = d, m):
/// `speed·Δt + ½·acceleration·Δt² ≤ MAX_STEP_DISPLACEMENT·d`, the positive root
/// `Δt = 2R / (v + √(v² + 2aR))` with `R = MAX_STEP_DISPLACEMENT·d`. Infinite when nothing
/// moves or accelerates. Every step is at most this (see `Simulation::step`), so no step
/// carries water from beside a wall through it; the scene validator refuses a
/// `time_step.min` above it at the start (the blocks' initial speeds under gravity).
pub fn step_displacement_bound(speed: f64, acceleration: f64, spacing: f64) -> f64 {
    let reach = f64::from(MAX_STEP_DISPLACEMENT) * spacing;
    let speed = speed.max(0.0);
    let denominator = speed + (speed * speed + 2.0 * acceleration.max(0.0) * reach).sqrt();
    if denominator > 0.0 {
        2.0 * reach / denominator
    } else {
        f64::INFINITY
    }
}
