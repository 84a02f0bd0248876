// The types a step's passes share (src/step/layout.rs has the same layouts in Rust).

// The step's state on the device, written by its passes: Δt, the solve in progress and the
// solves' reports. `clock` is a uniform copy of it, taken where Δt changes.
struct Control {
    // This step's Δt and the previous step's, s.
    dt: f32,
    last_dt: f32,
    // The solve at hand goes on, and its iterations so far.
    running: u32,
    iterations: u32,
    // Its average and largest error, percent, now and one iteration before.
    avg: f32,
    max_err: f32,
    prev_avg: f32,
    prev_max: f32,
    // The increments applied last made the error grow: take them back (from the buffer of
    // parity `take_back_parity`).
    take_back: u32,
    take_back_parity: u32,
    // The reports: the divergence solve's iterations and average error, the density solve's
    // iterations, average and largest error.
    div_iterations: u32,
    div_avg: f32,
    den_iterations: u32,
    den_avg: f32,
    den_max: f32,
    // The step the CFL condition and every bound give, before `dt_cap`, s.
    cfl_dt: f32,
    // The largest compression the step carries beyond the density solve's prediction
    // (relative to ρ0; `unseen_*.wgsl`).
    unseen: f32,
    // Whether the divergence and the density solve would have gone on after the last
    // iteration the host recorded (copied from the dispatch sizes after each solve).
    div_unfinished: u32,
    den_unfinished: u32,
    pad0: u32,
}

// One Jacobi solve's constants (TVCG 2017, Algorithm 2 or 3; `dfsph::pressure::jacobi`).
struct Solve {
    // 0: the divergence solve (Dρ/Dt = 0), 1: the density solve (ρ* = ρ0).
    density: u32,
    min_iterations: u32,
    max_iterations: u32,
    // The warm start applies only where a particle is compressed before it.
    gated: u32,
    tolerance_pct: f32,
    max_error_pct: f32,
    // An iteration whose average error exceeds this multiple of the one before (plus the
    // tolerance) is taken back and ends the solve.
    growth: f32,
    // Share of the previous step's stiffness the solve starts from (0: no warm start).
    warm_share: f32,
    // The divergence solve leaves out particles with fewer neighbours.
    min_neighbours: f32,
    // The fastest the density solve undoes existing compression over the spacing d
    // (`max_correction_speed`/d), 1/s.
    max_correction_rate: f32,
    // Workgroups of the residual pass (256 particles each) and of the others (64).
    partials: u32,
    groups: u32,
    // Fluid particles.
    n: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

// Which of the two increment buffers a bind group holds, and what the pass does with it:
// the apply pass applies it (0) or takes it back (1); the control pass runs after the first
// residual pass (1) or after an iteration (0).
struct Slot {
    parity: u32,
    mode: u32,
    pad0: u32,
    pad1: u32,
}

// The step's constants from the host: forces, the time step's bounds, the tank.
struct StepConsts {
    gravity: vec2<f32>,
    pointer_at: vec2<f32>,
    // The tank's interior and the box a particle stays in unless it went through a wall, m.
    tank_lo: vec2<f32>,
    tank_hi: vec2<f32>,
    outer_lo: vec2<f32>,
    outer_hi: vec2<f32>,
    // The tank's velocity, m/s.
    wall_v: vec2<f32>,
    // The pointer's reach, m, and strength, m/s² (0: none).
    pointer_radius: f32,
    pointer_strength: f32,
    // XSPH's coefficient, 8ν and 8ν_b (the Laplacian viscosity and the walls' friction),
    // and the Laplacian's regularisation 0.01h², m².
    xsph: f32,
    laplace: f32,
    friction: f32,
    eps2: f32,
    // The CFL number, the scene's shortest step and the step's upper bound, s.
    cfl: f32,
    dt_min: f32,
    dt_upper: f32,
    // The acceleration bound of the displacement limit, m/s², not counting a pull.
    accel: f32,
    // The fastest wall, m/s; whether the pointer pulls (it damps by 4|v| at most).
    wall_speed: f32,
    pulls: u32,
    // The farthest a particle may travel in one step, m, and the spacing d, m.
    reach: f32,
    spacing: f32,
    // Workgroups of the speed pass (256 particles each).
    partials: u32,
    // The longest step allowed after the bounds, s: a retry's shorter Δt, or the limit
    // a recent retry left (infinite otherwise).
    dt_cap: f32,
    // The slope of the mirrored walls' hydrostatic ghost pressure, g/c (m/s²; zero for
    // Akinci's walls): `dfsph::forces` (`GhostPressure`), added by `wall_forces.wgsl`.
    ghost_slope: vec2<f32>,
}

// The conjugate-gradient density solve's constants (`dfsph::pressure::conjugate_gradient`).
struct CgSolve {
    min_iterations: u32,
    max_iterations: u32,
    // Start from the previous step's pressure (1) or from zero (0).
    warm: u32,
    // Fluid particles.
    n: u32,
    // The stopping rule: average and largest density error, percent of ρ0.
    tolerance_pct: f32,
    max_error_pct: f32,
    // A step that makes the largest error exceed this multiple of the one before (plus
    // `max_error_pct`) is taken back and ends the solve.
    growth: f32,
    // A particle with fewer neighbours (fluid and walls) carries no pressure.
    min_neighbours: f32,
    // The fastest existing compression is undone, over the spacing d, 1/s.
    max_correction_rate: f32,
    // Compression left uncorrected, relative to ρ0.
    dead_band: f32,
    // The lattice's gradient consistency c: the stored pressure is c·κ/Δt.
    consistency: f32,
    // The velocity rule: the density tolerance over the spacing (m; over Δt a speed), and
    // the share of the gravity impulse g·Δt (m/s², 0 for none).
    density_speed: f32,
    gravity_impulse: f32,
    // Workgroups of the 256-wide passes and of the 64-wide ones.
    partials: u32,
    groups: u32,
    // The aggregates' width (m; 0: no deflation, `dfsph::pressure::deflation`).
    coarse_cell: f32,
}

// The deflation's coarse space on the device (`coarse_*.wgsl`): square cells `cell` wide
// from `origin` (the lower corner of the water that carries pressure), `cells` along x and
// y, every cell an aggregate, numbered along the shorter side (`coarse_key`); `band` is
// the half bandwidth of the coarse matrix E in that numbering.
struct Coarse {
    origin: vec2<f32>,
    cell: f32,
    count: u32,
    cells: vec2<u32>,
    band: u32,
    pad0: u32,
}

// The conjugate-gradient solve's state on the device (`cg_*.wgsl`).
struct CgState {
    // r·z, the step length along the search direction, the next direction's β, and the
    // r·z below which the solve stops (round-off of the one it started from).
    rz: f32,
    alpha: f32,
    beta: f32,
    round_off: f32,
    // α_k·(r_k·z_k) of the last four iterations: Δt times their squared velocity changes.
    energy: vec4<f32>,
    // Particles that carry pressure (at least 1), and the average and largest error, percent.
    n_active: f32,
    avg: f32,
    max_err: f32,
    // The solve goes on; iterations done; the last step is to be taken back; energies
    // recorded.
    running: u32,
    iterations: u32,
    take_back: u32,
    energies: u32,
    // Workgroups of the per-aggregate passes (0 without deflation).
    coarse_groups: u32,
}
