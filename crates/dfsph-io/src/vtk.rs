//! VTK XML output for ParaView: one UnstructuredGrid (`.vtu`) per snapshot, and a `.pvd`
//! collection that lists the snapshots with their simulated times. The walls are a `.vtu` of
//! points as the particles are; the rigid bodies a `.vtu` of polygons, one cell per body
//! ([`write_bodies_vtu`]).
//!
//! Each particle is a point (z = 0) with a vertex cell, so ParaView shows it directly and
//! filters such as *Point Gaussian* work. Point data: `velocity` (3 components, m/s, z = 0),
//! `density` (kg/m³), `pressure` (Pa) and `id` (the particle's stable id). Arrays are inline
//! binary: base64 of a little-endian `UInt64` byte count followed by the little-endian values,
//! the layout VTK writes for uncompressed data (`header_type="UInt64"`).

use std::io::{self, Write};
use std::path::Path;

use anyhow::Result;
use dfsph::rigid::RigidBodyState;
use dfsph::{Snapshot, Vec2};

use crate::atomic::write_atomic;

/// VTK cell type of a single point.
const VTK_VERTEX: u8 = 1;

/// VTK cell type of a polygon (its points in order around it).
const VTK_POLYGON: u8 = 7;

/// Write a snapshot as a VTK XML UnstructuredGrid (`.vtu`).
pub fn write_vtu(path: impl AsRef<Path>, snapshot: &Snapshot) -> Result<()> {
    write_atomic(path, |w| write_vtu_to(w, snapshot))
}

/// The `.vtu` document for `snapshot`, written to `w`.
pub fn write_vtu_to(w: &mut dyn Write, snapshot: &Snapshot) -> io::Result<()> {
    let n = snapshot.position.len();
    let get = |v: &[f32], i: usize| v.get(i).copied().unwrap_or(f32::NAN);
    let velocity: Vec<f32> = (0..n)
        .flat_map(|i| {
            let v = snapshot.velocity.get(i).copied().unwrap_or_default();
            [v.x, v.y, 0.0]
        })
        .collect();
    let density: Vec<f32> = (0..n).map(|i| get(&snapshot.density, i)).collect();
    let pressure: Vec<f32> = (0..n).map(|i| get(&snapshot.pressure, i)).collect();
    let id: Vec<u32> = (0..n)
        .map(|i| snapshot.id.get(i).copied().unwrap_or(i as u32))
        .collect();
    write_points(
        w,
        &snapshot.position,
        r#"Scalars="density" Vectors="velocity""#,
        &[
            ("Float32", "velocity", 3, bytes_f32(&velocity)),
            ("Float32", "density", 1, bytes_f32(&density)),
            ("Float32", "pressure", 1, bytes_f32(&pressure)),
            ("UInt32", "id", 1, bytes_u32(&id)),
        ],
    )
}

/// Write the walls the fluid feels as a `.vtu` of points: every boundary particle (the tank's
/// walls, the scene's obstacles, walls drawn in the viewer) at `positions`, with point data
/// `body` (0 = the tank, then one number per obstacle or drawn wall, `body`) and `volume`
/// (the particle's boundary volume Ψ, m², Akinci et al. 2012).
pub fn write_walls_vtu(
    path: impl AsRef<Path>,
    positions: &[Vec2],
    body: &[u16],
    volume: &[f32],
) -> Result<()> {
    write_atomic(path, |w| write_walls_vtu_to(w, positions, body, volume))
}

/// The `.vtu` document of [`write_walls_vtu`], written to `w`.
pub fn write_walls_vtu_to(
    w: &mut dyn Write,
    positions: &[Vec2],
    body: &[u16],
    volume: &[f32],
) -> io::Result<()> {
    let n = positions.len();
    let body: Vec<u32> = (0..n)
        .map(|i| body.get(i).copied().unwrap_or(0).into())
        .collect();
    let volume: Vec<f32> = (0..n)
        .map(|i| volume.get(i).copied().unwrap_or(f32::NAN))
        .collect();
    write_points(
        w,
        positions,
        r#"Scalars="body""#,
        &[
            ("UInt32", "body", 1, bytes_u32(&body)),
            ("Float32", "volume", 1, bytes_f32(&volume)),
        ],
    )
}

/// A `.vtu` of `positions` (z = 0), each point its own vertex cell, with the point data
/// `arrays` (VTK type, name, components, little-endian bytes); `defaults` names the active
/// scalars and vectors.
fn write_points(
    w: &mut dyn Write,
    positions: &[Vec2],
    defaults: &str,
    arrays: &[DataArray],
) -> io::Result<()> {
    let n = positions.len();
    let cells = Cells {
        connectivity: (0..n as i64).collect(),
        offsets: (1..=n as i64).collect(),
        types: vec![VTK_VERTEX; n],
    };
    write_grid(w, positions, &cells, (defaults, arrays), ("", &[]))
}

/// One named data array: VTK type, name, components, little-endian bytes.
type DataArray<'a> = (&'a str, &'a str, usize, Vec<u8>);

/// The cells of an UnstructuredGrid: the points of each in one list, where each ends in it,
/// and each one's VTK type.
struct Cells {
    connectivity: Vec<i64>,
    offsets: Vec<i64>,
    types: Vec<u8>,
}

/// A `.vtu` of `positions` (z = 0) and `cells`, with point data and cell data (each the
/// attribute naming its active scalars and vectors, and the arrays).
fn write_grid(
    w: &mut dyn Write,
    positions: &[Vec2],
    cells: &Cells,
    point_data: (&str, &[DataArray]),
    cell_data: (&str, &[DataArray]),
) -> io::Result<()> {
    let points: Vec<f32> = positions.iter().flat_map(|p| [p.x, p.y, 0.0]).collect();
    writeln!(w, r#"<?xml version="1.0"?>"#)?;
    writeln!(
        w,
        r#"<VTKFile type="UnstructuredGrid" version="1.0" byte_order="LittleEndian" header_type="UInt64">"#
    )?;
    writeln!(w, "  <UnstructuredGrid>")?;
    writeln!(
        w,
        r#"    <Piece NumberOfPoints="{}" NumberOfCells="{}">"#,
        positions.len(),
        cells.types.len()
    )?;
    for (tag, (defaults, arrays)) in [("PointData", point_data), ("CellData", cell_data)] {
        if arrays.is_empty() {
            continue;
        }
        writeln!(w, "      <{tag} {defaults}>")?;
        for (ty, name, components, bytes) in arrays {
            data_array(w, ty, Some(name), *components, bytes)?;
        }
        writeln!(w, "      </{tag}>")?;
    }
    writeln!(w, "      <Points>")?;
    data_array(w, "Float32", None, 3, &bytes_f32(&points))?;
    writeln!(w, "      </Points>")?;
    writeln!(w, "      <Cells>")?;
    data_array(
        w,
        "Int64",
        Some("connectivity"),
        1,
        &bytes_i64(&cells.connectivity),
    )?;
    data_array(w, "Int64", Some("offsets"), 1, &bytes_i64(&cells.offsets))?;
    data_array(w, "UInt8", Some("types"), 1, &cells.types)?;
    writeln!(w, "      </Cells>")?;
    writeln!(w, "    </Piece>")?;
    writeln!(w, "  </UnstructuredGrid>")?;
    writeln!(w, "</VTKFile>")
}

/// Write the rigid bodies as a `.vtu` of polygons: each body's outline in the tank's frame
/// (counter-clockwise; a circle as its 48-gon), z = 0, is one polygon cell, in the
/// simulation's order, with cell data `body` (the body's index, as in `bodies.csv`),
/// `velocity` (of its centre, 3 components, m/s, z = 0), `angle` (rad, counter-clockwise),
/// `omega` (spin, rad/s) and `mass` (kg per metre of depth). No bodies: an empty grid.
pub fn write_bodies_vtu(path: impl AsRef<Path>, bodies: &[RigidBodyState]) -> Result<()> {
    write_atomic(path, |w| write_bodies_vtu_to(w, bodies))
}

/// The `.vtu` document of [`write_bodies_vtu`], written to `w`.
pub fn write_bodies_vtu_to(w: &mut dyn Write, bodies: &[RigidBodyState]) -> io::Result<()> {
    let positions: Vec<Vec2> = bodies.iter().flat_map(|b| b.outline.clone()).collect();
    let mut offsets = Vec::with_capacity(bodies.len());
    let mut end = 0i64;
    for b in bodies {
        end += b.outline.len() as i64;
        offsets.push(end);
    }
    let cells = Cells {
        connectivity: (0..positions.len() as i64).collect(),
        offsets,
        types: vec![VTK_POLYGON; bodies.len()],
    };
    let body: Vec<u32> = (0..bodies.len() as u32).collect();
    let velocity: Vec<f32> = bodies
        .iter()
        .flat_map(|b| [b.velocity.x, b.velocity.y, 0.0])
        .collect();
    let angle: Vec<f32> = bodies.iter().map(|b| b.angle).collect();
    let omega: Vec<f32> = bodies.iter().map(|b| b.angular_velocity).collect();
    let mass: Vec<f32> = bodies.iter().map(|b| b.mass).collect();
    write_grid(
        w,
        &positions,
        &cells,
        ("", &[]),
        (
            r#"Scalars="body" Vectors="velocity""#,
            &[
                ("UInt32", "body", 1, bytes_u32(&body)),
                ("Float32", "velocity", 3, bytes_f32(&velocity)),
                ("Float32", "angle", 1, bytes_f32(&angle)),
                ("Float32", "omega", 1, bytes_f32(&omega)),
                ("Float32", "mass", 1, bytes_f32(&mass)),
            ],
        ),
    )
}

/// One inline binary `<DataArray>`.
fn data_array(
    w: &mut dyn Write,
    ty: &str,
    name: Option<&str>,
    components: usize,
    bytes: &[u8],
) -> io::Result<()> {
    write!(w, r#"        <DataArray type="{ty}""#)?;
    if let Some(name) = name {
        write!(w, r#" Name="{name}""#)?;
    }
    if components != 1 {
        write!(w, r#" NumberOfComponents="{components}""#)?;
    }
    write!(w, r#" format="binary">"#)?;
    let mut block = Vec::with_capacity(8 + bytes.len());
    block.extend_from_slice(&(bytes.len() as u64).to_le_bytes());
    block.extend_from_slice(bytes);
    w.write_all(base64(&block).as_bytes())?;
    writeln!(w, "</DataArray>")
}

fn bytes_f32(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

fn bytes_u32(v: &[u32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

fn bytes_i64(v: &[i64]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// Standard base64 (RFC 4648, with padding).
fn base64(data: &[u8]) -> String {
    const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(data.len().div_ceil(3) * 4);
    for chunk in data.chunks(3) {
        let b = [
            chunk[0],
            chunk.get(1).copied().unwrap_or(0),
            chunk.get(2).copied().unwrap_or(0),
        ];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for k in 0..4 {
            if k <= chunk.len() {
                out.push(ALPHABET[((n >> (18 - 6 * k)) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

/// Write a ParaView collection (`.pvd`) listing `(time in s, file name relative to the
/// .pvd)` pairs, so ParaView plays the `.vtu` series at the right simulated times.
pub fn write_pvd(path: impl AsRef<Path>, frames: &[(f64, String)]) -> Result<()> {
    write_atomic(path, |w| {
        writeln!(w, r#"<?xml version="1.0"?>"#)?;
        writeln!(
            w,
            r#"<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">"#
        )?;
        writeln!(w, "  <Collection>")?;
        for (time, file) in frames {
            writeln!(
                w,
                r#"    <DataSet timestep="{}" group="" part="0" file="{}"/>"#,
                crate::numbers::seconds(*time),
                xml_escape(file)
            )?;
        }
        writeln!(w, "  </Collection>")?;
        writeln!(w, "</VTKFile>")
    })
}

fn xml_escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

#[cfg(test)]
mod tests {
    use super::*;
    use dfsph::Vec2;
    use vtkio::model::{Attribute, DataSet, ElementType, Piece, VertexNumbers};

    #[test]
    fn base64_matches_rfc4648_vectors() {
        let cases = [
            ("", ""),
            ("f", "Zg=="),
            ("fo", "Zm8="),
            ("foo", "Zm9v"),
            ("foob", "Zm9vYg=="),
            ("fooba", "Zm9vYmE="),
            ("foobar", "Zm9vYmFy"),
        ];
        for (plain, encoded) in cases {
            assert_eq!(base64(plain.as_bytes()), encoded);
        }
        assert_eq!(base64(&[0xff, 0xfe, 0xfd]), "//79");
    }

    fn snapshot(n: usize) -> Snapshot {
        Snapshot {
            time: 0.25,
            id: (0..n as u32).collect(),
            position: (0..n)
                .map(|i| Vec2::new(0.1 * i as f32, 0.05 * i as f32))
                .collect(),
            velocity: (0..n).map(|i| Vec2::new(i as f32, -(i as f32))).collect(),
            density: (0..n).map(|i| 1000.0 + i as f32).collect(),
            pressure: (0..n).map(|i| 10.0 * i as f32).collect(),
        }
    }

    fn f32s(buf: &vtkio::IOBuffer) -> Vec<f32> {
        buf.clone().cast_into::<f32>().expect("f32 data")
    }

    #[test]
    fn vtu_reads_back_with_vtkio() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("00000.vtu");
        let snap = snapshot(7);
        write_vtu(&path, &snap).unwrap();

        let vtk = vtkio::Vtk::import(&path).expect("vtkio reads the .vtu");
        let pieces = match vtk.data {
            DataSet::UnstructuredGrid { pieces, .. } => pieces,
            other => panic!("expected an UnstructuredGrid, got {other:?}"),
        };
        assert_eq!(pieces.len(), 1);
        let piece = match &pieces[0] {
            Piece::Inline(p) => p.clone(),
            other => panic!("expected inline piece, got {other:?}"),
        };
        assert_eq!(piece.num_points(), 7);
        let points = f32s(&piece.points);
        assert_eq!(points.len(), 21);
        assert_eq!(points[3..6], [0.1, 0.05, 0.0]);

        match &piece.cells.cell_verts {
            VertexNumbers::XML {
                connectivity,
                offsets,
            } => {
                assert_eq!(connectivity, &(0..7).collect::<Vec<u64>>());
                assert_eq!(offsets, &(1..=7).collect::<Vec<u64>>());
            }
            other => panic!("unexpected cells {other:?}"),
        }
        assert_eq!(piece.cells.types.len(), 7);
        assert!(piece
            .cells
            .types
            .iter()
            .all(|t| *t == vtkio::model::CellType::Vertex));

        let mut seen = Vec::new();
        for attr in &piece.data.point {
            let Attribute::DataArray(a) = attr else {
                panic!("unexpected field attribute");
            };
            seen.push(a.name.clone());
            match a.name.as_str() {
                "velocity" => {
                    assert_eq!(a.elem, ElementType::Vectors);
                    let v = f32s(&a.data);
                    assert_eq!(v.len(), 21);
                    assert_eq!(v[6..9], [2.0, -2.0, 0.0]);
                }
                "density" => assert_eq!(f32s(&a.data)[3], 1003.0),
                "pressure" => assert_eq!(f32s(&a.data)[4], 40.0),
                "id" => {
                    let ids = a.data.clone().cast_into::<u32>().unwrap();
                    assert_eq!(ids, (0..7).collect::<Vec<u32>>());
                }
                other => panic!("unexpected array {other}"),
            }
        }
        seen.sort();
        assert_eq!(seen, ["density", "id", "pressure", "velocity"]);
    }

    #[test]
    fn walls_read_back_with_vtkio_with_their_bodies_and_volumes() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("walls_00000.vtu");
        let positions = [
            Vec2::new(-0.01, 0.5),
            Vec2::new(1.2, 0.3),
            Vec2::new(1.3, 0.3),
        ];
        write_walls_vtu(&path, &positions, &[0, 2, 2], &[1e-4, 2e-4, 3e-4]).unwrap();
        let vtk = vtkio::Vtk::import(&path).expect("vtkio reads the .vtu");
        let DataSet::UnstructuredGrid { pieces, .. } = vtk.data else {
            panic!("expected an UnstructuredGrid");
        };
        let Piece::Inline(piece) = &pieces[0] else {
            panic!("expected an inline piece");
        };
        assert_eq!(piece.num_points(), 3);
        assert_eq!(f32s(&piece.points)[3..6], [1.2, 0.3, 0.0]);
        let array = |name: &str| {
            piece
                .data
                .point
                .iter()
                .find_map(|a| match a {
                    Attribute::DataArray(a) if a.name == name => Some(a.data.clone()),
                    _ => None,
                })
                .unwrap_or_else(|| panic!("no {name}"))
        };
        assert_eq!(array("body").cast_into::<u32>().unwrap(), [0, 2, 2]);
        assert_eq!(f32s(&array("volume")), [1e-4, 2e-4, 3e-4]);
    }

    #[test]
    fn bodies_read_back_with_vtkio_as_polygons_with_their_cell_data() {
        use dfsph::rigid::BodySpec;
        let body =
            |outline: Vec<Vec2>, v: Vec2, angle: f32, omega: f32, mass: f32| RigidBodyState {
                position: outline.iter().copied().sum::<Vec2>() / outline.len() as f32,
                angle,
                velocity: v,
                angular_velocity: omega,
                mass,
                spec: BodySpec::new_box([0.2, 0.2], 500.0, [1.0, 1.0]),
                outline,
            };
        let square = vec![
            Vec2::new(0.9, 0.9),
            Vec2::new(1.1, 0.9),
            Vec2::new(1.1, 1.1),
            Vec2::new(0.9, 1.1),
        ];
        let triangle = vec![
            Vec2::new(2.0, 0.5),
            Vec2::new(2.3, 0.5),
            Vec2::new(2.1, 0.8),
        ];
        let bodies = [
            body(square, Vec2::new(0.5, -1.0), 0.25, 2.0, 20.0),
            body(triangle, Vec2::new(-0.5, 0.0), -1.0, 0.5, 7.5),
        ];
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("bodies_00000.vtu");
        write_bodies_vtu(&path, &bodies).unwrap();
        let vtk = vtkio::Vtk::import(&path).expect("vtkio reads the .vtu");
        let DataSet::UnstructuredGrid { pieces, .. } = vtk.data else {
            panic!("expected an UnstructuredGrid");
        };
        let Piece::Inline(piece) = &pieces[0] else {
            panic!("expected an inline piece");
        };
        assert_eq!(piece.num_points(), 7);
        assert_eq!(f32s(&piece.points)[3..6], [1.1, 0.9, 0.0]);
        assert_eq!(f32s(&piece.points)[18..21], [2.1, 0.8, 0.0]);
        match &piece.cells.cell_verts {
            VertexNumbers::XML {
                connectivity,
                offsets,
            } => {
                assert_eq!(connectivity, &(0..7).collect::<Vec<u64>>());
                assert_eq!(offsets, &[4, 7]);
            }
            other => panic!("unexpected cells {other:?}"),
        }
        assert_eq!(
            piece.cells.types,
            [
                vtkio::model::CellType::Polygon,
                vtkio::model::CellType::Polygon
            ]
        );
        assert!(piece.data.point.is_empty());
        let array = |name: &str| {
            piece
                .data
                .cell
                .iter()
                .find_map(|a| match a {
                    Attribute::DataArray(a) if a.name == name => Some(a.data.clone()),
                    _ => None,
                })
                .unwrap_or_else(|| panic!("no {name}"))
        };
        assert_eq!(array("body").cast_into::<u32>().unwrap(), [0, 1]);
        assert_eq!(f32s(&array("velocity")), [0.5, -1.0, 0.0, -0.5, 0.0, 0.0]);
        assert_eq!(f32s(&array("angle")), [0.25, -1.0]);
        assert_eq!(f32s(&array("omega")), [2.0, 0.5]);
        assert_eq!(f32s(&array("mass")), [20.0, 7.5]);

        // No bodies: an empty grid that still reads.
        write_bodies_vtu(&path, &[]).unwrap();
        let vtk = vtkio::Vtk::import(&path).expect("an empty grid reads");
        let DataSet::UnstructuredGrid { pieces, .. } = vtk.data else {
            panic!("expected an UnstructuredGrid");
        };
        let Piece::Inline(piece) = &pieces[0] else {
            panic!("expected an inline piece");
        };
        assert_eq!(piece.num_points(), 0);
    }

    #[test]
    fn pvd_lists_frames_with_times() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("particles.pvd");
        write_pvd(
            &path,
            &[(0.0, "00000.vtu".into()), (0.05, "00001.vtu".into())],
        )
        .unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(text.contains(r#"timestep="0.05" group="" part="0" file="00001.vtu""#));
        assert!(text.contains(r#"type="Collection""#));
    }
}
