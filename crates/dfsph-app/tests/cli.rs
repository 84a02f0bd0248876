//! The `dfsph2d` command as a user runs it: listing scenes, headless runs and every output
//! file, and the errors for bad scenes and arguments (exit code 2, one line, nothing
//! written). Scenes are coarse and runs short, so the whole file takes a second or two.

use std::path::Path;

use vtkio::model::{Attribute, DataSet, Piece};

mod common;

use common::{csv_rows, dfsph2d, text, write_scene, COARSE};

#[test]
fn scenes_lists_the_builtin_scenes_one_per_line() {
    let out = dfsph2d(&["scenes"]);
    assert!(out.status.success());
    let stdout = text(&out.stdout);
    let names: Vec<&str> = stdout
        .lines()
        .map(|l| l.split_whitespace().next().unwrap())
        .collect();
    for name in ["dam-break", "hydrostatic", "double-dam-break", "drop"] {
        assert!(names.contains(&name), "{name} missing from:\n{stdout}");
    }
    for line in stdout.lines() {
        let description = line.split_once(' ').map(|(_, d)| d.trim()).unwrap_or("");
        assert!(description.len() > 10, "no description: {line:?}");
    }
}

#[test]
fn run_writes_every_output_file() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = write_scene(tmp.path(), "coarse.json", COARSE.as_bytes());
    let out_dir = tmp.path().join("out");
    let out = dfsph2d(&[
        "run",
        scene.to_str().unwrap(),
        "--until",
        "0.05",
        "--every",
        "0.02",
        "--format",
        "csv,vtk,png",
        "--png-width",
        "320",
        "--threads",
        "2",
        "--out",
        out_dir.to_str().unwrap(),
    ]);
    let stdout = text(&out.stdout);
    assert!(out.status.success(), "{stdout}\n{}", text(&out.stderr));
    // No progress bar when stderr is not a terminal; a one-line summary on stdout.
    assert_eq!(text(&out.stderr), "");
    assert_eq!(stdout.lines().count(), 1, "{stdout}");
    assert!(
        stdout.contains("steps") && stdout.contains("0 non-finite"),
        "{stdout}"
    );

    // scene.json: the resolved scene, every key present, and it loads back.
    let resolved = std::fs::read_to_string(out_dir.join("scene.json")).unwrap();
    let scene = dfsph::Scene::from_json(&resolved).unwrap();
    assert_eq!(scene.particle_radius, 0.05);
    assert_eq!(scene.name, "coarse");
    for key in [
        "solver",
        "time_step",
        "viscosity",
        "max_particles",
        "tank",
        "fluid",
    ] {
        assert!(
            resolved.contains(&format!("\"{key}\"")),
            "{key} not in scene.json"
        );
    }

    // stats.csv: the contract header, one row per step, steps 1..n, ending at --until.
    let stats = csv_rows(&out_dir.join("stats.csv"));
    assert_eq!(
        stats[0].join(","),
        "step,time,dt,n_fluid,density_iterations,divergence_iterations,avg_density_error_pct,\
         max_density_error_pct,max_speed,kinetic_energy,divergence_error_pct,clamped,non_finite,\
         avg_neighbors,n_boundary,retries"
    );
    let rows = &stats[1..];
    assert!(
        rows.len() >= 10,
        "0.05 s at dt <= 5 ms is at least 10 steps"
    );
    for (k, row) in rows.iter().enumerate() {
        assert_eq!(row.len(), stats[0].len());
        assert_eq!(row[0], (k + 1).to_string());
        assert_eq!(row[3], scene.fluid_particle_count().to_string());
    }
    let last_time: f64 = rows.last().unwrap()[1].parse().unwrap();
    assert!((0.0499..0.056).contains(&last_time), "{last_time}");
    assert!(
        stdout.contains(&format!("{} steps", rows.len())),
        "{stdout}"
    );

    // index.csv: frames 0.. with their times, snapshots at t = 0, 0.02, 0.04 and the end.
    let particles = out_dir.join("particles");
    let index = csv_rows(&particles.join("index.csv"));
    assert_eq!(index[0], ["frame", "time", "file"]);
    let frames = &index[1..];
    assert_eq!(frames.len(), 4, "{frames:?}");
    let times: Vec<f64> = frames.iter().map(|f| f[1].parse().unwrap()).collect();
    for (got, want) in times.iter().zip([0.0, 0.02, 0.04, last_time]) {
        assert!((got - want).abs() < 1e-6, "{times:?}");
    }

    let mut expected_files = vec![
        "index.csv".to_string(),
        "particles.pvd".to_string(),
        "walls.pvd".to_string(),
        "walls_00000.vtu".to_string(),
    ];
    // The walls: one file, as they never moved, with every boundary particle, body 0 (the
    // tank) for all; the walls collection lists it at every frame's time.
    let n_boundary: usize = rows[0][14].parse().unwrap();
    let walls = vtkio::Vtk::import(particles.join("walls_00000.vtu")).expect("vtkio reads");
    let DataSet::UnstructuredGrid { pieces, .. } = walls.data else {
        panic!("walls: not an UnstructuredGrid");
    };
    let Piece::Inline(walls) = &pieces[0] else {
        panic!("walls: not inline");
    };
    assert_eq!(walls.num_points(), n_boundary);
    let bodies = walls
        .data
        .point
        .iter()
        .find_map(|a| match a {
            Attribute::DataArray(a) if a.name == "body" => a.data.clone().cast_into::<u32>(),
            _ => None,
        })
        .expect("walls have a body array");
    assert!(bodies.len() == n_boundary && bodies.iter().all(|&b| b == 0));
    let walls_pvd = std::fs::read_to_string(particles.join("walls.pvd")).unwrap();
    assert_eq!(
        walls_pvd.matches(r#"file="walls_00000.vtu""#).count(),
        frames.len()
    );
    for (k, frame) in frames.iter().enumerate() {
        let stem = format!("{k:05}");
        assert_eq!(frame[0], k.to_string());
        assert_eq!(frame[2], format!("{stem}.csv"));

        // The CSV snapshot.
        let csv = csv_rows(&particles.join(&frame[2]));
        assert_eq!(csv[0], ["x", "y", "vx", "vy", "density", "pressure"]);
        let n = csv.len() - 1;
        assert_eq!(n, scene.fluid_particle_count());
        for row in &csv[1..] {
            let v: Vec<f32> = row.iter().map(|x| x.parse().unwrap()).collect();
            assert!(v.iter().all(|x| x.is_finite()), "{row:?}");
            assert!((-0.01..=4.01).contains(&v[0]) && (-0.01..=3.01).contains(&v[1]));
        }

        // The .vtu, read back with vtkio: n vertices with the four point arrays.
        let vtk = vtkio::Vtk::import(particles.join(format!("{stem}.vtu"))).expect("vtkio reads");
        let DataSet::UnstructuredGrid { pieces, .. } = vtk.data else {
            panic!("not an UnstructuredGrid");
        };
        let Piece::Inline(piece) = &pieces[0] else {
            panic!("not an inline piece");
        };
        assert_eq!(piece.num_points(), n);
        assert_eq!(piece.cells.types.len(), n);
        let points: Vec<f32> = piece.points.clone().cast_into().unwrap();
        let first: Vec<f32> = csv[1].iter().map(|x| x.parse().unwrap()).collect();
        assert_eq!(points[0..2], first[0..2], "vtu and csv agree on particle 0");
        let mut arrays: Vec<(String, usize)> = piece
            .data
            .point
            .iter()
            .map(|a| match a {
                Attribute::DataArray(a) => (a.name.clone(), a.data.len()),
                Attribute::Field { name, .. } => (name.clone(), 0),
            })
            .collect();
        arrays.sort();
        assert_eq!(
            arrays,
            [
                ("density".to_string(), n),
                ("id".to_string(), n),
                ("pressure".to_string(), n),
                ("velocity".to_string(), 3 * n),
            ]
        );

        // The PNG opens, has the asked width and shows coloured (non-grey) water.
        let png = tiny_skia::Pixmap::load_png(particles.join(format!("{stem}.png")))
            .expect("the PNG decodes");
        assert_eq!(png.width(), 320);
        let coloured = png
            .pixels()
            .iter()
            .filter(|c| c.red().abs_diff(c.blue()) > 40 || c.green().abs_diff(c.blue()) > 40)
            .count();
        assert!(coloured > 500, "only {coloured} coloured pixels");

        for ext in ["csv", "vtu", "png"] {
            expected_files.push(format!("{stem}.{ext}"));
        }
    }
    // Nothing else, in particular no leftover NAME.tmp files.
    let mut files: Vec<String> = std::fs::read_dir(&particles)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    files.sort();
    expected_files.sort();
    assert_eq!(files, expected_files);
    let mut top: Vec<String> = std::fs::read_dir(&out_dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    top.sort();
    assert_eq!(
        top,
        [".dfsph2d-manifest", "particles", "scene.json", "stats.csv"]
    );

    // The ParaView collection lists every .vtu with its time.
    let pvd = std::fs::read_to_string(particles.join("particles.pvd")).unwrap();
    assert_eq!(pvd.matches("<DataSet ").count(), frames.len());
    assert!(pvd.contains(r#"file="00003.vtu""#));
}

#[test]
fn run_defaults_to_csv_every_50_ms_and_reuses_an_existing_directory() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = write_scene(tmp.path(), "coarse.json", COARSE.as_bytes());
    let out_dir = tmp.path().join("out");
    let particles = out_dir.join("particles");
    std::fs::create_dir_all(&particles).unwrap();
    // Files of the user's, two of them named like frames: no run of ours wrote them.
    std::fs::write(particles.join("00009.csv"), "mine").unwrap();
    std::fs::write(particles.join("20240101.png"), "mine").unwrap();
    std::fs::write(out_dir.join("notes.txt"), "mine").unwrap();

    let out = dfsph2d(&[
        "run",
        scene.to_str().unwrap(),
        "--until",
        "0.1",
        "--out",
        out_dir.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let index = csv_rows(&particles.join("index.csv"));
    let times: Vec<f64> = index[1..].iter().map(|f| f[1].parse().unwrap()).collect();
    assert_eq!(times.len(), 3, "t = 0, 0.05, 0.1: {times:?}");
    assert!((times[1] - 0.05).abs() < 1e-6 && (times[2] - 0.1).abs() < 0.006);
    assert!(particles.join("00002.csv").exists());
    assert!(!particles.join("00000.vtu").exists() && !particles.join("00000.png").exists());
    for mine in ["particles/00009.csv", "particles/20240101.png", "notes.txt"] {
        assert_eq!(
            std::fs::read_to_string(out_dir.join(mine)).unwrap(),
            "mine",
            "{mine}"
        );
    }
}

/// Runs the coarse scene to `until` into `out_dir` with `extra` arguments; must succeed.
fn run_coarse(tmp: &Path, out_dir: &Path, until: &str, extra: &[&str]) -> std::process::Output {
    let scene = write_scene(tmp, "coarse.json", COARSE.as_bytes());
    let mut args = vec![
        "run",
        scene.to_str().unwrap(),
        "--until",
        until,
        "--every",
        "0.02",
        "--out",
        out_dir.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    dfsph2d(&args)
}

fn names_in(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

#[test]
fn a_shorter_rerun_removes_our_old_frames_and_keeps_the_users() {
    let tmp = tempfile::tempdir().unwrap();
    let out_dir = tmp.path().join("out");
    let particles = out_dir.join("particles");
    let first = run_coarse(tmp.path(), &out_dir, "0.1", &["--format", "csv,png"]);
    assert!(first.status.success(), "{}", text(&first.stderr));
    assert!(particles.join("00005.png").exists());
    std::fs::write(particles.join("20240101.png"), "mine").unwrap();
    std::fs::write(particles.join("00042.csv"), "mine").unwrap();

    let second = run_coarse(tmp.path(), &out_dir, "0.04", &["--format", "csv"]);
    assert!(second.status.success(), "{}", text(&second.stderr));
    let frames = csv_rows(&particles.join("index.csv")).len() - 1;
    assert_eq!(frames, 3, "t = 0, 0.02, 0.04");
    let mut expected: Vec<String> = (0..frames).map(|i| format!("{i:05}.csv")).collect();
    expected.extend(["00042.csv", "20240101.png", "index.csv"].map(String::from));
    expected.sort();
    // No stale frame of the first run (00003.csv .. 00005.csv, every .png), the user's kept.
    assert_eq!(names_in(&particles), expected);
    assert_eq!(
        std::fs::read_to_string(particles.join("00042.csv")).unwrap(),
        "mine"
    );
    // The manifest lists exactly this run's files, each before it was written.
    let manifest = std::fs::read_to_string(out_dir.join(".dfsph2d-manifest")).unwrap();
    let listed: Vec<&str> = manifest.lines().skip(1).collect();
    assert_eq!(
        listed,
        [
            "scene.json",
            "stats.csv",
            "particles/index.csv",
            "particles/00000.csv",
            "particles/00001.csv",
            "particles/00002.csv"
        ]
    );
}

#[test]
fn a_csv_run_after_a_vtk_run_leaves_no_stale_pvd_and_keeps_a_users() {
    let tmp = tempfile::tempdir().unwrap();
    let out_dir = tmp.path().join("out");
    let particles = out_dir.join("particles");
    let vtk = run_coarse(tmp.path(), &out_dir, "0.04", &["--format", "vtk"]);
    assert!(vtk.status.success(), "{}", text(&vtk.stderr));
    assert!(particles.join("particles.pvd").exists());
    let csv = run_coarse(tmp.path(), &out_dir, "0.04", &["--format", "csv"]);
    assert!(csv.status.success(), "{}", text(&csv.stderr));
    // The old collection would list .vtu files that are gone.
    assert_eq!(
        names_in(&particles),
        ["00000.csv", "00001.csv", "00002.csv", "index.csv"]
    );

    // A particles.pvd that no run of ours wrote is the user's: kept.
    let other = tmp.path().join("other");
    std::fs::create_dir_all(other.join("particles")).unwrap();
    std::fs::write(other.join("particles/particles.pvd"), "mine").unwrap();
    let csv = run_coarse(tmp.path(), &other, "0.02", &["--format", "csv"]);
    assert!(csv.status.success(), "{}", text(&csv.stderr));
    assert_eq!(
        std::fs::read_to_string(other.join("particles/particles.pvd")).unwrap(),
        "mine"
    );
}

#[test]
fn a_run_without_probes_after_one_with_leaves_no_stale_probes_csv() {
    let tmp = tempfile::tempdir().unwrap();
    let probed = write_scene(
        tmp.path(),
        "probed.json",
        br#"{"particle_radius": 0.05,
             "probes": [{"type": "pressure", "name": "p", "at": [0.5, 0.05]}]}"#,
    );
    let out_dir = tmp.path().join("out");
    let with = dfsph2d(&[
        "run",
        probed.to_str().unwrap(),
        "--until",
        "0.02",
        "--out",
        out_dir.to_str().unwrap(),
    ]);
    assert!(with.status.success(), "{}", text(&with.stderr));
    assert!(out_dir.join("probes.csv").exists());
    let manifest = std::fs::read_to_string(out_dir.join(".dfsph2d-manifest")).unwrap();
    for name in [
        "scene.json",
        "stats.csv",
        "probes.csv",
        "particles/index.csv",
    ] {
        assert!(manifest.lines().any(|l| l == name), "{name}: {manifest}");
    }

    let without = run_coarse(tmp.path(), &out_dir, "0.02", &[]);
    assert!(without.status.success(), "{}", text(&without.stderr));
    assert_eq!(
        names_in(&out_dir),
        [".dfsph2d-manifest", "particles", "scene.json", "stats.csv"]
    );

    // A probes.csv of the user's in a fresh directory is kept.
    let other = tmp.path().join("other");
    std::fs::create_dir_all(&other).unwrap();
    std::fs::write(other.join("probes.csv"), "mine").unwrap();
    let without = run_coarse(tmp.path(), &other, "0.02", &[]);
    assert!(without.status.success(), "{}", text(&without.stderr));
    assert_eq!(
        std::fs::read_to_string(other.join("probes.csv")).unwrap(),
        "mine"
    );
}

#[cfg(unix)]
#[test]
fn a_particles_symlink_is_refused_and_nothing_behind_it_touched() {
    let tmp = tempfile::tempdir().unwrap();
    let elsewhere = tmp.path().join("elsewhere");
    std::fs::create_dir(&elsewhere).unwrap();
    for name in ["20240101.png", "00007.csv", "00000.csv"] {
        std::fs::write(elsewhere.join(name), "mine").unwrap();
    }
    let out_dir = tmp.path().join("out");
    std::fs::create_dir(&out_dir).unwrap();
    std::os::unix::fs::symlink(&elsewhere, out_dir.join("particles")).unwrap();
    // Even a manifest naming those files (say, copied from elsewhere) removes nothing.
    let first = run_coarse(tmp.path(), &tmp.path().join("real"), "0.02", &[]);
    assert!(first.status.success(), "{}", text(&first.stderr));
    std::fs::copy(
        tmp.path().join("real/.dfsph2d-manifest"),
        out_dir.join(".dfsph2d-manifest"),
    )
    .unwrap();

    let out = run_coarse(tmp.path(), &out_dir, "0.02", &[]);
    let stderr = text(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(
        stderr.starts_with("error: output `") && stderr.contains("particles` is a symbolic link"),
        "{stderr}"
    );
    assert_eq!(names_in(&out_dir), [".dfsph2d-manifest", "particles"]);
    assert_eq!(
        names_in(&elsewhere),
        ["00000.csv", "00007.csv", "20240101.png"]
    );
    for name in ["20240101.png", "00007.csv", "00000.csv"] {
        assert_eq!(
            std::fs::read_to_string(elsewhere.join(name)).unwrap(),
            "mine"
        );
    }
}

#[test]
fn run_help_says_what_an_existing_directory_gets() {
    let out = dfsph2d(&["run", "--help"]);
    let help = text(&out.stdout)
        .split_whitespace()
        .collect::<Vec<_>>()
        .join(" ");
    assert!(
        help.contains("removes the files an earlier run wrote there")
            && help.contains("every other file is kept")
            && help.contains("must not be a symbolic link"),
        "{help}"
    );
    // And its exit codes for a failed write and a signal.
    assert!(
        help.contains(
            "with 74 when a write fails (a full disk, an output directory that cannot be \
             created), naming the file"
        ) && help.contains("with 130 when stopped by Ctrl-C, SIGTERM or SIGHUP"),
        "{help}"
    );
}

/// An output directory the file system refuses to create is an I/O error (74), not bad input
/// (2): the arguments are sound, the disk said no. sysfs refuses every `mkdir`, root's too.
#[cfg(target_os = "linux")]
#[test]
fn an_output_directory_that_cannot_be_created_exits_74_naming_it() {
    let out_dir = "/sys/dfsph2d-test-output";
    let out = dfsph2d(&["run", "hydrostatic", "--until", "0.01", "--out", out_dir]);
    let stderr = text(&out.stderr);
    assert_eq!(out.status.code(), Some(74), "{stderr}");
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(
        stderr.starts_with(&format!(
            "error: cannot create output directory `{out_dir}/particles`: "
        )),
        "{stderr}"
    );
    assert!(!Path::new(out_dir).exists());
    assert_eq!(text(&out.stdout), "");
}

#[test]
fn builtin_scene_runs_by_name() {
    let tmp = tempfile::tempdir().unwrap();
    let out_dir = tmp.path().join("hydro");
    let out = dfsph2d(&[
        "run",
        "hydrostatic",
        "--until",
        "0.001",
        "--out",
        out_dir.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert!(text(&out.stdout).starts_with("hydrostatic: 1 steps"));
    let scene = std::fs::read_to_string(out_dir.join("scene.json")).unwrap();
    assert!(scene.contains("\"name\": \"hydrostatic\""));
    assert_eq!(csv_rows(&out_dir.join("stats.csv")).len(), 2);
    // The built-in tank is packed hexagonally: about the block's 2 m² over d² = 1e-4 m².
    let n = dfsph::scene::builtin("hydrostatic")
        .unwrap()
        .fluid_particle_count();
    assert!((4950..=5050).contains(&n), "{n}");
    assert_eq!(csv_rows(&out_dir.join("particles/00000.csv")).len(), 1 + n);
}

/// Runs `dfsph2d run SCENE --until 0.05 --out DIR` (plus `extra`), expects exit code 2, one
/// `error: ` line naming `needle`, and no output directory.
fn assert_rejected(tmp: &Path, scene: &str, extra: &[&str], needle: &str) {
    let out_dir = tmp.join("never");
    let mut args = vec![
        "run",
        scene,
        "--until",
        "0.05",
        "--out",
        out_dir.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    let out = dfsph2d(&args);
    let stderr = text(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{scene} {extra:?}: {stderr}");
    assert!(stderr.starts_with("error: "), "{stderr}");
    assert!(
        stderr.contains(needle),
        "{scene}: {stderr:?} lacks {needle:?}"
    );
    assert!(!stderr.contains("panicked") && !stderr.contains("RUST_BACKTRACE"));
    assert!(
        !out_dir.exists(),
        "{scene}: output written despite the error"
    );
    assert_eq!(text(&out.stdout), "");
}

#[test]
fn malformed_scenes_exit_2_name_the_problem_and_write_nothing() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let files: &[(&str, &[u8], &str)] = &[
        (
            "unknown-key.json",
            br#"{"radius": 0.05}"#,
            "unknown field `radius`",
        ),
        (
            "wrong-type.json",
            br#"{"particle_radius": "big"}"#,
            "particle_radius",
        ),
        (
            "negative.json",
            br#"{"particle_radius": -0.05}"#,
            "particle_radius",
        ),
        (
            "outside.json",
            br#"{"particle_radius": 0.05, "fluid": [{"min": [0, 0], "max": [5, 1]}]}"#,
            "fluid[0].max[0]",
        ),
        (
            "too-many.json",
            br#"{"particle_radius": 0.05, "max_particles": 100}"#,
            "max_particles",
        ),
        (
            "truncated.json",
            br#"{"particle_radius": 0.05"#,
            "EOF while parsing",
        ),
        ("empty.json", b"", "empty"),
        ("blank.json", b"  \n\t", "empty"),
        ("array.json", b"[1, 2]", "must be a JSON object"),
        ("infinite.json", br#"{"gravity": [0, -1e400]}"#, "gravity"),
        (
            "binary.json",
            &[0x89, b'P', b'N', b'G', 0xff, 0x00, 0xfe],
            "not UTF-8",
        ),
        (
            "method.json",
            br#"{"solver": {"method": "pbf"}}"#,
            "solver.method",
        ),
        ("cfl.json", br#"{"time_step": {"cfl": 2}}"#, "time_step.cfl"),
    ];
    for (name, content, needle) in files {
        let path = write_scene(dir, name, content);
        let path = path.to_str().unwrap();
        assert_rejected(dir, path, &[], needle);
        // The message names the file too.
        let out = dfsph2d(&["run", path, "--until", "0.05", "--out", "unused"]);
        assert!(text(&out.stderr).contains(path));
    }
    let subdir = dir.join("a-directory");
    std::fs::create_dir(&subdir).unwrap();
    assert_rejected(dir, subdir.to_str().unwrap(), &[], "is a directory");
    let missing = dir.join("missing.json");
    assert_rejected(dir, missing.to_str().unwrap(), &[], "does not exist");
    assert_rejected(dir, "dambreak", &[], "unknown scene `dambreak`");
    assert!(!Path::new("unused").exists());
}

#[test]
fn an_every_giving_more_than_a_million_snapshots_is_refused() {
    // --every 1e-300 used to hang before step 1, counting through snapshot times.
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let scene = write_scene(dir, "coarse.json", COARSE.as_bytes());
    let scene = scene.to_str().unwrap();
    assert_rejected(
        dir,
        scene,
        &["--every", "1e-300"],
        "error: --every 1e-300 s would take 5.000e298 snapshots over --until 0.05 s; \
         at most 1000000 are allowed (use a larger --every)",
    );
    assert_rejected(dir, scene, &["--every", "2.5e-8"], "--every");
    // 500,000 snapshot times over the run is allowed (one snapshot per step at most).
    let out_dir = dir.join("ok");
    let out = dfsph2d(&[
        "run",
        scene,
        "--until",
        "0.001",
        "--every",
        "2e-9",
        "--out",
        out_dir.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
}

#[test]
fn control_characters_in_names_are_printed_escaped() {
    // A scene named with ANSI sequences used to clear the terminal and retitle its window
    // when `run` printed its summary.
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let scene = write_scene(
        dir,
        "ansi.json",
        br#"{"particle_radius": 0.05, "name": "\u001b]0;pwned\u0007\u001b[2J"}"#,
    );
    let escaped = r"\u{1b}]0;pwned\u{7}\u{1b}[2J";
    let out_dir = dir.join("out\u{1b}[2J");
    let run = |extra: &[&str]| {
        let mut args = vec![
            "run",
            scene.to_str().unwrap(),
            "--until",
            "0.01",
            "--out",
            out_dir.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        dfsph2d(&args)
    };
    // The summary line: the scene's name and the output directory.
    let out = run(&[]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let stdout = text(&out.stdout);
    assert!(
        !out.stdout.contains(&0x1b) && !out.stderr.contains(&0x1b),
        "{stdout:?}"
    );
    assert!(stdout.starts_with(escaped), "{stdout}");
    assert!(stdout.contains(r"out\u{1b}[2J"), "{stdout}");
    // An error line naming a path from the command line.
    let missing = dir.join("missing\u{1b}[2J.jsonl");
    let out = run(&["--replay", missing.to_str().unwrap()]);
    let stderr = text(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(!out.stderr.contains(&0x1b), "{stderr:?}");
    assert!(
        stderr.contains(r"missing\u{1b}[2J.jsonl` does not exist"),
        "{stderr}"
    );
    // `stress` prints the scene's name in its summary.
    let out = dfsph2d(&["stress", scene.to_str().unwrap(), "--steps", "3"]);
    assert!(!out.stdout.contains(&0x1b) && !out.stderr.contains(&0x1b));
    assert!(text(&out.stdout).contains(escaped), "{}", text(&out.stdout));
}

#[test]
fn bad_arguments_exit_2_and_write_nothing() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let scene = write_scene(dir, "coarse.json", COARSE.as_bytes());
    let scene = scene.to_str().unwrap();
    assert_rejected(dir, scene, &["--until", "0"], "--until");
    assert_rejected(dir, scene, &["--until=-1"], "--until");
    assert_rejected(dir, scene, &["--until", "inf"], "--until");
    assert_rejected(dir, scene, &["--every", "0"], "--every");
    assert_rejected(dir, scene, &["--every", "soon"], "--every");
    assert_rejected(dir, scene, &["--format", "csv,avi"], "avi");
    assert_rejected(dir, scene, &["--threads", "0"], "--threads");
    // A negative number is a bad value, not an unknown argument; more threads than a
    // recording may name are refused, so that every recording can be replayed.
    assert_rejected(dir, scene, &["--threads", "-1"], "--threads");
    assert_rejected(dir, scene, &["--threads", "1100"], "--threads");
    assert_rejected(dir, scene, &["--every", "-1"], "--every");

    // --out naming an existing file: refused, the file untouched.
    let file = dir.join("a-file");
    std::fs::write(&file, "keep").unwrap();
    let out = dfsph2d(&[
        "run",
        scene,
        "--until",
        "0.05",
        "--out",
        file.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(2));
    let stderr = text(&out.stderr);
    assert!(
        stderr.starts_with("error: ") && stderr.contains("not a directory"),
        "{stderr}"
    );
    assert_eq!(stderr.lines().count(), 1);
    assert_eq!(std::fs::read_to_string(&file).unwrap(), "keep");
}

#[test]
fn scene_errors_are_one_line() {
    let tmp = tempfile::tempdir().unwrap();
    let path = write_scene(
        tmp.path(),
        "multi.json",
        b"{\n  \"tank\": {\"min\": [0, 0]}\n}\n",
    );
    let out = dfsph2d(&["run", path.to_str().unwrap(), "--until", "1", "--out", "x"]);
    assert_eq!(out.status.code(), Some(2));
    let stderr = text(&out.stderr);
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(stderr.contains("tank"), "{stderr}");
}

#[test]
fn view_rejects_a_bad_scene_before_opening_a_window() {
    let out = dfsph2d(&["view", "no-such-scene.json"]);
    assert_eq!(out.status.code(), Some(2));
    let stderr = text(&out.stderr);
    assert!(
        stderr.starts_with("error: ") && stderr.contains("does not exist"),
        "{stderr}"
    );
    let out = dfsph2d(&["view", "drop", "--exit-after=-1"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(text(&out.stderr).contains("--exit-after"));
}

/// A run that clamps particles back into the tank leaked water: it writes all its output, then
/// exits with 2 and one line saying how many particles were clamped (issue 32: it exited 0).
#[test]
fn a_run_that_clamps_particles_exits_2_after_writing_its_output() {
    let tmp = tempfile::tempdir().unwrap();
    // Weakly compressible water with a stiffness of 1 Pa: its pressure cannot hold the column
    // up, and the bottom rows sink through the floor's particles (a leak through the wall
    // model, not through a too long step, which the time step rules out) and are clamped
    // back. (A forced 1 s step from rest did this before `time_step.min` was bounded.)
    let scene = write_scene(
        tmp.path(),
        "leak.json",
        br#"{"particle_radius": 0.05, "solver": {"method": "wcsph", "wcsph_stiffness": 1}}"#,
    );
    let out_dir = tmp.path().join("out");
    let out = dfsph2d(&[
        "run",
        scene.to_str().unwrap(),
        "--until",
        "2",
        "--out",
        out_dir.to_str().unwrap(),
    ]);
    let (stdout, stderr) = (text(&out.stdout), text(&out.stderr));
    assert_eq!(out.status.code(), Some(2), "{stdout}{stderr}");
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    // The count is the sum of the per-step `clamped` column, and the summary's.
    let stats = csv_rows(&out_dir.join("stats.csv"));
    let column = stats[0].iter().position(|c| c == "clamped").unwrap();
    let clamped: u64 = stats[1..]
        .iter()
        .map(|r| r[column].parse::<u64>().unwrap())
        .sum();
    assert!(clamped > 0, "the scene no longer clamps: {stdout}");
    assert_eq!(
        stderr,
        format!(
            "error: {clamped} particles were clamped back into the tank over the run (water went \
             through a wall); the output is complete in `{}`\n",
            out_dir.display()
        )
    );
    assert!(
        stdout.contains(&format!("; {clamped} clamped, 0 non-finite")),
        "{stdout}"
    );
    // Everything was written: the run went on to --until.
    let last_time: f64 = stats.last().unwrap()[1].parse().unwrap();
    assert!(last_time >= 2.0, "{last_time}");
    for file in ["scene.json", "particles/index.csv", "particles/00000.csv"] {
        assert!(out_dir.join(file).is_file(), "{file} missing");
    }
}

/// A run whose density solve stops at its cap step after step (here one iteration allowed)
/// has not met its tolerances: it warns when it sees it, writes everything, and exits with 2;
/// `--allow-blow-up` accepts it (issue 46: such runs exited 0).
#[test]
fn a_run_that_blows_up_without_nan_warns_and_exits_2_unless_allowed() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = write_scene(
        tmp.path(),
        "capped.json",
        br#"{"particle_radius": 0.05, "solver": {"min_iterations": 1, "max_iterations": 1}}"#,
    );
    for allow in [false, true] {
        let out_dir = tmp.path().join(format!("out-{allow}"));
        let mut args = vec![
            "run",
            scene.to_str().unwrap(),
            "--until",
            "0.2",
            "--out",
            out_dir.to_str().unwrap(),
        ];
        if allow {
            args.push("--allow-blow-up");
        }
        let out = dfsph2d(&args);
        let (stdout, stderr) = (text(&out.stdout), text(&out.stderr));
        assert_eq!(
            out.status.code(),
            Some(if allow { 0 } else { 2 }),
            "{stderr}"
        );
        let lines: Vec<&str> = stderr.lines().collect();
        assert!(
            lines[0].starts_with("warning: step 20 (t = ")
                && lines[0].contains("ended at its cap of 1 iterations in 20 steps in a row"),
            "{stderr}"
        );
        if allow {
            assert_eq!(lines.len(), 1, "{stderr}");
        } else {
            assert_eq!(lines.len(), 2, "{stderr}");
            assert!(
                lines[1].starts_with("error: the simulation blew up at step 20 (t = ")
                    && lines[1].ends_with("(`--allow-blow-up` accepts such a run)"),
                "{stderr}"
            );
        }
        // The run went on to --until and wrote everything.
        let stats = csv_rows(&out_dir.join("stats.csv"));
        let last_time: f64 = stats.last().unwrap()[1].parse().unwrap();
        assert!(last_time >= 0.2, "{last_time} {stdout}");
        assert!(out_dir.join("particles/00004.csv").is_file());
    }
}

/// Times are written as the decimals the steps stand for: a hundred 1 ms steps end at
/// `0.1`, not at `0.10000000474974513` (the single-precision 1 ms, summed), in `index.csv`,
/// the `.pvd` collection and `stats.csv`, whose `dt` reads `0.001`.
#[test]
fn output_times_read_as_the_steps_decimals() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("still.json");
    // Water at rest: the CFL bound is far above the 1 ms cap, so every step is 1 ms.
    std::fs::write(
        &scene,
        r#"{"particle_radius": 0.025, "tank": {"min": [0, 0], "max": [1, 1]},
            "fluid": [{"min": [0, 0], "max": [1, 0.5]}], "time_step": {"max": 0.001}}"#,
    )
    .unwrap();
    let out_dir = dir.path().join("out");
    let out = dfsph2d(&[
        "run",
        scene.to_str().unwrap(),
        "--until",
        "0.3",
        "--every",
        "0.1",
        "--format",
        "csv,vtk",
        "--out",
        out_dir.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let index = std::fs::read_to_string(out_dir.join("particles/index.csv")).unwrap();
    let times: Vec<&str> = index
        .lines()
        .skip(1)
        .map(|l| l.split(',').nth(1).unwrap())
        .collect();
    assert_eq!(times, ["0", "0.1", "0.2", "0.3"], "{index}");
    let pvd = std::fs::read_to_string(out_dir.join("particles/particles.pvd")).unwrap();
    assert!(pvd.contains(r#"timestep="0.2""#), "{pvd}");
    let stats = std::fs::read_to_string(out_dir.join("stats.csv")).unwrap();
    let last: Vec<&str> = stats.lines().last().unwrap().split(',').collect();
    assert_eq!(&last[..3], ["300", "0.3", "0.001"], "{stats}");
}

/// `--color-by` colours the frames by another field (the legend's colour bar changes with
/// it: blue to red for the density error), and an unknown field is a usage error that
/// lists the known ones.
#[test]
fn frames_are_coloured_by_the_field_asked_for() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = write_scene(tmp.path(), "coarse.json", COARSE.as_bytes());
    let frame = |field: &str| -> Vec<u8> {
        let out_dir = tmp.path().join(field);
        let out = dfsph2d(&[
            "run",
            scene.to_str().unwrap(),
            "--until",
            "0.02",
            "--format",
            "png",
            "--color-by",
            field,
            "--out",
            out_dir.to_str().unwrap(),
        ]);
        assert!(out.status.success(), "{}", text(&out.stderr));
        std::fs::read(out_dir.join("particles/00001.png")).unwrap()
    };
    let (speed, pressure, density) = (frame("speed"), frame("pressure"), frame("density"));
    assert_ne!(speed, pressure);
    assert_ne!(speed, density);
    assert_ne!(pressure, density);

    let out = dfsph2d(&[
        "run",
        scene.to_str().unwrap(),
        "--color-by",
        "temperature",
        "--out",
        tmp.path().join("bad").to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(2));
    let stderr = text(&out.stderr);
    assert!(
        stderr.contains("\"temperature\" is not a field; one of speed, pressure, density"),
        "{stderr}"
    );
    assert!(!tmp.path().join("bad").exists());
}

/// `--look` draws the water as a surface (the default) or as dots: the dots leave the
/// background showing between particles, so the dotted frame has more background pixels; an
/// unknown look is a usage error that lists the known ones.
#[test]
fn frames_draw_the_water_as_a_surface_unless_asked_for_dots() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = write_scene(tmp.path(), "coarse.json", COARSE.as_bytes());
    let background = |look: Option<&str>| -> usize {
        let out_dir = tmp.path().join(look.unwrap_or("default"));
        let mut args = vec![
            "run",
            scene.to_str().unwrap(),
            "--until",
            "0.02",
            "--format",
            "png",
            "--out",
            out_dir.to_str().unwrap(),
        ];
        if let Some(look) = look {
            args.extend(["--look", look]);
        }
        let out = dfsph2d(&args);
        assert!(out.status.success(), "{}", text(&out.stderr));
        let png = tiny_skia::Pixmap::load_png(out_dir.join("particles/00001.png")).unwrap();
        png.pixels()
            .iter()
            .filter(|p| p.red() == 255 && p.green() == 255 && p.blue() == 255)
            .count()
    };
    let (default, surface, dots) = (
        background(None),
        background(Some("surface")),
        background(Some("particles")),
    );
    assert_eq!(default, surface);
    assert!(dots > surface, "dots {dots}, surface {surface}");

    let out = dfsph2d(&[
        "run",
        scene.to_str().unwrap(),
        "--look",
        "metaballs",
        "--out",
        tmp.path().join("bad").to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(2));
    let stderr = text(&out.stderr);
    assert!(
        stderr.contains("\"metaballs\" is not a look; one of surface, particles"),
        "{stderr}"
    );
    assert!(!tmp.path().join("bad").exists());
}
