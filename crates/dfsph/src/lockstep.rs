//! A parallel region whose workers run a sequence of passes in step, with a barrier between
//! passes, instead of one rayon fork-join per pass.
//!
//! A Jacobi iteration is two passes (apply an increment, then compute the residuals), and a
//! step runs ten or more iterations. Handed to rayon, every pass is a fork-join: on the
//! 2-core virtual machine of docs/PERFORMANCE.md that costs 2–8 µs (the second worker has
//! to notice the task, steal it and signal its end), where the pass itself takes 20–40 µs at
//! 5,000 particles. Inside one region, the workers of the pool meet at a spinning barrier
//! between passes instead, which costs a fraction of a microsecond.
//!
//! A pass's parts are handed out without rayon's stealing: each worker starts on its own
//! share, the same in every pass (so what it wrote stays in its core's cache), and a worker
//! that runs out takes the parts the others have not reached yet ([`Team::parts`]). The
//! workers share arrays that some of them write: [`Shared`] hands out the parts, and its
//! `unsafe` methods state what the barrier must order.

use std::marker::PhantomData;
use std::ops::Range;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};

/// Busy-wait rounds at a barrier before the waiting worker starts yielding (about 30–60 µs
/// of `pause`): a pass's shares end within microseconds of each other, but a worker
/// descheduled by the host, or sharing its core with another thread, may be late by a whole
/// time slice, and spinning through that would keep the late one off the core. After that
/// the waiting worker runs its own pending work, if any, else yields its core.
const SPINS_BEFORE_YIELD: u32 = 1 << 11;

/// One worker's view of the region.
pub struct Team<'a> {
    index: usize,
    region: &'a Region,
}

impl Team<'_> {
    /// This worker's number, `0..count()`.
    pub fn index(&self) -> usize {
        self.index
    }

    /// Workers in the region.
    pub fn count(&self) -> usize {
        self.region.count
    }

    /// Wait until every worker of the region has reached this call: what any worker wrote
    /// before it is visible to every worker after it.
    pub fn wait(&self) {
        self.region.wait();
    }

    /// This worker's share of `0..items`, cut where `cost_before(k)` (non-decreasing, the
    /// cost of items `0..k`) reaches its fraction of the total; consecutive workers get
    /// consecutive shares that cover `0..items`. The same worker gets the same share in
    /// every pass, so the data it writes stays in its core's cache.
    pub fn share(&self, items: usize, cost_before: impl Fn(usize) -> u64) -> Range<usize> {
        let total = cost_before(items);
        let cut = |w: usize| -> usize {
            if w == 0 {
                return 0;
            }
            if w == self.count() {
                return items;
            }
            let target = (total as u128 * w as u128 / self.count() as u128) as u64;
            // The first k whose cost reaches the target.
            let (mut lo, mut hi) = (0, items);
            while lo < hi {
                let mid = (lo + hi) / 2;
                if cost_before(mid) < target {
                    lo = mid + 1;
                } else {
                    hi = mid;
                }
            }
            lo
        };
        cut(self.index)..cut(self.index + 1)
    }

    /// The parts this worker runs in the current pass, given its `share` (from
    /// [`Team::share`], the same in every pass): first its own share, front to back; then,
    /// one at a time, parts from the back of other workers' shares that they have not
    /// reached yet. So a worker that the host holds up is relieved, while in a pass where
    /// both keep pace every part stays with its owner (and its data in the owner's cache).
    /// Every worker must call this once per pass and drain it before its next
    /// [`Team::wait`].
    pub fn parts(&self, share: Range<usize>) -> Parts<'_> {
        let mine = &self.region.shares[self.index];
        // Before this, every part of the last pass was taken (the barrier ended it), so no
        // worker can be taking from this share meanwhile.
        mine.store(pack(share.start, share.end), Ordering::Release);
        Parts {
            team: self,
            victim: self.index,
        }
    }
}

/// The iterator of [`Team::parts`].
pub struct Parts<'a> {
    team: &'a Team<'a>,
    /// The worker whose share is taken from now: this worker's own first.
    victim: usize,
}

impl Iterator for Parts<'_> {
    type Item = usize;

    fn next(&mut self) -> Option<usize> {
        let team = self.team;
        loop {
            let own = self.victim == team.index;
            let slot = &team.region.shares[self.victim];
            let mut state = slot.load(Ordering::Acquire);
            loop {
                let (front, back) = unpack(state);
                if front >= back {
                    break;
                }
                // The owner takes from the front, the others from the back.
                let (taken, next) = if own {
                    (front, pack(front + 1, back))
                } else {
                    (back - 1, pack(front, back - 1))
                };
                match slot.compare_exchange_weak(state, next, Ordering::AcqRel, Ordering::Acquire) {
                    Ok(_) => return Some(taken),
                    Err(now) => state = now,
                }
            }
            // This share is done: the next worker's, round to this one's own.
            self.victim = (self.victim + 1) % team.count();
            if self.victim == team.index {
                return None;
            }
        }
    }
}

fn pack(front: usize, back: usize) -> u64 {
    ((front as u64) << 32) | back as u64
}

fn unpack(state: u64) -> (usize, usize) {
    ((state >> 32) as usize, (state & 0xffff_ffff) as usize)
}

/// Run `body` on every worker of the current rayon pool at once (one worker when called
/// outside any pool with a one-thread global pool). Returns each worker's result, in worker
/// order.
///
/// If one worker panics, the others panic at their next [`Team::wait`] rather than wait
/// for it forever, and the panic reaches the caller.
pub fn run<R: Send>(body: impl Fn(&Team) -> R + Sync) -> Vec<R> {
    let region = Region::new(rayon::current_num_threads());
    if region.count == 1 {
        return vec![body(&Team {
            index: 0,
            region: &region,
        })];
    }
    // Started from outside the pool, the region is pool work in progress just as a step
    // is: no step may run at hand meanwhile (`parallel::alone_in_flight`).
    let _in_flight = rayon::current_thread_index()
        .is_none()
        .then(|| crate::parallel::alone_in_flight().0);
    rayon::broadcast(|ctx| {
        let team = Team {
            index: ctx.index(),
            region: &region,
        };
        let guard = PoisonOnUnwind(&region);
        let result = body(&team);
        std::mem::forget(guard);
        result
    })
}

/// What the workers of one region share: a counting barrier, and the parts of each
/// worker's share not yet taken.
struct Region {
    arrived: AtomicUsize,
    generation: AtomicUsize,
    count: usize,
    poisoned: AtomicBool,
    /// Per worker, the parts of its share not yet taken in the current pass, packed as
    /// (front, back) ([`Team::parts`]); each on its own cache line.
    shares: Vec<PaddedAtomic>,
}

/// An atomic alone on its cache line, so that the owner's updates do not contend with the
/// other workers' slots.
#[repr(align(64))]
struct PaddedAtomic(AtomicU64);

impl std::ops::Deref for PaddedAtomic {
    type Target = AtomicU64;
    fn deref(&self) -> &AtomicU64 {
        &self.0
    }
}

impl Region {
    fn new(count: usize) -> Self {
        Self {
            arrived: AtomicUsize::new(0),
            generation: AtomicUsize::new(0),
            count,
            poisoned: AtomicBool::new(false),
            shares: (0..count)
                .map(|_| PaddedAtomic(AtomicU64::new(0)))
                .collect(),
        }
    }

    fn wait(&self) {
        if self.count == 1 {
            return;
        }
        let generation = self.generation.load(Ordering::Acquire);
        if self.arrived.fetch_add(1, Ordering::AcqRel) + 1 == self.count {
            // The last to arrive opens the barrier. The reset is ordered before the new
            // generation, which the others acquire before they can arrive again.
            self.arrived.store(0, Ordering::Relaxed);
            self.generation.store(generation + 1, Ordering::Release);
            return;
        }
        let mut spins = 0;
        while self.generation.load(Ordering::Acquire) == generation {
            if self.poisoned.load(Ordering::Relaxed) {
                panic!("another worker of the lockstep region panicked");
            }
            if spins < SPINS_BEFORE_YIELD {
                spins += 1;
                std::hint::spin_loop();
            } else if rayon::yield_local() != Some(rayon::Yield::Executed) {
                // Only this worker's own queue and the broadcasts addressed to it (another
                // region's share, so that a region started by the worker we wait for does
                // not wait on us). Not other work of the pool: a job taken here that forks
                // can end up waiting for its half on the worker we wait for, while that
                // worker, inside the half, has joined this region and waits for us (seen
                // as a hang of the test suite, two tests stepping on the global pool).
                // Nothing to run: give the core away.
                std::thread::yield_now();
            }
        }
    }
}

/// Marks the region poisoned if the worker holding it unwinds.
struct PoisonOnUnwind<'a>(&'a Region);

impl Drop for PoisonOnUnwind<'_> {
    fn drop(&mut self) {
        self.0.poisoned.store(true, Ordering::Relaxed);
    }
}

/// A slice the workers of a region share. Between two barriers, either every worker only
/// reads it, or each worker writes (and reads) only its own part.
pub struct Shared<'a, T> {
    ptr: *mut T,
    len: usize,
    _borrow: PhantomData<&'a mut [T]>,
}

// SAFETY: access goes through the `unsafe` methods below, whose callers guarantee that no
// element is written by one worker while another touches it.
unsafe impl<T: Send + Sync> Sync for Shared<'_, T> {}

impl<'a, T> Shared<'a, T> {
    /// Share `values` for the region (borrowed until the `Shared` is dropped).
    pub fn new(values: &'a mut [T]) -> Self {
        Self {
            ptr: values.as_mut_ptr(),
            len: values.len(),
            _borrow: PhantomData,
        }
    }

    /// Elements `range`, to write.
    ///
    /// # Safety
    /// Until this worker's next [`Team::wait`], no other worker reads or writes any element
    /// of `range`, and this worker holds no other reference into it.
    #[allow(clippy::mut_from_ref)]
    pub unsafe fn part_mut(&self, range: Range<usize>) -> &mut [T] {
        assert!(
            range.start <= range.end && range.end <= self.len,
            "part {range:?} of a shared slice of {}",
            self.len
        );
        // SAFETY: in bounds (asserted); exclusive by the caller's guarantee.
        unsafe { std::slice::from_raw_parts_mut(self.ptr.add(range.start), range.len()) }
    }

    /// Every element, to read.
    ///
    /// # Safety
    /// Until this worker's next [`Team::wait`], no worker writes any element.
    pub unsafe fn read(&self) -> &[T] {
        // SAFETY: the whole borrowed slice; unchanged by the caller's guarantee.
        unsafe { std::slice::from_raw_parts(self.ptr, self.len) }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::parallel::test_pool as pool;

    /// Every worker reads the whole array each round, after all wrote their parts: a
    /// missing barrier, or shares that overlap or leave gaps, give another sum.
    #[test]
    fn workers_see_each_others_writes_after_the_barrier() {
        for threads in [1, 2, 3, 4] {
            let n = 1000;
            let mut values = vec![1u64; n];
            let shared = Shared::new(&mut values);
            let sums = pool(threads).install(|| {
                run(|team| {
                    let mine = team.share(n, |k| k as u64);
                    let mut seen = Vec::new();
                    for _ in 0..50 {
                        // SAFETY: shares are disjoint; reads happen between barriers.
                        let part = unsafe { shared.part_mut(mine.clone()) };
                        part.iter_mut().for_each(|v| *v *= 2);
                        team.wait();
                        seen.push(unsafe { shared.read() }.iter().sum::<u64>());
                        team.wait();
                    }
                    (team.count(), seen)
                })
            });
            assert_eq!(sums.len(), threads);
            for (count, seen) in sums {
                assert_eq!(count, threads);
                let expected: Vec<u64> = (1..=50).map(|r| n as u64 * (1 << r)).collect();
                assert_eq!(seen, expected);
            }
            assert!(values.iter().all(|&v| v == 1 << 50));
        }
    }

    /// Over many passes, every part is taken exactly once per pass; a worker held up (here
    /// by sleeping) has parts of its share taken by the other.
    #[test]
    fn every_part_is_taken_once_and_a_slow_worker_is_relieved() {
        use std::sync::atomic::AtomicU32;
        let parts = 40;
        let passes = 30;
        let taken: Vec<AtomicU32> = (0..parts).map(|_| AtomicU32::new(0)).collect();
        let per_worker = pool(2).install(|| {
            run(|team| {
                let share = team.share(parts, |k| k as u64);
                let mut count = 0;
                for _ in 0..passes {
                    for p in team.parts(share.clone()) {
                        if team.index() == 1 {
                            std::thread::sleep(std::time::Duration::from_micros(200));
                        }
                        taken[p].fetch_add(1, Ordering::Relaxed);
                        count += 1;
                    }
                    team.wait();
                }
                count
            })
        });
        assert!(taken.iter().all(|t| t.load(Ordering::Relaxed) == passes));
        assert_eq!(per_worker.iter().sum::<u32>(), parts as u32 * passes);
        // Without taking from the slow share, worker 0 would run exactly its 20 per pass.
        assert!(per_worker[0] > 20 * passes, "{per_worker:?}");
    }

    #[test]
    fn shares_follow_the_cost_and_cover_the_items() {
        let region = Region::new(3);
        // Items 0..10 cost 1 each, items 10..20 cost 9 each: 100 in all.
        let cost = |k: usize| (k.min(10) + 9 * k.saturating_sub(10)) as u64;
        let shares: Vec<_> = (0..3)
            .map(|index| {
                Team {
                    index,
                    region: &region,
                }
                .share(20, cost)
            })
            .collect();
        // Cuts where the cost first reaches 33 and 66: k = 13 (cost 37), k = 17 (cost 73).
        assert_eq!(shares, vec![0..13, 13..17, 17..20]);
        let empty = Team {
            index: 1,
            region: &region,
        }
        .share(0, |_| 0);
        assert_eq!(empty, 0..0);
    }

    /// A region started inside another (as a second simulation stepped from within a
    /// parallel job would): worker 1 waits at the outer barrier while the inner region
    /// needs it. A barrier that only spins and sleeps would wait for ever; one that runs
    /// the pool's pending work while it waits lets the inner region finish.
    #[test]
    fn a_region_inside_a_region_finishes() {
        let inner_workers = pool(2).install(|| {
            run(|team| {
                let inner = if team.index() == 0 {
                    run(|inner| {
                        inner.wait();
                        inner.index()
                    })
                    .len()
                } else {
                    0
                };
                team.wait();
                inner
            })
        });
        assert_eq!(inner_workers, vec![2, 0]);
    }

    #[test]
    fn a_panicking_worker_reaches_the_caller_instead_of_hanging_the_others() {
        let result = std::panic::catch_unwind(|| {
            pool(2).install(|| {
                run(|team| {
                    if team.index() == 1 {
                        panic!("worker 1 fails");
                    }
                    team.wait();
                })
            })
        });
        assert!(result.is_err());
    }
}
