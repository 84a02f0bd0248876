//! `dfsph2d stress [SCENE] --seed N --steps K [--record FILE]`: drive a scene with a seeded
//! random sequence of the viewer's actions and check the simulation after every action and
//! every step (the checks and ranges are listed in `dfsph2d stress --help`, `cli.rs`).
//!
//! The action sequence depends only on the seed, the step count and the scene (never on the
//! simulated state), so a seed names the same sequence on every machine; `--record` writes it
//! down anyway, with the final state's fingerprint, for `run --replay`.

use std::fs::File;
use std::io::BufWriter;
use std::path::PathBuf;

use dfsph::forces::MAX_POINTER_ACCELERATION;
use dfsph::recording::{End, Header, Recorder};
use dfsph::rigid::{BodySpec, RigidBodyState};
use dfsph::{Action, Scene, Simulation, StepStats, Vec2};

use crate::cli::StressArgs;
use crate::failure::Failure;
use dfsph_io::input::{load_scene, one_line, terminal_safe};

/// The viewer's pour speed, m/s (`dfsph_viewer::input::POUR_SPEED`).
const POUR_SPEED: f32 = 1.0;
/// The viewer's largest tilt of gravity, degrees.
const MAX_TILT_DEG: f32 = 45.0;

/// Densities of the bodies stress drops in, kg/m³ (log-uniform): from foam to steel.
const BODY_DENSITIES: (f64, f64) = (100.0, 8_000.0);
/// Most bodies stress drops in between resets (the scene's own come on top).
const MAX_DROPPED_BODIES: usize = 8;

/// `dfsph2d stress`.
pub fn command(args: StressArgs) -> Result<(), Failure> {
    if let Some(n) = args.threads {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n as usize)
            .build_global()
            .map_err(|e| Failure::input(format!("cannot start {n} threads: {e}")))?;
    }
    let scene = load_scene(&args.scene).map_err(Failure::input)?;
    let scene = budgeted(scene);
    crate::failure::check_memory(
        &format!("scene `{}`", args.scene),
        &scene.memory_estimate_for(scene.max_particles as u64),
        args.max_memory,
    )?;
    let (factory, mut notes) = crate::backends::factory(args.backend).map_err(Failure::input)?;
    let limits = dfsph::memory::MemoryLimits::of_this_process(args.max_memory);
    let (sim, on) = crate::backends::simulation(&scene, &limits, factory.as_ref())
        .map_err(|e| Failure::input(format!("scene `{}`: {e}", args.scene)))?;
    notes.extend(on);
    for note in notes {
        eprintln!("{}", terminal_safe(&note));
    }
    let recorder = match &args.record {
        Some(path) => Some(
            open_recorder(path, &args, &scene, &sim.backend_description())
                .map_err(Failure::input)?,
        ),
        None => None,
    };
    crate::interrupt::install();
    let plan = StressPlan {
        seed: args.seed,
        steps: args.steps,
        density_bound_pct: args.density_bound,
        bodies: !args.no_bodies,
    };
    let outcome = run(&plan, sim, recorder).map_err(Failure::runtime)?;
    println!("{}", terminal_safe(&outcome.summary(&scene.name, &plan)));
    if outcome.interrupted {
        return Err(Failure {
            code: crate::interrupt::EXIT_CODE,
            message: String::new(),
        });
    }
    match outcome.violation {
        // The summary line already names the violation.
        Some(_) => Err(Failure {
            code: 1,
            message: String::new(),
        }),
        None => Ok(()),
    }
}

fn open_recorder(
    path: &PathBuf,
    args: &StressArgs,
    scene: &Scene,
    backend: &str,
) -> Result<Recorder<BufWriter<File>>, String> {
    // A FIFO would block the open until someone reads it, /dev/null would swallow the
    // recording: only a regular file (or a new one) is written.
    dfsph_io::input::check_output_file(path, "--record")?;
    let source = format!("stress seed={} steps={}", args.seed, args.steps);
    let header = Header::new(source, rayon::current_num_threads(), scene).on_backend(backend);
    // Opened non-blocking and checked again, in case a FIFO took the file's place meanwhile
    // (opening one for writing would wait for a reader); a regular file ignores the flag.
    let mut options = std::fs::OpenOptions::new();
    options.write(true).create(true).truncate(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        options.custom_flags(libc::O_NONBLOCK);
    }
    let file: File = options
        .open(path)
        .map_err(|e| format!("cannot create recording `{}`: {e}", path.display()))?;
    if !file.metadata().is_ok_and(|m| m.is_file()) {
        return Err(format!(
            "--record `{}` is not a regular file (a FIFO, socket or device); give the path of a file",
            path.display()
        ));
    }
    Recorder::new(BufWriter::new(file), &header)
        .map_err(|e| format!("cannot write recording `{}`: {e}", path.display()))
}

/// The viewer's pour budget: room for the scene's fluid and as much again (at least 2,000
/// more), within the scene's own `max_particles` (`dfsph_viewer::app::budgeted_scene`).
pub fn budgeted(mut scene: Scene) -> Scene {
    let n = scene.fluid_particle_count();
    scene.max_particles = scene.max_particles.min((2 * n).max(n + 2000)).max(n);
    scene
}

/// What to run.
pub struct StressPlan {
    pub seed: u64,
    pub steps: u64,
    /// Largest allowed single-particle density error, percent.
    pub density_bound_pct: f64,
    /// Drop rigid bodies in and drag them about (their actions draw from a stream of their
    /// own: without them the others are the same).
    pub bodies: bool,
}

/// The first broken invariant.
#[derive(Clone, Debug, PartialEq)]
pub struct Violation {
    /// Steps taken when it was seen (0: before the first step, after an action).
    pub step: u64,
    pub what: String,
}

/// What a stress run saw.
#[derive(Clone, Debug, Default)]
pub struct StressOutcome {
    /// Steps taken.
    pub steps: u64,
    pub actions: usize,
    pub rejected: usize,
    pub resets: usize,
    pub n_fluid: usize,
    pub poured: usize,
    pub erased: usize,
    /// Fluid particles removed where a body was dropped in.
    pub displaced: usize,
    pub max_density_error_pct: f64,
    pub max_speed: f64,
    /// The deepest water seen, m ([`deepest_water`], after every step).
    pub max_depth_m: f64,
    pub clamped: u64,
    pub non_finite: u64,
    /// Rigid bodies at the end, and the most fluid particles seen inside one at once.
    pub bodies: usize,
    pub max_inside_bodies: usize,
    pub violation: Option<Violation>,
    pub interrupted: bool,
    /// Fingerprint of the final state.
    pub fingerprint: String,
}

impl StressOutcome {
    /// The one-line summary.
    pub fn summary(&self, scene: &str, plan: &StressPlan) -> String {
        let verdict = match (&self.violation, self.interrupted) {
            (Some(v), _) => format!("FAILED at step {}: {}", v.step, v.what),
            (None, true) => format!("interrupted at step {}", self.steps),
            (None, false) => "ok".to_string(),
        };
        let ran = if self.steps < plan.steps {
            format!("ran {} of {} steps, ", self.steps, plan.steps)
        } else {
            String::new()
        };
        let displaced = match self.displaced {
            0 => String::new(),
            n => format!(" −{n} under bodies"),
        };
        let resets = match self.resets {
            0 => String::new(),
            1 => ", 1 reset".to_string(),
            n => format!(", {n} resets"),
        };
        one_line(&format!(
            "stress {scene} seed={} steps={}: {verdict} — {ran}particles {} (+{} poured −{} \
             erased{displaced}{resets}), {} bodies, max density error {:.2} % (bound {} %), max speed \
             {:.2} m/s, deepest water {:.2} m, {} clamps, {} inside bodies, {} non-finite, {} actions ({} rejected)",
            plan.seed,
            plan.steps,
            self.n_fluid,
            self.poured,
            self.erased,
            self.bodies,
            self.max_density_error_pct,
            plan.density_bound_pct,
            self.max_speed,
            self.max_depth_m,
            self.clamped,
            self.max_inside_bodies,
            self.non_finite,
            self.actions,
            self.rejected,
        ))
    }
}

/// Run the plan on `sim` (built from the budgeted scene), recording the actions if asked.
/// Stops at the first violation or on Ctrl-C.
pub fn run<W: std::io::Write>(
    plan: &StressPlan,
    mut sim: Simulation,
    mut recorder: Option<Recorder<W>>,
) -> anyhow::Result<StressOutcome> {
    let mut gen = Generator::new(plan.seed, sim.scene());
    gen.bodies = plan.bodies;
    let mut out = StressOutcome::default();
    // Fluid particles expected now: the epoch's start (initial, or after a reset) plus
    // poured minus erased since.
    let mut expected = sim.fluid_count();
    let mut actions = Vec::new();
    while out.steps < plan.steps {
        if crate::interrupt::requested() {
            out.interrupted = true;
            break;
        }
        actions.clear();
        gen.actions(out.steps, sim.scene(), &mut actions);
        for action in &actions {
            if let Some(rec) = &mut recorder {
                rec.record(out.steps, action)?;
            }
            let o = sim.apply(action);
            out.actions += 1;
            if o.rejected.is_some() {
                out.rejected += 1;
                continue;
            }
            if let Action::Reset { .. } = action {
                out.resets += 1;
                expected = sim.fluid_count();
            } else if let Action::AddBody { .. } = action {
                out.displaced += o.removed;
                expected = expected.saturating_sub(o.removed);
            } else {
                out.poured += o.added;
                out.erased += o.removed;
                expected = (expected + o.added).saturating_sub(o.removed);
            }
        }
        if !actions.is_empty() {
            if let Some(what) = check_state(&sim, expected, &mut out) {
                out.violation = Some(Violation {
                    step: out.steps,
                    what: format!("after {}: {what}", action_names(&actions)),
                });
                break;
            }
        }
        // A panic in the solver is a finding: report it in the summary, without a backtrace.
        let default_hook = std::panic::take_hook();
        std::panic::set_hook(Box::new(|_| {}));
        let stepped = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| *sim.step()));
        std::panic::set_hook(default_hook);
        out.steps += 1;
        let s = match stepped {
            Ok(s) => s,
            Err(panic) => {
                let msg = dfsph_viewer::panic_message(panic.as_ref());
                out.violation = Some(Violation {
                    step: out.steps,
                    what: format!("the solver panicked: {msg}"),
                });
                break;
            }
        };
        out.clamped += s.clamped as u64;
        out.non_finite += s.non_finite as u64;
        if s.max_density_error_pct.is_finite() {
            out.max_density_error_pct = out.max_density_error_pct.max(s.max_density_error_pct);
        }
        if s.max_speed.is_finite() {
            out.max_speed = out.max_speed.max(s.max_speed);
        }
        out.max_depth_m = out.max_depth_m.max(deepest_water(&sim) as f64);
        let bodies = sim.rigid_body_count() > 0;
        let what = check_step(&s, plan.density_bound_pct, bodies)
            .or_else(|| check_state(&sim, expected, &mut out));
        if let Some(what) = what {
            out.violation = Some(Violation {
                step: out.steps,
                what,
            });
            break;
        }
    }
    out.n_fluid = sim.fluid_count();
    out.bodies = sim.rigid_body_count();
    let end = End::of(out.steps, &sim);
    out.fingerprint = end.fingerprint.clone();
    if let Some(rec) = recorder {
        rec.finish(&end)?;
    }
    Ok(out)
}

fn action_names(actions: &[Action]) -> String {
    let names: Vec<String> = actions
        .iter()
        .map(|a| match serde_json::to_value(a) {
            Ok(serde_json::Value::Object(o)) => o
                .get("action")
                .and_then(|v| v.as_str())
                .unwrap_or("?")
                .to_string(),
            _ => "?".into(),
        })
        .collect();
    names.join(", ")
}

/// The step's own report: non-finite values, clamps, density error. `bodies`: the
/// simulation has rigid bodies (a clamp may then have been out of one).
fn check_step(s: &StepStats, density_bound_pct: f64, bodies: bool) -> Option<String> {
    if s.non_finite > 0 {
        return Some(format!(
            "{} became non-finite (NaN or infinite) and reset by the solver",
            particles(s.non_finite)
        ));
    }
    for (name, v) in [
        ("max_speed", s.max_speed),
        ("kinetic_energy", s.kinetic_energy),
        ("max_density_error_pct", s.max_density_error_pct),
        ("avg_density_error_pct", s.avg_density_error_pct),
        ("divergence_error_pct", s.divergence_error_pct),
        ("dt", s.dt),
    ] {
        if !v.is_finite() {
            return Some(format!("non-finite statistic {name} = {v}"));
        }
    }
    if s.clamped > 0 {
        return Some(if bodies {
            format!(
                "{} clamped back into the tank or pushed out of a rigid body (a wall leaked)",
                particles(s.clamped)
            )
        } else {
            format!(
                "{} clamped back into the tank (the wall leaked)",
                particles(s.clamped)
            )
        });
    }
    if s.max_density_error_pct > density_bound_pct {
        return Some(format!(
            "max density error {:.2} % above the bound of {density_bound_pct} % ({} density \
             iterations)",
            s.max_density_error_pct, s.density_iterations
        ));
    }
    None
}

/// `1 particle`, `2 particles`.
fn particles(n: u32) -> String {
    match n {
        1 => "1 particle".into(),
        n => format!("{n} particles"),
    }
}

/// The particles themselves: finite, inside the tank, as many as poured and erased say, none
/// inside a rigid body; and the bodies: finite, inside the tank. Notes in `out` the most
/// particles seen inside the bodies.
fn check_state(sim: &Simulation, expected: usize, out: &mut StressOutcome) -> Option<String> {
    let n = sim.fluid_count();
    if n != expected {
        return Some(format!(
            "{n} fluid particles, but initial + poured − erased − under bodies = {expected}"
        ));
    }
    if n > sim.scene().max_particles {
        return Some(format!(
            "{n} fluid particles, more than the budget of {}",
            sim.scene().max_particles
        ));
    }
    // The centre line of the first wall layer, at least d/2 outside the interior (a hair more
    // for rounding).
    let (lo, hi) = sim.tank_containment();
    let slack = Vec2::splat(0.001 * sim.particle_radius());
    let (lo, hi) = (lo - slack, hi + slack);
    for ((x, v), id) in sim.positions().iter().zip(sim.velocities()).zip(sim.ids()) {
        if !(x.is_finite() && v.is_finite()) {
            return Some(format!(
                "particle {id} is not finite: position ({}, {}), velocity ({}, {})",
                x.x, x.y, v.x, v.y
            ));
        }
        if x.cmplt(lo).any() || x.cmpgt(hi).any() {
            return Some(format!(
                "particle {id} at ({:.4}, {:.4}) is outside the tank ({:.4}, {:.4})–({:.4}, {:.4})",
                x.x, x.y, lo.x, lo.y, hi.x, hi.y
            ));
        }
    }
    let bodies = sim.rigid_bodies();
    if bodies.is_empty() {
        return None;
    }
    // A body's outline may touch the tank's walls, and rapier lets contacts overlap a hair:
    // one spacing of slack.
    let d = sim.spacing();
    let (lo, hi) = sim.tank_interior();
    let (lo, hi) = (lo - Vec2::splat(d), hi + Vec2::splat(d));
    for (k, b) in bodies.iter().enumerate() {
        let finite = b.position.is_finite()
            && b.velocity.is_finite()
            && b.angle.is_finite()
            && b.angular_velocity.is_finite()
            && b.outline.iter().all(|p| p.is_finite());
        if !finite {
            return Some(format!(
                "rigid body {k} is not finite: position ({}, {}), angle {}, velocity ({}, {}), \
                 spin {}",
                b.position.x, b.position.y, b.angle, b.velocity.x, b.velocity.y, b.angular_velocity
            ));
        }
        if let Some(p) = b
            .outline
            .iter()
            .find(|p| p.cmplt(lo).any() || p.cmpgt(hi).any())
        {
            return Some(format!(
                "rigid body {k} reaches ({:.4}, {:.4}), outside the tank ({:.4}, {:.4})–({:.4}, \
                 {:.4}) by more than a spacing",
                p.x, p.y, lo.x, lo.y, hi.x, hi.y
            ));
        }
    }
    let inside = fluid_inside_bodies(sim.positions(), &bodies, 0.5 * d);
    out.max_inside_bodies = out.max_inside_bodies.max(inside.len());
    if let Some(&(i, k, depth)) = inside.first() {
        let x = sim.positions()[i];
        return Some(format!(
            "{} inside a rigid body (more than half a spacing within its outline): particle {} \
             at ({:.4}, {:.4}) is {:.4} m inside body {k}",
            particles(inside.len() as u32),
            sim.ids()[i],
            x.x,
            x.y,
            depth
        ));
    }
    None
}

/// The fluid particles whose centre lies more than `margin` (m) inside a rigid body's
/// outline, as (index, body, depth in m). Measured on the outlines the simulation reports
/// (convex, counter-clockwise; a circle as its 48-gon), not with the solver's own
/// containment, so that it checks it.
pub fn fluid_inside_bodies(
    positions: &[Vec2],
    bodies: &[RigidBodyState],
    margin: f32,
) -> Vec<(usize, usize, f32)> {
    let mut inside = Vec::new();
    for (k, b) in bodies.iter().enumerate() {
        let n = b.outline.len();
        if n < 3 {
            continue;
        }
        let (mut lo, mut hi) = (b.outline[0], b.outline[0]);
        for p in &b.outline {
            (lo, hi) = (lo.min(*p), hi.max(*p));
        }
        let (lo, hi) = (lo + Vec2::splat(margin), hi - Vec2::splat(margin));
        for (i, x) in positions.iter().enumerate() {
            if x.cmplt(lo).any() || x.cmpgt(hi).any() {
                continue;
            }
            // Depth inside a convex counter-clockwise polygon: the least distance to the left
            // of its edges.
            let depth = (0..n)
                .map(|j| {
                    let (a, c) = (b.outline[j], b.outline[(j + 1) % n]);
                    let e = c - a;
                    let len = e.length();
                    if len == 0.0 {
                        f32::INFINITY
                    } else {
                        e.perp_dot(*x - a) / len
                    }
                })
                .fold(f32::INFINITY, f32::min);
            if depth > margin {
                inside.push((i, k, depth));
            }
        }
    }
    inside
}

/// The deepest water in `sim`, m: the fluid's area per unit width in the fullest strip
/// across gravity (strips one kernel support, 2d, wide), which is the depth its particles
/// fill there when packed at rest. Issue 25 asks whether the pours build water metres deep;
/// a splash adds little to a strip, unlike the fluid's extent along gravity. 0 without
/// gravity.
pub fn deepest_water(sim: &Simulation) -> f32 {
    let g = sim.gravity();
    let positions = sim.positions();
    if g.length_squared() == 0.0 || positions.is_empty() {
        return 0.0;
    }
    let across = g.perp().normalize();
    let width = 2.0 * sim.spacing();
    let strip = |x: &Vec2| (x.dot(across) / width).floor() as i64;
    let first = positions.iter().map(strip).min().unwrap_or(0);
    let mut counts = Vec::new();
    for x in positions {
        let k = (strip(x) - first) as usize;
        if k >= counts.len() {
            counts.resize(k + 1, 0u32);
        }
        counts[k] += 1;
    }
    let fullest = counts.into_iter().max().unwrap_or(0);
    let area = sim.particle_mass() / sim.rest_density();
    fullest as f32 * area / width
}

/// SplitMix64: tiny, fast, and the same sequence on every platform and version.
struct Rng(u64);

impl Rng {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }

    fn rangef(&mut self, lo: f32, hi: f32) -> f32 {
        self.range(lo as f64, hi as f64) as f32
    }

    fn below(&mut self, n: u64) -> u64 {
        self.next_u64() % n
    }

    fn chance(&mut self, p: f64) -> bool {
        self.unit() < p
    }

    /// Uniform on a log scale in [lo, hi] (lo > 0).
    fn log_range(&mut self, lo: f64, hi: f64) -> f64 {
        (self.range(lo.ln(), hi.ln())).exp()
    }
}

/// A gesture that lasts several steps.
struct Held {
    at: Vec2,
    radius: f32,
    /// Push strength (m/s²) or pour velocity sign; unused for shaking.
    strength: f32,
    until: u64,
}

/// Makes the viewer's actions from a seed and the scene's (fixed) geometry.
struct Generator {
    rng: Rng,
    /// The initial tank interior and the area the pointer may reach around it.
    lo: Vec2,
    hi: Vec2,
    reach_lo: Vec2,
    reach_hi: Vec2,
    /// Lattice spacing of the scene, m.
    d: f32,
    shake_until: u64,
    shaking: bool,
    pointer: Option<Held>,
    pour: Option<Held>,
    /// The bodies' actions draw from a stream of their own, so that they leave every other
    /// action of a seed as it was before stress dropped bodies in.
    body_rng: Rng,
    /// Rigid bodies are dropped in ([`StressPlan::bodies`]).
    bodies: bool,
    /// The first bodies are due: at the start and after a reset.
    bodies_due: bool,
    /// The bodies dropped in since the start or the last reset: where (centre, m) and how far
    /// they reach from it (m).
    dropped: Vec<(Vec2, f32)>,
    /// A body is held by the pointer (if the grab found one) until this step.
    grab_until: Option<u64>,
}

impl Generator {
    fn new(seed: u64, scene: &Scene) -> Self {
        let lo = Vec2::new(scene.tank.min[0] as f32, scene.tank.min[1] as f32);
        let hi = Vec2::new(scene.tank.max[0] as f32, scene.tank.max[1] as f32);
        let margin = 0.1 * (hi - lo);
        Self {
            rng: Rng(seed ^ 0x5eed_d5f0_2d00_0000),
            lo,
            hi,
            reach_lo: lo - margin,
            reach_hi: hi + margin,
            d: scene.spacing() as f32,
            shake_until: 0,
            shaking: false,
            pointer: None,
            pour: None,
            body_rng: Rng(seed ^ 0xb0d1_e5b0_d1e5_0000),
            bodies: true,
            bodies_due: true,
            dropped: Vec::new(),
            grab_until: None,
        }
    }

    /// The rigid bodies' actions after `step` steps: first two to four bodies on the floor
    /// and in the air downstream of the water (boxes and circles of 100–8,000 kg/m³, from
    /// three spacings to 15 % of the tank across), which the surge carries into the far wall;
    /// then now and then another dropped from the upper half, and a body grabbed where one
    /// was dropped, dragged about anywhere the pointer reaches, and let go.
    fn body_actions(&mut self, step: u64, out: &mut Vec<Action>) {
        if self.bodies_due {
            self.bodies_due = false;
            for _ in 0..2 + self.body_rng.below(3) {
                if let Some(body) = self.body(true) {
                    out.push(Action::AddBody { body });
                }
            }
            return;
        }
        match self.grab_until {
            Some(until) if step >= until => {
                self.grab_until = None;
                out.push(Action::ReleaseBody);
            }
            Some(_) if step.is_multiple_of(4) => {
                let target = Vec2::new(
                    self.body_rng.rangef(self.reach_lo.x, self.reach_hi.x),
                    self.body_rng.rangef(self.reach_lo.y, self.reach_hi.y),
                );
                out.push(Action::DragBody { target });
            }
            Some(_) => {}
            None if !self.dropped.is_empty() && self.body_rng.chance(0.005) => {
                let k = self.body_rng.below(self.dropped.len() as u64) as usize;
                let (centre, reach) = self.dropped[k];
                let at = centre
                    + 0.5
                        * reach
                        * Vec2::new(
                            self.body_rng.rangef(-1.0, 1.0),
                            self.body_rng.rangef(-1.0, 1.0),
                        );
                self.grab_until = Some(step + 20 + self.body_rng.below(150));
                out.push(Action::GrabBody { at });
            }
            None => {}
        }
        if self.dropped.len() < MAX_DROPPED_BODIES && self.body_rng.chance(0.002) {
            if let Some(body) = self.body(false) {
                out.push(Action::AddBody { body });
            }
        }
    }

    /// A box or a circle clear of the bodies dropped so far: `downstream`, in the part of the
    /// tank right of its first 35 %, on the floor with odds 3 in 5; otherwise anywhere across
    /// the upper half. None when no place was found in a few tries.
    fn body(&mut self, downstream: bool) -> Option<BodySpec> {
        let size = self.hi - self.lo;
        let smallest = (3.15 * self.d as f64).max(0.05);
        let largest = (0.15 * size.min_element() as f64).max(1.5 * smallest);
        let rng = &mut self.body_rng;
        let density = rng.log_range(BODY_DENSITIES.0, BODY_DENSITIES.1);
        let mut spec = if rng.chance(0.4) {
            BodySpec::new_circle(0.5 * rng.range(smallest, largest), density, [0.0, 0.0])
        } else {
            let size = [rng.range(smallest, largest), rng.range(smallest, largest)];
            let mut b = BodySpec::new_box(size, density, [0.0, 0.0]);
            if rng.chance(0.3) {
                b.angle = rng.range(-std::f64::consts::PI, std::f64::consts::PI);
            }
            b
        };
        let half = spec.half_extent();
        let reach = half[0].hypot(half[1]) as f32;
        let gap = 0.01f64.max(self.d as f64);
        let (lo, hi) = (self.lo.as_dvec2(), self.hi.as_dvec2());
        for _ in 0..8 {
            let x_from = if downstream {
                lo.x + 0.35 * (hi.x - lo.x)
            } else {
                lo.x
            };
            let (x0, x1) = (x_from + half[0] + gap, hi.x - half[0] - gap);
            let on_floor = downstream && rng.chance(0.6);
            let (y0, y1) = if on_floor {
                (lo.y + half[1] + 0.25 * gap, lo.y + half[1] + 0.25 * gap)
            } else {
                (0.5 * (lo.y + hi.y) + half[1], hi.y - half[1] - gap)
            };
            if x0 > x1 || y0 > y1 {
                return None;
            }
            let at = [rng.range(x0, x1), rng.range(y0, y1)];
            let centre = Vec2::new(at[0] as f32, at[1] as f32);
            let clear = self
                .dropped
                .iter()
                .all(|(c, r)| (*c - centre).length() > r + reach + self.d);
            if clear {
                spec.position = at;
                self.dropped.push((centre, reach));
                return Some(spec);
            }
        }
        None
    }

    /// Anywhere the viewer's pointer could be: the tank and a margin around it.
    fn anywhere(&mut self) -> Vec2 {
        Vec2::new(
            self.rng.rangef(self.reach_lo.x, self.reach_hi.x),
            self.rng.rangef(self.reach_lo.y, self.reach_hi.y),
        )
    }

    /// Inside the tank, in its lower half with even odds (where the water is).
    fn in_tank(&mut self) -> Vec2 {
        let top = if self.rng.chance(0.5) {
            self.lo.y + 0.5 * (self.hi.y - self.lo.y)
        } else {
            self.hi.y
        };
        Vec2::new(
            self.rng.rangef(self.lo.x, self.hi.x),
            self.rng.rangef(self.lo.y, top),
        )
    }

    /// A tool radius within the viewer's limits (2d … 2 m), mostly small.
    fn tool_radius(&mut self) -> f32 {
        let max = (0.25 * (self.hi - self.lo).min_element()).clamp(2.0 * self.d, 2.0);
        self.rng.log_range(2.0 * self.d as f64, max as f64) as f32
    }

    /// The actions applied after `step` steps. `scene` is the simulation's current scene
    /// (parameter changes start from its values; they change only through these actions).
    fn actions(&mut self, step: u64, scene: &Scene, out: &mut Vec<Action>) {
        if self.bodies {
            self.body_actions(step, out);
        }

        // Shaking: hold left or right at full strength, switch or let go.
        if step >= self.shake_until && self.rng.chance(if self.shaking { 0.05 } else { 0.01 }) {
            let direction = match self.rng.below(5) {
                0 => 0.0,
                1 | 2 => -1.0,
                _ => 1.0,
            };
            self.shaking = direction != 0.0;
            self.shake_until = step + 20 + self.rng.below(300);
            out.push(Action::ShakeTank { direction });
        }

        // Push and pull: a drag, updated every few steps, then let go.
        match &mut self.pointer {
            Some(p) if step >= p.until => {
                self.pointer = None;
                out.push(Action::ReleasePointer);
            }
            Some(p) if step.is_multiple_of(4) => {
                let jitter = Vec2::new(self.rng.rangef(-0.05, 0.05), self.rng.rangef(-0.05, 0.05));
                p.at = (p.at + jitter).clamp(self.reach_lo, self.reach_hi);
                out.push(Action::Push {
                    at: p.at,
                    radius: p.radius,
                    strength: p.strength,
                });
            }
            Some(_) => {}
            None if self.rng.chance(0.015) => {
                let at = self.anywhere();
                let radius = self.tool_radius();
                let strength = if self.rng.chance(0.5) {
                    MAX_POINTER_ACCELERATION
                } else {
                    -MAX_POINTER_ACCELERATION
                };
                let until = step + 10 + self.rng.below(150);
                self.pointer = Some(Held {
                    at,
                    radius,
                    strength,
                    until,
                });
                out.push(Action::Push {
                    at,
                    radius,
                    strength,
                });
            }
            None => {}
        }

        // Pour: hold the pour key somewhere for a while (until the budget stops it); now
        // and then with the largest radius, to reach the budget quickly.
        match &self.pour {
            Some(p) if step >= p.until => self.pour = None,
            Some(p) if step.is_multiple_of(3) => out.push(Action::Emit {
                at: p.at,
                radius: p.radius,
                velocity: Vec2::new(0.0, -POUR_SPEED * p.strength),
            }),
            Some(_) => {}
            None if self.rng.chance(0.01) => {
                let at = self.anywhere();
                let radius = if self.rng.chance(0.2) {
                    1.0
                } else {
                    self.tool_radius()
                };
                let until = step + 10 + self.rng.below(200);
                self.pour = Some(Held {
                    at,
                    radius,
                    strength: 1.0,
                    until,
                });
            }
            None => {}
        }

        // One-off actions.
        let r = self.rng.unit();
        let p = 0.004;
        if r < p {
            // A wall through the water: 2–4 points in the tank.
            let n = 2 + self.rng.below(3) as usize;
            let polyline = (0..n).map(|_| self.in_tank()).collect();
            out.push(Action::AddWall { polyline });
        } else if r < 2.0 * p {
            let at = self.in_tank();
            let radius = self.tool_radius();
            out.push(Action::Erase { at, radius });
        } else if r < 3.0 * p {
            let magnitude = if self.rng.chance(0.5) {
                9.81
            } else {
                self.rng.rangef(0.0, 30.0)
            };
            let tilt = self.rng.rangef(-MAX_TILT_DEG, MAX_TILT_DEG).to_radians();
            let gravity = Vec2::new(magnitude * tilt.sin(), -magnitude * tilt.cos());
            out.push(Action::SetGravity { gravity });
        } else if r < 4.0 * p {
            let mut viscosity = scene.viscosity.clone();
            viscosity.xsph = self.rng.range(0.0, 0.5);
            viscosity.kinematic = self.maybe_zero_log(1e-6, 0.1);
            viscosity.boundary_kinematic = self.maybe_zero_log(1e-6, 0.1);
            out.push(Action::SetViscosity { viscosity });
        } else if r < 5.0 * p {
            let mut solver = scene.solver.clone();
            solver.density_tolerance_pct = self.rng.log_range(0.001, 0.5);
            solver.divergence_tolerance_pct = self.rng.log_range(0.01, 10.0);
            solver.min_iterations = self.rng.below(4) as u32;
            solver.max_iterations = 100 + self.rng.below(901) as u32;
            solver.warm_start = self.rng.chance(0.8);
            solver.divergence_solve = self.rng.chance(0.8);
            out.push(Action::SetSolver { solver });
        } else if r < 6.0 * p {
            let mut time_step = scene.time_step.clone();
            time_step.cfl = self.rng.range(0.1, 0.6);
            time_step.max = self.rng.log_range(2.5e-4, 2.5e-3);
            time_step.min = time_step.min.min(time_step.max);
            out.push(Action::SetTimeStep { time_step });
        } else if r < 6.3 * p {
            self.pointer = None;
            self.pour = None;
            self.shaking = false;
            self.bodies_due = true;
            self.dropped.clear();
            self.grab_until = None;
            out.push(Action::Reset { scene: None });
        }
    }

    /// 0 with odds 1 in 3, else log-uniform in [lo, hi].
    fn maybe_zero_log(&mut self, lo: f64, hi: f64) -> f64 {
        if self.rng.chance(1.0 / 3.0) {
            0.0
        } else {
            self.rng.log_range(lo, hi)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn coarse() -> Scene {
        let mut s = dfsph::scene::builtin("dam-break").unwrap();
        s.particle_radius = 0.05;
        budgeted(s)
    }

    #[test]
    fn the_action_sequence_depends_only_on_the_seed() {
        let scene = coarse();
        let sequence = |seed| {
            let mut g = Generator::new(seed, &scene);
            let mut all = Vec::new();
            for step in 0..3000 {
                let mut a = Vec::new();
                g.actions(step, &scene, &mut a);
                all.extend(a.into_iter().map(|a| (step, a)));
            }
            all
        };
        let a = sequence(1);
        assert_eq!(a, sequence(1));
        assert_ne!(a, sequence(2));
        let kinds: std::collections::BTreeSet<String> = a
            .iter()
            .map(|(_, a)| action_names(std::slice::from_ref(a)))
            .collect();
        for kind in [
            "shake_tank",
            "push",
            "release_pointer",
            "emit",
            "add_wall",
            "erase",
            "set_gravity",
            "set_viscosity",
            "set_solver",
            "set_time_step",
            "add_body",
            "grab_body",
            "drag_body",
            "release_body",
        ] {
            assert!(kinds.contains(kind), "{kind} never generated: {kinds:?}");
        }
        // The first actions drop bodies in, downstream of the water.
        assert!(matches!(a[0], (0, Action::AddBody { .. })), "{:?}", a[0]);
        // Every generated parameter change is one the simulation accepts.
        let mut sim = Simulation::new(&scene).unwrap();
        for (_, a) in &a {
            if matches!(
                a,
                Action::SetSolver { .. } | Action::SetViscosity { .. } | Action::SetTimeStep { .. }
            ) {
                assert_eq!(sim.apply(a).rejected, None, "{a:?}");
            }
            // Every body fits the scene, with its densities within stress's range.
            if let Action::AddBody { body } = a {
                body.validate("body", scene.spacing(), &scene.tank).unwrap();
                let rho = body.mean_density();
                assert!(
                    (BODY_DENSITIES.0..=BODY_DENSITIES.1).contains(&rho),
                    "{rho}"
                );
            }
        }
    }

    #[test]
    fn the_deepest_water_is_the_columns_height_whichever_way_gravity_points() {
        // The dam break's column is 2 m high and 1 m wide.
        let mut scene = coarse();
        scene.bodies.clear();
        let sim = Simulation::new(&scene).unwrap();
        let depth = deepest_water(&sim);
        assert!((depth - 2.0).abs() < 0.1, "{depth}");
        // With gravity along x the same column is 1 m deep.
        scene.gravity = [-9.81, 0.0];
        let depth = deepest_water(&Simulation::new(&scene).unwrap());
        assert!((depth - 1.0).abs() < 0.1, "{depth}");
        scene.gravity = [0.0, 0.0];
        assert_eq!(deepest_water(&Simulation::new(&scene).unwrap()), 0.0);
    }

    #[test]
    fn fluid_inside_a_body_is_found_by_its_outline() {
        let square = RigidBodyState {
            position: Vec2::new(1.0, 1.0),
            angle: 0.0,
            velocity: Vec2::ZERO,
            angular_velocity: 0.0,
            mass: 20.0,
            spec: BodySpec::new_box([0.2, 0.2], 500.0, [1.0, 1.0]),
            outline: vec![
                Vec2::new(0.9, 0.9),
                Vec2::new(1.1, 0.9),
                Vec2::new(1.1, 1.1),
                Vec2::new(0.9, 1.1),
            ],
        };
        let positions = [
            Vec2::new(1.0, 1.0),   // the centre: 0.1 m deep
            Vec2::new(1.08, 1.0),  // 0.02 m deep: within the margin
            Vec2::new(0.95, 1.04), // 0.05 m deep
            Vec2::new(1.2, 1.0),   // outside
        ];
        let inside = fluid_inside_bodies(&positions, std::slice::from_ref(&square), 0.025);
        let found: Vec<usize> = inside.iter().map(|(i, _, _)| *i).collect();
        assert_eq!(found, [0, 2]);
        assert!((inside[0].2 - 0.1).abs() < 1e-6);
    }

    #[test]
    fn budget_follows_the_viewer() {
        let s = coarse();
        assert_eq!(s.max_particles, 200 + 2000);
    }

    #[test]
    fn checks_catch_each_kind_of_violation() {
        let scene = coarse();
        let mut sim = Simulation::new(&scene).unwrap();
        let n = sim.fluid_count();
        let mut out = StressOutcome::default();
        assert_eq!(check_state(&sim, n, &mut out), None);
        assert!(check_state(&sim, n + 1, &mut out)
            .unwrap()
            .contains("poured"));
        let s = *sim.step();
        assert_eq!(check_step(&s, 5.0, false), None);
        let bad = StepStats { clamped: 2, ..s };
        assert!(check_step(&bad, 5.0, false).unwrap().contains("clamped"));
        assert!(check_step(&bad, 5.0, true)
            .unwrap()
            .contains("out of a rigid body"));
        let bad = StepStats { non_finite: 1, ..s };
        assert!(check_step(&bad, 5.0, false).unwrap().contains("non-finite"));
        let bad = StepStats {
            max_speed: f64::NAN,
            ..s
        };
        assert!(check_step(&bad, 5.0, false).unwrap().contains("max_speed"));
        let bad = StepStats {
            max_density_error_pct: 7.5,
            ..s
        };
        assert!(check_step(&bad, 5.0, false).unwrap().contains("7.50 %"));
    }

    #[test]
    fn a_short_run_records_what_it_did() {
        let scene = coarse();
        let plan = StressPlan {
            seed: 3,
            steps: 40,
            density_bound_pct: 1000.0,
            bodies: true,
        };
        let mut buf = Vec::new();
        let header = Header::new("test", rayon::current_num_threads(), &scene);
        let rec = Recorder::new(&mut buf, &header).unwrap();
        let out = run(&plan, Simulation::new(&scene).unwrap(), Some(rec)).unwrap();
        if out.violation.is_none() {
            assert_eq!(out.steps, 40);
        }
        let parsed =
            dfsph::recording::Recording::parse(std::str::from_utf8(&buf).unwrap()).unwrap();
        assert_eq!(parsed.entries.len(), out.actions);
        let end = parsed.end.unwrap();
        assert_eq!(
            (end.end, end.fingerprint),
            (out.steps, out.fingerprint.clone())
        );
        let line = out.summary("dam-break", &plan);
        assert!(
            line.starts_with("stress dam-break seed=3 steps=40: "),
            "{line}"
        );
        assert!(!line.contains('\n'));
    }

    /// Without bodies a seed drops none in, and its other actions are those it takes with
    /// them.
    #[test]
    fn no_bodies_drops_none_and_keeps_the_other_actions() {
        let scene = coarse();
        let recorded = |bodies: bool| {
            let plan = StressPlan {
                seed: 5,
                steps: 60,
                density_bound_pct: 1000.0,
                bodies,
            };
            let mut buf = Vec::new();
            let header = Header::new("test", rayon::current_num_threads(), &scene);
            let rec = Recorder::new(&mut buf, &header).unwrap();
            let out = run(&plan, Simulation::new(&scene).unwrap(), Some(rec)).unwrap();
            let parsed =
                dfsph::recording::Recording::parse(std::str::from_utf8(&buf).unwrap()).unwrap();
            let is_body = |a: &Action| {
                matches!(
                    a,
                    Action::AddBody { .. } | Action::Push { .. } | Action::ReleasePointer
                )
            };
            let others: Vec<Action> = parsed
                .entries
                .iter()
                .map(|e| e.action.clone())
                .filter(|a| !is_body(a))
                .collect();
            let dropped = parsed
                .entries
                .iter()
                .filter(|e| matches!(e.action, Action::AddBody { .. }))
                .count();
            (out.bodies, dropped, others)
        };
        let (with, dropped_with, others_with) = recorded(true);
        let (without, dropped_without, others_without) = recorded(false);
        assert!(with > 0 && dropped_with > 0, "the seed drops bodies in");
        assert_eq!((without, dropped_without), (0, 0));
        assert_eq!(others_with, others_without);
    }
}
