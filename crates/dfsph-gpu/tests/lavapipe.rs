//! The GPU passes against the CPU, on the software Vulkan adapter (Mesa's lavapipe, which
//! `.ci/run` installs): no test here is skipped for want of an adapter; without one they fail
//! with the device's error.

use dfsph_gpu::{AdapterChoice, DensityInput, DensityPass, Gpu, GridLayout, GridPass};

fn gpu() -> Gpu {
    Gpu::new(AdapterChoice::Software).unwrap_or_else(|e| panic!("{e}"))
}

/// Points scattered over 2 m × 1 m by a fixed sequence, some stacked in one cell, some
/// outside the grid's box on the left (they fall into its first column).
fn points(n: usize) -> Vec<[f32; 2]> {
    let mut state = 0x2545_f491_u32;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 17;
        state ^= state << 5;
        state as f32 / u32::MAX as f32
    };
    (0..n)
        .map(|k| match k % 10 {
            0 => [0.5, 0.5],
            1 => [-0.3, next()],
            _ => [2.0 * next(), next()],
        })
        .collect()
}

#[test]
fn the_grid_is_a_stable_counting_sort_and_the_same_on_every_run() {
    let gpu = gpu();
    let pass = GridPass::new(&gpu);
    let pts = points(5_003);
    // The box of the points in [0, 2] × [0, 1], cells of 0.04 m: 50 × 25.
    let layout = GridLayout::covering(&[[0.0, 0.0], [1.99, 0.99]], 0.04, pts.len());
    assert_eq!((layout.nx, layout.ny), (50, 25));
    let (sorted, starts) = pass.build(&gpu, layout, &pts).read(&gpu).unwrap();
    // The host's keys, by the shader's own f32 operations, and a stable sort by them.
    let key = |p: [f32; 2]| {
        let cx = ((p[0] - layout.origin[0]) * layout.inv_cell).floor();
        let cy = ((p[1] - layout.origin[1]) * layout.inv_cell).floor();
        let cx = cx.clamp(0.0, (layout.nx - 1) as f32) as u32;
        let cy = cy.clamp(0.0, (layout.ny - 1) as f32) as u32;
        cy * layout.nx + cx
    };
    let mut want: Vec<u32> = (0..pts.len() as u32).collect();
    want.sort_by_key(|&i| key(pts[i as usize]));
    assert_eq!(sorted, want);
    let mut want_starts = vec![0u32; layout.cells as usize + 1];
    for p in &pts {
        want_starts[key(*p) as usize + 1] += 1;
    }
    for c in 0..layout.cells as usize {
        want_starts[c + 1] += want_starts[c];
    }
    assert_eq!(starts, want_starts);
    // A cell holding 500 points (every tenth is at (0.5, 0.5)) comes out in index order.
    let again = pass.build(&gpu, layout, &pts).read(&gpu).unwrap();
    assert_eq!(again, (sorted, starts));
}

#[test]
fn densities_are_the_cpu_solvers() {
    let gpu = gpu();
    let pass = DensityPass::new(&gpu);
    for name in ["dam-break", "hydrostatic"] {
        let mut scene = dfsph::scene::builtin(name).unwrap();
        scene.particle_radius = 0.02;
        let sim = dfsph::Simulation::new(&scene).unwrap();
        let v2 = |v: &[dfsph::Vec2]| v.iter().map(|p| [p.x, p.y]).collect::<Vec<_>>();
        let (fluid, walls) = (v2(sim.positions()), v2(sim.boundary_positions()));
        let input = DensityInput {
            fluid: &fluid,
            walls: &walls,
            wall_volumes: sim.boundary_volumes(),
            volume: sim.particle_mass() / sim.rest_density(),
            support: sim.kernel().support(),
        };
        let gpu_density = pass.density_ratios(&gpu, &input).unwrap();
        let cpu = sim.density_ratios();
        assert_eq!(gpu_density.len(), cpu.len());
        // The same sums in another order: a few units in the last place of f32.
        let worst = gpu_density
            .iter()
            .zip(cpu)
            .map(|(g, c)| (g - c).abs() / c)
            .fold(0.0f32, f32::max);
        assert!(worst < 2e-6, "{name}: worst relative difference {worst}");
        // Not a vacuous match: the walls and the free surface move the density.
        let (lo, hi) = cpu
            .iter()
            .fold((f32::MAX, 0.0f32), |(a, b), &s| (a.min(s), b.max(s)));
        assert!(lo < 0.9 && hi > 0.99, "{name}: densities {lo}..{hi}");
        println!(
            "{name}: {} particles, worst relative difference {worst:e}",
            cpu.len()
        );
        // The same bits on a second run.
        assert_eq!(pass.density_ratios(&gpu, &input).unwrap(), gpu_density);
    }
}

#[test]
fn a_hardware_adapter_is_never_a_software_one() {
    // On a machine without a GPU (this test's CI) asking for hardware is an error that says
    // what to install; on one with a GPU it opens that GPU, not the fallback.
    match Gpu::new(AdapterChoice::Hardware) {
        Ok(gpu) => assert!(!gpu.adapter().contains("llvmpipe"), "{}", gpu.adapter()),
        Err(e) => assert!(e.to_string().contains("no hardware GPU adapter"), "{e}"),
    }
}
