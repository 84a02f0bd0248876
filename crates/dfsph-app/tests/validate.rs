//! `dfsph2d validate --quick --out DIR` as a user runs it: on a healthy build it exits 0, the
//! report exists with its table of checks (the smoke checks PASS, the comparisons that need
//! the full resolution reported but not checked), and every plot it references exists and is
//! a valid PNG. (Exit 1 on broken physics: the unit test in `src/main.rs`.)

use std::process::Command;

const BIN: &str = env!("CARGO_BIN_EXE_dfsph2d");

#[test]
fn quick_validation_writes_a_consistent_report() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("report");
    let output = Command::new(BIN)
        .args(["validate", "--quick", "--out"])
        .arg(&out)
        .output()
        .expect("dfsph2d runs");
    let stderr = String::from_utf8_lossy(&output.stderr);
    let stdout = String::from_utf8_lossy(&output.stdout);
    let code = output.status.code().expect("exited normally");
    assert_eq!(
        code, 0,
        "a healthy build's smoke checks fail:\n{stdout}\n{stderr}"
    );
    assert!(stdout.contains("smoke checks, 0 failed"), "{stdout}");

    let report = std::fs::read_to_string(out.join("report.md"))
        .unwrap_or_else(|e| panic!("no report.md ({e}): {stderr}"));
    assert!(report.contains("## Checks"), "{report}");
    assert!(report.contains("| # | case | check | value | tolerance | result |"));

    // The summary table: one row per check that counts, each PASS, with a tolerance; the
    // comparisons that need the full resolution are in a table of their own, with where the
    // coarse value lies and no verdict.
    let table = |title: &str| -> Vec<Vec<String>> {
        let start = report
            .find(title)
            .unwrap_or_else(|| panic!("no {title}:\n{report}"));
        report[start..]
            .lines()
            .skip_while(|l| !l.starts_with("|---"))
            .skip(1)
            .take_while(|l| l.starts_with('|'))
            .map(|row| {
                let cells: Vec<String> = row
                    .trim_matches('|')
                    .split(" | ")
                    .map(|c| c.trim().to_string())
                    .collect();
                let tolerance = &cells[cells.len() - 2];
                assert!(
                    tolerance.contains('≤') || tolerance.contains('±'),
                    "row without a tolerance: {row}"
                );
                cells
            })
            .collect()
    };
    let smoke = table("## Checks");
    for row in &smoke {
        assert_eq!(row.last().unwrap(), "PASS", "{row:?}");
    }
    let reported = table("## Reported, not checked (quick mode)");
    for row in &reported {
        let at = row.last().unwrap();
        assert!(at == "within" || at == "outside", "{row:?}");
    }
    // No verdict on a comparison in the checks' table, and no "fail" under the overall PASS.
    assert!(!report.contains("(fail;"), "{report}");
    // Both kinds are there: completion, rest and compression checks; the experiments.
    assert!(
        smoke.len() >= 10 && reported.len() >= 10,
        "{} smoke, {} reported",
        smoke.len(),
        reported.len()
    );
    assert!(report.contains("overall: **PASS**"));

    // Every referenced plot exists and decodes as a PNG of a sensible size.
    let mut plots = 0;
    for part in report.split("](").skip(1) {
        let file = &part[..part.find(')').unwrap()];
        assert!(file.ends_with(".png"), "{file}");
        let bytes = std::fs::read(out.join(file)).unwrap_or_else(|e| panic!("{file}: {e}"));
        let decoder = png::Decoder::new(std::io::Cursor::new(bytes));
        let mut reader = decoder
            .read_info()
            .unwrap_or_else(|e| panic!("{file}: {e}"));
        let mut buf = vec![0; reader.output_buffer_size()];
        let info = reader
            .next_frame(&mut buf)
            .unwrap_or_else(|e| panic!("{file}: {e}"));
        assert!(info.width >= 400 && info.height >= 300, "{file}");
        // Not a blank image: the plot has ink on it.
        assert!(buf.iter().any(|&b| b < 128), "{file} is blank");
        plots += 1;
    }
    assert!(plots >= 10, "only {plots} plots");
}

#[test]
fn run_writes_probe_readings_every_step() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("gauges.json");
    std::fs::write(
        &scene,
        r#"{
  "particle_radius": 0.02,
  "tank": { "min": [0, 0], "max": [4, 2] },
  "fluid": [{ "min": [0, 0], "max": [1, 1] }],
  "probes": [
    { "type": "water_level", "name": "h_0.5m", "x": 0.5 },
    { "type": "pressure", "name": "p_floor", "at": [0.5, 0.0] },
    { "type": "pressure", "name": "p_far_wall", "at": [4.0, 0.05] }
  ]
}"#,
    )
    .unwrap();
    let out = dir.path().join("out");
    let status = Command::new(BIN)
        .arg("run")
        .arg(&scene)
        .args(["--until", "0.05", "--out"])
        .arg(&out)
        .status()
        .unwrap();
    assert!(status.success());
    let probes = std::fs::read_to_string(out.join("probes.csv")).unwrap();
    let stats = std::fs::read_to_string(out.join("stats.csv")).unwrap();
    let lines: Vec<&str> = probes.lines().collect();
    assert_eq!(lines[0], "time,h_0.5m,p_floor,p_far_wall");
    // The initial state, then one row per step (as many as stats.csv has).
    assert_eq!(lines.len(), stats.lines().count() + 1);
    let first: Vec<f64> = lines[1].split(',').map(|v| v.parse().unwrap()).collect();
    assert_eq!(first[0], 0.0);
    assert!((first[1] - 1.0).abs() < 0.04, "level {}", first[1]);
    // The far wall is dry; the floor under 1 m of water feels pressure once the solver has
    // run (before the first step every pressure is 0), of the order of ρ0·g·H.
    assert_eq!(first[3], 0.0);
    let last: Vec<f64> = lines[lines.len() - 1]
        .split(',')
        .map(|v| v.parse().unwrap())
        .collect();
    assert!((last[0] - 0.05).abs() < 0.002, "time {}", last[0]);
    assert!(
        last[2] > 0.3 * 9810.0 && last[2] < 3.0 * 9810.0,
        "floor {}",
        last[2]
    );

    // A scene without probes writes no probes.csv.
    let out2 = dir.path().join("out2");
    let status = Command::new(BIN)
        .args(["run", "hydrostatic", "--until", "0.005", "--out"])
        .arg(&out2)
        .status()
        .unwrap();
    assert!(status.success());
    assert!(!out2.join("probes.csv").exists());
}
