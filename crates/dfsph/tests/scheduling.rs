//! The solver's scheduling cannot hang a step on a worker that is busy elsewhere: a step run
//! from inside a pool's tasks while another worker of that pool is blocked (an application
//! task waiting for the step's result) finishes, with the same result as anywhere else, on
//! pools of two to four workers; so does a step from outside any pool while a worker of the
//! global pool is blocked.
//!
//! A pool whose every worker is blocked cannot run anything, this solver's passes included;
//! and a blocking task that a worker steals while it waits inside a step (rayon's
//! work-stealing wait) blocks that step: rayon's rule, not to block in its tasks, stands.
// The solver runs in rayon's pools only in the default `parallel` build.
#![cfg(feature = "parallel")]

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc;

use dfsph::recording::fingerprint;
use dfsph::{scene, Simulation};

/// Steps each run takes.
const STEPS: usize = 40;

/// The dam break at 1,250 particles.
fn small_dam_break() -> dfsph::Scene {
    let mut s = scene::builtin("dam-break").unwrap();
    s.particle_radius = 0.02;
    s
}

/// The final state of [`STEPS`] steps of [`small_dam_break`].
fn stepped() -> u64 {
    let mut sim = Simulation::new(&small_dam_break()).unwrap();
    for _ in 0..STEPS {
        let stats = *sim.step();
        assert_eq!((stats.clamped, stats.non_finite), (0, 0));
    }
    fingerprint(&sim)
}

/// Spawn on `scope` a task that blocks its worker until it receives from `rx`, and return
/// once it is running (so it sits on a worker, not in a queue where a waiting worker could
/// take it).
fn block_a_worker<'s>(spawn: impl FnOnce(Box<dyn FnOnce() + Send + 's>), rx: mpsc::Receiver<u64>) {
    let running = std::sync::Arc::new(AtomicBool::new(false));
    let flag = std::sync::Arc::clone(&running);
    spawn(Box::new(move || {
        flag.store(true, Ordering::Release);
        // The application waits for the result of the steps.
        let _ = rx.recv();
    }));
    while !running.load(Ordering::Acquire) {
        std::thread::yield_now();
    }
}

#[test]
fn a_step_inside_a_pool_whose_other_worker_is_blocked_finishes() {
    let expected = stepped();
    for threads in [2, 3, 4] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        let (tx, rx) = mpsc::channel();
        let (result_tx, result_rx) = mpsc::channel();
        pool.in_place_scope(|s| {
            block_a_worker(|task| s.spawn(move |_| task()), rx);
            s.spawn(move |_| {
                let got = stepped();
                tx.send(got).unwrap();
                result_tx.send(got).unwrap();
            });
        });
        assert_eq!(result_rx.recv().unwrap(), expected, "{threads} workers");
    }
}

#[test]
fn a_step_from_outside_the_pool_while_a_worker_is_blocked_finishes() {
    if rayon::current_num_threads() < 2 {
        // The global pool's only worker blocked: nothing can run on it (see above).
        return;
    }
    let expected = stepped();
    let (tx, rx) = mpsc::channel();
    block_a_worker(rayon::spawn, rx);
    let got = stepped();
    tx.send(got).unwrap();
    assert_eq!(got, expected);
}
