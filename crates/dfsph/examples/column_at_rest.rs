//! Water at rest, by hand: a column W m wide and H m deep filling a tank 1.25 H tall, at
//! particle radius R, run for UNTIL seconds; EXTRA is appended to the scene's JSON object.
//! Prints the largest speed, the solver's work and the particles' pressure against
//! ρ0·g·(H − y) (the figures of docs/deep-columns.md), e.g.
//!
//! `cargo run --release -p dfsph --example column_at_rest -- 0.1 1 0.0025 0.3
//!  ', "packing": "hexagonal", "solver": {"pressure_solve": "conjugate_gradient"}'`
//!
//! `PRINTS=N` sets the number of progress lines; `SPIKES=1` prints every step faster than
//! 0.02 m/s with its fastest particle.
use dfsph::{Scene, Simulation};
fn main() {
    let a: Vec<String> = std::env::args().collect();
    if a.len() < 5 {
        eprintln!("usage: column_at_rest W H R UNTIL [EXTRA-JSON]");
        std::process::exit(2);
    }
    let (w, h, r, until): (f64, f64, f64, f64) = (
        a[1].parse().unwrap(),
        a[2].parse().unwrap(),
        a[3].parse().unwrap(),
        a[4].parse().unwrap(),
    );
    let extra = a.get(5).cloned().unwrap_or_default();
    let s = Scene::from_json(&format!(
        r#"{{"particle_radius": {r}, "tank": {{"min": [0, 0], "max": [{w}, {}]}},
            "fluid": [{{"min": [0, 0], "max": [{w}, {h}]}}] {extra} }}"#,
        h * 1.25
    ))
    .unwrap();
    let mut sim = Simulation::new(&s).unwrap();
    let d = 2.0 * r;
    let t0 = std::time::Instant::now();
    let mut vmax_all = 0.0f64;
    let mut next = 0.0;
    let mut its = 0u64;
    let prints: f64 = std::env::var("PRINTS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(10.0);
    {
        let snap = sim.snapshot();
        let top = snap.position.iter().map(|p| p.y).fold(0.0f32, f32::max) as f64 + r;
        let (mean, mx, _) = pressure_error(&snap, w, h, d, top);
        println!("t=0 top={top:.4} p_err vs top: mean={mean:.4} max={mx:.4}");
    }
    while sim.time() < until {
        let st = *sim.step();
        its += st.density_iterations as u64;
        vmax_all = vmax_all.max(st.max_speed);
        if st.max_speed > 0.02 && std::env::var("SPIKES").is_ok() {
            let snap = sim.snapshot();
            let i = (0..snap.position.len())
                .max_by(|&a, &b| {
                    snap.velocity[a]
                        .length()
                        .total_cmp(&snap.velocity[b].length())
                })
                .unwrap();
            println!(
                "  spike t={:.4} v={:.4} at {:?} rho={:.1} it={}",
                st.time, st.max_speed, snap.position[i], snap.density[i], st.density_iterations
            );
        }
        if st.time >= next || st.clamped + st.non_finite > 0 {
            next += until / prints;
            let snap = sim.snapshot();
            let (mean, mx, cnt) = pressure_error(&snap, w, h, d, h);
            println!(
                "t={:.3} dt={:.2e} it={} itv={} vmax={:.4} ke={:.3e} err={:.4}/{:.4} clamp={} p_err mean={:.4} max={:.4} (n={cnt}) wall={:.1}s",
                st.time, st.dt, st.density_iterations, st.divergence_iterations, st.max_speed, st.kinetic_energy,
                st.avg_density_error_pct, st.max_density_error_pct, sim.total_clamped(), mean, mx,
                t0.elapsed().as_secs_f64()
            );
        }
    }
    let snap = sim.snapshot();
    let heff = snap.position.len() as f64 * d * d / w;
    let (mean, mx, cnt) = pressure_error(&snap, w, heff, d, heff);
    let mut bands = std::collections::BTreeMap::<i64, (f64, f64, usize)>::new();
    for (p, pr) in snap.position.iter().zip(&snap.pressure) {
        let (x, y) = (p.x as f64, p.y as f64);
        if x > 3.0 * d && x < w - 3.0 * d {
            let e = bands.entry((10.0 * y / heff).floor() as i64).or_default();
            let err = (*pr as f64 - 1000.0 * 9.81 * (heff - y)) / (1000.0 * 9.81 * heff);
            e.0 += err;
            e.1 = e.1.max(err.abs());
            e.2 += 1;
        }
    }
    for (b, (sum, mx, c)) in &bands {
        println!(
            "  band {b}: mean err {:.4} max {:.4} n={c}",
            sum / *c as f64,
            mx
        );
    }
    let near_wall = snap
        .position
        .iter()
        .zip(&snap.pressure)
        .filter(|(p, _)| (p.x as f64) < 3.0 * d || (p.x as f64) > w - 3.0 * d)
        .map(|(p, pr)| {
            ((*pr as f64 - 1000.0 * 9.81 * (heff - p.y as f64)) / (1000.0 * 9.81 * heff)).abs()
        })
        .fold(0.0f64, f64::max);
    println!("  near side walls: max err {near_wall:.4}");
    // The interior: at least h = 2d from every wall and below the free surface.
    let interior_err = snap
        .position
        .iter()
        .zip(&snap.pressure)
        .filter(|(p, _)| {
            let (x, y) = (p.x as f64, p.y as f64);
            x > 2.0 * d && x < w - 2.0 * d && y > 2.0 * d && y < heff - 2.0 * d
        })
        .map(|(p, pr)| {
            ((*pr as f64 - 1000.0 * 9.81 * (heff - p.y as f64)) / (1000.0 * 9.81 * heff)).abs()
        })
        .fold(0.0f64, f64::max);
    println!("  interior (h from walls and surface): max err {interior_err:.4}");
    let interior: Vec<f64> = snap
        .position
        .iter()
        .zip(&snap.density)
        .filter(|(p, _)| (p.y as f64) < heff - 4.0 * r)
        .map(|(_, &rho)| (rho as f64 / 1000.0 - 1.0).abs() * 100.0)
        .collect();
    println!(
        "  mean |rho/rho0 - 1| more than h below the surface: {:.3} %",
        interior.iter().sum::<f64>() / interior.len().max(1) as f64
    );
    println!("end: H_eff={heff:.4} p_err vs H_eff: mean={mean:.4} max={mx:.4} n={cnt}");
    let mut idx: Vec<usize> = (0..snap.position.len()).collect();
    idx.sort_by(|&a, &b| {
        snap.velocity[b]
            .length()
            .partial_cmp(&snap.velocity[a].length())
            .unwrap()
    });
    for &i in idx.iter().take(6) {
        println!(
            "  fast: x={:.4} y={:.4} v={:?} rho={:.4} p={:.0}",
            snap.position[i].x,
            snap.position[i].y,
            snap.velocity[i],
            snap.density[i],
            snap.pressure[i]
        );
    }
    println!(
        "n={} steps={} vmax_all={:.4} (1% sqrt(gH)={:.4}) mean its={:.1} wall={:.1}s",
        snap.position.len(),
        sim.stats().step,
        vmax_all,
        0.01 * (9.81 * h).sqrt(),
        its as f64 / sim.stats().step as f64,
        t0.elapsed().as_secs_f64()
    );
}

/// Mean and largest `(p − ρ0·g·(top − y))/(ρ0·g·h)` of the particles more than three spacings
/// from the walls, the floor and the nominal surface `h`, and their count.
fn pressure_error(snap: &dfsph::Snapshot, w: f64, h: f64, d: f64, top: f64) -> (f64, f64, usize) {
    let (mut sum, mut max, mut count) = (0.0f64, 0.0f64, 0);
    for (p, pr) in snap.position.iter().zip(&snap.pressure) {
        let (x, y) = (p.x as f64, p.y as f64);
        if x > 3.0 * d && x < w - 3.0 * d && y > 3.0 * d && y < h - 3.0 * d {
            let e = (*pr as f64 - 1000.0 * 9.81 * (top - y)) / (1000.0 * 9.81 * h);
            sum += e;
            max = max.max(e.abs());
            count += 1;
        }
    }
    (sum / count.max(1) as f64, max, count)
}
