//! `dfsph2d bench --quick --json FILE`: the benchmark runs end to end and its JSON rows carry
//! every documented key with sane values. No wall-time assertions: a benchmark is a command,
//! not a test (BENCHMARK.md).

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
