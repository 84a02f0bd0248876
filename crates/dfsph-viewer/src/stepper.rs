//! The simulation steps on a thread of its own while the window draws.
//!
//! A frame hands the simulation to the stepping thread when it has read what it draws, and
//! takes it back at the start of the next frame: the steps run while egui tessellates and the
//! GPU (or the software rasteriser) draws, so a slow frame does not slow the water, and a
//! slow step holds a frame up by at most the one step in progress. Everything the viewer does
//! to the simulation (actions, resets, the single step, reading it for the HUD, plots,
//! recordings and files) happens while it is home, between steps, exactly as before.
//!
//! The stepping thread keeps simulated time on the wall clock ([`Pacer`]): it never runs
//! ahead of `time scale × wall time`, and what it cannot keep up with is dropped rather than
//! owed, so a slow scene runs slower than real time instead of falling ever further behind.

//!
//! The single-threaded page has no thread to spare: there the steps run at the start of the
//! next frame instead ([`Stepper::bring_home`]), for the wall time the frame took, within a
//! budget ([`stepping_budget`]), so the page keeps answering input.
//!
//! The threaded page (feature `threads`: WebAssembly threads, rayon's pool on Web Workers)
//! steps as the desktop does, on a task of the pool instead of a thread of its own, and the
//! page's main thread, which may not block (no `Atomics.wait` there), never waits on a
//! channel. The task returns the simulation by itself a little before the next frame is
//! expected (90 % of the last frame's time away, less a step), so a frame usually finds it
//! home; one that does not tells the task to stop and polls for its return (`try_recv`, a
//! spin), at most the step in progress, exactly the wait of a desktop frame.

use std::ops::{Deref, DerefMut};
#[cfg(any(not(target_arch = "wasm32"), feature = "threads"))]
use std::sync::atomic::{AtomicBool, Ordering};
#[cfg(any(not(target_arch = "wasm32"), feature = "threads"))]
use std::sync::{mpsc, Arc};
#[cfg(not(target_arch = "wasm32"))]
use std::thread::JoinHandle;
#[cfg(any(not(target_arch = "wasm32"), feature = "threads"))]
use web_time::Duration;
use web_time::Instant;

use dfsph::{Simulation, StepStats};

/// How far simulated time may lag the wall clock before the rest is dropped, in wall
/// seconds: a few frames' worth, so that one slow frame is caught up and a slow scene is not.
const MAX_LAG: f64 = 0.05;
/// In the browser, the wall seconds a frame may spend stepping when the last frame was drawn
/// quickly: the page stays responsive (at least ~20 frames a second around the steps), and
/// what does not fit is owed or dropped by the [`Pacer`] as on the stepping thread.
#[cfg(any(all(target_arch = "wasm32", not(feature = "threads")), test))]
pub const FRAME_STEPPING_BUDGET: f64 = 0.04;
/// The threaded page: the share of the last frame's time away after which the stepping
/// starts no step that would not end in time, and returns.
#[cfg(all(target_arch = "wasm32", feature = "threads"))]
const HOME_BY_FRACTION: f64 = 0.9;
/// How long the stepping thread waits before looking again when it is ahead of the clock.
#[cfg(any(not(target_arch = "wasm32"), feature = "threads"))]
const AHEAD_NAP: Duration = Duration::from_micros(500);

/// Real-time pacing: how much simulated time the stepping may cover after `wall` seconds
/// away, given what it was behind (positive) or ahead (negative) when it left.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Pacer {
    /// Simulated seconds owed from before (negative: the last step ran ahead).
    pub carry: f64,
}

impl Pacer {
    /// Simulated seconds the stepping may have covered after `wall` seconds at `time_scale`.
    pub fn allowed(&self, wall: f64, time_scale: f64) -> f64 {
        self.carry + time_scale * wall
    }

    /// After covering `simulated` seconds in `wall` seconds at `time_scale`: carry the
    /// difference, up to `MAX_LAG` (50 ms) of wall time behind (the rest is dropped, and returned)
    /// and one step ahead.
    pub fn settle(&mut self, simulated: f64, wall: f64, time_scale: f64) -> f64 {
        let owed = self.allowed(wall, time_scale) - simulated;
        let most = MAX_LAG * time_scale;
        self.carry = owed.min(most);
        (owed - most).max(0.0)
    }
}

/// What the stepping thread is given: the simulation and how to pace it.
#[cfg(any(not(target_arch = "wasm32"), feature = "threads"))]
struct Job {
    sim: Box<Simulation>,
    time_scale: f64,
    pacer: Pacer,
    /// Wall seconds after which no step is started that would not end by then (the page:
    /// home before the next frame looks for it); `None`: until told to stop (native).
    home_by: Option<f64>,
}

/// What comes back: the simulation, the steps taken and how long they took.
#[cfg(any(not(target_arch = "wasm32"), feature = "threads"))]
struct Returned {
    sim: Box<Simulation>,
    steps: Vec<StepStats>,
    simulated: f64,
    /// Wall seconds spent in the steps.
    busy: f64,
    wall: f64,
}

/// What a frame learns when it takes the simulation back.
#[derive(Debug, Default)]
pub struct Away {
    /// The steps taken while away, in order.
    pub steps: Vec<StepStats>,
    /// Simulated seconds they covered.
    pub simulated: f64,
    /// Wall seconds spent in those steps (the rest of the time away the stepping waited
    /// for the clock): `simulated / busy` is how fast this machine could run the scene.
    pub busy: f64,
    /// Wall seconds the simulation was away.
    pub wall: f64,
    /// Simulated seconds owed but dropped because the stepping fell behind.
    pub dropped: f64,
}

/// The simulation, at home (the window reads and changes it) or away (stepping). It
/// dereferences to the simulation while at home; the window takes it back
/// ([`Self::bring_home`]) before anything reads it in a frame.
#[cfg(any(not(target_arch = "wasm32"), feature = "threads"))]
pub struct Stepper {
    home: Option<Box<Simulation>>,
    /// Worker threads the steps run on.
    threads: usize,
    /// Jobs for the stepping thread (native; the page spawns a pool task per job instead).
    #[cfg(not(target_arch = "wasm32"))]
    jobs: Option<mpsc::Sender<Job>>,
    /// Where a pool task sends the simulation back (the page).
    #[cfg(target_arch = "wasm32")]
    outbox: mpsc::Sender<Returned>,
    returns: mpsc::Receiver<Returned>,
    stop: Arc<AtomicBool>,
    pacer: Pacer,
    time_scale: f64,
    /// The stepping thread (native).
    #[cfg(not(target_arch = "wasm32"))]
    worker: Option<JoinHandle<()>>,
    /// The page: when the simulation was sent away.
    #[cfg(target_arch = "wasm32")]
    sent: Option<Instant>,
    /// The page: how long it was away the last time, in wall seconds (about a frame).
    #[cfg(target_arch = "wasm32")]
    last_away: Option<f64>,
}

#[cfg(any(not(target_arch = "wasm32"), feature = "threads"))]
impl Stepper {
    /// Start the stepping thread (native), with `sim` at home, stepping on rayon's pool.
    pub fn new(sim: Simulation) -> Self {
        Self::with_threads(sim, None)
    }

    /// [`Self::new`], the steps run on a pool of their own of `threads` workers (native;
    /// `None`, or a pool that cannot start: rayon's global pool). Steps give the same bits on
    /// any thread count; this only shares the cores with the drawing ([`crate::threads`]).
    pub fn with_threads(sim: Simulation, threads: Option<usize>) -> Self {
        let (outbox, returns) = mpsc::channel();
        let stop = Arc::new(AtomicBool::new(false));
        #[cfg(not(target_arch = "wasm32"))]
        let pool = threads.and_then(|n| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(n)
                .thread_name(|i| format!("dfsph2d-solver-{i}"))
                .build()
                .ok()
        });
        // The threaded page steps on rayon's pool of Web Workers whatever is asked.
        #[cfg(target_arch = "wasm32")]
        let pool: Option<rayon::ThreadPool> = threads.and(None);
        let threads = pool
            .as_ref()
            .map_or_else(rayon::current_num_threads, |p| p.current_num_threads());
        #[cfg(not(target_arch = "wasm32"))]
        let (jobs, worker) = {
            let (jobs, inbox) = mpsc::channel::<Job>();
            let stop_flag = Arc::clone(&stop);
            let worker = std::thread::Builder::new()
                .name("dfsph2d-stepping".into())
                .spawn(move || {
                    for job in inbox {
                        let back = match &pool {
                            Some(pool) => pool.install(|| step_paced(job, &stop_flag)),
                            None => step_paced(job, &stop_flag),
                        };
                        if outbox.send(back).is_err() {
                            break;
                        }
                    }
                })
                .expect("a thread starts");
            (jobs, worker)
        };
        Self {
            home: Some(Box::new(sim)),
            threads,
            #[cfg(not(target_arch = "wasm32"))]
            jobs: Some(jobs),
            #[cfg(target_arch = "wasm32")]
            outbox,
            returns,
            stop,
            pacer: Pacer::default(),
            time_scale: 1.0,
            #[cfg(not(target_arch = "wasm32"))]
            worker: Some(worker),
            #[cfg(target_arch = "wasm32")]
            sent: None,
            #[cfg(target_arch = "wasm32")]
            last_away: None,
        }
    }

    /// Worker threads the steps run on.
    pub fn threads(&self) -> usize {
        self.threads
    }

    /// Replace the simulation (a reset or another scene); the pacing starts afresh.
    pub fn replace(&mut self, sim: Simulation) {
        self.bring_home();
        self.home = Some(Box::new(sim));
        self.pacer = Pacer::default();
    }

    /// Forget what the pacing owed (after a pause).
    pub fn reset_pace(&mut self) {
        self.pacer = Pacer::default();
    }

    /// Hand the simulation to the stepping thread, to step at `time_scale` × real time until
    /// [`Self::bring_home`].
    pub fn send_away(&mut self, time_scale: f64) {
        #[cfg(not(target_arch = "wasm32"))]
        let (Some(sim), Some(jobs)) = (self.home.take(), &self.jobs) else {
            return;
        };
        #[cfg(target_arch = "wasm32")]
        let Some(sim) = self.home.take() else {
            return;
        };
        if time_scale != self.time_scale {
            self.pacer = Pacer::default();
            self.time_scale = time_scale;
        }
        self.stop.store(false, Ordering::Release);
        #[cfg(not(target_arch = "wasm32"))]
        let home_by = None;
        // The page: back a little before a frame as long as the last one, so that the frame
        // finds it home rather than waiting for (spinning through) a step.
        #[cfg(target_arch = "wasm32")]
        let home_by = self.last_away.map(|away| HOME_BY_FRACTION * away);
        let job = Job {
            sim,
            time_scale,
            pacer: self.pacer,
            home_by,
        };
        #[cfg(not(target_arch = "wasm32"))]
        if let Err(mpsc::SendError(job)) = jobs.send(job) {
            // The thread is gone (it panicked while stepping before): keep stepping nothing.
            self.home = Some(job.sim);
        }
        // The page: a task of the pool steps it (on a Web Worker, where waiting is allowed)
        // and sends it back. Spawning only queues the task and wakes a worker; rayon's locks
        // spin on the main thread there (`web_spin_lock`), they never `Atomics.wait`.
        #[cfg(target_arch = "wasm32")]
        {
            self.sent = Some(Instant::now());
            let outbox = self.outbox.clone();
            let stop = Arc::clone(&self.stop);
            rayon::spawn(move || {
                // The receiver is gone only when the stepper is.
                let _ = outbox.send(step_paced(job, &stop));
            });
        }
    }

    /// Take the simulation back (the step in progress ends first) and say what it did while
    /// away. A panic in a step reaches the caller here, as it would have on this thread.
    pub fn bring_home(&mut self) -> Away {
        if self.home.is_some() {
            return Away::default();
        }
        self.stop.store(true, Ordering::Release);
        match self.wait_for_return() {
            Ok(back) => {
                self.home = Some(back.sim);
                // The page: the whole time away, also what followed an early return.
                #[cfg(target_arch = "wasm32")]
                let wall = {
                    let away = self.sent.take().map(|sent| sent.elapsed().as_secs_f64());
                    self.last_away = away;
                    away.unwrap_or(back.wall).max(back.wall)
                };
                #[cfg(not(target_arch = "wasm32"))]
                let wall = back.wall;
                let dropped = self.pacer.settle(back.simulated, wall, self.time_scale);
                Away {
                    steps: back.steps,
                    simulated: back.simulated,
                    busy: back.busy,
                    wall,
                    dropped,
                }
            }
            #[cfg(not(target_arch = "wasm32"))]
            Err(_) => {
                let worker = self.worker.take().expect("the stepping thread was started");
                match worker.join() {
                    Err(panic) => std::panic::resume_unwind(panic),
                    Ok(()) => unreachable!("the stepping thread ends only when told to"),
                }
            }
            // The stepper holds a sender itself, and a panic on the pool aborts the page.
            #[cfg(target_arch = "wasm32")]
            Err(_) => unreachable!("the stepper keeps its channel open"),
        }
    }

    /// The simulation back from the stepping, after `stop` was set: the step in progress
    /// ends first. On native a blocking receive; on the page's main thread, which may not
    /// block, a poll that spins for at most that step.
    fn wait_for_return(&self) -> Result<Returned, mpsc::RecvError> {
        #[cfg(not(target_arch = "wasm32"))]
        return self.returns.recv();
        #[cfg(target_arch = "wasm32")]
        loop {
            match self.returns.try_recv() {
                Ok(back) => return Ok(back),
                Err(mpsc::TryRecvError::Empty) => std::hint::spin_loop(),
                Err(mpsc::TryRecvError::Disconnected) => return Err(mpsc::RecvError),
            }
        }
    }
}

/// Steps taken away from home and the simulated time they covered.
#[derive(Default)]
struct Stepped {
    steps: Vec<StepStats>,
    simulated: f64,
    /// Wall seconds spent in the steps.
    busy: f64,
    /// A step came back with a non-finite or zero Δt: nothing more is stepped (a loop must
    /// not spin on it).
    broken: bool,
}

impl Stepped {
    /// Whether another step is due, `wall` seconds after leaving home.
    fn due(&self, pacer: &Pacer, wall: f64, time_scale: f64) -> bool {
        !self.broken && self.simulated < pacer.allowed(wall, time_scale)
    }

    fn step(&mut self, sim: &mut Simulation) {
        let started = Instant::now();
        let s = *sim.step();
        self.busy += started.elapsed().as_secs_f64();
        self.steps.push(s);
        self.broken = !(s.dt.is_finite() && s.dt > 0.0);
        if !self.broken {
            self.simulated += s.dt;
        }
    }
}

/// Step `job`'s simulation on the wall clock until `stop` is set (or, with `home_by`, until
/// the next step would end after it).
#[cfg(any(not(target_arch = "wasm32"), feature = "threads"))]
fn step_paced(job: Job, stop: &AtomicBool) -> Returned {
    let Job {
        mut sim,
        time_scale,
        pacer,
        home_by,
    } = job;
    let start = Instant::now();
    let mut stepped = Stepped::default();
    // How long the last step took.
    let mut step_wall = 0.0;
    while !stop.load(Ordering::Acquire) {
        let now = start.elapsed().as_secs_f64();
        if home_by.is_some_and(|by| now + step_wall > by) {
            break;
        }
        if stepped.due(&pacer, now, time_scale) {
            stepped.step(&mut sim);
            step_wall = start.elapsed().as_secs_f64() - now;
        } else {
            std::thread::sleep(AHEAD_NAP);
        }
    }
    Returned {
        sim,
        steps: stepped.steps,
        simulated: stepped.simulated,
        busy: stepped.busy,
        wall: start.elapsed().as_secs_f64(),
    }
}

/// The most wall time a page's frame spends stepping, s, however long it waited.
#[cfg(any(all(target_arch = "wasm32", not(feature = "threads")), test))]
pub const MAX_FRAME_STEPPING: f64 = 0.25;

/// The wall time a page's frame may spend stepping after waiting `waited` seconds since the
/// last frame handed the simulation over: [`FRAME_STEPPING_BUDGET`], or three quarters of
/// the wait when that is longer (at most [`MAX_FRAME_STEPPING`]). A long wait is the
/// browser drawing the last frame (software WebGL, a slow GPU), which it does beside the
/// page's thread: stepping for part of it costs the page few frames.
#[cfg(any(all(target_arch = "wasm32", not(feature = "threads")), test))]
pub fn stepping_budget(waited: f64) -> f64 {
    (0.75 * waited).clamp(FRAME_STEPPING_BUDGET, MAX_FRAME_STEPPING)
}

/// The browser's stepper: the simulation never leaves; what was due while a frame was drawn
/// is stepped when the next frame takes it back. (Built natively too, for its tests.)
#[cfg(any(all(target_arch = "wasm32", not(feature = "threads")), test))]
pub struct FrameStepper {
    home: Option<Box<Simulation>>,
    /// When the simulation was "sent away" and at what time scale.
    away: Option<(Instant, f64)>,
    pacer: Pacer,
    time_scale: f64,
}

/// The stepper of a page, which has no thread to spare.
#[cfg(all(target_arch = "wasm32", not(feature = "threads")))]
pub type Stepper = FrameStepper;

#[cfg(any(all(target_arch = "wasm32", not(feature = "threads")), test))]
impl FrameStepper {
    /// `sim`, at home.
    pub fn new(sim: Simulation) -> Self {
        Self {
            home: Some(Box::new(sim)),
            away: None,
            pacer: Pacer::default(),
            time_scale: 1.0,
        }
    }

    /// [`Self::new`]: the page steps on its one thread whatever is asked.
    pub fn with_threads(sim: Simulation, _threads: Option<usize>) -> Self {
        Self::new(sim)
    }

    /// Worker threads the steps run on: the page's one.
    pub fn threads(&self) -> usize {
        1
    }

    /// Replace the simulation (a reset or another scene); the pacing starts afresh.
    pub fn replace(&mut self, sim: Simulation) {
        self.away = None;
        self.home = Some(Box::new(sim));
        self.pacer = Pacer::default();
    }

    /// Forget what the pacing owed (after a pause).
    pub fn reset_pace(&mut self) {
        self.pacer = Pacer::default();
    }

    /// Let the simulation step at `time_scale` × real time until [`Self::bring_home`].
    pub fn send_away(&mut self, time_scale: f64) {
        if time_scale != self.time_scale {
            self.pacer = Pacer::default();
            self.time_scale = time_scale;
        }
        self.away = Some((Instant::now(), time_scale));
    }

    /// Step what came due since [`Self::send_away`], within [`stepping_budget`], and say
    /// what was done.
    pub fn bring_home(&mut self) -> Away {
        let (Some((sent, time_scale)), Some(sim)) = (self.away.take(), self.home.as_mut()) else {
            return Away::default();
        };
        let stepping = Instant::now();
        let budget = stepping_budget(stepping.duration_since(sent).as_secs_f64());
        let mut stepped = Stepped::default();
        while stepped.due(&self.pacer, sent.elapsed().as_secs_f64(), time_scale)
            && stepping.elapsed().as_secs_f64() < budget
        {
            stepped.step(sim);
        }
        let wall = sent.elapsed().as_secs_f64();
        let dropped = self.pacer.settle(stepped.simulated, wall, time_scale);
        Away {
            steps: stepped.steps,
            simulated: stepped.simulated,
            busy: stepped.busy,
            wall,
            dropped,
        }
    }

    /// The simulation (always at home between frames).
    pub fn home(&self) -> &Simulation {
        self.home.as_deref().expect("the simulation never leaves")
    }
}

impl Deref for Stepper {
    type Target = Simulation;
    fn deref(&self) -> &Simulation {
        self.home
            .as_deref()
            .expect("the simulation is home while the window reads it")
    }
}

impl DerefMut for Stepper {
    fn deref_mut(&mut self) -> &mut Simulation {
        self.home
            .as_deref_mut()
            .expect("the simulation is home while the window changes it")
    }
}

#[cfg(any(not(target_arch = "wasm32"), feature = "threads"))]
impl Drop for Stepper {
    fn drop(&mut self) {
        if self.home.is_none() {
            self.stop.store(true, Ordering::Release);
            let _ = self.wait_for_return();
        }
        // Closing the channel ends the thread.
        #[cfg(not(target_arch = "wasm32"))]
        {
            self.jobs = None;
            if let Some(worker) = self.worker.take() {
                let _ = worker.join();
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_pacer_carries_a_short_lag_and_drops_a_long_one() {
        let mut p = Pacer::default();
        // 20 ms away at real time, 15 ms simulated: 5 ms owed, carried.
        assert_eq!(p.settle(0.015, 0.020, 1.0), 0.0);
        assert!((p.carry - 0.005).abs() < 1e-12);
        assert!((p.allowed(0.010, 1.0) - 0.015).abs() < 1e-12);
        // A slow scene: 1 s away, 0.1 s simulated; at most MAX_LAG is carried.
        let dropped = p.settle(0.1, 1.0, 1.0);
        assert!((p.carry - MAX_LAG).abs() < 1e-12);
        assert!((dropped - (0.905 - MAX_LAG)).abs() < 1e-9, "{dropped}");
        // Running ahead (a step longer than the time away) is carried as negative.
        let mut p = Pacer::default();
        assert_eq!(p.settle(0.004, 0.001, 1.0), 0.0);
        assert!((p.carry + 0.003).abs() < 1e-12);
        // Twice real time allows twice the simulated time.
        assert!((Pacer::default().allowed(0.5, 2.0) - 1.0).abs() < 1e-12);
    }

    fn small_dam_break() -> Simulation {
        let mut scene = dfsph::scene::builtin("dam-break").unwrap();
        scene.particle_radius = 0.04;
        Simulation::new(&scene).unwrap()
    }

    #[test]
    fn steps_taken_away_are_reported_and_keep_to_the_clock() {
        let mut stepper = Stepper::new(small_dam_break());
        stepper.send_away(1.0);
        std::thread::sleep(Duration::from_millis(200));
        let away = stepper.bring_home();
        assert!(!away.steps.is_empty(), "{away:?}");
        assert_eq!(stepper.step_count(), away.steps.len() as u64);
        let covered: f64 = away.steps.iter().map(|s| s.dt).sum();
        assert!((covered - away.simulated).abs() < 1e-9);
        assert!((stepper.time() - away.simulated).abs() < 1e-6);
        // Never ahead of the wall clock by more than the last step.
        let last = away.steps.last().unwrap().dt;
        assert!(away.simulated <= away.wall + last + 1e-9, "{away:?}");
        // At home it stays put.
        let t = stepper.time();
        std::thread::sleep(Duration::from_millis(20));
        assert_eq!(stepper.bring_home().steps.len(), 0);
        assert_eq!(stepper.time(), t);
    }

    #[test]
    fn the_frame_stepper_keeps_to_the_clock_within_its_budget() {
        let mut stepper = FrameStepper::new(small_dam_break());
        // Nothing was sent away: nothing is stepped.
        assert!(stepper.bring_home().steps.is_empty());
        stepper.send_away(1.0);
        std::thread::sleep(Duration::from_millis(60));
        let away = stepper.bring_home();
        assert!(!away.steps.is_empty(), "{away:?}");
        assert_eq!(stepper.home().step_count(), away.steps.len() as u64);
        // Up to the clock (the last step may overshoot it), not beyond.
        let last = away.steps.last().unwrap().dt;
        assert!(away.simulated <= away.wall + last + 1e-9, "{away:?}");
        // Far more than a frame can step (100 x real time for half a second): stepping stops
        // at the budget (give or take a step and the host's scheduling), and what is owed
        // beyond the lag allowed is dropped.
        stepper.send_away(100.0);
        std::thread::sleep(Duration::from_millis(500));
        let stepping = Instant::now();
        let away = stepper.bring_home();
        let took = stepping.elapsed().as_secs_f64();
        assert!(away.simulated < 40.0 && away.dropped > 10.0, "{away:?}");
        assert!(
            took < MAX_FRAME_STEPPING + 0.2,
            "stepping ran past its budget: {took} s, {away:?}"
        );
    }

    #[test]
    fn a_frame_steps_for_part_of_a_long_wait_and_at_least_its_budget() {
        assert_eq!(stepping_budget(0.0), FRAME_STEPPING_BUDGET);
        assert_eq!(stepping_budget(0.016), FRAME_STEPPING_BUDGET);
        assert!((stepping_budget(0.2) - 0.15).abs() < 1e-12);
        assert_eq!(stepping_budget(5.0), MAX_FRAME_STEPPING);
    }

    /// Rounds of `round` (send away at 4 x real time, bring home: the steps taken) until 30
    /// steps or more were taken; how many.
    fn at_least_30_steps(mut round: impl FnMut() -> usize) -> usize {
        let mut steps = 0;
        while steps < 30 {
            steps += round();
        }
        steps
    }

    /// The fingerprint of the small dam break after `steps` steps taken on this thread.
    fn stepped_here(steps: usize) -> u64 {
        let mut here = small_dam_break();
        for _ in 0..steps {
            here.step();
        }
        dfsph::recording::fingerprint(&here)
    }

    #[test]
    fn the_frame_stepper_gives_the_bits_of_the_stepping_thread() {
        let mut frames = FrameStepper::new(small_dam_break());
        let steps = at_least_30_steps(|| {
            frames.send_away(4.0);
            std::thread::sleep(Duration::from_millis(5));
            frames.bring_home().steps.len()
        });
        assert_eq!(
            dfsph::recording::fingerprint(frames.home()),
            stepped_here(steps)
        );
    }

    #[test]
    fn a_stepped_simulation_gives_the_bits_of_one_stepped_here() {
        let mut stepper = Stepper::new(small_dam_break());
        let steps = at_least_30_steps(|| {
            stepper.send_away(4.0);
            std::thread::sleep(Duration::from_millis(5));
            stepper.bring_home().steps.len()
        });
        assert_eq!(dfsph::recording::fingerprint(&stepper), stepped_here(steps));
    }
}
