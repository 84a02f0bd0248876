//! Shake the dam break right then left and report stability, by hand:
//! `cargo run --release -p dfsph --example shake`.
use dfsph::{scene, Action, Simulation};
fn main() {
    let mut sim = Simulation::new(&scene::builtin("dam-break").unwrap()).unwrap();
    for (dir, until) in [(1.0, 1.0), (-1.0, 2.0), (0.0, 3.0)] {
        sim.apply(&Action::ShakeTank { direction: dir });
        while sim.time() < until {
            let s = *sim.step();
            if std::env::var("ALL").is_ok() && s.step.is_multiple_of(20) {
                println!(
                    "  t={:.4} dt={:.2e} it={} itv={} vmax={:.2} err={:.3}",
                    s.time,
                    s.dt,
                    s.density_iterations,
                    s.divergence_iterations,
                    s.max_speed,
                    s.max_density_error_pct
                );
            }
        }
        let s = sim.stats();
        println!(
            "t={:.2} vmax={:.2} it={} clamps={} nonfinite={} n={}",
            s.time,
            s.max_speed,
            s.density_iterations,
            sim.total_clamped(),
            sim.total_non_finite(),
            sim.fluid_count()
        );
    }
}
