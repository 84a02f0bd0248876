//! The eframe application: owns the simulation, turns input into actions between steps,
//! paces the stepping, draws, and handles screenshots and `--exit-after`.

use std::cell::RefCell;
use std::collections::VecDeque;
use std::io::Write as _;
use std::path::PathBuf;
use std::rc::Rc;
use web_time::{Duration, Instant};

use anyhow::{anyhow, Context as _};
use dfsph::recording::{End, Header, Recorder};
use dfsph::scene::BUILTIN_SCENES;
use dfsph::{Action, Scene, Simulation, StepStats};
use dfsph_io::render::WaterLook;
use eframe::egui::{self, vec2, Color32, Sense, Stroke, ViewportCommand};

use crate::bodies;
use crate::export;
use crate::hud::{self, FrameStats, History, HudInfo, Rate};
use crate::input::{Command, InputMapper, Tool, ViewInput};
use crate::panel::{self, PanelState};
use crate::render::{self, ColorScale, Coloring, ViewTransform};
use crate::resolution;
use crate::scene_file::{self, SceneOpener};
use crate::stepper::Stepper;
use crate::undo::{self, UndoHistory};
use crate::video::VideoRecorder;
use crate::view::{self, Camera, Layout};
use crate::ViewerOptions;

/// How long `--exit-after` waits for the screenshot before giving up.
const SCREENSHOT_TIMEOUT: Duration = Duration::from_secs(10);
/// How long a status message stays in the panel.
const STATUS_DURATION: Duration = Duration::from_secs(6);
/// How often the probes' readings on the view are refreshed: ten times a second, so the
/// numbers can be read (every frame they would flicker) and cost little.
const PROBE_INTERVAL: Duration = Duration::from_millis(100);
/// The HUD's size before it has been drawn once, points.
const HUD_SIZE_GUESS: egui::Vec2 = vec2(300.0, 170.0);

/// Errors the app hit that `run` must report after the window closes.
pub type Failures = Rc<RefCell<Vec<anyhow::Error>>>;

/// A requested screenshot, answered by the next `Event::Screenshot`.
// The page draws its screenshots itself (no `Event::Screenshot` on the web): only `Exit` there.
#[cfg_attr(target_arch = "wasm32", allow(dead_code))]
enum ShotPurpose {
    /// F12: save to this file.
    File(PathBuf),
    /// `--save-on-exit`: save, then close the window.
    Exit,
}

/// Measuring the pace to fit the scene to this machine ([`crate::resolution`]).
#[derive(Clone, Copy, Debug)]
struct FitMeasure {
    /// When this measurement started: its first [`resolution::SETTLE_SECONDS`] are not
    /// counted.
    since: Instant,
    /// Simulated seconds, wall seconds spent stepping them, and wall seconds counted since.
    simulated: f64,
    busy: f64,
    wall: f64,
    /// Fits made so far.
    fits: u32,
    /// The radius and pace measured before the last fit, for the exponent of the next.
    before: Option<(f64, f64)>,
}

impl FitMeasure {
    fn start(now: Instant, fits: u32, before: Option<(f64, f64)>) -> Self {
        Self {
            since: now,
            simulated: 0.0,
            busy: 0.0,
            wall: 0.0,
            fits,
            before,
        }
    }
}

/// `--exit-after` / `--save-on-exit` progress.
struct ExitPlan {
    at: Instant,
    dir: Option<PathBuf>,
    /// When the exit began (files written, screenshot requested).
    started: Option<Instant>,
}

/// One applied action, for the session record.
struct LoggedAction {
    time: f64,
    action: Action,
}

/// `view --record FILE`: the session's actions, each with the number of steps taken before
/// it, written as they happen (see [`dfsph::recording`]).
///
/// Created before the window opens (a path that cannot be written is refused then); the
/// header, which names the threads the solver steps on, is written once the window has
/// chosen them ([`ViewerApp::with_recorder`]).
pub struct SessionRecorder {
    path: PathBuf,
    file: std::io::BufWriter<std::fs::File>,
    /// The scene with the viewer's pour budget, as the simulation will run it.
    scene: Scene,
}

impl SessionRecorder {
    /// Create `path` for a session on `scene`.
    pub fn create(path: &std::path::Path, scene: &Scene) -> anyhow::Result<Self> {
        let file = std::fs::File::create(path)
            .with_context(|| format!("cannot create recording `{}`", path.display()))?;
        Ok(Self {
            path: path.to_path_buf(),
            file: std::io::BufWriter::new(file),
            scene: budgeted_scene(scene.clone(), scene.max_particles),
        })
    }

    /// Write the header, for a solver stepping on `threads` threads of `backend`
    /// ([`Simulation::backend_description`]).
    fn start(self, threads: usize, backend: &str) -> anyhow::Result<ActiveRecorder> {
        let header = Header::new("view", threads, &self.scene).on_backend(backend);
        let recorder = Recorder::new(self.file, &header)
            .with_context(|| format!("cannot write recording `{}`", self.path.display()))?;
        Ok(ActiveRecorder {
            path: self.path,
            recorder,
        })
    }
}

/// A recording under way.
struct ActiveRecorder {
    path: PathBuf,
    recorder: Recorder<std::io::BufWriter<std::fs::File>>,
}

/// What a frame showed, for an embedding page's hook (`window.dfsph2d.state()`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FrameReport {
    /// The built-in or loaded scene's name.
    pub scene: String,
    /// Fluid particles.
    pub particles: usize,
    /// Simulated time, s.
    pub time: f64,
    /// Mean x of the fluid particles, m.
    pub mean_x: f64,
    /// Steps taken since the scene was loaded.
    pub steps: u64,
    /// Simulated seconds per wall second (0 while paused).
    pub realtime: f64,
    /// Frames drawn per second.
    pub fps: f64,
    /// What fitting the scene to this machine did (the HUD's line), if it did
    /// ([`crate::resolution`]).
    pub fitted: Option<String>,
}

/// A frame observer ([`ViewerApp::on_frame`]).
type FrameObserver = Box<dyn FnMut(&FrameReport)>;

/// The viewer.
pub struct ViewerApp {
    /// The simulation: home while a frame reads it, stepping on its own thread in between.
    sim: Stepper,
    /// `max_particles` of the scene as loaded; the pour budget is derived from it.
    requested_max_particles: usize,
    /// Makes the backend of every simulation the window loads ([`ViewerOptions::backend`]).
    backend: Option<dfsph::simulation::BackendFactory>,
    /// The scene as loaded (from the command line, the scene list or a file): what `R`
    /// goes back to, whatever was changed since.
    loaded: Scene,
    /// The file the scene was opened from (its name, without the directory), or `None` for a
    /// built-in scene or the command line's: the scene list names the file then, not the
    /// built-in scene the file may have started as.
    opened_file: Option<String>,
    /// The "Open scene…" dialog.
    opener: SceneOpener,
    mapper: InputMapper,
    paused: bool,
    coloring: Coloring,
    /// The water as a surface (the default) or as dots (`P`).
    look: WaterLook,
    /// The surface's raster and texture.
    surface: render::SurfaceLayer,
    /// The walls drawn and the water poured, for undo.
    undo: UndoHistory,
    /// The colour scale of each colouring, in [`Coloring::ALL`] order.
    scales: [ColorScale; 3],
    /// The shown field's values (one per fluid particle) and scratch room for percentiles.
    values: Vec<f32>,
    scratch: Vec<f32>,
    /// The user's zoom and pan.
    camera: Camera,
    /// The room kept for the HUD beside the tank: the largest size it has had in a view of
    /// this size (so the tank does not jump when a line such as PAUSED comes and goes), and
    /// that view size.
    hud_room: (egui::Vec2, egui::Vec2),
    /// The probes' last readings and when they were taken.
    probe_readings: Vec<f64>,
    probes_read: Option<Instant>,
    /// Where the HUD was drawn last frame (its size is known only once drawn).
    last_hud_rect: Option<egui::Rect>,
    time_scale: f64,
    radius_edit: f64,
    /// Fitting the particle size to this machine, while it measures (`None` once done, or
    /// for a scene the user chose).
    fit: Option<FitMeasure>,
    /// What the fit chose, for the HUD ("1,922 particles, fitted to this machine ...").
    resolution_note: Option<String>,
    show_help: bool,
    history: History,
    fps: Rate,
    steps_per_second: Rate,
    /// Simulated seconds per wall second.
    sim_rate: Rate,
    last_frame: Option<Instant>,
    started: Instant,
    frames: u64,
    status: Option<(String, Instant)>,
    disc: egui::TextureHandle,
    fluid_colors: Vec<Color32>,
    shots: VecDeque<ShotPurpose>,
    exit: Option<ExitPlan>,
    failures: Failures,
    log: Vec<LoggedAction>,
    /// Steps taken since the window opened, resets included (the recording's clock).
    session_steps: u64,
    recorder: Option<ActiveRecorder>,
    /// The Record button's video.
    video: VideoRecorder,
    /// Told what each frame showed ([`Self::on_frame`]).
    observer: Option<FrameObserver>,
    /// The held body and the grabbed point in its frame, m (for the line to the pointer).
    grab_anchor: Option<(usize, dfsph::Vec2)>,
}

impl ViewerApp {
    /// Build the app for a scene; fails when the scene is invalid.
    pub fn new(
        cc: &eframe::CreationContext<'_>,
        opts: ViewerOptions,
        failures: Failures,
    ) -> anyhow::Result<Self> {
        // Under a software rasteriser the drawing takes cores the solver would otherwise use
        // (`crate::threads`).
        #[cfg(not(target_arch = "wasm32"))]
        let threads = {
            use eframe::glow::HasContext;
            let software = cc.gl.as_ref().is_some_and(|gl| {
                // SAFETY: a string query on the context eframe just made current.
                let renderer = unsafe { gl.get_parameter_string(eframe::glow::RENDERER) };
                crate::threads::is_software_renderer(&renderer)
            });
            crate::threads::solver_threads(crate::threads::cores(), software)
        };
        #[cfg(target_arch = "wasm32")]
        let threads = None;
        Self::with_context(&cc.egui_ctx, opts, failures, threads)
    }

    /// [`Self::new`] given only the egui context (tests drive the app without a window), the
    /// steps on `threads` threads of their own (`None`: rayon's pool).
    pub(crate) fn with_context(
        ctx: &egui::Context,
        opts: ViewerOptions,
        failures: Failures,
        threads: Option<usize>,
    ) -> anyhow::Result<Self> {
        // Dark whatever the system prefers (a browser reports its theme and egui would follow).
        ctx.set_theme(egui::Theme::Dark);
        let requested_max_particles = opts.scene.max_particles;
        let loaded = opts.scene.clone();
        let sim = build_simulation(opts.scene, requested_max_particles, opts.backend.as_ref())?;
        let started = Instant::now();
        let exit = opts.exit_after.map(|secs| ExitPlan {
            at: started + Duration::from_secs_f64(secs.max(0.0)),
            dir: opts.save_on_exit,
            started: None,
        });
        let scales =
            Coloring::ALL.map(|c| ColorScale::new(c.auto_by_default(), c.scene_range(&sim)));
        Ok(Self {
            mapper: InputMapper::new(sim.gravity(), 2.0 * sim.particle_radius()),
            radius_edit: sim.scene().particle_radius,
            fit: opts
                .fit_to_machine
                .then(|| FitMeasure::start(started, 0, None)),
            resolution_note: None,
            sim: Stepper::with_threads(sim, threads),
            requested_max_particles,
            backend: opts.backend,
            loaded,
            opened_file: opts.scene_file,
            opener: SceneOpener::default(),
            paused: false,
            coloring: Coloring::default(),
            look: WaterLook::default(),
            surface: render::SurfaceLayer::default(),
            undo: UndoHistory::default(),
            scales,
            values: Vec::new(),
            scratch: Vec::new(),
            camera: Camera::default(),
            hud_room: (HUD_SIZE_GUESS, egui::Vec2::ZERO),
            probe_readings: Vec::new(),
            probes_read: None,
            last_hud_rect: None,
            time_scale: 1.0,
            show_help: false,
            history: History::default(),
            fps: Rate::default(),
            steps_per_second: Rate::default(),
            sim_rate: Rate::default(),
            last_frame: None,
            started,
            frames: 0,
            status: None,
            disc: render::disc_texture(ctx),
            fluid_colors: Vec::new(),
            shots: VecDeque::new(),
            exit,
            failures,
            log: Vec::new(),
            session_steps: 0,
            recorder: None,
            video: VideoRecorder::default(),
            observer: None,
            grab_anchor: None,
        })
    }

    /// Auto colour scales start over at the new scene's data; fixed ones stay where the
    /// user (or the default) fixed them.
    fn restart_scales(&mut self) {
        for scale in &mut self.scales {
            scale.restart();
        }
    }

    /// The colour scale of the shown colouring.
    fn scale_mut(&mut self) -> &mut ColorScale {
        let i = Coloring::ALL
            .iter()
            .position(|&c| c == self.coloring)
            .unwrap_or(0);
        &mut self.scales[i]
    }

    /// Record the session into `recorder` (`view --record`).
    pub fn with_recorder(mut self, recorder: Option<SessionRecorder>) -> Self {
        if let Some(r) = recorder {
            match r.start(self.sim.threads(), &self.sim.backend_description()) {
                Ok(r) => {
                    self.set_status(format!("recording to {}", r.path.display()));
                    self.recorder = Some(r);
                }
                Err(e) => self.fail(e),
            }
        }
        self
    }

    /// Call `observer` after every frame with what it showed.
    pub fn on_frame(mut self, observer: impl FnMut(&FrameReport) + 'static) -> Self {
        self.observer = Some(Box::new(observer));
        self
    }

    /// Show `note` in the status line (why a page's link was not used, say).
    pub fn with_note(mut self, note: Option<String>) -> Self {
        if let Some(note) = note {
            self.set_status(note);
        }
        self
    }

    /// What the simulation shows now, for the frame observer.
    fn frame_report(&self) -> FrameReport {
        let positions = self.sim.positions();
        let sum: f64 = positions.iter().map(|p| f64::from(p.x)).sum();
        FrameReport {
            scene: self.sim.scene().name.clone(),
            particles: self.sim.fluid_count(),
            time: self.sim.time(),
            mean_x: sum / positions.len().max(1) as f64,
            steps: self.sim.step_count(),
            realtime: if self.paused {
                0.0
            } else {
                self.sim_rate.get()
            },
            fps: self.fps.get(),
            fitted: self.resolution_note.clone(),
        }
    }

    /// Append an applied action to the recording; on a write error, report it once and stop
    /// recording.
    fn record_action(&mut self, action: &Action) {
        let Some(rec) = &mut self.recorder else {
            return;
        };
        if let Err(e) = rec.recorder.record(self.session_steps, action) {
            let path = rec.path.display().to_string();
            self.recorder = None;
            self.fail(anyhow!("recording to `{path}` stopped: {e}"));
        }
    }

    fn set_status(&mut self, msg: impl Into<String>) {
        self.status = Some((msg.into(), Instant::now()));
    }

    fn fail(&mut self, err: anyhow::Error) {
        self.set_status(format!("error: {err:#}"));
        self.failures.borrow_mut().push(err);
    }

    /// Replace the simulation (reset, scene change, new radius), keeping the old one when
    /// the new scene is rejected.
    fn load(&mut self, ctx: &egui::Context, scene: Scene, requested_max_particles: usize) -> bool {
        match build_simulation(scene, requested_max_particles, self.backend.as_ref()) {
            Ok(sim) => {
                self.sim.replace(sim);
                self.grab_anchor = None;
                self.requested_max_particles = requested_max_particles;
                self.mapper
                    .reset(self.sim.gravity(), 2.0 * self.sim.particle_radius());
                self.radius_edit = self.sim.scene().particle_radius;
                self.history.clear();
                self.undo.clear();
                self.restart_scales();
                self.probes_read = None;
                ctx.send_viewport_cmd(ViewportCommand::Title(window_title(self.sim.scene())));
                true
            }
            Err(e) => {
                self.radius_edit = self.sim.scene().particle_radius;
                self.set_status(format!("scene rejected: {e:#}"));
                false
            }
        }
    }

    /// Load a different scene (or radius); recorded as a reset to that scene.
    fn load_other(
        &mut self,
        ctx: &egui::Context,
        scene: Scene,
        requested_max_particles: usize,
    ) -> bool {
        let loaded = self.load(ctx, scene, requested_max_particles);
        if loaded {
            let scene = Box::new(self.sim.scene().clone());
            self.record_action(&Action::Reset { scene: Some(scene) });
        }
        loaded
    }

    /// Load a scene as the one `R` goes back to (a built-in, a file).
    fn load_as_loaded(&mut self, ctx: &egui::Context, scene: Scene) -> bool {
        let max = scene.max_particles;
        let loaded = self.load_other(ctx, scene.clone(), max);
        if loaded {
            self.loaded = scene;
        }
        loaded
    }

    /// Load a scene file the user opened; a bad one leaves the simulation as it is and says
    /// why.
    fn open_scene(&mut self, ctx: &egui::Context, opened: scene_file::Opened) {
        match opened.scene {
            Ok(scene) => {
                if self.load_as_loaded(ctx, scene) {
                    self.opened_file = Some(scene_file::file_label(&opened.name));
                    self.set_status(format!("opened {}", opened.name));
                }
            }
            Err(e) => self.set_status(format!("cannot open: {e:#}")),
        }
    }

    /// Save the state as `scene-<time>.json`: in the current directory, or as a download in
    /// the browser.
    fn save_scene(&mut self) {
        let saved = scene_file::saved_scene(&self.sim, self.requested_max_particles)
            .and_then(|scene| scene_file::save_state(&scene));
        match saved {
            Ok(said) => self.set_status(said),
            Err(e) => self.set_status(format!("not saved: {e:#}")),
        }
    }

    /// Put a link to the scene being played in the address bar and on the clipboard.
    fn share_link(&mut self, ctx: &egui::Context) {
        let scene = crate::share::shared_scene(&self.sim, &self.loaded);
        let fragment = crate::share::fragment(&scene);
        #[cfg(target_arch = "wasm32")]
        let link = crate::web::set_location_hash(&fragment).unwrap_or(format!("#{fragment}"));
        #[cfg(not(target_arch = "wasm32"))]
        let link = format!("#{fragment}");
        let said = format!(
            "link copied ({} characters): it opens this scene with its walls and settings, \
             water as it started",
            link.len()
        );
        ctx.copy_text(link);
        self.set_status(said);
    }

    fn apply(&mut self, ctx: &egui::Context, cmd: Command) {
        match cmd {
            Command::Sim(action) => {
                self.undo.before(&self.sim, &action);
                let outcome = self.sim.apply(&action);
                self.undo.after(&self.sim, &action, &outcome);
                match &action {
                    Action::GrabBody { at } => {
                        self.grab_anchor = self.sim.dragged_body().and_then(|(k, _)| {
                            let body = self.sim.rigid_bodies().into_iter().nth(k)?;
                            Some((k, bodies::body_frame_point(&body, *at)))
                        });
                        if outcome.rejected.is_some() {
                            self.mapper.forget_body();
                        }
                    }
                    Action::ReleaseBody => self.grab_anchor = None,
                    _ => {}
                }
                if let Some(why) = outcome.rejected {
                    self.set_status(format!("rejected: {why}"));
                } else if matches!(action, Action::Emit { .. })
                    && outcome.added == 0
                    && self.sim.fluid_count() >= self.sim.scene().max_particles
                {
                    self.set_status("particle budget reached");
                }
                self.record_action(&action);
                self.log.push(LoggedAction {
                    time: self.sim.time(),
                    action,
                });
            }
            Command::Undo => match self.undo.pop(&self.sim) {
                Some(stroke) => {
                    // Applied, recorded and logged as any other action.
                    let before = self.sim.fluid_count();
                    self.apply(ctx, Command::Sim(stroke.undo_action()));
                    let said = match stroke {
                        undo::Stroke::Wall { .. } => "took away the last wall drawn".to_string(),
                        undo::Stroke::Pour { .. } => format!(
                            "took away the last pour: {} particles",
                            before.saturating_sub(self.sim.fluid_count())
                        ),
                    };
                    self.set_status(said);
                }
                None => self.set_status("nothing to undo"),
            },
            Command::TogglePause => {
                self.paused = !self.paused;
                self.sim.reset_pace();
            }
            Command::Step => {
                self.paused = true;
                let s = *self.sim.step();
                self.session_steps += 1;
                self.record(&[s]);
            }
            Command::ChangeResolution { finer } => {
                self.fit = None;
                self.change_resolution(ctx, finer);
            }
            Command::Reset => {
                // The scene as loaded, not as changed since: recorded as a reset to it.
                let scene = self.loaded.clone();
                let max = scene.max_particles;
                self.load_other(ctx, scene, max);
            }
            Command::LoadScene(i) => {
                self.fit = None;
                self.resolution_note = None;
                if let Some(b) = BUILTIN_SCENES.get(i) {
                    if self.load_as_loaded(ctx, b.scene()) {
                        self.opened_file = None;
                    }
                    // Another tank: a zoom into the last one means nothing there.
                    self.camera.reset();
                }
            }
            Command::SaveScene => self.save_scene(),
            Command::OpenScene => {
                if let Err(e) = self.opener.open() {
                    self.set_status(format!("{e:#}"));
                }
            }
            Command::ShareLink => self.share_link(ctx),
            Command::SetParticleRadius(r) => {
                self.fit = None;
                self.resolution_note = None;
                let mut scene = self.sim.scene().clone();
                scene.particle_radius = r;
                self.load_other(ctx, scene, self.requested_max_particles);
            }
            Command::CycleColoring => self.coloring = self.coloring.next(),
            Command::ToggleLook => {
                self.look = match self.look {
                    WaterLook::Surface => WaterLook::Particles,
                    WaterLook::Particles => WaterLook::Surface,
                }
            }
            #[cfg(not(target_arch = "wasm32"))]
            Command::Screenshot => {
                let dir = std::env::current_dir().unwrap_or_else(|_| PathBuf::from("."));
                self.shots
                    .push_back(ShotPurpose::File(export::timestamped_png(&dir)));
                ctx.send_viewport_cmd(ViewportCommand::Screenshot(Default::default()));
            }
            // The page cannot read its own WebGL canvas back: the picture is drawn by the
            // CPU rasteriser of `dfsph2d run --format png` and downloaded.
            #[cfg(target_arch = "wasm32")]
            Command::Screenshot => {
                let said = match export::download_rendered_png(
                    &self.sim,
                    self.coloring.frame_field(),
                    self.look,
                ) {
                    Ok(name) => format!("downloaded {name}"),
                    Err(e) => format!("screenshot failed: {e:#}"),
                };
                self.set_status(said);
            }
            Command::ToggleHelp => self.show_help = !self.show_help,
            Command::CloseHelp => self.show_help = false,
            Command::ToggleRecording => {
                let dir = std::env::current_dir().unwrap_or_else(|_| PathBuf::from("."));
                let said =
                    self.video
                        .toggle(&self.sim, &dir, self.coloring.frame_field(), self.look);
                self.set_status(said);
            }
            Command::DropBody { shape, at } => {
                let body = bodies::drop_spec(&self.sim, shape, at, self.mapper.body_density);
                self.apply(ctx, Command::Sim(Action::AddBody { body }));
            }
            // The view commands are applied where the view's geometry is known (`update`).
            Command::ZoomView { .. } | Command::PanView { .. } | Command::ResetView => {}
        }
    }

    /// Apply a zoom, pan or view reset to the camera of the world `lo`–`hi` shown in `rect`.
    fn apply_view(&mut self, cmd: &Command, lo: dfsph::Vec2, hi: dfsph::Vec2, rect: egui::Rect) {
        match cmd {
            Command::ZoomView { factor, about } => {
                self.camera.zoom_about(*factor, *about, lo, hi, rect)
            }
            Command::PanView { delta } => {
                let scale = self.camera.transform(lo, hi, rect).scale();
                self.camera.pan(*delta, scale);
            }
            Command::ResetView => self.camera.reset(),
            _ => {}
        }
    }

    fn record(&mut self, steps: &[StepStats]) {
        let mut f = FrameStats::default();
        for s in steps {
            f.add(s);
        }
        if let Some(s) = f.sample() {
            self.history.push(s);
        }
    }

    /// Answer screenshot events with the purpose they were requested for.
    fn handle_screenshots(&mut self, ctx: &egui::Context) {
        let images: Vec<_> = ctx.input(|i| {
            i.events
                .iter()
                .filter_map(|e| match e {
                    egui::Event::Screenshot { image, .. } => Some(image.clone()),
                    _ => None,
                })
                .collect()
        });
        for image in images {
            match self.shots.pop_front() {
                Some(ShotPurpose::File(path)) => match export::save_png(&path, &image) {
                    Ok(()) => self.set_status(format!("saved {}", path.display())),
                    Err(e) => self.set_status(format!("screenshot failed: {e:#}")),
                },
                Some(ShotPurpose::Exit) => {
                    if let Some(dir) = self.exit.as_ref().and_then(|e| e.dir.clone()) {
                        let path = dir.join("screenshot.png");
                        if let Err(e) = export::save_png(&path, &image) {
                            self.fail(e);
                        }
                    }
                    ctx.send_viewport_cmd(ViewportCommand::Close);
                }
                None => {}
            }
        }
    }

    /// `--exit-after`: when the time comes, write the particles and the session record,
    /// request the screenshot, and close once it is saved (or after a timeout).
    fn check_exit(&mut self, ctx: &egui::Context) {
        let Some(plan) = &self.exit else { return };
        let now = Instant::now();
        if let Some(started) = plan.started {
            if now - started > SCREENSHOT_TIMEOUT {
                self.fail(anyhow!(
                    "no screenshot arrived within {} s",
                    SCREENSHOT_TIMEOUT.as_secs()
                ));
                ctx.send_viewport_cmd(ViewportCommand::Close);
            }
            return;
        }
        if now < plan.at {
            return;
        }
        let dir = plan.dir.clone();
        if let Some(plan) = &mut self.exit {
            plan.started = Some(now);
        }
        match dir {
            Some(dir) => {
                if let Err(e) = self.save_outputs(&dir) {
                    self.fail(e);
                }
                self.shots.push_back(ShotPurpose::Exit);
                ctx.send_viewport_cmd(ViewportCommand::Screenshot(Default::default()));
            }
            None => ctx.send_viewport_cmd(ViewportCommand::Close),
        }
    }

    /// Write `particles.csv` and `session.json` (run statistics and every applied action).
    fn save_outputs(&self, dir: &std::path::Path) -> anyhow::Result<()> {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        export::write_particles_csv(&dir.join("particles.csv"), &self.sim.snapshot())?;
        let wall = self.started.elapsed().as_secs_f64();
        let actions: Vec<_> = self
            .log
            .iter()
            .map(|l| serde_json::json!({ "time": l.time, "action": l.action }))
            .collect();
        let session = serde_json::json!({
            "scene": self.sim.scene().name,
            "simulated_time": self.sim.time(),
            "steps": self.sim.step_count(),
            "frames": self.frames,
            "wall_seconds": wall,
            "mean_fps": self.frames as f64 / wall.max(1e-9),
            "pace": self.sim_rate.get() / self.time_scale,
            "fluid_particles": self.sim.fluid_count(),
            "clamped": self.sim.total_clamped(),
            "non_finite": self.sim.total_non_finite(),
            "view": {
                "zoom": self.camera.zoom(),
                "offset": [self.camera.offset().x, self.camera.offset().y],
            },
            "actions": actions,
        });
        let path = dir.join("session.json");
        std::fs::write(&path, serde_json::to_string_pretty(&session)?)
            .with_context(|| format!("writing {}", path.display()))?;
        // The state as a scene that `run` and `view` load (session.json is a record).
        let scene = scene_file::saved_scene(&self.sim, self.requested_max_particles)?;
        scene_file::write_scene(&dir.join("scene.json"), &scene)
    }
}

/// Colour of probe markers and readings: amber, apart from every colour map's water.
const PROBE_COLOR: Color32 = Color32::from_rgb(255, 200, 60);

/// A probe's reading with its unit: "1.23 kPa", "850 Pa", "0.512 m".
pub fn probe_reading(probe: &dfsph::scene::Probe, value: f64) -> String {
    match probe {
        dfsph::scene::Probe::Pressure { .. } if value.abs() >= 10_000.0 => {
            format!("{:.1} kPa", value / 1000.0)
        }
        dfsph::scene::Probe::Pressure { .. } if value.abs() >= 1000.0 => {
            format!("{:.2} kPa", value / 1000.0)
        }
        dfsph::scene::Probe::Pressure { .. } => format!("{value:.0} Pa"),
        dfsph::scene::Probe::WaterLevel { .. } => format!("{value:.3} m"),
    }
}

/// A simulation for `scene` with the viewer's pour budget: room for the scene's fluid and as
/// much again (at least 2,000 more), within the scene's own `max_particles`, on `backend`'s
/// backend (the CPU's for `None`).
fn build_simulation(
    scene: Scene,
    requested_max_particles: usize,
    backend: Option<&dfsph::simulation::BackendFactory>,
) -> anyhow::Result<Simulation> {
    let scene = budgeted_scene(scene, requested_max_particles);
    let sim = match backend {
        Some(factory) => Simulation::with_backend(
            &scene,
            &dfsph::memory::MemoryLimits::of_this_process(None),
            factory.clone(),
        ),
        None => Simulation::new(&scene),
    };
    sim.map_err(|e| anyhow!("scene `{}`: {e}", scene.name))
}

/// `scene` with the viewer's pour budget in `max_particles` (see `build_simulation`).
pub fn budgeted_scene(mut scene: Scene, requested_max_particles: usize) -> Scene {
    let n = scene.fluid_particle_count();
    scene.max_particles = requested_max_particles.min((2 * n).max(n + 2000)).max(n);
    scene
}

/// The window title; always contains "dfsph2d" (the Xvfb test finds the window by it).
pub fn window_title(scene: &Scene) -> String {
    format!("dfsph2d — {}", scene.name)
}

impl eframe::App for ViewerApp {
    /// The window is closing: end the recording with the session's length and a
    /// fingerprint of the final state.
    fn on_exit(&mut self, _gl: Option<&eframe::glow::Context>) {
        self.take_back_the_simulation(0.0);
        // A video being recorded is finished, not lost; its name goes to the terminal.
        for said in self.video.finish_all(self.sim.time()) {
            // Not eprintln!: a terminal gone (SIGHUP) must not turn closing into a panic.
            let _ = writeln!(std::io::stderr(), "{said}");
        }
        if let Some(rec) = self.recorder.take() {
            let end = End::of(self.session_steps, &self.sim);
            if let Err(e) = rec.recorder.finish(&end) {
                self.fail(anyhow!(
                    "cannot finish recording `{}`: {e}",
                    rec.path.display()
                ));
            }
        }
    }

    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
        let ctx = &ui.ctx().clone();
        let now = Instant::now();
        let frame_seconds = self.last_frame.map_or(0.0, |l| (now - l).as_secs_f64());
        self.fps.add(1.0, frame_seconds);
        self.last_frame = Some(now);
        self.frames += 1;
        // Everything below reads the simulation: it comes home first, with the steps it took
        // while the last frame was drawn.
        self.take_back_the_simulation(frame_seconds);
        self.fit_to_machine(ctx);
        self.video.capture(&self.sim);
        if let Some(said) = self.video.poll() {
            self.set_status(said);
        }
        if self
            .status
            .as_ref()
            .is_some_and(|(_, t)| t.elapsed() > STATUS_DURATION)
        {
            self.status = None;
        }

        self.handle_screenshots(ctx);
        self.check_exit(ctx);
        let exiting = self.exit.as_ref().is_some_and(|e| e.started.is_some());

        // Side panel.
        let mut commands = Vec::new();
        let status = self.status.as_ref().map(|(s, _)| s.clone());
        egui::Panel::right("controls")
            .default_size(300.0)
            .show(ui, |ui| {
                commands = panel::side_panel(
                    ui,
                    PanelState {
                        sim: &self.sim,
                        mapper: &mut self.mapper,
                        time_scale: &mut self.time_scale,
                        coloring: &mut self.coloring,
                        look: &mut self.look,
                        undo: self.undo.last(&self.sim),
                        scales: &mut self.scales,
                        view_fitted: self.camera.is_fitted(),
                        radius_edit: &mut self.radius_edit,
                        radius_range: scene_file::radius_range(
                            self.sim.scene(),
                            self.requested_max_particles,
                        ),
                        paused: self.paused,
                        recording: self.video.is_recording(),
                        status: status.as_deref(),
                        opened_file: self.opened_file.as_deref(),
                    },
                );
            });

        let plots_height = (0.2 * ctx.content_rect().height()).clamp(70.0, 150.0);
        egui::Panel::bottom("plots")
            .exact_size(plots_height)
            .show(ui, |ui| {
                ui.add_space(4.0);
                self.history.plots(ui);
            });

        // The view: its rect, its response to the pointer, and a painter clipped to it.
        let (rect, response, painter) = egui::CentralPanel::default()
            .frame(egui::Frame::NONE.fill(Color32::from_rgb(18, 20, 26)))
            .show(ui, |ui| {
                // Clickable and draggable, but never focused: the keys belong to the viewer.
                let sense = Sense::CLICK | Sense::DRAG;
                let (rect, response) = ui.allocate_exact_size(ui.available_size(), sense);
                (rect, response, ui.painter_at(rect))
            })
            .inner;
        let layout = self.layout(rect);
        let (lo, hi) = render::world_bounds(&self.sim);
        let transform = self.camera.transform(lo, hi, layout.world);
        let hover = ctx.input(|i| i.pointer.hover_pos());
        // The tools and the wheel act over the world's rectangle, not over the HUD and the
        // colour bar beside it (a drag that started in it keeps going anywhere).
        let over_view = (response.hovered() && hover.is_some_and(|p| layout.world.contains(p)))
            || response.dragged();
        let pointer = hover.filter(|_| over_view).map(|p| transform.to_world(p));
        let over_body = pointer.is_some_and(|p| self.sim.rigid_body_at(p).is_some());
        let view = ViewInput {
            pointer,
            // The open-scene dialog's keys are its own.
            keyboard: !ctx.egui_wants_keyboard_input() && !self.opener.is_open(),
            over_body,
        };
        commands.extend(ctx.input(|i| self.mapper.update(i, view)));

        // Actions between steps, then this frame's slice of simulated time.
        for cmd in commands {
            self.apply_view(&cmd, lo, hi, layout.world);
            self.apply(ctx, cmd);
        }
        self.undo.end_frame(&self.sim);
        // A scene file picked in the dialog or dropped on the window.
        let mut opened = ctx.input(scene_file::dropped_scenes);
        opened.extend(self.opener.update(ctx));
        for file in opened {
            self.open_scene(ctx, file);
        }
        // A reset or a new scene may have changed the world bounds.
        let (lo, hi) = render::world_bounds(&self.sim);
        let transform = self.camera.transform(lo, hi, layout.world);
        if matches!(self.mapper.tool(), Tool::Pan | Tool::Drag) {
            ctx.set_cursor_icon(egui::CursorIcon::Grabbing);
        } else if over_body && self.mapper.tool() == Tool::Idle {
            ctx.set_cursor_icon(egui::CursorIcon::Grab);
        }
        let world_painter = painter.with_clip_rect(layout.world);
        self.draw(
            ctx,
            &painter,
            &world_painter,
            &layout,
            &transform,
            hover.filter(|_| over_view),
            frame_seconds as f32,
        );
        hud::help_window(ctx, &mut self.show_help);
        if self.observer.is_some() {
            let report = self.frame_report();
            if let Some(observe) = &mut self.observer {
                observe(&report);
            }
        }
        // The simulation steps while this frame is drawn, until the next one begins.
        if !self.paused && !exiting {
            self.sim.send_away(self.time_scale);
        }
        ctx.request_repaint();
    }
}

impl ViewerApp {
    /// Once the pace has been measured for [`resolution::MEASURE_SECONDS`] (as simulated
    /// time per wall time spent stepping, which the real-time pacing does not cap), restart
    /// the scene with the particle size that keeps real time on this machine if it is slower
    /// ([`resolution::radius_for_pace`]), and measure again; the HUD says what was chosen.
    fn fit_to_machine(&mut self, ctx: &egui::Context) {
        let Some(m) = self.fit else {
            return;
        };
        if m.wall < resolution::MEASURE_SECONDS {
            return;
        }
        self.fit = None;
        // Simulated seconds per wall second of stepping: the pace this machine could keep
        // (the pace shown is held to real time and cannot say how much faster it could go).
        let pace = m.simulated / m.busy.max(1e-9) / self.time_scale;
        let scene = self.sim.scene();
        let now = (scene.particle_radius, pace);
        let exponent = m.before.map_or(resolution::COST_EXPONENT, |before| {
            resolution::measured_exponent(before, now)
        });
        let Some(radius) = resolution::radius_for_pace(
            scene.particle_radius,
            pace,
            exponent,
            scene.particle_radius_limits(),
        )
        .filter(|_| m.fits < resolution::MAX_FITS) else {
            return;
        };
        let before = self.sim.fluid_count();
        let mut fitted = self.loaded.clone();
        fitted.particle_radius = radius;
        if self.load_as_loaded(ctx, fitted) {
            self.radius_edit = radius;
            self.fit = Some(FitMeasure::start(Instant::now(), m.fits + 1, Some(now)));
            self.resolution_note = Some(format!(
                "{} particles, fitted to this machine ({} ran at x{pace:.2}); {} finer, {} \
                 coarser",
                resolution::thousands(self.sim.fluid_count()),
                resolution::thousands(before),
                resolution::FINER_KEY,
                resolution::COARSER_KEY,
            ));
        }
    }

    /// Restart the scene as it stands with twice (`finer`) or half as many particles.
    fn change_resolution(&mut self, ctx: &egui::Context, finer: bool) {
        let scene = self.sim.scene();
        let Some(radius) = resolution::radius_after_key(
            scene.particle_radius,
            finer,
            scene.particle_radius_limits(),
        ) else {
            self.set_status(format!(
                "the particles cannot be {} in this tank",
                if finer { "finer" } else { "coarser" }
            ));
            return;
        };
        let mut scene = scene.clone();
        scene.particle_radius = radius;
        if self.load_other(ctx, scene, self.requested_max_particles) {
            self.radius_edit = radius;
            self.resolution_note = None;
            self.set_status(format!(
                "particle radius {radius} m: {} particles",
                resolution::thousands(self.sim.fluid_count())
            ));
        }
    }

    /// Bring the simulation home from its stepping and account for the steps it took, over
    /// `frame_seconds` of wall time.
    fn take_back_the_simulation(&mut self, frame_seconds: f64) {
        let away = self.sim.bring_home();
        self.session_steps += away.steps.len() as u64;
        if !self.paused {
            self.steps_per_second
                .add(away.steps.len() as f64, frame_seconds);
            self.sim_rate.add(away.simulated, frame_seconds);
        }
        if let Some(m) = &mut self.fit {
            if self.paused {
                // A pause (or a single step) says nothing of this machine's pace.
                *m = FitMeasure::start(Instant::now(), m.fits, m.before);
            } else if m.since.elapsed().as_secs_f64() >= resolution::SETTLE_SECONDS {
                m.simulated += away.simulated;
                m.busy += away.busy;
                m.wall += frame_seconds;
            }
        }
        self.record(&away.steps);
    }

    /// Where the world, the HUD and the colour bar go in the view `rect`, keeping room for
    /// the HUD as large as it has been in a view of this size.
    fn layout(&mut self, rect: egui::Rect) -> Layout {
        let size = self.hud_room.1;
        if size != rect.size() {
            self.hud_room = (egui::Vec2::ZERO, rect.size());
        }
        if let Some(r) = self.last_hud_rect.filter(|r| r.is_positive()) {
            self.hud_room.0 = self.hud_room.0.max(r.size());
        }
        let hud = if self.hud_room.0 == egui::Vec2::ZERO {
            HUD_SIZE_GUESS
        } else {
            self.hud_room.0
        };
        let (lo, hi) = render::world_bounds(&self.sim);
        view::layout(rect, hud, hi - lo)
    }

    /// How much slower than asked simulated time runs (budget overruns and slow frames
    /// together), when it is noticeably slower.
    fn slowed(&self) -> Option<f64> {
        let pace = self.sim_rate.get() / self.time_scale;
        (!self.paused && self.sim_rate.get() > 0.0 && pace < 0.95).then_some(pace)
    }

    #[allow(clippy::too_many_arguments)]
    fn draw(
        &mut self,
        ctx: &egui::Context,
        painter: &egui::Painter,
        world_painter: &egui::Painter,
        layout: &Layout,
        transform: &ViewTransform,
        hover: Option<egui::Pos2>,
        frame_seconds: f32,
    ) {
        // The colours: the field, the scale following it (when auto), the colour map.
        self.coloring.values(&self.sim, &mut self.values);
        let coloring = self.coloring;
        let target = if self.scale_mut().auto {
            coloring.auto_target(&self.values, &mut self.scratch)
        } else {
            None
        };
        self.scale_mut().follow(target, frame_seconds);
        let scale = *self.scale_mut();
        coloring.colors(&self.values, scale.range, &mut self.fluid_colors);
        let mesh = render::particle_mesh(
            &self.sim,
            transform,
            self.disc.id(),
            &self.fluid_colors,
            self.look,
        );
        world_painter.add(egui::Shape::mesh(mesh));
        if self.look == WaterLook::Surface {
            self.surface.draw(
                world_painter,
                transform,
                ctx.pixels_per_point(),
                &self.sim,
                &self.fluid_colors,
            );
        }
        // The bodies over the water that touches them; their boundary particles are not drawn.
        let rigid = self.sim.rigid_bodies();
        bodies::draw_bodies(world_painter, transform, &rigid);
        if let (Some((k, target)), Some((held, local))) =
            (self.sim.dragged_body(), self.grab_anchor)
        {
            if let Some(body) = rigid.get(k).filter(|_| k == held) {
                let from = transform.to_screen(bodies::grabbed_point(body, local));
                let to = transform.to_screen(target);
                let stroke = Stroke::new(1.5_f32, Color32::from_white_alpha(200));
                world_painter.line_segment([from, to], stroke);
                world_painter.circle_filled(from, 3.0, Color32::WHITE);
                world_painter.circle_stroke(to, 4.0, stroke);
            }
        }
        self.draw_probes(world_painter, transform);

        // Wall preview and the tool circle.
        if let Some(wall) = self.mapper.wall_preview() {
            let pts: Vec<_> = wall.iter().map(|&p| transform.to_screen(p)).collect();
            let width = (2.0 * self.sim.particle_radius() * transform.scale()).max(2.0);
            world_painter.add(egui::Shape::line(
                pts,
                Stroke::new(width, render::WALL_COLOR.gamma_multiply(0.7)),
            ));
        }
        if let Some(pos) = hover {
            let erase_armed = ctx.input(|i| i.key_down(egui::Key::X));
            let color = match self.mapper.tool() {
                Tool::Pull => Color32::from_rgb(120, 220, 255),
                Tool::Push => Color32::from_rgb(255, 170, 80),
                Tool::Pour => Color32::from_rgb(80, 140, 255),
                Tool::Erase => Color32::from_rgb(255, 80, 80),
                Tool::Wall | Tool::Pan | Tool::Drag => Color32::TRANSPARENT,
                Tool::Idle if erase_armed => Color32::from_rgb(255, 80, 80),
                Tool::Idle => Color32::from_white_alpha(110),
            };
            world_painter.circle_stroke(
                pos,
                self.mapper.tool_radius * transform.scale(),
                Stroke::new(1.5_f32, color),
            );
        }

        render::legend(
            painter,
            layout.legend,
            layout.legend_horizontal,
            coloring,
            &scale,
        );

        let stats = *self.sim.stats();
        let zoom = self.camera.zoom();
        let backend = self.sim.backend_description();
        let info = HudInfo {
            scene: &self.sim.scene().name,
            backend: &backend,
            fps: self.fps.get(),
            steps_per_second: self.steps_per_second.get(),
            particles: self.sim.fluid_count(),
            budget: self.sim.scene().max_particles,
            time: self.sim.time(),
            stats: &stats,
            paused: self.paused,
            realtime: (!self.paused).then(|| self.sim_rate.get()),
            slowed: self.slowed(),
            clamped: self.sim.total_clamped(),
            non_finite: self.sim.total_non_finite(),
            zoom: (!self.camera.is_fitted()).then_some(zoom),
            resolution_note: self.resolution_note.as_deref(),
        };
        let shown = egui::Area::new(egui::Id::new("hud"))
            .fixed_pos(layout.hud)
            .interactable(false)
            .show(ctx, |ui| hud::hud(ui, &info));
        self.last_hud_rect = Some(shown.response.rect);
    }

    /// The scene's probes on the view: a ring for each pressure probe, a dashed line with a
    /// bar at the water level for each gauge, and each one's name and reading beside it, so
    /// that a user sees what `dfsph2d run` would write into `probes.csv`.
    fn draw_probes(&mut self, painter: &egui::Painter, transform: &ViewTransform) {
        let probes = &self.sim.scene().probes;
        if probes.is_empty() {
            return;
        }
        let due = self
            .probes_read
            .is_none_or(|t| t.elapsed() >= PROBE_INTERVAL);
        if due || self.probe_readings.len() != probes.len() {
            self.probe_readings = dfsph::probes::sample_all(&self.sim);
            self.probes_read = Some(Instant::now());
        }
        let scene = self.sim.scene();
        // Probes are fixed to the tank: they move with it when it is shaken.
        let (lo, hi) = self.sim.tank_interior();
        let offset = lo - dfsph::Vec2::new(scene.tank.min[0] as f32, scene.tank.min[1] as f32);
        let color = PROBE_COLOR;
        let font = egui::FontId::proportional(12.0);
        for (probe, &value) in probes.iter().zip(&self.probe_readings) {
            let reading = probe_reading(probe, value);
            let (anchor, align) = match probe {
                dfsph::scene::Probe::Pressure { at, .. } => {
                    let p =
                        transform.to_screen(dfsph::Vec2::new(at[0] as f32, at[1] as f32) + offset);
                    painter.circle_stroke(p, 5.0, Stroke::new(2.0_f32, Color32::BLACK));
                    painter.circle_stroke(p, 5.0, Stroke::new(1.5_f32, color));
                    painter.circle_filled(p, 1.5, color);
                    // Labels of probes on the right wall go to their left, inside the tank.
                    let right_wall =
                        (at[0] - scene.tank.max[0]).abs() <= scene.tank.edge_tolerance();
                    if right_wall {
                        (p - vec2(9.0, 0.0), egui::Align2::RIGHT_CENTER)
                    } else {
                        (p + vec2(9.0, 0.0), egui::Align2::LEFT_CENTER)
                    }
                }
                dfsph::scene::Probe::WaterLevel { x, .. } => {
                    let x = *x as f32 + offset.x;
                    let bottom = transform.to_screen(dfsph::Vec2::new(x, lo.y));
                    let top = transform.to_screen(dfsph::Vec2::new(x, hi.y));
                    painter.add(egui::Shape::dashed_line(
                        &[bottom, top],
                        Stroke::new(1.0_f32, color.gamma_multiply(0.8)),
                        6.0,
                        4.0,
                    ));
                    let level = transform.to_screen(dfsph::Vec2::new(x, lo.y + value as f32));
                    painter.line_segment(
                        [level - vec2(8.0, 0.0), level + vec2(8.0, 0.0)],
                        Stroke::new(2.5_f32, color),
                    );
                    (level + vec2(10.0, -9.0), egui::Align2::LEFT_BOTTOM)
                }
            };
            let text = format!("{} {reading}", probe.name());
            let galley = painter.layout_no_wrap(text, font.clone(), color);
            let rect = align.anchor_size(anchor, galley.size());
            painter.rect_filled(rect.expand(2.0), 3.0, Color32::from_black_alpha(170));
            painter.galley(rect.min, galley, color);
        }
    }
}

#[cfg(test)]
mod probe_tests {
    use super::*;
    use dfsph::scene::Probe;

    #[test]
    fn probe_readings_carry_their_unit_and_sensible_digits() {
        let p = Probe::Pressure {
            name: "p".into(),
            at: [1.0, 0.1],
        };
        let h = Probe::WaterLevel {
            name: "h".into(),
            x: 2.0,
        };
        assert_eq!(probe_reading(&p, 850.4), "850 Pa");
        assert_eq!(probe_reading(&p, 1612.0), "1.61 kPa");
        assert_eq!(probe_reading(&p, 24282.0), "24.3 kPa");
        assert_eq!(probe_reading(&h, 0.51234), "0.512 m");
    }
}

#[cfg(test)]
#[path = "app_tests.rs"]
mod tests;
