//! The backend a command runs its simulation on (`--backend cpu|gpu|auto`): every command
//! that builds a simulation goes through [`simulation`], so all refuse an unavailable GPU
//! with the same one line and say the same where the choice falls back.

use dfsph::memory::MemoryLimits;
use dfsph::simulation::BackendFactory;
use dfsph::{Scene, Simulation};

/// The factory of the backend `choice` names (`None`: the CPU's) and the notes to print,
/// or the one line saying why it cannot be had (which adapters wgpu found). The device is
/// opened on the first call and shared by every simulation of the process.
pub fn factory(choice: Backend) -> Result<(Option<BackendFactory>, Vec<String>), String> {
    let (factory, note) = dfsph_gpu::backend_factory(choice.choice())
        .map_err(|e| format!("--backend {}: {e}", choice.name()))?;
    Ok((factory, note.into_iter().collect()))
}

/// `scene` within `limits` on `factory`'s backend (the CPU's for `None`), and, for the GPU's,
/// a note naming what steps the water: the adapter, or the CPU and why.
pub fn simulation(
    scene: &Scene,
    limits: &MemoryLimits,
    factory: Option<&BackendFactory>,
) -> Result<(Simulation, Option<String>), dfsph::SceneError> {
    let Some(factory) = factory else {
        return Ok((Simulation::new_within(scene, limits)?, None));
    };
    let sim = Simulation::with_backend(scene, limits, factory.clone())?;
    let note = format!("note: the water steps on the {}", sim.backend_description());
    Ok((sim, Some(note)))
}

/// Which backend steps the water (`--backend`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum Backend {
    /// The CPU backend.
    #[default]
    Cpu,
    /// The GPU backend: a hardware adapter, else a software one.
    Gpu,
    /// The GPU backend on a hardware adapter, else the CPU backend.
    Auto,
}

impl Backend {
    /// The GPU crate's name for the choice.
    pub fn choice(self) -> dfsph_gpu::BackendChoice {
        match self {
            Backend::Cpu => dfsph_gpu::BackendChoice::Cpu,
            Backend::Gpu => dfsph_gpu::BackendChoice::Gpu,
            Backend::Auto => dfsph_gpu::BackendChoice::Auto,
        }
    }

    /// How the command line writes it.
    pub fn name(self) -> &'static str {
        match self {
            Backend::Cpu => "cpu",
            Backend::Gpu => "gpu",
            Backend::Auto => "auto",
        }
    }
}
