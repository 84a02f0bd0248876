//! Shake the dam break right then left and report stability, by hand:
//! `cargo run --release -p dfsph --example shake`.
use dfsph::{scene, Action, Simulation};
fn main() {
    let mut sim = Simulation::new(&scene::builtin("dam-break").unwrap()).unwrap();
    for (dir, until) in [(1.0, 1.0), (-1.0, 2.0), (0.0, 3.0)] {
        sim.apply(&Action::ShakeTank { direction: dir });
        while sim.time() < until {
            sim.step();
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
