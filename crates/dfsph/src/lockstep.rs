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
//! workers share arrays that some of them write: within a [`Pass`] (from one barrier to the
//! next) a [`Shared`] array is either read whole by any worker or written part by part, each
//! part by the worker that took it ([`Part`]). Its methods check both at run time (a
//! conflict panics, and the panic reaches the caller), and the borrows they hand out end
//! with the pass, so the solves that use it need no `unsafe`.

use std::marker::PhantomData;
use std::ops::Range;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use web_time::{Duration, Instant};

use crate::parallel::{Invitations, INVITATIONS};

/// Busy-wait rounds at a barrier before the waiting worker starts yielding (about 30–60 µs
/// of `pause`): a pass's shares end within microseconds of each other, but a worker
/// descheduled by the host, or sharing its core with another thread, may be late by a whole
/// time slice, and spinning through that would keep the late one off the core. After that
/// the waiting worker yields its core between polls.
const SPINS_BEFORE_YIELD: u32 = 1 << 11;

/// One worker's view of the region.
pub struct Team<'a> {
    index: usize,
    region: &'a Region,
    /// Barriers this worker has passed: the same count in every worker between two
    /// barriers, so it names the pass at hand ([`Shared`]'s checks).
    passes: usize,
}

impl<'a> Team<'a> {
    /// This worker's number, `0..count()` (in a pass: [`Pass::index`]).
    #[cfg(all(test, feature = "parallel"))]
    pub fn index(&self) -> usize {
        self.index
    }

    /// Members of the region.
    pub fn count(&self) -> usize {
        self.region.count()
    }

    /// Wait until every worker of the region has reached this call: what any worker wrote
    /// before it is visible to every worker after it.
    pub fn wait(&mut self) {
        self.region.wait();
        self.passes += 1;
    }

    /// The pass at hand, until [`Pass::end`]: what [`Shared`] arrays are read and written
    /// through.
    pub fn pass(&mut self) -> Pass<'_, 'a> {
        Pass { team: self }
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

/// One worker's part of a pass: from [`Team::pass`] to [`Pass::end`], the barrier. The
/// slices that [`Shared`] hands out borrow it, so none outlives the pass.
pub struct Pass<'p, 'a> {
    team: &'p mut Team<'a>,
}

impl Pass<'_, '_> {
    /// This worker's number, `0..` the members: the solver's passes need only their
    /// shares, and a value every worker must agree on is read by worker 0 alone.
    pub fn index(&self) -> usize {
        self.team.index
    }

    /// The parts this worker runs in this pass ([`Team::parts`]), each as a [`Part`] that
    /// writes its elements of [`Shared`] arrays.
    pub fn parts(&self, share: Range<usize>) -> impl Iterator<Item = Part<'_>> + '_ {
        let pass = self.team.passes;
        self.team.parts(share).map(move |index| Part {
            index,
            pass,
            _pass: PhantomData,
        })
    }

    /// End the pass: wait at the barrier for every worker.
    pub fn end(self) {
        self.team.wait();
    }
}

/// One part of a pass, taken by this worker alone ([`Pass::parts`]).
pub struct Part<'p> {
    index: usize,
    pass: usize,
    _pass: PhantomData<&'p ()>,
}

impl Part<'_> {
    /// Its number, `0..` the parts of the pass.
    pub fn index(&self) -> usize {
        self.index
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

/// How long the thread that starts a region waits for the pool's other workers to join it
/// before it closes the door and starts with those that did. Workers polling for tasks (a
/// step runs with them at hand, `parallel::with_workers_at_hand`) join within a
/// microsecond or two, once all have joined the wait ends; a worker asleep takes 10–50 µs
/// to wake on the virtual machine of docs/PERFORMANCE.md; a worker that is busy elsewhere,
/// or blocked in an application's task, may never come, and the region runs without it.
const JOIN_WINDOW: Duration = Duration::from_micros(200);

/// Run `body` on the calling thread and on every worker of the current rayon pool that
/// joins within [`JOIN_WINDOW`], at once. Returns each member's result, in member order;
/// the caller is member 0, so a region always has a member and finishes whatever the
/// pool's other workers are doing.
///
/// Progress does not depend on them: the other workers are invited with
/// `par::invite_every_worker` (rayon's `spawn_broadcast`), which does not wait for them; the
/// members are fixed when the door closes, and a barrier waits only for members, which run
/// nothing but `body` until it returns (a barrier spins, then yields its core, and never runs
/// other tasks). An invitation taken after the door closed returns at once.
///
/// If one member panics, the others panic at their next [`Team::wait`] rather than wait
/// for it forever, and the first panic reaches the caller once every member has stopped.
pub fn run<R: Send>(body: impl Fn(&mut Team) -> R + Sync) -> Vec<R> {
    run_joined_within(JOIN_WINDOW, &INVITATIONS, body)
}

/// [`run`], with the workers given `window` to join (the wait ends as soon as all have), and
/// the untaken invitations counted in `invitations`.
fn run_joined_within<R: Send>(
    window: Duration,
    invitations: &'static Invitations,
    body: impl Fn(&mut Team) -> R + Sync,
) -> Vec<R> {
    let workers = crate::par::current_num_threads();
    let outside = crate::par::current_thread_index().is_none();
    // At most every worker, plus the caller where it is not one of them.
    let most = workers + usize::from(outside);
    if workers == 1 {
        let region = Region::new(1);
        region.door.store(CLOSED, Ordering::Release);
        return vec![body(&mut Team {
            index: 0,
            region: &region,
            passes: 0,
        })];
    }
    // Started from outside the pool, the region is pool work in progress just as a step
    // is: no step may run at hand meanwhile (`parallel::alone_in_flight`).
    let _in_flight = outside.then(|| crate::parallel::alone_in_flight().0);
    let region = Arc::new(Region::new(most));
    let results: Vec<Mutex<Option<R>>> = (0..most).map(|_| Mutex::new(None)).collect();
    let member = |index: usize| {
        let mut team = Team {
            index,
            region: &region,
            passes: 0,
        };
        let result = body(&mut team);
        *results[index].lock().unwrap_or_else(|e| e.into_inner()) = Some(result);
    };
    let member: &(dyn Fn(usize) + Sync) = &member;
    // SAFETY: the invitations outlive this call, the closure they reach does not. An
    // invitation calls it only after joining, which only happens before the door closes
    // below, and this function returns only after every member that joined has finished
    // (`wait_for_members`), also when a member or the caller panics. The lifetime is erased
    // for the `'static` bound of `spawn_broadcast`, and restored in this sense.
    let member: &'static (dyn Fn(usize) + Sync) = unsafe { std::mem::transmute(member) };
    let invitation = Invitation {
        region: Arc::clone(&region),
        member: MemberPtr(member as *const _),
    };
    // A worker that stays blocked keeps the invitations sent to it; past a bound, regions
    // run on their caller alone rather than pile up more.
    let invited = invitations.send(workers);
    if invited {
        crate::par::invite_every_worker(move || {
            invitations.taken();
            invitation.accept();
        });
    }

    let opened = Instant::now();
    while invited && region.joined() < most - 1 && opened.elapsed() < window {
        std::hint::spin_loop();
    }
    region.close();
    // Member 0 (this thread); then wait for the others whatever happened.
    let caller = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        let _poison = PoisonOnUnwind(&region);
        member(0);
        std::mem::forget(_poison);
    }));
    region.wait_for_members();
    // A member's own panic before the caller's, which may only echo it at a barrier.
    if let Some(panic) = region
        .panic
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .take()
    {
        std::panic::resume_unwind(panic);
    }
    if let Err(panic) = caller {
        std::panic::resume_unwind(panic);
    }
    let members = region.count();
    results
        .into_iter()
        .take(members)
        .map(|r| {
            r.into_inner()
                .unwrap_or_else(|e| e.into_inner())
                .expect("every member returned")
        })
        .collect()
}

/// Set in [`Region::door`] once the members are fixed; the bits below count the workers
/// that joined the caller.
const CLOSED: usize = 1 << (usize::BITS - 1);

/// A raw pointer to a region's member closure ([`run`]), to send with an invitation.
#[derive(Clone, Copy)]
struct MemberPtr(*const (dyn Fn(usize) + Sync));

// SAFETY: the closure is `Sync`, and [`run`] keeps it alive while any member may call it.
unsafe impl Send for MemberPtr {}
unsafe impl Sync for MemberPtr {}

/// What a worker of the pool is sent when a region starts.
struct Invitation {
    region: Arc<Region>,
    member: MemberPtr,
}

impl Invitation {
    /// Join the region if its door is still open, and run the member closure once the door
    /// has closed; else return at once.
    fn accept(&self) {
        let region = &self.region;
        let Some(index) = region.join() else {
            return;
        };
        while region.door.load(Ordering::Acquire) & CLOSED == 0 {
            // The caller closes the door within JOIN_WINDOW.
            std::hint::spin_loop();
        }
        let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            let _poison = PoisonOnUnwind(region);
            // SAFETY: this member joined before the door closed, and `run` does not return
            // before it has finished (see there).
            unsafe { (*self.member.0)(index) };
            std::mem::forget(_poison);
        }));
        if let Err(panic) = outcome {
            let mut first = region.panic.lock().unwrap_or_else(|e| e.into_inner());
            first.get_or_insert(panic);
        }
        region.finished.fetch_add(1, Ordering::AcqRel);
    }
}

/// What the members of one region share: the door, a counting barrier, and the parts of
/// each member's share not yet taken.
struct Region {
    /// [`CLOSED`] once the members are fixed, plus the number of workers that joined.
    door: AtomicUsize,
    /// Members other than the caller that have finished.
    finished: AtomicUsize,
    arrived: AtomicUsize,
    generation: AtomicUsize,
    poisoned: AtomicBool,
    /// The first panic of a member other than the caller.
    panic: Mutex<Option<Box<dyn std::any::Any + Send>>>,
    /// Per member, the parts of its share not yet taken in the current pass, packed as
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
    /// A region of at most `most` members, its door open.
    fn new(most: usize) -> Self {
        Self {
            door: AtomicUsize::new(0),
            finished: AtomicUsize::new(0),
            arrived: AtomicUsize::new(0),
            generation: AtomicUsize::new(0),
            poisoned: AtomicBool::new(false),
            panic: Mutex::new(None),
            shares: (0..most).map(|_| PaddedAtomic(AtomicU64::new(0))).collect(),
        }
    }

    /// Workers that joined the caller so far.
    fn joined(&self) -> usize {
        self.door.load(Ordering::Acquire) & !CLOSED
    }

    /// Join as the next member, if the door is open and there is room: the member's index.
    fn join(&self) -> Option<usize> {
        let most = self.shares.len();
        self.door
            .fetch_update(Ordering::AcqRel, Ordering::Acquire, |d| {
                (d & CLOSED == 0 && d + 1 < most).then_some(d + 1)
            })
            .ok()
            .map(|before| before + 1)
    }

    /// Fix the members: no worker joins after this.
    fn close(&self) {
        self.door.fetch_or(CLOSED, Ordering::AcqRel);
    }

    /// Members, once the door has closed.
    fn count(&self) -> usize {
        self.joined() + 1
    }

    /// Wait until every member other than the caller has finished.
    fn wait_for_members(&self) {
        let mut spins = 0u32;
        while self.finished.load(Ordering::Acquire) < self.joined() {
            if spins < SPINS_BEFORE_YIELD {
                spins += 1;
                std::hint::spin_loop();
            } else {
                std::thread::yield_now();
            }
        }
    }

    fn wait(&self) {
        let count = self.count();
        if count == 1 {
            return;
        }
        let generation = self.generation.load(Ordering::Acquire);
        if self.arrived.fetch_add(1, Ordering::AcqRel) + 1 == count {
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
            } else {
                // Nothing else is run here: a task taken at a barrier could wait on work
                // that waits on this region. Give the core to the member we wait for.
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

/// A slice the workers of a region share, in parts of `part_len` elements (part k: elements
/// `k·part_len ..`). Within a pass, either any worker reads the whole of it, or each worker
/// writes the parts it took; both are checked as they are asked for. It serves one region.
pub struct Shared<'a, T> {
    ptr: *mut T,
    len: usize,
    part_len: usize,
    /// How the slice is used in the latest pass that used it: `2·pass` read, `2·pass + 1`
    /// written by parts; [`UNUSED`] before the first.
    use_in: AtomicU64,
    /// Per part, one more than the pass that last took it (0: never).
    taken_in: Box<[AtomicUsize]>,
    _borrow: PhantomData<&'a mut [T]>,
}

/// [`Shared::use_in`] before the slice is first used.
const UNUSED: u64 = u64::MAX;

// SAFETY: every access goes through `read` and `part_mut`, which check at run time that no
// element is written by one worker while another reads or writes it within a pass, and whose
// borrows end with the pass (the barrier orders the passes).
unsafe impl<T: Send + Sync> Sync for Shared<'_, T> {}

impl<'a, T> Shared<'a, T> {
    /// Share `values` for the region, in parts of `part_len` elements (borrowed until the
    /// `Shared` is dropped).
    pub fn new(values: &'a mut [T], part_len: usize) -> Self {
        assert!(part_len > 0, "parts of no element");
        Self {
            ptr: values.as_mut_ptr(),
            len: values.len(),
            part_len,
            use_in: AtomicU64::new(UNUSED),
            taken_in: (0..values.len().div_ceil(part_len))
                .map(|_| AtomicUsize::new(0))
                .collect(),
            _borrow: PhantomData,
        }
    }

    /// Every element, to read for the rest of `pass`. Panics if a worker writes a part of
    /// this slice in the same pass.
    pub fn read<'p>(&'p self, pass: &'p Pass) -> &'p [T] {
        self.use_in_pass(pass.team.passes, false);
        // SAFETY: the whole borrowed slice; no worker writes it in this pass (checked), and
        // the borrow ends with the pass.
        unsafe { std::slice::from_raw_parts(self.ptr, self.len) }
    }

    /// The elements of `part`, to write for the rest of its pass. Panics if a worker reads
    /// this slice in the same pass, or if the part of this slice was taken before in it.
    #[allow(clippy::mut_from_ref)]
    pub fn part_mut<'p>(&'p self, part: &'p Part) -> &'p mut [T] {
        self.use_in_pass(part.pass, true);
        let start = part.index * self.part_len;
        assert!(
            start < self.len,
            "part {} of a shared slice of {} in parts of {}",
            part.index,
            self.len,
            self.part_len
        );
        let before = self.taken_in[part.index].swap(part.pass + 1, Ordering::AcqRel);
        assert!(
            before != part.pass + 1,
            "part {} of a shared slice taken twice in one pass",
            part.index
        );
        let end = (start + self.part_len).min(self.len);
        // SAFETY: in bounds (asserted); no other worker reads the slice in this pass, and
        // this part is taken once in it (both checked); the borrow ends with the pass.
        unsafe { std::slice::from_raw_parts_mut(self.ptr.add(start), end - start) }
    }

    /// Record that the slice is read (`write` false) or written by parts in pass `pass`;
    /// panic if it is already used the other way in it. The barrier keeps every worker in
    /// the same pass, so a use from an earlier pass is simply replaced.
    fn use_in_pass(&self, pass: usize, write: bool) {
        let wanted = 2 * pass as u64 + u64::from(write);
        let mut now = self.use_in.load(Ordering::Acquire);
        loop {
            if now == wanted {
                return;
            }
            assert!(
                now == UNUSED || now / 2 != pass as u64,
                "a shared slice read and written in one pass"
            );
            match self.use_in.compare_exchange_weak(
                now,
                wanted,
                Ordering::AcqRel,
                Ordering::Acquire,
            ) {
                Ok(_) => return,
                Err(seen) => now = seen,
            }
        }
    }
}

// The regions' tests need a pool of several workers.
#[cfg(all(test, feature = "parallel"))]
mod tests {
    use super::*;
    use crate::parallel::{test_pool as pool, with_a_worker_held};

    /// [`run`] with every worker of the pool a member: a window long enough for any idle
    /// worker of a test machine to join.
    fn run_all<R: Send>(body: impl Fn(&mut Team) -> R + Sync) -> Vec<R> {
        run_joined_within(Duration::from_secs(10), &INVITATIONS, body)
    }

    /// Every worker reads the whole array each round, after all wrote their parts: a
    /// missing barrier, or parts that overlap or leave gaps, give another sum.
    #[test]
    fn workers_see_each_others_writes_after_the_barrier() {
        for threads in [1, 2, 3, 4] {
            let n = 1000;
            let mut values = vec![1u64; n];
            let shared = Shared::new(&mut values, 7);
            let parts = n.div_ceil(7);
            let sums = pool(threads).install(|| {
                run_all(|team| {
                    let mine = team.share(parts, |k| k as u64);
                    let mut seen = Vec::new();
                    for _ in 0..50 {
                        let pass = team.pass();
                        for part in pass.parts(mine.clone()) {
                            shared.part_mut(&part).iter_mut().for_each(|v| *v *= 2);
                        }
                        pass.end();
                        let pass = team.pass();
                        seen.push(shared.read(&pass).iter().sum::<u64>());
                        pass.end();
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

    /// The text of a caught panic.
    fn message(payload: Box<dyn std::any::Any + Send>) -> String {
        payload
            .downcast_ref::<String>()
            .cloned()
            .or_else(|| payload.downcast_ref::<&str>().map(|s| s.to_string()))
            .unwrap_or_default()
    }

    /// Reading a slice whole and writing a part of it in one pass, or taking a part twice,
    /// panics (in the caller), whichever worker comes first; the same uses in separate
    /// passes do not.
    #[test]
    fn a_slice_read_and_written_in_one_pass_or_a_part_taken_twice_panics() {
        let mut values = vec![0u32; 64];
        let shared = Shared::new(&mut values, 16);
        let read_then_write = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            run(|team| {
                let mine = team.share(4, |k| k as u64);
                let pass = team.pass();
                let whole = shared.read(&pass).len();
                for part in pass.parts(mine.clone()) {
                    shared.part_mut(&part)[0] = 1;
                }
                whole
            })
        }));
        assert!(message(read_then_write.unwrap_err()).contains("read and written in one pass"));
        let mut values = vec![0u32; 64];
        let shared = Shared::new(&mut values, 16);
        let twice = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            run(|team| {
                let mine = team.share(4, |k| k as u64);
                let pass = team.pass();
                for part in pass.parts(mine.clone()) {
                    shared.part_mut(&part)[0] = 1;
                    shared.part_mut(&part)[1] = 1;
                }
            })
        }));
        assert!(message(twice.unwrap_err()).contains("taken twice in one pass"));
        let mut values = vec![0u32; 64];
        let shared = Shared::new(&mut values, 16);
        let sums = run(|team| {
            let mine = team.share(4, |k| k as u64);
            let pass = team.pass();
            for part in pass.parts(mine.clone()) {
                shared.part_mut(&part).fill(2);
            }
            pass.end();
            let pass = team.pass();
            let sum: u32 = shared.read(&pass).iter().sum();
            pass.end();
            let pass = team.pass();
            for part in pass.parts(mine.clone()) {
                shared.part_mut(&part).fill(3);
            }
            pass.end();
            sum
        });
        assert!(sums.iter().all(|&sum| sum == 128), "{sums:?}");
        assert!(values.iter().all(|&v| v == 3));
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
            run_all(|team| {
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
        region.door.store(CLOSED | 2, Ordering::Release);
        // Items 0..10 cost 1 each, items 10..20 cost 9 each: 100 in all.
        let cost = |k: usize| (k.min(10) + 9 * k.saturating_sub(10)) as u64;
        let shares: Vec<_> = (0..3)
            .map(|index| {
                Team {
                    index,
                    region: &region,
                    passes: 0,
                }
                .share(20, cost)
            })
            .collect();
        // Cuts where the cost first reaches 33 and 66: k = 13 (cost 37), k = 17 (cost 73).
        assert_eq!(shares, vec![0..13, 13..17, 17..20]);
        let empty = Team {
            index: 1,
            region: &region,
            passes: 0,
        }
        .share(0, |_| 0);
        assert_eq!(empty, 0..0);
    }

    /// A region started inside another (as a second simulation stepped from within a
    /// parallel job would): worker 1 waits at the outer barrier and cannot join the inner
    /// region, which closes its door without it and runs on worker 0 alone.
    #[test]
    fn a_region_inside_a_region_finishes() {
        let inner_workers = pool(2).install(|| {
            run_all(|team| {
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
        assert_eq!(inner_workers, vec![1, 0]);
    }

    /// A worker blocked in another task (until the regions are done) does not hold them
    /// up: each runs with the members that came, and any one member finishes it alone.
    #[test]
    fn a_worker_blocked_elsewhere_does_not_hold_up_a_region() {
        let pool = pool(3);
        let sums: Vec<Vec<u64>> = with_a_worker_held(&pool, || {
            pool.install(|| {
                (0..200)
                    .map(|_| {
                        run(|team| {
                            let mut sum = 0u64;
                            for pass in 0..5u64 {
                                for p in team.parts(team.share(64, |k| k as u64)) {
                                    sum += p as u64 * pass;
                                }
                                team.wait();
                            }
                            sum
                        })
                    })
                    .collect()
            })
        });
        for s in sums {
            assert!((1..=2).contains(&s.len()), "{} members", s.len());
            assert_eq!(s.iter().sum::<u64>(), (0..64).sum::<u64>() * 10);
        }
    }

    /// A worker blocked for good keeps every invitation sent to it: they stop at a bound, and
    /// the regions go on without inviting.
    #[test]
    fn invitations_to_a_blocked_worker_stop_at_a_bound() {
        // A count of its own, so that other tests running meanwhile still invite.
        static OWN: Invitations = Invitations::new();
        const MAX_PENDING: usize = Invitations::MAX_PENDING;
        let pool = pool(2);
        let (members, pending) = with_a_worker_held(&pool, || {
            pool.install(|| {
                let members: Vec<usize> = (0..MAX_PENDING + 500)
                    .map(|_| run_joined_within(JOIN_WINDOW, &OWN, |team| team.count()).len())
                    .collect();
                // Read on the worker that ran them, before it can take its own invitations.
                (members, OWN.pending())
            })
        });
        assert!(
            (MAX_PENDING..MAX_PENDING + 4).contains(&pending),
            "{pending} pending"
        );
        assert!(members.iter().all(|&m| m == 1), "{members:?}");
    }

    #[test]
    fn a_panicking_worker_reaches_the_caller_instead_of_hanging_the_others() {
        let result = std::panic::catch_unwind(|| {
            pool(2).install(|| {
                run_all(|team| {
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
