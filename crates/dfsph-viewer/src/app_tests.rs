//! The app driven without a window: commands in, the simulation it then runs out.

use super::*;
use dfsph::Vec2;

fn coarse(name: &str) -> Scene {
    let mut s = dfsph::scene::builtin(name).unwrap();
    s.particle_radius = 0.05;
    s
}

fn app(scene: Scene) -> (egui::Context, ViewerApp) {
    let ctx = egui::Context::default();
    let failures: Failures = Rc::new(RefCell::new(Vec::new()));
    let app = ViewerApp::with_context(&ctx, ViewerOptions::new(scene), failures).unwrap();
    (ctx, app)
}

fn drawn_wall_particles(sim: &Simulation) -> usize {
    let first_drawn = 1 + sim.scene().obstacles.len() as u16;
    sim.boundary_bodies()
        .iter()
        .filter(|&&b| b >= first_drawn)
        .count()
}

fn bits(v: &[Vec2]) -> Vec<[u32; 2]> {
    v.iter().map(|p| [p.x.to_bits(), p.y.to_bits()]).collect()
}

#[test]
fn reset_restores_the_scene_as_loaded_not_as_changed() {
    let loaded = coarse("dam-break");
    let (ctx, mut app) = app(loaded.clone());
    let fresh = build_simulation(loaded.clone(), loaded.max_particles).unwrap();

    // Gravity off, another radius, a drawn wall, other settings, some steps.
    app.apply(
        &ctx,
        Command::Sim(Action::SetGravity {
            gravity: Vec2::ZERO,
        }),
    );
    app.apply(&ctx, Command::SetParticleRadius(0.04));
    assert_eq!(app.sim.scene().particle_radius, 0.04);
    app.apply(
        &ctx,
        Command::Sim(Action::AddWall {
            polyline: vec![Vec2::new(2.0, 1.0), Vec2::new(3.0, 1.0)],
        }),
    );
    let mut viscosity = app.sim.scene().viscosity.clone();
    viscosity.xsph = 0.3;
    app.apply(&ctx, Command::Sim(Action::SetViscosity { viscosity }));
    app.apply(
        &ctx,
        Command::Sim(Action::SetGravity {
            gravity: Vec2::new(0.0, -1.0),
        }),
    );
    app.apply(&ctx, Command::Step);
    assert!(drawn_wall_particles(&app.sim) > 0);

    app.apply(&ctx, Command::Reset);
    assert_eq!(app.sim.scene(), fresh.scene());
    assert_eq!(app.sim.scene().particle_radius, 0.05);
    assert_eq!(app.sim.gravity(), Vec2::new(0.0, -9.81));
    assert_eq!(app.radius_edit, 0.05);
    assert_eq!(app.mapper.gravity(), app.sim.gravity());
    assert_eq!(drawn_wall_particles(&app.sim), 0, "drawn walls go");
    assert_eq!(bits(app.sim.positions()), bits(fresh.positions()));
    assert_eq!(app.sim.time(), 0.0);
}

#[test]
fn reset_after_opening_a_saved_scene_brings_back_its_walls_and_water() {
    // Save a state with a drawn wall and moving water.
    let mut sim = Simulation::new(&coarse("dam-break")).unwrap();
    sim.apply(&Action::AddWall {
        polyline: vec![Vec2::new(2.0, 1.0), Vec2::new(3.0, 1.0)],
    });
    for _ in 0..20 {
        sim.step();
    }
    let saved = scene_file::saved_scene(&sim, 1_000_000).unwrap();
    let dir = std::env::temp_dir().join(format!("dfsph-viewer-app-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("saved.json");
    scene_file::write_scene(&path, &saved).unwrap();

    // Open it over another scene, change things, reset.
    let (ctx, mut app) = app(coarse("hydrostatic"));
    app.open_scene(&ctx, scene_file::Opened::from_path(&path));
    assert_eq!(app.sim.fluid_count(), sim.fluid_count());
    let walls = drawn_wall_particles(&sim);
    // The drawn wall is one of the saved scene's obstacles now.
    let wall_bodies = |s: &Simulation| s.boundary_bodies().iter().filter(|&&b| b != 0).count();
    assert_eq!(wall_bodies(&app.sim), walls);
    app.apply(
        &ctx,
        Command::Sim(Action::Erase {
            at: Vec2::new(2.5, 1.0),
            radius: 1.0,
        }),
    );
    assert_eq!(wall_bodies(&app.sim), 0);
    app.apply(&ctx, Command::Step);
    app.apply(&ctx, Command::Reset);
    assert_eq!(wall_bodies(&app.sim), walls);
    assert_eq!(bits(app.sim.positions()), bits(sim.positions()));
    assert_eq!(bits(app.sim.velocities()), bits(sim.velocities()));

    // A bad file is refused with the validator's message; the simulation stays.
    let bad = dir.join("bad.json");
    std::fs::write(&bad, r#"{"gravity": [0, -1e9]}"#).unwrap();
    app.apply(&ctx, Command::Step);
    let steps = app.sim.step_count();
    app.open_scene(&ctx, scene_file::Opened::from_path(&bad));
    assert_eq!(app.sim.step_count(), steps);
    let status = app.status.as_ref().map(|s| s.0.clone()).unwrap_or_default();
    assert!(
        status.contains("bad.json") && status.contains("`gravity`"),
        "{status}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}
