//! Dam-break surge front against Martin & Moyce (1952), Table 2, by hand:
//! `cargo run --release -p dfsph --example front -- 0.01`.
use dfsph::{scene, Simulation};
fn main() {
    let r: f64 = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(0.01);
    let mut sc = scene::builtin("dam-break").unwrap();
    sc.particle_radius = r;
    let mut sim = Simulation::new(&sc).unwrap();
    let mm = [
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
    let s2g = (2.0f64 * 9.81).sqrt();
    let t0 = std::time::Instant::now();
    let (mut k, mut steps, mut its) = (0, 0u64, 0u64);
    while k < mm.len() {
        let s = *sim.step();
        steps += 1;
        its += s.density_iterations as u64;
        if s.time * s2g >= mm[k].0 {
            let z = sim.front_position(3).unwrap_or(0.0);
            println!(
                "T={:.2} Z={:.3} MM={:.2} dev={:+.1}% clamps={} vmax={:.2}",
                mm[k].0,
                z,
                mm[k].1,
                (z / mm[k].1 - 1.0) * 100.0,
                sim.total_clamped(),
                s.max_speed
            );
            k += 1;
        }
    }
    println!(
        "n={} steps={} wall={:.1}s density iterations/step={:.1}",
        sim.fluid_count(),
        steps,
        t0.elapsed().as_secs_f64(),
        its as f64 / steps as f64
    );
}
