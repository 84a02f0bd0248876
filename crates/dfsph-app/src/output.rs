//! The output directory of `dfsph2d run` and the per-snapshot files in it:
//!
//! ```text
//! DIR/scene.json              the resolved scene
//! DIR/stats.csv               one row per step
//! DIR/particles/index.csv     frame,time,file
//! DIR/particles/NNNNN.csv     per snapshot (.vtu / .png when asked for)
//! DIR/particles/particles.pvd ParaView collection of the .vtu files with their times
//! ```

use std::path::{Path, PathBuf};

use anyhow::Result;
use dfsph::{Scene, Simulation};
use dfsph_io::{FrameRecord, RenderGeometry, RenderOptions};

use crate::cli::Format;

/// Sub-directory holding the snapshots.
pub const PARTICLES_DIR: &str = "particles";

/// Check, without creating anything, that `dir` can be used as the output directory: it
/// may exist (its files are then overwritten) but must not be a file.
pub fn check_output_dir(dir: &Path) -> Result<(), String> {
    match std::fs::metadata(dir) {
        Ok(meta) if meta.is_dir() => {
            let particles = dir.join(PARTICLES_DIR);
            match std::fs::metadata(&particles) {
                Ok(m) if !m.is_dir() => Err(format!(
                    "output `{}` exists and is not a directory",
                    particles.display()
                )),
                _ => Ok(()),
            }
        }
        Ok(_) => Err(format!(
            "output directory `{}` exists and is not a directory",
            dir.display()
        )),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(()),
        Err(e) => Err(format!(
            "cannot use output directory `{}`: {e}",
            dir.display()
        )),
    }
}

/// Create `dir` and `dir/particles`, and remove snapshot files a previous run left there
/// (`NNNNN.csv|vtu|png`), so the directory holds exactly this run's frames.
pub fn create_output_dir(dir: &Path) -> Result<(), String> {
    let particles = dir.join(PARTICLES_DIR);
    std::fs::create_dir_all(&particles).map_err(|e| {
        format!(
            "cannot create output directory `{}`: {e}",
            particles.display()
        )
    })?;
    let entries = std::fs::read_dir(&particles)
        .map_err(|e| format!("cannot list `{}`: {e}", particles.display()))?;
    for entry in entries.flatten() {
        let name = entry.file_name();
        let name = name.to_string_lossy();
        // `NAME.tmp`: a file a killed run was writing (see `dfsph_io::atomic`).
        if is_frame_file(name.strip_suffix(".tmp").unwrap_or(&name)) {
            std::fs::remove_file(entry.path()).map_err(|e| {
                format!("cannot remove old frame `{}`: {e}", entry.path().display())
            })?;
        }
    }
    // Temporary files of a run that was killed (SIGKILL, power loss) while writing them.
    for tmp in [
        dir.join("scene.json.tmp"),
        dir.join("stats.csv.tmp"),
        dir.join("probes.csv.tmp"),
        particles.join("index.csv.tmp"),
        particles.join("particles.pvd.tmp"),
    ] {
        match std::fs::remove_file(&tmp) {
            Ok(()) => {}
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
            Err(e) => return Err(format!("cannot remove `{}`: {e}", tmp.display())),
        }
    }
    Ok(())
}

/// `00042.csv`, `00042.vtu`, `123456.png`: a snapshot file this program writes.
fn is_frame_file(name: &str) -> bool {
    let Some((stem, ext)) = name.rsplit_once('.') else {
        return false;
    };
    stem.len() >= 5
        && stem.bytes().all(|b| b.is_ascii_digit())
        && matches!(ext, "csv" | "vtu" | "png")
}

/// Writes numbered snapshots in the chosen formats and, at the end, the index.
pub struct FrameWriter {
    dir: PathBuf,
    formats: Vec<Format>,
    frames: Vec<FrameRecord>,
    png: RenderOptions,
    /// Step of the last frame written.
    last_step: Option<u64>,
}

impl FrameWriter {
    /// Frames go to `out/particles`; `formats` is deduplicated and ordered csv, vtk, png.
    pub fn new(out: &Path, formats: &[Format], scene: &Scene, png_width: u32) -> Self {
        let mut formats = formats.to_vec();
        formats.sort();
        formats.dedup();
        Self {
            dir: out.join(PARTICLES_DIR),
            formats,
            frames: Vec::new(),
            png: RenderOptions {
                width: png_width,
                speed_max: speed_scale(scene),
            },
            last_step: None,
        }
    }

    /// The simulation was rebuilt (a reset in a replay): its step count starts again, so
    /// the next [`FrameWriter::write`] must not be mistaken for a repeat of the last frame.
    pub fn new_epoch(&mut self) {
        self.last_step = None;
    }

    /// Frames written so far.
    pub fn count(&self) -> usize {
        self.frames.len()
    }

    /// Write the simulation's current state as the next frame, unless this step was
    /// already written.
    pub fn write(&mut self, sim: &Simulation) -> Result<()> {
        let step = sim.step_count();
        if self.last_step == Some(step) {
            return Ok(());
        }
        let frame = self.frames.len() as u32;
        let stem = format!("{frame:05}");
        let snapshot = sim.snapshot();
        for &format in &self.formats {
            let path = self.dir.join(format!("{stem}.{}", format.extension()));
            match format {
                Format::Csv => dfsph_io::write_snapshot_csv(&path, &snapshot)?,
                Format::Vtk => dfsph_io::write_vtu(&path, &snapshot)?,
                Format::Png => {
                    dfsph_io::write_png(&path, &RenderGeometry::of(sim), &snapshot, &self.png)?
                }
            }
        }
        let first = self.formats.first().copied().unwrap_or(Format::Csv);
        self.frames.push(FrameRecord {
            frame,
            time: snapshot.time,
            file: format!("{stem}.{}", first.extension()),
        });
        self.last_step = Some(step);
        Ok(())
    }

    /// Write `index.csv` (and `particles.pvd` for VTK output).
    pub fn finish(&self) -> Result<()> {
        dfsph_io::write_frame_index(self.dir.join("index.csv"), &self.frames)?;
        if self.formats.contains(&Format::Vtk) {
            let series: Vec<(f64, String)> = self
                .frames
                .iter()
                .map(|f| (f.time, format!("{:05}.vtu", f.frame)))
                .collect();
            dfsph_io::write_pvd(self.dir.join("particles.pvd"), &series)?;
        }
        Ok(())
    }
}

/// A fixed top of the PNG colour scale for the whole run, so colours mean the same speed in
/// every frame: the speed of a fall from the top of the tank, `√(2·|g|·H)`, plus the fastest
/// initial block velocity. `None` (scale per frame) when that is zero.
fn speed_scale(scene: &Scene) -> Option<f32> {
    let g = scene.gravity[0].hypot(scene.gravity[1]);
    let height = scene.tank.max[1] - scene.tank.min[1];
    let initial = scene
        .fluid
        .iter()
        .map(|b| b.velocity[0].hypot(b.velocity[1]))
        .fold(0.0, f64::max);
    let v = (2.0 * g * height).sqrt() + initial;
    (v.is_finite() && v > 0.0).then_some(v as f32)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_files_are_recognised() {
        assert!(is_frame_file("00000.csv"));
        assert!(is_frame_file("123456.png"));
        assert!(is_frame_file("00042.vtu"));
        assert!(!is_frame_file("index.csv"));
        assert!(!is_frame_file("0001.csv"));
        assert!(!is_frame_file("00001.txt"));
        assert!(!is_frame_file("notes-00001.csv"));
    }

    #[test]
    fn output_dir_must_not_be_a_file() {
        let dir = tempfile::tempdir().unwrap();
        assert!(check_output_dir(&dir.path().join("new")).is_ok());
        assert!(check_output_dir(dir.path()).is_ok());
        let file = dir.path().join("f");
        std::fs::write(&file, "x").unwrap();
        assert!(check_output_dir(&file)
            .unwrap_err()
            .contains("is not a directory"));
    }

    #[test]
    fn stale_frames_are_removed_other_files_kept() {
        let dir = tempfile::tempdir().unwrap();
        let particles = dir.path().join(PARTICLES_DIR);
        std::fs::create_dir_all(&particles).unwrap();
        std::fs::write(particles.join("00007.csv"), "old").unwrap();
        std::fs::write(particles.join("notes.txt"), "mine").unwrap();
        std::fs::write(particles.join("00008.vtu.tmp"), "partial").unwrap();
        std::fs::write(dir.path().join("stats.csv.tmp"), "partial").unwrap();
        create_output_dir(dir.path()).unwrap();
        assert!(!particles.join("00008.vtu.tmp").exists());
        assert!(!dir.path().join("stats.csv.tmp").exists());
        assert!(!particles.join("00007.csv").exists());
        assert!(particles.join("notes.txt").exists());
    }

    #[test]
    fn speed_scale_is_a_fall_from_the_tank_top() {
        let s = dfsph::scene::builtin("dam-break").unwrap();
        let v = speed_scale(&s).unwrap();
        assert!((v - (2.0f32 * 9.81 * 3.0).sqrt()).abs() < 1e-3);
        let mut still = s.clone();
        still.gravity = [0.0, 0.0];
        assert_eq!(speed_scale(&still), None);
    }
}
