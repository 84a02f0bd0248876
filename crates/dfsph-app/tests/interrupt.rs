//! Ctrl-C (or SIGHUP, the terminal closing) during `dfsph2d run`: the run stops after the
//! step in progress, finishes its files and exits with 130; every snapshot on disk is
//! complete, the index lists exactly them, and no temporary file is left behind.

#![cfg(unix)]

use std::process::{Command, Stdio};
use std::thread::sleep;
use std::time::{Duration, Instant};

mod common;

use common::{all_files, BIN};

#[test]
fn ctrl_c_leaves_only_complete_files() {
    stops_cleanly_on("INT");
}

#[test]
fn sighup_stops_like_ctrl_c() {
    stops_cleanly_on("HUP");
}

/// Send `signal` (a name for `kill -SIGNAL`) to a run that is writing frames.
fn stops_cleanly_on(signal: &str) {
    let tmp = tempfile::tempdir().unwrap();
    let scene = tmp.path().join("coarse.json");
    std::fs::write(&scene, r#"{"particle_radius": 0.05}"#).unwrap();
    let out_dir = tmp.path().join("out");
    let mut child = Command::new(BIN)
        .args([
            "run",
            scene.to_str().unwrap(),
            "--until",
            "1000",
            "--every",
            "0.002",
        ])
        .args(["--format", "csv,vtk", "--threads", "2", "--out"])
        .arg(&out_dir)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Wait until it is writing frames, then interrupt it.
    let deadline = Instant::now() + Duration::from_secs(60);
    while !out_dir.join("particles/00020.csv").exists() {
        assert!(Instant::now() < deadline, "no frames appeared");
        assert!(child.try_wait().unwrap().is_none(), "the run ended early");
        sleep(Duration::from_millis(20));
    }
    let status = Command::new("kill")
        .args([&format!("-{signal}"), &child.id().to_string()])
        .status()
        .unwrap();
    assert!(status.success());
    let out = child.wait_with_output().unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(
        out.status.code(),
        Some(130),
        "SIG{signal}: {stdout}{stderr}"
    );
    assert_eq!(stdout.lines().count(), 1, "{stdout}");
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(
        stderr.starts_with("error: interrupted at step "),
        "{stderr}"
    );

    let mut files = Vec::new();
    all_files(&out_dir, &mut files);
    assert!(
        files.iter().all(|f| !f.ends_with(".tmp")),
        "temporary files left: {files:?}"
    );
    let particles = out_dir.join("particles");
    let resolved = std::fs::read_to_string(out_dir.join("scene.json")).unwrap();
    let fluid = dfsph::Scene::from_json(&resolved)
        .unwrap()
        .fluid_particle_count();
    let index = std::fs::read_to_string(particles.join("index.csv")).unwrap();
    let listed: Vec<String> = index
        .lines()
        .skip(1)
        .map(|l| l.rsplit(',').next().unwrap().to_string())
        .collect();
    let csvs = files
        .iter()
        .filter(|f| f.ends_with(".csv") && !f.ends_with("index.csv") && f.contains("particles"))
        .count();
    assert_eq!(listed.len(), csvs, "the index lists every snapshot");
    for name in &listed {
        let text = std::fs::read_to_string(particles.join(name)).unwrap();
        assert!(text.ends_with('\n'), "{name} is cut short");
        let rows: Vec<&str> = text.lines().collect();
        assert_eq!(rows.len(), fluid + 1, "{name}");
        assert!(rows.iter().all(|r| r.split(',').count() == 6), "{name}");
        let vtu = std::fs::read_to_string(particles.join(name.replace(".csv", ".vtu"))).unwrap();
        assert!(
            vtu.trim_end().ends_with("</VTKFile>"),
            "{name}: .vtu cut short"
        );
    }
    let pvd = std::fs::read_to_string(particles.join("particles.pvd")).unwrap();
    assert_eq!(pvd.matches("<DataSet ").count(), listed.len());
    let stats = std::fs::read_to_string(out_dir.join("stats.csv")).unwrap();
    let steps: usize = stderr
        .trim_start_matches("error: interrupted at step ")
        .split(' ')
        .next()
        .unwrap()
        .parse()
        .unwrap();
    assert_eq!(stats.lines().count(), 1 + steps);
}
