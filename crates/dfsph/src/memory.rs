//! How much memory a scene needs, and how much this process may use: checked before anything
//! big is allocated, so a scene too large for the machine gets one error line instead of an
//! allocation failure and a backtrace (issue 32: 49 M particles, under the particle-count
//! budget, died at 6.3 GB with `memory allocation of 32768 bytes failed`).
//!
//! [`Scene::memory_estimate`] adds up what a [`crate::Simulation`] of the scene allocates
//! (every per-particle array, the neighbour lists and the per-pair caches at a neighbour
//! count with headroom, both grids, a snapshot for output) from the scene alone, allocating
//! nothing. [`MemoryLimits::of_this_process`] reads what the process may use: the memory
//! the kernel says is available (`MemAvailable` in `/proc/meminfo`), the cgroup's limit
//! (`memory.max` less `memory.current`, cgroup v2), and the address-space limit
//! (`RLIMIT_AS`, as `ulimit -v` sets it) less what the process has mapped already.
//! [`MemoryLimits::check`] compares the two, and a user's own `--max-memory`.

use crate::scene::{Obstacle, PressureSolve, Scene};

/// Fluid–fluid neighbours per particle the estimate plans for. At rest density a particle's
/// support disc (radius h = 2d) holds π·4 ≈ 12.6 lattice sites, itself included; compressed
/// water and the SIMD blocks' padding (5–9 %) hold a little more. 1.5 times that covers
/// splashing fronts and the chunk buffers' growth.
pub const PLANNED_NEIGHBOURS: u64 = 19;

/// Fluid neighbours per boundary particle the estimate plans for. Of a wall's two layers only
/// the inner one reaches into the water at rest, with 3 fluid neighbours (at distances d and
/// √2·d; the next row lies at 2d, the edge of the support); twice that per particle of both
/// layers covers water pressed into the wall and corners.
pub const PLANNED_WALL_NEIGHBOURS: u64 = 6;

/// Bytes per fluid particle in arrays of one entry per particle: the particle state (position,
/// velocity, id, density, factor, pressure, divergence stiffness, acceleration: 44), the
/// reordering scratch (16), the fluid grid's keys, order and sorted copies (20), the pair
/// cache's gradient sums and wall fluxes (12), the Jacobi scratch (20), a step's retry copies
/// (12), the neighbour lists' offsets (fluid and wall, 8), the density rates of the
/// linearisation check (4) and a snapshot sorted for output (id, position, velocity, density,
/// pressure and the sort order: 36).
pub const BYTES_PER_FLUID_PARTICLE: u64 = 44 + 16 + 20 + 12 + 20 + 12 + 8 + 4 + 36;

/// Extra bytes per fluid particle of the conjugate-gradient solve's scratch (eight arrays) and
/// its hydrostatic start (a column map while the simulation is built).
pub const BYTES_PER_PARTICLE_CG: u64 = 36 + 24;

/// Bytes per fluid–fluid pair: its index in the neighbour list (4), and in the solver's SIMD
/// blocks its index, gradient and window code (4 + 8 + 1).
pub const BYTES_PER_FLUID_PAIR: u64 = 4 + 13;

/// Bytes per fluid–wall pair: its index in the list (4) and its cached kernel gradient (8).
pub const BYTES_PER_WALL_PAIR: u64 = 4 + 8;

/// Bytes per boundary particle: position, velocity, volume and body (22), the wall grid's keys,
/// order and sorted copies (20), and the samples they were built from (18).
pub const BYTES_PER_BOUNDARY_PARTICLE: u64 = 22 + 20 + 18;

/// Bytes per grid cell: its start and fill cursor (8).
pub const BYTES_PER_CELL: u64 = 8;

/// What the process itself takes besides the simulation: code, the thread stacks' touched
/// pages, the allocator's own slack and the output writers' buffers.
pub const PROCESS_BASE_BYTES: u64 = 32 << 20;

/// The memory a scene needs, in bytes, and the particle counts it was estimated for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MemoryEstimate {
    /// Fluid particles planned for (the scene's own, or a larger pour budget).
    pub fluid_particles: u64,
    /// Boundary particles the tank and obstacles are sampled with (an upper bound).
    pub boundary_particles: u64,
    /// Per-particle arrays, fluid and boundary.
    pub particles: u64,
    /// Neighbour lists and per-pair caches.
    pub pairs: u64,
    /// Both grids' cells.
    pub grids: u64,
    /// Output buffers beyond the snapshot (image frames, VTK arrays), added by the caller
    /// with [`Self::with_output`].
    pub output: u64,
    /// [`PROCESS_BASE_BYTES`].
    pub process: u64,
}

impl MemoryEstimate {
    /// Everything together, bytes.
    pub fn total(&self) -> u64 {
        self.particles
            .saturating_add(self.pairs)
            .saturating_add(self.grids)
            .saturating_add(self.output)
            .saturating_add(self.process)
    }

    /// What the simulation and its snapshot allocate (the total less the process and the
    /// output buffers), bytes.
    pub fn simulation(&self) -> u64 {
        self.particles
            .saturating_add(self.pairs)
            .saturating_add(self.grids)
    }

    /// This estimate with `bytes` of output buffers more.
    pub fn with_output(mut self, bytes: u64) -> Self {
        self.output = self.output.saturating_add(bytes);
        self
    }
}

impl Scene {
    /// Boundary particles the tank, the obstacles and the rigid bodies are sampled with: two
    /// layers around the tank, corners filled, [`Scene::validate`]'s estimate for the
    /// obstacles and two layers round each body (an upper bound).
    pub fn boundary_particle_estimate(&self) -> u64 {
        let d = self.spacing();
        let (w, h) = (
            self.tank.max[0] - self.tank.min[0],
            self.tank.max[1] - self.tank.min[1],
        );
        // `layers` layers (two for the cubic spline) of (w + h)·2/d each, plus the corners;
        // the hexagonal lattice's rows are 7 % denser along x.
        let layers = self.wall_layers() as f64;
        let per_layer = 0.5 * layers;
        let tank = per_layer * (4.4 * (w + h) / d + 64.0);
        let obstacles: f64 = self
            .obstacles
            .iter()
            .map(|o| match o {
                Obstacle::Rect { min, max } => {
                    per_layer * (4.0 * ((max[0] - min[0]) + (max[1] - min[1])) / d + 16.0)
                }
                Obstacle::Polyline { points } => {
                    layers
                        * points
                            .windows(2)
                            .map(|w| (w[1][0] - w[0][0]).hypot(w[1][1] - w[0][1]) / d + 2.0)
                            .sum::<f64>()
                }
                Obstacle::Particles { positions } => positions.len() as f64,
            })
            .sum();
        // Rigid bodies: two layers along their outline (a circle's perimeter bounds a box's
        // within its bounding circle).
        let bodies: f64 = self
            .bodies
            .iter()
            .map(|b| {
                let e = b.half_extent();
                per_layer * (2.0 * std::f64::consts::TAU * e[0].hypot(e[1]) / d + 8.0)
            })
            .sum();
        (tank + obstacles + bodies).ceil().min(u64::MAX as f64) as u64
    }

    /// [`PLANNED_NEIGHBOURS`] for this scene's kernel: the support disc's area grows with
    /// the square of the support (2d for the cubic spline).
    fn planned_neighbours(&self) -> u64 {
        let ratio = self.solver.kernel.support_in_spacings() / 2.0;
        (PLANNED_NEIGHBOURS as f64 * ratio * ratio).ceil() as u64
    }

    /// [`PLANNED_WALL_NEIGHBOURS`] for this scene's kernel, scaled as
    /// [`Self::planned_neighbours`].
    fn planned_wall_neighbours(&self) -> u64 {
        let ratio = self.solver.kernel.support_in_spacings() / 2.0;
        (PLANNED_WALL_NEIGHBOURS as f64 * ratio * ratio).ceil() as u64
    }

    /// The memory a simulation of this scene needs with its own fluid particles
    /// ([`Scene::fluid_particle_count`]); see [`Scene::memory_estimate_for`].
    pub fn memory_estimate(&self) -> MemoryEstimate {
        self.memory_estimate_for(self.fluid_particle_count() as u64)
    }

    /// The memory a simulation of this (validated) scene needs when it holds `fluid`
    /// particles (more than its own where water is poured in later: the viewer's and a
    /// replay's budget, `max_particles`). Computed from the scene alone; allocates nothing.
    /// An upper bound on what [`crate::Simulation::new`] and its steps allocate, within
    /// about 1.5 times (`tests/memory_estimate.rs` measures it), plus
    /// [`PROCESS_BASE_BYTES`].
    pub fn memory_estimate_for(&self, fluid: u64) -> MemoryEstimate {
        let boundary = self.boundary_particle_estimate();
        let per_fluid = BYTES_PER_FLUID_PARTICLE
            + if self.solver.pressure_solve == PressureSolve::ConjugateGradient {
                BYTES_PER_PARTICLE_CG
            } else {
                0
            };
        let particles = fluid
            .saturating_mul(per_fluid)
            .saturating_add(boundary.saturating_mul(BYTES_PER_BOUNDARY_PARTICLE));
        // Fluid–wall pairs: no more than the walls can have, nor than the fluid can.
        let wall_pairs = self
            .planned_wall_neighbours()
            .saturating_mul(boundary)
            .min(self.planned_neighbours().saturating_mul(fluid));
        let pairs = self
            .planned_neighbours()
            .saturating_mul(fluid)
            .saturating_mul(BYTES_PER_FLUID_PAIR)
            .saturating_add(wall_pairs.saturating_mul(BYTES_PER_WALL_PAIR));
        // Cells of side h over the walls' extent (1.5 d beyond the interior on each side).
        // The wall grid stays dense up to 4 cells per fluid particle, the fluid grid up to 4
        // per fluid particle (at least 4096); beyond, both hash into at most 4 keys per point.
        let h = self.support();
        let d = self.spacing();
        let cells = ((self.tank.max[0] - self.tank.min[0] + 3.0 * d) / h + 2.0)
            * ((self.tank.max[1] - self.tank.min[1] + 3.0 * d) / h + 2.0);
        let cells = cells.min(u64::MAX as f64) as u64;
        let fluid_cells = cells.min((4 * fluid).max(4096));
        let wall_cells = cells.min((4 * fluid).max(4 * boundary).max(4096));
        let grids = fluid_cells
            .saturating_add(wall_cells)
            .saturating_mul(BYTES_PER_CELL);
        MemoryEstimate {
            fluid_particles: fluid,
            boundary_particles: boundary,
            particles,
            pairs,
            grids,
            output: 0,
            process: PROCESS_BASE_BYTES,
        }
    }
}

/// Where a limit on this process's memory comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LimitSource {
    /// The user's own limit, by the name it was given with: `--max-memory` on the command
    /// line, `max_memory` in Python.
    User(&'static str),
    /// `MemAvailable` in `/proc/meminfo`: memory the kernel can give without swapping.
    Available,
    /// The cgroup's `memory.max` less its `memory.current` (cgroup v2; containers).
    Cgroup,
    /// `RLIMIT_AS` (`ulimit -v`) less the address space the process has mapped already.
    AddressSpace,
    /// WebAssembly's 4 GiB of linear memory less what the page's module has grown to.
    WebAssembly,
}

/// The most linear memory a 32-bit WebAssembly module can address: 4 GiB.
#[cfg(target_arch = "wasm32")]
const WASM32_MEMORY: u64 = 1 << 32;

/// One limit on the memory this process may use, bytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Limit {
    pub source: LimitSource,
    /// Bytes the scene may use under this limit.
    pub bytes: u64,
    /// The limit as set (`RLIMIT_AS`, `memory.max`), where it differs from `bytes`.
    pub set_to: Option<u64>,
}

/// The limits on the memory this process may use, as read by
/// [`MemoryLimits::of_this_process`] (each only where the system has it).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct MemoryLimits {
    pub limits: Vec<Limit>,
}

impl MemoryLimits {
    /// The limits of this process: available memory, the cgroup's, the address space's, and
    /// `user` (`--max-memory`) if given.
    pub fn of_this_process(user: Option<u64>) -> Self {
        Self::of_this_process_and_user(user.map(|bytes| (bytes, "--max-memory")))
    }

    /// [`Self::of_this_process`] with the user's limit and the name it was given with
    /// (`"max_memory"` from Python), which a refusal then names.
    pub fn of_this_process_and_user(user: Option<(u64, &'static str)>) -> Self {
        let mut limits = Vec::new();
        if let Some((bytes, name)) = user {
            limits.push(Limit {
                source: LimitSource::User(name),
                bytes,
                set_to: None,
            });
        }
        if let Some(bytes) = mem_available() {
            limits.push(Limit {
                source: LimitSource::Available,
                bytes,
                set_to: None,
            });
        }
        if let Some((max, current)) = cgroup_memory() {
            limits.push(Limit {
                source: LimitSource::Cgroup,
                bytes: max.saturating_sub(current),
                set_to: Some(max),
            });
        }
        #[cfg(target_arch = "wasm32")]
        {
            let grown = core::arch::wasm32::memory_size(0) as u64 * 65_536;
            limits.push(Limit {
                source: LimitSource::WebAssembly,
                bytes: WASM32_MEMORY.saturating_sub(grown),
                set_to: Some(WASM32_MEMORY),
            });
        }
        if let Some(max) = address_space_limit() {
            limits.push(Limit {
                source: LimitSource::AddressSpace,
                bytes: max.saturating_sub(mapped_bytes().unwrap_or(0)),
                set_to: Some(max),
            });
        }
        Self { limits }
    }

    /// The user's own limit (`--max-memory`), bytes, and the name it was given with, if one
    /// was given.
    pub fn user(&self) -> Option<(u64, &'static str)> {
        self.limits.iter().find_map(|l| match l.source {
            LimitSource::User(name) => Some((l.bytes, name)),
            _ => None,
        })
    }

    /// `Ok` when `estimate` fits every limit; otherwise one line saying how much the scene
    /// needs, which limit it exceeds and what that limit allows (the tightest limit exceeded).
    pub fn check(&self, estimate: &MemoryEstimate) -> Result<(), String> {
        let need = estimate.total();
        let Some(limit) = self
            .limits
            .iter()
            .filter(|l| l.bytes < need)
            .min_by_key(|l| l.bytes)
        else {
            return Ok(());
        };
        let what = match limit.source {
            LimitSource::User(name) => format!("{name} ({})", format_bytes(limit.bytes)),
            LimitSource::Available => format!(
                "the memory available ({}, MemAvailable in /proc/meminfo)",
                format_bytes(limit.bytes)
            ),
            LimitSource::Cgroup => format!(
                "what the cgroup's memory limit of {} leaves ({})",
                format_bytes(limit.set_to.unwrap_or(limit.bytes)),
                format_bytes(limit.bytes)
            ),
            LimitSource::WebAssembly => format!(
                "what WebAssembly's {} of memory leaves this page ({})",
                format_bytes(limit.set_to.unwrap_or(limit.bytes)),
                format_bytes(limit.bytes)
            ),
            LimitSource::AddressSpace => format!(
                "what the address-space limit (ulimit -v) of {} leaves ({})",
                format_bytes(limit.set_to.unwrap_or(limit.bytes)),
                format_bytes(limit.bytes)
            ),
        };
        Err(format!(
            "the scene needs about {} of memory ({} fluid and {} boundary particles), more than \
             {what}; use fewer or larger particles",
            format_bytes(need),
            estimate.fluid_particles,
            estimate.boundary_particles,
        ))
    }
}

/// `1.50 GiB`, `512 MiB`, `900 B`: powers of 1024, three significant digits.
pub fn format_bytes(bytes: u64) -> String {
    const UNITS: [&str; 6] = ["B", "KiB", "MiB", "GiB", "TiB", "PiB"];
    let mut value = bytes as f64;
    let mut unit = 0;
    while value >= 1024.0 && unit + 1 < UNITS.len() {
        value /= 1024.0;
        unit += 1;
    }
    if unit == 0 {
        format!("{bytes} B")
    } else if value >= 100.0 {
        format!("{value:.0} {}", UNITS[unit])
    } else if value >= 10.0 {
        format!("{value:.1} {}", UNITS[unit])
    } else {
        format!("{value:.2} {}", UNITS[unit])
    }
}

/// A byte count as a user writes it: `1000000`, `512M`, `2G`, `1.5GiB`, `64k`. The suffixes
/// K, M, G and T (with or without `i` and `B`, any case) are powers of 1024, as `ulimit` and
/// `free` use them; a plain number is bytes.
pub fn parse_bytes(text: &str) -> Result<u64, String> {
    let t = text.trim();
    let split = t
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(t.len());
    let (number, suffix) = t.split_at(split);
    let scale: u64 = match suffix.trim().to_ascii_lowercase().as_str() {
        "" | "b" => 1,
        "k" | "kb" | "kib" => 1 << 10,
        "m" | "mb" | "mib" => 1 << 20,
        "g" | "gb" | "gib" => 1 << 30,
        "t" | "tb" | "tib" => 1 << 40,
        _ => {
            return Err(format!(
                "`{text}` is not a size: a number of bytes, optionally with K, M, G or T \
                 (powers of 1024), such as 512M or 2G"
            ))
        }
    };
    let value: f64 = number
        .parse()
        .map_err(|_| format!("`{text}` is not a size: expected a number such as 512M or 2G"))?;
    let bytes = value * scale as f64;
    if !(bytes.is_finite() && bytes >= 1.0 && bytes < u64::MAX as f64) {
        return Err(format!(
            "`{text}` is not a size between 1 byte and 16 EiB (such as 512M or 2G)"
        ));
    }
    Ok(bytes as u64)
}

/// `MemAvailable` from `/proc/meminfo`, bytes (Linux 3.14+).
fn mem_available() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    kib_field(&text, "MemAvailable:")
}

/// The address space this process has mapped, `VmSize` from `/proc/self/status`, bytes.
fn mapped_bytes() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/self/status").ok()?;
    kib_field(&text, "VmSize:")
}

/// The value of a `Key:   1234 kB` line, in bytes.
fn kib_field(text: &str, key: &str) -> Option<u64> {
    let line = text.lines().find(|l| l.starts_with(key))?;
    let kib: u64 = line[key.len()..].split_whitespace().next()?.parse().ok()?;
    Some(kib.saturating_mul(1024))
}

/// The cgroup v2 memory limit of this process and its current use, bytes; `None` without a
/// limit (`max`) or without cgroup v2.
fn cgroup_memory() -> Option<(u64, u64)> {
    let text = std::fs::read_to_string("/proc/self/cgroup").ok()?;
    // cgroup v2: the one line `0::/path`.
    let path = text.lines().find_map(|l| l.strip_prefix("0::"))?;
    let dir = std::path::Path::new("/sys/fs/cgroup").join(path.trim_start_matches('/'));
    let read = |name: &str| -> Option<u64> {
        std::fs::read_to_string(dir.join(name))
            .ok()?
            .trim()
            .parse()
            .ok()
    };
    let max = read("memory.max")?;
    Some((max, read("memory.current").unwrap_or(0)))
}

/// The soft `RLIMIT_AS` of this process (`ulimit -v`), bytes; `None` when unlimited.
#[cfg(unix)]
fn address_space_limit() -> Option<u64> {
    // `None` for the current limit is RLIM_INFINITY.
    rustix::process::getrlimit(rustix::process::Resource::As).current
}

#[cfg(not(unix))]
fn address_space_limit() -> Option<u64> {
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse_with_binary_suffixes() {
        assert_eq!(parse_bytes("1000000"), Ok(1_000_000));
        assert_eq!(parse_bytes("512M"), Ok(512 << 20));
        assert_eq!(parse_bytes("2G"), Ok(2 << 30));
        assert_eq!(parse_bytes("2GiB"), Ok(2 << 30));
        assert_eq!(parse_bytes("1.5gb"), Ok(3 << 29));
        assert_eq!(parse_bytes("64k"), Ok(64 << 10));
        assert_eq!(parse_bytes(" 3 T "), Ok(3 << 40));
        for bad in [
            "",
            "M",
            "-1G",
            "0",
            "1e9",
            "2X",
            "1.2.3M",
            "99999999999T",
            "NaN",
        ] {
            assert!(parse_bytes(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn bytes_format_in_powers_of_1024() {
        assert_eq!(format_bytes(900), "900 B");
        assert_eq!(format_bytes(1536), "1.50 KiB");
        assert_eq!(format_bytes(512 << 20), "512 MiB");
        assert_eq!(format_bytes(6_300_000_000), "5.87 GiB");
    }

    #[test]
    fn the_tightest_exceeded_limit_is_named() {
        let scene = crate::scene::builtin("dam-break").unwrap();
        let e = scene.memory_estimate();
        assert_eq!(e.fluid_particles, 5000);
        let limits = |user: u64, avail: u64| MemoryLimits {
            limits: vec![
                Limit {
                    source: LimitSource::User("--max-memory"),
                    bytes: user,
                    set_to: None,
                },
                Limit {
                    source: LimitSource::AddressSpace,
                    bytes: avail,
                    set_to: Some(avail + (10 << 20)),
                },
            ],
        };
        assert_eq!(limits(u64::MAX, u64::MAX).check(&e), Ok(()));
        let msg = limits(1 << 20, 2 << 20).check(&e).unwrap_err();
        assert!(
            msg.starts_with("the scene needs about ")
                && msg.contains("(5000 fluid and ")
                && msg.contains("more than --max-memory (1.00 MiB)"),
            "{msg}"
        );
        let msg = limits(u64::MAX, 2 << 20).check(&e).unwrap_err();
        assert!(
            msg.contains("the address-space limit (ulimit -v) of 12.0 MiB leaves (2.00 MiB)"),
            "{msg}"
        );
    }

    #[test]
    fn the_estimate_grows_with_the_particles_and_the_pour_budget() {
        let mut scene = crate::scene::builtin("dam-break").unwrap();
        let base = scene.memory_estimate();
        let poured = scene.memory_estimate_for(2 * base.fluid_particles);
        assert!(poured.simulation() > base.simulation());
        scene.particle_radius = 0.005;
        let fine = scene.memory_estimate();
        assert_eq!(fine.fluid_particles, 20_000);
        // Four times the particles: close to four times the memory.
        let ratio = fine.simulation() as f64 / base.simulation() as f64;
        assert!((3.5..4.5).contains(&ratio), "{ratio}");
    }
}
