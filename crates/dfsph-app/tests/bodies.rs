//! Rigid bodies through the command line (issue 30): `run` writes their state at every
//! snapshot to `bodies.csv` and, with `--format vtk`, their outlines as polygons; a scene
//! without bodies gets neither; a bad body is one `error:` line naming its key, exit code 2,
//! and nothing written. Scenes are coarse (r = 2 cm) and runs short.

use std::path::Path;

use vtkio::model::{Attribute, CellType, DataSet, Piece, VertexNumbers};

mod common;

use common::{all_files, csv_rows, dfsph2d, text, write_scene};

/// The issue's example bodies in the default dam break, at r = 2 cm.
const TWO_BODIES: &str = r#"{
  "particle_radius": 0.02,
  "bodies": [
    {"shape": "box", "size": [0.4, 0.2], "density": 500, "position": [1.0, 0.8]},
    {"shape": "circle", "radius": 0.1, "density": 250, "position": [0.5, 0.8]}
  ]
}"#;

fn run(scene: &Path, out_dir: &Path, format: &str) -> std::process::Output {
    dfsph2d(&[
        "run",
        scene.to_str().unwrap(),
        "--until",
        "0.05",
        "--every",
        "0.01",
        "--format",
        format,
        "--threads",
        "2",
        "--out",
        out_dir.to_str().unwrap(),
    ])
}

/// The inline piece of a `.vtu`.
fn piece(path: &Path) -> vtkio::model::UnstructuredGridPiece {
    let vtk = vtkio::Vtk::import(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let DataSet::UnstructuredGrid { pieces, .. } = vtk.data else {
        panic!("{}: not an UnstructuredGrid", path.display());
    };
    match pieces.into_iter().next() {
        Some(Piece::Inline(p)) => *p,
        other => panic!("{}: {other:?}", path.display()),
    }
}

fn cell_array(piece: &vtkio::model::UnstructuredGridPiece, name: &str) -> Vec<f32> {
    piece
        .data
        .cell
        .iter()
        .find_map(|a| match a {
            Attribute::DataArray(a) if a.name == name => {
                Some(a.data.clone().cast_into::<f32>().unwrap())
            }
            _ => None,
        })
        .unwrap_or_else(|| panic!("no cell array {name}"))
}

#[test]
fn run_writes_the_bodies_at_every_snapshot_as_csv_and_vtk() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = write_scene(tmp.path(), "two-bodies.json", TWO_BODIES.as_bytes());
    let out_dir = tmp.path().join("out");
    let out = run(&scene, &out_dir, "csv,vtk");
    let stdout = text(&out.stdout);
    assert!(out.status.success(), "{stdout}\n{}", text(&out.stderr));
    assert!(stdout.contains("0 clamped, 0 non-finite"), "{stdout}");

    // The snapshots, as the index lists them.
    let index = csv_rows(&out_dir.join("particles/index.csv"));
    let frames: Vec<(String, String)> = index[1..]
        .iter()
        .map(|r| (r[0].clone(), r[1].clone()))
        .collect();
    assert!(frames.len() >= 6, "{frames:?}");

    // bodies.csv: the columns, then one row per body per snapshot, with the index's frame
    // numbers and times.
    let rows = csv_rows(&out_dir.join("bodies.csv"));
    assert_eq!(
        rows[0].join(","),
        "frame,time,body,x,y,angle,vx,vy,omega",
        "header"
    );
    assert_eq!(rows.len() - 1, 2 * frames.len(), "{rows:?}");
    for (k, (frame, time)) in frames.iter().enumerate() {
        for body in 0..2 {
            let row = &rows[1 + 2 * k + body];
            assert_eq!(row.len(), 9, "{row:?}");
            assert_eq!((&row[0], &row[1]), (frame, time), "{row:?}");
            assert_eq!(row[2], body.to_string());
            for v in &row[3..] {
                let v: f64 = v.parse().unwrap_or_else(|_| panic!("{row:?}"));
                assert!(v.is_finite(), "{row:?}");
            }
        }
    }
    // The first snapshot is the scene as given: the box at (1.0, 0.8), the circle at (0.5, 0.8).
    let first: Vec<f64> = rows[1][3..5].iter().map(|v| v.parse().unwrap()).collect();
    assert!(
        (first[0] - 1.0).abs() < 1e-6 && (first[1] - 0.8).abs() < 1e-6,
        "{first:?}"
    );
    // They start at rest and move: the water (and gravity) acts on them.
    assert!(rows[1][6..].iter().all(|v| v == "0"), "{:?}", rows[1]);
    for row in &rows[rows.len() - 2..] {
        let speed = row[6]
            .parse::<f64>()
            .unwrap()
            .hypot(row[7].parse().unwrap());
        assert!(speed > 1e-3, "{row:?}");
    }

    // VTK: one bodies_NNNNN.vtu per snapshot, the box a 4-gon and the circle a 48-gon, with
    // the body's velocity, angle and spin as cell data; bodies.pvd lists them with their times.
    let particles = out_dir.join("particles");
    let pvd = std::fs::read_to_string(particles.join("bodies.pvd")).unwrap();
    assert_eq!(pvd.matches("<DataSet ").count(), frames.len(), "{pvd}");
    for (k, (frame, time)) in frames.iter().enumerate() {
        let name = format!("bodies_{frame:0>5}.vtu");
        assert!(
            pvd.contains(&format!(
                r#"timestep="{time}" group="" part="0" file="{name}""#
            )),
            "{name} at {time} not in bodies.pvd:\n{pvd}"
        );
        let p = piece(&particles.join(&name));
        assert_eq!(p.num_points(), 4 + 48, "{name}");
        assert_eq!(p.cells.types, [CellType::Polygon, CellType::Polygon]);
        let VertexNumbers::XML { offsets, .. } = &p.cells.cell_verts else {
            panic!("{name}: {:?}", p.cells.cell_verts);
        };
        assert_eq!(offsets, &[4, 52], "{name}");
        let row = &rows[1 + 2 * k];
        let csv = |c: usize| row[c].parse::<f32>().unwrap();
        assert_eq!(cell_array(&p, "velocity")[..2], [csv(6), csv(7)], "{name}");
        assert_eq!(cell_array(&p, "angle")[0], csv(5), "{name}");
        assert_eq!(cell_array(&p, "omega")[0], csv(8), "{name}");
        // The box's outline: its corners 0.4 m and 0.2 m apart around its centre.
        let pts = p.points.clone().cast_into::<f32>().unwrap();
        let corner = |i: usize| (pts[3 * i], pts[3 * i + 1]);
        let ((x0, y0), (x1, y1), (x2, y2)) = (corner(0), corner(1), corner(2));
        let side = |a: (f32, f32), b: (f32, f32)| (a.0 - b.0).hypot(a.1 - b.1);
        assert!((side((x0, y0), (x1, y1)) - 0.4).abs() < 1e-4, "{pts:?}");
        assert!((side((x1, y1), (x2, y2)) - 0.2).abs() < 1e-4, "{pts:?}");
        let centre = (0.5 * (x0 + x2), 0.5 * (y0 + y2));
        assert!(
            (centre.0 - csv(3)).abs() < 1e-4 && (centre.1 - csv(4)).abs() < 1e-4,
            "{centre:?} against {row:?}"
        );
    }

    // The manifest lists the new files, so that the next run in this directory removes them.
    let manifest = std::fs::read_to_string(out_dir.join(".dfsph2d-manifest")).unwrap();
    for name in [
        "bodies.csv",
        "particles/bodies.pvd",
        "particles/bodies_00000.vtu",
    ] {
        assert!(manifest.lines().any(|l| l == name), "{name}:\n{manifest}");
    }
    // No temporary file is left.
    let mut files = Vec::new();
    all_files(&out_dir, &mut files);
    assert!(!files.iter().any(|f| f.ends_with(".tmp")), "{files:?}");

    // A run of a scene without bodies in the same directory writes no bodies files, and the
    // earlier run's are gone (they were ours); a file of the user's stays.
    std::fs::write(out_dir.join("notes.txt"), "mine").unwrap();
    let plain = write_scene(tmp.path(), "plain.json", br#"{"particle_radius": 0.05}"#);
    let out = run(&plain, &out_dir, "csv,vtk");
    assert!(out.status.success(), "{}", text(&out.stderr));
    let mut files = Vec::new();
    all_files(&out_dir, &mut files);
    assert!(!files.iter().any(|f| f.contains("bodies")), "{files:?}");
    assert_eq!(
        std::fs::read_to_string(out_dir.join("notes.txt")).unwrap(),
        "mine"
    );
}

#[test]
fn bodies_csv_does_not_depend_on_the_snapshot_format() {
    // bodies.csv is written as stats.csv is, whatever --format asks for.
    let tmp = tempfile::tempdir().unwrap();
    let scene = write_scene(tmp.path(), "two-bodies.json", TWO_BODIES.as_bytes());
    let out_dir = tmp.path().join("out");
    let out = run(&scene, &out_dir, "png");
    assert!(out.status.success(), "{}", text(&out.stderr));
    let frames = csv_rows(&out_dir.join("particles/index.csv")).len() - 1;
    let rows = csv_rows(&out_dir.join("bodies.csv"));
    assert_eq!(rows.len() - 1, 2 * frames);
    // No VTK asked for: no bodies' .vtu.
    assert!(!out_dir.join("particles/bodies.pvd").exists());
    assert!(!out_dir.join("particles/bodies_00000.vtu").exists());
}

#[test]
fn the_floating_scene_runs() {
    let tmp = tempfile::tempdir().unwrap();
    // The built-in scene at a coarser resolution, through its resolved scene.json.
    let first = tmp.path().join("first");
    let out = dfsph2d(&[
        "run",
        "floating",
        "--until",
        "0.001",
        "--out",
        first.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let resolved = std::fs::read_to_string(first.join("scene.json")).unwrap();
    let mut scene: serde_json::Value = serde_json::from_str(&resolved).unwrap();
    assert_eq!(scene["bodies"].as_array().unwrap().len(), 4);
    scene["particle_radius"] = serde_json::json!(0.05);
    let path = write_scene(
        tmp.path(),
        "floating-coarse.json",
        scene.to_string().as_bytes(),
    );
    let out_dir = tmp.path().join("out");
    let out = run(&path, &out_dir, "csv");
    assert!(out.status.success(), "{}", text(&out.stderr));
    let frames = csv_rows(&out_dir.join("particles/index.csv")).len() - 1;
    assert_eq!(csv_rows(&out_dir.join("bodies.csv")).len() - 1, 4 * frames);
}

/// A scene of the default dam break at r = 2 cm with one body, `body` (JSON).
fn scene_with(body: &str) -> String {
    format!(r#"{{"particle_radius": 0.02, "bodies": [{body}]}}"#)
}

#[test]
fn a_bad_body_is_one_error_naming_its_key_and_nothing_is_written() {
    let cases = [
        (
            "outside the tank",
            r#"{"shape": "box", "size": [0.4, 0.2], "density": 500, "position": [3.9, 0.8]}"#,
            "`bodies[0].position[0]`",
        ),
        (
            "below the floor",
            r#"{"shape": "circle", "radius": 0.1, "density": 500, "position": [2.0, 0.05]}"#,
            "`bodies[0].position[1]`",
        ),
        (
            "a zero height",
            r#"{"shape": "box", "size": [0.4, 0], "density": 500, "position": [2.0, 0.8]}"#,
            "`bodies[0].size[1]`",
        ),
        (
            "a negative width",
            r#"{"shape": "box", "size": [-0.4, 0.2], "density": 500, "position": [2.0, 0.8]}"#,
            "`bodies[0].size[0]`",
        ),
        (
            "a zero radius",
            r#"{"shape": "circle", "radius": 0, "density": 500, "position": [2.0, 0.8]}"#,
            "`bodies[0].radius`",
        ),
        (
            "a zero density",
            r#"{"shape": "box", "size": [0.4, 0.2], "density": 0, "position": [2.0, 0.8]}"#,
            "`bodies[0].density`",
        ),
        (
            "a negative density",
            r#"{"shape": "box", "size": [0.4, 0.2], "density": -500, "position": [2.0, 0.8]}"#,
            "`bodies[0].density`",
        ),
        (
            "a negative mass",
            r#"{"shape": "circle", "radius": 0.1, "mass": -3, "position": [2.0, 0.8]}"#,
            "`bodies[0].mass`",
        ),
        (
            "a non-convex polygon",
            r#"{"shape": "polygon", "points": [[-0.2, -0.2], [0.2, -0.2], [-0.1, -0.1],
                [-0.2, 0.2]], "density": 500, "position": [2.0, 0.8]}"#,
            "`bodies[0].points[2]`",
        ),
        (
            "a body thinner than three spacings",
            r#"{"shape": "box", "size": [0.4, 0.1], "density": 500, "position": [2.0, 0.8]}"#,
            "`bodies[0].size`",
        ),
        (
            "an unknown shape",
            r#"{"shape": "star", "radius": 0.1, "density": 500, "position": [2.0, 0.8]}"#,
            "bodies[0].shape",
        ),
    ];
    let tmp = tempfile::tempdir().unwrap();
    for (what, body, key) in cases {
        let scene = write_scene(tmp.path(), "bad.json", scene_with(body).as_bytes());
        // A new output directory is not created; an existing one is left as it was.
        let fresh = tmp.path().join("never");
        let kept = tmp.path().join("kept");
        std::fs::create_dir_all(&kept).unwrap();
        std::fs::write(kept.join("bodies.csv"), "the user's own\n").unwrap();
        for out_dir in [&fresh, &kept] {
            let out = run(&scene, out_dir, "csv,vtk");
            let stderr = text(&out.stderr);
            assert_eq!(out.status.code(), Some(2), "{what}: {stderr}");
            assert_eq!(stderr.lines().count(), 1, "{what}: not one line: {stderr}");
            assert!(stderr.starts_with("error: "), "{what}: {stderr}");
            assert!(stderr.contains(key), "{what}: {stderr:?} lacks {key}");
            assert!(!stderr.contains("panicked"), "{what}: {stderr}");
            assert_eq!(text(&out.stdout), "", "{what}");
        }
        assert!(!fresh.exists(), "{what}: output directory created");
        let mut files = Vec::new();
        all_files(&kept, &mut files);
        assert_eq!(files.len(), 1, "{what}: {files:?}");
        assert_eq!(
            std::fs::read_to_string(kept.join("bodies.csv")).unwrap(),
            "the user's own\n",
            "{what}"
        );
        // stress refuses it too, before any step.
        let out = dfsph2d(&["stress", scene.to_str().unwrap(), "--steps", "5"]);
        let stderr = text(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "stress {what}: {stderr}");
        assert_eq!(stderr.lines().count(), 1, "stress {what}: {stderr}");
        assert!(stderr.contains(key), "stress {what}: {stderr}");
    }
}
