//! The GPU passes against the CPU, on the software Vulkan adapter (Mesa's lavapipe). Without
//! one the tests say so and do not run, except on CI, which installs it (`.ci/run`) and where
//! they fail with the device's error.

use dfsph_gpu::{
    AdapterChoice, DensityPass, DeviceParticles, Fold, Gpu, GridLayout, GridPass, Operators,
    ParticleInput, Reductions,
};

fn gpu() -> Option<Gpu> {
    match Gpu::new(AdapterChoice::Software) {
        Ok(gpu) => Some(gpu),
        Err(e) => {
            assert!(
                std::env::var_os("CI").is_none(),
                "CI installs lavapipe (.ci/run): {e}"
            );
            eprintln!("{e}: the GPU passes' tests did not run");
            None
        }
    }
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
    let Some(gpu) = gpu() else { return };
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
fn densities_and_factors_are_the_cpu_solvers() {
    let Some(gpu) = gpu() else { return };
    let (grid, pass) = (GridPass::new(&gpu), DensityPass::new(&gpu));
    for name in ["dam-break", "hydrostatic"] {
        let case = Case::of(name);
        let (sim, kernel, volume) = (&case.sim, *case.sim.kernel(), case.volume);
        let (wall_weight, max_factor) = (case.wall_weight, case.max_factor);
        let particles = DeviceParticles::upload(&gpu, &grid, &case.input());
        let out = pass.run(&gpu, &particles).read(&gpu).unwrap();
        let cpu = sim.density_ratios();
        assert_eq!(out.ratio.len(), cpu.len());
        // The same sums in another order: a few units in the last place of f32.
        let worst = out
            .ratio
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
        // The factors and gradient sums against the formula summed on the host in f64.
        let (pos, wpos, wvol) = (
            sim.positions(),
            sim.boundary_positions(),
            sim.boundary_volumes(),
        );
        let mut capped = 0;
        for i in 0..pos.len() {
            let (mut g, mut scale, mut sq) = (glam_d(0.0, 0.0), 0.0f64, 0.0f64);
            for (j, &xj) in pos.iter().enumerate() {
                if j != i {
                    let gw = kernel.grad_w(pos[i] - xj) * volume;
                    g += glam_d(gw.x as f64, gw.y as f64);
                    scale += gw.length() as f64;
                    sq += gw.length_squared() as f64;
                }
            }
            for (&xb, &vb) in wpos.iter().zip(wvol) {
                let gw = kernel.grad_w(pos[i] - xb) * (vb * wall_weight);
                g += glam_d(gw.x as f64, gw.y as f64);
                scale += gw.length() as f64;
            }
            let got = out.grad_sum[i];
            let err = ((got[0] as f64 - g.0).powi(2) + (got[1] as f64 - g.1).powi(2)).sqrt();
            assert!(err < 1e-5 * scale, "{name}: g_{i} {got:?} against {g:?}");
            let denom = g.0 * g.0 + g.1 * g.1 + sq;
            let want = (1.0 / denom).min(max_factor as f64);
            capped += (want == max_factor as f64) as usize;
            let rel = (out.factor[i] as f64 - want).abs() / want;
            assert!(
                rel < 1e-5,
                "{name}: factor_{i} {} against {want}",
                out.factor[i]
            );
        }
        println!(
            "{name}: {} particles, densities within {worst:e}, {capped} factors at the cap",
            cpu.len()
        );
        // The same bits on a second run.
        assert_eq!(pass.run(&gpu, &particles).read(&gpu).unwrap(), out);
    }
}

/// A built-in scene at r = 2 cm, as the CPU solver starts it, with the GPU passes' inputs.
struct Case {
    sim: dfsph::Simulation,
    fluid: Vec<[f32; 2]>,
    walls: Vec<[f32; 2]>,
    wall_velocities: Vec<[f32; 2]>,
    volume: f32,
    wall_weight: f32,
    max_factor: f32,
}

impl Case {
    fn of(name: &str) -> Self {
        let mut scene = dfsph::scene::builtin(name).unwrap();
        scene.particle_radius = 0.02;
        let sim = dfsph::Simulation::new(&scene).unwrap();
        let v2 = |v: &[dfsph::Vec2]| v.iter().map(|p| [p.x, p.y]).collect::<Vec<_>>();
        let volume = sim.particle_mass() / sim.rest_density();
        let settings = dfsph::settings::SolverSettings::from_scene(&scene);
        let max_factor = settings.max_factor_ratio
            * dfsph::solver::lattice_factor(sim.kernel(), sim.spacing(), volume);
        // Walls sliding along x and y at different speeds, for the flux.
        let walls = v2(sim.boundary_positions());
        let wall_velocities = walls.iter().map(|p| [0.3 * p[1], -0.2 * p[0]]).collect();
        Self {
            fluid: v2(sim.positions()),
            walls,
            wall_velocities,
            volume,
            // The conjugate-gradient solve's mirrored walls count twice in the gradient sum.
            wall_weight: 2.0,
            max_factor,
            sim,
        }
    }

    fn input(&self) -> ParticleInput<'_> {
        ParticleInput {
            fluid: &self.fluid,
            walls: &self.walls,
            wall_volumes: self.sim.boundary_volumes(),
            wall_velocities: &self.wall_velocities,
            volume: self.volume,
            support: self.sim.kernel().support(),
            wall_weight: self.wall_weight,
            max_factor: self.max_factor,
        }
    }
}

#[test]
fn the_rate_and_push_operators_are_the_formulas() {
    let Some(gpu) = gpu() else { return };
    let (grid, density, ops) = (
        GridPass::new(&gpu),
        DensityPass::new(&gpu),
        Operators::new(&gpu),
    );
    let case = Case::of("dam-break");
    let particles = DeviceParticles::upload(&gpu, &grid, &case.input());
    let densities = density.run(&gpu, &particles);
    let g = densities.read(&gpu).unwrap().grad_sum;
    let n = case.fluid.len();
    // A velocity and a stiffness field that vary from particle to particle.
    let vel: Vec<[f32; 2]> = (0..n)
        .map(|i| {
            [
                ((i * 37) % 101) as f32 / 50.0 - 1.0,
                ((i * 53) % 97) as f32 / 48.0 - 1.0,
            ]
        })
        .collect();
    let kappa: Vec<f32> = (0..n).map(|i| ((i * 29) % 89) as f32 * 1e-4).collect();
    let flux = ops.wall_flux(&gpu, &particles);
    let v_buf = gpu.upload("velocity", &vel);
    let rate: Vec<f32> = gpu
        .read(
            &ops.density_rates(&gpu, &particles, &densities, &v_buf, &flux),
            n,
        )
        .unwrap();
    let k_buf = gpu.upload("kappa", &kappa);
    let dv: Vec<[f32; 2]> = gpu
        .read(&ops.pressure_push(&gpu, &particles, &densities, &k_buf), n)
        .unwrap();
    let flux_count: Vec<[f32; 2]> = gpu.read(&flux, n).unwrap();
    let flux: Vec<f32> = flux_count.iter().map(|f| f[0]).collect();
    let kernel = *case.sim.kernel();
    let h2 = kernel.support() * kernel.support();
    let (pos, wpos, wvol) = (
        case.sim.positions(),
        case.sim.boundary_positions(),
        case.sim.boundary_volumes(),
    );
    let (mut moving_walls, mut pushed) = (0, 0);
    for i in 0..n {
        // The walls' flux.
        let (mut f, mut f_scale) = (0.0f64, 0.0f64);
        for (b, (&xb, &vb)) in wpos.iter().zip(wvol).enumerate() {
            let gw = kernel.grad_w(pos[i] - xb);
            let u = case.wall_velocities[b];
            let term = (vb * case.wall_weight) as f64 * (u[0] * gw.x + u[1] * gw.y) as f64;
            f += term;
            f_scale += term.abs();
        }
        assert!(
            (flux[i] as f64 - f).abs() <= 1e-5 * f_scale + 1e-9,
            "flux_{i}"
        );
        moving_walls += (f_scale > 0.0) as usize;
        // The neighbour count: fluid (itself excluded) and walls within the support.
        let close = |x: &[dfsph::Vec2]| {
            x.iter()
                .filter(|&&y| (pos[i] - y).length_squared() < h2)
                .count()
        };
        let count = close(pos) - 1 + close(wpos);
        assert_eq!(flux_count[i][1], count as f32, "neighbours of {i}");
        // The rate and the push.
        let vi = vel[i];
        let mut r = (vi[0] * g[i][0] + vi[1] * g[i][1]) as f64 - flux[i] as f64;
        let mut r_scale = r.abs();
        let mut p = [-(kappa[i] * g[i][0]) as f64, -(kappa[i] * g[i][1]) as f64];
        let mut p_scale = p[0].abs() + p[1].abs();
        for (j, &xj) in pos.iter().enumerate() {
            if j == i {
                continue;
            }
            let gw = kernel.grad_w(pos[i] - xj) * case.volume;
            let t = (vel[j][0] * gw.x + vel[j][1] * gw.y) as f64;
            r -= t;
            r_scale += t.abs();
            p[0] -= (kappa[j] * gw.x) as f64;
            p[1] -= (kappa[j] * gw.y) as f64;
            p_scale += (kappa[j] * gw.length()) as f64;
        }
        assert!(
            (rate[i] as f64 - r).abs() <= 1e-5 * r_scale + 1e-9,
            "rate_{i}: {} against {r}",
            rate[i]
        );
        let err = (dv[i][0] as f64 - p[0]).abs() + (dv[i][1] as f64 - p[1]).abs();
        assert!(
            err <= 1e-5 * p_scale + 1e-12,
            "push_{i}: {:?} against {p:?}",
            dv[i]
        );
        pushed += (p_scale > 0.0) as usize;
    }
    assert!(
        moving_walls > 50 && pushed > n / 2,
        "{moving_walls} {pushed}"
    );
}

/// A point of f64 components (the host's sums).
fn glam_d(x: f64, y: f64) -> D2 {
    D2(x, y)
}

#[derive(Clone, Copy, Debug)]
struct D2(f64, f64);

impl std::ops::AddAssign for D2 {
    fn add_assign(&mut self, o: D2) {
        self.0 += o.0;
        self.1 += o.1;
    }
}

#[test]
fn a_lone_particle_gets_no_factor_and_a_barely_touching_pair_the_cap() {
    let Some(gpu) = gpu() else { return };
    let h = 0.04;
    // No walls at all: the pass must also take empty wall buffers.
    let fluid = [[0.0, 0.0], [1.0, 1.0], [1.0 + 0.9 * h, 1.0]];
    let input = ParticleInput {
        fluid: &fluid,
        walls: &[],
        wall_volumes: &[],
        wall_velocities: &[],
        volume: 4.0e-4,
        support: h,
        wall_weight: 2.0,
        max_factor: 1.0e-3,
    };
    let particles = DeviceParticles::upload(&gpu, &GridPass::new(&gpu), &input);
    let out = DensityPass::new(&gpu)
        .run(&gpu, &particles)
        .read(&gpu)
        .unwrap();
    assert_eq!(out.factor, vec![0.0, 1.0e-3, 1.0e-3], "{out:?}");
    // Alone, a particle's density is its own kernel value, V·W(0).
    let w0 = 40.0 / (7.0 * std::f32::consts::PI * h * h);
    assert!((out.ratio[0] - 4.0e-4 * w0).abs() < 1e-6 * w0, "{out:?}");
}

#[test]
fn reductions_fold_on_the_device_the_same_way_every_run() {
    let Some(gpu) = gpu() else { return };
    let reduce = Reductions::new(&gpu);
    let one = |fold: Fold, a: &[f32], b: Option<&[f32]>| -> f32 {
        let (a_buf, b_buf) = (gpu.upload("a", a), b.map(|b| gpu.upload("b", b)));
        let out = reduce.fold(&gpu, fold, &a_buf, b_buf.as_ref(), a.len());
        gpu.read::<f32>(&out, 1).unwrap()[0]
    };
    // Sizes around the workgroup's 256 and past one level of 256 × 256, and a million.
    for n in [1usize, 255, 256, 257, 65_537, 1_000_003] {
        let a: Vec<f32> = (0..n)
            .map(|i| ((i * 7919) % 1000) as f32 / 100.0 - 4.0)
            .collect();
        let b: Vec<f32> = (0..n)
            .map(|i| ((i * 104_729) % 997) as f32 / 997.0)
            .collect();
        let sum: f64 = a.iter().map(|&x| x as f64).sum();
        let dot: f64 = a.iter().zip(&b).map(|(&x, &y)| x as f64 * y as f64).sum();
        let scale: f64 = a.iter().map(|&x| x.abs() as f64).sum();
        let max = a.iter().copied().fold(f32::MIN, f32::max);
        let got_sum = one(Fold::Sum, &a, None);
        assert!(
            (got_sum as f64 - sum).abs() <= 1e-6 * scale,
            "n = {n}: sum {got_sum} against {sum}"
        );
        assert_eq!(one(Fold::Max, &a, None), max, "n = {n}");
        let got_dot = one(Fold::Dot, &a, Some(&b));
        assert!(
            (got_dot as f64 - dot).abs() <= 1e-6 * scale,
            "n = {n}: dot {got_dot} against {dot}"
        );
        assert_eq!(
            one(Fold::Sum, &a, None).to_bits(),
            got_sum.to_bits(),
            "n = {n}: another run"
        );
    }
    assert_eq!(one(Fold::Sum, &[], None), 0.0);
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
