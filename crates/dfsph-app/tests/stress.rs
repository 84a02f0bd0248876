//! `dfsph2d stress`: seeded random sessions of the viewer's actions at small particle counts,
//! with every invariant checked (see `dfsph2d stress --help`). A failure here names the seed,
//! the step and the violation; reproduce it with
//! `dfsph2d stress SCENE --seed N --steps K --record rec.jsonl` and
//! `dfsph2d run SCENE --replay rec.jsonl --out DIR`.

use std::path::{Path, PathBuf};

mod common;

use common::{dfsph2d, text, COARSE};

/// Coarse scenes: a 200-particle dam break and a 200-particle hydrostatic tank.
fn scenes(dir: &Path) -> Vec<PathBuf> {
    let coarse = [
        ("dam-break-coarse.json", COARSE),
        (
            "hydrostatic-coarse.json",
            r#"{"particle_radius": 0.05, "tank": {"min": [0, 0], "max": [2, 2]},
                "fluid": [{"min": [0, 0], "max": [2, 1]}]}"#,
        ),
    ];
    coarse
        .iter()
        .map(|(name, json)| {
            let path = dir.join(name);
            std::fs::write(&path, json).unwrap();
            path
        })
        .collect()
}

#[test]
fn stress_passes_at_small_n_over_several_seeds() {
    let tmp = tempfile::tempdir().unwrap();
    let mut failures = Vec::new();
    for scene in scenes(tmp.path()) {
        for seed in 1..=4 {
            let seed = seed.to_string();
            let out = dfsph2d(&[
                "stress",
                scene.to_str().unwrap(),
                "--seed",
                &seed,
                "--steps",
                "400",
                "--threads",
                "2",
            ]);
            let stdout = text(&out.stdout);
            let stderr = text(&out.stderr);
            assert_eq!(
                stdout.lines().count(),
                1,
                "one summary line: {stdout}{stderr}"
            );
            assert!(!stderr.contains("panicked"), "{stderr}");
            assert!(
                stdout.starts_with("stress ")
                    && stdout.contains(&format!("seed={seed} steps=400: ")),
                "{stdout}"
            );
            match out.status.code() {
                Some(0) => assert!(stdout.contains(": ok — "), "{stdout}"),
                Some(1) => {
                    assert!(stdout.contains(": FAILED at step "), "{stdout}");
                    failures.push(stdout.trim().to_string());
                }
                other => panic!("exit code {other:?}: {stdout}{stderr}"),
            }
        }
    }
    assert!(
        failures.is_empty(),
        "stress found violations:\n{}",
        failures.join("\n")
    );
}

#[test]
fn a_violation_exits_1_with_one_line_naming_it_and_its_step() {
    // A density bound no solver meets: the first step violates it.
    let tmp = tempfile::tempdir().unwrap();
    let scene = &scenes(tmp.path())[0];
    let out = dfsph2d(&[
        "stress",
        scene.to_str().unwrap(),
        "--seed",
        "1",
        "--steps",
        "50",
        "--density-bound",
        "0.000001",
    ]);
    let stdout = text(&out.stdout);
    assert_eq!(out.status.code(), Some(1), "{stdout}");
    assert_eq!(text(&out.stderr), "", "the summary line says it all");
    assert_eq!(stdout.lines().count(), 1, "{stdout}");
    assert!(
        stdout.contains("FAILED at step ")
            && stdout.contains("max density error")
            && stdout.contains("above the bound of 0.000001 %"),
        "{stdout}"
    );
}

#[test]
fn the_same_seed_gives_the_same_summary() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = &scenes(tmp.path())[0];
    let run = |seed: &str| {
        text(
            &dfsph2d(&[
                "stress",
                scene.to_str().unwrap(),
                "--seed",
                seed,
                "--steps",
                "300",
                "--threads",
                "2",
            ])
            .stdout,
        )
    };
    let a = run("7");
    assert_eq!(a, run("7"));
    assert_ne!(a, run("8"));
}

#[test]
fn help_states_every_check_and_the_density_bound() {
    let out = dfsph2d(&["stress", "--help"]);
    assert!(out.status.success());
    let help = text(&out.stdout);
    for needle in [
        "--seed",
        "--steps",
        "--record",
        "non-finite",
        "outside the tank",
        "initial + poured − erased",
        "clamped",
        "--density-bound",
        "default 5 %",
    ] {
        assert!(
            help.contains(needle),
            "`stress --help` lacks {needle:?}:\n{help}"
        );
    }
}

#[test]
fn bad_arguments_and_scenes_exit_2_without_a_panic() {
    let tmp = tempfile::tempdir().unwrap();
    for args in [
        vec!["stress", "no-such-scene"],
        vec!["stress", "dam-break", "--steps", "0"],
        vec!["stress", "dam-break", "--seed", "-1"],
        vec!["stress", "dam-break", "--density-bound", "0"],
        vec!["stress", "dam-break", "--density-bound", "NaN"],
    ] {
        let out = dfsph2d(&args);
        let stderr = text(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(!stderr.contains("panicked"), "{stderr}");
    }
    // --record into a directory: refused before anything runs.
    let out = dfsph2d(&[
        "stress",
        "dam-break",
        "--record",
        tmp.path().to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(text(&out.stderr).contains("is a directory"));
}
