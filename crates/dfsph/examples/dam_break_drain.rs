//! How a dam break drains, by hand: the validation's dam break (a column a = 1 m wide and
//! 2a high, n² = 2, in a tank 18 m × 3 m, long enough that no wave comes back) at particle
//! radius R, with the general defaults (EXTRA is appended to the scene's JSON object, e.g.
//! `, "packing": "square", "solver": {"pressure_solve": "jacobi"}` for the built-in scene's
//! own settings).
//!
//! `cargo run --release -p dfsph --example dam_break_drain -- R [EXTRA-JSON]`
//!
//! At every time of Martin & Moyce's Table 6 it prints the residual column height
//! H = h/(2a) read where the validation reads it (a water-level probe 2R from the back
//! wall) against the table, and the same level 0.05, 0.1, 0.25 and 0.5 m from the wall:
//! water held back by the wall shows as a level that falls with the distance from it.
//! Every half unit of T = t·√(2g/a) it prints the surge front Z = x/a. At the end: the
//! worst relative error against the table, the mean density iterations per step, the wall
//! time.
use dfsph::{Scene, Simulation};

/// Martin & Moyce (1952) Table 6 (n² = 2, a = 2.25 in): τ = t·√(g/a), H = h/(2a); the file
/// the validation reads.
const TABLE_6: &str = include_str!(concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../dfsph-app/data/validation/martin_moyce_1952_height_n2_a2p25in.csv"
));

fn main() {
    let a: Vec<String> = std::env::args().collect();
    let Some(r) = a.get(1).and_then(|s| s.parse::<f64>().ok()) else {
        eprintln!("usage: dam_break_drain R [EXTRA-JSON]");
        std::process::exit(2);
    };
    let extra = a.get(2).cloned().unwrap_or_default();
    let scene = Scene::from_json(&format!(
        r#"{{"particle_radius": {r}, "tank": {{"min": [0, 0], "max": [18, 3]}},
            "fluid": [{{"min": [0, 0], "max": [1, 2]}}] {extra}}}"#
    ))
    .unwrap_or_else(|e| {
        eprintln!("{e}");
        std::process::exit(2)
    });
    let table: Vec<(f64, f64)> = TABLE_6
        .lines()
        .filter(|l| !l.starts_with('#') && !l.starts_with("tau"))
        .filter_map(|l| {
            let (t, h) = l.split_once(',')?;
            Some((t.trim().parse().ok()?, h.trim().parse().ok()?))
        })
        .collect();
    let mut sim = Simulation::new(&scene).unwrap();
    let g = 9.81f64;
    let (k_tau, k_front) = (g.sqrt(), (2.0 * g).sqrt());
    println!(
        "{} particles, packing {:?}, solve {:?}",
        sim.fluid_count(),
        scene.packing,
        scene.solver.pressure_solve
    );
    let level = |sim: &Simulation, x: f64| dfsph::probes::water_level_at(sim, x as f32) / 2.0;
    let wall = std::time::Instant::now();
    let (mut steps, mut iterations) = (0u64, 0u64);
    let (mut next, mut next_front, mut worst) = (0usize, 0.5f64, 0.0f64);
    while next < table.len() {
        let st = *sim.step();
        steps += 1;
        iterations += st.density_iterations as u64;
        if st.non_finite > 0 {
            println!("non-finite values at t = {:.4} s", st.time);
            std::process::exit(1);
        }
        let t = sim.time();
        if t * k_front >= next_front {
            let z = sim.front_position(3).unwrap_or(0.0);
            println!("T = {:.2}: front Z = {z:.3}", t * k_front);
            next_front += 0.5;
        }
        let (tau, expected) = table[next];
        if t * k_tau >= tau {
            let h = level(&sim, 2.0 * r);
            let error = h / expected - 1.0;
            worst = worst.max(error.abs());
            println!(
                "tau = {tau:.2}: H = {h:.3} against {expected:.2} ({:+.1} %); \
                 at 0.05 / 0.1 / 0.25 / 0.5 m: {:.3} / {:.3} / {:.3} / {:.3}",
                100.0 * error,
                level(&sim, 0.05),
                level(&sim, 0.1),
                level(&sim, 0.25),
                level(&sim, 0.5)
            );
            next += 1;
        }
    }
    println!(
        "worst {:.1} % against Table 6, {:.1} iterations a step over {steps} steps, {:.1} s wall",
        100.0 * worst,
        iterations as f64 / steps as f64,
        wall.elapsed().as_secs_f64()
    );
}
