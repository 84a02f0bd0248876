//! Recording and replay: the same scene, recording and thread count give byte-identical
//! particle files, and `stress --record` followed by `run --replay` reaches the stress run's
//! final state bit for bit.

use std::path::{Path, PathBuf};
use std::process::Output;

mod common;

use common::{coarse_scene, dfsph2d, dfsph2d_with, replay, text, COARSE};
use dfsph::simd::SimdPath;

/// Every file under `dir/particles`, sorted by name, with its bytes.
fn particle_files(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut files: Vec<(String, Vec<u8>)> = std::fs::read_dir(dir.join("particles"))
        .unwrap()
        .map(|e| {
            let e = e.unwrap();
            (
                e.file_name().to_string_lossy().into_owned(),
                std::fs::read(e.path()).unwrap(),
            )
        })
        .collect();
    files.sort();
    files
}

fn assert_same_files(a: &Path, b: &Path) {
    let (fa, fb) = (particle_files(a), particle_files(b));
    let names = |f: &[(String, Vec<u8>)]| f.iter().map(|(n, _)| n.clone()).collect::<Vec<_>>();
    assert_eq!(names(&fa), names(&fb));
    assert!(fa.len() > 2, "{:?}", names(&fa));
    for ((name, x), (_, y)) in fa.iter().zip(&fb) {
        assert!(x == y, "particles/{name} differs between the runs");
    }
}

/// The stdout of a command that must have succeeded.
fn succeeded(out: Output) -> String {
    let stdout = text(&out.stdout);
    assert!(out.status.success(), "{stdout}{}", text(&out.stderr));
    stdout
}

#[test]
fn two_runs_give_byte_identical_particle_files() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = coarse_scene(tmp.path());
    let (a, b) = (tmp.path().join("a"), tmp.path().join("b"));
    for dir in [&a, &b] {
        succeeded(dfsph2d(&[
            "run",
            scene.to_str().unwrap(),
            "--until",
            "0.5",
            "--every",
            "0.1",
            "--threads",
            "2",
            "--out",
            dir.to_str().unwrap(),
        ]));
    }
    assert_same_files(&a, &b);
    assert_eq!(
        std::fs::read(a.join("stats.csv")).unwrap(),
        std::fs::read(b.join("stats.csv")).unwrap()
    );
}

/// `stress --record`, then replay twice: each replay says it reached the recorded final
/// state, and the two replays' particle files are byte-identical.
fn record_and_replay(seed: &str, steps: &str) -> String {
    let tmp = tempfile::tempdir().unwrap();
    let scene = coarse_scene(tmp.path());
    // Whether or not stress found a violation, the recording reproduces the session.
    let (rec, summary) = stress_recording(tmp.path(), &scene, seed, steps);
    let recording = std::fs::read_to_string(&rec).unwrap();
    let last: serde_json::Value = serde_json::from_str(recording.lines().last().unwrap()).unwrap();
    let fingerprint = last["fingerprint"]
        .as_str()
        .expect("an end line")
        .to_string();
    let n_fluid = last["n_fluid"].as_u64().unwrap() as usize;

    let (a, b) = (tmp.path().join("a"), tmp.path().join("b"));
    for dir in [&a, &b] {
        let stdout = succeeded(replay(
            scene.to_str().unwrap(),
            &rec,
            dir,
            &["--every", "0.05"],
        ));
        assert!(
            stdout.contains(&format!(
                "final state matches the recording ({fingerprint})"
            )),
            "{stdout}"
        );
        assert_eq!(stdout.lines().count(), 1);
    }
    assert_same_files(&a, &b);
    // The last snapshot holds the final state: as many particles as the recording ended with.
    let index = std::fs::read_to_string(a.join("particles/index.csv")).unwrap();
    let last_file = index.lines().last().unwrap().rsplit(',').next().unwrap();
    let rows = std::fs::read_to_string(a.join("particles").join(last_file))
        .unwrap()
        .lines()
        .count();
    assert_eq!(rows, 1 + n_fluid);
    summary
}

#[test]
fn stress_record_then_replay_reproduces_the_final_state() {
    record_and_replay("2", "400");
}

#[test]
fn replay_reproduces_a_session_with_resets() {
    // Seed 3 resets the scene once within its first 500 steps (the summary says so).
    let summary = record_and_replay("3", "500");
    assert!(summary.contains("reset"), "{summary}");
}

/// `stress --record` on `scene`: the recording and the stress summary line. Stress may find a
/// violation (exit 1); the recording is written either way.
fn stress_recording(dir: &Path, scene: &Path, seed: &str, steps: &str) -> (PathBuf, String) {
    let rec = dir.join(format!("seed{seed}.jsonl"));
    let out = dfsph2d(&[
        "stress",
        scene.to_str().unwrap(),
        "--seed",
        seed,
        "--steps",
        steps,
        "--threads",
        "2",
        "--record",
        rec.to_str().unwrap(),
    ]);
    let summary = text(&out.stdout);
    assert!(
        matches!(out.status.code(), Some(0 | 1)),
        "{summary}{}",
        text(&out.stderr)
    );
    (rec, summary)
}

#[test]
fn replay_with_until_runs_by_simulated_time() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = coarse_scene(tmp.path());
    let (rec, _) = stress_recording(tmp.path(), &scene, "5", "200");
    let out_dir = tmp.path().join("out");
    let stdout = succeeded(replay(
        scene.to_str().unwrap(),
        &rec,
        &out_dir,
        &["--until", "0.5"],
    ));
    assert!(
        stdout.contains("--until given, final state not compared"),
        "{stdout}"
    );
    let stats = std::fs::read_to_string(out_dir.join("stats.csv")).unwrap();
    let last_time: f64 = stats
        .lines()
        .last()
        .unwrap()
        .split(',')
        .nth(1)
        .unwrap()
        .parse()
        .unwrap();
    assert!(last_time >= 0.499, "{last_time}");
}

#[test]
fn a_diverging_replay_exits_1_and_says_so() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = coarse_scene(tmp.path());
    let (rec, _) = stress_recording(tmp.path(), &scene, "1", "100");
    // Tamper with the recorded fingerprint.
    let text_in = std::fs::read_to_string(&rec).unwrap();
    let mut lines: Vec<String> = text_in.lines().map(str::to_string).collect();
    let mut end: serde_json::Value = serde_json::from_str(lines.last().unwrap()).unwrap();
    end["fingerprint"] = "0000000000000000".into();
    *lines.last_mut().unwrap() = end.to_string();
    std::fs::write(&rec, lines.join("\n") + "\n").unwrap();
    let out_dir = tmp.path().join("out");
    let out = replay(scene.to_str().unwrap(), &rec, &out_dir, &[]);
    let stderr = text(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.starts_with("error: the replay diverged"), "{stderr}");
    assert_eq!(stderr.lines().count(), 1);
    assert!(text(&out.stdout).contains("DIFFERS"));
}

/// A recording made on the portable SIMD path and replayed on the fastest one: the replay says
/// which path made it; where the final state differs, the error names the setting that
/// replays it bit for bit, and with that setting the final state matches.
#[test]
fn a_replay_on_another_simd_path_says_so() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = coarse_scene(tmp.path());
    let rec = tmp.path().join("portable.jsonl");
    let portable = [("DFSPH2D_SIMD", "portable")];
    let out = dfsph2d_with(
        &[
            "stress",
            scene.to_str().unwrap(),
            "--seed",
            "2",
            "--steps",
            "300",
            "--threads",
            "2",
            "--record",
            rec.to_str().unwrap(),
        ],
        &portable,
    );
    assert!(
        matches!(out.status.code(), Some(0 | 1)),
        "{}",
        text(&out.stderr)
    );
    let recording = std::fs::read_to_string(&rec).unwrap();
    let header: serde_json::Value =
        serde_json::from_str(recording.lines().next().unwrap()).unwrap();
    assert_eq!(header["simd"], "portable");
    let replay_with = |dir: &str, env: &[(&str, &str)]| {
        let out_dir = tmp.path().join(dir);
        let (scene, rec, out_dir) = (scene.to_str().unwrap(), rec.to_str().unwrap(), out_dir);
        let args = [
            "run",
            scene,
            "--replay",
            rec,
            "--out",
            out_dir.to_str().unwrap(),
        ];
        dfsph2d_with(&args, env)
    };
    let fastest = SimdPath::fastest();
    if fastest != SimdPath::Portable {
        let out = replay_with("fastest", &[("DFSPH2D_SIMD", fastest.name())]);
        let (stdout, stderr) = (text(&out.stdout), text(&out.stderr));
        let said = format!("recorded on the portable SIMD path, replayed on {fastest}");
        assert!(stdout.contains(&said), "{stdout}");
        if !out.status.success() {
            assert!(stderr.contains("try DFSPH2D_SIMD=portable"), "{stderr}");
        }
    }
    let out = replay_with("portable", &portable);
    let stdout = succeeded(out);
    assert!(stdout.contains("final state matches"), "{stdout}");
    assert!(!stdout.contains("SIMD path"), "{stdout}");
}

#[test]
fn a_recording_of_another_scene_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = coarse_scene(tmp.path());
    let (rec, _) = stress_recording(tmp.path(), &scene, "1", "20");
    let out_dir = tmp.path().join("out");
    let out = replay("hydrostatic", &rec, &out_dir, &[]);
    let stderr = text(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("was made on a different scene"), "{stderr}");
    assert!(!out_dir.exists());
}

#[test]
fn run_without_until_needs_a_recording() {
    let out = dfsph2d(&["run", "dam-break", "--out", "never"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(text(&out.stderr).contains("--until"));
    assert!(!Path::new("never").exists());
}

/// A recording cut down to its header replays no step and says how much water it holds; one
/// whose last action lies 10¹⁰ steps out is refused naming the recording's length and
/// `--until`, not only the `--every` the user never gave.
#[test]
fn a_header_alone_reports_its_water_and_a_far_action_names_the_recording() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = coarse_scene(tmp.path());
    let (rec, _) = stress_recording(tmp.path(), &scene, "2", "20");
    let header = std::fs::read_to_string(&rec)
        .unwrap()
        .lines()
        .next()
        .unwrap()
        .to_string();
    let n = dfsph::Simulation::new(&dfsph::Scene::from_json(COARSE).unwrap())
        .unwrap()
        .fluid_count();
    let only = tmp.path().join("header.jsonl");
    std::fs::write(&only, format!("{header}\n")).unwrap();
    let stdout = succeeded(replay(
        scene.to_str().unwrap(),
        &only,
        &tmp.path().join("out"),
        &[],
    ));
    assert!(stdout.contains(" 0 steps "), "{stdout}");
    assert!(stdout.contains(&format!("; {n} fluid + ")), "{stdout}");

    let far = tmp.path().join("far.jsonl");
    std::fs::write(
        &far,
        format!("{header}\n{{\"step\":10000000000,\"action\":\"release_pointer\"}}\n"),
    )
    .unwrap();
    let out = replay(scene.to_str().unwrap(), &far, &tmp.path().join("o2"), &[]);
    let stderr = text(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("over the recording's 10000000000 steps")
            && stderr.contains("give --until to replay part of it"),
        "{stderr}"
    );
}
