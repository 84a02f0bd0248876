use super::layout::WINDOW;
use super::*;
use crate::kernel::KernelShape;

/// Deterministic pseudo-random numbers in [0, 1).
fn unit(k: u64) -> f32 {
    let x = k.wrapping_mul(0x9E37_79B9_7F4A_7C15).rotate_left(29);
    (x >> 40) as f32 / (1u64 << 24) as f32
}

/// Lists of random lengths (0 to 20, some empty) with random neighbours and gradients.
fn random_lists(n: usize) -> (NeighborLists, Vec<Vec2>) {
    random_lists_ending_with(n, None)
}

/// [`random_lists`], with the last pair's neighbour replaced by `last` when given.
fn random_lists_ending_with(n: usize, last: Option<u32>) -> (NeighborLists, Vec<Vec2>) {
    let mut raw: Vec<Vec<u32>> = Vec::new();
    let mut grads = Vec::new();
    for i in 0..n {
        let len = (unit(i as u64) * 21.0) as usize;
        let mut list = Vec::new();
        for k in 0..len {
            let key = (i * 31 + k) as u64;
            list.push((unit(key) * n as f32) as u32);
            grads.push(Vec2::new(unit(key + 7) - 0.5, unit(key + 13) - 0.5));
        }
        raw.push(list);
    }
    if let Some(j) = last {
        let list = raw.iter_mut().rfind(|l| !l.is_empty()).expect("some pair");
        *list.last_mut().unwrap() = j;
    }
    let mut lists = NeighborLists::default();
    for list in &raw {
        lists.push(list);
    }
    (lists, grads)
}

#[test]
fn both_paths_give_the_per_list_sums() {
    // 16 particles exactly, a partial last block, and none at all.
    for n in [16usize, 1000, 0] {
        let (lists, grads) = random_lists(n);
        let s: Vec<f32> = (0..n).map(|k| unit(k as u64 + 99) - 0.3).collect();
        let v: Vec<Vec2> = (0..n)
            .map(|k| Vec2::new(unit(k as u64 + 5), unit(k as u64 + 6)) - 0.5)
            .collect();
        let mut blocks = BlockedPairs::default();
        blocks.build(&lists, &grads);
        assert_eq!(blocks.blocks(), n.div_ceil(LANES));
        for path in SimdPath::available_paths() {
            blocks.set_simd_path(path);
            for b in 0..blocks.blocks() {
                let (sx, sy) = blocks.weighted_gradient_sums(b, &s);
                let dots = blocks.velocity_gradient_dots(b, &v);
                for l in 0..LANES {
                    let i = b * LANES + l;
                    if i >= n {
                        continue;
                    }
                    let r = lists.range(i);
                    let (mut want, mut dot) = (glam::DVec2::ZERO, 0.0f64);
                    for (&j, g) in lists.of(i).iter().zip(&grads[r]) {
                        want += (s[j as usize] * *g).as_dvec2();
                        dot += v[j as usize].dot(*g) as f64;
                    }
                    let got = glam::DVec2::new(sx[l] as f64, sy[l] as f64);
                    assert!(
                        (got - want).length() < 1e-5,
                        "n {n}, path {path}, particle {i}: {got} against {want}"
                    );
                    assert!(
                        (dots[l] as f64 - dot).abs() < 1e-5,
                        "n {n}, path {path}, particle {i}: {} against {dot}",
                        dots[l]
                    );
                }
            }
        }
    }
}

/// The fused block passes of the Jacobi iterations: the per-particle terms on top of the
/// pair sums, checked against the formulas written out per particle. On each path the
/// terms are the scalar expressions in their order, so they must match the path's own
/// pair sums followed by those expressions bit for bit (a reordered or fused term fails).
#[test]
fn block_passes_add_the_per_particle_terms_of_the_scalar_code() {
    for n in [16usize, 1000, 37] {
        let (lists, grads) = random_lists(n);
        let val = |k: usize, salt: u64| unit(k as u64 * 7 + salt) - 0.3;
        let vec = |k: usize, salt: u64| Vec2::new(val(k, salt), val(k, salt + 1));
        let kappa: Vec<f32> = (0..n).map(|k| val(k, 1)).collect();
        let vel: Vec<Vec2> = (0..n).map(|k| vec(k, 2)).collect();
        let grad_sum: Vec<Vec2> = (0..n).map(|k| vec(k, 4)).collect();
        let wall_flux: Vec<f32> = (0..n).map(|k| val(k, 6)).collect();
        // Some sources of −∞ (particles left out), some residuals clamped at 0.
        let source: Vec<f32> = (0..n)
            .map(|k| {
                if k % 9 == 4 {
                    f32::NEG_INFINITY
                } else {
                    val(k, 7)
                }
            })
            .collect();
        let factor: Vec<f32> = (0..n).map(|k| 1.0 + val(k, 8)).collect();
        let terms = ResidualTerms {
            volume: 0.7,
            grad_sum: &grad_sum,
            wall_flux: &wall_flux,
            source: &source,
            rate_scale: 0.25,
            factor: &factor,
            increment_scale: 3.0,
        };
        let mut blocks = BlockedPairs::default();
        blocks.build(&lists, &grads);
        for path in SimdPath::available_paths() {
            blocks.set_simd_path(path);
            let mut moved = vel.clone();
            let mut total: Vec<f32> = (0..n).map(|k| val(k, 9)).collect();
            let mut delta = vec![0.0f32; n];
            let mut rates = vec![0.0f32; n];
            for b in 0..blocks.blocks() {
                let r = b * LANES..((b + 1) * LANES).min(n);
                let mut errors = [f32::NAN; LANES];
                blocks.residual_block(
                    b,
                    &vel,
                    &terms,
                    &mut delta[r.clone()],
                    &mut rates[r.clone()],
                    &mut errors,
                );
                // Lanes past the last particle hold 0, which adds nothing to the sums.
                assert!(errors[r.len()..].iter().all(|e| e.to_bits() == 0));
                blocks.apply_block(
                    b,
                    terms.volume,
                    &kappa,
                    &grad_sum,
                    &mut moved[r.clone()],
                    Some(&mut total[r.clone()]),
                );
                let dots = blocks.velocity_gradient_dots(b, &vel);
                let (sx, sy) = blocks.weighted_gradient_sums(b, &kappa);
                let (mut want_sum, mut want_max) = (0.0f64, 0.0f64);
                for i in r {
                    let l = i - b * LANES;
                    let rate = vel[i].dot(grad_sum[i]) - 0.7 * dots[l] - wall_flux[i];
                    assert_eq!(rates[i].to_bits(), rate.to_bits(), "path {path}, {i}");
                    let e = (source[i] + 0.25 * rate).max(0.0);
                    assert_eq!(errors[l].to_bits(), e.to_bits(), "path {path}, {i}");
                    let d = e * factor[i] * 3.0;
                    assert_eq!(delta[i].to_bits(), d.to_bits(), "path {path}, n {n}, {i}");
                    (want_sum, want_max) = (want_sum + e as f64, want_max.max(e as f64));
                    let dv = -(kappa[i] * grad_sum[i] + 0.7 * Vec2::new(sx[l], sy[l]));
                    let v = vel[i] + dv;
                    assert_eq!(
                        (moved[i].x.to_bits(), moved[i].y.to_bits()),
                        (v.x.to_bits(), v.y.to_bits()),
                        "path {path}, n {n}, particle {i}"
                    );
                    let t = val(i, 9) + kappa[i];
                    assert_eq!(total[i].to_bits(), t.to_bits(), "path {path}, {i}");
                    // The left-out particles, and the formula against f64.
                    if source[i] == f32::NEG_INFINITY {
                        assert_eq!(d, 0.0);
                    }
                    let rate64 = vel[i].as_dvec2().dot(grad_sum[i].as_dvec2())
                        - 0.7 * dots[l] as f64
                        - wall_flux[i] as f64;
                    let e64 = (source[i] as f64 + 0.25 * rate64).max(0.0);
                    assert!((e as f64 - e64).abs() < 1e-5, "path {path}, {i}");
                }
                let mut group = [[0.0; LANES]; crate::reduce::BLOCKS_TOGETHER];
                group[0] = errors;
                let (sum, max) = crate::reduce::fold_block_sums((0.0, 0.0), &group, 1);
                assert_eq!(sum.to_bits(), want_sum.to_bits(), "path {path}, block {b}");
                assert_eq!(max, want_max, "path {path}, block {b}");
            }
            // Every particle was written: none of the placeholder zeros remain where a
            // residual is positive somewhere in the block.
            assert!(delta.iter().any(|&d| d > 0.0), "path {path}: a real test");
        }
    }
}

/// [`random_lists`] with every list (and its gradients) sorted by neighbour index, as a
/// dense grid's are.
fn sorted_random_lists(n: usize) -> (NeighborLists, Vec<Vec2>) {
    let (raw, raw_grads) = random_lists(n);
    let (mut lists, mut grads) = (NeighborLists::default(), Vec::new());
    for i in 0..n {
        let mut pairs: Vec<(u32, Vec2)> = raw
            .of(i)
            .iter()
            .copied()
            .zip(raw_grads[raw.range(i)].iter().copied())
            .collect();
        pairs.sort_by_key(|p| p.0);
        lists.push(&pairs.iter().map(|p| p.0).collect::<Vec<_>>());
        grads.extend(pairs.iter().map(|p| p.1));
    }
    assert!(lists.ascending());
    (lists, grads)
}

/// The bits of every kernel's results over all blocks, and of the blocks `fill_block`
/// writes, for blocks set up by `setup` before they are built.
fn all_kernel_bits(
    lists: &NeighborLists,
    grads: &[Vec2],
    setup: impl Fn(&mut BlockedPairs),
) -> Vec<u32> {
    let n = lists.len();
    let val = |k: usize, salt: u64| unit(k as u64 * 5 + salt) - 0.4;
    let s: Vec<f32> = (0..n).map(|k| val(k, 1)).collect();
    let pos: Vec<Vec2> = (0..n)
        .map(|k| Vec2::new(val(k, 2), val(k, 3)) * 0.05)
        .collect();
    let vel: Vec<Vec2> = (0..n).map(|k| Vec2::new(val(k, 4), val(k, 5))).collect();
    let mut bits = Vec::new();
    // Every kernel shape, at a support that reaches the lists' neighbours.
    for shape in [KernelShape::CubicSpline, KernelShape::WendlandC2] {
        let kernel = Kernel::new(shape, 0.04);
        let mut blocks = BlockedPairs::default();
        setup(&mut blocks);
        blocks.build(lists, grads);
        let mut push = |v: &[f32]| bits.extend(v.iter().map(|x| x.to_bits()));
        for b in 0..blocks.blocks() {
            let (sx, sy) = blocks.weighted_gradient_sums(b, &s);
            push(&sx);
            push(&sy);
            push(&blocks.velocity_gradient_dots(b, &vel));
            push(&blocks.advected_kernel_sums(b, &pos, &vel, 1e-3, &kernel, 0.5, 0.1));
            let (smooth, laplace) = blocks.viscosity_sums(b, &pos, &vel, &kernel, 1e-6, true);
            for v in smooth.iter().chain(&laplace) {
                push(&[v.x, v.y]);
            }
        }
        let mut writer_sums = Vec::new();
        let mut filled = BlockedPairs::default();
        setup(&mut filled);
        filled.prepare(lists);
        for (b, mut w) in filled.writers(1).into_iter().enumerate() {
            let sums = w.fill_block(b, lists, &pos, &kernel, 0.5, 0.1);
            writer_sums.extend(
                sums.density
                    .iter()
                    .chain(&sums.grad_sq)
                    .map(|x| x.to_bits()),
            );
        }
        // The density pass writes the same indices as `build` (the SIMD path reads them from
        // the lists itself).
        assert_eq!(filled.absolute_indices(), blocks.absolute_indices());
        assert_eq!(filled.relative_indices(), blocks.relative_indices());
        assert_eq!(filled.window_start, blocks.window_start);
        assert_eq!(filled.window_code, blocks.window_code);
        bits.extend(writer_sums);
        bits.extend(
            filled
                .grad_x
                .iter()
                .chain(&filled.grad_y)
                .map(|x| x.to_bits()),
        );
    }
    bits
}

/// Gather instructions and plain loads read the same values, so every SIMD kernel must
/// give the same bits either way, with either kind of index. (Without AVX-512 both runs
/// take the lane kernels.)
#[test]
fn gathers_and_loads_give_identical_bits() {
    for (lists, grads) in [random_lists(333), sorted_random_lists(333)] {
        let run =
            |gather: Gather| all_kernel_bits(&lists, &grads, |blocks| blocks.set_gather(gather));
        let (instruction, loads) = (run(Gather::Instruction), run(Gather::Loads));
        assert_eq!(instruction.len(), loads.len());
        assert!(
            instruction == loads,
            "the two ways of reading neighbours differ"
        );
    }
}

/// The passes over runs of blocks give the bits of one call per block: on both paths,
/// reading through windows and with loads, for runs that end in the partial last block
/// (a run that read another block's entries, or wrote a lane past its particles, would
/// differ).
#[test]
fn passes_over_runs_of_blocks_give_the_per_block_bits() {
    let n = 1000;
    let (lists, grads) = lattice_lists(n, 40, Some(485));
    let val = |k: usize, salt: u64| unit(k as u64 * 3 + salt) - 0.3;
    let vec = |k: usize, salt: u64| Vec2::new(val(k, salt), val(k, salt + 1));
    let kappa: Vec<f32> = (0..n).map(|k| val(k, 1)).collect();
    let vel: Vec<Vec2> = (0..n).map(|k| vec(k, 2)).collect();
    let grad_sum: Vec<Vec2> = (0..n).map(|k| vec(k, 4)).collect();
    let wall_flux: Vec<f32> = (0..n).map(|k| val(k, 6)).collect();
    let source: Vec<f32> = (0..n).map(|k| val(k, 7)).collect();
    let factor: Vec<f32> = (0..n).map(|k| 1.0 + val(k, 8)).collect();
    let terms = ResidualTerms {
        volume: 0.7,
        grad_sum: &grad_sum,
        wall_flux: &wall_flux,
        source: &source,
        rate_scale: 0.25,
        factor: &factor,
        increment_scale: 3.0,
    };
    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    let pair_bits = |v: &[Vec2]| {
        v.iter()
            .flat_map(|p| [p.x.to_bits(), p.y.to_bits()])
            .collect::<Vec<_>>()
    };
    let ways = [
        (SimdPath::Avx512, Gather::Windows),
        (SimdPath::Avx512, Gather::Loads),
        (SimdPath::Fma, Gather::Loads),
        (SimdPath::Portable, Gather::Loads),
    ];
    for (path, gather) in ways.into_iter().filter(|(p, _)| p.available()) {
        let mut blocks = BlockedPairs::default();
        blocks.set_simd_path(path);
        blocks.set_gather(gather);
        blocks.build(&lists, &grads);
        let count = blocks.blocks();
        // Both ways: (delta, rates, errors, velocities, totals).
        let mut outs = Vec::new();
        for run in [1, 5] {
            let (mut delta, mut rates) = (vec![0.0f32; n], vec![0.0f32; n]);
            let mut errors = vec![[f32::NAN; LANES]; count];
            let mut moved = vel.clone();
            let mut total: Vec<f32> = (0..n).map(|k| val(k, 9)).collect();
            for start in (0..count).step_by(run) {
                let blocks_run = start..(start + run).min(count);
                let p = start * LANES..(blocks_run.end * LANES).min(n);
                if run == 1 {
                    let e = &mut errors[start];
                    blocks.residual_block(
                        start,
                        &vel,
                        &terms,
                        &mut delta[p.clone()],
                        &mut rates[p.clone()],
                        e,
                    );
                    blocks.apply_block(
                        start,
                        0.7,
                        &kappa,
                        &grad_sum,
                        &mut moved[p.clone()],
                        Some(&mut total[p]),
                    );
                } else {
                    let e = &mut errors[blocks_run.clone()];
                    blocks.residual_blocks(
                        blocks_run.clone(),
                        &vel,
                        &terms,
                        &mut delta[p.clone()],
                        &mut rates[p.clone()],
                        e,
                    );
                    blocks.apply_blocks(
                        blocks_run,
                        0.7,
                        &kappa,
                        &grad_sum,
                        &mut moved[p.clone()],
                        Some(&mut total[p]),
                    );
                }
            }
            let flat: Vec<f32> = errors.iter().flatten().copied().collect();
            outs.push((
                bits(&delta),
                bits(&rates),
                bits(&flat),
                pair_bits(&moved),
                bits(&total),
            ));
        }
        assert!(outs[0] == outs[1], "path {path}, {gather:?}");
        assert!(
            outs[0].4 != bits(&(0..n).map(|k| val(k, 9)).collect::<Vec<_>>()),
            "a real test"
        );
    }
}

/// Lists of a lattice `width` points wide, numbered row by row, as a grid sorted by cell
/// gives them: each point's neighbours are the other points of its 3×3 patch, with
/// random gradients. Particle `far`, where given, also has the last point as neighbour.
fn lattice_lists(n: usize, width: usize, far: Option<usize>) -> (NeighborLists, Vec<Vec2>) {
    let (mut lists, mut grads) = (NeighborLists::default(), Vec::new());
    for i in 0..n {
        let (x, y) = ((i % width) as i64, (i / width) as i64);
        let mut list = Vec::new();
        for dy in -1..=1 {
            for dx in -1..=1 {
                let (nx, ny) = (x + dx, y + dy);
                let j = ny * width as i64 + nx;
                if (dx, dy) != (0, 0)
                    && (0..width as i64).contains(&nx)
                    && (0..n as i64).contains(&j)
                {
                    list.push(j as u32);
                }
            }
        }
        if far == Some(i) {
            list.push(n as u32 - 1);
        }
        for k in 0..list.len() {
            let key = (i * 31 + k) as u64;
            grads.push(Vec2::new(unit(key + 7) - 0.5, unit(key + 13) - 0.5));
        }
        lists.push(&list);
    }
    assert!(lists.ascending());
    (lists, grads)
}

/// Reading through windows gives every kernel the bits loads give: on lattice lists
/// whose blocks fit (but for one), on random lists that do not, and with fewer
/// particles than a window. (Without AVX-512 both runs take the lane kernels.)
#[test]
fn windows_and_loads_give_identical_bits() {
    let cases = [
        lattice_lists(1000, 40, None),
        lattice_lists(1000, 40, Some(485)),
        lattice_lists(37, 7, None),
        lattice_lists(20, 5, None),
        sorted_random_lists(333),
    ];
    for (c, (lists, grads)) in cases.iter().enumerate() {
        let run =
            |gather: Gather| all_kernel_bits(lists, grads, |blocks| blocks.set_gather(gather));
        assert!(run(Gather::Windows) == run(Gather::Loads), "case {c}");
    }
}

/// Every windowed entry's code names its neighbour, every window lies inside the
/// particles, and a block whose neighbours span four runs is read with loads.
#[test]
#[ignore = "needs an AVX-512F CPU: .ci/run runs the AVX-512 tests where there is one"]
fn avx512_window_codes_name_each_neighbour() {
    // Windows exist on the AVX-512 path only.
    assert!(SimdPath::Avx512.available(), "this CPU has no AVX-512F");
    let n = 1000;
    // Particle 485 (block 30, rows 11–13 of the lattice) also reaches the last point.
    let (lists, grads) = lattice_lists(n, 40, Some(485));
    let mut blocks = BlockedPairs::default();
    // The AVX-512 path even where another one is in use (`DFSPH2D_SIMD=fma|portable`).
    blocks.set_simd_path(SimdPath::Avx512);
    blocks.set_gather(Gather::Windows);
    blocks.build(&lists, &grads);
    assert!(blocks.windows(30).is_none());
    assert_eq!(blocks.windowed_blocks(), blocks.blocks() - 1);
    let absolute = blocks.absolute_indices();
    for b in 0..blocks.blocks() {
        let Some(w) = blocks.windows(b) else {
            continue;
        };
        assert!(
            w.starts.iter().all(|&s| s as usize + WINDOW <= n),
            "block {b}"
        );
        let entries = &absolute[blocks.slots_before(b) * LANES..];
        for (&code, &j) in w.codes.iter().zip(entries) {
            let (window, place) = ((code >> 5) as usize, (code & 31) as u32);
            assert_eq!(w.starts[window] + place, j, "block {b}");
        }
    }
}

/// The same lists stored with relative and with absolute indices give the same bits in
/// every kernel, on both paths (a kernel that read an offset as an index, or missed the
/// own-particle test, would differ).
#[test]
fn relative_and_absolute_indices_give_identical_bits() {
    for n in [1000, 37, 16] {
        let (lists, grads) = sorted_random_lists(n);
        for path in SimdPath::available_paths() {
            let run = |relative: bool| {
                all_kernel_bits(&lists, &grads, |blocks| {
                    blocks.set_simd_path(path);
                    blocks.set_relative_indices(relative);
                })
            };
            assert!(run(true) == run(false), "n {n}, path {path}");
        }
        let mut blocks = BlockedPairs::default();
        blocks.build(&lists, &grads);
        assert!(
            blocks.relative_indices(),
            "n {n}: sorted lists near their blocks"
        );
        assert!(blocks.index.is_empty() && blocks.relative.len() == blocks.entries());
        blocks.set_relative_indices(false);
        blocks.build(&lists, &grads);
        assert!(!blocks.relative_indices());
        assert!(blocks.relative.is_empty() && blocks.index.len() == blocks.entries());
    }
    // Unordered lists: their span is unknown without reading them all.
    let (lists, grads) = random_lists(100);
    let mut blocks = BlockedPairs::default();
    blocks.build(&lists, &grads);
    assert!(!blocks.relative_indices());
}

/// A neighbour 32,767 places after its block's first particle or 32,768 before still
/// fits in 16 bits; one place further does not, and then every block stores absolute
/// indices, with the same sums.
#[test]
fn neighbours_beyond_16_bits_keep_absolute_indices() {
    let n = 40_000;
    // Particle 3 (block 0) and particle 32_790 (block 2,049, first particle 32,784).
    let cases = [
        (3, 32_767, true),
        (3, 32_768, false),
        (32_790, 16, true),
        (32_790, 15, false),
    ];
    for (i, j, fits) in cases {
        let mut lists = NeighborLists::default();
        let mut grads = Vec::new();
        for k in 0..n {
            let list: Vec<u32> = if k == i {
                vec![j]
            } else if k % 500 == 7 {
                vec![k as u32 - 1, k as u32 + 1]
            } else {
                vec![]
            };
            grads.extend(list.iter().map(|&j| Vec2::new(1.0, j as f32 * 1e-4)));
            lists.push(&list);
        }
        let mut blocks = BlockedPairs::default();
        blocks.build(&lists, &grads);
        assert_eq!(
            blocks.relative_indices(),
            fits,
            "particle {i}, neighbour {j}"
        );
        let s: Vec<f32> = (0..n).map(|k| 1.0 + k as f32).collect();
        for k in [i, 7, 39_507] {
            let (sx, sy) = blocks.weighted_gradient_sums(k / LANES, &s);
            let (mut wx, mut wy) = (0.0f32, 0.0f32);
            for (&j, g) in lists.of(k).iter().zip(&grads[lists.range(k)]) {
                wx += s[j as usize] * g.x;
                wy += s[j as usize] * g.y;
            }
            let l = k % LANES;
            assert!(
                (sx[l] - wx).abs() <= 1e-3 * wx.abs(),
                "{i}, {j}, particle {k}"
            );
            assert!(
                (sy[l] - wy).abs() <= 1e-3 * wy.abs().max(1.0),
                "{i}, {j}, {k}"
            );
        }
    }
}

#[test]
fn padding_stays_inside_the_particle_arrays() {
    let (lists, grads) = random_lists(100);
    let mut blocks = BlockedPairs::default();
    blocks.build(&lists, &grads);
    // 7 blocks; every block is as wide as its longest list.
    assert_eq!(blocks.blocks(), 7);
    assert!(blocks.index.iter().all(|&j| (j as usize) < 100));
    let real = lists.pair_count();
    assert!(blocks.entries() >= real);
    let padded = blocks.grad_x.iter().zip(&blocks.grad_y);
    assert_eq!(
        padded.filter(|(x, y)| **x != 0.0 || **y != 0.0).count(),
        grads.iter().filter(|g| **g != Vec2::ZERO).count()
    );
}

#[test]
#[should_panic(expected = "neighbour index out of range")]
fn a_neighbour_index_past_the_particles_is_refused() {
    // The gathers read through these indices unchecked, so they are checked when written.
    let (lists, grads) = random_lists_ending_with(40, Some(40));
    let mut blocks = BlockedPairs::default();
    blocks.build(&lists, &grads);
}

#[test]
#[should_panic(expected = "neighbour index out of range")]
fn the_density_pass_refuses_a_neighbour_index_past_the_particles() {
    // The SIMD path reads the lists itself; it checks before it reads positions.
    let (lists, _) = random_lists_ending_with(40, Some(40));
    let pos = vec![Vec2::ZERO; 40];
    let kernel = Kernel::cubic_spline(0.04);
    let mut blocks = BlockedPairs::default();
    blocks.prepare(&lists);
    for (b, mut w) in blocks.writers(1).into_iter().enumerate() {
        w.fill_block(b, &lists, &pos, &kernel, 0.5, 0.1);
    }
}

#[test]
#[should_panic(expected = "one value per particle")]
fn a_short_value_array_is_refused() {
    let (lists, grads) = random_lists(40);
    let mut blocks = BlockedPairs::default();
    blocks.build(&lists, &grads);
    blocks.weighted_gradient_sums(0, &[0.0; 39]);
}

/// The `fma` lane kernels and the AVX-512 kernels do the same operations in the same order
/// (the pressure sums' multiply-adds fused in both), so they give the same bits. Only a CPU
/// with AVX-512F runs both.
#[test]
#[ignore = "needs an AVX-512F CPU: .ci/run runs the AVX-512 tests where there is one"]
fn the_fma_path_gives_the_avx512_bits() {
    assert!(SimdPath::Avx512.available(), "this CPU has no AVX-512F");
    for (lists, grads) in [
        random_lists(333),
        sorted_random_lists(333),
        lattice_lists(1000, 40, None),
    ] {
        let run = |path| all_kernel_bits(&lists, &grads, |b| b.set_simd_path(path));
        assert!(run(SimdPath::Fma) == run(SimdPath::Avx512));
    }
}

/// The `fma` path fuses the pressure sums' multiply-adds and `portable` does not: the two
/// differ in the last bits of some sums, and only there (the other passes are tested
/// bit-identical above).
#[test]
fn the_fma_path_fuses_the_pressure_sums() {
    if !SimdPath::Fma.available() {
        return;
    }
    let (lists, grads) = sorted_random_lists(333);
    let s: Vec<f32> = (0..333).map(|k| unit(k as u64 + 7) - 0.4).collect();
    let sums = |path| {
        let mut blocks = BlockedPairs::default();
        blocks.set_simd_path(path);
        blocks.build(&lists, &grads);
        (0..blocks.blocks())
            .flat_map(|b| {
                let (x, y) = blocks.weighted_gradient_sums(b, &s);
                x.into_iter().chain(y)
            })
            .collect::<Vec<f32>>()
    };
    let (fused, apart) = (sums(SimdPath::Fma), sums(SimdPath::Portable));
    let differ = fused.iter().zip(&apart).filter(|(a, b)| a != b).count();
    assert!(differ > 0, "no sum rounds differently");
    for (a, b) in fused.iter().zip(&apart) {
        assert!((a - b).abs() <= 1e-5 * a.abs().max(1.0), "{a} against {b}");
    }
}

/// The density pass stores, for every pair on every path, the bits of
/// [`Kernel::w_and_grad`]'s `∇W`: `+0` (its `Vec2::ZERO`) beyond the support, where
/// `r·0` would carry `r`'s sign, and `+0` in the padding. (The AVX-512 kernel once wrote
/// `−0` there, which no sum shows; the gradients are read again by every later pass.)
#[test]
fn the_density_pass_stores_the_scalar_gradients() {
    for (lists, _) in [random_lists(333), lattice_lists(1000, 40, None)] {
        let n = lists.len();
        let pos: Vec<Vec2> = (0..n)
            .map(|k| Vec2::new(unit(k as u64 * 5 + 2), unit(k as u64 * 5 + 3)) - 0.4)
            .map(|p| p * 0.05)
            .collect();
        for (path, shape) in SimdPath::available_paths()
            .flat_map(|p| [(p, KernelShape::CubicSpline), (p, KernelShape::WendlandC2)])
        {
            let kernel = Kernel::new(shape, 0.04);
            let mut blocks = BlockedPairs::default();
            blocks.set_simd_path(path);
            blocks.prepare(&lists);
            for (b, mut w) in blocks.writers(1).into_iter().enumerate() {
                w.fill_block(b, &lists, &pos, &kernel, 0.5, 0.1);
            }
            let (mut beyond, mut negative) = (0, 0);
            for b in 0..blocks.blocks() {
                let e = blocks.slots_before(b) * LANES..blocks.slots_before(b + 1) * LANES;
                for (s, k) in e.step_by(LANES).enumerate() {
                    for l in 0..LANES {
                        let i = b * LANES + l;
                        let list = if i < n { lists.of(i) } else { &[] };
                        let want = list.get(s).map_or(Vec2::ZERO, |&j| {
                            let r = pos[i] - pos[j as usize];
                            let g = kernel.w_and_grad(r).1;
                            beyond += usize::from(g == Vec2::ZERO);
                            negative += usize::from(g == Vec2::ZERO && r.x < 0.0);
                            g
                        });
                        let got = (blocks.grad_x[k + l], blocks.grad_y[k + l]);
                        assert_eq!(
                            (got.0.to_bits(), got.1.to_bits()),
                            (want.x.to_bits(), want.y.to_bits()),
                            "path {path}, {shape:?}, particle {i}, slot {s}"
                        );
                    }
                }
            }
            assert!(
                negative > 0 && beyond > negative,
                "path {path}: a real test"
            );
        }
    }
}
