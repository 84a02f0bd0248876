//! Parallel float reductions that give the same bits whatever rayon's split of the work.
//!
//! Rayon's `reduce` combines partial results in a tree whose shape follows the work
//! stealing, and floating-point addition is not associative: the same particles could give
//! an average residual that differs in its last bit from one run to the next. The solver
//! compares that average with the tolerance, so a last bit could change an iteration count
//! and, from there, the trajectories (and break a replay). Here the items are cut into at
//! most [`MAX_PARTS`] parts whose bounds depend only on the item count; each part is reduced
//! in item order, and the parts in part order.

use rayon::prelude::*;

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
    combine_in_order(items.par_chunks(per_part).map(|chunk| {
        chunk.iter().fold((0.0, 0.0), |acc, x| {
            let v = value(x);
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
}
