//! # dfsph-gpu — the solver's passes on the GPU
//!
//! The first parts of the GPU backend (issue 50), in wgpu and WGSL: a device chosen the way
//! the command line will choose it ([`Gpu`]), the neighbour grid built by a counting sort with
//! a deterministic order inside each cell ([`GridPass`]), the particles on the device
//! ([`DeviceParticles`]), every fluid particle's density, gradient sum and DFSPH factor
//! ([`DensityPass`]), and the two operators every pressure solve is built from: the density
//! rate of a velocity field and the push of a stiffness field ([`Operators`]), and reductions
//! that stay on the device ([`Reductions`]: sums, maxima, dot products). Each part is
//! checked against the CPU solver's formulas on a software Vulkan device (lavapipe) by the
//! tests in `tests/`.
//!
//! The whole step ([`DeviceStep`]: both solves, the Jacobi iteration and the deflated
//! conjugate gradients, with their stopping rules on the device, the forces, Δt, advection
//! and containment, one submission and one read-back a step) and the backend that steps a world with it ([`GpuBackend`], which hands what the
//! device does not do yet to the CPU backend and says so).

mod backend;
mod choice;
mod density;
mod device;
mod grid;
mod operators;
mod pairs;
mod reduce;
mod step;

pub use backend::GpuBackend;
pub use choice::{backend_factory, BackendChoice};
pub use density::{Densities, DensityPass, DeviceDensities};
pub use device::{AdapterChoice, Gpu, GpuError};
pub use grid::{GridLayout, GridPass, SortedGrid};
pub use operators::Operators;
pub use pairs::{DeviceParticles, ParticleInput};
pub use reduce::{Fold, Reductions};
pub use step::recording::{Recording, RecordingCounts};
pub use step::{
    CgSolve, CgState, Control, DensitySolve, DeviceStep, Solve, StepConsts, StepInput, StepOutput,
};
