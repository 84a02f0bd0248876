//! CSV files: particle snapshots and the frame index.
//!
//! Numbers are written with Rust's shortest round-trip formatting, so reading a value back
//! gives exactly the `f32` the solver held.

use std::path::Path;

use anyhow::Result;
use dfsph::rigid::RigidBodyState;
use dfsph::Snapshot;

use crate::atomic::write_atomic;
use crate::numbers::seconds;

/// Header of a particle snapshot CSV.
pub const SNAPSHOT_HEADER: &str = "x,y,vx,vy,density,pressure";

/// Header of the frame index CSV.
pub const INDEX_HEADER: &str = "frame,time,file";

/// Header of the rigid bodies' CSV (`bodies.csv`): one row per body per snapshot.
pub const BODIES_HEADER: &str = "frame,time,body,x,y,angle,vx,vy,omega";

/// The rows of `bodies.csv` for one snapshot (`frame` at `time`, s), one per body in the
/// simulation's order (the scene's, then those added), joined by newlines without a final
/// one, so that [`crate::AppendFile::append`] puts the whole frame on disk in one write:
/// `frame,time,body,x,y,angle,vx,vy,omega` with the body's index, the position of its centre
/// (m), its angle (rad, counter-clockwise), the velocity of its centre (m/s) and its spin
/// (rad/s, counter-clockwise). Empty without bodies.
pub fn bodies_csv_rows(frame: u32, time: f64, bodies: &[RigidBodyState]) -> String {
    let rows: Vec<String> = bodies
        .iter()
        .enumerate()
        .map(|(k, b)| {
            format!(
                "{frame},{},{k},{},{},{},{},{},{}",
                seconds(time),
                b.position.x,
                b.position.y,
                b.angle,
                b.velocity.x,
                b.velocity.y,
                b.angular_velocity
            )
        })
        .collect();
    rows.join("\n")
}

/// Write a snapshot as CSV: [`SNAPSHOT_HEADER`], then one row per fluid particle in the
/// snapshot's order (sorted by id): position (m), velocity (m/s), density (kg/m³),
/// pressure (Pa).
pub fn write_snapshot_csv(path: impl AsRef<Path>, snapshot: &Snapshot) -> Result<()> {
    write_atomic(path, |w| {
        writeln!(w, "{SNAPSHOT_HEADER}")?;
        let n = snapshot.position.len();
        for i in 0..n {
            let p = snapshot.position[i];
            let v = snapshot.velocity.get(i).copied().unwrap_or_default();
            let rho = snapshot.density.get(i).copied().unwrap_or(f32::NAN);
            let pr = snapshot.pressure.get(i).copied().unwrap_or(f32::NAN);
            writeln!(w, "{},{},{},{},{},{}", p.x, p.y, v.x, v.y, rho, pr)?;
        }
        Ok(())
    })
}

/// One written snapshot, as listed in the frame index.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameRecord {
    /// Frame number, counting from 0.
    pub frame: u32,
    /// Simulated time of the snapshot, s.
    pub time: f64,
    /// File name of the snapshot, relative to the index's directory.
    pub file: String,
}

/// One row of the frame index (without the newline): `frame,time,file`.
pub fn frame_index_row(f: &FrameRecord) -> String {
    format!("{},{},{}", f.frame, seconds(f.time), f.file)
}

/// Write the frame index at once: [`INDEX_HEADER`], then one row per frame. (`dfsph2d run`
/// appends the rows as the frames are written instead, with [`crate::AppendFile`].)
pub fn write_frame_index(path: impl AsRef<Path>, frames: &[FrameRecord]) -> Result<()> {
    write_atomic(path, |w| {
        writeln!(w, "{INDEX_HEADER}")?;
        for f in frames {
            writeln!(w, "{}", frame_index_row(f))?;
        }
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use dfsph::Vec2;

    fn snapshot() -> Snapshot {
        Snapshot {
            time: 0.5,
            id: vec![0, 1],
            position: vec![Vec2::new(0.01, 0.02), Vec2::new(0.03, 0.04)],
            velocity: vec![Vec2::new(1.5, -2.0), Vec2::ZERO],
            density: vec![1000.0, 1001.25],
            pressure: vec![0.0, 98.1],
        }
    }

    #[test]
    fn snapshot_csv_has_header_and_exact_rows() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("00000.csv");
        write_snapshot_csv(&path, &snapshot()).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines[0], "x,y,vx,vy,density,pressure");
        assert_eq!(lines[1], "0.01,0.02,1.5,-2,1000,0");
        assert_eq!(lines[2], "0.03,0.04,0,0,1001.25,98.1");
        assert_eq!(lines.len(), 3);
        // Values round-trip exactly to f32.
        let x: f32 = lines[2].split(',').next().unwrap().parse().unwrap();
        assert_eq!(x, 0.03f32);
    }

    fn body(x: f32, angle: f32) -> RigidBodyState {
        let spec = dfsph::rigid::BodySpec::new_box([0.4, 0.2], 500.0, [x as f64, 0.8]);
        RigidBodyState {
            position: Vec2::new(x, 0.8),
            angle,
            velocity: Vec2::new(0.5, -1.25),
            angular_velocity: -0.125,
            mass: 40.0,
            spec,
            outline: Vec::new(),
        }
    }

    #[test]
    fn bodies_rows_are_one_per_body_with_exact_values() {
        let rows = bodies_csv_rows(3, 0.15, &[body(1.0, 0.0), body(2.5, 0.1)]);
        assert_eq!(
            rows,
            "3,0.15,0,1,0.8,0,0.5,-1.25,-0.125\n3,0.15,1,2.5,0.8,0.1,0.5,-1.25,-0.125"
        );
        assert_eq!(BODIES_HEADER.split(',').count(), 9);
        assert_eq!(bodies_csv_rows(0, 0.0, &[]), "");
    }

    #[test]
    fn empty_snapshot_is_just_the_header() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("e.csv");
        write_snapshot_csv(&path, &Snapshot::default()).unwrap();
        assert_eq!(
            std::fs::read_to_string(&path).unwrap(),
            "x,y,vx,vy,density,pressure\n"
        );
    }

    #[test]
    fn frame_index_lists_frames() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("index.csv");
        let frames = [
            FrameRecord {
                frame: 0,
                time: 0.0,
                file: "00000.csv".into(),
            },
            FrameRecord {
                frame: 1,
                time: 0.0525,
                file: "00001.csv".into(),
            },
        ];
        write_frame_index(&path, &frames).unwrap();
        assert_eq!(
            std::fs::read_to_string(&path).unwrap(),
            "frame,time,file\n0,0,00000.csv\n1,0.0525,00001.csv\n"
        );
    }
}
