//! Which backend steps a simulation, as a user asks for it (`--backend cpu|gpu|auto`,
//! Python's `backend=`): the factory [`dfsph::Simulation::with_backend`] takes.

use std::sync::{Arc, OnceLock};

use dfsph::simulation::BackendFactory;

use crate::backend::GpuBackend;
use crate::device::{AdapterChoice, Gpu, GpuError};

/// The backend a user asked for.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum BackendChoice {
    /// The CPU backend.
    #[default]
    Cpu,
    /// The GPU backend on a hardware adapter, or on the software one (e.g. Mesa's lavapipe,
    /// which says nothing about speed) where there is none; an error where there is neither.
    Gpu,
    /// The GPU backend on a hardware adapter, the CPU backend where there is none (never a
    /// software adapter).
    Auto,
}

impl std::str::FromStr for BackendChoice {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "cpu" => Ok(Self::Cpu),
            "gpu" => Ok(Self::Gpu),
            "auto" => Ok(Self::Auto),
            _ => Err(format!("`{s}` is not a backend (cpu, gpu or auto)")),
        }
    }
}

/// What [`backend_factory`] found for a choice.
type Opened = Result<(Option<BackendFactory>, Option<String>), GpuError>;

/// The factory of the backend `choice` names (`None`: the CPU backend's) and a note for
/// the user where the choice fell back or runs on a software adapter. The device is opened
/// on the first call for a choice and shared by every simulation of the process.
pub fn backend_factory(choice: BackendChoice) -> Opened {
    static OPENED: [OnceLock<Opened>; 3] = [OnceLock::new(), OnceLock::new(), OnceLock::new()];
    let slot = match choice {
        BackendChoice::Cpu => 0,
        BackendChoice::Gpu => 1,
        BackendChoice::Auto => 2,
    };
    OPENED[slot].get_or_init(|| open(choice)).clone()
}

/// [`backend_factory`]'s work: open the device `choice` asks for.
fn open(choice: BackendChoice) -> Opened {
    let gpu = match choice {
        BackendChoice::Cpu => return Ok((None, None)),
        BackendChoice::Auto => match Gpu::new(AdapterChoice::Hardware) {
            Ok(gpu) => gpu,
            Err(e) => return Ok((None, Some(format!("note: --backend auto: {e}; on the CPU")))),
        },
        BackendChoice::Gpu => match Gpu::new(AdapterChoice::Hardware) {
            Ok(gpu) => gpu,
            Err(_) => Gpu::new(AdapterChoice::Software)?,
        },
    };
    let note = gpu.is_software().then(|| {
        format!(
            "note: the GPU backend runs on the software adapter {}: right, but no measure of \
             a GPU's speed",
            gpu.adapter()
        )
    });
    let gpu = Arc::new(gpu);
    let factory: BackendFactory =
        Arc::new(move |world| Box::new(GpuBackend::new(gpu.clone(), world)));
    Ok((Some(factory), note))
}
