//! The state fingerprint of every built-in scene after a number of steps, one line each:
//! `cargo run --release -p dfsph --example fingerprint [-- STEPS]` (default 200).
//!
//! Two builds that print the same lines computed the same bits. `.ci/run` compares the
//! parallel and the serial (`--no-default-features`) builds on one SIMD path, and the
//! portable path natively with the WebAssembly build (scripts/test-wasm.sh).
use dfsph::recording::fingerprint_hex;
use dfsph::scene::BUILTIN_SCENES;
use dfsph::Simulation;

fn main() {
    let steps: u64 = match std::env::args().nth(1).map(|a| a.parse()) {
        None => 200,
        Some(Ok(n)) => n,
        Some(Err(_)) => {
            eprintln!("error: the number of steps must be a whole number");
            std::process::exit(2);
        }
    };
    for builtin in BUILTIN_SCENES {
        let mut scene = builtin.scene();
        // Coarse enough to take seconds, not minutes, in WebAssembly.
        scene.particle_radius = scene.particle_radius.max(0.02);
        let mut sim = match Simulation::new(&scene) {
            Ok(sim) => sim,
            Err(e) => {
                eprintln!("error: {}: {e}", builtin.name);
                std::process::exit(1);
            }
        };
        for _ in 0..steps {
            sim.step();
        }
        println!(
            "{} {} particles, {} steps, t = {:.6} s: {}",
            builtin.name,
            sim.fluid_count(),
            sim.step_count(),
            sim.time(),
            fingerprint_hex(&sim)
        );
    }
}
