//! The step's shared blocks as the shaders read them (`shaders/step_prelude.wgsl`): the
//! same fields in the same order, each 4 bytes, vectors on 8-byte boundaries.

/// Particles per workgroup of the reductions and of the passes that feed them.
pub(crate) const WIDE: u32 = 256;

/// The step's state on the device (`struct Control`): Δt, the solve in progress and the
/// solves' reports.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct Control {
    pub dt: f32,
    pub last_dt: f32,
    pub running: u32,
    pub iterations: u32,
    pub avg: f32,
    pub max_err: f32,
    pub prev_avg: f32,
    pub prev_max: f32,
    pub take_back: u32,
    pub take_back_parity: u32,
    pub div_iterations: u32,
    pub div_avg: f32,
    pub den_iterations: u32,
    pub den_avg: f32,
    pub den_max: f32,
    pub cfl_dt: f32,
    pub unseen: f32,
    /// The first dispatch size of the divergence and the density solve's iteration after
    /// the last one recorded: not zero when the solve would have gone on
    /// (`recording::Recording`).
    pub div_unfinished: u32,
    pub den_unfinished: u32,
    pub pad: u32,
}

/// One Jacobi solve's constants (`struct Solve`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
pub struct Solve {
    pub density: u32,
    pub min_iterations: u32,
    pub max_iterations: u32,
    pub gated: u32,
    pub tolerance_pct: f32,
    pub max_error_pct: f32,
    pub growth: f32,
    pub warm_share: f32,
    pub min_neighbours: f32,
    pub max_correction_rate: f32,
    pub partials: u32,
    pub groups: u32,
    pub n: u32,
    pub pad: [u32; 3],
}

/// Which increment buffer a bind group holds, and the pass's mode (`struct Slot`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
pub struct Slot {
    pub parity: u32,
    pub mode: u32,
    pub pad: [u32; 2],
}

/// The step's constants from the host (`struct StepConsts`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
pub struct StepConsts {
    pub gravity: [f32; 2],
    pub pointer_at: [f32; 2],
    pub tank_lo: [f32; 2],
    pub tank_hi: [f32; 2],
    pub outer_lo: [f32; 2],
    pub outer_hi: [f32; 2],
    pub wall_v: [f32; 2],
    pub pointer_radius: f32,
    pub pointer_strength: f32,
    pub xsph: f32,
    pub laplace: f32,
    pub friction: f32,
    pub eps2: f32,
    pub cfl: f32,
    pub dt_min: f32,
    pub dt_upper: f32,
    pub accel: f32,
    pub wall_speed: f32,
    pub pulls: u32,
    pub reach: f32,
    pub spacing: f32,
    pub partials: u32,
    pub dt_cap: f32,
    pub ghost_slope: [f32; 2],
}

/// The conjugate-gradient density solve's constants (`struct CgSolve`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
pub struct CgSolve {
    pub min_iterations: u32,
    pub max_iterations: u32,
    pub warm: u32,
    pub n: u32,
    pub tolerance_pct: f32,
    pub max_error_pct: f32,
    pub growth: f32,
    pub min_neighbours: f32,
    pub max_correction_rate: f32,
    pub dead_band: f32,
    pub consistency: f32,
    pub density_speed: f32,
    pub gravity_impulse: f32,
    pub partials: u32,
    pub groups: u32,
    pub coarse_cell: f32,
}

/// The deflation's coarse space on the device (`struct Coarse`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
pub struct Coarse {
    pub origin: [f32; 2],
    pub cell: f32,
    pub count: u32,
    pub cells: [u32; 2],
    pub band: u32,
    pub pad: u32,
}

/// The conjugate-gradient solve's state on the device (`struct CgState`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
pub struct CgState {
    pub rz: f32,
    pub alpha: f32,
    pub beta: f32,
    pub round_off: f32,
    pub energy: [f32; 4],
    pub n_active: f32,
    pub avg: f32,
    pub max_err: f32,
    pub running: u32,
    pub iterations: u32,
    pub take_back: u32,
    pub energies: u32,
    pub coarse_groups: u32,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The sizes the shaders' uniform rules give (multiples of 16 bytes).
    #[test]
    fn the_blocks_have_the_shaders_sizes() {
        assert_eq!(std::mem::size_of::<Control>(), 80);
        assert_eq!(std::mem::size_of::<Solve>(), 64);
        assert_eq!(std::mem::size_of::<Slot>(), 16);
        assert_eq!(std::mem::size_of::<StepConsts>(), 128);
        assert_eq!(std::mem::size_of::<CgSolve>(), 64);
        assert_eq!(std::mem::size_of::<CgState>(), 64);
        assert_eq!(std::mem::size_of::<Coarse>(), 32);
    }
}
