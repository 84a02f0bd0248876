//! `dfsph2d bench --quick --json FILE`: the benchmark runs end to end and its JSON rows carry
//! every documented key with sane values. No wall-time assertions: a benchmark is a command,
//! not a test (docs/BENCHMARK.md).

use std::process::Command;

const BIN: &str = env!("CARGO_BIN_EXE_dfsph2d");

#[test]
fn quick_bench_writes_sane_json_rows() {
    let dir = tempfile::tempdir().unwrap();
    let json = dir.path().join("bench.json");
    let plot = dir.path().join("bench.svg");
    let out = Command::new(BIN)
        .args([
            "bench",
            "--quick",
            "--codes",
            "dfsph2d",
            "--threads",
            "1,2",
            "--json",
        ])
        .arg(&json)
        .arg("--plot")
        .arg(&plot)
        .output()
        .expect("dfsph2d runs");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "stdout:\n{stdout}\nstderr:\n{stderr}");
    assert!(
        stdout.contains("dfsph2d") && stdout.contains("quick"),
        "{stdout}"
    );

    let rows: Vec<serde_json::Value> =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(rows.len(), 2, "one row per thread count: {rows:?}");
    for (row, threads) in rows.iter().zip([1, 2]) {
        for key in [
            "code",
            "n",
            "sim_seconds",
            "wall_seconds",
            "steps",
            "particle_steps_per_second",
            "avg_density_iterations",
            "avg_divergence_iterations",
            "peak_rss_bytes",
            "threads",
            "front_x",
        ] {
            assert!(row.get(key).is_some(), "`{key}` missing from {row}");
        }
        let num = |key: &str| row[key].as_f64().unwrap_or_else(|| panic!("{key}: {row}"));
        assert_eq!(row["code"], "dfsph2d");
        assert_eq!(row["threads"], threads);
        assert_eq!(num("n"), 1250.0, "25 x 50 lattice at d = 0.04 m");
        assert!(num("steps") > 0.0);
        assert!(num("sim_seconds") >= 0.1 - 1e-9 && num("sim_seconds") < 0.11);
        assert!(num("wall_seconds") > 0.0);
        assert!(num("particle_steps_per_second") > 0.0);
        assert!(num("avg_density_iterations") >= 2.0);
        assert!(num("avg_divergence_iterations") >= 2.0);
        assert!(
            num("peak_rss_bytes") > 1.0e6,
            "a process uses more than 1 MB"
        );
        // The column has started to collapse but is still far from the right wall.
        let front = num("front_x");
        assert!(front > 0.9 && front < 4.0, "front {front}");
        assert_eq!(num("non_finite"), 0.0);
        assert_eq!(num("leaked"), 0.0);
        assert!(num("retries") >= 0.0, "retries are reported: {row}");
        // The row process inherits `DFSPH2D_SIMD`, as this test's process does.
        let path = dfsph::simd::SimdPath::in_use();
        let runtime = row["runtime_simd"].as_str().unwrap();
        assert!(runtime.starts_with(path.name()), "{path}: {row}");
    }
    let svg = std::fs::read_to_string(&plot).unwrap();
    assert!(
        svg.starts_with("<svg") && svg.contains("<polyline"),
        "{svg}"
    );

    // The table can be rebuilt from the JSON alone.
    let again = Command::new(BIN)
        .args(["bench", "--from-json"])
        .arg(&json)
        .output()
        .unwrap();
    assert!(again.status.success());
    let table = String::from_utf8_lossy(&again.stdout);
    assert_eq!(table.lines().count(), stdout.lines().count(), "{table}");
}

#[test]
fn salva_without_the_feature_is_a_clear_error() {
    if cfg!(feature = "salva") {
        return;
    }
    let out = Command::new(BIN)
        .args(["bench", "--quick", "--codes", "salva2d"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("--features salva"), "{stderr}");
    assert!(out.stdout.is_empty());
}

/// The parent pid of process `pid` while it is alive; `None` once it has exited or is a
/// zombie waiting to be reaped.
#[cfg(target_os = "linux")]
fn living_parent(pid: u32) -> Option<u32> {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    // `pid (comm) state ppid ...`; comm may hold spaces, so split after the last ')'.
    let mut fields = stat[stat.rfind(')')? + 1..].split_whitespace();
    let state = fields.next()?;
    let parent = fields.next()?.parse().ok()?;
    (state != "Z").then_some(parent)
}

/// The pids of the living `bench-row` children of `parent`.
#[cfg(target_os = "linux")]
fn bench_rows_of(parent: u32) -> Vec<u32> {
    std::fs::read_dir("/proc")
        .unwrap()
        .flatten()
        .filter_map(|entry| entry.file_name().to_string_lossy().parse::<u32>().ok())
        .filter(|&pid| {
            living_parent(pid) == Some(parent)
                && std::fs::read(format!("/proc/{pid}/cmdline"))
                    .is_ok_and(|c| String::from_utf8_lossy(&c).contains("bench-row"))
        })
        .collect()
}

#[cfg(target_os = "linux")]
#[test]
fn killing_bench_ends_its_row_process() {
    use std::time::{Duration, Instant};
    // 5k for 50 simulated seconds: the row runs far longer than this test waits.
    let mut bench = Command::new(BIN)
        .args([
            "bench", "--sizes", "5k", "--until", "50", "--codes", "dfsph2d",
        ])
        .args(["--threads", "1"])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .expect("dfsph2d runs");
    let started = Instant::now();
    let rows = loop {
        let rows = bench_rows_of(bench.id());
        if !rows.is_empty() || started.elapsed() > Duration::from_secs(30) {
            break rows;
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    assert_eq!(rows.len(), 1, "bench started no row process");
    let row = rows[0];
    bench.kill().unwrap();
    bench.wait().unwrap();
    let killed = Instant::now();
    while living_parent(row).is_some() {
        assert!(
            killed.elapsed() < Duration::from_secs(10),
            "the bench-row process {row} outlived its killed parent by 10 s"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// `bench --realtime` runs the dam break with the viewer's settings (the built-in scene's
/// own: Δt at most its `time_step.max`, its XSPH), on two threads by default, and reports the
/// real-time factor.
#[test]
fn realtime_bench_runs_the_viewer_settings_on_two_threads() {
    let dir = tempfile::tempdir().unwrap();
    let json = dir.path().join("rt.json");
    let out = Command::new(BIN)
        .args([
            "bench",
            "--realtime",
            "--sizes",
            "5k",
            "--until",
            "0.02",
            "--json",
        ])
        .arg(&json)
        .output()
        .expect("dfsph2d runs");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        stdout.contains("rt x") && stdout.contains("(viewer settings)"),
        "{stdout}"
    );
    // Under the table, what its terse column names mean.
    assert!(
        stdout.contains("rt x: simulated seconds per wall second")
            && stdout.contains("fr@0.4: the front at t = 0.4 s"),
        "{stdout}"
    );
    let rows: Vec<serde_json::Value> =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(rows.len(), 1, "{rows:?}");
    let row = &rows[0];
    let scene = dfsph::scene::builtin("dam-break").unwrap();
    assert_eq!(row["settings"], "viewer");
    assert_eq!(row["threads"], 2);
    assert_eq!(row["n"], 5000);
    assert_eq!(row["xsph"].as_f64(), Some(scene.viscosity.xsph));
    let mean_dt = row["mean_dt"].as_f64().unwrap();
    // (Δt is an f32: 1 ms is 1.0000000475 ms.)
    assert!(
        mean_dt > 0.0 && mean_dt <= scene.time_step.max * (1.0 + 1e-6),
        "{row}"
    );

    // The benchmark's own settings are another row kind, and salva2d has only those.
    let refused = Command::new(BIN)
        .args(["bench", "--realtime", "--codes", "salva2d"])
        .output()
        .unwrap();
    assert_eq!(refused.status.code(), Some(2));
}
