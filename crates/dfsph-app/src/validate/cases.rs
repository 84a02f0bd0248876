//! The validation cases. Each runs one or more simulations and returns report sections:
//! text, plots and checks. Tolerances come from the issue and from the experimental scatter;
//! they are stated beside every check and never tuned to make a run pass.

use std::fmt::Write;

use anyhow::Result;
use dfsph::scene::{self, FluidBlock, Method, Probe, Tank};
use dfsph::Scene;

use super::case::{completion_check, interp, simulate, CaseReport, Check, Settings, Trace};
use super::data;
use super::plot::{Plot, Series, Style};
use super::report::run_table;

/// |g|, m/s² (the scenes' default gravity).
const G: f64 = 9.81;
/// ρ0, kg/m³.
const RHO0: f64 = 1000.0;

fn pct(v: f64) -> String {
    format!("{v:.1} %")
}

/// Largest relative deviation |sim/exp − 1| over the data points that the simulation covers,
/// in percent, with the abscissa where it occurs; and the number of points compared.
fn worst_relative(sim_x: &[f64], sim_y: &[f64], exp: &[(f64, f64)]) -> (f64, f64, usize) {
    let mut worst = (f64::NAN, f64::NAN, 0usize);
    for &(x, y) in exp {
        let s = interp(sim_x, sim_y, x);
        if !s.is_finite() {
            continue;
        }
        let dev = ((s / y) - 1.0).abs() * 100.0;
        worst.2 += 1;
        if worst.0.is_nan() || dev > worst.0 {
            worst = (dev, x, worst.2);
        }
    }
    worst
}

/// Check "every point within `limit` %": the worst deviation and where it is.
fn front_check(
    case: &str,
    name: &str,
    sim_x: &[f64],
    sim_y: &[f64],
    exp: &[(f64, f64)],
    limit: f64,
    xname: &str,
) -> Check {
    let (dev, at, n) = worst_relative(sim_x, sim_y, exp);
    let mut c = Check::at_most(case, name, if n == 0 { f64::NAN } else { dev }, limit, pct);
    if n > 0 {
        c.value = format!("{} (worst of {n} points, at {xname} = {at:.2})", pct(dev));
    } else {
        c.value = "no data point within the simulated time".into();
    }
    // Within 10 % of an experiment takes the full resolution.
    c.full_run_only()
}

fn rms(values: impl Iterator<Item = f64>) -> f64 {
    let (s, n) = values
        .filter(|v| v.is_finite())
        .fold((0.0, 0usize), |(s, n), v| (s + v * v, n + 1));
    if n == 0 {
        f64::NAN
    } else {
        (s / n as f64).sqrt()
    }
}

// ---------------------------------------------------------------------------------------
// Hydrostatic tank
// ---------------------------------------------------------------------------------------

/// The hydrostatic case's radius and duration, s.
fn hydrostatic_run(s: Settings) -> (f64, f64) {
    if s.quick {
        (0.025, 2.0)
    } else {
        (0.01, 15.0)
    }
}

/// Heights of the hydrostatic tank's interior pressure probes, m.
const HYDROSTATIC_HEIGHTS: [f64; 5] = [0.05, 0.25, 0.5, 0.75, 0.9];

/// The built-in hydrostatic tank at radius `r` with the case's probes.
fn hydrostatic_scene(r: f64) -> Scene {
    let mut scene = scene::builtin("hydrostatic").expect("built-in");
    scene.particle_radius = r;
    let heights = HYDROSTATIC_HEIGHTS;
    let mut probes: Vec<Probe> = heights
        .iter()
        .map(|&y| Probe::Pressure {
            name: format!("p_x1_y{y}"),
            at: [1.0, y],
        })
        .collect();
    probes.push(Probe::Pressure {
        name: "p_floor".into(),
        at: [1.0, 0.0],
    });
    probes.push(Probe::Pressure {
        name: "p_left_wall_y0.25".into(),
        at: [0.0, 0.25],
    });
    probes.push(Probe::WaterLevel {
        name: "level_x1".into(),
        x: 1.0,
    });
    scene.probes = probes;
    scene
}

/// Every scene `validate` runs with these settings, to check their memory before any runs
/// (`dfsph2d validate --max-memory`).
pub fn scenes(s: Settings) -> Vec<Scene> {
    let mut all = vec![hydrostatic_scene(hydrostatic_run(s).0)];
    for r in dam_radii(s) {
        all.push(dam_scene(r, Method::Dfsph));
    }
    all.push(dam_scene(dam_radii(s)[1], Method::Wcsph));
    all.push(lobovsky_scene(lobovsky_run(s).0));
    all
}

pub fn hydrostatic(s: Settings) -> Result<Vec<CaseReport>> {
    const CASE: &str = "Hydrostatic";
    // The built-in tank starts on the hexagonal packing with a hydrostatic pressure and the
    // conjugate-gradient solve, and is at rest from the first step. (On the square lattice
    // with the Jacobi solve it rearranged in bursts for 3–9.5 s.) 15 s at r = 1 cm checks that
    // it stays at rest.
    let (r, until) = hydrostatic_run(s);
    let depth = 1.0;
    let scene = hydrostatic_scene(r);
    let probes = scene.probes.clone();
    let (trace, sim) = simulate(s, "hydrostatic", &scene, until)?;
    let completed = completion_check(CASE, &trace, until);

    // Averages over the last quarter of the run.
    let from = 0.75 * until;
    let late: Vec<usize> = (0..trace.t.len()).filter(|&i| trace.t[i] >= from).collect();
    let mean_of =
        |k: usize| late.iter().map(|&i| trace.probes[i][k]).sum::<f64>() / late.len().max(1) as f64;
    let p_ref = RHO0 * G * depth;
    let mut checks = Vec::new();
    let mut probe_points = Vec::new();
    let mut rows = String::from(
        "| probe | position (m) | mean reading, last quarter | ρ0·g·(H − y) | error / (ρ0·g·H) | std of the readings / (ρ0·g·H) |\n|---|---|---|---|---|---|\n",
    );
    for (k, p) in probes.iter().enumerate() {
        let Probe::Pressure { name, at } = p else {
            continue;
        };
        let mean = mean_of(k);
        let std = (late
            .iter()
            .map(|&i| (trace.probes[i][k] - mean).powi(2))
            .sum::<f64>()
            / late.len().max(1) as f64)
            .sqrt();
        let expected = RHO0 * G * (depth - at[1]);
        let err = (mean - expected).abs() / p_ref * 100.0;
        probe_points.push((at[1], mean / 1000.0));
        let _ = writeln!(
            rows,
            "| `{name}` | ({}, {}) | {:.0} Pa | {:.0} Pa | {:.2} % | {:.1} % |",
            at[0],
            at[1],
            mean,
            expected,
            err,
            std / p_ref * 100.0
        );
        checks.push(
            Check::at_most(
                CASE,
                format!(
                    "pressure at `{name}` ({}, {}) m against ρ0·g·(H − y)",
                    at[0], at[1]
                ),
                err,
                2.0,
                |v| format!("{v:.2} % of ρ0·g·H"),
            )
            // A probe's kernel sum at r = 2.5 cm reaches the floor and the free surface: 2 % of
            // ρ0·g·H needs the full resolution.
            .full_run_only(),
        );
    }
    let level = mean_of(probes.len() - 1);
    checks.push(completed);

    // Mean density error of the particles more than h below the surface, final state.
    let h = scene.support();
    let ratios = sim.density_ratios();
    let interior: Vec<f64> = sim
        .positions()
        .iter()
        .zip(ratios)
        .filter(|(x, _)| (x.y as f64) < depth - h)
        .map(|(_, &q)| ((q as f64) - 1.0).abs() * 100.0)
        .collect();
    let mean_density_err = interior.iter().sum::<f64>() / interior.len().max(1) as f64;
    checks.push(Check::at_most(
        CASE,
        "mean |ρ/ρ0 − 1| of the particles more than h below the surface, final state",
        mean_density_err,
        0.1,
        |v| format!("{v:.3} %"),
    ));

    // Each interior particle's output pressure (CSV/VTK), final state, against ρ0·g·(H − y)
    // of the water's real depth, half a spacing above its top particle.
    let d = scene.spacing();
    let width = scene.tank.max[0] - scene.tank.min[0];
    let top = sim
        .positions()
        .iter()
        .map(|x| x.y as f64)
        .fold(0.0, f64::max);
    let real_depth = top + 0.5 * d;
    let worst_particle = sim
        .positions()
        .iter()
        .zip(sim.interpolated_pressures_over_rho0())
        .filter(|(x, _)| {
            let (x, y) = (x.x as f64 - scene.tank.min[0], x.y as f64);
            x > h && x < width - h && y > h && y < top - h
        })
        .map(|(x, p)| (p as f64 * RHO0 - RHO0 * G * (real_depth - x.y as f64)).abs())
        .fold(0.0, f64::max)
        / (RHO0 * G * real_depth)
        * 100.0;
    checks.push(Check::at_most(
        CASE,
        "output pressure of every particle at least h from the walls and the surface, final \
         state, against ρ0·g·(H − y) (H half a spacing above the top particle)",
        worst_particle,
        1.0,
        |v| format!("{v:.2} % of ρ0·g·H"),
    ));

    // At rest from the first step: no step faster than 1 % of sqrt(gH).
    let ke: Vec<f64> = trace.stats.iter().map(|s| s.kinetic_energy).collect();
    let peak = ke.iter().cloned().fold(0.0, f64::max);
    let fastest = trace.stats.iter().map(|s| s.max_speed).fold(0.0, f64::max);
    let sqrt_gh = (G * depth).sqrt();
    checks.push(Check::at_most(
        CASE,
        "largest particle speed over the whole run / sqrt(g·H)",
        fastest / sqrt_gh * 100.0,
        1.0,
        |v| format!("{v:.2} %"),
    ));

    // Plots.
    let particles: Vec<(f64, f64)> = sim
        .positions()
        .iter()
        .zip(sim.interpolated_pressures_over_rho0())
        .map(|(x, p)| (x.y as f64, p as f64 * RHO0 / 1000.0))
        .collect();
    let mut pressure = Plot::new(
        "hydrostatic_pressure.png",
        &format!("Hydrostatic tank, H = {depth} m, r = {r} m: pressure at t = {until} s"),
        "height y (m)",
        "pressure (kPa)",
    )
    .with(Series::new("particles", particles, Style::Dots, 1))
    .with(Series::new(
        "analytic ρ0·g·(H − y)",
        vec![(0.0, p_ref / 1000.0), (depth, 0.0)],
        Style::Dashed,
        0,
    ))
    .with(Series::new(
        "probes (mean of the last quarter)",
        probe_points,
        Style::Markers,
        2,
    ));
    pressure.legend_right = true;
    let energy = Plot::new(
        "hydrostatic_energy.png",
        "Hydrostatic tank: kinetic energy",
        "time t (s)",
        "kinetic energy (J per metre of depth)",
    )
    .with(Series::new(
        "simulation",
        trace.t.iter().cloned().zip(ke.iter().cloned()).collect(),
        Style::Line,
        1,
    ));
    let density = Plot::new(
        "hydrostatic_density.png",
        "Hydrostatic tank: density error after the density solve",
        "time t (s)",
        "average density error (%)",
    )
    .with(Series::new(
        "simulation (solver's average compression)",
        trace
            .t
            .iter()
            .zip(&trace.stats)
            .skip(1)
            .map(|(&t, s)| (t, s.avg_density_error_pct))
            .collect(),
        Style::Line,
        1,
    ));

    let mut text = String::new();
    let _ = writeln!(
        text,
        "Water {depth} m deep at rest in a 2 m wide tank (built-in scene `hydrostatic`), \
         particle radius r = {r} m, run for {until} s from the lattice at rest (gravity on \
         from t = 0). Analytic solution: p(y) = ρ0·g·(H − y), density ρ0, velocity 0. The \
         scene uses the hexagonal packing and the conjugate-gradient pressure solve \
         (`docs/scenes.md`): the fluid starts in equilibrium, with a hydrostatic pressure, and \
         must stay at rest, no step faster than 1 % of sqrt(g·H) (see the energy plot).\n\n\
         Pressure probes on the centre line x = 1 m and on the floor and the left wall. The \
         centre-line probes read the mechanical pressure, the force the fluid transmits per \
         unit length across lines within h of the probe (the virial of the solver's pair \
         forces); the wall sensors read the fluid's normal force on the wall per unit length \
         (see `docs/scenes.md` for both). Readings are averaged over the last quarter of the \
         run (t ≥ {from} s). Tolerance: 2 % of ρ0·g·H = {p_ref:.0} Pa (the issue). The last \
         column is the standard deviation of the readings over the window. The water-level \
         gauge at x = 1 m reads {level:.4} m (nominal {depth} m).\n\n\
         The plot also shows each particle's pressure at the last step as CSV and VTK \
         output it: the solve's pressures interpolated twice with the kernel over each \
         particle's neighbourhood (`Simulation::interpolated_pressures_over_rho0`). The \
         solve's own values carry particle-scale patterns that exert no force (alternate rows \
         above and below the hydrostatic line); the interpolation removes all but about 7 % \
         of them. The solve reports the physical pressure: the \
         SPH gradient of a linear field on the hexagonal lattice recovers 98.1 % of it, so \
         the solve's stiffness field is that much steeper than the pressure it exerts \
         (`dfsph::packing::gradient_consistency`). The mechanical pressure does not respond \
         to the patterns (`dfsph::probes`). Both are compared with the nominal depth; the \
         hexagonal rows fill the block to the gauge's level above, not exactly to it.\n"
    );
    text.push_str(&rows);
    let _ = writeln!(
        text,
        "\nMean density error: over the {} particles more than h = {h} m below the surface, \
         the mean of |ρ/ρ0 − 1| at the end of the run is {mean_density_err:.3} %. Tolerance \
         0.1 %: twice the solver's average-compression tolerance (`density_tolerance_pct` = \
         {} %), since the solver corrects compression only. Existing expansion is left alone \
         (pulling the thin rows under the free surface together would be a surface tension of \
         the solver's own), so the expansion each step's residual leaves accumulates over a \
         long run: measured 0.047 % after 5 s and 0.134 % after 15 s at r = 1 cm \
         (docs/deep-columns.md).\n\n\
         Output pressure, one particle at a time: over the particles at least h from the \
         walls, the floor and the surface, the pressure that CSV and VTK write is at worst \
         {worst_particle:.2} % of ρ0·g·H from ρ0·g·(H − y) at the end of the run, with H half a \
         spacing above the top particle (tolerance 1 %, the issue). The same expansion moves \
         it: the water's surface rises while its weight, and so the pressure below, stays; \
         measured 0.38 % after 5 s, 0.65 % after 10 s and 1.40 % after 15 s, the interior's \
         mean going from −0.20 to −0.44 %. (The tests hold 777 particles at r = 2.5 cm for \
         10 s, and columns of 200 to 400 layers, within 1 %.)\n\n\
         Motion: the largest particle speed over the run is {fastest:.4} m/s, {:.2} % of \
         sqrt(g·H) = {sqrt_gh:.2} m/s (tolerance 1 %); the kinetic energy peaks at \
         {peak:.3e} J/m.\n",
        interior.len(),
        scene.solver.density_tolerance_pct,
        fastest / sqrt_gh * 100.0
    );
    text.push_str(&run_table([&trace.info]));
    Ok(vec![CaseReport {
        title: "Hydrostatic tank".into(),
        text,
        checks,
        plots: vec![pressure, energy, density],
        runs: vec![trace.info.clone()],
    }])
}

// ---------------------------------------------------------------------------------------
// Dam break, n² = 2: Martin & Moyce, Koshizuka & Oka, resolution study, WCSPH
// ---------------------------------------------------------------------------------------

/// Column width a, m.
const A: f64 = 1.0;
/// Tank length in units of a: the front reaches Z ≈ 16 by the end of the long run.
const TANK_LENGTH: f64 = 18.0;

/// The dam-break case's radii: coarse, main, fine.
fn dam_radii(s: Settings) -> [f64; 3] {
    if s.quick {
        [0.035, 0.025, 0.0175]
    } else {
        [0.02, 0.01, 0.005]
    }
}

/// The validation's dam break: the built-in dam break's discretisation
/// ([`scene::square_lattice_jacobi`]) at radius `r`.
fn dam_scene(r: f64, method: Method) -> Scene {
    let mut s = Scene {
        name: "validation-dam-break".into(),
        description: format!(
            "{A} m x {} m column (n^2 = 2) in a {} m x {} m tank",
            2.0 * A,
            TANK_LENGTH * A,
            3.0 * A
        ),
        particle_radius: r,
        tank: Tank {
            min: [0.0, 0.0],
            max: [TANK_LENGTH * A, 3.0 * A],
        },
        fluid: vec![FluidBlock {
            min: [0.0, 0.0],
            max: [A, 2.0 * A],
            velocity: [0.0, 0.0],
        }],
        // Residual column height: a gauge h/2 from the left wall (closer, the kernel is cut
        // off by the wall and the gauge under-reads; see dfsph::probes).
        probes: vec![Probe::WaterLevel {
            name: "h_wall".into(),
            x: 2.0 * r,
        }],
        ..scene::square_lattice_jacobi(Scene::default())
    };
    s.solver.method = method;
    s
}

/// T = t·√(2g/a) and Z = x_front/a of a trace.
fn front_tz(tr: &Trace) -> (Vec<f64>, Vec<f64>) {
    let k = (2.0 * G / A).sqrt();
    (
        tr.t.iter().map(|t| t * k).collect(),
        tr.front.iter().map(|x| x / A).collect(),
    )
}

pub fn dam_break(s: Settings) -> Result<Vec<CaseReport>> {
    const CASE: &str = "Dam break";
    let radii = dam_radii(s);
    let r = radii[1];
    let k_front = (2.0 * G / A).sqrt();
    let k_height = (G / A).sqrt();
    let mm2 = data::mm_front_table2().pairs("T", "Z");
    let fig3 = data::mm_front_fig3();
    let fig3_small = fig3.pairs_where("a_inch", 1.125, "T", "Z");
    let fig3_large = fig3.pairs_where("a_inch", 2.25, "T", "Z");
    let ko = data::ko_front().pairs("T", "Z");
    let mm6 = data::mm_height_table6().pairs("tau", "H");
    let t_fig3 = fig3_large.iter().map(|p| p.0).fold(0.0, f64::max) / k_front;
    let t_height = mm6.iter().map(|p| p.0).fold(0.0, f64::max) / k_height;
    let t_long = t_fig3.max(t_height) + 0.03;
    let t_short = 3.4 / k_front;

    let (main, _) = simulate(
        s,
        &format!("DFSPH r = {r}"),
        &dam_scene(r, Method::Dfsph),
        t_long,
    )?;
    let (coarse, _) = simulate(
        s,
        &format!("DFSPH r = {}", radii[0]),
        &dam_scene(radii[0], Method::Dfsph),
        t_short,
    )?;
    let (fine, _) = simulate(
        s,
        &format!("DFSPH r = {}", radii[2]),
        &dam_scene(radii[2], Method::Dfsph),
        t_short,
    )?;
    let (wc, _) = simulate(
        s,
        &format!("WCSPH r = {r}"),
        &dam_scene(r, Method::Wcsph),
        t_short,
    )?;

    let (tt, zz) = front_tz(&main);
    let sim_front = |label: &str, tr: &Trace, color: usize| {
        let (t, z) = front_tz(tr);
        Series::new(label, t.into_iter().zip(z).collect(), Style::Line, color)
    };
    let sim_label = format!("DFSPH, r = {r} m ({} particles)", main.info.n_fluid);

    // --- Front against Martin & Moyce and Koshizuka & Oka.
    let mut checks = vec![
        completion_check(CASE, &main, t_long),
        front_check(
            CASE,
            "surge front Z against Martin & Moyce Table 2 (a = 2.25 in), every point",
            &tt,
            &zz,
            &mm2,
            10.0,
            "T",
        ),
        front_check(
            CASE,
            "surge front Z against Martin & Moyce Fig. 3, a = 1.125 in, every point",
            &tt,
            &zz,
            &fig3_small,
            10.0,
            "T",
        ),
        front_check(
            CASE,
            "surge front Z against Martin & Moyce Fig. 3, a = 2.25 in, every point",
            &tt,
            &zz,
            &fig3_large,
            10.0,
            "T",
        ),
        front_check(
            CASE,
            "surge front Z against Koshizuka & Oka (1996), every point",
            &tt,
            &zz,
            &ko,
            10.0,
            "T",
        ),
    ];
    let tau: Vec<f64> = main.t.iter().map(|t| t * k_height).collect();
    let hh: Vec<f64> = main.probe(0).iter().map(|h| h / (2.0 * A)).collect();
    checks.push(front_check(
        CASE,
        "residual column height H against Martin & Moyce Table 6, every point",
        &tau,
        &hh,
        &mm6,
        10.0,
        "τ",
    ));

    // Time shift that would best fit MM Table 2 (information only; not applied).
    let best_shift = {
        let mut best = (f64::INFINITY, 0.0);
        for i in -50..=50 {
            let dt = i as f64 * 0.01;
            let e = rms(mm2.iter().map(|&(t, z)| interp(&tt, &zz, t - dt) / z - 1.0));
            if e < best.0 {
                best = (e, dt);
            }
        }
        best
    };
    let unshifted = rms(mm2.iter().map(|&(t, z)| interp(&tt, &zz, t) / z - 1.0));
    // The same shift applied to the residual height of the same experiments (τ = T/√2).
    let height_rms = |shift_t: f64| {
        let shift_tau = shift_t / 2.0f64.sqrt();
        rms(mm6
            .iter()
            .map(|&(t, h)| interp(&tau, &hh, t - shift_tau) / h - 1.0))
    };
    let mut dev_rows =
        String::from("| T | Z (MM Table 2) | Z (simulation) | deviation |\n|---|---|---|---|\n");
    for &(t, z) in &mm2 {
        let zs = interp(&tt, &zz, t);
        let _ = writeln!(
            dev_rows,
            "| {t:.2} | {z:.2} | {zs:.3} | {:+.1} % |",
            (zs / z - 1.0) * 100.0
        );
    }

    let exp_markers = |label: &str, pts: &[(f64, f64)], color: usize| {
        Series::new(label, pts.to_vec(), Style::Markers, color)
    };
    let plot_mm2 = Plot::new(
        "dambreak_front_mm_table2.png",
        "Dam break (n² = 2): surge front, Martin & Moyce (1952) Table 2",
        "T = t·√(2g/a)  (–)",
        "Z = x_front / a  (–)",
    )
    .with(exp_markers("Martin & Moyce Table 2, a = 2.25 in", &mm2, 0))
    .with(sim_front(&sim_label, &main, 1));
    let mut plot_mm2 = plot_mm2;
    plot_mm2.x_range = Some((0.0, 3.5));
    plot_mm2.y_range = Some((0.8, 5.0));
    let plot_fig3 = Plot::new(
        "dambreak_front_mm_fig3.png",
        "Dam break (n² = 2): long-time surge front, Martin & Moyce (1952) Fig. 3",
        "T = t·√(2g/a)  (–)",
        "Z = x_front / a  (–)",
    )
    .with(exp_markers(
        "Martin & Moyce Fig. 3, a = 1.125 in",
        &fig3_small,
        2,
    ))
    .with(exp_markers(
        "Martin & Moyce Fig. 3, a = 2.25 in",
        &fig3_large,
        0,
    ))
    .with(sim_front(&sim_label, &main, 1));
    let mut plot_ko = Plot::new(
        "dambreak_front_ko.png",
        "Dam break (n² = 2): surge front, Koshizuka & Oka (1996) experiment",
        "T = t·√(2g/L)  (–)",
        "Z = x_front / L  (–)",
    )
    .with(exp_markers("Koshizuka & Oka 1996, L = 0.146 m", &ko, 0))
    .with(sim_front(&sim_label, &main, 1));
    plot_ko.x_range = Some((0.0, 3.5));
    plot_ko.y_range = Some((0.8, 5.0));
    let mut plot_h = Plot::new(
        "dambreak_height_mm_table6.png",
        "Dam break (n² = 2): residual column height, Martin & Moyce (1952) Table 6",
        "τ = t·√(g/a)  (–)",
        "H = h / (2a)  (–)",
    )
    .with(exp_markers("Martin & Moyce Table 6, a = 2.25 in", &mm6, 0))
    .with(Series::new(
        format!("{sim_label}, gauge at x = 2r"),
        tau.iter().cloned().zip(hh.iter().cloned()).collect(),
        Style::Line,
        1,
    ));
    plot_h.legend_right = true;
    plot_h.y_range = Some((0.0, 1.05));

    let mut text = String::new();
    let _ = writeln!(
        text,
        "Column a = {A} m wide and 2a = {} m high against the left wall of a {} m × {} m tank \
         (long enough that the front never reaches the far wall), particle radius r = {r} m, \
         DFSPH with the default solver settings, run to t = {t_long:.2} s. Normalisation as in \
         the data files: T = t·√(2g/a), Z = x_front/a for the front, τ = t·√(g/a), H = h/(2a) \
         for the residual height. The front is `Simulation::front_position(3)`: the largest x \
         of a fluid particle with at least 3 fluid neighbours, measured from the left wall. \
         The residual height is a water-level probe (fluid fraction 0.5 on a vertical line) \
         at x = 2r = h/2 from the left wall.\n\n\
         **Time origin.** No time shift is applied: T = 0 is the release in both the \
         simulation and the experiments. The experiments released the column by lifting or \
         breaking a gate, which delays the motion; a shift would hide a part of the \
         difference that we would rather show. For information, the shift ΔT that minimises \
         the RMS deviation from MM Table 2 (simulation compared at T − ΔT) is ΔT = {:+.2}, \
         RMS {:.1} % against {:.1} % unshifted. The residual height of the same \
         experiments argues against such a shift: it fits unshifted (RMS {:.1} % over Table \
         6), and the same shift (Δτ = ΔT/√2) would raise its RMS to {:.1} %. A gate that \
         held the water back would have delayed the column's fall as much as the front, so \
         the difference lies at the front itself, most likely at the thin tip running along \
         the floor, which friction and surface tension slow at the experiments' 3–15 cm \
         scale and which our free-slip walls at 1 m leave free (the smaller of Martin & \
         Moyce's two columns is the slower one, as that would predict). Tolerance: every \
         data point within 10 % (the issue; Martin & Moyce's own two column sizes differ by \
         up to 9 %).\n",
        2.0 * A,
        TANK_LENGTH * A,
        3.0 * A,
        best_shift.1,
        best_shift.0 * 100.0,
        unshifted * 100.0,
        height_rms(0.0) * 100.0,
        height_rms(best_shift.1) * 100.0,
    );
    text.push_str(&dev_rows);
    text.push('\n');
    text.push_str(&run_table([&main.info]));
    let front_report = CaseReport {
        title:
            "Dam break: surge front and residual height (Martin & Moyce 1952, Koshizuka & Oka 1996)"
                .into(),
        text,
        checks,
        plots: vec![plot_mm2, plot_fig3, plot_ko, plot_h],
        runs: vec![main.info.clone()],
    };

    // --- Resolution study.
    let at_mm = |tr: &Trace| -> Vec<f64> {
        let (t, z) = front_tz(tr);
        mm2.iter().map(|&(tm, _)| interp(&t, &z, tm)).collect()
    };
    let (zc, zm, zf) = (at_mm(&coarse), at_mm(&main), at_mm(&fine));
    let d1 = rms(zc.iter().zip(&zm).map(|(a, b)| a - b));
    let d2 = rms(zm.iter().zip(&zf).map(|(a, b)| a - b));
    let ratio = d2 / d1;
    let order = (d1 / d2).ln() / (radii[0] / radii[1]).ln();
    let mut res_rows = String::from(
        "| r (m) | fluid particles | worst deviation from MM Table 2 | RMS deviation |\n|---|---|---|---|\n",
    );
    for (tr, z) in [(&coarse, &zc), (&main, &zm), (&fine, &zf)] {
        let (t, zs) = front_tz(tr);
        let (worst, at, _) = worst_relative(&t, &zs, &mm2);
        let r_dev = rms(z.iter().zip(&mm2).map(|(a, &(_, b))| a / b - 1.0)) * 100.0;
        let _ = writeln!(
            res_rows,
            "| {} | {} | {worst:.1} % at T = {at:.2} | {r_dev:.1} % |",
            tr.info.particle_radius, tr.info.n_fluid
        );
    }
    let mut res_check = Check::at_most(
        "Resolution",
        format!(
            "front converges: RMS(Z_{} − Z_{}) / RMS(Z_{} − Z_{}) at the MM Table 2 times",
            radii[1], radii[2], radii[0], radii[1]
        ),
        ratio,
        1.0,
        |v| format!("{v:.2}"),
    );
    res_check.tolerance = "≤ 1 (differences shrink as r halves)".into();
    let mut plot_res = Plot::new(
        "resolution_front.png",
        "Dam break (n² = 2): surge front at three resolutions",
        "T = t·√(2g/a)  (–)",
        "Z = x_front / a  (–)",
    )
    .with(exp_markers("Martin & Moyce Table 2, a = 2.25 in", &mm2, 0));
    for (tr, c) in [(&coarse, 4), (&main, 1), (&fine, 3)] {
        plot_res = plot_res.with(sim_front(
            &format!(
                "DFSPH, r = {} m ({} particles)",
                tr.info.particle_radius, tr.info.n_fluid
            ),
            tr,
            c,
        ));
    }
    plot_res.x_range = Some((0.0, 3.5));
    plot_res.y_range = Some((0.8, 5.0));
    let mut text = String::new();
    let _ = writeln!(
        text,
        "The same dam break at particle radii {} m, {} m and {} m (spacing ratio {:.2}), run \
         to T = 3.4. The front converges when the difference between successive resolutions \
         shrinks: RMS(Z_coarse − Z_mid) = {d1:.3}, RMS(Z_mid − Z_fine) = {d2:.3} (ratio \
         {ratio:.2}, observed order of convergence {order:.2}). Converging is not the same as \
         converging to the experiment: the table shows the deviation from Martin & Moyce at \
         each resolution.\n",
        radii[0],
        radii[1],
        radii[2],
        radii[0] / radii[1],
    );
    text.push_str(&res_rows);
    text.push('\n');
    text.push_str(&run_table([&coarse.info, &main.info, &fine.info]));
    let res_report = CaseReport {
        title: "Resolution study".into(),
        text,
        checks: vec![
            completion_check("Resolution", &coarse, t_short),
            completion_check("Resolution", &fine, t_short),
            res_check,
        ],
        plots: vec![plot_res],
        runs: vec![coarse.info.clone(), fine.info.clone()],
    };

    // --- DFSPH beside WCSPH.
    let mean_err = |tr: &Trace| {
        let v: Vec<f64> = tr
            .stats
            .iter()
            .skip(1)
            .filter(|s| s.time <= t_short)
            .map(|s| s.avg_density_error_pct)
            .collect();
        v.iter().sum::<f64>() / v.len().max(1) as f64
    };
    let max_err = |tr: &Trace| {
        tr.stats
            .iter()
            .filter(|s| s.time <= t_short)
            .map(|s| s.max_density_error_pct)
            .fold(0.0, f64::max)
    };
    let (e_df, e_wc) = (mean_err(&main), mean_err(&wc));
    let tol = dam_scene(r, Method::Dfsph).solver.density_tolerance_pct;
    let mut c1 = Check::at_most(
        "DFSPH vs WCSPH",
        "DFSPH mean average density error over the dam break (T ≤ 3.4)",
        e_df,
        tol,
        |v| format!("{v:.4} %"),
    );
    c1.tolerance = format!("≤ {tol} % (`density_tolerance_pct`)");
    let mut c2 = Check::at_most(
        "DFSPH vs WCSPH",
        "DFSPH mean density error / WCSPH mean density error",
        e_df / e_wc,
        1.0,
        |v| format!("{v:.3}"),
    );
    c2.tolerance = "≤ 1 (DFSPH at most as compressed)".into();
    let (tw, zw) = front_tz(&wc);
    let (wc_worst, wc_at, _) = worst_relative(&tw, &zw, &mm2);
    let (df_worst, df_at, _) = worst_relative(&tt, &zz, &mm2);
    let err_series = |label: &str, tr: &Trace, style: Style, color: usize| {
        Series::new(
            label,
            tr.stats
                .iter()
                .skip(1)
                .filter(|s| s.time <= t_short)
                .map(|s| (s.time * k_front, s.avg_density_error_pct))
                .collect(),
            style,
            color,
        )
    };
    let mut plot_rho = Plot::new(
        "dfsph_vs_wcsph_density.png",
        &format!("Dam break, r = {r} m: average density error, DFSPH and WCSPH"),
        "T = t·√(2g/a)  (–)",
        "average density error (%)",
    )
    .with(err_series("DFSPH", &main, Style::Line, 1))
    .with(err_series("WCSPH", &wc, Style::Line, 2));
    plot_rho.legend_right = true;
    let mut plot_wf = Plot::new(
        "dfsph_vs_wcsph_front.png",
        &format!("Dam break, r = {r} m: surge front, DFSPH and WCSPH"),
        "T = t·√(2g/a)  (–)",
        "Z = x_front / a  (–)",
    )
    .with(exp_markers("Martin & Moyce Table 2, a = 2.25 in", &mm2, 0))
    .with(sim_front("DFSPH", &main, 1))
    .with(sim_front("WCSPH", &wc, 2));
    plot_wf.x_range = Some((0.0, 3.5));
    plot_wf.y_range = Some((0.8, 5.0));
    let wcs = dam_scene(r, Method::Wcsph);
    let mut text = String::new();
    let _ = writeln!(
        text,
        "The dam break at r = {r} m with DFSPH (density tolerance {tol} %) and with WCSPH \
         (Tait equation, B = {} Pa, γ = {}), to T = 3.4.\n\n\
         | solver | mean average density error | largest single-particle compression | steps | wall (s) | worst front deviation from MM Table 2 |\n|---|---|---|---|---|---|\n\
         | DFSPH | {e_df:.4} % | {:.2} % | {} (whole run to T = {:.1}) | {:.1} (whole run) | {df_worst:.1} % at T = {df_at:.2} |\n\
         | WCSPH | {e_wc:.4} % | {:.2} % | {} | {:.1} | {wc_worst:.1} % at T = {wc_at:.2} |\n",
        wcs.solver.wcsph_stiffness,
        wcs.solver.wcsph_exponent,
        max_err(&main),
        main.info.steps,
        main.info.sim_time * k_front,
        main.info.wall_s,
        max_err(&wc),
        wc.info.steps,
        wc.info.wall_s,
    );
    let wc_report = CaseReport {
        title: "DFSPH beside WCSPH".into(),
        text,
        checks: vec![completion_check("DFSPH vs WCSPH", &wc, t_short), c1, c2],
        plots: vec![plot_rho, plot_wf],
        runs: vec![wc.info.clone()],
    };
    Ok(vec![front_report, res_report, wc_report])
}

// ---------------------------------------------------------------------------------------
// Lobovsky et al. 2014, H = 300 mm
// ---------------------------------------------------------------------------------------

/// Initial water depth, m.
const LH: f64 = 0.3;
/// Gauges: name, x (m), experiment columns, end of the comparison window in T.
const GAUGES: [(&str, f64, &[&str], f64); 4] = [
    ("H1", 0.300, &["h_H1_2"], 9.0),
    ("H2", 0.865, &["h_H2_3", "h_H2_4"], 7.0),
    ("H3", 1.114, &["h_H3_3", "h_H3_4"], 6.5),
    ("H4", 1.3625, &["h_H4_4", "h_H4_5"], 5.5),
];
/// Far-wall sensors: name, height (m), experiment column.
const SENSORS: [(&str, f64, &str); 4] = [
    ("s1", 0.003, "p_s1"),
    ("s2", 0.015, "p_s2"),
    ("s3", 0.030, "p_s3"),
    ("s4", 0.080, "p_s4"),
];
/// Pressure threshold P = p/(ρgH) that marks the arrival at a sensor.
const ARRIVAL_P: f64 = 0.1;
/// Length of the impulse window after arrival, in T.
const IMPULSE_WINDOW: f64 = 1.0;
/// Bands (see the report text for the justification).
const LEVEL_BAND: f64 = 0.05;
const ARRIVAL_BAND: f64 = 0.1;
const IMPULSE_BAND_PCT: f64 = 25.0;

/// Window of the moving average drawn over the raw simulated pressure (plots only; the
/// checks use the raw signal), in T.
const SMOOTH_T: f64 = 0.05;

/// Centred moving average of (t, v) over a window of `width` in t.
fn moving_average(t: &[f64], v: &[f64], width: f64) -> Vec<f64> {
    let (mut lo, mut hi, mut sum) = (0usize, 0usize, 0.0);
    let mut out = Vec::with_capacity(t.len());
    for i in 0..t.len() {
        while hi < t.len() && t[hi] <= t[i] + 0.5 * width {
            sum += v[hi];
            hi += 1;
        }
        while t[lo] < t[i] - 0.5 * width {
            sum -= v[lo];
            lo += 1;
        }
        out.push(sum / (hi - lo) as f64);
    }
    out
}

fn arrival(t: &[f64], p: &[f64]) -> f64 {
    t.iter()
        .zip(p)
        .find(|(_, &v)| v > ARRIVAL_P)
        .map(|(&t, _)| t)
        .unwrap_or(f64::NAN)
}

fn impulse(t: &[f64], p: &[f64], from: f64, len: f64) -> f64 {
    let mut sum = 0.0;
    for i in 1..t.len() {
        let (a, b) = (t[i - 1].max(from), t[i].min(from + len));
        if b > a {
            let pm = 0.5 * (interp(t, p, a) + interp(t, p, b));
            sum += pm * (b - a);
        }
    }
    sum
}

/// The Lobovsky case's radius and duration (in units of √(H/g)).
fn lobovsky_run(s: Settings) -> (f64, f64) {
    if s.quick {
        (0.005, 7.3)
    } else {
        (0.002, 11.2)
    }
}

/// Lobovsky et al.'s tank at radius `r` with the case's gauges and sensors, on the built-in
/// dam break's discretisation ([`scene::square_lattice_jacobi`]).
fn lobovsky_scene(r: f64) -> Scene {
    let mut probes: Vec<Probe> = GAUGES
        .iter()
        .map(|&(name, x, _, _)| Probe::WaterLevel {
            name: name.into(),
            x,
        })
        .collect();
    probes.extend(SENSORS.iter().map(|&(name, y, _)| Probe::Pressure {
        name: name.into(),
        at: [1.61, y],
    }));
    Scene {
        name: "lobovsky-2014-h300".into(),
        description: "Lobovsky et al. 2014 dam break, H = 300 mm".into(),
        particle_radius: r,
        tank: Tank {
            min: [0.0, 0.0],
            max: [1.61, 0.6],
        },
        fluid: vec![FluidBlock {
            min: [0.0, 0.0],
            max: [0.6, LH],
            velocity: [0.0, 0.0],
        }],
        probes,
        ..scene::square_lattice_jacobi(Scene::default())
    }
}

pub fn lobovsky(s: Settings) -> Result<Vec<CaseReport>> {
    let (r, t_end) = lobovsky_run(s);
    let k = (G / LH).sqrt();
    let scene = lobovsky_scene(r);
    let (tr, _) = simulate(s, &format!("Lobovsky r = {r}"), &scene, t_end / k)?;
    let ts: Vec<f64> = tr.t.iter().map(|t| t * k).collect();
    let t_sim_end = *ts.last().unwrap_or(&0.0);
    let levels = data::lobovsky_levels();
    let te = levels.col("T");
    let pressure = data::lobovsky_pressure();
    let tp = pressure.col("T");

    // Water levels.
    let mut level_checks = Vec::new();
    let mut level_plots = Vec::new();
    let mut level_rows = String::from(
        "| gauge | x (m) | window | repetitions | scatter between repetitions (RMS h/H) | simulation − mean of repetitions (RMS h/H) |\n|---|---|---|---|---|---|\n",
    );
    for (gi, &(name, x, cols, t_win)) in GAUGES.iter().enumerate() {
        let win = t_win.min(t_sim_end);
        let sim_h: Vec<f64> = tr.probe(gi).iter().map(|h| h / LH).collect();
        let idx: Vec<usize> = (0..te.len()).filter(|&i| te[i] <= win).collect();
        let mean_exp =
            |i: usize| cols.iter().map(|c| levels.col(c)[i]).sum::<f64>() / cols.len() as f64;
        let err = rms(idx
            .iter()
            .map(|&i| interp(&ts, &sim_h, te[i]) - mean_exp(i)));
        let scatter = if cols.len() > 1 {
            format!(
                "{:.4}",
                rms(idx
                    .iter()
                    .map(|&i| levels.col(cols[0])[i] - levels.col(cols[1])[i]))
            )
        } else {
            "– (one repetition)".into()
        };
        let _ = writeln!(
            level_rows,
            "| {name} | {x} | T ≤ {win:.2} | {} | {scatter} | {err:.4} |",
            cols.join(", ")
        );
        let mut c = Check::at_most(
            "Lobovsky",
            format!("water level at gauge {name} (x = {x} m), RMS of h/H error for T ≤ {win:.2}"),
            err,
            LEVEL_BAND,
            |v| format!("{v:.3}"),
        );
        c.tolerance = format!("≤ {LEVEL_BAND} (= {:.0} mm)", LEVEL_BAND * LH * 1000.0);
        level_checks.push(c.full_run_only());
        let mut p = Plot::new(
            &format!("lobovsky_level_{name}.png"),
            &format!("Lobovsky et al. 2014, H = 300 mm: water level at gauge {name}, x = {x} m"),
            "T = t·√(g/H)  (–)",
            "h / H  (–)",
        );
        for (ci, c) in cols.iter().enumerate() {
            let pts: Vec<(f64, f64)> = te
                .iter()
                .zip(levels.col(c))
                .step_by(3)
                .map(|(&a, &b)| (a, b))
                .collect();
            p = p.with(Series::new(
                format!("experiment, {c}"),
                pts,
                Style::Markers,
                [0, 7][ci % 2],
            ));
        }
        p = p.with(Series::new(
            format!("DFSPH, r = {r} m"),
            ts.iter().cloned().zip(sim_h).collect(),
            Style::Line,
            1,
        ));
        p.x_range = Some((0.0, t_end.max(t_sim_end)));
        p.y_range = Some((0.0, 1.1));
        p.legend_right = gi == 0;
        level_plots.push(p);
    }

    // Far-wall pressure.
    let mut p_checks = Vec::new();
    let mut p_plots = Vec::new();
    let mut p_rows = String::from(
        "| sensor | height (mm) | arrival T (exp.) | arrival T (sim.) | impulse ∫P dT (exp.) | impulse (sim.) |\n|---|---|---|---|---|---|\n",
    );
    let twin = (
        arrival(tp, pressure.col("p_s2")),
        arrival(tp, pressure.col("p_s2L")),
    );
    let twin_imp = (
        impulse(tp, pressure.col("p_s2"), twin.0, IMPULSE_WINDOW),
        impulse(tp, pressure.col("p_s2L"), twin.1, IMPULSE_WINDOW),
    );
    for (si, &(name, y, col)) in SENSORS.iter().enumerate() {
        let pe = pressure.col(col);
        let ps: Vec<f64> = tr
            .probe(GAUGES.len() + si)
            .iter()
            .map(|p| p / (RHO0 * G * LH))
            .collect();
        let (ae, asim) = (arrival(tp, pe), arrival(&ts, &ps));
        let ie = impulse(tp, pe, ae, IMPULSE_WINDOW);
        let isim = if asim + IMPULSE_WINDOW <= t_sim_end {
            impulse(&ts, &ps, asim, IMPULSE_WINDOW)
        } else {
            f64::NAN
        };
        let _ = writeln!(
            p_rows,
            "| {name} | {} | {ae:.3} | {asim:.3} | {ie:.3} | {isim:.3} |",
            y * 1000.0
        );
        let mut c = Check::at_most(
            "Lobovsky",
            format!(
                "far-wall pressure arrival at {name} (y = {} mm), |T_sim − T_exp|",
                y * 1000.0
            ),
            (asim - ae).abs(),
            ARRIVAL_BAND,
            |v| format!("{v:.3}"),
        );
        c.value = format!("{:.3} (sim {asim:.3}, exp {ae:.3})", (asim - ae).abs());
        p_checks.push(c.full_run_only());
        let dev = (isim / ie - 1.0).abs() * 100.0;
        let mut c = Check::at_most(
            "Lobovsky",
            format!(
                "far-wall pressure impulse at {name}, ∫P dT over {IMPULSE_WINDOW} after arrival"
            ),
            dev,
            IMPULSE_BAND_PCT,
            pct,
        );
        c.value = format!("{} (sim {isim:.3}, exp {ie:.3})", pct(dev));
        p_checks.push(c.full_run_only());
        let mut p = Plot::new(
            &format!("lobovsky_pressure_{name}.png"),
            &format!(
                "Lobovsky et al. 2014, H = 300 mm: far-wall pressure, sensor {name} at y = {} mm",
                y * 1000.0
            ),
            "T = t·√(g/H)  (–)",
            "P = p / (ρ0·g·H)  (–)",
        )
        .with(Series::new(
            format!("experiment, {col} (every 20th sample of the 2 kHz data)"),
            tp.iter()
                .zip(pe)
                .step_by(20)
                .map(|(&a, &b)| (a, b))
                .collect(),
            Style::Markers,
            0,
        ))
        .with(Series::new(
            format!("DFSPH, r = {r} m, every step"),
            ts.iter().cloned().zip(ps.iter().cloned()).collect(),
            Style::Faint,
            1,
        ))
        .with(Series::new(
            format!("DFSPH, moving average over ΔT = {SMOOTH_T}"),
            ts.iter()
                .cloned()
                .zip(moving_average(&ts, &ps, SMOOTH_T))
                .collect(),
            Style::Line,
            1,
        ));
        p.x_range = Some((2.0, tp.last().copied().unwrap_or(7.2)));
        let top = pe.iter().cloned().fold(1.0, f64::max) * 1.4;
        p.y_range = Some((-0.3, top));
        p.legend_right = true;
        p_plots.push(p);
    }

    let mut text = String::new();
    let _ = writeln!(
        text,
        "Tank 1.61 m long and 0.6 m high, water column 0.6 m long × H = 0.3 m high against the \
         left wall, particle radius r = {r} m, run to T = {t_end} (T = t·√(g/H)). Probes as \
         in the experiment (and TNL-SPH's configuration of it): water-level gauges H1–H4 at \
         x = 0.300, 0.865, 1.114, 1.3625 m and pressure sensors on the far wall x = 1.61 m at \
         heights 3, 15, 30 and 80 mm (wall sensors: the fluid's normal force on the wall per unit \
         length, 0 when dry; see `docs/scenes.md`). No time shift.\n\n\
         **Water levels.** The comparison window of each gauge ends before the wave reflected \
         from the far wall returns to it: from there on the repetitions of the experiment \
         themselves disagree by up to 0.36 H. Inside the windows the repetitions agree to an \
         RMS of 0.005–0.013 H (table). The band, RMS error ≤ {LEVEL_BAND} H ({:.0} mm), is \
         about 4× the largest repetition scatter: two repetitions underestimate the spread \
         of the full experimental series, and the gate removal and the 3D flow near the \
         gauges are absent from a 2D simulation.\n",
        LEVEL_BAND * LH * 1000.0
    );
    if tr.info.non_finite > 0 {
        let _ = writeln!(
            text,
            "**The run broke down** (non-finite values) at t = {:.3} s, T = {t_sim_end:.2}, \
             after {} particles had been clamped back into the tank; every comparison below \
             stops there.\n",
            tr.info.sim_time, tr.info.clamped
        );
    }
    text.push_str(&level_rows);
    let _ = writeln!(
        text,
        "\n**Far-wall pressure.** Impact peaks are stochastic, so we compare the arrival time \
         (first T where P = p/(ρ0·g·H) exceeds {ARRIVAL_P}) and the impulse ∫P dT over \
         {IMPULSE_WINDOW} in T after arrival (the impact and the run-up that follows). \
         Experimental scatter: the twin sensors s2 and s2L at the same height give arrivals \
         {:.3} and {:.3} and impulses {:.3} and {:.3} ({:.0} % apart); between repetitions the \
         front reaches the gauges H2–H4 up to 0.04 apart in T. Bands: arrival within \
         ±{ARRIVAL_BAND} in T (2.5× the repetition spread of the front's arrival, ≈ 4 % of \
         the arrival time) and impulse within ±{IMPULSE_BAND_PCT} % (about 3× the twin-sensor \
         difference). The plots draw the raw simulated signal faintly and a moving average \
         over ΔT = {SMOOTH_T} on top; the vertical axis stops at 1.4× the experimental peak, \
         so single-step spikes of the raw signal may be cut. The checks use the raw signal.\n",
        twin.0,
        twin.1,
        twin_imp.0,
        twin_imp.1,
        (twin_imp.0 / twin_imp.1 - 1.0).abs() * 100.0,
    );
    text.push_str(&p_rows);
    text.push('\n');
    text.push_str(&run_table([&tr.info]));
    let mut checks = vec![completion_check("Lobovsky", &tr, t_end / k)];
    checks.extend(level_checks);
    checks.extend(p_checks);
    let mut plots = level_plots;
    plots.extend(p_plots);
    Ok(vec![CaseReport {
        title: "Dam break of Lobovsky et al. (2014), H = 300 mm".into(),
        text,
        checks,
        plots,
        runs: vec![tr.info.clone()],
    }])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn moving_average_and_impulse() {
        let t: Vec<f64> = (0..11).map(|i| i as f64 * 0.1).collect();
        let v: Vec<f64> = t
            .iter()
            .map(|&x| if x < 0.45 { 0.0 } else { 2.0 })
            .collect();
        let m = moving_average(&t, &v, 0.25);
        assert_eq!(m[0], 0.0);
        assert!((m[5] - 4.0 / 3.0).abs() < 1e-12, "{m:?}");
        assert_eq!(m[10], 2.0);
        assert!((arrival(&t, &v) - 0.5).abs() < 1e-12);
        // Constant 2 over [0.5, 1.0]: impulse 1.
        assert!((impulse(&t, &v, 0.5, 0.5) - 1.0).abs() < 1e-9);
    }

    #[test]
    fn worst_relative_finds_the_largest_deviation() {
        let x = [0.0, 1.0, 2.0];
        let y = [1.0, 2.0, 3.0];
        let exp = [(0.5, 1.5), (1.5, 2.0), (5.0, 1.0)];
        let (dev, at, n) = worst_relative(&x, &y, &exp);
        assert_eq!(n, 2);
        assert_eq!(at, 1.5);
        assert!((dev - 25.0).abs() < 1e-9);
    }
}
