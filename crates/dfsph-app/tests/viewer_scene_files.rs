//! Scene files through the viewer's window, under a virtual X display (`common::xvfb`;
//! without `Xvfb` and `xdotool` the tests print a note and pass):
//!
//! - a scene at a radius the old slider range lacked (r = 0.0025, 80,000 particles) runs as
//!   written: every particle, at its own radius;
//! - the state the viewer saves (`--save-on-exit DIR` writes `DIR/scene.json`; Ctrl+S writes
//!   `scene-<time>.json` in the current directory) runs again with `dfsph2d run`, with the
//!   same particles.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::thread::sleep;
use std::time::{Duration, Instant};

use common::xvfb::{find_window, focus, missing_tools, xdotool, KillOnDrop, Xvfb};
use dfsph::Scene;

/// What the viewer prints when it cannot connect to the X server; such a start is tried
/// again (see `viewer_xvfb.rs`: on a loaded machine the first connection sometimes fails).
const NO_X_CONNECTION: &str = "Failed to open connection to X server";

fn tools_missing() -> bool {
    let missing = missing_tools();
    if !missing.is_empty() {
        eprintln!(
            "note: skipping the viewer test, {} not installed",
            missing.join(" and ")
        );
    }
    !missing.is_empty()
}

/// `dfsph2d view SCENE --exit-after SECS --save-on-exit DIR`, run in `cwd`; with `keys`, they are
/// pressed together in the window once it shows (a chord: `["ctrl", "s"]`). Returns once the viewer
/// has exited successfully; panics with its output otherwise.
fn view(display: &str, scene: &Path, exit_after: f64, dir: &Path, cwd: &Path, keys: &[&str]) {
    let log_path = dir.with_extension("log");
    for attempt in 1..=3 {
        let log = std::fs::File::create(&log_path).unwrap();
        let child = Command::new(common::BIN)
            .arg("view")
            .arg(scene)
            .args(["--exit-after", &exit_after.to_string(), "--save-on-exit"])
            .arg(dir)
            .current_dir(cwd)
            .env("DISPLAY", display)
            .env_remove("WAYLAND_DISPLAY")
            .env("LIBGL_ALWAYS_SOFTWARE", "1")
            .stdin(Stdio::null())
            .stdout(log.try_clone().unwrap())
            .stderr(log)
            .spawn()
            .expect("starting dfsph2d view");
        let mut viewer = KillOnDrop(child, "dfsph2d view");
        if !keys.is_empty() {
            if let Ok(wid) = find_window(display, &mut viewer) {
                focus(display, &wid);
                // Held a moment each: a chord sent at once (`xdotool key ctrl+s`) reached
                // the window without its modifier.
                for k in keys {
                    xdotool(display, &["keydown", k]);
                    sleep(Duration::from_millis(300));
                }
                for k in keys.iter().rev() {
                    xdotool(display, &["keyup", k]);
                    sleep(Duration::from_millis(200));
                }
            }
        }
        let deadline = Instant::now() + Duration::from_secs_f64(exit_after + 90.0);
        let status = loop {
            if let Some(s) = viewer.0.try_wait().unwrap() {
                break s;
            }
            assert!(Instant::now() < deadline, "the viewer did not exit");
            sleep(Duration::from_millis(100));
        };
        let log = std::fs::read_to_string(&log_path).unwrap_or_default();
        if status.success() {
            return;
        }
        if !(log.contains(NO_X_CONNECTION) && attempt < 3) {
            panic!("dfsph2d view failed: {status}\n{log}");
        }
        sleep(Duration::from_millis(500));
    }
}

/// Data rows of a particle CSV (`x,y,vx,vy,...`) as (x, y).
fn csv_positions(path: &Path) -> Vec<(f64, f64)> {
    let rows = common::csv_rows(path);
    assert!(rows[0][0] == "x", "{}: {:?}", path.display(), rows[0]);
    rows[1..]
        .iter()
        .map(|r| (r[0].parse().unwrap(), r[1].parse().unwrap()))
        .collect()
}

fn read_scene(path: &Path) -> Scene {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    Scene::from_json(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn session_particles(dir: &Path) -> u64 {
    let text = std::fs::read_to_string(dir.join("session.json")).unwrap();
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    v["fluid_particles"].as_u64().unwrap()
}

#[test]
fn a_fine_scene_opens_with_every_particle_at_its_own_radius() {
    if tools_missing() {
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    // The dam break's 1 m x 2 m column at d = 5 mm: about 80,000 particles. The slider used
    // to restart it at r = 0.004 (31,250 particles) in the first frame.
    let scene_path =
        common::write_scene(tmp.path(), "fine.json", br#"{"particle_radius": 0.0025}"#);
    let expected = read_scene(&scene_path).fluid_particle_count();
    assert!((79_000..=80_000).contains(&expected), "{expected}");
    let out = tmp.path().join("out");
    let xvfb = Xvfb::start();
    // Long enough for frames after the first (the slider runs in each).
    view(&xvfb.display(), &scene_path, 2.5, &out, tmp.path(), &[]);

    assert_eq!(csv_positions(&out.join("particles.csv")).len(), expected);
    assert_eq!(session_particles(&out), expected as u64);
    let saved = read_scene(&out.join("scene.json"));
    assert_eq!(saved.particle_radius, 0.0025);
    assert_eq!(saved.particles.len(), expected);
}

#[test]
fn a_saved_viewer_state_runs_again_with_run() {
    if tools_missing() {
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let scene_path = common::write_scene(
        tmp.path(),
        "dam.json",
        br#"{"name": "dam", "particle_radius": 0.02}"#,
    );
    let out = tmp.path().join("out");
    let cwd = tmp.path().join("cwd");
    std::fs::create_dir_all(&cwd).unwrap();
    let xvfb = Xvfb::start();
    view(
        &xvfb.display(),
        &scene_path,
        6.0,
        &out,
        &cwd,
        &["ctrl", "s"],
    );

    // --save-on-exit: the particles, the session and the scene agree.
    let saved_path = out.join("scene.json");
    let saved = read_scene(&saved_path);
    let n = saved.particles.len();
    assert_eq!(
        n,
        read_scene(&scene_path).fluid_particle_count(),
        "the 1 m x 2 m column at d = 4 cm"
    );
    assert_eq!(csv_positions(&out.join("particles.csv")).len(), n);
    assert_eq!(session_particles(&out), n as u64);
    assert!(saved.fluid.is_empty());

    // Ctrl+S: a timestamped scene in the viewer's current directory, which loads.
    let pressed: Vec<PathBuf> = std::fs::read_dir(&cwd)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| {
            let name = p.file_name().unwrap().to_string_lossy();
            name.starts_with("scene-") && name.ends_with(".json")
        })
        .collect();
    assert_eq!(pressed.len(), 1, "Ctrl+S wrote {pressed:?}");
    assert_eq!(read_scene(&pressed[0]).particles.len(), n);

    // `run` takes the saved scene: the same particles where they were saved, all of them
    // to the end.
    let run_out = tmp.path().join("run");
    let o = Command::new(common::BIN)
        .arg("run")
        .arg(&saved_path)
        .args(["--until", "0.01", "--every", "0.005", "--out"])
        .arg(&run_out)
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "{}{}",
        common::text(&o.stdout),
        common::text(&o.stderr)
    );
    let index = common::csv_rows(&run_out.join("particles").join("index.csv"));
    let first = csv_positions(&run_out.join("particles").join(&index[1][2]));
    let last = csv_positions(&run_out.join("particles").join(&index[index.len() - 1][2]));
    assert!(index.len() >= 3, "{index:?}");
    assert_eq!((first.len(), last.len()), (n, n));
    for (k, (a, p)) in first.iter().zip(&saved.particles.positions).enumerate() {
        assert!(
            (a.0 - p[0]).abs() < 1e-6 && (a.1 - p[1]).abs() < 1e-6,
            "particle {k}: run starts at {a:?}, the scene says {p:?}"
        );
    }
}
