//! Scene description: the tank, the fluid blocks, obstacles and every solver parameter, read
//! from JSON with serde. Every key has a documented unit and default (`docs/scenes.md`);
//! unknown keys, wrong types and impossible values are rejected with an error that names the
//! key. Nothing here allocates particles: see [`crate::Simulation::new`].

use serde::{Deserialize, Serialize};

pub(crate) mod error;
mod probe;
pub(crate) mod shapes;

pub use crate::rigid::spec::{BodyJoint, BodyShape, BodySpec};
pub use error::SceneError;
pub(crate) use error::{finite, invalid, point};
pub use probe::Probe;
pub use shapes::{Obstacle, Point, Tank};

/// A complete scene. `Default` is the built-in dam break.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Scene {
    /// Short name, shown in the viewer and written to outputs.
    pub name: String,
    /// One line describing the scene.
    pub description: String,
    /// Particle radius r in metres. Lattice spacing d = 2r, kernel support h = 4r.
    pub particle_radius: f64,
    /// Rest density ρ0 in kg/m³.
    pub rest_density: f64,
    /// Gravity in m/s².
    pub gravity: Point,
    /// The tank: an axis-aligned box whose interior holds the fluid; its walls are boundary
    /// particles sampled just outside the interior.
    pub tank: Tank,
    /// Axis-aligned blocks of fluid, each filled with the lattice `packing` names.
    pub fluid: Vec<FluidBlock>,
    /// Fluid particles listed one by one (a state saved by the viewer), placed exactly as
    /// written, after those of the blocks. Left out of the JSON when empty.
    #[serde(skip_serializing_if = "ParticleList::is_empty")]
    pub particles: ParticleList,
    /// The lattice the fluid blocks and the tank's walls are sampled on: `square` (spacing d)
    /// or `hexagonal` (the same area d² per particle; the packing that holds still under
    /// pressure, see [`crate::packing`]).
    pub packing: Packing,
    /// Static obstacles inside the tank, sampled as boundary particles.
    pub obstacles: Vec<Obstacle>,
    /// Rigid bodies that float, sink and tumble, two-way coupled with the fluid
    /// ([`crate::rigid`]). Left out of the JSON when empty.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub bodies: Vec<BodySpec>,
    /// Pressure solver and its tolerances.
    pub solver: SolverParams,
    /// Adaptive (CFL) time stepping.
    pub time_step: TimeStepParams,
    /// Viscosity models.
    pub viscosity: ViscosityParams,
    /// Upper bound on the number of fluid particles, the scene's own and those poured in
    /// later; a scene whose blocks hold more is rejected.
    pub max_particles: usize,
    /// Pressure probes and water-level gauges, read every step into `probes.csv` by
    /// `dfsph2d run` (see [`crate::probes`]). Empty by default.
    pub probes: Vec<Probe>,
}

/// A rectangle of fluid. Particle centres lie at `min + d/2 + (i, j)·d` inside it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FluidBlock {
    /// Lower-left corner, metres.
    pub min: Point,
    /// Upper-right corner, metres.
    pub max: Point,
    /// Initial velocity in m/s.
    #[serde(default)]
    pub velocity: Point,
}

/// Fluid particles given one by one: `positions[i]` in metres, `velocities[i]` in m/s
/// (all at rest when `velocities` is left out).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ParticleList {
    /// Particle centres, metres.
    pub positions: Vec<Point>,
    /// Velocities, m/s: empty (all at rest) or one per position.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub velocities: Vec<Point>,
}

impl ParticleList {
    /// Whether no particle is listed.
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// Number of particles listed.
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// The velocity of particle `i` (zero when `velocities` is empty), m/s.
    pub fn velocity(&self, i: usize) -> Point {
        self.velocities.get(i).copied().unwrap_or([0.0, 0.0])
    }
}

/// The lattice of the initial fluid particles and of the tank's walls. The default is the
/// hexagonal one, for every scene: it is the lattice that water under pressure rests on (the
/// square one is not stable under deep pressure: a 300-layer column on it sloshed at 1.1 m/s
/// with the conjugate-gradient solve).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Packing {
    /// Particle centres at `min + d/2 + (i, j)·d` in each block; walls continue the lattice.
    Square,
    /// The hexagonal lattice of [`crate::packing`], anchored at the tank's lower-left corner;
    /// walls are its sites outside the tank's interior.
    Hexagonal,
}

/// How the DFSPH density solve solves its linear system.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PressureSolve {
    /// The paper's Jacobi iteration with Akinci boundary terms, warm-started with half of the
    /// previous step's pressure.
    Jacobi,
    /// Preconditioned conjugate gradients with the full previous pressure as the starting
    /// guess, a stopping rule that sees momentum, walls that mirror the fluid's pressure with
    /// its hydrostatic gradient, and a hydrostatic initial pressure
    /// (`pressure::conjugate_gradient`), deflated by a coarse space so that its reach does
    /// not grow with the depth of the water. Water at rest stays at rest. The default.
    ConjugateGradient,
}

/// Which pressure solver runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    /// Divergence-free SPH (Bender & Koschier 2015/2017).
    Dfsph,
    /// Weakly compressible SPH with the Tait equation of state (Becker & Teschner 2007).
    Wcsph,
}

/// Pressure solver parameters.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SolverParams {
    /// `dfsph` or `wcsph`.
    pub method: Method,
    /// DFSPH density solve: `jacobi` or `conjugate_gradient`.
    pub pressure_solve: PressureSolve,
    /// The smoothing kernel, and with it the support: `cubic_spline` (2d) or `wendland_c2`
    /// (3.5d). See [`crate::kernel::KernelShape`].
    pub kernel: crate::kernel::KernelShape,
    /// DFSPH density solve: stop when the *average* relative density error is at most this,
    /// in percent.
    pub density_tolerance_pct: f64,
    /// DFSPH divergence solve: stop when the *average* relative density change per step is
    /// at most this, in percent.
    pub divergence_tolerance_pct: f64,
    /// Minimum iterations of each DFSPH solve.
    pub min_iterations: u32,
    /// Maximum iterations of each DFSPH solve.
    pub max_iterations: u32,
    /// Run the divergence solve (DFSPH only).
    pub divergence_solve: bool,
    /// Start both solves from the previous step's stiffness values.
    pub warm_start: bool,
    /// WCSPH stiffness B in Pa of `p = B·((ρ/ρ0)^γ − 1)`.
    pub wcsph_stiffness: f64,
    /// WCSPH exponent γ.
    pub wcsph_exponent: f64,
}

/// CFL time step: `Δt = cfl · d / v_max`, clamped to `[min, max]` seconds.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TimeStepParams {
    /// CFL factor λ (dimensionless).
    pub cfl: f64,
    /// Smallest time step, seconds.
    pub min: f64,
    /// Largest time step, seconds. The default 1 ms is an accuracy cap: above it the resting
    /// hydrostatic tank at r = 1 cm moves faster than 1 % of sqrt(gH) (docs/scenes.md).
    pub max: f64,
}

/// Viscosity parameters.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ViscosityParams {
    /// XSPH velocity smoothing coefficient (dimensionless, 0 = off, typically 0.01–0.1).
    pub xsph: f64,
    /// Kinematic viscosity ν of the fluid in m²/s (water: 1e-6), Laplacian form of Morris
    /// et al. 1997 / Monaghan 2005.
    pub kinematic: f64,
    /// Kinematic viscosity in m²/s applied between fluid and walls (wall friction).
    pub boundary_kinematic: f64,
}

impl Default for Scene {
    fn default() -> Self {
        Self {
            name: "dam-break".into(),
            description: "1 m x 2 m water column collapsing in a 4 m x 3 m tank".into(),
            particle_radius: 0.01,
            rest_density: 1000.0,
            gravity: [0.0, -9.81],
            tank: Tank {
                min: [0.0, 0.0],
                max: [4.0, 3.0],
            },
            fluid: vec![FluidBlock {
                min: [0.0, 0.0],
                max: [1.0, 2.0],
                velocity: [0.0, 0.0],
            }],
            particles: ParticleList::default(),
            packing: Packing::Hexagonal,
            obstacles: Vec::new(),
            bodies: Vec::new(),
            solver: SolverParams::default(),
            time_step: TimeStepParams::default(),
            viscosity: ViscosityParams::default(),
            max_particles: 1_000_000,
            probes: Vec::new(),
        }
    }
}

impl Default for SolverParams {
    fn default() -> Self {
        Self {
            method: Method::Dfsph,
            pressure_solve: PressureSolve::ConjugateGradient,
            kernel: crate::kernel::KernelShape::CubicSpline,
            density_tolerance_pct: 0.05,
            divergence_tolerance_pct: 0.1,
            min_iterations: 2,
            max_iterations: 100,
            divergence_solve: true,
            warm_start: true,
            wcsph_stiffness: 5.0e5,
            wcsph_exponent: 7.0,
        }
    }
}

impl Default for TimeStepParams {
    fn default() -> Self {
        Self {
            cfl: 0.4,
            min: 1.0e-5,
            max: 1.0e-3,
        }
    }
}

impl Default for ViscosityParams {
    fn default() -> Self {
        Self {
            xsph: 0.01,
            kinematic: 0.0,
            boundary_kinematic: 0.0,
        }
    }
}

/// Range of `rest_density`, kg/m³: every liquid lies within it (liquid hydrogen 71, mercury
/// 13,534), and particle masses and pressures stay far from f32's limits.
pub const MIN_REST_DENSITY: f64 = 10.0;
/// See [`MIN_REST_DENSITY`].
pub const MAX_REST_DENSITY: f64 = 100_000.0;

/// Fastest initial speed of a fluid block, m/s. A 3 m dam break reaches about 8 m/s; the CFL
/// step is `λ·d/v`, so a block thrown at 1e30 m/s would take steps of 1e-32 s (clamped to the
/// minimum and leaking through every wall).
pub const MAX_INITIAL_SPEED: f64 = 100.0;

/// Largest kinematic viscosity, m²/s: 100 times honey. The explicit viscosity limits the step
/// to 0.125·d²/ν (12.5 µs at d = 1 cm and 1 m²/s), so much more would never finish.
pub const MAX_KINEMATIC_VISCOSITY: f64 = 1.0;

/// Most fluid blocks a scene may have. Checking that blocks do not overlap compares each with
/// the blocks beside it along x, which for blocks stacked in one column is every pair: 20,000
/// blocks took 2 s; at this bound it stays under half a second.
pub const MAX_FLUID_BLOCKS: usize = 10_000;

/// Most boundary particles the obstacles of a scene may take together (each is a few dozen
/// bytes plus its neighbour lists): a scene over this is rejected as asking for too much memory.
pub const MAX_OBSTACLE_PARTICLES: usize = 10_000_000;

/// Largest accepted `time_step.max`, s. Far above any stable step for a particle radius under
/// a metre; it keeps a number that is not a time step (1e308 in a fuzzed file, which is
/// infinite in single precision) out of the solver.
pub const MAX_TIME_STEP: f64 = 1.0;

/// Most lattice sites (tank area / d²) a scene may have: a tank a million particle spacings
/// across is a typo, and its grid would not fit in memory.
pub const MAX_LATTICE_SITES: f64 = 1.0e9;

/// Longest `name` a scene may have, in characters: it heads every summary line, the window's
/// title and the HUD (a 10 MB name was printed whole).
pub const MAX_NAME_CHARS: usize = 200;

/// Longest `description`, in characters: one line of text, shown in the viewer.
pub const MAX_DESCRIPTION_CHARS: usize = 2000;

/// Largest `viscosity.xsph`. XSPH and the Laplacian viscosity act in one explicit update, so
/// the viscosity's step bound is shortened by `1 − xsph` (`viscosity::Viscosity::max_time_step`);
/// at 1 no step would be stable, and 0.5 keeps half of it (the viewer's slider has the same
/// range).
pub const MAX_XSPH: f64 = 0.5;

/// Farthest a tank's corner may lie from the origin, in particle spacings d. The solver keeps
/// positions in single precision, which resolves a coordinate X to X·2⁻²⁴: at 4,096
/// spacings that is 2.4·10⁻⁴ d, and beyond it the rounding of the pair distances is felt in
/// the density (a 1 m tank of water at rest at d = 2 cm, 1 s: 0.006 m/s at the origin,
/// 0.016 m/s 5,000 spacings out, 0.10 m/s at 15,000, 0.49 m/s at 150,000, and 15 m/s at
/// 500,000, where the walls leaked).
pub const MAX_SPACINGS_FROM_ORIGIN: f64 = 4096.0;

/// Closest two listed fluid particles (`particles`) may be, in particle spacings d: closer
/// they are one particle written twice (the kernel's gradient vanishes between them, so the
/// pressure cannot push them apart). Water in motion does bring pairs far closer than d: a
/// dam break at d = 4 cm had two particles 0.24·d apart within 5 s.
pub const MIN_PARTICLE_DISTANCE: f64 = 1.0e-3;

/// Most other listed particles one may have closer than a spacing d. A lattice has none,
/// water in motion a few; more are particles piled on top of each other, which make the
/// neighbour lists grow quadratically (see `check_block_overlaps`).
pub const MAX_CLOSE_PARTICLES: usize = 12;

/// Water's kinematic viscosity near 20 °C, m²/s.
pub const WATER_KINEMATIC_VISCOSITY: f64 = 1.0e-6;

/// A kinematic viscosity this many times water's gets a note ([`Scene::viscosity_note`]).
pub const THICK_VISCOSITY_FACTOR: f64 = 100.0;

impl Scene {
    /// A note for a kinematic viscosity (`viscosity.kinematic` or `boundary_kinematic`) over
    /// [`THICK_VISCOSITY_FACTOR`] times water's: legal (honey, a deliberately damped run),
    /// but often water's *dynamic* viscosity, 0.001 Pa·s, typed as the kinematic one in m²/s,
    /// which makes the water syrup-thick and the run slow (the viscous step bound). `None`
    /// otherwise.
    pub fn viscosity_note(&self) -> Option<String> {
        let v = &self.viscosity;
        let (key, value) = [
            ("kinematic", v.kinematic),
            ("boundary_kinematic", v.boundary_kinematic),
        ]
        .into_iter()
        .max_by(|a, b| a.1.total_cmp(&b.1))?;
        let times = value / WATER_KINEMATIC_VISCOSITY;
        (times > THICK_VISCOSITY_FACTOR).then(|| {
            format!(
                "note: viscosity.{key} is {value} m²/s, {times:.0} times water's \
                 ({WATER_KINEMATIC_VISCOSITY:e} m²/s): the water flows like syrup and the \
                 steps are short; water's dynamic viscosity is 0.001 Pa·s, and kinematic = \
                 dynamic / density"
            )
        })
    }

    /// Parse and validate a scene from JSON text. Keys that are absent take their defaults,
    /// the same for every scene whatever its shape (`Scene::default`, `SolverParams::default`).
    pub fn from_json(text: &str) -> Result<Self, SceneError> {
        if text.trim().is_empty() {
            return Err(SceneError::Parse(
                "the scene is empty: expected a JSON object such as {\"particle_radius\": 0.01}"
                    .into(),
            ));
        }
        if !text.trim_start().starts_with('{') {
            let value: serde_json::Value = serde_json::from_str(text)
                .map_err(|e| SceneError::Parse(format!("not valid JSON: {e}")))?;
            let kind = match value {
                serde_json::Value::Array(_) => "an array",
                serde_json::Value::String(_) => "a string",
                serde_json::Value::Number(_) => "a number",
                serde_json::Value::Bool(_) => "a boolean",
                _ => "null",
            };
            return Err(SceneError::Parse(format!(
                "the scene must be a JSON object {{...}}, got {kind}"
            )));
        }
        let de = &mut serde_json::Deserializer::from_str(text);
        let scene: Scene = serde_path_to_error::deserialize(&mut *de).map_err(|e| {
            let path = e.path().to_string();
            let inner = e.into_inner();
            if path.is_empty() || path == "." || path == "?" {
                SceneError::Parse(inner.to_string())
            } else {
                SceneError::Parse(format!("`{path}`: {inner}"))
            }
        })?;
        de.end().map_err(|e| {
            SceneError::Parse(format!("unexpected text after the scene object: {e}"))
        })?;
        scene.validate()?;
        Ok(scene)
    }

    /// The resolved scene as pretty JSON: every key present, defaults filled in.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("a scene always serialises")
    }

    /// The particle radii [`Self::validate`] accepts for this tank, m: small enough that
    /// the tank fits two particles across, large enough that it holds at most
    /// [`MAX_LATTICE_SITES`] and lies within [`MAX_SPACINGS_FROM_ORIGIN`] of the origin.
    /// (`max_particles` bounds it too, through the fluid's count.)
    pub fn particle_radius_limits(&self) -> (f64, f64) {
        let w = self.tank.max[0] - self.tank.min[0];
        let h = self.tank.max[1] - self.tank.min[1];
        let far = self.tank.farthest_coordinate().0;
        let smallest = (w * h / MAX_LATTICE_SITES)
            .sqrt()
            .max(far / MAX_SPACINGS_FROM_ORIGIN);
        (0.5 * smallest, 0.25 * w.min(h))
    }

    /// The corner the hexagonal lattice of the fluid blocks, the tank's walls and the boxes
    /// is anchored at (the tank's lower-left, m); `None` on the square packing.
    pub fn hexagonal_anchor(&self) -> Option<[f64; 2]> {
        (self.packing == Packing::Hexagonal).then_some(self.tank.min)
    }

    /// Lattice spacing d = 2r, metres.
    pub fn spacing(&self) -> f64 {
        2.0 * self.particle_radius
    }

    /// Kernel support h, metres: the kernel's support in spacings times d (4r for the cubic
    /// spline, 7r for Wendland C2).
    pub fn support(&self) -> f64 {
        self.solver.kernel.support_in_spacings() * self.spacing()
    }

    /// The scene's smoothing kernel.
    pub fn kernel(&self) -> crate::kernel::Kernel {
        crate::kernel::Kernel::new(self.solver.kernel, self.support() as f32)
    }

    /// Layers of every wall the scene's kernel needs ([`crate::boundary::wall_layers`]).
    pub(crate) fn wall_layers(&self) -> usize {
        crate::boundary::wall_layers(&self.kernel(), self.spacing() as f32)
    }

    /// Number of lattice sites along one side of a fluid block of this length.
    pub(crate) fn lattice_count(&self, length: f64) -> usize {
        // A block that is an integer number of spacings long gets exactly that many
        // particles; the small epsilon keeps 1.0 / 0.02 from rounding down to 49.
        ((length / self.spacing()) + 1.0e-6).floor().max(0.0) as usize
    }

    /// Number of lattice sites in the scene's fluid blocks plus the particles listed in
    /// `particles`: the number of fluid particles without obstacles, an upper bound with them
    /// (block sites an obstacle covers stay empty; see `Simulation::new`).
    pub fn fluid_particle_count(&self) -> usize {
        let blocks: usize = match self.packing {
            Packing::Square => self
                .fluid
                .iter()
                .map(|b| {
                    self.lattice_count(b.max[0] - b.min[0])
                        * self.lattice_count(b.max[1] - b.min[1])
                })
                .sum(),
            // Each site once, where blocks share an edge or overlap.
            Packing::Hexagonal => crate::packing::rows_of_boxes(
                self.tank.min,
                &self.fluid_boxes(),
                self.spacing(),
                self.tank.edge_tolerance(),
            )
            .iter()
            .map(|(_, r)| r.count)
            .sum(),
        };
        self.particles.len() + blocks
    }

    /// The fluid blocks' corners, `(min, max)`, m.
    pub fn fluid_boxes(&self) -> Vec<(Point, Point)> {
        self.fluid.iter().map(|b| (b.min, b.max)).collect()
    }

    /// Bodies may touch each other and the obstacles but not overlap them: a quarter spacing
    /// of slack, into each other, into a box obstacle, or into the balls of radius d/2 around
    /// an obstacle's wall particles that bodies collide with (so nearer than d/4 to one of
    /// them). Rapier would push such a body out, through whatever lies beyond (the floor).
    /// (`Action::AddBody` asks a new body to clear the balls.)
    fn check_body_overlaps(&self) -> Result<(), SceneError> {
        if self.bodies.is_empty() {
            return Ok(());
        }
        let d = self.spacing() as f32;
        let placed: Vec<_> = self
            .bodies
            .iter()
            .map(|b| crate::rigid::outline::placed(b, d))
            .collect();
        let key = |i: usize| format!("bodies[{i}].position");
        for i in 0..self.bodies.len() {
            for j in 0..i {
                if placed[i].overlaps(&placed[j], d) {
                    return Err(invalid(
                        key(i),
                        format!("the body overlaps bodies[{j}]; bodies may touch but not overlap"),
                    ));
                }
            }
        }
        // On the hexagonal lattice a box's faces stand up to half a lattice step inside the
        // box (`BoundarySamples::add_hexagonal_rect`), and a body resting on one stands there
        // too.
        let face = match self.packing {
            Packing::Hexagonal => 0.5 * crate::packing::ROW_SPACING * self.spacing(),
            Packing::Square => 0.0,
        };
        for (k, obstacle) in self.obstacles.iter().enumerate() {
            let mut walls = crate::boundary::BoundarySamples::new(self.wall_layers());
            walls.add_obstacle(obstacle, d, self.hexagonal_anchor(), 1);
            for (i, body) in placed.iter().enumerate() {
                let in_box = match obstacle {
                    Obstacle::Rect { min, max } => body.outline.iter().any(|p| {
                        let (p, q) = (p.as_dvec2(), 0.25 * self.spacing() + face);
                        p.x > min[0] + q && p.x < max[0] - q && p.y > min[1] + q && p.y < max[1] - q
                    }),
                    _ => false,
                };
                if in_box
                    || walls
                        .positions
                        .iter()
                        .any(|&p| (body.distance)(p) < 0.25 * d)
                {
                    return Err(invalid(
                        key(i),
                        format!(
                            "the body overlaps obstacles[{k}] by more than a quarter particle \
                             spacing; bodies may touch obstacles but not overlap them"
                        ),
                    ));
                }
            }
        }
        Ok(())
    }

    /// Fluid blocks may touch, and overlap by less than one particle spacing d along either
    /// axis (their particles then start compressed and are pushed apart, see
    /// `SolverSettings::max_correction_speed`). A deeper overlap puts particles on top of each
    /// other (ten copies of one block made neighbour lists quadratic: 0.5 steps/s at 5,000
    /// particles), so it is rejected, naming both blocks. A sweep along x compares each block
    /// only with those still open there.
    fn check_block_overlaps(&self) -> Result<(), SceneError> {
        let d = self.spacing();
        let mut order: Vec<usize> = (0..self.fluid.len()).collect();
        order.sort_by(|&a, &b| self.fluid[a].min[0].total_cmp(&self.fluid[b].min[0]));
        let mut open: Vec<usize> = Vec::new();
        for &j in &order {
            let b = &self.fluid[j];
            open.retain(|&i| self.fluid[i].max[0] - b.min[0] >= d);
            for &i in &open {
                let a = &self.fluid[i];
                let dx = a.max[0].min(b.max[0]) - a.min[0].max(b.min[0]);
                let dy = a.max[1].min(b.max[1]) - a.min[1].max(b.min[1]);
                if dx >= d && dy >= d {
                    let (first, second) = (i.min(j), i.max(j));
                    return Err(invalid(
                        format!("fluid[{second}]"),
                        format!(
                            "overlaps fluid[{first}] by {dx:.3} m x {dy:.3} m; blocks may overlap by \
                             less than one particle spacing ({d} m), deeper their particles \
                             would sit on top of each other"
                        ),
                    ));
                }
            }
            open.push(j);
        }
        Ok(())
    }

    /// The listed fluid particles (`particles`): finite, inside the tank (give or take half a
    /// spacing: water pressed against a wall sits between its interior and the centre line
    /// of its first layer), with one velocity each (or none), no faster than a fluid block may
    /// start, no two closer than [`MIN_PARTICLE_DISTANCE`]·d, none with more than
    /// [`MAX_CLOSE_PARTICLES`] others closer than d, and none inside a fluid block's lattice
    /// (there they would sit on its particles). Errors name the particle's index.
    fn check_particles(&self) -> Result<(), SceneError> {
        let list = &self.particles;
        if list.is_empty() {
            if !list.velocities.is_empty() {
                return Err(invalid(
                    "particles.velocities",
                    format!(
                        "{} velocities for no positions: `particles.positions` is empty",
                        list.velocities.len()
                    ),
                ));
            }
            return Ok(());
        }
        if !list.velocities.is_empty() && list.velocities.len() != list.positions.len() {
            return Err(invalid(
                "particles.velocities",
                format!(
                    "{} velocities for {} positions: give one per position, or leave the key \
                     out for water at rest",
                    list.velocities.len(),
                    list.positions.len()
                ),
            ));
        }
        let d = self.spacing();
        let slack = 0.5 * d + self.tank.edge_tolerance();
        for (i, p) in list.positions.iter().enumerate() {
            let key = format!("particles.positions[{i}]");
            point(&key, *p)?;
            for (axis, &v) in p.iter().enumerate() {
                let (lo, hi) = (self.tank.min[axis], self.tank.max[axis]);
                if v < lo - slack || v > hi + slack {
                    return Err(invalid(
                        format!("{key}[{axis}]"),
                        format!(
                            "{v} lies outside the tank ({lo} to {hi}, give or take half a \
                             particle spacing, {} m)",
                            0.5 * d
                        ),
                    ));
                }
            }
        }
        for (i, v) in list.velocities.iter().enumerate() {
            let key = format!("particles.velocities[{i}]");
            point(&key, *v)?;
            let speed = v[0].hypot(v[1]);
            if speed > MAX_INITIAL_SPEED {
                return Err(invalid(
                    key,
                    format!("{speed} m/s is faster than {MAX_INITIAL_SPEED} m/s"),
                ));
            }
        }
        if list.len() > self.max_particles {
            return Err(invalid(
                "particles.positions",
                format!(
                    "{} particles, more than max_particles = {}",
                    list.len(),
                    self.max_particles
                ),
            ));
        }

        // Cells of side d: a pair closer than d lies in the same or a neighbouring cell. The
        // positions are inside the tank, whose cell count the radius check bounds.
        let cell = |p: Point| {
            (
                ((p[0] - self.tank.min[0]) / d).floor() as i64,
                ((p[1] - self.tank.min[1]) / d).floor() as i64,
            )
        };
        let mut cells: std::collections::HashMap<(i64, i64), Vec<usize>> =
            std::collections::HashMap::with_capacity(list.len());
        for (i, &p) in list.positions.iter().enumerate() {
            cells.entry(cell(p)).or_default().push(i);
        }
        let closest = MIN_PARTICLE_DISTANCE * d;
        for (j, &p) in list.positions.iter().enumerate() {
            let (cx, cy) = cell(p);
            let mut close = 0;
            for dy in -1..=1 {
                for dx in -1..=1 {
                    let Some(others) = cells.get(&(cx + dx, cy + dy)) else {
                        continue;
                    };
                    for &i in others.iter().filter(|&&i| i != j) {
                        let q = list.positions[i];
                        let r = (p[0] - q[0]).hypot(p[1] - q[1]);
                        close += usize::from(r < d);
                        if i < j && r < closest {
                            return Err(invalid(
                                format!("particles.positions[{j}]"),
                                format!(
                                    "lies {r:.3e} m from particles.positions[{i}], closer than \
                                     {MIN_PARTICLE_DISTANCE} particle spacings ({closest} m): \
                                     one particle written twice"
                                ),
                            ));
                        }
                    }
                }
            }
            if close > MAX_CLOSE_PARTICLES {
                return Err(invalid(
                    format!("particles.positions[{j}]"),
                    format!(
                        "{close} other particles lie closer than one spacing ({d} m), more than \
                         {MAX_CLOSE_PARTICLES}: the particles are piled on top of each other"
                    ),
                ));
            }
        }

        // A listed particle deeper than half a spacing inside a block sits among the block's
        // own particles. Each block looks at the particles of the cells it covers, or at every
        // particle when that is fewer.
        for (k, b) in self.fluid.iter().enumerate() {
            let (lo, hi) = (
                [b.min[0] + 0.5 * d, b.min[1] + 0.5 * d],
                [b.max[0] - 0.5 * d, b.max[1] - 0.5 * d],
            );
            if hi[0] <= lo[0] || hi[1] <= lo[1] {
                continue;
            }
            let inside = |p: &Point| p[0] > lo[0] && p[0] < hi[0] && p[1] > lo[1] && p[1] < hi[1];
            let (c0, c1) = (cell(lo), cell(hi));
            let covered = ((c1.0 - c0.0 + 1) as f64) * ((c1.1 - c0.1 + 1) as f64);
            let found = if covered < list.len() as f64 {
                (c0.1..=c1.1)
                    .flat_map(|cy| (c0.0..=c1.0).map(move |cx| (cx, cy)))
                    .filter_map(|c| cells.get(&c))
                    .flatten()
                    .copied()
                    .filter(|&i| inside(&list.positions[i]))
                    .min()
            } else {
                list.positions.iter().position(inside)
            };
            if let Some(i) = found {
                return Err(invalid(
                    format!("particles.positions[{i}]"),
                    format!(
                        "{:?} lies inside fluid[{k}], whose lattice already fills it",
                        list.positions[i]
                    ),
                ));
            }
        }
        Ok(())
    }

    /// Check every value for being finite and physically possible. Called by
    /// [`Scene::from_json`]; call it yourself on scenes built in code.
    pub fn validate(&self) -> Result<(), SceneError> {
        let positive = |key: &str, v: f64| -> Result<(), SceneError> {
            finite(key, v)?;
            if v > 0.0 {
                Ok(())
            } else {
                Err(invalid(key, format!("must be greater than 0, got {v}")))
            }
        };
        for (key, text, most) in [
            ("name", &self.name, MAX_NAME_CHARS),
            ("description", &self.description, MAX_DESCRIPTION_CHARS),
        ] {
            let chars = text.chars().count();
            if chars > most {
                return Err(invalid(
                    key,
                    format!("{chars} characters is longer than the {most} it may have"),
                ));
            }
        }
        positive("particle_radius", self.particle_radius)?;
        positive("rest_density", self.rest_density)?;
        if !(MIN_REST_DENSITY..=MAX_REST_DENSITY).contains(&self.rest_density) {
            return Err(invalid(
                "rest_density",
                format!(
                    "{} kg/m³ is outside {MIN_REST_DENSITY}–{MAX_REST_DENSITY} kg/m³ (every \
                     liquid lies within it: liquid hydrogen 71, mercury 13,534)",
                    self.rest_density
                ),
            ));
        }
        point("gravity", self.gravity)?;
        if self.gravity[0].hypot(self.gravity[1]) > 1000.0 {
            return Err(invalid(
                "gravity",
                "must be at most 1000 m/s² in magnitude (about 100 g)",
            ));
        }
        point("tank.min", self.tank.min)?;
        point("tank.max", self.tank.max)?;
        for axis in 0..2 {
            if self.tank.max[axis] <= self.tank.min[axis] {
                return Err(invalid(
                    format!("tank.max[{axis}]"),
                    format!(
                        "must be greater than tank.min[{axis}] ({} <= {})",
                        self.tank.max[axis], self.tank.min[axis]
                    ),
                ));
            }
        }
        let d = self.spacing();
        let tank_size = [
            self.tank.max[0] - self.tank.min[0],
            self.tank.max[1] - self.tank.min[1],
        ];
        if tank_size[0] < 2.0 * d || tank_size[1] < 2.0 * d {
            return Err(invalid(
                "particle_radius",
                format!(
                    "{} m is too large for a tank of {} m x {} m (it must fit at least two particles across)",
                    self.particle_radius, tank_size[0], tank_size[1]
                ),
            ));
        }
        // Grid and memory safety: a tank a million particle spacings across is a typo.
        let cells = (tank_size[0] / d) * (tank_size[1] / d);
        if cells > MAX_LATTICE_SITES {
            return Err(invalid(
                "particle_radius",
                format!(
                    "{} m is too small for a tank of {} m x {} m ({cells:.2e} lattice sites)",
                    self.particle_radius, tank_size[0], tank_size[1]
                ),
            ));
        }

        let (far, far_key) = self.tank.farthest_coordinate();
        if far / d > MAX_SPACINGS_FROM_ORIGIN {
            return Err(invalid(
                far_key,
                format!(
                    "the tank reaches {far} m from the origin, {:.0} particle spacings: \
                     positions are kept in single precision, which resolves {:.1e} of a \
                     spacing there; place the tank within {MAX_SPACINGS_FROM_ORIGIN} spacings \
                     ({} m at this particle_radius) of the origin, or use larger particles \
                     (every length in a scene is in metres)",
                    far / d,
                    far * f64::powi(2.0, -24) / d,
                    MAX_SPACINGS_FROM_ORIGIN * d
                ),
            ));
        }
        if self.fluid.is_empty() && self.particles.is_empty() {
            return Err(invalid(
                "fluid",
                "at least one fluid block (or a `particles` list) is needed",
            ));
        }
        if self.fluid.len() > MAX_FLUID_BLOCKS {
            return Err(invalid(
                "fluid",
                format!(
                    "{} blocks is more than the {MAX_FLUID_BLOCKS} a scene may have (describe \
                     the water as a few rectangles, not particle by particle)",
                    self.fluid.len()
                ),
            ));
        }
        let eps = self.tank.edge_tolerance();
        for (i, b) in self.fluid.iter().enumerate() {
            let key = format!("fluid[{i}]");
            point(&format!("{key}.min"), b.min)?;
            point(&format!("{key}.max"), b.max)?;
            point(&format!("{key}.velocity"), b.velocity)?;
            let speed = b.velocity[0].hypot(b.velocity[1]);
            if speed > MAX_INITIAL_SPEED {
                return Err(invalid(
                    format!("{key}.velocity"),
                    format!(
                        "{speed} m/s is faster than {MAX_INITIAL_SPEED} m/s (a 3 m dam break \
                         reaches 8 m/s; the CFL step shrinks with the speed)"
                    ),
                ));
            }
            for axis in 0..2 {
                if b.max[axis] <= b.min[axis] {
                    return Err(invalid(
                        format!("{key}.max[{axis}]"),
                        format!(
                            "must be greater than {key}.min[{axis}] ({} <= {})",
                            b.max[axis], b.min[axis]
                        ),
                    ));
                }
                if b.min[axis] < self.tank.min[axis] - eps {
                    return Err(invalid(
                        format!("{key}.min[{axis}]"),
                        format!(
                            "{} lies outside the tank (tank.min[{axis}] = {})",
                            b.min[axis], self.tank.min[axis]
                        ),
                    ));
                }
                if b.max[axis] > self.tank.max[axis] + eps {
                    return Err(invalid(
                        format!("{key}.max[{axis}]"),
                        format!(
                            "{} lies outside the tank (tank.max[{axis}] = {})",
                            b.max[axis], self.tank.max[axis]
                        ),
                    ));
                }
                if b.max[axis] - b.min[axis] < d * (1.0 - 1.0e-6) {
                    return Err(invalid(
                        format!("{key}.max[{axis}]"),
                        format!(
                            "the block is {} m wide, less than one particle spacing ({d} m)",
                            b.max[axis] - b.min[axis]
                        ),
                    ));
                }
            }
        }
        self.check_block_overlaps()?;
        self.check_particles()?;
        if self.bodies.len() > crate::rigid::spec::MAX_BODIES {
            return Err(invalid(
                "bodies",
                format!(
                    "{} bodies, more than the {} a scene may have",
                    self.bodies.len(),
                    crate::rigid::spec::MAX_BODIES
                ),
            ));
        }
        for (i, b) in self.bodies.iter().enumerate() {
            b.validate(&format!("bodies[{i}]"), d, &self.tank)?;
        }
        self.check_body_overlaps()?;
        if !self.bodies.is_empty() && self.solver.method == Method::Wcsph {
            return Err(invalid(
                "solver.method",
                "rigid bodies are coupled through the DFSPH solves; the WCSPH baseline has none \
                 (use \"dfsph\", or leave `bodies` out)",
            ));
        }
        for (i, o) in self.obstacles.iter().enumerate() {
            let key = format!("obstacles[{i}]");
            match o {
                Obstacle::Rect { min, max } => {
                    point(&format!("{key}.min"), *min)?;
                    point(&format!("{key}.max"), *max)?;
                    for axis in 0..2 {
                        if max[axis] <= min[axis] {
                            return Err(invalid(
                                format!("{key}.max[{axis}]"),
                                format!("must be greater than {key}.min[{axis}]"),
                            ));
                        }
                    }
                }
                Obstacle::Polyline { points } => {
                    if points.len() < 2 {
                        return Err(invalid(
                            format!("{key}.points"),
                            format!("a polyline needs at least 2 points, got {}", points.len()),
                        ));
                    }
                    for (k, p) in points.iter().enumerate() {
                        point(&format!("{key}.points[{k}]"), *p)?;
                    }
                }
                Obstacle::Particles { positions } => {
                    if positions.is_empty() {
                        return Err(invalid(
                            format!("{key}.positions"),
                            "a wall of particles needs at least one particle",
                        ));
                    }
                    for (k, p) in positions.iter().enumerate() {
                        point(&format!("{key}.positions[{k}]"), *p)?;
                    }
                }
            }
        }

        // Obstacles beyond the tank never meet the fluid, and far-away coordinates (typos,
        // fuzzed files) would be sampled with billions of boundary particles: every corner
        // and point must lie within one kernel support h of the tank, and all obstacles
        // together within the boundary-particle budget.
        let margin = self.support();
        let mut boundary_estimate = 0.0;
        for (i, o) in self.obstacles.iter().enumerate() {
            let key = format!("obstacles[{i}]");
            let (points, estimate): (Vec<(String, Point)>, f64) = match o {
                Obstacle::Rect { min, max } => (
                    vec![(format!("{key}.min"), *min), (format!("{key}.max"), *max)],
                    4.0 * ((max[0] - min[0]) + (max[1] - min[1])) / d,
                ),
                Obstacle::Polyline { points } => (
                    points
                        .iter()
                        .enumerate()
                        .map(|(k, p)| (format!("{key}.points[{k}]"), *p))
                        .collect(),
                    2.0 * points
                        .windows(2)
                        .map(|w| (w[1][0] - w[0][0]).hypot(w[1][1] - w[0][1]) / d + 1.0)
                        .sum::<f64>(),
                ),
                Obstacle::Particles { positions } => (
                    positions
                        .iter()
                        .enumerate()
                        .map(|(k, p)| (format!("{key}.positions[{k}]"), *p))
                        .collect(),
                    positions.len() as f64,
                ),
            };
            for (k, p) in &points {
                for (axis, &v) in p.iter().enumerate() {
                    let (lo, hi) = (self.tank.min[axis], self.tank.max[axis]);
                    if v < lo - margin || v > hi + margin {
                        return Err(invalid(
                            format!("{k}[{axis}]"),
                            format!(
                                "{v} lies outside the tank ({lo} to {hi}, give or take the \
                                 kernel support h = {margin} m)"
                            ),
                        ));
                    }
                }
            }
            boundary_estimate += estimate;
        }
        if boundary_estimate > MAX_OBSTACLE_PARTICLES as f64 {
            return Err(invalid(
                "obstacles",
                format!(
                    "the obstacles would take about {boundary_estimate:.3e} boundary particles, \
                     more than the budget of {MAX_OBSTACLE_PARTICLES}"
                ),
            ));
        }

        let s = &self.solver;
        positive("solver.density_tolerance_pct", s.density_tolerance_pct)?;
        positive(
            "solver.divergence_tolerance_pct",
            s.divergence_tolerance_pct,
        )?;
        if s.max_iterations == 0 {
            return Err(invalid("solver.max_iterations", "must be at least 1"));
        }
        if s.min_iterations > s.max_iterations {
            return Err(invalid(
                "solver.min_iterations",
                format!(
                    "{} is greater than solver.max_iterations ({})",
                    s.min_iterations, s.max_iterations
                ),
            ));
        }
        if s.max_iterations > 10_000 {
            return Err(invalid(
                "solver.max_iterations",
                format!("{} is unreasonably large (at most 10000)", s.max_iterations),
            ));
        }
        positive("solver.wcsph_stiffness", s.wcsph_stiffness)?;
        positive("solver.wcsph_exponent", s.wcsph_exponent)?;

        let t = &self.time_step;
        positive("time_step.cfl", t.cfl)?;
        if t.cfl > 1.0 {
            return Err(invalid(
                "time_step.cfl",
                format!("{} exceeds 1: the CFL condition would be violated", t.cfl),
            ));
        }
        positive("time_step.min", t.min)?;
        positive("time_step.max", t.max)?;
        if t.max > MAX_TIME_STEP {
            return Err(invalid(
                "time_step.max",
                format!(
                    "{} s is unreasonably large (at most {MAX_TIME_STEP} s)",
                    t.max
                ),
            ));
        }
        if t.min > t.max {
            return Err(invalid(
                "time_step.min",
                format!("{} is greater than time_step.max ({})", t.min, t.max),
            ));
        }
        // The first step starts from the blocks' own velocities under gravity alone; a
        // minimum above the displacement bound there could not be honoured even once (the
        // bound wins at run time, see `simulation::step_displacement_bound`).
        let initial_speed = self
            .fluid
            .iter()
            .map(|b| b.velocity)
            .chain(self.particles.velocities.iter().copied())
            .map(|v| v[0].hypot(v[1]))
            .fold(0.0, f64::max);
        let g = self.gravity[0].hypot(self.gravity[1]);
        let first_step = crate::displacement::step_displacement_bound(initial_speed, g, d);
        if t.min > first_step {
            return Err(invalid(
                "time_step.min",
                format!(
                    "must be at most {first_step:.3e} s, got {} s: in a longer first step water \
                     starting at {initial_speed} m/s under gravity {g} m/s² moves more than \
                     {}·d = {} m and can pass through a wall",
                    t.min,
                    crate::displacement::MAX_STEP_DISPLACEMENT,
                    d * f64::from(crate::displacement::MAX_STEP_DISPLACEMENT)
                ),
            ));
        }

        let v = &self.viscosity;
        for (key, val) in [
            ("viscosity.xsph", v.xsph),
            ("viscosity.kinematic", v.kinematic),
            ("viscosity.boundary_kinematic", v.boundary_kinematic),
        ] {
            finite(key, val)?;
            if val < 0.0 {
                return Err(invalid(key, format!("must not be negative, got {val}")));
            }
        }
        for (key, val) in [
            ("viscosity.kinematic", v.kinematic),
            ("viscosity.boundary_kinematic", v.boundary_kinematic),
        ] {
            if val > MAX_KINEMATIC_VISCOSITY {
                return Err(invalid(
                    key,
                    format!(
                        "{val} m²/s is more than {MAX_KINEMATIC_VISCOSITY} m²/s (100 times \
                         honey; the explicit viscosity caps the step at 0.125·d²/ν, 12.5 µs at \
                         d = 1 cm and 1 m²/s)"
                    ),
                ));
            }
        }
        if v.xsph > MAX_XSPH {
            return Err(invalid(
                "viscosity.xsph",
                format!(
                    "{} exceeds {MAX_XSPH} (the share of the way to the neighbours' average \
                     velocity each step: beyond it the smoothing and a viscosity together are \
                     unstable at any step the viscosity allows)",
                    v.xsph
                ),
            ));
        }

        let n = self.fluid_particle_count();
        if n > self.max_particles {
            return Err(invalid(
                "max_particles",
                format!(
                    "the fluid blocks and listed particles hold {n} particles, more than \
                     max_particles = {}",
                    self.max_particles
                ),
            ));
        }
        if self.max_particles > 50_000_000 {
            return Err(invalid(
                "max_particles",
                format!("{} exceeds the hard limit of 50000000", self.max_particles),
            ));
        }
        probe::validate(&self.tank, &self.probes)?;
        Ok(())
    }
}

/// One built-in scene: its name, a one-line description, and how to build it.
pub struct BuiltinScene {
    pub name: &'static str,
    pub description: &'static str,
    build: fn() -> Scene,
}

impl BuiltinScene {
    /// The scene with all its values.
    pub fn scene(&self) -> Scene {
        let mut s = (self.build)();
        s.name = self.name.to_string();
        s.description = self.description.to_string();
        s
    }
}

/// `scene` on the square lattice with the Jacobi solve (the paper's DFSPH), in place of the
/// defaults (the hexagonal lattice, conjugate gradients). The built-in collapsing columns (the
/// dam breaks, `obstacle`, `floating`) and the validation's dam breaks name it: on the defaults
/// the 5k dam break drains too slowly (its residual height at the back wall 58 % off
/// Martin & Moyce's Table 6 at τ = 5.25, against 13 % here) and takes 4.4 times as long
/// (26.5 density iterations a step against 3.0; docs/deep-columns.md, "One set of
/// defaults"). Deep water at rest is what it cannot hold: a pool 300 layers deep sloshes at
/// 1.1 m/s on it.
pub fn square_lattice_jacobi(mut scene: Scene) -> Scene {
    scene.packing = Packing::Square;
    scene.solver.pressure_solve = PressureSolve::Jacobi;
    scene
}

/// The built-in scenes, in the order the viewer's number keys select them.
pub const BUILTIN_SCENES: &[BuiltinScene] = &[
    BuiltinScene {
        name: "dam-break",
        description: "1 m x 2 m water column collapsing in a 4 m x 3 m tank (5,000 particles)",
        build: || square_lattice_jacobi(Scene::default()),
    },
    BuiltinScene {
        name: "hydrostatic",
        description: "water 1 m deep at rest in a 2 m wide tank: pressure should be rho0*g*(H - y)",
        build: || Scene {
            tank: Tank {
                min: [0.0, 0.0],
                max: [2.0, 2.0],
            },
            fluid: vec![FluidBlock {
                min: [0.0, 0.0],
                max: [2.0, 1.0],
                velocity: [0.0, 0.0],
            }],
            ..Scene::default()
        },
    },
    BuiltinScene {
        name: "double-dam-break",
        description: "two 0.8 m x 1.6 m columns released from both ends of a 4 m x 3 m tank",
        build: || Scene {
            fluid: vec![
                FluidBlock {
                    min: [0.0, 0.0],
                    max: [0.8, 1.6],
                    velocity: [0.0, 0.0],
                },
                FluidBlock {
                    min: [3.2, 0.0],
                    max: [4.0, 1.6],
                    velocity: [0.0, 0.0],
                },
            ],
            ..square_lattice_jacobi(Scene::default())
        },
    },
    BuiltinScene {
        name: "drop",
        description: "a 0.6 m square of water falling into a 0.6 m deep pool",
        build: || Scene {
            tank: Tank {
                min: [0.0, 0.0],
                max: [3.0, 3.0],
            },
            fluid: vec![
                FluidBlock {
                    min: [0.0, 0.0],
                    max: [3.0, 0.6],
                    velocity: [0.0, 0.0],
                },
                FluidBlock {
                    min: [1.2, 1.8],
                    max: [1.8, 2.4],
                    velocity: [0.0, -1.0],
                },
            ],
            // The defaults: on the square lattice with the Jacobi solve the pool sloshed at
            // 0.5 m/s before the drop reached it; on these it stays under 0.001 m/s, and the
            // splash is the same (15 m/s at its tip against 14.7).
            ..Scene::default()
        },
    },
    BuiltinScene {
        name: "obstacle",
        description: "a dam break against a block and a ramp in the middle of the tank",
        build: || Scene {
            obstacles: vec![
                Obstacle::Rect {
                    min: [2.0, 0.0],
                    max: [2.2, 0.5],
                },
                Obstacle::Polyline {
                    points: vec![[3.0, 0.0], [4.0, 0.8]],
                },
            ],
            ..square_lattice_jacobi(Scene::default())
        },
    },
    BuiltinScene {
        name: "floating",
        description: "a dam break into a pool with floating boxes and circles (300-700 kg/m3) \
                      and a sunken one (2,000 kg/m3), swept into the far wall",
        // The bodies float in a pool 0.25 m deep, near their drafts, so water lies under the
        // light ones: a body resting on a dry floor has none under it to lift it (no water
        // fits into a gap narrower than a spacing). Every body is 0.3 m across or more, so
        // the scene holds at particle radii up to 5 cm (a body must be three spacings
        // across).
        build: || Scene {
            fluid: vec![
                FluidBlock {
                    min: [0.0, 0.0],
                    max: [1.0, 2.0],
                    velocity: [0.0, 0.0],
                },
                FluidBlock {
                    min: [1.0, 0.0],
                    max: [4.0, 0.25],
                    velocity: [0.0, 0.0],
                },
            ],
            bodies: vec![
                BodySpec::new_box([0.4, 0.3], 300.0, [1.7, 0.31]),
                BodySpec::new_circle(0.15, 500.0, [2.4, 0.25]),
                BodySpec::new_box([0.3, 0.3], 700.0, [3.0, 0.19]),
                BodySpec::new_circle(0.15, 2000.0, [3.6, 0.155]),
            ],
            ..square_lattice_jacobi(Scene::default())
        },
    },
];

/// Look up a built-in scene by name.
pub fn builtin(name: &str) -> Option<Scene> {
    BUILTIN_SCENES
        .iter()
        .find(|b| b.name == name)
        .map(BuiltinScene::scene)
}

#[cfg(test)]
mod tests {
    #[test]
    fn a_viscosity_far_above_water_s_gets_a_note_naming_the_mix_up() {
        let mut s = super::Scene::default();
        assert_eq!(s.viscosity_note(), None);
        s.viscosity.kinematic = 5.0e-5;
        assert_eq!(s.viscosity_note(), None, "50 times water's: no note");
        s.viscosity.kinematic = 0.001;
        let note = s.viscosity_note().unwrap();
        assert!(
            note.starts_with("note: viscosity.kinematic is 0.001 m²/s, 1000 times water's"),
            "{note}"
        );
        assert!(note.contains("dynamic viscosity is 0.001 Pa·s"), "{note}");
        s.viscosity.boundary_kinematic = 0.01;
        assert!(s
            .viscosity_note()
            .unwrap()
            .starts_with("note: viscosity.boundary_kinematic is 0.01"));
    }

    use super::*;

    fn err(text: &str) -> String {
        Scene::from_json(text).unwrap_err().to_string()
    }

    #[test]
    fn more_fluid_blocks_than_the_bound_are_rejected() {
        // Blocks one site each, 100 to a row (a tank 2,000 m tall would lie beyond
        // `MAX_SPACINGS_FROM_ORIGIN`).
        let mut s = Scene {
            particle_radius: 0.005,
            ..Scene::default()
        };
        s.tank.max = [1.0, 1.1];
        s.fluid = (0..=MAX_FLUID_BLOCKS)
            .map(|i| {
                let (x, y) = ((i % 100) as f64 * 0.01, (i / 100) as f64 * 0.01);
                FluidBlock {
                    min: [x, y],
                    max: [x + 0.01, y + 0.01],
                    velocity: [0.0, 0.0],
                }
            })
            .collect();
        let e = s.validate().unwrap_err().to_string();
        assert!(e.contains("`fluid`") && e.contains("10001 blocks"), "{e}");
        s.fluid.pop();
        s.max_particles = 50_000_000;
        s.validate().unwrap();
    }

    #[test]
    fn fluid_blocks_overlapping_by_a_spacing_are_rejected_naming_both() {
        let block = |x0: f64, x1: f64| format!(r#"{{"min": [{x0}, 0], "max": [{x1}, 0.4]}}"#);
        let scene = |blocks: &[String]| {
            format!(
                r#"{{"particle_radius": 0.01, "tank": {{"min": [0, 0], "max": [2, 1]}},
                    "fluid": [{}]}}"#,
                blocks.join(",")
            )
        };
        // Touching, and a third of a spacing deep: accepted.
        Scene::from_json(&scene(&[block(0.0, 0.5), block(0.5, 1.0)])).unwrap();
        Scene::from_json(&scene(&[block(0.0, 0.5), block(0.4933, 0.9933)])).unwrap();
        // Side by side far apart, then one block on top of another: the second is named.
        let e = Scene::from_json(&scene(&[block(1.2, 1.6), block(0.0, 0.5), block(0.0, 0.5)]))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("`fluid[2]`") && e.contains("overlaps fluid[1] by 0.500 m x 0.400 m"),
            "{e}"
        );
        // Overlapping by exactly one spacing along x.
        let e = Scene::from_json(&scene(&[block(0.0, 0.5), block(0.48, 1.0)]))
            .unwrap_err()
            .to_string();
        assert!(e.contains("`fluid[1]`") && e.contains("fluid[0]"), "{e}");
    }

    #[test]
    fn the_kernel_is_read_sets_the_support_and_a_bad_value_is_named() {
        use crate::kernel::KernelShape;
        let s =
            Scene::from_json(r#"{"particle_radius": 0.01, "solver": {"kernel": "wendland_c2"}}"#)
                .unwrap();
        assert_eq!(s.solver.kernel, KernelShape::WendlandC2);
        assert!((s.support() - 0.07).abs() < 1e-12, "{}", s.support());
        assert_eq!(s.kernel().shape(), KernelShape::WendlandC2);
        let d = Scene::default();
        assert_eq!(d.solver.kernel, KernelShape::CubicSpline);
        assert!((d.support() - 4.0 * d.particle_radius).abs() < 1e-12);
        let e = Scene::from_json(r#"{"solver": {"kernel": "gaussian"}}"#)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("`solver.kernel`") && e.contains("wendland_c2"),
            "{e}"
        );
    }

    #[test]
    fn packing_and_pressure_solve_are_read_and_bad_values_named() {
        let s =
            Scene::from_json(r#"{"packing": "square", "solver": {"pressure_solve": "jacobi"}}"#)
                .unwrap();
        assert_eq!(s.packing, Packing::Square);
        assert_eq!(s.solver.pressure_solve, PressureSolve::Jacobi);
        let d = Scene::default();
        assert_eq!(
            (d.packing, d.solver.pressure_solve),
            (Packing::Hexagonal, PressureSolve::ConjugateGradient)
        );
        let e = Scene::from_json(r#"{"packing": "triangular"}"#)
            .unwrap_err()
            .to_string();
        assert!(e.contains("`packing`") && e.contains("hexagonal"), "{e}");
        let e = Scene::from_json(r#"{"solver": {"pressure_solve": "cg"}}"#)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("solver.pressure_solve") && e.contains("conjugate_gradient"),
            "{e}"
        );
    }

    #[test]
    fn every_scene_gets_the_same_defaults_whatever_its_shape() {
        // Water at rest, a column short of the far wall, a moving block, a block above a
        // wall-to-wall pool, gravity along x, particles listed one by one: the keys a file
        // leaves out take one set of values, never a guess from the scene's shape.
        let tank = r#""tank": {"min": [0, 0], "max": [0.25, 2]}, "particle_radius": 0.0025"#;
        let defaults = Scene::default();
        for fluid in [
            r#""fluid": [{"min": [0, 0], "max": [0.25, 1.5]}]"#,
            r#""fluid": [{"min": [0, 0], "max": [0.2, 1.5]}]"#,
            r#""fluid": [{"min": [0, 0], "max": [0.25, 1.5], "velocity": [0, -1]}]"#,
            r#""fluid": [{"min": [0, 0], "max": [0.25, 0.5]}, {"min": [0, 1], "max": [0.1, 1.2]}]"#,
            r#""fluid": [{"min": [0, 0], "max": [0.25, 1.5]}], "gravity": [9.81, 0]"#,
            r#""fluid": [], "particles": {"positions": [[0.01, 0.01], [0.03, 0.01]]}"#,
        ] {
            let s = Scene::from_json(&format!("{{{tank}, {fluid}}}")).unwrap();
            assert_eq!(
                (s.packing, &s.solver, &s.time_step),
                (Packing::Hexagonal, &defaults.solver, &defaults.time_step),
                "{fluid}"
            );
        }
        assert_eq!(
            (
                defaults.solver.pressure_solve,
                defaults.solver.max_iterations
            ),
            (PressureSolve::ConjugateGradient, 100)
        );
        // What the file says is kept.
        let s = Scene::from_json(&format!(
            r#"{{{tank}, "fluid": [{{"min": [0, 0], "max": [0.25, 1.5]}}], "packing": "square",
                "solver": {{"pressure_solve": "jacobi", "max_iterations": 50}}}}"#
        ))
        .unwrap();
        assert_eq!(
            (s.packing, s.solver.pressure_solve, s.solver.max_iterations),
            (Packing::Square, PressureSolve::Jacobi, 50)
        );
        // The built-in collapsing columns name the square lattice and the Jacobi solve.
        for name in ["dam-break", "double-dam-break", "obstacle", "floating"] {
            let s = builtin(name).unwrap();
            assert_eq!(
                (s.packing, s.solver.pressure_solve),
                (Packing::Square, PressureSolve::Jacobi),
                "{name}"
            );
        }
        for name in ["hydrostatic", "drop"] {
            let s = builtin(name).unwrap();
            assert_eq!(
                (s.packing, &s.solver),
                (Packing::Hexagonal, &defaults.solver)
            );
        }
    }

    #[test]
    fn a_hexagonal_scene_counts_the_particles_it_creates() {
        let mut s = builtin("hydrostatic").unwrap();
        assert_eq!(s.packing, Packing::Hexagonal);
        s.particle_radius = 0.02;
        let n = crate::Simulation::new(&s).unwrap().fluid_count();
        assert_eq!(n, s.fluid_particle_count());
        // 2 m² of water at d² = 0.0016 m² per particle, less the rows the edges cut.
        assert!((1200..=1270).contains(&n), "{n}");
    }

    #[test]
    fn listed_particles_are_validated_naming_the_key_and_index() {
        let scene = |fluid: &str, particles: &str| {
            format!(
                r#"{{"particle_radius": 0.01, "tank": {{"min": [0, 0], "max": [2, 1]}},
                    "fluid": [{fluid}], "particles": {particles}}}"#
            )
        };
        // Water given particle by particle only, at rest or moving: accepted, counted.
        let s =
            Scene::from_json(&scene("", r#"{"positions": [[0.01, 0.01], [0.03, 0.01]]}"#)).unwrap();
        assert_eq!(s.fluid_particle_count(), 2);
        Scene::from_json(&scene(
            r#"{"min": [1, 0], "max": [2, 0.5]}"#,
            r#"{"positions": [[0.01, 0.01], [1.995, 0.6]], "velocities": [[0, 0], [1, -2]]}"#,
        ))
        .unwrap();
        let cases: &[(&str, &str, &str)] = &[
            ("", r#"{"positions": []}"#, "`fluid`"),
            (
                "",
                r#"{"positions": [[0.5, 0.5]], "spin": 1}"#,
                "unknown field `spin`",
            ),
            ("", r#"{"positions": [[0.5]]}"#, "particles.positions[0]"),
            (
                "",
                r#"{"positions": [[0.5, 0.5], [0.7, 1.2]]}"#,
                "`particles.positions[1][1]`: 1.2 lies outside the tank",
            ),
            (
                "",
                r#"{"positions": [[0.5, 0.5], [-0.1, 0.5]]}"#,
                "`particles.positions[1][0]`",
            ),
            (
                "",
                r#"{"positions": [[0.5, 0.5], [0.6, 0.5]], "velocities": [[0, 0]]}"#,
                "`particles.velocities`: 1 velocities for 2 positions",
            ),
            (
                "",
                r#"{"positions": [[0.5, 0.5]], "velocities": [[500, 0]]}"#,
                "`particles.velocities[0]`",
            ),
            (
                "",
                r#"{"positions": [[0.5, 0.5], [0.6, 0.5], [0.500001, 0.5]]}"#,
                "`particles.positions[2]`: lies 1.000e-6 m from particles.positions[0]",
            ),
            (
                r#"{"min": [0, 0], "max": [1, 0.5]}"#,
                r#"{"positions": [[1.5, 0.5], [0.5, 0.25]]}"#,
                "`particles.positions[1]`: [0.5, 0.25] lies inside fluid[0]",
            ),
        ];
        for (fluid, particles, needle) in cases {
            let msg = err(&scene(fluid, particles));
            assert!(
                msg.contains(needle),
                "{particles}: {msg:?} lacks {needle:?}"
            );
        }
        // Fourteen particles within half a spacing of each other; thirteen are accepted.
        let pile = |n: usize| {
            let p: Vec<String> = (0..n)
                .map(|k| format!("[{}, 0.5]", 0.5 + 0.0007 * k as f64))
                .collect();
            scene("", &format!(r#"{{"positions": [{}]}}"#, p.join(",")))
        };
        Scene::from_json(&pile(13)).unwrap();
        let msg = err(&pile(14));
        assert!(
            msg.contains(
                "`particles.positions[0]`: 13 other particles lie closer than one spacing"
            ),
            "{msg}"
        );
        let msg =
            err(r#"{"max_particles": 1, "particles": {"positions": [[0.5, 0.5], [0.6, 0.5]]}}"#);
        assert!(
            msg.contains("`particles.positions`") && msg.contains("max_particles = 1"),
            "{msg}"
        );
        let msg = err(r#"{"obstacles": [{"type": "particles", "positions": [[1, 1], [9, 1]]}]}"#);
        assert!(msg.contains("`obstacles[0].positions[1][0]`"), "{msg}");
    }

    #[test]
    fn the_radius_limits_are_the_validators() {
        let mut s = Scene::default();
        let (lo, hi) = s.particle_radius_limits();
        // The default tank (4 m × 3 m at the origin): the smallest radius is set by its far
        // corner's distance from the origin, 4,096 spacings.
        assert!(
            lo == 4.0 / MAX_SPACINGS_FROM_ORIGIN / 2.0 && hi == 0.75,
            "{lo} {hi}"
        );
        s.particle_radius = lo * 0.999;
        let e = s.validate().unwrap_err().to_string();
        assert!(e.contains("`tank.max[0]`"), "{e}");
        s.tank.min = [-0.5, -0.5];
        s.tank.max = [0.5, 0.5];
        s.fluid[0].min = [-0.5, -0.5];
        let (lo, hi) = s.particle_radius_limits();
        assert!(
            lo == 0.5 / MAX_SPACINGS_FROM_ORIGIN / 2.0 && hi == 0.25,
            "{lo} {hi}"
        );
        // Without fluid for the max_particles check to count.
        s.fluid[0].max = [2.0 * hi, 2.0 * hi];
        for (r, ok) in [(hi, true), (hi * 1.001, false)] {
            s.particle_radius = r;
            assert_eq!(s.validate().is_ok(), ok, "r = {r}");
        }
        s.fluid[0].max = [0.5, 0.5];
        s.max_particles = 50_000_000;
        for (r, key) in [(lo * 1.001, "max_particles"), (lo * 0.999, "tank.min[0]")] {
            s.particle_radius = r;
            let e = s.validate().unwrap_err().to_string();
            assert!(e.contains(&format!("`{key}`")), "r = {r}: {e}");
        }
    }

    #[test]
    fn a_name_or_description_too_long_to_print_is_rejected() {
        let mut s = Scene {
            name: "é".repeat(MAX_NAME_CHARS),
            description: "d".repeat(MAX_DESCRIPTION_CHARS),
            ..Scene::default()
        };
        s.validate().unwrap();
        s.name.push('x');
        let e = s.validate().unwrap_err().to_string();
        assert_eq!(
            e,
            "`name`: 201 characters is longer than the 200 it may have"
        );
        s.name.pop();
        s.description.push('x');
        let e = s.validate().unwrap_err().to_string();
        assert!(e.starts_with("`description`: 2001 characters"), "{e}");
    }

    #[test]
    fn a_tank_beyond_single_precisions_reach_is_rejected_naming_its_corner() {
        let at = |x0: f64, r: f64| {
            Scene::from_json(&format!(
                r#"{{"particle_radius": {r}, "tank": {{"min": [{x0}, -1], "max": [{}, 0]}},
                    "fluid": [{{"min": [{x0}, -1], "max": [{}, -0.5]}}]}}"#,
                x0 + 1.0,
                x0 + 1.0
            ))
        };
        // 4,096 spacings at d = 2 cm: 81.92 m.
        assert!(at(80.0, 0.01).is_ok());
        let e = at(81.0, 0.01).unwrap_err().to_string();
        assert!(
            e.contains("`tank.max[0]`") && e.contains("4096 spacings"),
            "{e}"
        );
        let e = at(-10_000.0, 0.01).unwrap_err().to_string();
        assert!(e.contains("`tank.min[0]`"), "{e}");
        // Larger particles reach farther.
        assert!(at(1_000.0, 0.2).is_ok());
        let far = at(80.0, 0.01).unwrap();
        let (lo, _) = far.particle_radius_limits();
        assert!((lo - 81.0 / 4096.0 / 2.0).abs() < 1e-12, "{lo}");
    }

    #[test]
    fn empty_object_gives_the_default_scene() {
        let s = Scene::from_json("{}").unwrap();
        assert_eq!(s, Scene::default());
    }

    #[test]
    fn resolved_json_round_trips() {
        for b in BUILTIN_SCENES {
            let s = b.scene();
            s.validate().unwrap();
            let back = Scene::from_json(&s.to_json()).unwrap();
            assert_eq!(back, s, "{}", b.name);
        }
    }

    #[test]
    fn malformed_scenes_name_the_problem() {
        let cases: &[(&str, &str)] = &[
            ("", "empty"),
            ("   \n", "empty"),
            ("[1, 2]", "must be a JSON object"),
            ("{\"particle_radius\": 0.01", "EOF"),
            ("{\"particle_radius\": -0.01}", "particle_radius"),
            ("{\"particle_radius\": 0}", "particle_radius"),
            ("{\"particle_radius\": \"big\"}", "particle_radius"),
            ("{\"radius\": 0.01}", "unknown field `radius`"),
            ("{\"solver\": {\"tolerance\": 1}}", "solver"),
            ("{\"solver\": {\"method\": \"pbf\"}}", "solver.method"),
            (
                "{\"solver\": {\"max_iterations\": 0}}",
                "solver.max_iterations",
            ),
            (
                "{\"solver\": {\"min_iterations\": 5, \"max_iterations\": 3}}",
                "solver.min_iterations",
            ),
            (
                "{\"solver\": {\"density_tolerance_pct\": -1}}",
                "solver.density_tolerance_pct",
            ),
            ("{\"time_step\": {\"cfl\": 2}}", "time_step.cfl"),
            ("{\"time_step\": {\"max\": 1e308}}", "time_step.max"),
            (
                "{\"time_step\": {\"min\": 0.1, \"max\": 0.01}}",
                "time_step.min",
            ),
            ("{\"time_step\": {\"min\": 1, \"max\": 1}}", "time_step.min"),
            (
                "{\"tank\": {\"min\": [0, 0], \"max\": [0, 1]}}",
                "tank.max[0]",
            ),
            ("{\"tank\": {\"min\": [0, 0]}}", "tank"),
            (
                "{\"fluid\": [{\"min\": [0, 0], \"max\": [5, 1]}]}",
                "fluid[0].max[0]",
            ),
            (
                "{\"fluid\": [{\"min\": [0, -1], \"max\": [1, 1]}]}",
                "fluid[0].min[1]",
            ),
            ("{\"fluid\": []}", "fluid"),
            ("{\"max_particles\": 100}", "max_particles"),
            (
                "{\"viscosity\": {\"kinematic\": -1e-6}}",
                "viscosity.kinematic",
            ),
            ("{\"rest_density\": 1e-300}", "rest_density"),
            ("{\"rest_density\": 1e300}", "rest_density"),
            (
                "{\"fluid\": [{\"min\": [0, 0], \"max\": [1, 1], \"velocity\": [1e30, 0]}]}",
                "fluid[0].velocity",
            ),
            (
                "{\"viscosity\": {\"kinematic\": 1e6}}",
                "viscosity.kinematic",
            ),
            (
                "{\"viscosity\": {\"boundary_kinematic\": 2}}",
                "viscosity.boundary_kinematic",
            ),
            ("{\"gravity\": [0]}", "gravity"),
            ("{\"gravity\": [0, -1e20]}", "gravity"),
            (
                "{\"obstacles\": [{\"type\": \"polyline\", \"points\": [[1, 1]]}]}",
                "obstacles[0].points",
            ),
            ("{\"obstacles\": [{\"type\": \"circle\"}]}", "obstacles[0]"),
            ("{\"particle_radius\": 1e-9}", "particle_radius"),
            ("{\"particle_radius\": 3}", "particle_radius"),
        ];
        for (text, needle) in cases {
            let msg = err(text);
            assert!(
                msg.contains(needle),
                "scene {text:?}: message {msg:?} does not mention {needle:?}"
            );
        }
    }

    #[test]
    fn numbers_beyond_single_precision_are_rejected_naming_the_key() {
        let e = Scene::from_json(
            r#"{"bodies": [{"shape": "box", "size": [0.2, 0.2], "density": 500,
                            "position": [1.0, 2.5], "angle": 1e39}]}"#,
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("`bodies[0].angle`") && e.contains("single precision"),
            "{e}"
        );
        let e = Scene::from_json(r#"{"gravity": [0, -1e300]}"#)
            .unwrap_err()
            .to_string();
        assert!(e.contains("`gravity[1]`"), "{e}");
    }

    #[test]
    fn non_finite_numbers_are_rejected() {
        // JSON has no NaN literal; a huge exponent overflows to infinity in serde_json.
        let msg = err("{\"gravity\": [0, -1e400]}");
        assert!(msg.contains("gravity"), "{msg}");
        let s = Scene {
            gravity: [f64::NAN, -9.81],
            ..Scene::default()
        };
        assert!(s.validate().unwrap_err().to_string().contains("gravity[0]"));
    }

    #[test]
    fn lattice_count_is_exact_for_whole_multiples() {
        let s = builtin("dam-break").unwrap();
        assert_eq!(s.lattice_count(1.0), 50);
        assert_eq!(s.lattice_count(2.0), 100);
        assert_eq!(s.fluid_particle_count(), 5000);
    }
}
