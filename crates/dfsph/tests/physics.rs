//! Physics checks at small particle counts: rest state, hydrostatic tank, dam break, WCSPH.

use dfsph::kernel::KernelShape;
use dfsph::scene::{self, Method};
use dfsph::{Scene, Simulation, Snapshot};

fn coarse(name: &str, radius: f64) -> Scene {
    let mut s = scene::builtin(name).expect("built-in scene");
    s.particle_radius = radius;
    s
}

/// The largest |p − ρ0·g·(H − y)| / (ρ0·g·H) over the particles at least h = 2d from the
/// side walls, the floor and the free surface: the output pressure (`Snapshot::pressure`) of
/// water at rest, one particle at a time. H is the water's depth, half a spacing above the top
/// particle; `width` the tank's, from x = 0; `snap` a snapshot of `sim`.
fn interior_pressure_error(sim: &Simulation, snap: &Snapshot, width: f64) -> f64 {
    let (rho0, g) = (sim.rest_density() as f64, sim.gravity().length() as f64);
    let d = sim.spacing() as f64;
    let top = snap.position.iter().map(|p| p.y).fold(0.0f32, f32::max) as f64;
    let depth = top + 0.5 * d;
    let (mut worst, mut checked) = (0.0f64, 0);
    for (p, pr) in snap.position.iter().zip(&snap.pressure) {
        let (x, y) = (p.x as f64, p.y as f64);
        if x > 2.0 * d && x < width - 2.0 * d && y > 2.0 * d && y < top - 2.0 * d {
            worst = worst.max((*pr as f64 - rho0 * g * (depth - y)).abs() / (rho0 * g * depth));
            checked += 1;
        }
    }
    assert!(checked > 100, "only {checked} interior particles");
    worst
}

/// With either kernel: the walls are as many layers deep as the kernel reaches
/// (`boundary::wall_layers`), so water beside them reads ρ0 too.
#[test]
fn fluid_starts_at_rest_density() {
    let kernels = [KernelShape::CubicSpline, KernelShape::WendlandC2];
    for (name, kernel) in ["dam-break", "hydrostatic", "double-dam-break", "drop"]
        .into_iter()
        .flat_map(|n| kernels.map(|k| (n, k)))
    {
        let mut s = coarse(name, 0.02);
        s.solver.kernel = kernel;
        let sim = Simulation::new(&s).unwrap();
        let mut checked = 0;
        for (i, p) in sim.positions().iter().enumerate() {
            // Interior: farther than one kernel support from every block edge that is a free
            // surface (edges lying on a tank wall are not).
            let (x, y, h) = (p.x as f64, p.y as f64, s.support());
            let interior = s.fluid.iter().any(|b| {
                let inside = x > b.min[0] && x < b.max[0] && y > b.min[1] && y < b.max[1];
                let clear = |dist: f64, on_wall: bool| on_wall || dist > h;
                inside
                    && clear(x - b.min[0], b.min[0] <= s.tank.min[0])
                    && clear(b.max[0] - x, b.max[0] >= s.tank.max[0])
                    && clear(y - b.min[1], b.min[1] <= s.tank.min[1])
                    && clear(b.max[1] - y, b.max[1] >= s.tank.max[1])
            });
            if interior {
                let err = (sim.density_ratios()[i] - 1.0).abs();
                assert!(
                    err < 1.0e-3,
                    "{name}, {kernel:?}: particle at {p:?} starts {:.4} % off ρ0",
                    err * 100.0
                );
                checked += 1;
            }
        }
        assert!(
            checked > 100,
            "{name}: only {checked} interior particles checked"
        );
    }
}

#[test]
fn the_hydrostatic_tank_is_at_rest_from_the_first_step() {
    // The built-in tank (hexagonal packing, conjugate-gradient pressure solve with mirrored,
    // hydrostatic walls and a hydrostatic start), 777 particles, 1 m deep, for 10 s. The exact
    // answer is no motion at all: no step may be faster than 1 % of sqrt(gH); every 20th step,
    // each interior particle's output pressure is within 1 % of ρ0·g·H of ρ0·g·(H − y); and
    // the pressure averaged over bands over the last second is within 1 % (measured: −0.85 to
    // +0.23 %). (With the square lattice and the Jacobi solve the tank burst to 0.9 m/s and
    // took 3–9.5 s to settle.)
    let s = coarse("hydrostatic", 0.025);
    let mut sim = Simulation::new(&s).unwrap();
    let n0 = sim.fluid_count();
    let (rho0, g) = (1000.0f64, 9.81f64);
    let d = s.spacing();
    // The water's depth: half a spacing above the top row (the hexagonal rows, 0.93 d apart,
    // fill the 1 m block to 0.977 m).
    let top = sim.positions().iter().map(|p| p.y).fold(0.0f32, f32::max) as f64;
    let depth = top + 0.5 * d;
    assert!((0.97..1.0).contains(&depth), "{depth}");
    let limit = 0.01 * (g * depth).sqrt();
    // Pressure away from the walls and the free surface, against ρ0 g (H − y) at each
    // particle's own height, averaged over bands 0.1 m (two spacings) high and over the last
    // second (every 20th step).
    let mut bands = std::collections::BTreeMap::<i64, (f64, usize)>::new();
    let mut worst_particle = (0.0f64, 0.0f64);
    while sim.time() < 10.0 {
        let st = *sim.step();
        assert!(
            st.max_speed < limit,
            "{:.4} m/s at t = {:.3} s, 1 % of sqrt(gH) is {limit:.4}",
            st.max_speed,
            st.time
        );
        if !st.step.is_multiple_of(20) {
            continue;
        }
        let snap = sim.snapshot();
        let error = interior_pressure_error(&sim, &snap, s.tank.max[0]);
        if error > worst_particle.0 {
            worst_particle = (error, st.time);
        }
        if st.time >= 9.0 {
            for (p, pr) in snap.position.iter().zip(&snap.pressure) {
                let (x, y) = (p.x as f64, p.y as f64);
                if x > 0.3 && x < 1.7 && y > 0.3 && y < 0.9 {
                    let e = bands.entry((y / (2.0 * d)).floor() as i64).or_default();
                    e.0 += *pr as f64 - rho0 * g * (depth - y);
                    e.1 += 1;
                }
            }
        }
    }
    let stats = *sim.stats();
    assert!(stats.avg_density_error_pct <= 0.05, "{stats:?}");
    assert_eq!(sim.total_clamped(), 0);
    assert_eq!(sim.total_non_finite(), 0);
    assert_eq!(sim.fluid_count(), n0);
    assert!(
        worst_particle.0 < 0.01,
        "a particle's pressure {:.2} % of rho0 g H off at t = {:.2} s",
        100.0 * worst_particle.0,
        worst_particle.1
    );
    assert!(bands.len() >= 5);
    for (band, (sum, count)) in bands {
        let error = sum / count as f64;
        assert!(
            error.abs() < 0.01 * rho0 * g * depth,
            "band from y = {:.2} m: mean pressure error {error:.0} Pa",
            band as f64 * 2.0 * d
        );
    }
}

#[test]
fn the_drop_scenes_pool_is_still_when_the_drop_arrives() {
    // The built-in `drop`: a 0.6 m pool and a block falling into it, with the settings for
    // water at rest. Until the drop reaches the pool (t ≈ 0.4 s) no pool particle may move
    // faster than 1 % of sqrt(g·0.6 m). (With the square lattice and the Jacobi solve the
    // pool sloshed at 0.5 m/s.)
    let s = coarse("drop", 0.02);
    let mut sim = Simulation::new(&s).unwrap();
    let limit = 0.01 * (9.81f64 * 0.6).sqrt() as f32;
    let mut fastest = 0.0f32;
    while sim.time() < 0.3 {
        sim.step();
        for (p, v) in sim.positions().iter().zip(sim.velocities()) {
            if p.y < 0.6 {
                fastest = fastest.max(v.length());
            }
        }
    }
    assert!(fastest < limit, "{fastest} m/s, limit {limit}");
    assert_eq!(sim.total_clamped() + sim.total_non_finite(), 0);
}

/// Steps `sim` until `until` s: no step clamps, makes non-finite values or moves any particle
/// as fast as `limit` m/s (water at rest: 1 % of sqrt(gH)).
fn assert_stays_under(sim: &mut Simulation, until: f64, limit: f64) {
    while sim.time() < until {
        let st = *sim.step();
        assert_eq!(st.clamped + st.non_finite, 0, "{st:?}");
        assert!(st.max_speed < limit, "{st:?}");
    }
}

/// Water `width` m wide and `depth` m deep at d = 5 mm from wall to wall, at rest, in a tank
/// 1.25 times as high, from a scene file that names no solver settings.
fn column(width: f64, depth: f64) -> Scene {
    Scene::from_json(&format!(
        r#"{{"particle_radius": 0.0025, "tank": {{"min": [0, 0], "max": [{width}, {}]}},
            "fluid": [{{"min": [0, 0], "max": [{width}, {depth}]}}]}}"#,
        1.25 * depth
    ))
    .unwrap()
}

/// A column `depth` m deep and 0.1 m wide at d = 5 mm between two walls ([`column`]), on the default
/// settings (the hexagonal packing, the deflated conjugate-gradient solve, at most 100
/// iterations a step), run for 0.3 s: every step stays under 1 % of sqrt(gH), and at the end each interior
/// particle's output pressure is within 1 % of ρ0·g·H of ρ0·g·(H − y), and the pressure in
/// bands 0.1 m high within 3 %.
fn assert_column_stays_at_rest(depth: f64) {
    let s = column(0.1, depth);
    let (rho0, g) = (1000.0f64, 9.81f64);
    let limit = 0.01 * (g * depth).sqrt();
    let mut sim = Simulation::new(&s).unwrap();
    assert_stays_under(&mut sim, 0.3, limit);
    let snap = sim.snapshot();
    let error = interior_pressure_error(&sim, &snap, 0.1);
    assert!(
        error < 0.01,
        "a particle's pressure {:.2} % of rho0 g H off",
        100.0 * error
    );
    let mut bands = std::collections::BTreeMap::<i64, (f64, usize)>::new();
    for (p, pr) in snap.position.iter().zip(&snap.pressure) {
        let y = p.y as f64;
        if y < depth - 0.1 {
            let e = bands.entry((y / 0.1).floor() as i64).or_default();
            e.0 += *pr as f64 - rho0 * g * (depth - y);
            e.1 += 1;
        }
    }
    assert_eq!(bands.len(), (depth * 10.0).round() as usize - 1);
    for (band, (sum, count)) in bands {
        let error = sum / count as f64 / (rho0 * g * depth);
        assert!(
            error.abs() < 0.03,
            "band from y = {:.1} m: mean pressure error {:.2} % of rho0 g H",
            band as f64 * 0.1,
            100.0 * error
        );
    }
}

#[test]
fn a_column_200_layers_deep_stays_at_rest() {
    // 3,978 particles. Measured: 0.012 m/s against 0.031, bands +0.5 to +2.9 %.
    assert_column_stays_at_rest(1.0);
}

#[test]
fn a_column_300_layers_deep_stays_at_rest() {
    // 5,957 particles. Without deflation the solve needed more than 100 iterations in some
    // steps (its smoothest mode spans 300 layers) and the column was not held (0.12 m/s or
    // more within 0.5 s). Deflated: 0.0026 m/s over 0.3 s, 5.0 iterations a step, 8 at most.
    assert_column_stays_at_rest(1.5);
}

/// A drop of water falling into a pool 300 layers deep (0.3 m wide, 1.5 m deep at d = 5 mm,
/// conjugate gradients on the hexagonal packing): until the drop lands (it falls 0.5 m, about
/// 0.32 s), nothing has touched the pool, and every particle of it stays under 1 % of
/// sqrt(gH), on the default settings. The solve's stopping rule must not loosen because the drop is fast: with a rule
/// that also accepted 1 % of the fastest particle's speed the pool reached 0.46 m/s.
#[test]
fn a_pool_300_layers_deep_stays_at_rest_while_a_drop_falls_into_it() {
    // 13,466 particles; measured 0.0062 m/s, 5.1 iterations a step.
    let s = Scene::from_json(
        r#"{"particle_radius": 0.0025, "tank": {"min": [0, 0], "max": [0.3, 2.2]},
            "fluid": [{"min": [0, 0], "max": [0.3, 1.5]},
                      {"min": [0.12, 2.0], "max": [0.18, 2.06]}]}"#,
    )
    .unwrap();
    let limit = 0.01 * (9.81f32 * 1.5).sqrt();
    let mut sim = Simulation::new(&s).unwrap();
    let (mut fastest, mut most_iterations) = (0.0f32, 0);
    while sim.time() < 0.3 {
        let st = *sim.step();
        assert_eq!(st.clamped + st.non_finite, 0, "{st:?}");
        most_iterations = most_iterations.max(st.density_iterations);
        let pool = sim
            .positions()
            .iter()
            .zip(sim.velocities())
            .filter(|(p, _)| p.y < 1.55)
            .map(|(_, v)| v.length())
            .fold(0.0f32, f32::max);
        fastest = fastest.max(pool);
        // The drop is still in the air.
        assert!(
            sim.positions().iter().filter(|p| p.y > 1.55).count() > 100,
            "the drop landed by t = {}",
            st.time
        );
    }
    assert!(
        fastest < limit,
        "the pool moved at {fastest} m/s, limit {limit}"
    );
    // The deflated solve reaches all 300 layers at once: 14 iterations in its slowest step
    // (the diagonal preconditioner alone: 164).
    assert!(
        most_iterations <= 40,
        "a step took {most_iterations} iterations"
    );
}

/// An island in a pool: a box 0.1 m wide and 0.4 m high standing on the floor of a pool
/// 0.5 m wide and 0.6 m deep (d = 1 cm, hexagonal, conjugate gradients). The water beside
/// the box is at rest from the first step: every particle under 1 % of sqrt(gH) for 1 s. With
/// the box sampled on the square lattice next to the hexagonal water it reached 1.08 m/s.
#[test]
fn a_pool_with_an_island_on_its_floor_stays_at_rest() {
    // 2,584 particles; measured 0.0055 m/s, 4.0 iterations a step.
    let s = Scene::from_json(
        r#"{"particle_radius": 0.005, "tank": {"min": [0, 0], "max": [0.5, 0.8]},
            "fluid": [{"min": [0, 0], "max": [0.5, 0.6]}],
            "obstacles": [{"type": "rect", "min": [0.2, 0], "max": [0.3, 0.4]}]}"#,
    )
    .unwrap();
    let limit = 0.01 * (9.81f64 * 0.6).sqrt();
    let mut sim = Simulation::new(&s).unwrap();
    while sim.time() < 1.0 {
        let st = *sim.step();
        assert_eq!(st.clamped + st.non_finite, 0, "{st:?}");
        assert!(st.max_speed < limit, "{st:?}");
    }
}

/// A standing wave in a closed tank without actions (1 m wide, water 0.5 m deep, first mode,
/// amplitude 1 cm, d = 2 cm, hexagonal, conjugate gradients), started from the linear
/// mode's velocity field with a flat surface: over one period the mechanical energy of the
/// water never rises above its lowest value so far by more than the solver's tolerance lets
/// it, the water expanding by the average density tolerance δ, which lifts its centre of
/// mass by δ·H/2: `M·g·δ·H/2`.
#[test]
fn a_standing_wave_creates_no_energy_beyond_the_solver_tolerance() {
    let (h, amp, g) = (0.5f64, 0.01f64, 9.81f64);
    let base = r#""particle_radius": 0.01, "tank": {"min": [0, 0], "max": [1, 0.8]}"#;
    let block = Scene::from_json(&format!(
        r#"{{{base}, "fluid": [{{"min": [0, 0], "max": [1, {h}]}}]}}"#
    ))
    .unwrap();
    let k = std::f64::consts::PI;
    let omega = (g * k * (k * h).tanh()).sqrt();
    let (mut positions, mut velocities) = (Vec::new(), Vec::new());
    for p in Simulation::new(&block).unwrap().positions() {
        let (x, y) = (p.x as f64, p.y as f64);
        let s = amp * omega / (k * h).sinh();
        positions.push(format!("[{x}, {y}]"));
        velocities.push(format!(
            "[{}, {}]",
            -s * (k * x).sin() * (k * y).cosh(),
            s * (k * x).cos() * (k * y).sinh()
        ));
    }
    let s = Scene::from_json(&format!(
        r#"{{{base}, "fluid": [], "particles": {{"positions": [{}], "velocities": [{}]}}}}"#,
        positions.join(", "),
        velocities.join(", ")
    ))
    .unwrap();
    let mut sim = Simulation::new(&s).unwrap();
    let mass = sim.particle_mass() as f64 * sim.fluid_count() as f64;
    let allowed = mass * g * (s.solver.density_tolerance_pct / 100.0) * h / 2.0;
    let wave = 0.25 * mass / h * g * amp * amp;
    let mut lowest = sim.mechanical_energy();
    let mut worst = 0.0f64;
    while sim.time() < 2.0 * std::f64::consts::PI / omega {
        let st = *sim.step();
        assert_eq!(st.clamped + st.non_finite, 0, "{st:?}");
        let e = sim.mechanical_energy();
        worst = worst.max(e - lowest);
        lowest = lowest.min(e);
    }
    println!("rise {worst} J/m, allowed {allowed} J/m, wave energy {wave} J/m");
    assert!(
        worst <= allowed,
        "the energy rose by {worst} J/m, allowed {allowed}"
    );
}

/// Martin & Moyce (1952), Table 2, column height 2a: (T, Z) with T = t·sqrt(2g/a) and
/// Z = x_front/a (`shared/validation/martin_moyce_1952_front_n2_a2p25in.csv`).
const MARTIN_MOYCE_FRONT: [(f64, f64); 11] = [
    (1.19, 1.44),
    (1.43, 1.67),
    (1.63, 1.89),
    (1.83, 2.11),
    (1.98, 2.33),
    (2.20, 2.56),
    (2.32, 2.78),
    (2.51, 3.00),
    (2.65, 3.22),
    (2.83, 3.44),
    (2.98, 3.67),
];

/// Time shift applied to the simulation before comparing with Martin & Moyce: the experiment
/// released the column by lifting a gate, the simulation releases it instantly. The
/// validation data's README gives ΔT ≈ 0.1–0.2 as customary; we take 0.2 (about 45 ms for
/// the 1 m column). Without it the front is 9–17 % ahead.
const MARTIN_MOYCE_TIME_SHIFT: f64 = 0.2;

#[test]
fn dam_break_front_follows_martin_and_moyce() {
    let s = coarse("dam-break", 0.025);
    let a = 1.0; // column width, m
    let time_scale = (2.0 * 9.81f64 / a).sqrt();
    let mut sim = Simulation::new(&s).unwrap();
    let mut front = vec![(0.0, 1.0)];
    while sim.time() * time_scale < 3.0 {
        sim.step();
        front.push((sim.time() * time_scale, sim.front_position(3).unwrap() / a));
    }
    for (t, z) in MARTIN_MOYCE_FRONT {
        let shifted = t - MARTIN_MOYCE_TIME_SHIFT;
        let ours = front.iter().find(|p| p.0 >= shifted).unwrap().1;
        assert!(
            (ours / z - 1.0).abs() < 0.10,
            "T = {t}: Z = {ours:.3}, Martin & Moyce {z}"
        );
    }
}

#[test]
fn an_oversized_time_step_is_redone_not_taken() {
    // With a 20 ms cap the first steps of a dam break ask the density solve for more than it
    // can give in 100 iterations; the step must be redone with smaller Δt, not taken broken.
    let mut s = coarse("dam-break", 0.025);
    s.time_step.max = 0.02;
    s.time_step.cfl = 1.0;
    let mut sim = Simulation::new(&s).unwrap();
    let mut retried = 0;
    while sim.time() < 0.5 {
        let st = *sim.step();
        retried += st.retries;
        assert!(st.dt <= 0.02);
        assert_eq!(st.clamped, 0, "leak at t = {}", st.time);
        assert_eq!(st.non_finite, 0);
        if st.retries > 0 {
            assert!(st.dt < 0.02, "{st:?}");
        }
    }
    assert!(retried > 0, "no step was redone");
    assert!(sim.positions().iter().all(|p| p.is_finite()));
}

#[test]
fn a_still_tank_under_a_one_second_cap_steps_by_gravity_and_pressure() {
    // Nothing moves at t = 0, so the velocity CFL alone would take the whole 1 s cap (and
    // its retries 0.5 s down to 62 ms): the water would drop metres in one step. The gravity
    // bound √(λ·d/|g|) takes over. It bounds the motion, not the pressure solve: a 45 ms step
    // at r = 2.5 cm is still far too long for it (docs/scenes.md; the step may be redone
    // shorter for its unseen compression), so only finiteness is asked of the steps that
    // follow. The pressure's bound on Δt (`PRESSURE_WAVE_STABILITY`, 9.5 ms for the 0.98 m
    // of water) is the tighter one here; both must hold.
    let mut s = coarse("hydrostatic", 0.025);
    s.time_step.max = 1.0;
    let gravity_bound = (s.time_step.cfl * s.spacing() / 9.81).sqrt();
    let mut sim = Simulation::new(&s).unwrap();
    let extent = sim.positions().iter().map(|p| p.y).fold(0.0f32, f32::max)
        - sim
            .positions()
            .iter()
            .map(|p| p.y)
            .fold(f32::INFINITY, f32::min);
    let pressure_bound = f64::from(dfsph::simulation::PRESSURE_WAVE_STABILITY) * s.spacing()
        / (9.81 * (f64::from(extent) + s.spacing())).sqrt();
    assert!(pressure_bound < gravity_bound / 2.0);
    let bound = gravity_bound.min(pressure_bound);
    let first = *sim.step();
    let attempted = first.dt * f64::from(1u32 << first.retries);
    assert!(
        (attempted - bound).abs() <= 1.0e-4 * bound,
        "first Δt {} after {} retries, against the bound {bound}",
        first.dt,
        first.retries
    );
    for _ in 0..20 {
        let st = *sim.step();
        assert!(st.dt <= bound * 1.0001, "Δt {} above {bound}", st.dt);
        assert_eq!(st.non_finite, 0);
    }
    assert!(sim.positions().iter().all(|p| p.is_finite()));
}

#[test]
fn a_fine_wide_column_starts_without_a_kick() {
    // Lobovsky et al.'s 0.6 m x 0.3 m column at r = 2.5 mm (7,200 particles): the first
    // steps' density solves reach their cap while the pressure builds up through 60 layers.
    // Redoing those steps with a smaller dt used to correct the compression they carried over
    // the shorter step, with a proportionally larger velocity: 8.6 m/s at t = 0.05 s and a
    // spray over the whole tank. Falling from 0.3 m, nothing should be faster than ~2.4 m/s.
    run_column_at_fine_resolution([1.61, 0.6], [0.6, 0.3], 0.1, 2.5);
}

/// A column `fluid` (m) in the corner of a tank `tank` (m) at r = 2.5 mm, run for `until`
/// seconds: no step may leak or go non-finite, none may be as fast as `max_speed`.
fn run_column_at_fine_resolution(tank: [f64; 2], fluid: [f64; 2], until: f64, max_speed: f64) {
    let s = Scene::from_json(&format!(
        r#"{{"particle_radius": 0.0025, "tank": {{"min": [0, 0], "max": {tank:?}}},
            "fluid": [{{"min": [0, 0], "max": {fluid:?}}}]}}"#
    ))
    .unwrap();
    let mut sim = Simulation::new(&s).unwrap();
    while sim.time() < until {
        let st = *sim.step();
        assert_eq!(st.clamped + st.non_finite, 0, "{st:?}");
        assert!(st.max_speed < max_speed, "{st:?}");
    }
}

#[test]
fn dam_break_runs_one_second_without_leaks() {
    let s = coarse("dam-break", 0.025);
    let mut sim = Simulation::new(&s).unwrap();
    let n0 = sim.fluid_count();
    while sim.time() < 1.0 {
        let st = sim.step();
        assert!(st.max_speed.is_finite() && st.kinetic_energy.is_finite());
        assert_eq!(
            st.clamped, 0,
            "a particle went through a wall at t = {}",
            st.time
        );
        assert_eq!(st.non_finite, 0);
    }
    assert_eq!(sim.fluid_count(), n0);
    assert!(sim.positions().iter().all(|p| p.is_finite()));
    // The surge has reached the far wall (4 m) by 1 s.
    assert!(sim.front_position(3).unwrap() > 3.5);
}

#[test]
fn wcsph_hydrostatic_tank_does_not_blow_up() {
    let mut s = coarse("hydrostatic", 0.025);
    s.solver.method = Method::Wcsph;
    let mut sim = Simulation::new(&s).unwrap();
    while sim.time() < 0.5 {
        sim.step();
    }
    let st = *sim.stats();
    assert!(st.max_speed < 1.0, "{st:?}");
    assert!(st.max_density_error_pct < 5.0, "{st:?}");
    assert_eq!(sim.total_non_finite(), 0);
    assert!(sim.positions().iter().all(|p| p.y < 1.2));
}

#[test]
fn overlapping_fluid_is_pushed_apart_gently() {
    // Two blocks placed a third of a spacing into each other: the particles along the seam
    // start strongly compressed. With 0.1 ms steps, undoing that in one step threw them apart
    // at 100 m/s; the density solve now removes existing compression no faster than
    // `SolverSettings::max_correction_speed` per step. On the hexagonal lattice the blocks
    // share the sites of the seam, each taken once (`packing::rows_of_boxes`); taken twice,
    // particles sat on top of each other and were thrown apart at 5 m/s in the first step.
    for (packing, pressure_solve) in [("square", "jacobi"), ("hexagonal", "conjugate_gradient")] {
        let s = Scene::from_json(&format!(
            r#"{{"particle_radius": 0.01, "tank": {{"min": [0, 0], "max": [2, 1]}},
                "fluid": [{{"min": [0, 0], "max": [0.5, 0.4]}},
                          {{"min": [0.4933, 0], "max": [0.9933, 0.4]}}],
                "packing": "{packing}", "solver": {{"pressure_solve": "{pressure_solve}"}},
                "time_step": {{"max": 0.0001}}}}"#
        ))
        .unwrap();
        let mut sim = Simulation::new(&s).unwrap();
        let mut max_speed = 0.0f64;
        for _ in 0..200 {
            let st = *sim.step();
            assert_eq!(st.clamped + st.non_finite, 0, "{packing}: {st:?}");
            max_speed = max_speed.max(st.max_speed);
        }
        // Uncapped: 103 m/s. Capped: about 6 m/s (corrections of successive steps add up
        // before the seam has opened).
        println!("{packing}: {max_speed} m/s");
        assert!(
            max_speed < 10.0,
            "{packing}: pushed apart at {max_speed} m/s"
        );
    }
}

#[test]
fn a_very_viscous_tank_at_rest_stays_at_rest() {
    // ν = 0.2 m²/s at d = 4 cm: the explicit viscosity is stable only below
    // 0.125·d²/ν = 1 ms, and this scene allows steps of 2.5 ms. Before the viscous bound on
    // Δt the resting tank reached 34 m/s.
    let mut s = coarse("hydrostatic", 0.02);
    s.viscosity.kinematic = 0.2;
    s.viscosity.boundary_kinematic = 0.2;
    s.time_step.max = 0.0025;
    s.time_step.cfl = 0.6;
    let bound = 0.125 * s.spacing().powi(2) / 0.2;
    let mut sim = Simulation::new(&s).unwrap();
    while sim.time() < 0.5 {
        let st = *sim.step();
        assert!(
            st.dt <= bound * 1.0001,
            "Δt {} over the viscous bound {bound}",
            st.dt
        );
        assert!(st.max_speed < 0.5, "{st:?}");
    }
}

/// XSPH and the viscosity act in one explicit update: at the largest smoothing the scene
/// format allows and 100 times honey, the dam break stays slower than free fall from the
/// column's top (√(2gH) = 6.3 m/s). With each model's step bound alone it reached 16 m/s
/// (28 m/s at the smoothing of 1 that the format allowed before).
#[test]
fn xsph_and_a_viscosity_together_are_stable_over_the_documented_range() {
    let mut s = coarse("dam-break", 0.025);
    s.viscosity.xsph = scene::MAX_XSPH;
    s.viscosity.kinematic = 1.0;
    s.viscosity.boundary_kinematic = 1.0;
    let mut sim = Simulation::new(&s).unwrap();
    let mut fastest = 0.0f64;
    while sim.time() < 0.5 {
        let st = *sim.step();
        assert_eq!(st.clamped + st.non_finite, 0, "{st:?}");
        fastest = fastest.max(st.max_speed);
    }
    assert!(fastest < (2.0 * 9.81 * 2.0f64).sqrt(), "{fastest} m/s");
    s.viscosity.xsph = scene::MAX_XSPH * 1.01;
    let e = s.validate().unwrap_err().to_string();
    assert!(e.starts_with("`viscosity.xsph`: 0.505 exceeds 0.5"), "{e}");
}

#[test]
fn a_deep_column_at_the_benchmark_time_step_does_not_burst() {
    // The narrow 400-layer column below at docs/BENCHMARK.md's solver settings (tolerance 0.01 %,
    // CFL 0.2, Δt up to 5 ms), 0.3 s. The first steps are long enough that the density solve's
    // linear prediction misses several percent of compression in the bottom rows, every step;
    // before steps checked their linearisation (`solver::unseen_compression`) the rows burst:
    // 19.5 m/s and 431 J/m. With the check: 1.8 m/s and 10 J/m. (Still not at rest; see the
    // ignored test below.)
    let s = Scene::from_json(
        r#"{"particle_radius": 0.0025, "tank": {"min": [0, 0], "max": [0.1, 2.5]},
            "fluid": [{"min": [0, 0], "max": [0.1, 2.0]}],
            "solver": {"density_tolerance_pct": 0.01},
            "time_step": {"cfl": 0.2, "max": 0.005}}"#,
    )
    .unwrap();
    let mut sim = Simulation::new(&s).unwrap();
    while sim.time() < 0.3 {
        let st = *sim.step();
        assert_eq!(st.clamped + st.non_finite, 0, "{st:?}");
        assert!(st.max_speed < 3.0 && st.kinetic_energy < 40.0, "{st:?}");
    }
}

#[test]
fn a_deep_narrow_column_stays_at_rest() {
    // 20 x 400 particles (0.1 m x 2 m at d = 5 mm) at rest between two walls, from a scene
    // file that names no solver settings. The exact answer is no motion at all: anything
    // faster than 1 % of sqrt(gH) is spurious. Every scene gets the hexagonal packing and the
    // deflated conjugate-gradient solve by default, with the default cap of 100 iterations;
    // on the square lattice with the Jacobi solve the column fell into its bottom rows and
    // sloshed at 1–3.5 m/s (docs/deep-columns.md). Before the pressure's bound on Δt
    // (`PRESSURE_WAVE_STABILITY`) it burst at the default 1 ms steps (13 m/s); with it the
    // steps are 0.68 ms and the largest speed is about 0.009 m/s.
    let s = column(0.1, 2.0);
    assert_eq!(s.packing, scene::Packing::Hexagonal);
    assert_eq!(
        s.solver.pressure_solve,
        scene::PressureSolve::ConjugateGradient
    );
    let limit = 0.01 * (9.81f64 * 2.0).sqrt();
    let mut sim = Simulation::new(&s).unwrap();
    assert_stays_under(&mut sim, 0.3, limit);
    let error = interior_pressure_error(&sim, &sim.snapshot(), 0.1);
    assert!(
        error < 0.01,
        "a particle's pressure {:.2} % of rho0 g H off",
        100.0 * error
    );
}

#[test]
fn a_column_1000_layers_deep_stays_at_rest() {
    // 10 x 1,000 layers (0.05 m x 5 m at d = 5 mm, 9,675 particles) at rest between two walls,
    // from a scene file that names no solver settings. Its first step's solve used to remove
    // the lattice's own density scatter (a few 10^-6 of rho0) at once: a smooth pressure of
    // about rho0 delta H^2 / dt^2, 3.6 % of rho0 g H in that step, and the column burst to
    // 98 m/s within 10 ms. With `SolverSettings::compression_dead_band`: 0.0096 m/s over
    // 0.5 s, 9.7 iterations a step. Not checked here: the pressure near the floor drifts up
    // while the water stays still (10-13 % of rho0 g H by 0.2-0.5 s in this narrow column,
    // 2-3 % in one 0.1 m wide; docs/deep-columns.md, "1,000 layers").
    let s = column(0.05, 5.0);
    let limit = 0.01 * (9.81f64 * 5.0).sqrt();
    let mut sim = Simulation::new(&s).unwrap();
    assert_stays_under(&mut sim, 0.2, limit);
}

/// A droplet thrown at a wall does not bounce back elastically: water does not. The pressure
/// that stops it is a one-off; carried into the next steps by a warm start applied to every
/// particle it threw the droplet back (a lone particle thrown at the ceiling at 10 m/s left
/// it at 3.8–9.5 m/s, median 6.3, depending on where its last step before the wall ended;
/// splashes in the dam break's far corner then flew across the tank at 11–14 m/s and set the
/// CFL step). The impact's phase matters, so ten start offsets a fifth of a spacing apart;
/// both walls a jet meets, the ceiling and a side wall.
#[test]
fn a_droplet_thrown_at_a_wall_does_not_bounce_back() {
    for (at, velocity) in [([2.0, 2.0], [0.0, 10.0]), ([3.0, 1.5], [10.0, 0.0])] {
        let mut rebounds = Vec::new();
        for k in 0..10 {
            let offset = 0.002 * k as f64;
            let (x, y) = (
                at[0] + offset * velocity[0] / 10.0,
                at[1] + offset * velocity[1] / 10.0,
            );
            let json = format!(
                r#"{{"particle_radius": 0.01, "gravity": [0, 0],
                    "tank": {{"min": [0, 0], "max": [4, 3]}}, "fluid": [],
                    "particles": {{"positions": [[{x}, {y}]], "velocities": [{velocity:?}]}}}}"#
            );
            let scene = Scene::from_json(&json).unwrap();
            let mut sim = Simulation::new(&scene).unwrap();
            assert_eq!(sim.fluid_count(), 1);
            // It reaches the wall within 0.1 s; afterwards its speed away from the wall is
            // the rebound.
            while sim.time() < 0.2 {
                sim.step();
            }
            let v = sim.velocities()[0];
            rebounds.push(-(v.x * velocity[0] as f32 + v.y * velocity[1] as f32) / 10.0);
            assert_eq!(sim.total_clamped(), 0, "went through the wall");
        }
        rebounds.sort_by(f32::total_cmp);
        let (median, largest) = (rebounds[rebounds.len() / 2], rebounds[rebounds.len() - 1]);
        assert!(
            median < 1.0 && largest < 5.0,
            "thrown at {velocity:?} m/s, left the wall at {rebounds:?} m/s"
        );
    }
}

/// The stop flag (`Simulation::set_stop_flag`, Ctrl-C in `run` and Python) ends the pressure
/// solves, conjugate gradients or Jacobi, at their next iteration: a deep scene's step, which
/// may run to thousands of iterations, ends within one. Cleared, the solve runs as before.
#[test]
fn the_stop_flag_ends_the_density_solve_of_either_kind() {
    use dfsph::scene::PressureSolve;
    use std::sync::atomic::{AtomicBool, Ordering};
    use std::sync::Arc;
    let stop = Arc::new(AtomicBool::new(false));
    for solve in [PressureSolve::ConjugateGradient, PressureSolve::Jacobi] {
        let mut s = coarse("hydrostatic", 0.02);
        s.solver.min_iterations = 5;
        s.solver.pressure_solve = solve;
        let mut sim = Simulation::new(&s).unwrap();
        sim.set_stop_flag(Arc::clone(&stop));
        assert!(sim.step().density_iterations >= 5, "{solve:?}");
        stop.store(true, Ordering::Relaxed);
        let stopped = *sim.step();
        assert_eq!(stopped.density_iterations, 0, "{solve:?}");
        assert_eq!(stopped.divergence_iterations, 0, "{solve:?}");
        stop.store(false, Ordering::Relaxed);
        assert!(sim.step().density_iterations >= 5, "{solve:?}");
        // A reset keeps the flag, as it keeps the memory limit.
        assert_eq!(
            sim.apply(&dfsph::Action::Reset { scene: None }).rejected,
            None
        );
        stop.store(true, Ordering::Relaxed);
        assert_eq!(sim.step().density_iterations, 0, "{solve:?}");
        stop.store(false, Ordering::Relaxed);
    }
}

/// The clock counts 1 ms steps as 0.001 s each (not the single-precision step's
/// 0.0010000000474974513), and `has_reached` ends a loop after exactly the steps that
/// reach a target, however the double-precision sum rounds.
#[test]
fn the_clock_counts_the_steps_decimals_and_reaches_targets_on_time() {
    // Water at rest: every step is the 1 ms cap.
    let s = Scene::from_json(
        r#"{"particle_radius": 0.025, "tank": {"min": [0, 0], "max": [1, 1]},
            "fluid": [{"min": [0, 0], "max": [1, 0.5]}], "time_step": {"max": 0.001}}"#,
    )
    .unwrap();
    let mut sim = Simulation::new(&s).unwrap();
    for target in [0.1, 0.2, 1.5] {
        let before = sim.step_count();
        while !sim.has_reached(target) {
            sim.step();
        }
        assert_eq!(sim.stats().dt, 0.001);
        assert!(
            (sim.time() - target).abs() < 1e-12,
            "{} at {target}",
            sim.time()
        );
        assert_eq!(
            sim.step_count(),
            (target * 1000.0).round() as u64,
            "after {before} steps, t = {}",
            sim.time()
        );
    }
}
