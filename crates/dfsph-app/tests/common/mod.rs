//! Helpers shared by the integration tests that run the `dfsph2d` binary. Each test file uses
//! its own subset of them.
#![allow(dead_code)]

pub mod xvfb;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The binary under test.
pub const BIN: &str = env!("CARGO_BIN_EXE_dfsph2d");

/// A 200-particle dam break.
pub const COARSE: &str = r#"{"particle_radius": 0.05}"#;

/// Run `dfsph2d` with no display, as on a headless machine, and with backtraces asked for: a
/// panic must never reach a user, and tests that check stderr see one at once if it does.
pub fn dfsph2d(args: &[&str]) -> Output {
    dfsph2d_with(args, &[])
}

/// [`dfsph2d`] with the environment variables `env` set.
pub fn dfsph2d_with(args: &[&str], env: &[(&str, &str)]) -> Output {
    Command::new(BIN)
        .args(args)
        .env_remove("DISPLAY")
        .env_remove("WAYLAND_DISPLAY")
        .env("RUST_BACKTRACE", "1")
        .envs(env.iter().copied())
        .output()
        .expect("dfsph2d runs")
}

/// `dfsph2d run SCENE --replay REC --out OUT`, then `extra`.
pub fn replay(scene: &str, recording: &Path, out_dir: &Path, extra: &[&str]) -> Output {
    let mut args = vec![
        "run",
        scene,
        "--replay",
        recording.to_str().unwrap(),
        "--out",
        out_dir.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    dfsph2d(&args)
}

/// Output bytes as text.
pub fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

/// Write a scene file `dir/name`.
pub fn write_scene(dir: &Path, name: &str, content: &[u8]) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, content).unwrap();
    path
}

/// [`COARSE`] written to `dir/coarse.json`.
pub fn coarse_scene(dir: &Path) -> PathBuf {
    write_scene(dir, "coarse.json", COARSE.as_bytes())
}

/// The rows of a CSV file, split on commas.
pub fn csv_rows(path: &Path) -> Vec<Vec<String>> {
    std::fs::read_to_string(path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .lines()
        .map(|l| l.split(',').map(str::to_string).collect())
        .collect()
}

/// Every file below `dir`, recursively, as paths.
pub fn all_files(dir: &Path, out: &mut Vec<String>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let e = e.unwrap();
        if e.file_type().unwrap().is_dir() {
            all_files(&e.path(), out);
        } else {
            out.push(e.path().to_string_lossy().into_owned());
        }
    }
}
