//! Physics checks at small particle counts: rest state, hydrostatic tank, dam break, WCSPH.

use dfsph::scene::{self, Method};
use dfsph::{Scene, Simulation};

fn coarse(name: &str, radius: f64) -> Scene {
    let mut s = scene::builtin(name).expect("built-in scene");
    s.particle_radius = radius;
    s
}

#[test]
fn fluid_starts_at_rest_density() {
    for name in ["dam-break", "hydrostatic", "double-dam-break", "drop"] {
        let s = coarse(name, 0.02);
        let sim = Simulation::new(&s).unwrap();
        let d = s.spacing() as f32;
        let mut checked = 0;
        for (i, p) in sim.positions().iter().enumerate() {
            // Interior: farther than one kernel support from every block edge that is a free
            // surface (edges lying on a tank wall are not).
            let (x, y, h) = (p.x as f64, p.y as f64, 2.0 * d as f64);
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
                    "{name}: particle at {p:?} starts {:.4} % off ρ0",
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
fn hydrostatic_tank_settles_to_the_right_pressure() {
    let s = coarse("hydrostatic", 0.025);
    let mut sim = Simulation::new(&s).unwrap();
    let n0 = sim.fluid_count();
    while sim.time() < 5.0 {
        sim.step();
    }
    let stats = *sim.stats();
    assert!(stats.avg_density_error_pct <= 0.1, "{stats:?}");
    assert_eq!(sim.total_clamped(), 0);
    assert_eq!(sim.total_non_finite(), 0);
    assert_eq!(sim.fluid_count(), n0);
    // Pressure away from the walls and the free surface, against ρ0 g (H − y), averaged per
    // lattice row to remove particle noise.
    let snap = sim.snapshot();
    let (rho0, g, depth) = (1000.0, 9.81, 1.0);
    let d = s.spacing();
    let mut rows = std::collections::BTreeMap::<i64, (f64, usize)>::new();
    for (p, pr) in snap.position.iter().zip(&snap.pressure) {
        let (x, y) = (p.x as f64, p.y as f64);
        if x > 0.3 && x < 1.7 && y > 0.3 && y < 0.9 {
            let e = rows.entry((y / d).floor() as i64).or_default();
            e.0 += *pr as f64;
            e.1 += 1;
        }
    }
    assert!(rows.len() > 5);
    for (row, (sum, count)) in rows {
        let y = (row as f64 + 0.5) * d;
        let expected = rho0 * g * (depth - y);
        let got = sum / count as f64;
        assert!(
            (got - expected).abs() < 0.02 * rho0 * g * depth,
            "row at y = {y:.3}: p = {got:.0} Pa, expected {expected:.0} Pa"
        );
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
