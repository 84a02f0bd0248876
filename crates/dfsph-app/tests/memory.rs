//! Issue 32: a scene that needs more memory than the process may use is refused before
//! anything big is allocated: one `error:` line saying how much it needs and which limit it
//! exceeds, exit code 2, nothing written. (A 49-million-particle scene died at 6.3 GB with
//! `memory allocation of 32768 bytes failed` and a backtrace.) The limits here are small and
//! passed in (`--max-memory`, `ulimit -v`): no test allocates gigabytes.

use std::process::Command;

mod common;

use common::{dfsph2d, text, write_scene, BIN};

/// A dam break at r = 5 mm: 20,000 fluid particles, about 43 MiB by the estimate.
const FINE: &str = r#"{"particle_radius": 0.005}"#;

/// The fluid particles of the scene `json` (about 20,000 for [`FINE`]).
fn fluid_count(json: &str) -> usize {
    dfsph::Scene::from_json(json)
        .unwrap()
        .fluid_particle_count()
}

/// One `error:` line naming the need and the limit, exit 2, no panic, nothing on stdout.
fn assert_refused(out: &std::process::Output, needle: &str) -> String {
    let stderr = text(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(
        stderr.starts_with("error: ") && stderr.contains("the scene needs about "),
        "{stderr}"
    );
    assert!(stderr.contains(needle), "{stderr:?} lacks {needle:?}");
    assert!(!stderr.contains("panicked") && !stderr.contains("memory allocation"));
    assert_eq!(text(&out.stdout), "");
    stderr
}

#[test]
fn run_refuses_a_scene_above_max_memory_and_writes_nothing() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = write_scene(tmp.path(), "fine.json", FINE.as_bytes());
    let out_dir = tmp.path().join("out");
    let args = |max: &'static str| {
        vec![
            "run".to_string(),
            scene.to_str().unwrap().to_string(),
            "--until".into(),
            "0.002".into(),
            "--out".into(),
            out_dir.to_str().unwrap().to_string(),
            "--max-memory".into(),
            max.into(),
        ]
    };
    let run = |max| {
        let a = args(max);
        dfsph2d(&a.iter().map(String::as_str).collect::<Vec<_>>())
    };
    let out = run("16M");
    let stderr = assert_refused(&out, "more than --max-memory (16.0 MiB)");
    assert!(
        stderr.starts_with(&format!(
            "error: scene `{}`: the scene needs about ",
            scene.display()
        )) && stderr.contains(&format!(" of memory ({} fluid and ", fluid_count(FINE)))
            && stderr.ends_with("; use fewer or larger particles\n"),
        "{stderr}"
    );
    assert!(!out_dir.exists(), "output written despite the refusal");
    // The same scene under a limit it fits runs; plain bytes are accepted too.
    let out = run("1073741824");
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    assert!(out_dir.join("stats.csv").is_file());
}

#[test]
fn stress_view_and_validate_check_max_memory_too() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = write_scene(tmp.path(), "fine.json", FINE.as_bytes());
    let scene = scene.to_str().unwrap();
    // stress plans for its pour budget: the scene's fluid and as much again.
    let out = dfsph2d(&["stress", scene, "--steps", "1", "--max-memory", "40M"]);
    assert_refused(&out, &format!("({} fluid and ", 2 * fluid_count(FINE)));
    // view refuses before opening a window (these tests have no display).
    let out = dfsph2d(&["view", scene, "--max-memory", "1M"]);
    assert_refused(&out, "more than --max-memory (1.00 MiB)");
    let out_dir = tmp.path().join("report");
    let out = dfsph2d(&[
        "validate",
        "--quick",
        "--out",
        out_dir.to_str().unwrap(),
        "--max-memory",
        "1M",
    ]);
    let stderr = assert_refused(&out, "more than --max-memory (1.00 MiB)");
    assert!(stderr.starts_with("error: validation scene `"), "{stderr}");
    assert!(!out_dir.exists(), "validate wrote its report directory");
}

#[test]
fn a_size_that_is_not_a_size_is_a_usage_error() {
    for bad in ["2X", "-1G", "0", "lots"] {
        let arg = format!("--max-memory={bad}");
        let out = dfsph2d(&["run", "dam-break", "--until", "1", "--out", "never", &arg]);
        let stderr = text(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{bad}: {stderr}");
        assert!(stderr.contains("--max-memory"), "{bad}: {stderr}");
    }
}

/// `ulimit -v` (RLIMIT_AS) below the estimate: the same one line, naming the address-space
/// limit, instead of an allocation failure. The scene holds 2,000,000 particles (about 1 GiB
/// by the estimate) and is refused before any is allocated.
#[test]
#[cfg(unix)]
fn an_address_space_limit_below_the_estimate_is_one_error_line() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = write_scene(
        tmp.path(),
        "big.json",
        br#"{"particle_radius": 0.0005, "max_particles": 5000000}"#,
    );
    let out_dir = tmp.path().join("out");
    let script = format!(
        "ulimit -v 262144 && exec \"$0\" run '{}' --until 0.01 --out '{}'",
        scene.display(),
        out_dir.display()
    );
    let out = Command::new("sh")
        .args(["-c", &script, BIN])
        .env("RUST_BACKTRACE", "1")
        .output()
        .expect("sh runs");
    let stderr = assert_refused(
        &out,
        "more than what the address-space limit (ulimit -v) of 256 MiB leaves (",
    );
    let needle = format!(
        "({} fluid and ",
        fluid_count(r#"{"particle_radius": 0.0005, "max_particles": 5000000}"#)
    );
    assert!(stderr.contains(&needle), "{stderr}");
    assert!(!out_dir.exists(), "output written despite the refusal");
}
