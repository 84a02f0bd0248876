//! Hostile and broken input: every scene file (and every recording) that is empty, truncated,
//! not an object, deeply nested, huge, binary, a directory or a missing path, or that asks for
//! more particles or memory than the stated budgets, gives one `error:` line naming the
//! problem, exit code 2, no panic or backtrace, and writes nothing — for `run`, `stress` and
//! `view` alike.

use std::path::{Path, PathBuf};
use std::process::Output;

mod common;

use common::{dfsph2d, replay, text};

/// A file of `len` bytes that takes no disk space (a hole).
fn sparse(path: &Path, len: u64) {
    std::fs::File::create(path).unwrap().set_len(len).unwrap();
}

fn nested(depth: usize) -> Vec<u8> {
    let mut s = String::from(r#"{"fluid": "#);
    s.push_str(&"[".repeat(depth));
    s.push_str(&"]".repeat(depth));
    s.push('}');
    s.into_bytes()
}

/// A wall zigzagging across the tank 30,000 times: about 15 million boundary particles.
fn zigzag() -> Vec<u8> {
    let points: Vec<&str> = (0..30_000)
        .map(|i| {
            if i % 2 == 0 {
                "[0.1, 0.1]"
            } else {
                "[3.9, 2.9]"
            }
        })
        .collect();
    format!(
        r#"{{"obstacles": [{{"type": "polyline", "points": [{}]}}]}}"#,
        points.join(", ")
    )
    .into_bytes()
}

/// (file name, content, what the message must say). `None` content: special (see below).
fn scene_cases() -> Vec<(&'static str, Option<Vec<u8>>, &'static str)> {
    vec![
        ("empty.json", Some(b"".to_vec()), "empty"),
        ("blank.json", Some(b" \n\t\r\n".to_vec()), "empty"),
        (
            "truncated.json",
            Some(br#"{"particle_radius": 0.05, "tank": {"min": [0"#.to_vec()),
            "EOF while parsing",
        ),
        (
            "array.json",
            Some(b"[1, 2]".to_vec()),
            "must be a JSON object {...}, got an array",
        ),
        (
            "string.json",
            Some(br#""dam-break""#.to_vec()),
            "must be a JSON object {...}, got a string",
        ),
        (
            "number.json",
            Some(b"42".to_vec()),
            "must be a JSON object {...}, got a number",
        ),
        (
            "null.json",
            Some(b"null".to_vec()),
            "must be a JSON object {...}, got null",
        ),
        (
            "garbage.json",
            Some(b"scene: dam-break".to_vec()),
            "not valid JSON",
        ),
        (
            "trailing.json",
            Some(br#"{} {}"#.to_vec()),
            "unexpected text after the scene",
        ),
        (
            "nested.json",
            Some(nested(100_000)),
            "`fluid[0][0][0]`: invalid type",
        ),
        (
            "nested-array.json",
            Some("[".repeat(100_000).into_bytes()),
            "recursion limit exceeded",
        ),
        ("huge.json", None, "too large"),
        (
            "binary.json",
            Some(vec![0x89, b'P', b'N', b'G', 0x0d, 0x0a, 0x1a, 0xff, 0x00]),
            "not UTF-8",
        ),
        ("nul.json", Some(b"\0\0\0\0".to_vec()), "not valid JSON"),
        (
            "too-many-particles.json",
            Some(br#"{"particle_radius": 0.0005}"#.to_vec()),
            "max_particles",
        ),
        (
            "over-hard-limit.json",
            Some(br#"{"max_particles": 100000000}"#.to_vec()),
            "hard limit",
        ),
        (
            "giant-tank.json",
            Some(br#"{"tank": {"min": [0, 0], "max": [1e7, 1e7]}}"#.to_vec()),
            "lattice sites",
        ),
        (
            "far-tank.json",
            Some(
                br#"{"tank": {"min": [10000, 0], "max": [10001, 1]},
                     "fluid": [{"min": [10000, 0], "max": [10001, 0.5]}]}"#
                    .to_vec(),
            ),
            "`tank.max[0]`: the tank reaches 10001 m from the origin",
        ),
        (
            "far-obstacle.json",
            Some(
                br#"{"obstacles": [{"type": "polyline", "points": [[0, 0], [1e9, 0]]}]}"#.to_vec(),
            ),
            "`obstacles[0].points[1][0]`",
        ),
        (
            "giant-box.json",
            Some(
                br#"{"obstacles": [{"type": "rect", "min": [-1e7, -1e7], "max": [1e7, 1e7]}]}"#
                    .to_vec(),
            ),
            "`obstacles[0].min[0]`",
        ),
        ("zigzag.json", Some(zigzag()), "boundary particles"),
        ("directory", None, "is a directory"),
        ("missing.json", None, "does not exist"),
    ]
}

fn materialise(dir: &Path, name: &str, content: &Option<Vec<u8>>) -> PathBuf {
    let path = dir.join(name);
    match (name, content) {
        (_, Some(bytes)) => std::fs::write(&path, bytes).unwrap(),
        ("huge.json", None) => sparse(&path, 17 * 1024 * 1024),
        ("directory", None) => std::fs::create_dir(&path).unwrap(),
        ("missing.json", None) => {}
        _ => unreachable!(),
    }
    path
}

/// Exit code 2, one `error: ` line naming `needle`, nothing on stdout, no panic, no
/// backtrace, no output directory.
fn assert_refused(out: &Output, needle: &str, out_dir: &Path, what: &str) {
    let stderr = text(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{what}: {stderr}");
    assert_eq!(stderr.lines().count(), 1, "{what}: not one line: {stderr}");
    assert!(stderr.starts_with("error: "), "{what}: {stderr}");
    assert!(
        stderr.contains(needle),
        "{what}: {stderr:?} lacks {needle:?}"
    );
    for bad in ["panicked", "backtrace", "RUST_BACKTRACE"] {
        assert!(!stderr.contains(bad), "{what}: {stderr}");
    }
    assert_eq!(text(&out.stdout), "", "{what}");
    assert!(
        !out_dir.exists(),
        "{what}: output written despite the error"
    );
}

#[test]
fn malformed_scenes_are_refused_by_every_command() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let out_dir = dir.join("never");
    let rec = dir.join("never.jsonl");
    for (name, content, needle) in scene_cases() {
        let path = materialise(dir, name, &content);
        let path = path.to_str().unwrap();
        let run = dfsph2d(&[
            "run",
            path,
            "--until",
            "0.01",
            "--out",
            out_dir.to_str().unwrap(),
        ]);
        assert_refused(&run, needle, &out_dir, &format!("run {name}"));
        let stress = dfsph2d(&[
            "stress",
            path,
            "--steps",
            "5",
            "--record",
            rec.to_str().unwrap(),
        ]);
        assert_refused(&stress, needle, &rec, &format!("stress {name}"));
        let view = dfsph2d(&["view", path, "--record", rec.to_str().unwrap()]);
        assert_refused(&view, needle, &rec, &format!("view {name}"));
    }
}

fn good_recording(dir: &Path) -> (PathBuf, String) {
    let scene = dir.join("coarse.json");
    std::fs::write(&scene, r#"{"particle_radius": 0.05}"#).unwrap();
    let rec = dir.join("good.jsonl");
    let out = dfsph2d(&[
        "stress",
        scene.to_str().unwrap(),
        "--seed",
        "1",
        "--steps",
        "30",
        "--record",
        rec.to_str().unwrap(),
    ]);
    assert!(matches!(out.status.code(), Some(0 | 1)));
    let text = std::fs::read_to_string(&rec).unwrap();
    (scene, text)
}

/// The `"threads":N` of a recording's header, as written.
fn threads_key(recording: &str) -> String {
    let header: serde_json::Value =
        serde_json::from_str(recording.lines().next().unwrap()).unwrap();
    format!("\"threads\":{}", header["threads"])
}

#[test]
fn malformed_recordings_are_refused_naming_the_line() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let (scene, good) = good_recording(dir);
    let lines: Vec<&str> = good.lines().collect();
    let header = lines[0];
    let with_line = |extra: &str| format!("{header}\n{extra}\n").into_bytes();
    let cases: Vec<(&str, Option<Vec<u8>>, &str)> = vec![
        ("empty.jsonl", Some(Vec::new()), "line 1: the recording is empty"),
        (
            "scene.jsonl",
            Some(br#"{"particle_radius": 0.05}"#.to_vec()),
            "line 1: not a dfsph2d recording",
        ),
        (
            "truncated.jsonl",
            Some(header.as_bytes()[..header.len() / 2].to_vec()),
            "line 1: header: not valid JSON",
        ),
        (
            // Without the bound a replay started a million threads (stack overflow) or, later,
            // 4096 of them on a small machine.
            "threads.jsonl",
            Some(
                good.replacen(&threads_key(&good), "\"threads\":1000000", 1)
                    .into_bytes(),
            ),
            "line 1: header: `threads` must be 1 to 1024 worker threads, got 1000000",
        ),
        (
            "version.jsonl",
            Some(good.replacen("\"version\":1", "\"version\":99", 1).into_bytes()),
            "version 99 is not supported",
        ),
        (
            "bad-scene.jsonl",
            Some(good.replacen("\"particle_radius\":0.05", "\"particle_radius\":0", 1).into_bytes()),
            "particle_radius",
        ),
        ("garbage.jsonl", Some(with_line("step 3: push")), "line 2: not valid JSON"),
        ("array.jsonl", Some(with_line("[1, 2]")), "line 2: expected an object"),
        (
            "unknown.jsonl",
            Some(with_line(r#"{"step": 1, "action": "explode"}"#)),
            "line 2: action: unknown variant `explode`",
        ),
        (
            "nested.jsonl",
            Some(with_line(&format!(
                r#"{{"step": 1, "action": "add_wall", "polyline": {}{}}}"#,
                "[".repeat(50_000),
                "]".repeat(50_000)
            ))),
            "line 2: not valid JSON: recursion limit exceeded",
        ),
        (
            "backwards.jsonl",
            Some(with_line(
                "{\"step\": 9, \"action\": \"release_pointer\"}\n{\"step\": 3, \"action\": \"release_pointer\"}",
            )),
            "line 3: step 3 comes after step 9",
        ),
        ("binary.jsonl", Some(vec![0xde, 0xad, 0xbe, 0xef, 0x00]), "not UTF-8"),
        ("huge.jsonl", None, "more than the"),
        ("directory", None, "is a directory"),
        ("missing.jsonl", None, "does not exist"),
    ];
    let out_dir = dir.join("never");
    for (name, content, needle) in cases {
        let path = dir.join(name);
        match (name, &content) {
            (_, Some(bytes)) => std::fs::write(&path, bytes).unwrap(),
            ("huge.jsonl", None) => sparse(&path, 300 * 1024 * 1024),
            ("directory", None) => std::fs::create_dir(&path).unwrap(),
            _ => {}
        }
        let out = replay(scene.to_str().unwrap(), &path, &out_dir, &[]);
        assert_refused(&out, needle, &out_dir, &format!("replay {name}"));
        assert!(
            text(&out.stderr).contains(path.to_str().unwrap()),
            "names the file"
        );
    }
}

#[test]
fn hostile_actions_in_a_recording_are_refused_not_executed() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let (scene, good) = good_recording(dir);
    let header = good.lines().next().unwrap();
    let rec = dir.join("hostile.jsonl");
    std::fs::write(
        &rec,
        format!(
            "{header}\n\
             {{\"step\":0,\"action\":\"add_wall\",\"polyline\":[[0,0],[1e30,0]]}}\n\
             {{\"step\":0,\"action\":\"add_wall\",\"polyline\":[[0,0],[1e6,1e6],[0,0]]}}\n\
             {{\"step\":1,\"action\":\"emit\",\"at\":[1,1],\"radius\":1e30,\"velocity\":[0,0]}}\n\
             {{\"step\":1,\"action\":\"push\",\"at\":[1,1],\"radius\":-1,\"strength\":1e30}}\n\
             {{\"step\":2,\"action\":\"set_gravity\",\"gravity\":[0,-1e30]}}\n\
             {{\"step\":3,\"action\":\"erase\",\"at\":[1,1],\"radius\":0}}\n"
        ),
    )
    .unwrap();
    let out_dir = dir.join("out");
    let out = replay(scene.to_str().unwrap(), &rec, &out_dir, &[]);
    let stdout = text(&out.stdout);
    assert!(out.status.success(), "{stdout}{}", text(&out.stderr));
    assert!(
        stdout.contains("replayed 6 of 6 actions over 3 steps (5 rejected"),
        "{stdout}"
    );
}

/// Run `dfsph2d` with `args`, killed after 30 s: a command that blocks on a FIFO or reads
/// `/dev/zero` for ever fails the test instead of hanging it. `None` when it had to be killed.
fn dfsph2d_within_30s(args: &[&str]) -> Option<Output> {
    use std::process::{Command, Stdio};
    let mut child = Command::new(common::BIN)
        .args(args)
        .env_remove("DISPLAY")
        .env_remove("WAYLAND_DISPLAY")
        .env("RUST_BACKTRACE", "1")
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("dfsph2d runs");
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(30);
    while child.try_wait().unwrap().is_none() {
        if std::time::Instant::now() > deadline {
            child.kill().unwrap();
            child.wait().unwrap();
            return None;
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    Some(child.wait_with_output().unwrap())
}

/// A FIFO at `path` (nobody ever opens its other end).
fn mkfifo(path: &Path) {
    let c = std::ffi::CString::new(path.to_str().unwrap()).unwrap();
    // SAFETY: `c` is a valid NUL-terminated path.
    assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0, "mkfifo");
}

#[test]
fn a_fifo_or_device_is_refused_as_a_recording_without_blocking() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let (scene, _) = good_recording(dir);
    let fifo = dir.join("fifo.jsonl");
    mkfifo(&fifo);
    let out_dir = dir.join("never");
    for path in [
        fifo.as_path(),
        Path::new("/dev/zero"),
        Path::new("/dev/null"),
    ] {
        let shown = path.to_str().unwrap();
        // A replay reading it: the FIFO blocked for ever, /dev/zero was read until memory ran out.
        let args = [
            "run",
            scene.to_str().unwrap(),
            "--replay",
            shown,
            "--out",
            out_dir.to_str().unwrap(),
        ];
        let out = dfsph2d_within_30s(&args).unwrap_or_else(|| panic!("replay {shown} hung"));
        assert_refused(
            &out,
            "is not a regular file",
            &out_dir,
            &format!("replay {shown}"),
        );
        assert!(text(&out.stderr).contains(&format!("recording `{shown}`")));
        // `stress --record` writing it: the FIFO blocked for ever, the devices swallowed the
        // recording and stress exited 0.
        let args = [
            "stress",
            scene.to_str().unwrap(),
            "--steps",
            "5",
            "--record",
            shown,
        ];
        let out = dfsph2d_within_30s(&args).unwrap_or_else(|| panic!("stress {shown} hung"));
        assert_refused(
            &out,
            "is not a regular file",
            &out_dir,
            &format!("stress {shown}"),
        );
        assert!(text(&out.stderr).contains(&format!("--record `{shown}`")));
        // `view --record` the same, refused before any window is opened (with no display
        // here, a test of the order: the recording is checked first).
        let args = ["view", scene.to_str().unwrap(), "--record", shown];
        let out = dfsph2d_within_30s(&args).unwrap_or_else(|| panic!("view {shown} hung"));
        assert_refused(
            &out,
            "is not a regular file (a FIFO, socket or device); give the path of a file",
            &out_dir,
            &format!("view {shown}"),
        );
        assert!(text(&out.stderr).contains(&format!("--record `{shown}`")));
    }
    assert!(fifo.exists(), "the FIFO is left where it was");
}
