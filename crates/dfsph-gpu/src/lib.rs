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
//! Not yet here: the two pressure solves, viscosity, the time step, and the backend that
//! steps a world (`dfsph::backend::Backend`).

mod density;
mod device;
mod grid;
mod operators;
mod pairs;
mod reduce;

pub use density::{Densities, DensityPass, DeviceDensities};
pub use device::{AdapterChoice, Gpu, GpuError};
pub use grid::{GridLayout, GridPass, SortedGrid};
pub use operators::Operators;
pub use pairs::{DeviceParticles, ParticleInput};
pub use reduce::{Fold, Reductions};
