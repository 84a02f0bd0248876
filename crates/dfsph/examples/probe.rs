use dfsph::{scene, Simulation};
fn main() {
    let args: Vec<String> = std::env::args().collect();
    let name = args.get(1).map(|s| s.as_str()).unwrap_or("hydrostatic");
    let r: f64 = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(0.01);
    let until: f64 = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(1.0);
    let mut sc = scene::builtin(name).unwrap();
    sc.particle_radius = r;
    if let Ok(t) = std::env::var("TOL") {
        sc.solver.density_tolerance_pct = t.parse().unwrap();
    }
    if let Ok(t) = std::env::var("DTMAX") {
        sc.time_step.max = t.parse().unwrap();
    }
    if std::env::var("NOG").is_ok() {
        sc.gravity = [0.0, 0.0];
    }
    if std::env::var("NOX").is_ok() {
        sc.viscosity.xsph = 0.0;
    }
    if std::env::var("DIV").is_ok() {
        sc.solver.divergence_solve = false;
    }
    if std::env::var("NOWS").is_ok() {
        sc.solver.warm_start = false;
    }
    if std::env::var("WC").is_ok() {
        sc.solver.method = dfsph::scene::Method::Wcsph;
    }
    let mut sim = Simulation::new(&sc).unwrap();
    let t0 = std::time::Instant::now();
    let mut next = 0.0;
    let (mut it, mut itv, mut steps) = (0u64, 0u64, 0u64);
    while sim.time() < until {
        let s = *sim.step();
        it += s.density_iterations as u64;
        itv += s.divergence_iterations as u64;
        steps += 1;
        if std::env::var("ALL").is_ok() {
            let (k, _) =
                sim.velocities()
                    .iter()
                    .enumerate()
                    .fold((0, 0.0f32), |(bk, bv), (k, v)| {
                        if v.length() > bv {
                            (k, v.length())
                        } else {
                            (bk, bv)
                        }
                    });
            println!(
                "  fastest at {:?} v={:?}",
                sim.positions()[k],
                sim.velocities()[k]
            );
        }
        if s.time >= next || std::env::var("ALL").is_ok() {
            next += until / 20.0;
            println!("t={:.3} dt={:.2e} it={} itv={} err={:.4}% max={:.3}% div={:.4}% vmax={:.3} ke={:.3e} clamp={} nan={} front={:?} nb={:.2}",
                s.time, s.dt, s.density_iterations, s.divergence_iterations, s.avg_density_error_pct, s.max_density_error_pct, s.divergence_error_pct, s.max_speed, s.kinetic_energy, sim.total_clamped(), sim.total_non_finite(), sim.front_position(3), s.avg_neighbors);
        }
    }
    let (k, _) = sim
        .velocities()
        .iter()
        .enumerate()
        .fold((0, 0.0f32), |(bk, bv), (k, v)| {
            if v.length() > bv {
                (k, v.length())
            } else {
                (bk, bv)
            }
        });
    println!(
        "fastest at {:?} v={:?}",
        sim.positions()[k],
        sim.velocities()[k]
    );
    println!(
        "n={} steps={} wall={:.2}s mean it={:.2} itv={:.2}",
        sim.fluid_count(),
        steps,
        t0.elapsed().as_secs_f64(),
        it as f64 / steps as f64,
        itv as f64 / steps as f64
    );
    // pressure profile (hydrostatic)
    let snap = sim.snapshot();
    let rho0 = 1000.0;
    let g = 9.81;
    let h = sc.fluid[0].max[1];
    let mut rows = std::collections::BTreeMap::new();
    for i in 0..snap.id.len() {
        let y = snap.position[i].y as f64;
        let x = snap.position[i].x as f64;
        if x > 0.3 && x < sc.tank.max[0] - 0.3 {
            let k = (y / (2.0 * r)).floor() as i64;
            let e = rows.entry(k).or_insert((0.0, 0.0, 0usize));
            e.0 += snap.pressure[i] as f64;
            e.1 += snap.density[i] as f64;
            e.2 += 1;
        }
    }
    for (k, (p, d, n)) in rows.iter().step_by(4) {
        let y = (*k as f64 + 0.5) * 2.0 * r;
        println!(
            "y={:.3} p={:.1} expected={:.1} dev%H={:.2} rho={:.2}",
            y,
            p / *n as f64,
            rho0 * g * (h - y),
            (p / *n as f64 - rho0 * g * (h - y)) / (rho0 * g * h) * 100.0,
            d / *n as f64
        );
    }
}
