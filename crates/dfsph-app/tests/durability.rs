//! Output that survives a hard stop: a run killed with SIGKILL, stopped twice with Ctrl-C or
//! stopped by a full disk keeps the statistics of every completed step and an index of
//! complete frames; a full disk is an I/O error (exit code 74) naming the file, with no
//! `.tmp` left. Recordings: one cut short replays up to where it stops, with a warning, and a
//! replay of a recording with a hundred thousand actions at one step stops on Ctrl-C.

#![cfg(unix)]

use std::os::unix::process::CommandExt;
use std::path::Path;
use std::process::{Child, Command, Output, Stdio};
use std::thread::sleep;
use std::time::{Duration, Instant};

mod common;

use common::{all_files, coarse_scene, dfsph2d, text, BIN};

/// Start `dfsph2d args` with its output piped.
fn spawn(args: &[&str]) -> Child {
    Command::new(BIN)
        .args(args)
        .env_remove("DISPLAY")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap()
}

/// Wait until `ready` holds while `child` runs (a hang guard of 60 s, not a timing check).
fn wait_for(child: &mut Child, what: &str, ready: impl Fn() -> bool) {
    let deadline = Instant::now() + Duration::from_secs(60);
    while !ready() {
        assert!(Instant::now() < deadline, "{what} never happened");
        assert!(child.try_wait().unwrap().is_none(), "the run ended early");
        sleep(Duration::from_millis(20));
    }
}

/// `child`'s output, killing it after 60 s (a hang guard: a run that ignores a signal fails
/// the test instead of hanging it).
fn finish(mut child: Child) -> Output {
    let deadline = Instant::now() + Duration::from_secs(60);
    while child.try_wait().unwrap().is_none() {
        if Instant::now() > deadline {
            child.kill().unwrap();
            panic!("still running 60 s after it was told to stop");
        }
        sleep(Duration::from_millis(20));
    }
    child.wait_with_output().unwrap()
}

fn signal(child: &Child, name: &str) {
    let status = Command::new("kill")
        .args([&format!("-{name}"), &child.id().to_string()])
        .status()
        .unwrap();
    assert!(status.success());
}

/// Frames listed in `particles/index.csv` (without the header).
fn index_rows(out: &Path) -> Vec<String> {
    std::fs::read_to_string(out.join("particles/index.csv"))
        .map(|t| t.lines().skip(1).map(str::to_string).collect())
        .unwrap_or_default()
}

/// What a stopped run must leave, however it stopped: `stats.csv` with its header and one
/// complete row for every step 1..=n in order (n returned); `index.csv` listing frames whose
/// files are all complete, at times the statistics reached; `particles.pvd` (VTK runs) a
/// complete file listing complete frames.
fn assert_completed_output_readable(out: &Path, vtk: bool) -> usize {
    let stats = std::fs::read_to_string(out.join("stats.csv")).unwrap();
    assert!(stats.ends_with('\n'), "stats.csv ends in a partial row");
    let mut lines = stats.lines();
    assert_eq!(lines.next(), Some(dfsph_io_header()));
    let columns = dfsph_io_header().split(',').count();
    let mut last_time = 0.0;
    let mut n = 0;
    for (i, row) in lines.enumerate() {
        let cells: Vec<&str> = row.split(',').collect();
        assert_eq!(cells.len(), columns, "row {}: {row}", i + 1);
        assert_eq!(cells[0], (i + 1).to_string(), "steps in order");
        last_time = cells[1].parse::<f64>().unwrap();
        n = i + 1;
    }
    let particles = out.join("particles");
    let resolved = std::fs::read_to_string(out.join("scene.json")).unwrap();
    let fluid = dfsph::Scene::from_json(&resolved)
        .unwrap()
        .fluid_particle_count();
    let index = std::fs::read_to_string(particles.join("index.csv")).unwrap();
    assert!(index.starts_with("frame,time,file\n") && index.ends_with('\n'));
    let rows = index_rows(out);
    for (k, row) in rows.iter().enumerate() {
        let cells: Vec<&str> = row.split(',').collect();
        assert_eq!(cells[0], k.to_string(), "{row}");
        assert!(
            cells[1].parse::<f64>().unwrap() <= last_time + 1e-12,
            "{row}"
        );
        let csv = std::fs::read_to_string(particles.join(cells[2])).unwrap();
        assert!(csv.ends_with('\n'), "{row}: cut short");
        assert_eq!(csv.lines().count(), fluid + 1, "{row}");
        if vtk {
            let vtu = std::fs::read_to_string(particles.join(cells[2].replace(".csv", ".vtu")));
            assert!(vtu.unwrap().trim_end().ends_with("</VTKFile>"), "{row}");
        }
    }
    if vtk {
        let pvd = std::fs::read_to_string(particles.join("particles.pvd")).unwrap();
        assert!(pvd.trim_end().ends_with("</VTKFile>"), "{pvd}");
        let listed = pvd.matches("<DataSet ").count();
        // Rewritten just after each index row: killed in between, it lags by that frame.
        assert!(
            listed == rows.len() || listed + 1 == rows.len(),
            "{listed} frames in the .pvd, {} in the index",
            rows.len()
        );
        for k in 0..listed {
            assert!(particles.join(format!("{k:05}.vtu")).exists());
        }
    }
    n
}

fn dfsph_io_header() -> &'static str {
    "step,time,dt,n_fluid,density_iterations,divergence_iterations,avg_density_error_pct,\
     max_density_error_pct,max_speed,kinetic_energy,divergence_error_pct,clamped,non_finite,\
     avg_neighbors,n_boundary,retries"
}

/// A long run writing csv and vtk frames every 2 ms of simulated time.
fn long_run(scene: &Path, out: &Path) -> Child {
    spawn(&[
        "run",
        scene.to_str().unwrap(),
        "--until",
        "1000",
        "--every",
        "0.002",
        "--format",
        "csv,vtk",
        "--threads",
        "2",
        "--out",
        out.to_str().unwrap(),
    ])
}

#[test]
fn sigkill_mid_run_keeps_the_completed_statistics_and_index() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = coarse_scene(tmp.path());
    let out = tmp.path().join("out");
    let mut child = long_run(&scene, &out);
    wait_for(&mut child, "five frames", || index_rows(&out).len() >= 5);
    child.kill().unwrap(); // SIGKILL: no handler runs.
    child.wait().unwrap();
    let steps = assert_completed_output_readable(&out, true);
    assert!(steps >= 8, "{steps} steps for 5 frames 2 ms apart");
}

#[test]
fn a_second_ctrl_c_keeps_the_completed_statistics() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = coarse_scene(tmp.path());
    let out = tmp.path().join("out");
    let mut child = long_run(&scene, &out);
    wait_for(&mut child, "five frames", || index_rows(&out).len() >= 5);
    signal(&child, "INT");
    signal(&child, "INT"); // The second one ends the process at once.
    let output = finish(child);
    assert_eq!(output.status.code(), Some(130), "{}", text(&output.stderr));
    assert!(assert_completed_output_readable(&out, true) >= 8);
}

/// A full disk, made with a file-size limit (`ulimit -f`) in the child: writes past 10,000
/// bytes fail (EFBIG). The first snapshot (velocities 0, 5 kB) fits, the second (13 kB) does
/// not: it fails in the atomic writer's last flush, after 20 completed steps.
#[test]
fn a_full_disk_is_an_io_error_that_keeps_the_completed_statistics() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = coarse_scene(tmp.path());
    let out = tmp.path().join("out");
    let mut command = Command::new(BIN);
    command.args([
        "run",
        scene.to_str().unwrap(),
        "--until",
        "1",
        "--every",
        "0.02",
        "--threads",
        "1",
        "--out",
        out.to_str().unwrap(),
    ]);
    // SAFETY: only async-signal-safe calls (signal, setrlimit) between fork and exec.
    unsafe {
        command.pre_exec(|| {
            libc::signal(libc::SIGXFSZ, libc::SIG_IGN);
            let limit = libc::rlimit {
                rlim_cur: 10_000,
                rlim_max: 10_000,
            };
            if libc::setrlimit(libc::RLIMIT_FSIZE, &limit) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            Ok(())
        });
    }
    let output = command.output().unwrap();
    let stderr = text(&output.stderr);
    assert_eq!(output.status.code(), Some(74), "{stderr}");
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    let failed = out.join("particles/00001.csv.tmp");
    assert!(
        stderr.starts_with(&format!(
            "error: cannot write `{}`: File too large (os error 27); the completed output is \
             kept in `{}`",
            failed.display(),
            out.display()
        )),
        "{stderr}"
    );
    assert_eq!(text(&output.stdout), "");
    let mut files = Vec::new();
    all_files(&out, &mut files);
    assert!(files.iter().all(|f| !f.ends_with(".tmp")), "{files:?}");
    let steps = assert_completed_output_readable(&out, false);
    assert_eq!(steps, 20, "the steps up to the failed snapshot");
    assert_eq!(index_rows(&out), ["0,0,00000.csv"]);
    assert!(!out.join("particles/00001.csv").exists());
}

/// A stress recording of `steps` steps on the coarse scene.
fn recording(dir: &Path, steps: &str) -> (String, String) {
    let scene = coarse_scene(dir);
    let rec = dir.join("full.jsonl");
    let out = dfsph2d(&[
        "stress",
        scene.to_str().unwrap(),
        "--seed",
        "3",
        "--steps",
        steps,
        "--record",
        rec.to_str().unwrap(),
    ]);
    assert!(matches!(out.status.code(), Some(0 | 1)));
    (
        scene.to_string_lossy().into_owned(),
        std::fs::read_to_string(&rec).unwrap(),
    )
}

#[test]
fn a_recording_cut_short_replays_what_is_complete_with_a_warning() {
    let tmp = tempfile::tempdir().unwrap();
    let (scene, full) = recording(tmp.path(), "40");
    let lines: Vec<&str> = full.lines().collect();
    assert!(lines.len() >= 4, "{full}");
    // Cut in the middle of the last action line, as a full disk leaves a recording.
    let cut_line = lines.len() - 1; // 1-based: the line before the end line.
    let last_action = lines[cut_line - 1];
    let start = full.find(last_action).unwrap();
    let cut = tmp.path().join("cut.jsonl");
    std::fs::write(&cut, &full[..start + last_action.len() / 2]).unwrap();
    let complete_actions = cut_line - 2;
    let step_of = |line: &str| -> u64 {
        let v: serde_json::Value = serde_json::from_str(line).unwrap();
        v["step"].as_u64().unwrap()
    };
    let last_step = step_of(lines[cut_line - 2]);

    let out_dir = tmp.path().join("out");
    let out = common::replay(&scene, &cut, &out_dir, &[]);
    let stderr = text(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{stderr}");
    assert_eq!(
        stderr,
        format!(
            "warning: recording `{}` is cut short: line {cut_line} is incomplete (the disk \
             filled up or the recorder was stopped while writing it); replaying the {} \
             complete lines before it, {complete_actions} actions up to step {last_step}\n",
            cut.display(),
            cut_line - 1
        )
    );
    let stdout = text(&out.stdout);
    assert!(
        stdout.contains(&format!(
            "replayed {complete_actions} of {complete_actions} actions over {last_step} steps"
        )),
        "{stdout}"
    );
    assert!(stdout.contains("the recording has no end line"), "{stdout}");

    // A malformed line that is not the last stays an error, naming it.
    let broken = tmp.path().join("broken.jsonl");
    std::fs::write(
        &broken,
        full.replacen(last_action, &last_action[..last_action.len() / 2], 1),
    )
    .unwrap();
    let out = common::replay(&scene, &broken, &tmp.path().join("never"), &[]);
    let stderr = text(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.starts_with("error: recording `")
            && stderr.contains(&format!("line {cut_line}: not valid JSON")),
        "{stderr}"
    );
}

/// A recording with 100,000 `emit`s at step 0 (about 15 s of work on this machine): Ctrl-C
/// stops the replay in the middle of them, before step 1, with exit code 130.
#[test]
fn a_replay_stops_on_ctrl_c_in_a_long_run_of_actions() {
    let tmp = tempfile::tempdir().unwrap();
    let (scene, full) = recording(tmp.path(), "5");
    let header = full.lines().next().unwrap();
    let n = 100_000;
    let mut text_ = String::with_capacity(n * 80);
    text_.push_str(header);
    text_.push('\n');
    for _ in 0..n {
        text_.push_str(
            "{\"step\":0,\"action\":\"emit\",\"at\":[1,1],\"radius\":0.1,\"velocity\":[0,0]}\n",
        );
    }
    let rec = tmp.path().join("emits.jsonl");
    std::fs::write(&rec, text_).unwrap();
    let out_dir = tmp.path().join("out");
    let mut child = spawn(&[
        "run",
        &scene,
        "--replay",
        rec.to_str().unwrap(),
        "--out",
        out_dir.to_str().unwrap(),
    ]);
    // Frame 0 is written just before the actions start.
    wait_for(&mut child, "frame 0", || {
        out_dir.join("particles/00000.csv").exists()
    });
    sleep(Duration::from_millis(100));
    signal(&child, "INT");
    let output = finish(child);
    let stdout = text(&output.stdout);
    let stderr = text(&output.stderr);
    assert_eq!(output.status.code(), Some(130), "{stdout}{stderr}");
    assert!(
        stderr.starts_with("error: interrupted at step 0 "),
        "{stderr}"
    );
    let applied: usize = stdout
        .split("replayed ")
        .nth(1)
        .and_then(|s| s.split(' ').next())
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("{stdout}"));
    assert!(applied < n, "all {n} actions were applied: {stdout}");
    assert_eq!(
        assert_completed_output_readable(&out_dir, false),
        0,
        "no step taken"
    );
}

#[test]
fn a_run_of_a_million_steps_says_so_up_front_and_stops_on_ctrl_c() {
    // A legal but very viscous scene: ν = 1 m²/s at d = 1 cm limits Δt to about 1e-5 s, so
    // 20 s take more than a million steps.
    let tmp = tempfile::tempdir().unwrap();
    let scene = common::write_scene(
        tmp.path(),
        "honey.json",
        br#"{"particle_radius": 0.005, "tank": {"min": [0, 0], "max": [0.2, 0.2]},
             "fluid": [{"min": [0, 0], "max": [0.05, 0.05]}],
             "viscosity": {"kinematic": 1}}"#,
    );
    let out = tmp.path().join("out");
    let mut child = Command::new(BIN)
        .args(["run", scene.to_str().unwrap(), "--until", "20", "--out"])
        .arg(&out)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // The note comes before the first step; stop the run once a step is on disk.
    let stderr = child.stderr.take().unwrap();
    let first = std::io::BufRead::lines(std::io::BufReader::new(stderr))
        .next()
        .unwrap()
        .unwrap();
    assert!(
        first.starts_with("note: this run will take at least ")
            && first.contains(" steps (Δt ≤ ")
            && first.contains("Ctrl-C stops it"),
        "{first}"
    );
    let steps: f64 = first
        .trim_start_matches("note: this run will take at least ")
        .split(' ')
        .next()
        .unwrap()
        .parse()
        .unwrap();
    assert!(steps >= 1.0e6, "{first}");
    let deadline = Instant::now() + Duration::from_secs(60);
    while std::fs::read_to_string(out.join("stats.csv"))
        .map(|t| t.lines().count() < 3)
        .unwrap_or(true)
    {
        assert!(Instant::now() < deadline, "no step written within 60 s");
        sleep(Duration::from_millis(20));
    }
    signal(&child, "INT");
    let output = finish(child);
    assert_eq!(output.status.code(), Some(130));
}

#[test]
fn a_short_run_gets_no_note() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = coarse_scene(tmp.path());
    let out = tmp.path().join("out");
    let o = dfsph2d(&[
        "run",
        scene.to_str().unwrap(),
        "--until",
        "0.01",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));
    assert!(!text(&o.stderr).contains("note:"), "{}", text(&o.stderr));
}

/// Links planted in the output directory where the run writes (`stats.csv`,
/// `particles/index.csv`, a frame's temporary file) are replaced by the run's files; the
/// files they pointed to, outside the directory, are left as they were.
#[test]
fn links_planted_in_the_output_directory_are_replaced_not_written_through() {
    let dir = tempfile::tempdir().unwrap();
    let scene = coarse_scene(dir.path());
    let victims = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    std::fs::create_dir_all(out.join("particles")).unwrap();
    let planted = [
        "stats.csv",
        "particles/index.csv",
        "particles/00000.csv.tmp",
    ];
    for (k, name) in planted.iter().enumerate() {
        let victim = victims.path().join(format!("victim{k}"));
        std::fs::write(&victim, "keep me\n").unwrap();
        std::os::unix::fs::symlink(&victim, out.join(name)).unwrap();
    }
    let run = dfsph2d(&[
        "run",
        scene.to_str().unwrap(),
        "--until",
        "0.05",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(run.status.success(), "{}", text(&run.stderr));
    for k in 0..planted.len() {
        let victim = victims.path().join(format!("victim{k}"));
        assert_eq!(std::fs::read_to_string(victim).unwrap(), "keep me\n");
    }
    let stats = std::fs::symlink_metadata(out.join("stats.csv")).unwrap();
    assert!(!stats.file_type().is_symlink());
    assert!(std::fs::read_to_string(out.join("stats.csv"))
        .unwrap()
        .starts_with("step,"));
}
