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
    let app = ViewerApp::with_context(&ctx, ViewerOptions::new(scene), failures, None).unwrap();
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
    let fresh = build_simulation(loaded.clone(), loaded.max_particles, None).unwrap();

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
    assert_eq!(app.opened_file, None);
    app.open_scene(&ctx, scene_file::Opened::from_path(&path));
    assert_eq!(app.sim.fluid_count(), sim.fluid_count());
    // The scene list names the file, not the built-in scene the state started as (its
    // scene name is still "dam-break").
    assert_eq!(app.sim.scene().name, "dam-break");
    assert_eq!(app.opened_file.as_deref(), Some("saved.json"));
    assert_eq!(
        crate::panel::scene_list_label(&app.sim.scene().name, app.opened_file.as_deref()),
        "saved.json (file)"
    );
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
    // A refused file leaves the list naming the file that runs; a built-in scene clears it.
    assert_eq!(app.opened_file.as_deref(), Some("saved.json"));
    app.apply(&ctx, Command::LoadScene(0));
    assert_eq!(app.opened_file, None);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// One frame of synthetic input through the app's mapper, as `update` runs it (the pointer
/// given in world coordinates, a body under it found the same way), its commands applied.
fn input_frame(
    ctx: &egui::Context,
    app: &mut ViewerApp,
    events: Vec<egui::Event>,
    pointer: Option<Vec2>,
) -> Vec<Command> {
    let raw = egui::RawInput {
        events,
        ..Default::default()
    };
    let view = ViewInput {
        pointer,
        keyboard: true,
        over_body: pointer.is_some_and(|p| app.sim.rigid_body_at(p).is_some()),
    };
    let mut commands = Vec::new();
    let _ = ctx.run_ui(raw, |ui| {
        commands = ui.ctx().input(|i| app.mapper.update(i, view));
    });
    for cmd in commands.clone() {
        app.apply(ctx, cmd);
    }
    commands
}

fn key_down(key: egui::Key) -> egui::Event {
    egui::Event::Key {
        key,
        physical_key: None,
        pressed: true,
        repeat: false,
        modifiers: egui::Modifiers::NONE,
    }
}

fn primary(pressed: bool) -> egui::Event {
    egui::Event::PointerButton {
        pos: egui::Pos2::new(100.0, 100.0),
        button: egui::PointerButton::Primary,
        pressed,
        modifiers: egui::Modifiers::NONE,
    }
}

fn moved(x: f32) -> egui::Event {
    egui::Event::PointerMoved(egui::Pos2::new(x, 100.0))
}

fn coarse_pool() -> Scene {
    let mut s = dfsph::scene::builtin("hydrostatic").unwrap();
    s.particle_radius = 0.025;
    s
}

#[test]
fn b_and_o_drop_bodies_at_the_cursor_and_a_left_drag_moves_one() {
    let (ctx, mut app) = app(coarse_pool());
    app.mapper.body_density = 800.0;
    let fluid = app.sim.fluid_count();
    let box_at = Vec2::new(0.5, 1.5);
    input_frame(&ctx, &mut app, vec![key_down(egui::Key::B)], Some(box_at));
    input_frame(
        &ctx,
        &mut app,
        vec![key_down(egui::Key::O)],
        Some(Vec2::new(1.5, 0.5)),
    );
    assert_eq!(app.sim.rigid_body_count(), 2, "{:?}", app.status);
    let bodies = app.sim.rigid_bodies();
    assert_eq!(bodies[0].spec.shape, dfsph::scene::BodyShape::Box);
    assert_eq!(bodies[1].spec.shape, dfsph::scene::BodyShape::Circle);
    assert_eq!(bodies[0].spec.density, Some(800.0));
    assert!((bodies[0].position - box_at).length() < 1e-6);
    assert!(
        app.sim.fluid_count() < fluid,
        "the circle dropped in the water displaced some"
    );
    // The rigid bodies' particles are not drawn as walls.
    let t = render::ViewTransform::fit(
        Vec2::ZERO,
        Vec2::new(2.0, 2.0),
        egui::Rect::from_min_size(egui::Pos2::ZERO, egui::vec2(640.0, 480.0)),
    );
    let mesh = render::particle_mesh(
        &app.sim,
        &t,
        egui::TextureId::default(),
        &[],
        WaterLook::Particles,
    );
    let rigid = app
        .sim
        .boundary_bodies()
        .iter()
        .filter(|&&b| app.sim.rigid_body_of(b).is_some())
        .count();
    assert!(rigid > 0);
    let drawn = app.sim.positions().len() + app.sim.boundary_positions().len() - rigid;
    assert_eq!(mesh.vertices.len(), 4 * drawn);

    // Grab the box (the pull tool is ignored on a body) and pull it to the right.
    let grabbed = input_frame(
        &ctx,
        &mut app,
        vec![moved(100.0), primary(true)],
        Some(box_at),
    );
    assert_eq!(grabbed, vec![Command::Sim(Action::GrabBody { at: box_at })]);
    assert_eq!(app.sim.dragged_body().map(|d| d.0), Some(0));
    let target = Vec2::new(1.0, 1.5);
    input_frame(&ctx, &mut app, vec![moved(200.0)], Some(target));
    assert_eq!(app.sim.dragged_body(), Some((0, target)));
    for _ in 0..60 {
        app.apply(&ctx, Command::Step);
    }
    let x = app.sim.rigid_bodies()[0].position.x;
    assert!(x > box_at.x + 0.1, "dragged from {} to {x}", box_at.x);
    input_frame(&ctx, &mut app, vec![primary(false)], Some(target));
    assert_eq!(app.sim.dragged_body(), None);
    assert!(app.grab_anchor.is_none());

    // A press beside the bodies pulls water, as before.
    let out = input_frame(
        &ctx,
        &mut app,
        vec![primary(true)],
        Some(Vec2::new(1.9, 0.1)),
    );
    assert!(
        matches!(out.as_slice(), [Command::Sim(Action::Push { .. })]),
        "{out:?}"
    );
}

#[test]
fn the_panels_drop_buttons_put_bodies_at_the_top_and_a_full_spot_is_refused() {
    let (ctx, mut app) = app(coarse_pool());
    let drop = |shape| Command::DropBody { shape, at: None };
    app.apply(&ctx, drop(dfsph::scene::BodyShape::Box));
    assert_eq!(app.sim.rigid_body_count(), 1);
    let b = &app.sim.rigid_bodies()[0];
    let top = app.sim.scene().tank.max[1] as f32;
    assert!(b.position.y > top - 0.3 && (b.position.x - 1.0).abs() < 1e-6);
    // Another at the same spot is refused with the solver's reason.
    app.apply(&ctx, drop(dfsph::scene::BodyShape::Circle));
    assert_eq!(app.sim.rigid_body_count(), 1);
    let status = app.status.as_ref().map(|s| s.0.clone()).unwrap_or_default();
    assert!(status.contains("rejected"), "{status}");
}

#[test]
fn a_recorded_session_with_bodies_replays_to_the_same_fingerprint() {
    let scene = coarse_pool();
    let dir = std::env::temp_dir().join(format!("dfsph-viewer-bodies-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("session.jsonl");
    let recorder = SessionRecorder::create(&path, &scene).unwrap();
    let (ctx, app) = app(scene);
    let mut app = app.with_recorder(Some(recorder));

    let at = Vec2::new(1.0, 1.4);
    input_frame(&ctx, &mut app, vec![key_down(egui::Key::B)], Some(at));
    app.mapper.body_density = 3000.0;
    input_frame(
        &ctx,
        &mut app,
        vec![key_down(egui::Key::O)],
        Some(Vec2::new(0.4, 1.6)),
    );
    for _ in 0..10 {
        app.apply(&ctx, Command::Step);
    }
    let on_box = app.sim.rigid_bodies()[0].position;
    input_frame(
        &ctx,
        &mut app,
        vec![moved(100.0), primary(true)],
        Some(on_box),
    );
    for (i, x) in [1.1f32, 1.3, 1.5].into_iter().enumerate() {
        input_frame(
            &ctx,
            &mut app,
            vec![moved(110.0 + i as f32)],
            Some(Vec2::new(x, 1.5)),
        );
        for _ in 0..5 {
            app.apply(&ctx, Command::Step);
        }
    }
    input_frame(
        &ctx,
        &mut app,
        vec![primary(false)],
        Some(Vec2::new(1.5, 1.5)),
    );
    for _ in 0..10 {
        app.apply(&ctx, Command::Step);
    }
    assert_eq!(app.sim.rigid_body_count(), 2);
    <ViewerApp as eframe::App>::on_exit(&mut app, None);

    let text = std::fs::read_to_string(&path).unwrap();
    let rec = dfsph::recording::Recording::parse(&text).unwrap();
    let kinds: Vec<_> = rec
        .entries
        .iter()
        .map(|e| serde_json::to_value(&e.action).unwrap()["action"].clone())
        .collect();
    for want in ["add_body", "grab_body", "drag_body", "release_body"] {
        assert!(kinds.iter().any(|k| k == want), "{want} in {kinds:?}");
    }
    let end = rec.end.clone().expect("the session's end");
    let mut sim = Simulation::new(&rec.header.scene).unwrap();
    let mut steps = 0;
    for e in &rec.entries {
        while steps < e.step {
            sim.step();
            steps += 1;
        }
        sim.apply(&e.action);
    }
    while steps < end.end {
        sim.step();
        steps += 1;
    }
    assert_eq!(sim.rigid_body_count(), 2);
    assert_eq!(dfsph::recording::fingerprint_hex(&sim), end.fingerprint);
    assert_eq!(end.fingerprint, dfsph::recording::fingerprint_hex(&app.sim));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn the_steps_run_on_the_threads_chosen_and_a_recording_names_them() {
    let dir = std::env::temp_dir().join(format!("dfsph-viewer-threads-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    for threads in [1, 3] {
        let path = dir.join(format!("session-{threads}.jsonl"));
        let scene = coarse("dam-break");
        let recorder = SessionRecorder::create(&path, &scene).unwrap();
        let ctx = egui::Context::default();
        let failures: Failures = Rc::new(RefCell::new(Vec::new()));
        let app = ViewerApp::with_context(&ctx, ViewerOptions::new(scene), failures, Some(threads))
            .unwrap()
            .with_recorder(Some(recorder));
        assert_eq!(app.sim.threads(), threads);
        let header = std::fs::read_to_string(&path).unwrap();
        let header: dfsph::recording::Header =
            serde_json::from_str(header.lines().next().unwrap()).unwrap();
        assert_eq!(header.threads, threads);
        assert_eq!(header.source, "view");
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn resolution_keys_make_twice_or_half_as_many_particles() {
    let (ctx, mut app) = app(coarse("dam-break"));
    let before = app.sim.fluid_count();
    app.apply(&ctx, Command::ChangeResolution { finer: true });
    assert_eq!(app.sim.scene().particle_radius, 0.035);
    assert_eq!(app.radius_edit, 0.035);
    let finer = app.sim.fluid_count() as f64 / before as f64;
    assert!((1.7..2.3).contains(&finer), "{finer}");
    app.apply(&ctx, Command::ChangeResolution { finer: false });
    app.apply(&ctx, Command::ChangeResolution { finer: false });
    let coarser = app.sim.fluid_count() as f64 / before as f64;
    assert!((0.4..0.6).contains(&coarser), "{coarser}");
    // `R` goes back to the scene as loaded, as with the panel's radius slider.
    app.apply(&ctx, Command::Reset);
    assert_eq!(app.sim.fluid_count(), before);
}

#[test]
fn the_opening_scene_is_fitted_to_a_slow_machine_and_a_chosen_one_is_not() {
    let ctx = egui::Context::default();
    let failures: Failures = Rc::new(RefCell::new(Vec::new()));
    let mut opts = ViewerOptions::new(coarse("dam-break"));
    opts.fit_to_machine = true;
    let mut viewer = ViewerApp::with_context(&ctx, opts, failures, None).unwrap();
    let before = viewer.sim.fluid_count();
    // Measured: 0.4 simulated seconds a wall second. The cost goes as 1/r³, so the radius
    // that keeps 1.5x real time is 0.05·(1.5/0.4)^(1/3) = 0.0777, rounded up to 0.078.
    let measured = |pace: f64, fits: u32| FitMeasure {
        since: Instant::now(),
        simulated: pace * resolution::MEASURE_SECONDS,
        busy: resolution::MEASURE_SECONDS,
        wall: resolution::MEASURE_SECONDS,
        fits,
        before: None,
    };
    viewer.fit = Some(measured(0.4, 0));
    viewer.fit_to_machine(&ctx);
    assert_eq!(viewer.sim.scene().particle_radius, 0.078);
    assert_eq!(
        viewer.loaded.particle_radius, 0.078,
        "R keeps the fitted size"
    );
    let count = viewer.sim.fluid_count();
    assert!(count < before / 2, "{count} of {before}");
    let note = viewer.resolution_note.clone().unwrap();
    assert!(
        note.starts_with(&format!(
            "{count} particles, fitted to this machine ({before} ran"
        )),
        "{note}"
    );
    // It measures again; on pace now, it stays.
    assert_eq!(viewer.fit.map(|m| (m.fits, m.wall)), Some((1, 0.0)));
    viewer.fit = Some(measured(1.5, 1));
    viewer.fit_to_machine(&ctx);
    assert_eq!(viewer.sim.scene().particle_radius, 0.078);
    assert!(viewer.fit.is_none());
    // After the last fit it stops trying, however slow.
    viewer.fit = Some(measured(0.1, resolution::MAX_FITS));
    viewer.fit_to_machine(&ctx);
    assert_eq!(viewer.sim.scene().particle_radius, 0.078);

    // A scene the user chose is never fitted.
    let (_, chosen) = app(coarse("dam-break"));
    assert!(chosen.fit.is_none());
}

/// Undo takes away the last wall drawn, then the last pour (its particles wherever they
/// went), each as an action in the log a recording keeps. A reset forgets what could be
/// undone.
#[test]
fn undo_takes_away_the_last_wall_then_the_last_pour_and_is_recorded() {
    let (ctx, mut app) = app(coarse("dam-break"));
    let n = app.sim.fluid_count();
    for at in [3.0, 3.4] {
        app.apply(
            &ctx,
            Command::Sim(Action::Emit {
                at: Vec2::new(at, 2.0),
                radius: 0.2,
                velocity: Vec2::ZERO,
            }),
        );
    }
    app.undo.end_frame(&app.sim);
    assert!(app.sim.fluid_count() > n);
    app.apply(&ctx, Command::Step);
    app.apply(
        &ctx,
        Command::Sim(Action::AddWall {
            polyline: vec![Vec2::new(2.0, 1.0), Vec2::new(3.0, 1.0)],
        }),
    );
    app.undo.end_frame(&app.sim);
    assert!(drawn_wall_particles(&app.sim) > 0);

    app.apply(&ctx, Command::Undo);
    assert_eq!(drawn_wall_particles(&app.sim), 0);
    assert!(app.sim.fluid_count() > n, "the pour is still there");
    app.apply(&ctx, Command::Undo);
    assert_eq!(app.sim.fluid_count(), n);
    app.apply(&ctx, Command::Undo);
    assert_eq!(
        app.status.as_ref().map(|s| s.0.as_str()),
        Some("nothing to undo")
    );
    let undone: Vec<&Action> = app
        .log
        .iter()
        .map(|l| &l.action)
        .filter(|a| {
            matches!(
                a,
                Action::RemoveDrawnWall { .. } | Action::RemoveParticles { .. }
            )
        })
        .collect();
    assert_eq!(undone.len(), 2, "{undone:?}");

    app.apply(
        &ctx,
        Command::Sim(Action::AddWall {
            polyline: vec![Vec2::new(2.0, 1.0), Vec2::new(3.0, 1.0)],
        }),
    );
    assert!(app.undo.last(&app.sim).is_some());
    app.apply(&ctx, Command::Reset);
    assert_eq!(app.undo.last(&app.sim), None);
}
