//! A standing wave, by hand: the first mode of a closed tank L = 1 m wide with water H m
//! deep, amplitude A m, at particle radius R, for PERIODS linear periods; EXTRA is appended
//! to the scene's JSON object. The water is listed from the scene's own lattice with the
//! linear mode's velocity field at the instant the surface is flat
//! (`u = −s·sin(kx)·cosh(ky)`, `v = s·cos(kx)·sinh(ky)`, `s = A·ω/sinh(kH)`, k = π/L,
//! `ω² = g·k·tanh(kH)`).
//!
//! `cargo run --release -p dfsph --example standing_wave -- H A R PERIODS [EXTRA-JSON]`
//!
//! Prints the period against linear theory and the amplitude lost per period, read two
//! ways: the modal velocity (every particle's velocity projected on the mode's field, which
//! averages out particle-scale motion) and the surface gauges 5 cm from either wall (half
//! their difference, which cancels a drift of the mean level). `FASTEST=1` also prints the
//! eight fastest particles at the end (where particle-scale motion grows).
use dfsph::{Scene, Simulation};
use std::f64::consts::PI;

fn main() {
    let a: Vec<String> = std::env::args().collect();
    if a.len() < 5 {
        eprintln!("usage: standing_wave H A R PERIODS [EXTRA-JSON]");
        std::process::exit(2);
    }
    let (h, amp, r, periods): (f64, f64, f64, f64) = (
        a[1].parse().unwrap(),
        a[2].parse().unwrap(),
        a[3].parse().unwrap(),
        a[4].parse().unwrap(),
    );
    let extra = a.get(5).cloned().unwrap_or_default();
    let g = 9.81f64;
    let width = 1.0f64;
    let k = PI / width;
    let omega = (g * k * (k * h).tanh()).sqrt();
    let period = 2.0 * PI / omega;
    let base = format!(
        r#""particle_radius": {r}, "tank": {{"min": [0, 0], "max": [{width}, {}]}} {extra}"#,
        h * 1.6
    );
    let block = Scene::from_json(&format!(
        r#"{{{base}, "fluid": [{{"min": [0, 0], "max": [{width}, {h}]}}]}}"#
    ))
    .unwrap();
    let s = amp * omega / (k * h).sinh();
    let mode = |x: f64, y: f64| -> (f64, f64) {
        (
            -(k * x).sin() * (k * y).cosh(),
            (k * x).cos() * (k * y).sinh(),
        )
    };
    let (mut positions, mut velocities) = (Vec::new(), Vec::new());
    for p in Simulation::new(&block).unwrap().positions() {
        let (x, y) = (p.x as f64, p.y as f64);
        let (u, v) = mode(x, y);
        positions.push(format!("[{x}, {y}]"));
        velocities.push(format!("[{}, {}]", s * u, s * v));
    }
    let scene = Scene::from_json(&format!(
        r#"{{{base}, "fluid": [], "particles": {{"positions": [{}], "velocities": [{}]}}}}"#,
        positions.join(", "),
        velocities.join(", ")
    ))
    .unwrap();
    let mut sim = Simulation::new(&scene).unwrap();
    let d = 2.0 * r;
    println!(
        "{} particles, d = {d}, theory T = {period:.4} s, wave energy {:.4} J/m",
        sim.fluid_count(),
        0.25 * 1000.0 * width * g * amp * amp
    );
    // The modal velocity: q(t) = Σ v_i·φ(x_i) / Σ |φ(x_i)|², 1 at the start (in units of s).
    let modal = |sim: &Simulation| -> f64 {
        let (mut num, mut den) = (0.0, 0.0);
        for (p, v) in sim.positions().iter().zip(sim.velocities()) {
            let (u, w) = mode(p.x as f64, p.y as f64);
            num += v.x as f64 * u + v.y as f64 * w;
            den += u * u + w * w;
        }
        num / den / s
    };
    // Surface height at x: the highest particle within 1.5 d, plus d/2.
    let gauge = |sim: &Simulation, xg: f64| -> f64 {
        sim.positions()
            .iter()
            .filter(|p| (p.x as f64 - xg).abs() < 1.5 * d)
            .map(|p| p.y as f64)
            .fold(f64::MIN, f64::max)
            + d / 2.0
    };
    let wall = std::time::Instant::now();
    let (mut steps, mut its) = (0u64, 0u64);
    let mut samples = vec![(0.0f64, modal(&sim), 0.0f64)];
    let level0 = 0.5 * (gauge(&sim, 0.05) + gauge(&sim, width - 0.05));
    let e0 = sim.mechanical_energy();
    let mut emax_rise = 0.0f64;
    let mut fastest = 0.0f64;
    while sim.time() < periods * period {
        let st = *sim.step();
        steps += 1;
        its += st.density_iterations as u64;
        fastest = fastest.max(st.max_speed);
        assert_eq!(st.non_finite, 0, "non-finite at t = {}", st.time);
        let eta = 0.5 * (gauge(&sim, 0.05) - gauge(&sim, width - 0.05));
        samples.push((sim.time(), modal(&sim), eta));
        emax_rise = emax_rise.max(sim.mechanical_energy() - e0);
    }
    if std::env::var("FASTEST").is_ok() {
        let mut idx: Vec<usize> = (0..sim.fluid_count()).collect();
        let (p, v) = (sim.positions(), sim.velocities());
        idx.sort_by(|&a, &b| v[b].length().total_cmp(&v[a].length()));
        for &i in idx.iter().take(8) {
            println!(
                "  fast: at ({:.4}, {:.4}) v = ({:.4}, {:.4})",
                p[i].x, p[i].y, v[i].x, v[i].y
            );
        }
        let top = p.iter().map(|q| q.y).fold(0.0f32, f32::max);
        println!("  top particle at {top:.4}");
    }
    let level1 = 0.5 * (gauge(&sim, 0.05) + gauge(&sim, width - 0.05));
    // Zero crossings of the modal velocity (downward and upward alike) by linear
    // interpolation; half a period apart.
    let crossings = |f: &dyn Fn(&(f64, f64, f64)) -> f64| -> Vec<f64> {
        samples
            .windows(2)
            .filter(|w| f(&w[0]) * f(&w[1]) < 0.0)
            .map(|w| {
                let (a, b) = (f(&w[0]), f(&w[1]));
                w[0].0 + (w[1].0 - w[0].0) * a / (a - b)
            })
            .collect()
    };
    let report = |name: &str, f: &dyn Fn(&(f64, f64, f64)) -> f64| {
        let z = crossings(f);
        if z.len() < 3 {
            println!("{name}: too few zero crossings ({})", z.len());
            return;
        }
        let half: Vec<f64> = z.windows(2).map(|w| w[1] - w[0]).collect();
        let measured = 2.0 * (z[z.len() - 1] - z[0]) / (z.len() - 1) as f64;
        // Peaks: the largest |f| between successive crossings.
        let mut peaks = Vec::new();
        for w in z.windows(2) {
            let peak = samples
                .iter()
                .filter(|s| s.0 > w[0] && s.0 < w[1])
                .map(|s| f(s).abs())
                .fold(0.0, f64::max);
            peaks.push(peak);
        }
        let lost: Vec<String> = peaks
            .windows(3)
            .map(|w| format!("{:.1}", 100.0 * (1.0 - w[2] / w[0])))
            .collect();
        println!(
            "{name}: period {measured:.4} s ({:+.2} % against theory); half periods {:?}",
            100.0 * (measured / period - 1.0),
            half.iter()
                .map(|h| (h * 1000.0).round() / 1000.0)
                .collect::<Vec<_>>()
        );
        println!(
            "{name}: peaks {:?}; lost per period (%) {}",
            peaks
                .iter()
                .map(|p| (p * 1000.0).round() / 1000.0)
                .collect::<Vec<_>>(),
            lost.join(", ")
        );
    };
    report("modal velocity", &|s| s.1);
    report("gauges", &|s| s.2);
    println!(
        "{steps} steps, {:.1} iterations a step, fastest {fastest:.4} m/s, energy rise {emax_rise:.4} J/m, mean level {:+.2} mm, {:.1} s wall",
        its as f64 / steps as f64,
        (level1 - level0) * 1000.0,
        wall.elapsed().as_secs_f64()
    );
}
