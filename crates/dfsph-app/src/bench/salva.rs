//! The peer row: salva2d (crates.io, DFSPH) on the benchmark's initial particles and walls.
//!
//! Same lattice (our `Simulation`'s initial fluid positions), same wall particles (our tank's
//! boundary samples; salva2d computes their Akinci volumes itself), kernel support h = 4r
//! (salva's smoothing factor 2), rest density 1000 kg/m³, particle volume d² (salva's default
//! is 0.8·d²), average density error 0.01 % (`max_density_error` is a fraction: 1e-4),
//! divergence error 0.1 % (salva: percent per step), 2–100 iterations of each solve, XSPH
//! 0.01 between fluid particles, and a fixed Δt (salva2d has no CFL control).

use std::time::{Duration, Instant};

use dfsph::{Simulation, Vec2};
use salva2d::kernel::CubicSplineKernel;
use salva2d::math::Vector;
use salva2d::object::interaction_groups::InteractionGroups;
use salva2d::object::{Boundary, Fluid};
use salva2d::solver::{DFSPHSolver, DfsphParameters, XSPHViscosity};
use salva2d::LiquidWorld;

use super::row::{base_row, bench_scene, front_of, Progress, FRONT_CHECK_TIME, XSPH};
use super::types::{Code, Row, RowArgs};

pub fn run(args: &RowArgs) -> Result<Row, String> {
    let scene = bench_scene(args.spacing);
    let dt = args
        .salva_dt
        .ok_or("salva2d needs a fixed time step (--salva-dt)")?;
    let setup = Instant::now();
    // Our initial state supplies the identical particles and walls.
    let ours = Simulation::new(&scene).map_err(|e| format!("benchmark scene: {e}"))?;
    let d = args.spacing as f32;
    let r = 0.5 * d;
    let support = 4.0 * r;
    let (tank_min, tank_max) = ours.tank_interior();
    let to_na = |p: &Vec2| Vector::new(p.x, p.y);
    let fluid_positions: Vec<_> = ours.positions().iter().map(to_na).collect();
    let wall_positions: Vec<_> = ours.boundary_positions().iter().map(to_na).collect();
    let n = fluid_positions.len();
    let n_boundary = wall_positions.len();
    drop(ours);

    let parameters = DfsphParameters {
        min_pressure_iter: 2,
        max_pressure_iter: 100,
        max_density_error: 1.0e-4,
        min_divergence_iter: 2,
        max_divergence_iter: 100,
        max_divergence_error: 0.1,
    };
    let mut world = LiquidWorld::new(
        DFSPHSolver::<CubicSplineKernel, CubicSplineKernel>::with_parameters(parameters),
        r,
        2.0,
        1.0,
    );
    let mut fluid = Fluid::new(
        fluid_positions,
        r,
        scene.rest_density as f32,
        InteractionGroups::default(),
    );
    fluid.volumes.iter_mut().for_each(|v| *v = d * d);
    fluid
        .nonpressure_forces
        .push(Box::new(XSPHViscosity::new(XSPH as f32, 0.0)));
    let fluid_handle = world.add_fluid(fluid);
    let _ = world.add_boundary(Boundary::new(wall_positions, InteractionGroups::default()));
    let gravity = Vector::new(scene.gravity[0] as f32, scene.gravity[1] as f32);
    let setup_seconds = setup.elapsed().as_secs_f64();

    let positions = |world: &LiquidWorld| -> Vec<Vec2> {
        world.fluids()[fluid_handle]
            .positions
            .iter()
            .map(|p| Vec2::new(p.x, p.y))
            .collect()
    };
    let mut progress = Progress::new(Code::Salva2d, &args.case, args.until);
    let mut steps = 0u64;
    let mut time = 0.0f64;
    let mut front_at_check = None;
    let mut untimed = Duration::ZERO;
    let start = Instant::now();
    while time < args.until - 1.0e-9 {
        world.step(dt as f32, &gravity);
        steps += 1;
        time = steps as f64 * dt;
        if front_at_check.is_none() && time >= FRONT_CHECK_TIME {
            let t = Instant::now();
            front_at_check = front_of(&positions(&world), support, tank_min.x);
            untimed += t.elapsed();
        }
        progress.tick(time, steps);
    }
    let wall = (start.elapsed() - untimed).as_secs_f64();

    let end = positions(&world);
    let mut row = base_row(Code::Salva2d, args, n, n_boundary);
    row.setup_seconds = setup_seconds;
    row.sim_seconds = time;
    row.dt_rule = format!("fixed {dt:e} s");
    row.front_x = front_of(&end, support, tank_min.x).unwrap_or(0.0);
    row.front_x_at_0_4 = front_at_check;
    row.non_finite = end.iter().filter(|p| !p.is_finite()).count() as u64;
    // A particle whose centre is past the centre line of the first wall layer has leaked.
    let (lo, hi) = (tank_min - 0.5 * d, tank_max + 0.5 * d);
    row.leaked = end
        .iter()
        .filter(|p| p.is_finite() && (p.cmplt(lo).any() || p.cmpgt(hi).any()))
        .count() as u64;
    row.finish_timing(wall, steps);
    Ok(row)
}
