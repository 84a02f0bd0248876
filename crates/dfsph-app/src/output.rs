//! The output directory of `dfsph2d run` and the per-snapshot files in it:
//!
//! ```text
//! DIR/scene.json              the resolved scene
//! DIR/stats.csv               one row per step
//! DIR/particles/index.csv     frame,time,file
//! DIR/particles/NNNNN.csv     per snapshot (.vtu / .png when asked for)
//! DIR/particles/particles.pvd ParaView collection of the .vtu files with their times
//! DIR/particles/walls_NNNNN.vtu the walls (tank, obstacles, drawn walls) as boundary
//!                             particles, VTK only, written when they changed
//! DIR/particles/walls.pvd     ParaView collection of the walls at every frame's time
//! DIR/bodies.csv              the rigid bodies at every snapshot (scenes with bodies only)
//! DIR/particles/bodies_NNNNN.vtu the rigid bodies' outlines as polygons, VTK only, from the
//!                             first frame with a body on
//! DIR/particles/bodies.pvd    ParaView collection of the bodies' files with their times
//! DIR/video.gif, video.mp4    every snapshot's picture in one animation (`--format gif,mp4`)
//! DIR/.dfsph2d-manifest       every file above that this run wrote, one per line
//! ```
//!
//! A video is written to `video.gif.tmp` (`video.mp4.tmp`, by ffmpeg) as the run goes and
//! renamed when the run ends, so `video.gif` exists only complete; a run stopped by an error
//! leaves neither, a run stopped by Ctrl-C finishes the video with the frames it wrote.
//!
//! `bodies.csv` has the columns `frame,time,body,x,y,angle,vx,vy,omega`, one row per body
//! per snapshot (`frame` and `time` as in `index.csv`). It is created with the first
//! snapshot that has a body (a scene without bodies, replayed without dropping one in, has
//! none, not an empty one); a frame's rows go to the file in one write.
//!
//! What a run completed survives however it stops (SIGKILL, a full disk): `stats.csv`,
//! `probes.csv`, `bodies.csv` and `index.csv` grow one complete line (`bodies.csv`: one
//! complete frame) at a time, on disk at once; snapshots,
//! `scene.json` and `particles.pvd` are written to `NAME.tmp`, synced and renamed, and a
//! frame is listed in `index.csv` and `particles.pvd` only once all its files are complete.
//!
//! A run removes only what an earlier run of ours wrote: the files its manifest lists (and
//! their `NAME.tmp`, left by a killed run), nothing else; so no `particles.pvd` or
//! `probes.csv` of an earlier run outlives a run that does not write one. A name is recorded
//! in the manifest before its file is created, so a run killed at any point leaves a manifest
//! that covers everything it wrote. `DIR/particles` must be a real directory, not a symbolic
//! link, so nothing outside DIR is ever written or removed.

use std::io::{BufRead, Write};
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use dfsph::{Scene, Simulation};
use dfsph_io::{FrameRecord, RenderGeometry, RenderOptions};

use crate::cli::Format;

/// Sub-directory holding the snapshots.
pub const PARTICLES_DIR: &str = "particles";

/// The list of files a run wrote, in the output directory, relative to it.
pub const MANIFEST: &str = ".dfsph2d-manifest";

/// The rigid bodies at every snapshot, in the output directory.
pub const BODIES_CSV: &str = "bodies.csv";

/// The GIF of `--format gif`, in the output directory.
pub const GIF_FILE: &str = "video.gif";

/// The MP4 of `--format mp4`, in the output directory.
pub const MP4_FILE: &str = "video.mp4";

/// First line of [`MANIFEST`].
const MANIFEST_HEADER: &str =
    "# dfsph2d run: files written by this run, removed by the next run in this directory";

/// Memory the frame writers take besides the simulation's snapshot, bytes, for the memory
/// check (`dfsph::memory`): a picture (PNG or video frame) is a pixmap of `png_width` × its
/// height in RGBA and its encoded copy (at most as large); a GIF frame adds its RGB copy and
/// palette indices (4 bytes a pixel), an MP4 frame its RGB copy (3); a VTK frame builds its
/// arrays (53 bytes per particle) and the base64 text of the largest (16 bytes per particle).
pub fn buffer_bytes(formats: &[Format], png_width: u32, scene: &Scene, fluid: u64) -> u64 {
    let mut bytes = 0u64;
    if formats.iter().any(|f| f.is_picture()) {
        let width = png_width.clamp(dfsph_io::render::MIN_WIDTH, dfsph_io::render::MAX_SIDE) as f64;
        let margin = 4.0 * scene.spacing();
        let aspect = (scene.tank.max[1] - scene.tank.min[1] + margin)
            / (scene.tank.max[0] - scene.tank.min[0] + margin);
        let height = (width * aspect + 64.0).min(dfsph_io::render::MAX_SIDE as f64);
        let per_pixel =
            8.0 + if formats.contains(&Format::Gif) {
                4.0
            } else {
                0.0
            } + if formats.contains(&Format::Mp4) {
                3.0
            } else {
                0.0
            };
        bytes += (per_pixel * width * height) as u64;
    }
    if formats.contains(&Format::Vtk) {
        bytes = bytes.saturating_add(fluid.saturating_mul(53 + 16));
    }
    bytes
}

/// Check, without creating anything, that `dir` can be used as the output directory: it
/// may exist (its files of the names we write are then overwritten) but must not be a file,
/// and `dir/particles`, if it exists, must be a directory and not a symbolic link (which
/// would have frames written, and old ones removed, outside `dir`).
pub fn check_output_dir(dir: &Path) -> Result<(), String> {
    match std::fs::metadata(dir) {
        Ok(meta) if meta.is_dir() => {
            let particles = dir.join(PARTICLES_DIR);
            match std::fs::symlink_metadata(&particles) {
                Ok(m) if m.file_type().is_symlink() => Err(format!(
                    "output `{}` is a symbolic link; the frames must go into a directory of \
                     their own inside `{}`",
                    particles.display(),
                    dir.display()
                )),
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

/// Why the output directory could not be prepared: a path that must not be used (a file, a
/// symbolic link where the frames go: bad input) or a file-system call that failed
/// (permission denied, a read-only or full disk: an I/O error).
#[derive(Debug)]
pub enum OutputDirError {
    Refused(String),
    Io(String),
}

impl std::fmt::Display for OutputDirError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Refused(m) | Self::Io(m) => f.write_str(m),
        }
    }
}

/// Create `dir` and `dir/particles`, and remove the files an earlier run of ours listed in
/// `dir/`[`MANIFEST`] (with their `NAME.tmp`), so the directory holds exactly this run's
/// output and every file of the user's. Call [`check_output_dir`] first.
pub fn create_output_dir(dir: &Path) -> Result<(), OutputDirError> {
    use OutputDirError::{Io, Refused};
    let particles = dir.join(PARTICLES_DIR);
    std::fs::create_dir_all(&particles).map_err(|e| {
        Io(format!(
            "cannot create output directory `{}`: {e}",
            particles.display()
        ))
    })?;
    // Checked again now that it exists: never follow a link out of `dir`.
    check_output_dir(dir).map_err(Refused)?;
    let manifest = dir.join(MANIFEST);
    for name in previous_outputs(&manifest)? {
        let path = dir.join(&name);
        remove_our_file(&dfsph_io::atomic::tmp_path(&path)).map_err(Io)?;
        remove_our_file(&path).map_err(Io)?;
    }
    match std::fs::remove_file(&manifest) {
        Ok(()) => {}
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
        Err(e) => return Err(Io(format!("cannot remove `{}`: {e}", manifest.display()))),
    }
    // Temporary files of a run that was killed (SIGKILL, power loss) while writing them.
    for tmp in [
        dir.join("scene.json.tmp"),
        dir.join("stats.csv.tmp"),
        dir.join("probes.csv.tmp"),
        particles.join("index.csv.tmp"),
        particles.join("particles.pvd.tmp"),
        dfsph_io::atomic::tmp_path(&dir.join(GIF_FILE)),
        dfsph_io::atomic::tmp_path(&dir.join(MP4_FILE)),
    ] {
        remove_our_file(&tmp).map_err(Io)?;
    }
    Ok(())
}

/// The names listed in the manifest at `path` that are names we write (see
/// [`is_our_output`]); anything else in it is ignored. None when there is no manifest.
fn previous_outputs(path: &Path) -> Result<Vec<String>, OutputDirError> {
    use OutputDirError::{Io, Refused};
    let cannot_read = |e: std::io::Error| Io(format!("cannot read `{}`: {e}", path.display()));
    let meta = match std::fs::symlink_metadata(path) {
        Ok(m) => m,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Vec::new()),
        Err(e) => return Err(cannot_read(e)),
    };
    if !meta.is_file() {
        return Err(Refused(format!(
            "`{}` is not a regular file; it is where dfsph2d lists the files it wrote",
            path.display()
        )));
    }
    let file = std::fs::File::open(path).map_err(cannot_read)?;
    let mut names = Vec::new();
    let mut lines = std::io::BufReader::new(file).lines();
    if !matches!(lines.next(), Some(Ok(ref l)) if l == MANIFEST_HEADER) {
        return Ok(names); // Not one of ours: remove nothing.
    }
    for line in lines {
        let line = line.map_err(cannot_read)?;
        if is_our_output(&line) {
            names.push(line);
        }
    }
    Ok(names)
}

/// A name, relative to the output directory, of a file a run writes: only these are ever
/// removed, whatever the manifest says (no `..`, no absolute paths).
fn is_our_output(name: &str) -> bool {
    match name.split_once('/') {
        Some((PARTICLES_DIR, file)) => {
            is_frame_file(file)
                || is_walls_file(file)
                || is_bodies_file(file)
                || matches!(
                    file,
                    "index.csv" | "particles.pvd" | "walls.pvd" | "bodies.pvd"
                )
        }
        Some(_) => false,
        None => matches!(
            name,
            "scene.json" | "stats.csv" | "probes.csv" | BODIES_CSV | GIF_FILE | MP4_FILE
        ),
    }
}

/// Remove `path` if it is a regular file (a symbolic link of that name is left alone, and
/// its target is never touched).
fn remove_our_file(path: &Path) -> Result<(), String> {
    match std::fs::symlink_metadata(path) {
        Ok(m) if m.is_file() => std::fs::remove_file(path)
            .map_err(|e| format!("cannot remove old output `{}`: {e}", path.display())),
        Ok(_) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(()),
        Err(e) => Err(format!("cannot remove `{}`: {e}", path.display())),
    }
}

/// The manifest of the running run: every output file's name is appended (and flushed to the
/// file) before the file is created.
pub struct Manifest {
    path: PathBuf,
    file: std::fs::File,
}

impl Manifest {
    /// Start `dir/`[`MANIFEST`] (removed by [`create_output_dir`]; never follows a link).
    pub fn create(dir: &Path) -> Result<Self> {
        let path = dir.join(MANIFEST);
        let mut file = std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&path)
            .with_context(|| format!("cannot create `{}`", path.display()))?;
        writeln!(file, "{MANIFEST_HEADER}")
            .with_context(|| format!("cannot write `{}`", path.display()))?;
        Ok(Self { path, file })
    }

    /// Record `name` (relative to the output directory) as written by this run.
    pub fn record(&mut self, name: &str) -> Result<()> {
        debug_assert!(is_our_output(name), "{name}");
        // One unbuffered write per name: it is in the file as soon as this returns.
        self.file
            .write_all(format!("{name}\n").as_bytes())
            .with_context(|| format!("cannot write `{}`", self.path.display()))
    }
}

/// `walls_00042.vtu`: the walls as they stood at frame 42.
fn is_walls_file(name: &str) -> bool {
    name.strip_prefix("walls_")
        .is_some_and(|rest| is_frame_file(rest) && rest.ends_with(".vtu"))
}

/// `bodies_00042.vtu`: the rigid bodies at frame 42.
fn is_bodies_file(name: &str) -> bool {
    name.strip_prefix("bodies_")
        .is_some_and(|rest| is_frame_file(rest) && rest.ends_with(".vtu"))
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

/// Writes numbered snapshots in the chosen formats, each followed by its row in `index.csv`
/// (appended, on disk at once) and, for VTK output, a new `particles.pvd` (rewritten
/// atomically), so the index of a run stopped at any point lists exactly its complete frames.
pub struct FrameWriter {
    /// The output directory.
    out: PathBuf,
    /// Its `particles` directory.
    dir: PathBuf,
    /// Formats with a file per snapshot (csv, vtk, png).
    formats: Vec<Format>,
    /// Draw a picture of each frame (png, gif, mp4).
    pictures: bool,
    gif: Option<dfsph_io::video::GifWriter>,
    mp4: Option<dfsph_io::video::Mp4Writer>,
    /// Simulated time between snapshots, s: how long each video frame is shown.
    every: f64,
    /// Digits of the video frames' time stamps.
    decimals: usize,
    frames: Vec<FrameRecord>,
    index: dfsph_io::AppendFile,
    /// Frames listed in the `particles.pvd` on disk.
    pvd_frames: usize,
    /// The walls file of each frame (VTK output): the frame's own `walls_NNNNN.vtu` when the
    /// boundary had changed since the last one written, else that last one.
    wall_files: Vec<String>,
    /// The boundary particles and bodies of the last walls file written.
    last_walls: Option<(Vec<dfsph::Vec2>, Vec<u16>)>,
    /// `bodies.csv`, from the first frame with a rigid body on.
    bodies_csv: Option<dfsph_io::AppendFile>,
    /// The frames with a `bodies_NNNNN.vtu` (VTK output): every one from the first with a
    /// rigid body on, as (time, file).
    body_files: Vec<(f64, String)>,
    png: RenderOptions,
    /// Step of the last frame written.
    last_step: Option<u64>,
}

/// Frames up to which `particles.pvd` is rewritten after every frame; past it, after every
/// 1/[`PVD_GROWTH`] more frames (and at the end), so a run of a million frames does not
/// rewrite a file of a million entries a million times.
const PVD_EVERY_FRAME_UP_TO: usize = 1024;
const PVD_GROWTH: usize = 64;

impl FrameWriter {
    /// Frames go to `out/particles`, videos to `out/video.gif` and `out/video.mp4`;
    /// `formats` is deduplicated and ordered csv, vtk, png. Creates
    /// `out/particles/index.csv` with its header. `every` is the snapshot interval, s.
    pub fn create(
        out: &Path,
        formats: &[Format],
        scene: &Scene,
        picture: RenderOptions,
        every: f64,
        manifest: &mut Manifest,
    ) -> Result<Self> {
        let mut formats = formats.to_vec();
        formats.sort();
        formats.dedup();
        let pictures = formats.iter().any(|f| f.is_picture());
        let gif = if formats.contains(&Format::Gif) {
            manifest.record(GIF_FILE)?;
            Some(dfsph_io::video::GifWriter::new(out.join(GIF_FILE)).for_field(picture.field))
        } else {
            None
        };
        let mp4 = if formats.contains(&Format::Mp4) {
            // Checked before the run started (`main.rs`); here for any other caller.
            let ffmpeg = dfsph_io::video::find_ffmpeg()
                .ok_or_else(|| anyhow::anyhow!(dfsph_io::video::FFMPEG_MISSING))?;
            manifest.record(MP4_FILE)?;
            Some(dfsph_io::video::Mp4Writer::new(
                out.join(MP4_FILE),
                ffmpeg,
                every,
            ))
        } else {
            None
        };
        formats.retain(|f| !f.is_video());
        let dir = out.join(PARTICLES_DIR);
        manifest.record(&format!("{PARTICLES_DIR}/index.csv"))?;
        let mut index = dfsph_io::AppendFile::create(dir.join("index.csv"))?;
        index.append(dfsph_io::INDEX_HEADER)?;
        if formats.contains(&Format::Vtk) {
            manifest.record(&format!("{PARTICLES_DIR}/particles.pvd"))?;
            manifest.record(&format!("{PARTICLES_DIR}/walls.pvd"))?;
        }
        Ok(Self {
            out: out.to_path_buf(),
            dir,
            formats,
            pictures,
            gif,
            mp4,
            every,
            decimals: dfsph_io::video::stamp_decimals(every),
            frames: Vec::new(),
            index,
            pvd_frames: 0,
            wall_files: Vec::new(),
            last_walls: None,
            bodies_csv: None,
            body_files: Vec::new(),
            png: RenderOptions {
                scale_max: dfsph_io::render::field_scale(scene, picture.field),
                ..picture
            },
            last_step: None,
        })
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
    pub fn write(&mut self, sim: &Simulation, manifest: &mut Manifest) -> Result<()> {
        let step = sim.step_count();
        if self.last_step == Some(step) {
            return Ok(());
        }
        let frame = self.frames.len() as u32;
        let stem = format!("{frame:05}");
        let snapshot = sim.snapshot();
        // The bodies once there is one (a replay may drop the first in mid-run), from then on
        // at every frame.
        let bodies = sim.rigid_bodies();
        let with_bodies = !bodies.is_empty() || self.bodies_csv.is_some();
        // One picture for the PNG and the videos' frame.
        let mut picture = if self.pictures {
            Some(dfsph_io::render_frame(
                &RenderGeometry::of(sim),
                &snapshot,
                &self.png,
            )?)
        } else {
            None
        };
        for format in self.formats.clone() {
            let name = format!("{stem}.{}", format.extension());
            manifest.record(&format!("{PARTICLES_DIR}/{name}"))?;
            let path = self.dir.join(name);
            match format {
                Format::Csv => dfsph_io::write_snapshot_csv(&path, &snapshot)?,
                Format::Vtk => {
                    dfsph_io::write_vtu(&path, &snapshot)?;
                    self.write_walls(sim, &stem, manifest)?;
                    if with_bodies {
                        if self.body_files.is_empty() {
                            manifest.record(&format!("{PARTICLES_DIR}/bodies.pvd"))?;
                        }
                        let name = format!("bodies_{stem}.vtu");
                        manifest.record(&format!("{PARTICLES_DIR}/{name}"))?;
                        dfsph_io::write_bodies_vtu(self.dir.join(&name), &bodies)?;
                        self.body_files.push((snapshot.time, name));
                    }
                }
                Format::Png => {
                    let pixmap = picture.as_ref().expect("drawn for png");
                    dfsph_io::render::write_pixmap_png(&path, pixmap)?
                }
                Format::Gif | Format::Mp4 => unreachable!("videos are not per-frame files"),
            }
        }
        if let Some(pixmap) = picture.as_mut() {
            if self.gif.is_some() || self.mp4.is_some() {
                dfsph_io::render::stamp_time(pixmap, snapshot.time, self.decimals);
            }
            if let Some(gif) = self.gif.as_mut() {
                gif.push(pixmap, self.every)?;
            }
            if let Some(mp4) = self.mp4.as_mut() {
                mp4.push(pixmap, self.every)?;
            }
        }
        // Without a file per snapshot (videos only) the row names none: the frame is the
        // video's frame of the same number.
        let file = match self.formats.first() {
            Some(first) => format!("{stem}.{}", first.extension()),
            None => String::new(),
        };
        if with_bodies {
            if self.bodies_csv.is_none() {
                manifest.record(BODIES_CSV)?;
                let mut csv = dfsph_io::AppendFile::create(self.out.join(BODIES_CSV))?;
                csv.append(dfsph_io::BODIES_HEADER)?;
                self.bodies_csv = Some(csv);
            }
            let csv = self.bodies_csv.as_mut().expect("created above");
            // A frame's rows in one write; none when every body is gone (a reset).
            if !bodies.is_empty() {
                csv.append(&dfsph_io::bodies_csv_rows(frame, snapshot.time, &bodies))?;
            }
        }
        let record = FrameRecord {
            frame,
            time: snapshot.time,
            file,
        };
        // Listed only once every file of the frame is complete.
        self.index.append(&dfsph_io::frame_index_row(&record))?;
        self.frames.push(record);
        self.last_step = Some(step);
        let n = self.frames.len();
        if n <= PVD_EVERY_FRAME_UP_TO || n - self.pvd_frames >= n / PVD_GROWTH {
            self.write_pvd()?;
        }
        Ok(())
    }

    /// The walls of the frame `stem`: a new `walls_STEM.vtu` when the boundary particles
    /// moved (a shaken tank) or changed (a wall drawn or erased) since the last one written,
    /// else the last one again.
    fn write_walls(&mut self, sim: &Simulation, stem: &str, manifest: &mut Manifest) -> Result<()> {
        let (positions, bodies) = (sim.boundary_positions(), sim.boundary_bodies());
        let unchanged = self
            .last_walls
            .as_ref()
            .is_some_and(|(p, b)| p.as_slice() == positions && b.as_slice() == bodies);
        if !unchanged {
            let name = format!("walls_{stem}.vtu");
            manifest.record(&format!("{PARTICLES_DIR}/{name}"))?;
            dfsph_io::write_walls_vtu(
                self.dir.join(&name),
                positions,
                bodies,
                sim.boundary_volumes(),
            )?;
            self.last_walls = Some((positions.to_vec(), bodies.to_vec()));
            self.wall_files.push(name);
        } else {
            let last = self.wall_files.last().cloned().unwrap_or_default();
            self.wall_files.push(last);
        }
        Ok(())
    }

    /// Rewrite `particles.pvd` and `walls.pvd` (VTK output only) with every frame so far.
    fn write_pvd(&mut self) -> Result<()> {
        if !self.formats.contains(&Format::Vtk) || self.pvd_frames == self.frames.len() {
            return Ok(());
        }
        let series: Vec<(f64, String)> = self
            .frames
            .iter()
            .map(|f| (f.time, format!("{:05}.vtu", f.frame)))
            .collect();
        dfsph_io::write_pvd(self.dir.join("particles.pvd"), &series)?;
        let walls: Vec<(f64, String)> = self
            .frames
            .iter()
            .zip(&self.wall_files)
            .map(|(f, file)| (f.time, file.clone()))
            .collect();
        dfsph_io::write_pvd(self.dir.join("walls.pvd"), &walls)?;
        if !self.body_files.is_empty() {
            dfsph_io::write_pvd(self.dir.join("bodies.pvd"), &self.body_files)?;
        }
        self.pvd_frames = self.frames.len();
        Ok(())
    }

    /// Bring `particles.pvd` up to date, make `index.csv` durable and complete the videos.
    pub fn finish(mut self) -> Result<()> {
        self.write_pvd()?;
        if let Some(csv) = self.bodies_csv.take() {
            csv.finish()?;
        }
        self.index.finish()?;
        if let Some(gif) = self.gif.take() {
            gif.finish()?;
        }
        if let Some(mp4) = self.mp4.take() {
            mp4.finish()?;
        }
        Ok(())
    }
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
    fn walls_files_follow_the_walls() {
        assert!(is_walls_file("walls_00003.vtu") && is_our_output("particles/walls_00003.vtu"));
        assert!(!is_walls_file("walls_00003.csv") && !is_walls_file("walls_x.vtu"));

        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir_all(dir.path().join(PARTICLES_DIR)).unwrap();
        let mut manifest = Manifest::create(dir.path()).unwrap();
        let mut scene = dfsph::scene::builtin("dam-break").unwrap();
        scene.particle_radius = 0.05;
        let mut sim = Simulation::new(&scene).unwrap();
        let mut frames = FrameWriter::create(
            dir.path(),
            &[Format::Vtk],
            &scene,
            RenderOptions {
                width: 320,
                ..Default::default()
            },
            0.05,
            &mut manifest,
        )
        .unwrap();
        frames.write(&sim, &mut manifest).unwrap();
        sim.step();
        frames.write(&sim, &mut manifest).unwrap(); // walls unchanged: no new file
        let wall = dfsph::Action::AddWall {
            polyline: vec![dfsph::Vec2::new(2.0, 0.5), dfsph::Vec2::new(3.0, 0.5)],
        };
        assert!(sim.apply(&wall).boundary_change > 0);
        sim.step();
        frames.write(&sim, &mut manifest).unwrap(); // a drawn wall: a new file
        sim.apply(&dfsph::Action::ShakeTank { direction: 1.0 });
        sim.step();
        frames.write(&sim, &mut manifest).unwrap(); // the tank moved: a new file
        let boundary = sim.boundary_positions().len();
        frames.finish().unwrap();

        let pvd = std::fs::read_to_string(dir.path().join("particles/walls.pvd")).unwrap();
        let files: Vec<&str> = pvd
            .lines()
            .filter_map(|l| l.split("file=\"").nth(1)?.split('"').next())
            .collect();
        assert_eq!(
            files,
            [
                "walls_00000.vtu",
                "walls_00000.vtu",
                "walls_00002.vtu",
                "walls_00003.vtu"
            ]
        );
        assert!(!dir.path().join("particles/walls_00001.vtu").exists());
        let last = std::fs::read_to_string(dir.path().join("particles/walls_00003.vtu")).unwrap();
        assert!(
            last.contains(&format!("NumberOfPoints=\"{boundary}\"")),
            "{boundary}"
        );
    }

    #[test]
    fn bodies_files_start_with_the_first_body() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir_all(dir.path().join(PARTICLES_DIR)).unwrap();
        let mut manifest = Manifest::create(dir.path()).unwrap();
        let mut scene = dfsph::scene::builtin("dam-break").unwrap();
        scene.particle_radius = 0.05;
        let mut sim = Simulation::new(&scene).unwrap();
        let mut frames = FrameWriter::create(
            dir.path(),
            &[Format::Vtk],
            &scene,
            RenderOptions {
                width: 320,
                ..Default::default()
            },
            0.05,
            &mut manifest,
        )
        .unwrap();
        frames.write(&sim, &mut manifest).unwrap();
        sim.step();
        frames.write(&sim, &mut manifest).unwrap();
        // No body yet: no bodies files.
        assert!(!dir.path().join(BODIES_CSV).exists());
        assert!(!dir.path().join("particles/bodies_00001.vtu").exists());
        // A body dropped in (as a replayed recording does): from this frame on.
        let body = dfsph::rigid::BodySpec::new_box([0.4, 0.4], 500.0, [2.5, 1.5]);
        assert_eq!(sim.apply(&dfsph::Action::AddBody { body }).rejected, None);
        sim.step();
        frames.write(&sim, &mut manifest).unwrap();
        sim.step();
        frames.write(&sim, &mut manifest).unwrap();
        frames.finish().unwrap();

        let csv = std::fs::read_to_string(dir.path().join(BODIES_CSV)).unwrap();
        let frames: Vec<&str> = csv.lines().map(|l| l.split(',').next().unwrap()).collect();
        assert_eq!(frames, ["frame", "2", "3"], "{csv}");
        let pvd = std::fs::read_to_string(dir.path().join("particles/bodies.pvd")).unwrap();
        let files: Vec<&str> = pvd
            .lines()
            .filter_map(|l| l.split("file=\"").nth(1)?.split('"').next())
            .collect();
        assert_eq!(files, ["bodies_00002.vtu", "bodies_00003.vtu"]);
        assert!(!dir.path().join("particles/bodies_00001.vtu").exists());
        let listed = std::fs::read_to_string(dir.path().join(MANIFEST)).unwrap();
        for name in [
            BODIES_CSV,
            "particles/bodies.pvd",
            "particles/bodies_00002.vtu",
            "particles/bodies_00003.vtu",
        ] {
            assert!(listed.lines().any(|l| l == name), "{name}: {listed}");
            assert!(is_our_output(name), "{name}");
        }
        assert!(!is_bodies_file("bodies_00003.csv") && !is_our_output("particles/bodies.csv"));
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
    fn only_files_in_our_manifest_are_removed() {
        let dir = tempfile::tempdir().unwrap();
        let particles = dir.path().join(PARTICLES_DIR);
        std::fs::create_dir_all(&particles).unwrap();
        for name in [
            "00007.csv",
            "00008.csv",
            "00008.vtu.tmp",
            "00009.vtu.tmp",
            "notes.txt",
        ] {
            std::fs::write(particles.join(name), "x").unwrap();
        }
        std::fs::write(dir.path().join("stats.csv.tmp"), "partial").unwrap();
        std::fs::write(dir.path().join("mine.csv"), "mine").unwrap();
        let listed = "particles/00008.csv\nparticles/00008.vtu\n../mine.csv\n/etc/passwd\n\
                      particles/../mine.csv\nparticles/notes.txt\n";
        let manifest = dir.path().join(MANIFEST);
        // Without our header, the list is not ours: nothing is removed.
        std::fs::write(&manifest, listed).unwrap();
        create_output_dir(dir.path()).unwrap();
        assert!(particles.join("00008.csv").exists());
        std::fs::write(&manifest, format!("{MANIFEST_HEADER}\n{listed}")).unwrap();
        create_output_dir(dir.path()).unwrap();
        assert!(!particles.join("00008.csv").exists());
        assert!(!particles.join("00008.vtu.tmp").exists());
        assert!(!dir.path().join("stats.csv.tmp").exists());
        assert!(!manifest.exists());
        for kept in ["00007.csv", "00009.vtu.tmp", "notes.txt", "../mine.csv"] {
            assert!(particles.join(kept).exists(), "{kept} removed");
        }
        // A new manifest is never written through a link.
        let mut m = Manifest::create(dir.path()).unwrap();
        m.record("particles/00000.csv").unwrap();
        assert_eq!(
            std::fs::read_to_string(&manifest).unwrap(),
            format!("{MANIFEST_HEADER}\nparticles/00000.csv\n")
        );
    }

    #[cfg(unix)]
    #[test]
    fn a_particles_link_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let elsewhere = tempfile::tempdir().unwrap();
        let out = dir.path().join("out");
        std::fs::create_dir(&out).unwrap();
        std::os::unix::fs::symlink(elsewhere.path(), out.join(PARTICLES_DIR)).unwrap();
        let err = check_output_dir(&out).unwrap_err();
        assert!(err.contains("is a symbolic link"), "{err}");
        assert!(create_output_dir(&out).is_err());
    }
}
