//! Parallel float reductions that give the same bits whatever rayon's split of the work.
//!
//! Rayon's `reduce` combines partial results in a tree whose shape follows the work
//! stealing, and floating-point addition is not associative: the same particles could give
//! an average residual that differs in its last bit from one run to the next. The solver
//! compares that average with the tolerance, so a last bit could change an iteration count
//! and, from there, the trajectories (and break a replay). Here the items are cut into at
//! most [`MAX_PARTS`] parts whose bounds depend only on the item count; each part is reduced
//! in item order, and the parts in part order.

use crate::par::prelude::*;
use crate::parallel::LIGHT_PASS_MIN_ITEMS;

/// The most parts a reduction is cut into; its partial results live on the stack.
pub const MAX_PARTS: usize = 256;

/// Units (items, or blocks of items) per part, for `units` units cut into at most
/// [`MAX_PARTS`] parts of at least `min_units` (so that small inputs are not cut finer than
/// is worth a task).
pub fn part_units(units: usize, min_units: usize) -> usize {
    units.div_ceil(MAX_PARTS).max(min_units).max(1)
}

/// Adds `(sum, max)` pairs: the sums in f64, the largest kept.
#[inline]
pub fn add_sum_max(a: (f64, f64), b: (f64, f64)) -> (f64, f64) {
    (a.0 + b.0, a.1.max(b.1))
}

/// Blocks whose sums [`fold_block_sums`] runs side by side.
pub const BLOCKS_TOGETHER: usize = 8;

/// Fold the first `count` of 8 blocks of 16 values into `acc` in block order: each block's
/// sum taken lane by lane from 0 in f64, and its largest value, added with [`add_sum_max`].
/// The same bits as folding each block's own sum in turn, but the 8 blocks' sums run side
/// by side (in registers, two to a vector): one block's 16 dependent additions are a
/// latency chain that cost 2 % of a 100k step when run one block at a time.
// Indexed loops: lane-major across the blocks is the order that interleaves the chains.
#[allow(clippy::needless_range_loop)]
#[inline]
pub fn fold_block_sums(
    mut acc: (f64, f64),
    blocks: &[[f32; 16]; BLOCKS_TOGETHER],
    count: usize,
) -> (f64, f64) {
    let mut sums = [0.0f64; BLOCKS_TOGETHER];
    let mut maxima = [0.0f32; BLOCKS_TOGETHER];
    for lane in 0..16 {
        for k in 0..BLOCKS_TOGETHER {
            let e = blocks[k][lane];
            sums[k] += e as f64;
            // The largest f32 is the largest f64 too. A comparison rather than `f32::max`,
            // whose NaN rule costs more; a NaN is not kept either way.
            if e > maxima[k] {
                maxima[k] = e;
            }
        }
    }
    for k in 0..count.min(BLOCKS_TOGETHER) {
        acc = add_sum_max(acc, (sums[k], maxima[k] as f64));
    }
    acc
}

/// The `(sum, max)` of each part, computed in parallel (at most [`MAX_PARTS`] parts, whose
/// bounds the caller fixed), combined in part order.
pub fn combine_in_order(parts: impl IndexedParallelIterator<Item = (f64, f64)>) -> (f64, f64) {
    let used = parts.len();
    assert!(used <= MAX_PARTS, "{used} parts, at most {MAX_PARTS}");
    let mut results = [(0.0, 0.0); MAX_PARTS];
    parts
        .zip(results.par_iter_mut())
        .for_each(|(part, slot)| *slot = part);
    results[..used]
        .iter()
        .copied()
        .fold((0.0, 0.0), add_sum_max)
}

/// `Σ_i value(x_i)` and `max_i value(x_i)` (0 when empty), the same bits for any thread
/// count and any work split.
pub fn sum_and_max<T: Sync>(items: &[T], value: impl Fn(&T) -> f64 + Sync) -> (f64, f64) {
    let per_part = part_units(items.len(), 1024);
    let parts = items
        .par_chunks(per_part)
        .with_min_len(LIGHT_PASS_MIN_ITEMS.div_ceil(per_part));
    combine_in_order(parts.map(|chunk| {
        chunk.iter().fold((0.0, 0.0), |acc, x| {
            let v = value(x);
            add_sum_max(acc, (v, v))
        })
    }))
}

/// `Σ_i value(i)` and `max_i value(i)` over `0..n` (0 when empty), the same bits for any
/// thread count and any work split: [`sum_and_max`] for values computed from an index (several
/// arrays at once).
pub fn sum_and_max_of(n: usize, value: impl Fn(usize) -> f64 + Sync) -> (f64, f64) {
    let per_part = part_units(n, 1024);
    let parts = (0..n.div_ceil(per_part))
        .into_par_iter()
        .with_min_len(LIGHT_PASS_MIN_ITEMS.div_ceil(per_part));
    combine_in_order(parts.map(|p| {
        (p * per_part..((p + 1) * per_part).min(n)).fold((0.0, 0.0), |acc, i| {
            let v = value(i);
            add_sum_max(acc, (v, v))
        })
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Values whose f64 sum depends on the order of the additions: every addition rounds.
    fn awkward(n: usize) -> Vec<f64> {
        (0..n)
            .map(|i| ((i * 7919) % 1009) as f64 / 1009.0 + 1.0 / 3.0)
            .collect()
    }

    #[test]
    fn sum_and_max_of_indices_matches_sum_and_max_bit_for_bit() {
        let values = awkward(100_003);
        let by_index = || sum_and_max_of(values.len(), |i| values[i]);
        let direct = sum_and_max(&values, |&v| v);
        // On pools of several sizes where the solver runs in rayon's pools.
        #[cfg(feature = "parallel")]
        let results: Vec<(f64, f64)> = [1, 2, 3, 8]
            .map(|threads| crate::parallel::test_pool(threads).install(by_index))
            .into();
        #[cfg(not(feature = "parallel"))]
        let results = vec![by_index()];
        for (sum, max) in results {
            assert_eq!(
                (sum.to_bits(), max.to_bits()),
                (direct.0.to_bits(), direct.1.to_bits())
            );
        }
    }

    #[test]
    // Thread counts matter only where the solver runs in rayon's pools.
    #[cfg(feature = "parallel")]
    fn sum_and_max_is_the_same_for_any_thread_count() {
        let values = awkward(100_003);
        let run = |threads: usize| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| sum_and_max(&values, |&v| v))
        };
        let one = run(1);
        for threads in [2, 3, 7] {
            let other = run(threads);
            assert_eq!(one.0.to_bits(), other.0.to_bits(), "{threads} threads");
            assert_eq!(one.1, other.1);
        }
        // And it is the sum: within rounding of a plain serial sum.
        let serial: f64 = values.iter().sum();
        assert!(
            (one.0 - serial).abs() <= 1.0e-12 * serial,
            "{} vs {serial}",
            one.0
        );
        assert_eq!(one.1, values.iter().copied().fold(0.0, f64::max));
    }

    #[test]
    fn parts_cover_every_item_within_the_part_limit() {
        for (units, min) in [(0, 1), (1, 1024), (5000, 1024), (100_003, 1024), (6250, 16)] {
            let per = part_units(units, min);
            assert!(per >= min.max(1));
            assert!(
                units.div_ceil(per) <= MAX_PARTS,
                "{units} units, {per} per part"
            );
        }
        assert_eq!(sum_and_max(&[] as &[f64], |&v| v), (0.0, 0.0));
        assert_eq!(sum_and_max(&[2.5f64], |&v| v), (2.5, 2.5));
    }

    /// Side by side or one block at a time, the blocks' sums are the same bits, for any
    /// number of blocks (partial groups included) and a running total to start from.
    #[test]
    fn block_sums_side_by_side_match_one_block_at_a_time() {
        // Values spread over many magnitudes, so that every addition rounds.
        let value = |k: usize| {
            let x = ((k as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 40) as f32;
            x * 10f32.powi((k % 31) as i32 - 15)
        };
        for count in [0, 1, 7, 8, 9, 23] {
            let blocks: Vec<[f32; 16]> = (0..count)
                .map(|b| std::array::from_fn(|l| value(b * 16 + l)))
                .collect();
            let start = (0.1, 0.5);
            let want = blocks.iter().fold(start, |acc, block| {
                let (mut sum, mut max) = (0.0f64, 0.0f64);
                for &e in block {
                    sum += e as f64;
                    max = max.max(e as f64);
                }
                add_sum_max(acc, (sum, max))
            });
            let mut got = start;
            for group in blocks.chunks(BLOCKS_TOGETHER) {
                // Whatever the unused blocks hold is left out.
                let mut padded = [[f32::MAX; 16]; BLOCKS_TOGETHER];
                padded[..group.len()].copy_from_slice(group);
                got = fold_block_sums(got, &padded, group.len());
            }
            assert_eq!(got.0.to_bits(), want.0.to_bits(), "{count} blocks");
            assert_eq!(got.1.to_bits(), want.1.to_bits(), "{count} blocks");
            // And the order matters here: a sum over all values at once differs.
            if count >= 8 {
                let flat: f64 = blocks.iter().flatten().map(|&e| e as f64).sum::<f64>() + 0.1;
                assert_ne!(flat.to_bits(), want.0.to_bits(), "{count}: a real test");
            }
        }
    }
}
