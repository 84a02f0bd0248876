//! Scene files in the viewer: the running state saved as a scene that `dfsph2d run` and
//! `dfsph2d view` accept ([`saved_scene`], [`save_timestamped`]), scene files opened from the
//! window (a file dialog, or a `.json` dropped on it: [`SceneOpener`]), and the particle
//! radius slider's range ([`radius_range`]), which must hold the scene's own radius: a scene
//! runs exactly as written.

use std::path::{Path, PathBuf};

use anyhow::{anyhow, Context as _};
use dfsph::{Scene, Simulation};
use eframe::egui;
#[cfg(not(target_arch = "wasm32"))]
use egui_file_dialog::{DialogState, FileDialog};

/// What the scene list calls a scene read from the file `name` (a path as given): the file's
/// own name, without its directory.
pub fn file_label(name: &str) -> String {
    std::path::Path::new(name)
        .file_name()
        .map_or_else(|| name.to_string(), |f| f.to_string_lossy().into_owned())
}

/// The particle radius slider's range, m: what the scene validator accepts for this tank
/// ([`Scene::particle_radius_limits`]), raised to where the fluid blocks would hold about
/// `max_particles` and lowered to where the narrowest block is one spacing wide (both
/// validator rules too), and always including the scene's own radius. `None` for a scene that
/// lists its particles: they are one resolution and cannot be resampled at another.
pub fn radius_range(scene: &Scene, max_particles: usize) -> Option<(f64, f64)> {
    if !scene.particles.is_empty() {
        return None;
    }
    let (lo, hi) = scene.particle_radius_limits();
    // A block of area A holds about A/d² = A/(4r²) particles.
    let area: f64 = scene
        .fluid
        .iter()
        .map(|b| (b.max[0] - b.min[0]) * (b.max[1] - b.min[1]))
        .sum();
    let lo = lo.max(0.5 * (area / max_particles.max(1) as f64).sqrt());
    let narrowest = scene
        .fluid
        .iter()
        .map(|b| (b.max[0] - b.min[0]).min(b.max[1] - b.min[1]))
        .fold(f64::INFINITY, f64::min);
    // A rigid body must measure `MIN_BODY_SPACINGS` spacings (of 2r) across.
    let thinnest = scene
        .bodies
        .iter()
        .map(|b| b.thickness())
        .fold(f64::INFINITY, f64::min);
    let hi = hi
        .min(0.5 * narrowest)
        .min(thinnest / (2.0 * dfsph::rigid::spec::MIN_BODY_SPACINGS));
    let r = scene.particle_radius;
    Some((lo.min(r), hi.max(r)))
}

/// The simulation as it stands, as a scene file's contents ([`dfsph::world::World::to_scene`]), with
/// the `max_particles` the scene was loaded with (the viewer runs with a smaller pour budget),
/// and checked by the scene validator, so that what is written loads again.
pub fn saved_scene(sim: &Simulation, max_particles: usize) -> anyhow::Result<Scene> {
    let mut scene = sim.to_scene();
    scene.max_particles = max_particles.max(scene.fluid_particle_count());
    scene.description = format!(
        "`{}` saved by the viewer at t = {:.3} s ({} particles)",
        sim.scene().name,
        sim.time(),
        sim.fluid_count()
    );
    scene
        .validate()
        .map_err(|e| anyhow!("the state cannot be saved as a scene: {e}"))?;
    Ok(scene)
}

/// Write `scene` to `path` whole or not at all: a reader never sees half a file.
pub fn write_scene(path: &Path, scene: &Scene) -> anyhow::Result<()> {
    dfsph_io::atomic::write_atomic(path, |w| {
        w.write_all(scene.to_json_compact_points().as_bytes())?;
        Ok(())
    })
    .with_context(|| format!("writing {}", path.display()))
}

/// Save `scene` as `scene-YYYYMMDD-HHMMSS.json` (UTC) in `dir`, with `-2`, `-3`, ... when
/// that name is taken; never overwrites a file. Returns the path written.
pub fn save_timestamped(dir: &Path, scene: &Scene) -> anyhow::Result<PathBuf> {
    let stem = format!("scene-{}", crate::file_names::utc_stamp_now());
    for k in 1..10_000 {
        let path = match k {
            1 => dir.join(format!("{stem}.json")),
            _ => dir.join(format!("{stem}-{k}.json")),
        };
        // Claim the name first (`create_new` fails if it exists, also against another
        // process saving at the same moment), then fill it atomically.
        match std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&path)
        {
            Ok(_) => {
                if let Err(e) = write_scene(&path, scene) {
                    let _ = std::fs::remove_file(&path);
                    return Err(e);
                }
                return Ok(path);
            }
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => continue,
            Err(e) => return Err(anyhow!("cannot create {}: {e}", path.display())),
        }
    }
    Err(anyhow!(
        "no free file name {stem}-N.json in {}",
        dir.display()
    ))
}

/// Read and validate a scene file; the error names the file and, for a bad scene, the key
/// (the scene validator's message).
pub fn read_scene(path: &Path) -> anyhow::Result<Scene> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    Scene::from_json(&text).map_err(|e| anyhow!("{}: {e}", path.display()))
}

/// A scene file the user opened (picked or dropped): its name, and the scene or why it was
/// refused (naming the file and the key).
pub struct Opened {
    pub name: String,
    pub scene: anyhow::Result<Scene>,
}

impl Opened {
    /// A scene file read from disk.
    pub fn from_path(path: &Path) -> Self {
        Self {
            name: path.display().to_string(),
            scene: read_scene(path),
        }
    }

    /// A scene file's contents (the browser hands over bytes, not paths).
    pub fn from_bytes(name: &str, bytes: &[u8]) -> Self {
        let scene = std::str::from_utf8(bytes)
            .map_err(|_| anyhow!("{name}: not a text file"))
            .and_then(|text| Scene::from_json(text).map_err(|e| anyhow!("{name}: {e}")));
        Self {
            name: name.to_string(),
            scene,
        }
    }
}

/// The files dropped on the window this frame (drag and drop), by path.
#[cfg(not(target_arch = "wasm32"))]
pub fn dropped_scenes(input: &egui::InputState) -> Vec<Opened> {
    input
        .raw
        .dropped_files
        .iter()
        .map(|f| Opened::from_path(f.path()))
        .collect()
}

/// The files dropped on the page (drag and drop), by contents: the browser reads them
/// asynchronously, so a file dropped in one frame is opened in a later one.
#[cfg(target_arch = "wasm32")]
pub fn dropped_scenes(input: &egui::InputState) -> Vec<Opened> {
    thread_local! {
        static READ: std::cell::RefCell<Vec<(String, Vec<u8>)>> = Default::default();
    }
    for file in &input.raw.dropped_files {
        let (file, name) = (file.clone(), file.path().display().to_string());
        wasm_bindgen_futures::spawn_local(async move {
            if let Ok(bytes) = file.bytes_async().await {
                READ.with(|read| read.borrow_mut().push((name, bytes)));
            }
        });
    }
    READ.with(|read| {
        read.borrow_mut()
            .drain(..)
            .map(|(name, bytes)| Opened::from_bytes(&name, &bytes))
            .collect()
    })
}

/// Save the state `scene` where the user finds it: `scene-<time>.json` in the current
/// directory ([`save_timestamped`]), or a download of that name in the browser. Returns what
/// to tell the user.
pub fn save_state(scene: &Scene) -> anyhow::Result<String> {
    #[cfg(not(target_arch = "wasm32"))]
    {
        let dir = std::env::current_dir().unwrap_or_else(|_| PathBuf::from("."));
        save_timestamped(&dir, scene).map(|path| format!("saved {}", path.display()))
    }
    #[cfg(target_arch = "wasm32")]
    {
        let name = format!("scene-{}.json", crate::file_names::utc_stamp_now());
        crate::web::download(
            &name,
            "application/json",
            scene.to_json_compact_points().as_bytes(),
        )
        .map_err(|e| anyhow!("the browser refused the download: {e}"))?;
        Ok(format!("downloaded {name}"))
    }
}

/// The "Open scene…" dialog: on the desktop egui's own widgets (no desktop portal or GTK
/// needed), showing directories and `.json` files; in the browser, the browser's file
/// picker.
pub struct SceneOpener {
    #[cfg(not(target_arch = "wasm32"))]
    dialog: FileDialog,
    #[cfg(target_arch = "wasm32")]
    picker: crate::web::FilePicker,
}

impl Default for SceneOpener {
    #[cfg(not(target_arch = "wasm32"))]
    fn default() -> Self {
        let dialog = FileDialog::new()
            .title("Open scene")
            .add_file_filter_extensions("scene files (.json)", vec!["json", "JSON"])
            .default_file_filter("scene files (.json)")
            .initial_directory(std::env::current_dir().unwrap_or_else(|_| PathBuf::from(".")));
        Self { dialog }
    }

    #[cfg(target_arch = "wasm32")]
    fn default() -> Self {
        Self {
            picker: Default::default(),
        }
    }
}

#[cfg(not(target_arch = "wasm32"))]
impl SceneOpener {
    /// Show the dialog, in the directory the viewer was started in.
    pub fn open(&mut self) -> anyhow::Result<()> {
        self.dialog.pick_file();
        Ok(())
    }

    /// Whether the dialog is showing.
    pub fn is_open(&self) -> bool {
        *self.dialog.state() == DialogState::Open
    }

    /// Draw the dialog if it is open; the file the user picked, once.
    pub fn update(&mut self, ctx: &egui::Context) -> Option<Opened> {
        self.dialog.update(ctx);
        self.dialog.take_picked().map(|p| Opened::from_path(&p))
    }
}

#[cfg(target_arch = "wasm32")]
impl SceneOpener {
    /// Show the browser's file picker.
    pub fn open(&mut self) -> anyhow::Result<()> {
        self.picker
            .open()
            .map_err(|e| anyhow!("the browser's file picker did not open: {e}"))
    }

    /// The picker is the browser's, drawn over the page, not a part of it.
    pub fn is_open(&self) -> bool {
        false
    }

    /// The file picked since the last frame, if one was.
    pub fn update(&mut self, _ctx: &egui::Context) -> Option<Opened> {
        self.picker.take().pop().map(|(name, text)| match text {
            Ok(text) => Opened::from_bytes(&name, text.as_bytes()),
            Err(e) => Opened {
                scene: Err(anyhow!("{name}: cannot read: {e}")),
                name,
            },
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn coarse() -> Scene {
        let mut s = dfsph::scene::builtin("dam-break").unwrap();
        s.particle_radius = 0.05;
        s
    }

    #[test]
    fn the_radius_range_holds_the_scenes_radius_and_stays_within_the_validator() {
        let mut s = coarse();
        for r in [0.0025, 0.004, 0.06, 0.5] {
            s.particle_radius = r;
            let (lo, hi) = radius_range(&s, 1_000_000).unwrap();
            assert!(lo <= r && r <= hi, "{r} in {lo}..{hi}");
        }
        // The dam break's 2 m² of water reaches a million particles at r ≈ 0.7 mm; its 1 m
        // wide column is one spacing wide at r = 0.5 m (the tank would allow 0.75 m).
        let (lo, hi) = radius_range(&coarse(), 1_000_000).unwrap();
        assert!((lo - 0.000707).abs() < 1e-5 && hi == 0.5, "{lo} {hi}");
        for r in [lo * 1.01, hi] {
            let mut s = coarse();
            s.particle_radius = r;
            s.validate().unwrap_or_else(|e| panic!("r = {r}: {e}"));
        }
        let saved = Simulation::new(&coarse()).unwrap().to_scene();
        assert_eq!(radius_range(&saved, 1_000_000), None);
        // The floating scene's thinnest body (0.3 m) holds three spacings up to r = 0.05 m.
        let floating = dfsph::scene::builtin("floating").unwrap();
        let thinnest = floating
            .bodies
            .iter()
            .map(|b| b.thickness())
            .fold(f64::INFINITY, f64::min);
        let (_, hi) = radius_range(&floating, 1_000_000).unwrap();
        assert!((hi - thinnest / 6.0).abs() < 1e-12, "{hi} {thinnest}");
        let mut s = floating;
        s.particle_radius = hi;
        s.validate().unwrap();
        s.particle_radius = hi * 1.01;
        assert!(s.validate().is_err());
    }

    #[test]
    fn a_saved_scene_is_written_once_per_name_and_reads_back() {
        let dir = std::env::temp_dir().join(format!("dfsph-viewer-scene-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let mut sim = Simulation::new(&coarse()).unwrap();
        for _ in 0..10 {
            sim.step();
        }
        let scene = saved_scene(&sim, 1_000_000).unwrap();
        assert_eq!(scene.max_particles, 1_000_000);
        let a = save_timestamped(&dir, &scene).unwrap();
        let b = save_timestamped(&dir, &scene).unwrap();
        assert_ne!(a, b);
        let name = a.file_name().unwrap().to_str().unwrap().to_string();
        assert!(
            name.starts_with("scene-") && name.ends_with(".json"),
            "{name}"
        );
        let back = read_scene(&b).unwrap();
        assert_eq!(back, scene);
        assert_eq!(
            Simulation::new(&back).unwrap().fluid_count(),
            sim.fluid_count()
        );

        // A bad file: the error names the file and the key.
        let bad = dir.join("bad.json");
        std::fs::write(&bad, r#"{"particles": {"positions": [[0.5, 9]]}}"#).unwrap();
        let e = format!("{:#}", read_scene(&bad).unwrap_err());
        assert!(
            e.contains("bad.json") && e.contains("`particles.positions[0][1]`"),
            "{e}"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_state_with_no_water_left_is_not_saved() {
        let mut sim = Simulation::new(&coarse()).unwrap();
        sim.apply(&dfsph::Action::Erase {
            at: dfsph::Vec2::new(0.5, 1.0),
            radius: 5.0,
        });
        assert_eq!(sim.fluid_count(), 0);
        let e = saved_scene(&sim, 1000).unwrap_err().to_string();
        assert!(e.contains("`fluid`"), "{e}");
    }

    /// A file dropped on the desktop window, as egui-winit hands it over.
    #[derive(Debug)]
    struct Dropped(PathBuf);

    impl egui::DroppedFile for Dropped {
        fn path(&self) -> &Path {
            &self.0
        }

        fn bytes(&self) -> Result<Vec<u8>, String> {
            std::fs::read(&self.0).map_err(|e| e.to_string())
        }
    }

    #[test]
    fn dropped_files_are_read_by_path() {
        let dir = tempfile::tempdir().unwrap();
        let (good, bad) = (dir.path().join("a.json"), dir.path().join("c.json"));
        write_scene(&good, &coarse()).unwrap();
        // A file that is not a scene.
        std::fs::write(&bad, br#"{"particle_radius": "big"}"#).unwrap();
        let ctx = egui::Context::default();
        let raw = egui::RawInput {
            dropped_files: vec![
                std::sync::Arc::new(Dropped(good.clone())),
                std::sync::Arc::new(Dropped(bad.clone())),
            ],
            ..Default::default()
        };
        let mut got = Vec::new();
        let _ = ctx.run_ui(raw, |ui| got = ui.ctx().input(dropped_scenes));
        assert_eq!(got.len(), 2);
        assert_eq!(got[0].name, good.display().to_string());
        assert_eq!(got[0].scene.as_ref().unwrap(), &coarse());
        let e = format!("{:#}", got[1].scene.as_ref().unwrap_err());
        assert!(e.contains("c.json") && e.contains("particle_radius"), "{e}");
    }
}
