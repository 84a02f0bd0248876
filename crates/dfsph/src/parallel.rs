//! How the step's passes are handed to rayon's workers.
//!
//! A pass that rayon splits between two workers pays for the hand-over: the second worker
//! has to notice the task, steal it, and signal its end. A worker that found nothing to do
//! goes to sleep after a few dozen polls, and waking it takes a system call and, on the
//! 2-core virtual machine of docs/PERFORMANCE.md, 10–50 µs before it runs; a step runs some
//! fifty passes, separated by serial stretches long enough for the second worker to fall
//! asleep in between. [`with_workers_at_hand`] keeps the other workers polling for the
//! whole step instead, so a hand-over is a steal by a worker that is already looking; then
//! even the light passes (a few operations per item: scale an array, advect, reorder, take
//! a maximum) pay for splitting at a few thousand items.

use std::cell::Cell;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Duration;
// The standing-by machinery, which the serial build has no workers for.
#[cfg(feature = "parallel")]
use std::{sync::atomic::AtomicBool, sync::Arc};
#[cfg(feature = "parallel")]
use web_time::Instant;

/// Fewest items a task of a light pass (a few arithmetic operations, or one copy, per
/// item) is given: such a pass over fewer items than this runs on one worker. At about
/// 0.2–1 ns per item this is 0.5–2 µs of work, about what handing a task to a polling
/// worker costs. (Measured at 5,000 particles on two workers, in one process, steps
/// alternating in blocks of 8: 2,048 took 4.5 % less time than 32,768, which runs every
/// light pass there on one worker; 512 took 3 % less.)
pub const LIGHT_PASS_MIN_ITEMS: usize = 2 * 1024;

/// Polls of the pool that find nothing before a worker at hand starts giving its core away
/// between polls (a few hundred µs): the serial stretches of a step are tens of µs, but a
/// pool with more workers than cores must not have them spin through the time slices of
/// the worker that runs the step.
#[cfg(feature = "parallel")]
const IDLE_POLLS_BEFORE_YIELD: u32 = 1 << 12;

/// How long the worker that runs the work waits for the others to join
/// [`with_workers_at_hand`] before it starts without those still missing. A worker that is
/// polling for tasks joins within a microsecond or two; one that has gone to sleep takes
/// 10–50 µs to wake on the virtual machine of docs/PERFORMANCE.md, longer than it would
/// save in a step with a serial stretch in between (the validation runs, which measure
/// the front between steps: 6–9 % slower with a wait for every worker).
#[cfg(feature = "parallel")]
const JOIN_WINDOW: Duration = Duration::from_micros(5);

/// How long after a step ends the pool's idle workers are taken to be still polling for
/// tasks (rayon puts them to sleep after a few dozen rounds of polls and yields): a
/// [`with_workers_at_hand`] call that comes within this of the last one finds them awake
/// to join. One that comes later finds them asleep, and waking them to stand by costs more
/// than it saves: in the validation runs, which measure the front between steps (gaps of
/// hundreds of µs; under 200 µs in 352 of 14,790 steps), steps took 2–3 % longer standing
/// by than not. `dfsph2d run` writes a line of statistics between steps: within 20 µs in
/// 129–188 of 207 steps of the 100k column, within 60 µs in 202.
pub const WORKERS_STILL_POLLING: Duration = Duration::from_micros(50);

/// Calls of [`alone_in_flight`] whose guard is alive: steps in progress, of any
/// simulation on any pool of the process, and lockstep regions started from outside a pool.
static IN_FLIGHT: AtomicUsize = AtomicUsize::new(0);

/// Counts a step (or a lockstep region started from outside a pool) as in progress until
/// the returned guard drops, and says whether nothing else was then in progress. Only a
/// step alone runs [`with_workers_at_hand`]; steps that overlap (tests stepping simulations
/// on one pool at once) run as plain pool jobs, so that no worker stands by, polling, for
/// one step while another step's region could use it as a member.
pub fn alone_in_flight() -> (InFlight, bool) {
    let before = IN_FLIGHT.fetch_add(1, Ordering::AcqRel);
    (InFlight, before == 0)
}

/// A step in progress ([`alone_in_flight`]).
pub struct InFlight;

impl Drop for InFlight {
    fn drop(&mut self) {
        IN_FLIGHT.fetch_sub(1, Ordering::AcqRel);
    }
}

thread_local! {
    /// Set while this thread runs [`with_workers_at_hand`]'s work or stands by for one.
    static AT_HAND_BUSY: Cell<bool> = const { Cell::new(false) };
}

/// Run `work` on a worker of rayon's pool while the pool's other workers stay at hand:
/// instead of going to sleep when it runs out of tasks, each that joins within
/// `JOIN_WINDOW` polls the pool for tasks (and runs them) until `work` returns. Called
/// from inside a pool, or with a pool of one worker, this just runs `work` on the calling
/// thread.
pub fn with_workers_at_hand<R: Send>(work: impl FnOnce() -> R + Send) -> R {
    if crate::par::current_thread_index().is_some() || crate::par::current_num_threads() == 1 {
        return work();
    }
    #[cfg(feature = "parallel")]
    return run_at_hand(None, work, JOIN_WINDOW, Arc::default());
    #[cfg(not(feature = "parallel"))]
    return work();
}

/// [`with_workers_at_hand`] on `pool` (the global pool where `None`), called from outside
/// it, counting the workers standing by in `standing_by`.
///
/// The other workers are invited with `spawn_broadcast`, which does not wait for them, and
/// `work` runs as one pool task: a worker blocked elsewhere holds nothing up. A worker
/// stands by only if it joins before `work` starts: the worker running `work` waits up to
/// `join_window` for the others, then closes the door and starts. (A worker that joined
/// later might be inside a task of `work` it had taken meanwhile, and standing by there
/// would hold that task's result until `work` ended, while `work` waits for it.) A worker
/// asleep when the call came wakes too late and leaves this call's passes to rayon's usual
/// waking, as without this function. A worker already running such work or standing by
/// for another call does not stand by again, so two calls from different threads cannot
/// hold each other's workers.
#[cfg(feature = "parallel")]
fn run_at_hand<R: Send>(
    pool: Option<&rayon::ThreadPool>,
    work: impl FnOnce() -> R + Send,
    join_window: Duration,
    standing_by: Arc<AtomicUsize>,
) -> R {
    let call = Arc::new(AtHand {
        door: AtomicUsize::new(0),
        done: AtomicBool::new(false),
        standing_by,
    });
    let run = || {
        // Ends the standing by also when `work` panics (the panic then reaches the caller).
        // Set before the invitations go out, so that this worker's own is turned down.
        let _end = EndOnDrop {
            done: &call.done,
            was_busy: AT_HAND_BUSY.replace(true),
        };
        // On a worker now: this goes to the pool's workers.
        let invitation = Arc::clone(&call);
        let invited = INVITATIONS.send(rayon::current_num_threads());
        if invited {
            rayon::spawn_broadcast(move |_| {
                INVITATIONS.taken();
                invitation.stand_by();
            });
        }
        let others = rayon::current_num_threads() - 1;
        let opened = Instant::now();
        while invited
            && call.door.load(Ordering::Acquire) < others
            && opened.elapsed() < join_window
        {
            std::hint::spin_loop();
        }
        call.door.fetch_or(CLOSED, Ordering::AcqRel);
        work()
    };
    match pool {
        Some(pool) => pool.install(run),
        None => rayon::scope(|_| run()),
    }
}

/// Set in [`AtHand::door`] once the work has started; the bits below count the workers that
/// joined before.
#[cfg(feature = "parallel")]
const CLOSED: usize = 1 << (usize::BITS - 1);

/// One [`run_at_hand`] call, as its invitations see it.
#[cfg(feature = "parallel")]
struct AtHand {
    door: AtomicUsize,
    /// Set when the work has returned (or unwound).
    done: AtomicBool,
    standing_by: Arc<AtomicUsize>,
}

#[cfg(feature = "parallel")]
impl AtHand {
    /// An invitation: stand by until the work is done, if the door is still open and this
    /// worker is not already running or standing by for such work.
    fn stand_by(&self) {
        if AT_HAND_BUSY.replace(true) {
            return;
        }
        let joined = self
            .door
            .fetch_update(Ordering::AcqRel, Ordering::Acquire, |d| {
                (d & CLOSED == 0).then_some(d + 1)
            })
            .is_ok();
        if joined {
            self.standing_by.fetch_add(1, Ordering::AcqRel);
            wait_until(|| self.done.load(Ordering::Acquire));
            self.standing_by.fetch_sub(1, Ordering::AcqRel);
        }
        AT_HAND_BUSY.set(false);
    }
}

/// Invitations sent to a pool's workers (lockstep regions, standing by) that no worker has
/// taken yet. A worker blocked in an application's task keeps those sent to it in its queue
/// until it is free; past [`Invitations::MAX_PENDING`] (a few hundred kilobytes), no more are
/// sent, and regions run on their caller alone until the queues drain.
pub(crate) struct Invitations {
    pending: AtomicUsize,
}

/// The process's count of untaken invitations (tests of the bound keep their own).
pub(crate) static INVITATIONS: Invitations = Invitations::new();

impl Invitations {
    /// The most invitations left untaken before no more are sent.
    pub const MAX_PENDING: usize = 1024;

    pub const fn new() -> Self {
        Self {
            pending: AtomicUsize::new(0),
        }
    }

    /// Account for an invitation to each of `workers` workers, if the bound allows: whether
    /// to send them.
    pub fn send(&self, workers: usize) -> bool {
        if self.pending.load(Ordering::Relaxed) >= Self::MAX_PENDING {
            return false;
        }
        self.pending.fetch_add(workers, Ordering::Relaxed);
        true
    }

    /// One invitation was taken (accepted or turned down).
    pub fn taken(&self) {
        self.pending.fetch_sub(1, Ordering::Relaxed);
    }

    /// Invitations not yet taken.
    #[cfg(all(test, feature = "parallel"))]
    pub fn pending(&self) -> usize {
        self.pending.load(Ordering::Relaxed)
    }
}

/// Poll the pool for tasks, running them, until `ready()`.
#[cfg(feature = "parallel")]
fn wait_until(ready: impl Fn() -> bool) {
    let mut idle = 0u32;
    while !ready() {
        if rayon::yield_now() == Some(rayon::Yield::Executed) {
            idle = 0;
        } else if idle < IDLE_POLLS_BEFORE_YIELD {
            idle += 1;
            std::hint::spin_loop();
        } else {
            std::thread::yield_now();
        }
    }
}

/// Ends a [`run_at_hand`] call on the worker that ran its work, returned or unwinding.
#[cfg(feature = "parallel")]
struct EndOnDrop<'a> {
    done: &'a AtomicBool,
    was_busy: bool,
}

#[cfg(feature = "parallel")]
impl Drop for EndOnDrop<'_> {
    fn drop(&mut self) {
        AT_HAND_BUSY.set(self.was_busy);
        self.done.store(true, Ordering::Release);
    }
}

/// A pool of `threads` workers, for tests.
#[cfg(all(test, feature = "parallel"))]
pub(crate) fn test_pool(threads: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
}

/// For tests: run `work` on the calling thread while a worker of `pool` is held in a task,
/// from before `work` starts until it ends (also if it panics, so that a failing assertion
/// cannot hang the pool's scope), and return what `work` returned.
#[cfg(all(test, feature = "parallel"))]
pub(crate) fn with_a_worker_held<R>(pool: &rayon::ThreadPool, work: impl FnOnce() -> R) -> R {
    /// Releases the held worker when dropped, also while a panic unwinds.
    struct Release<'a>(&'a AtomicBool);
    impl Drop for Release<'_> {
        fn drop(&mut self) {
            self.0.store(true, Ordering::Release);
        }
    }
    let (held, release) = (AtomicBool::new(false), AtomicBool::new(false));
    pool.in_place_scope(|s| {
        s.spawn(|_| {
            held.store(true, Ordering::Release);
            while !release.load(Ordering::Acquire) {
                std::thread::yield_now();
            }
        });
        while !held.load(Ordering::Acquire) {
            std::hint::spin_loop();
        }
        let _release = Release(&release);
        work()
    })
}

// Standing by needs a pool of several workers.
#[cfg(all(test, feature = "parallel"))]
mod tests {
    use super::*;
    use crate::par::prelude::*;
    use std::time::{Duration, Instant};

    use super::test_pool as pool;

    /// [`run_at_hand`] on `pool`, from this thread (outside the pool, as `Simulation::step`
    /// calls it).
    /// With a join window long enough for every idle worker of a test machine to join.
    fn at_hand_on<R: Send>(
        pool: &rayon::ThreadPool,
        standing_by: &Arc<AtomicUsize>,
        work: impl FnOnce() -> R + Send,
    ) -> R {
        let window = Duration::from_secs(10);
        run_at_hand(Some(pool), work, window, Arc::clone(standing_by))
    }

    /// Within `work`: wait (up to 10 s) until `count` workers stand by, and return how many
    /// did at most.
    fn most_standing_by(standing_by: &AtomicUsize, count: usize) -> usize {
        let start = Instant::now();
        let mut most = 0;
        while start.elapsed() < Duration::from_secs(10) && most < count {
            most = most.max(standing_by.load(Ordering::Acquire));
            std::hint::spin_loop();
        }
        most
    }

    #[test]
    fn the_work_runs_its_passes_and_returns_their_result() {
        let sum = at_hand_on(&pool(2), &Arc::default(), || {
            (0..50u64)
                .map(|pass| {
                    (0..10_000u32)
                        .into_par_iter()
                        .with_min_len(LIGHT_PASS_MIN_ITEMS)
                        .map(|i| i as u64 * pass)
                        .sum::<u64>()
                })
                .sum::<u64>()
        });
        assert_eq!(sum, (0..50u64).sum::<u64>() * (0..10_000u64).sum::<u64>());
    }

    #[test]
    fn the_other_workers_stand_by_while_the_work_runs() {
        let standing_by = Arc::new(AtomicUsize::new(0));
        let most = at_hand_on(&pool(3), &standing_by, || most_standing_by(&standing_by, 2));
        assert_eq!(most, 2, "both other workers of a 3-worker pool stand by");
        let ended = Instant::now();
        while standing_by.load(Ordering::Acquire) > 0 && ended.elapsed().as_secs() < 10 {
            std::thread::yield_now();
        }
        assert_eq!(
            standing_by.load(Ordering::Acquire),
            0,
            "and stop when it ends"
        );
    }

    #[test]
    fn a_worker_that_joins_after_the_work_started_does_not_stand_by() {
        let pool = pool(2);
        // Worker 1 is held in a task until the work has started.
        let release = AtomicBool::new(false);
        let release = &release;
        pool.in_place_scope(|s| {
            s.spawn_broadcast(|_, ctx| {
                if ctx.index() == 1 {
                    while !release.load(Ordering::Acquire) {
                        std::thread::yield_now();
                    }
                }
            });
            let standing_by = Arc::new(AtomicUsize::new(0));
            let most = run_at_hand(
                Some(&pool),
                || {
                    release.store(true, Ordering::Release);
                    let start = Instant::now();
                    let mut most = 0;
                    while start.elapsed() < Duration::from_millis(300) {
                        most = most.max(standing_by.load(Ordering::Acquire));
                    }
                    most
                },
                Duration::from_millis(1),
                Arc::clone(&standing_by),
            );
            assert_eq!(most, 0);
        });
    }

    #[test]
    fn two_threads_running_work_on_one_pool_both_finish() {
        let pool = pool(2);
        let results: Vec<u64> = std::thread::scope(|s| {
            let handles: Vec<_> = (0..2u32)
                .map(|t| {
                    let pool = &pool;
                    s.spawn(move || {
                        let mut total = 0;
                        for _ in 0..200 {
                            // Each call's worker 0 may wait for a worker standing by
                            // for the other call: the window bounds that wait.
                            total += run_at_hand(
                                Some(pool),
                                || {
                                    (0..5_000u32)
                                        .into_par_iter()
                                        .with_min_len(64)
                                        .map(|i| (i + t) as u64)
                                        .sum::<u64>()
                                },
                                JOIN_WINDOW,
                                Arc::default(),
                            );
                        }
                        total
                    })
                })
                .collect();
            handles.into_iter().map(|h| h.join().unwrap()).collect()
        });
        let once = (0..5_000u64).sum::<u64>();
        assert_eq!(results, vec![200 * once, 200 * (once + 5_000)]);
    }

    #[test]
    fn a_panic_in_the_work_ends_the_standing_by_and_reaches_the_caller() {
        let pool = pool(2);
        let caught = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            at_hand_on(&pool, &Arc::default(), || panic!("in the work"))
        }));
        assert!(caught.is_err());
        // Both workers are free again, and the one whose work panicked runs the next.
        let standing_by = Arc::new(AtomicUsize::new(0));
        let most = at_hand_on(&pool, &standing_by, || most_standing_by(&standing_by, 1));
        assert_eq!(most, 1);
    }

    /// While one step is in progress, another is not alone (whatever other tests step
    /// meanwhile), so it does not run at hand.
    #[test]
    fn a_step_that_overlaps_another_is_not_alone() {
        let (_first, _) = alone_in_flight();
        let (_second, alone) = alone_in_flight();
        assert!(!alone);
    }

    /// A worker blocked in another task (until the work is done) holds nothing up: the work
    /// runs on another worker, and the blocked one stands by for none of it.
    #[test]
    fn a_worker_blocked_elsewhere_does_not_hold_up_the_work() {
        let pool = pool(2);
        let sums: Vec<u64> = with_a_worker_held(&pool, || {
            (0..100)
                .map(|_| {
                    run_at_hand(
                        Some(&pool),
                        || {
                            (0..10_000u32)
                                .into_par_iter()
                                .with_min_len(64)
                                .map(u64::from)
                                .sum::<u64>()
                        },
                        Duration::from_micros(50),
                        Arc::default(),
                    )
                })
                .collect()
        });
        assert!(sums.iter().all(|&s| s == (0..10_000u64).sum::<u64>()));
    }

    #[test]
    fn inside_a_pool_the_work_just_runs_on_the_calling_worker() {
        // Each worker of a pool calls it at once: each runs its own work, on itself.
        let ran_on = pool(2).broadcast(|ctx| {
            (
                ctx.index(),
                with_workers_at_hand(rayon::current_thread_index),
            )
        });
        assert_eq!(ran_on, vec![(0, Some(0)), (1, Some(1))]);
    }
}
