//! # dfsph-gpu — the solver's passes on the GPU
//!
//! The first parts of the GPU backend (issue 50), in wgpu and WGSL: a device chosen the way
//! the command line will choose it ([`Gpu`]), the neighbour grid built by a counting sort with
//! a deterministic order inside each cell ([`GridPass`]), and the SPH density of every
//! particle from the fluid and the walls with its DFSPH factor ([`DensityPass`]). Each part is checked against the
//! CPU solver on a software Vulkan device (lavapipe) by the tests in `tests/`.
//!
//! Not yet here: the two pressure solves, viscosity, the time step, and
//! the backend that steps a world (`dfsph::backend::Backend`).

mod density;
mod device;
mod grid;

pub use density::{Densities, DensityInput, DensityPass};
pub use device::{AdapterChoice, Gpu, GpuError};
pub use grid::{GridLayout, GridPass, SortedGrid};
