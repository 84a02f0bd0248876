//! `dfsph2d._dfsph2d`: the solver's public API ([`dfsph::Simulation`]) as a Python class.
//!
//! The Python package (`python/dfsph2d/`) re-exports [`PySimulation`] as
//! `dfsph2d.Simulation`; `python/dfsph2d/_dfsph2d.pyi` documents every method with its units.
//! Scenes are read by [`dfsph_io::input`] and validated by the library, so a bad scene raises
//! `ValueError` with the message the command line prints after `error: `.
//!
//! Particle arrays are copies, ordered by particle id: the solver sorts its particles by grid
//! cell in every step, into buffers it swaps, so a view into its memory would show other
//! particles (or freed memory) after the next step.
//!
//! Steps run with the GIL released, in the simulation's own thread pool when it was given a
//! thread count. The calling thread checks for signals every [`SIGNAL_POLL`] while they run:
//! Ctrl-C (`KeyboardInterrupt`) ends the step in progress within one solver iteration (its
//! pressure solve left unconverged, as `run` does) and raises when that step is over.
//!
//! Threads. One simulation may be used from several Python threads. Its state sits behind a
//! lock that is only ever waited for with the GIL released ([`PySimulation::lock`]): a thread
//! that held the GIL while it waited for a stepping thread, which needs the GIL back between
//! its chunks, would hang both. `step` and `advance` hold the lock one chunk of steps
//! ([`SIGNAL_CHECK`]) at a time, so another thread's reads and actions (`positions`, `time`,
//! `push`, ...) wait at most one chunk and then see the state between two steps; the stepping
//! call goes on after them. The steps themselves run in a thread of their own
//! ([`PySimulation::step_while`]) so that the calling thread, which does not hold the lock,
//! can see Ctrl-C in the middle of a long step.

use std::borrow::Cow;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{mpsc, Arc, Mutex, MutexGuard, TryLockError};
use std::time::{Duration, Instant};

use dfsph::actions::ActionOutcome;
use dfsph::rigid::BodySpec;
use dfsph::{probes, Action, Scene, SceneError, Simulation, StepStats, Vec2};
use dfsph_io::input::one_line;
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray1, PyArray2};
use pyo3::exceptions::{PyMemoryError, PyRuntimeError, PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyString};

/// How long `step` and `advance` step at a time before other threads get the state.
const SIGNAL_CHECK: Duration = Duration::from_millis(100);

/// How often a thread waiting for its steps checks for signals (Ctrl-C).
const SIGNAL_POLL: Duration = Duration::from_millis(20);

/// Longest a stepping thread waits between two chunks for other threads to take their turn
/// with the state (a reader that holds it longer is waited for at the next chunk).
const YIELD_LIMIT: Duration = Duration::from_millis(50);

/// Most worker threads a simulation may ask for: more than any machine's cores, far fewer
/// than would exhaust the process's threads.
const MAX_THREADS: usize = 1024;

/// How a chunk of steps ([`PySimulation::chunk`]) ended.
enum ChunkEnd {
    /// Its time was up, or a stop was asked for: step on (or raise).
    More,
    /// Nothing more to do; the last step's diagnostics.
    Done(StepStats),
    /// A step did not move the clock on.
    Stuck { time: f64, dt: f64 },
}

/// The solver's state and the pool its steps run in.
struct State {
    sim: Simulation,
    /// `None`: rayon's global pool (one thread per core).
    pool: Option<rayon::ThreadPool>,
}

impl State {
    /// Run `f` in this simulation's pool.
    fn in_pool<R: Send>(&mut self, f: impl FnOnce(&mut Simulation) -> R + Send) -> R {
        let sim = &mut self.sim;
        match &self.pool {
            Some(pool) => pool.install(|| f(sim)),
            None => f(sim),
        }
    }

    /// Indices of the fluid particles in increasing id order.
    fn id_order(&self) -> Vec<usize> {
        let ids = self.sim.ids();
        let mut order: Vec<usize> = (0..ids.len()).collect();
        order.sort_unstable_by_key(|&i| ids[i]);
        order
    }
}

/// One running scene: `Simulation(scene, *, threads=None)`.
///
/// `scene`: a built-in scene name (`dfsph2d.scenes()`), the path of a JSON scene file, or a
/// dict in the same format (docs/scenes.md); a scene that does not validate raises
/// ValueError naming the key. `threads`: worker threads of this simulation's own pool (None:
/// one per core). Units are SI: m, s, kg/m³, Pa. Particle arrays are NumPy copies in
/// particle-id order (the solver re-sorts its particles every step). `step(n)` and
/// `advance(seconds)` release the GIL. Every method with its units: dfsph2d/_dfsph2d.pyi.
#[pyclass(module = "dfsph2d._dfsph2d", name = "Simulation")]
struct PySimulation {
    state: Mutex<State>,
    /// Threads waiting for [`Self::state`]: a stepping thread lets them in between its chunks
    /// (the lock is not fair, and the stepper would otherwise take it straight back).
    waiting: AtomicUsize,
    /// The simulation's stop flag ([`Simulation::set_stop_flag`]): set on Ctrl-C to end the
    /// step in progress within one solver iteration.
    stop: Arc<AtomicBool>,
}

/// The scene `scene` names: a dict (the JSON scene format), a built-in name, or the path of a
/// JSON file (str or `os.PathLike`).
fn scene_from(py: Python<'_>, scene: &Bound<'_, PyAny>) -> PyResult<Scene> {
    if scene.is_instance_of::<PyDict>() {
        let text: String = py
            .import("json")?
            .call_method1("dumps", (scene,))
            .map_err(|e| {
                PyValueError::new_err(format!("scene: the dict is not JSON-serialisable: {e}"))
            })?
            .extract()?;
        return Scene::from_json(&text).map_err(scene_error);
    }
    let arg: String = if scene.is_instance_of::<PyString>() {
        scene.extract()?
    } else if scene.hasattr("__fspath__")? {
        py.import("os")?
            .call_method1("fspath", (scene,))?
            .extract()
            .map_err(|_| PyTypeError::new_err("scene: a bytes path is not supported; pass a str"))?
    } else {
        return Err(PyTypeError::new_err(format!(
            "scene must be a dict, a built-in scene name or a path, not {}",
            scene.get_type().name()?
        )));
    };
    dfsph_io::input::load_scene(&arg).map_err(PyValueError::new_err)
}

/// A scene the solver refuses, as `ValueError` in the command line's words; one too large
/// for this process's memory as `MemoryError`, before anything large was allocated.
fn scene_error(e: SceneError) -> PyErr {
    let text = format!("scene: {}", one_line(&e.to_string()));
    match e {
        SceneError::Memory(_) => PyMemoryError::new_err(text),
        _ => PyValueError::new_err(text),
    }
}

/// A JSON-serialisable value as the Python object `json.loads` makes of it.
fn to_python<'py>(py: Python<'py>, value: &impl serde::Serialize) -> PyResult<Bound<'py, PyAny>> {
    let text = serde_json::to_string(value).map_err(|e| PyRuntimeError::new_err(e.to_string()))?;
    py.import("json")?.call_method1("loads", (text,))
}

/// `values` as a float32 array of shape (N, 2).
fn points_array<'py>(py: Python<'py>, values: Vec<Vec2>) -> Bound<'py, PyArray2<f32>> {
    let n = values.len();
    let mut flat = Vec::with_capacity(2 * n);
    for v in values {
        flat.extend_from_slice(&[v.x, v.y]);
    }
    Array2::from_shape_vec((n, 2), flat)
        .expect("two values per point")
        .into_pyarray(py)
}

/// An action's outcome: a refusal becomes `ValueError` with the solver's reason.
fn accepted(what: &str, outcome: ActionOutcome) -> PyResult<ActionOutcome> {
    match outcome.rejected {
        Some(reason) => Err(PyValueError::new_err(format!("{what} rejected: {reason}"))),
        None => Ok(outcome),
    }
}

fn finite(name: &str, values: &[f32]) -> PyResult<()> {
    if values.iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(PyValueError::new_err(format!("{name} must be finite")))
    }
}

impl PySimulation {
    /// The state, locked. The lock is taken while holding the GIL only when it is free;
    /// otherwise this thread waits for it with the GIL released, since its holder may need
    /// the GIL to finish (a stepping thread between chunks).
    fn lock(&self, py: Python<'_>) -> MutexGuard<'_, State> {
        let mut counted = false;
        let guard = loop {
            match self.state.try_lock() {
                Ok(guard) => break guard,
                // A panic inside a step (a solver bug) poisons the lock; the state is still
                // the one the step left, which the caller can inspect.
                Err(TryLockError::Poisoned(e)) => break e.into_inner(),
                Err(TryLockError::WouldBlock) => {
                    if !counted {
                        self.waiting.fetch_add(1, Ordering::SeqCst);
                        counted = true;
                    }
                    // Wait until the holder lets go, then try again with the GIL.
                    py.detach(|| drop(self.state.lock()));
                }
            }
        };
        if counted {
            self.waiting.fetch_sub(1, Ordering::SeqCst);
        }
        guard
    }

    /// Between two chunks of steps: let the threads waiting for the state in first (for at
    /// most [`YIELD_LIMIT`]), with the GIL released so that they can take it.
    fn let_waiters_in(&self, py: Python<'_>) {
        if self.waiting.load(Ordering::SeqCst) == 0 {
            return;
        }
        py.detach(|| {
            let start = Instant::now();
            while self.waiting.load(Ordering::SeqCst) > 0 && start.elapsed() < YIELD_LIMIT {
                std::thread::sleep(Duration::from_micros(50));
            }
        });
    }

    /// Apply `action` between steps.
    fn act(&self, py: Python<'_>, what: &str, action: Action) -> PyResult<ActionOutcome> {
        let mut guard = self.lock(py);
        let state: &mut State = &mut guard;
        let outcome = py.detach(|| state.in_pool(|sim| sim.apply(&action)));
        accepted(what, outcome)
    }

    /// Step while `more(sim)` says so; returns the last step's diagnostics. The steps run in a
    /// thread of their own, a chunk of at most [`SIGNAL_CHECK`] at a time, holding the state's
    /// lock only while they run; this thread waits for them with the GIL released and checks
    /// for signals every [`SIGNAL_POLL`]. On Ctrl-C (a signal handler that raises) it sets the
    /// simulation's stop flag, which ends the step in progress within one solver iteration
    /// (its pressure solve unconverged), and raises once that step is over. A step that does
    /// not move the clock on (a non-finite or zero Δt) ends it with `RuntimeError`: the loop
    /// would never end. The signal handler runs without the state's lock, so a handler that
    /// reads the simulation waits for the chunk rather than deadlocking.
    fn step_while<'py>(
        &self,
        py: Python<'py>,
        mut more: impl FnMut(&Simulation) -> bool + Send,
    ) -> PyResult<Bound<'py, PyAny>> {
        loop {
            let (end, interrupted) = std::thread::scope(|scope| {
                let (sender, receiver) = mpsc::channel();
                let more = &mut more;
                scope.spawn(move || {
                    let mut guard = self.state.lock().unwrap_or_else(|e| e.into_inner());
                    let end = guard.in_pool(|sim| self.chunk(sim, more));
                    drop(guard);
                    // The receiver waits until the end is sent: it cannot be gone.
                    let _ = sender.send(end);
                });
                let mut interrupted = None;
                let mut receiver = receiver;
                loop {
                    // The receiver is not Sync: it goes into the GIL-free closure and back.
                    let (received, back) = py.detach(move || {
                        let received = receiver.recv_timeout(SIGNAL_POLL);
                        (received, receiver)
                    });
                    receiver = back;
                    match received {
                        Ok(end) => return (end, interrupted),
                        Err(mpsc::RecvTimeoutError::Timeout) => {}
                        Err(mpsc::RecvTimeoutError::Disconnected) => {
                            // The stepping thread panicked (a solver bug): what is returned
                            // here is never seen, as the scope re-raises that panic when it
                            // ends (PanicException in Python).
                            return (ChunkEnd::More, interrupted);
                        }
                    }
                    if interrupted.is_none() {
                        if let Err(e) = py.check_signals() {
                            self.stop.store(true, Ordering::SeqCst);
                            interrupted = Some(e);
                        }
                    }
                }
            });
            if let Some(e) = interrupted {
                self.stop.store(false, Ordering::SeqCst);
                return Err(e);
            }
            match end {
                ChunkEnd::More => {}
                ChunkEnd::Done(stats) => return to_python(py, &stats),
                ChunkEnd::Stuck { time, dt } => {
                    return Err(PyRuntimeError::new_err(format!(
                        "the simulation stopped advancing at t = {time} s (a step of {dt} s)"
                    )))
                }
            }
            self.let_waiters_in(py);
            // A signal that came as the chunk ended.
            py.check_signals()?;
        }
    }

    /// Steps for at most [`SIGNAL_CHECK`], while `more(sim)` says so and no stop is asked for.
    fn chunk(&self, sim: &mut Simulation, more: &mut impl FnMut(&Simulation) -> bool) -> ChunkEnd {
        let start = Instant::now();
        while start.elapsed() < SIGNAL_CHECK {
            if self.stop.load(Ordering::SeqCst) {
                return ChunkEnd::More;
            }
            if !more(sim) {
                return ChunkEnd::Done(*sim.stats());
            }
            let dt = sim.step().dt;
            if !(dt.is_finite() && dt > 0.0) {
                return ChunkEnd::Stuck {
                    time: sim.time(),
                    dt: sim.stats().dt,
                };
            }
        }
        ChunkEnd::More
    }

    /// Per-particle values (the solver's order) rearranged into id order.
    fn by_id<T: Copy>(
        &self,
        py: Python<'_>,
        pick: impl for<'a> FnOnce(&'a Simulation) -> Cow<'a, [T]>,
    ) -> Vec<T> {
        let state = self.lock(py);
        let values = pick(&state.sim);
        state.id_order().into_iter().map(|i| values[i]).collect()
    }
}

/// The factory of the backend `name` names (`None`: the CPU's; the device is opened once
/// per process): `cpu`, `gpu` (a hardware adapter, else a software one) or `auto` (a
/// hardware adapter, else the CPU), as the command line's `--backend`.
fn backend_factory(name: &str) -> PyResult<Option<dfsph::simulation::BackendFactory>> {
    let choice: dfsph_gpu::BackendChoice = name
        .parse()
        .map_err(|e: String| PyValueError::new_err(format!("backend: {e}")))?;
    dfsph_gpu::backend_factory(choice)
        .map(|(factory, _)| factory)
        .map_err(|e| PyRuntimeError::new_err(format!("backend {name:?}: {e}")))
}

#[pymethods]
impl PySimulation {
    #[new]
    #[pyo3(signature = (scene, *, threads = None, max_memory = None, backend = "cpu"))]
    fn new(
        py: Python<'_>,
        scene: &Bound<'_, PyAny>,
        threads: Option<usize>,
        max_memory: Option<&Bound<'_, PyAny>>,
        backend: &str,
    ) -> PyResult<Self> {
        let scene = scene_from(py, scene)?;
        let factory = backend_factory(backend)?;
        let max_memory = match max_memory {
            None => None,
            Some(v) if v.is_instance_of::<PyString>() => {
                let text: String = v.extract()?;
                Some(
                    dfsph::memory::parse_bytes(&text)
                        .map_err(|e| PyValueError::new_err(format!("max_memory: {e}")))?,
                )
            }
            Some(v) => match v.extract::<u64>() {
                Ok(bytes) if bytes > 0 => Some(bytes),
                _ => {
                    return Err(PyValueError::new_err(format!(
                        "max_memory must be a number of bytes > 0 or a size such as \"2G\", not {}",
                        v.repr()?
                    )))
                }
            },
        };
        let limits = dfsph::memory::MemoryLimits::of_this_process_and_user(
            max_memory.map(|bytes| (bytes, "max_memory")),
        );
        let pool = match threads {
            None => None,
            Some(n) if n == 0 || n > MAX_THREADS => {
                return Err(PyValueError::new_err(format!(
                    "threads must be between 1 and {MAX_THREADS}, not {n}"
                )))
            }
            Some(n) => Some(
                rayon::ThreadPoolBuilder::new()
                    .num_threads(n)
                    .build()
                    .map_err(|e| {
                        PyRuntimeError::new_err(format!("cannot start {n} threads: {e}"))
                    })?,
            ),
        };
        let build = || match &factory {
            Some(factory) => Simulation::with_backend(&scene, &limits, factory.clone()),
            None => Simulation::new_within(&scene, &limits),
        };
        let mut sim = py
            .detach(|| match &pool {
                Some(pool) => pool.install(build),
                None => build(),
            })
            .map_err(scene_error)?;
        let stop = Arc::new(AtomicBool::new(false));
        sim.set_stop_flag(Arc::clone(&stop));
        Ok(Self {
            state: Mutex::new(State { sim, pool }),
            waiting: AtomicUsize::new(0),
            stop,
        })
    }

    /// Take `n` steps; returns the last one's diagnostics.
    #[pyo3(signature = (n = 1))]
    fn step<'py>(&self, py: Python<'py>, n: u64) -> PyResult<Bound<'py, PyAny>> {
        let mut left = n;
        self.step_while(py, |_| {
            let go = left > 0;
            left = left.saturating_sub(1);
            go
        })
    }

    /// Step until `seconds` more have been simulated; returns the last step's diagnostics.
    fn advance<'py>(&self, py: Python<'py>, seconds: f64) -> PyResult<Bound<'py, PyAny>> {
        if !(seconds.is_finite() && seconds >= 0.0) {
            return Err(PyValueError::new_err(format!(
                "seconds must be a finite number >= 0, not {seconds}"
            )));
        }
        let until = self.lock(py).sim.time() + seconds;
        self.step_while(py, |sim| !sim.has_reached(until))
    }

    /// What steps the water: `cpu`, or the GPU backend and its adapter (and, where it hands
    /// the scene to the CPU, why).
    #[getter]
    fn backend(&self, py: Python<'_>) -> String {
        self.lock(py).sim.backend_description()
    }

    /// Simulated time, s.
    #[getter]
    fn time(&self, py: Python<'_>) -> f64 {
        self.lock(py).sim.time()
    }

    /// Steps taken.
    #[getter]
    fn step_count(&self, py: Python<'_>) -> u64 {
        self.lock(py).sim.step_count()
    }

    /// Fluid particles.
    #[getter]
    fn particle_count(&self, py: Python<'_>) -> usize {
        self.lock(py).sim.fluid_count()
    }

    fn __len__(&self, py: Python<'_>) -> usize {
        self.particle_count(py)
    }

    /// Particle radius r, m (the spacing is d = 2r).
    #[getter]
    fn particle_radius(&self, py: Python<'_>) -> f32 {
        self.lock(py).sim.particle_radius()
    }

    /// Particle mass, kg per metre of depth.
    #[getter]
    fn particle_mass(&self, py: Python<'_>) -> f32 {
        self.lock(py).sim.particle_mass()
    }

    /// Rest density ρ0, kg/m³.
    #[getter]
    fn rest_density(&self, py: Python<'_>) -> f32 {
        self.lock(py).sim.rest_density()
    }

    /// The scene as a dict (its JSON form, every default filled in).
    #[getter]
    fn scene<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_python(py, self.lock(py).sim.scene())
    }

    /// The last step's diagnostics.
    #[getter]
    fn diagnostics<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let state = self.lock(py);
        let mut stats = serde_json::to_value(state.sim.stats())
            .map_err(|e| PyRuntimeError::new_err(e.to_string()))?;
        if let serde_json::Value::Object(map) = &mut stats {
            map.insert("total_clamped".into(), state.sim.total_clamped().into());
            map.insert(
                "total_non_finite".into(),
                state.sim.total_non_finite().into(),
            );
        }
        to_python(py, &stats)
    }

    /// Particle ids, uint32 (N,).
    #[getter]
    fn ids<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<u32>> {
        self.by_id(py, |s| Cow::Borrowed(s.ids())).into_pyarray(py)
    }

    /// Positions, m, float32 (N, 2).
    #[getter]
    fn positions<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f32>> {
        points_array(py, self.by_id(py, |s| Cow::Borrowed(s.positions())))
    }

    /// Velocities, m/s, float32 (N, 2).
    #[getter]
    fn velocities<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f32>> {
        points_array(py, self.by_id(py, |s| Cow::Borrowed(s.velocities())))
    }

    /// Densities, kg/m³, float32 (N,).
    #[getter]
    fn densities<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f32>> {
        self.by_id(py, |s| {
            let rho0 = s.rest_density();
            Cow::Owned(s.density_ratios().iter().map(|r| r * rho0).collect())
        })
        .into_pyarray(py)
    }

    /// Pressures, Pa, float32 (N,).
    #[getter]
    fn pressures<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f32>> {
        self.by_id(py, |s| {
            let rho0 = s.rest_density();
            Cow::Owned(
                s.interpolated_pressures_over_rho0()
                    .into_iter()
                    .map(|p| p * rho0)
                    .collect(),
            )
        })
        .into_pyarray(py)
    }

    /// Everything at one instant: time, ids, positions, velocities, densities, pressures.
    fn snapshot<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let snap = self.lock(py).sim.snapshot();
        let out = PyDict::new(py);
        out.set_item("time", snap.time)?;
        out.set_item("ids", snap.id.into_pyarray(py))?;
        out.set_item("positions", points_array(py, snap.position))?;
        out.set_item("velocities", points_array(py, snap.velocity))?;
        out.set_item("densities", snap.density.into_pyarray(py))?;
        out.set_item("pressures", snap.pressure.into_pyarray(py))?;
        Ok(out)
    }

    /// The scene's probes, name → value (units in `probe_units`).
    #[getter]
    fn probes<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let state = self.lock(py);
        let out = PyDict::new(py);
        let values = probes::sample_all(&state.sim);
        for (probe, value) in state.sim.scene().probes.iter().zip(values) {
            out.set_item(probe.name(), value)?;
        }
        Ok(out)
    }

    /// The unit of each probe, name → unit.
    #[getter]
    fn probe_units<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let state = self.lock(py);
        let out = PyDict::new(py);
        for probe in &state.sim.scene().probes {
            out.set_item(probe.name(), probe.unit())?;
        }
        Ok(out)
    }

    /// The largest x of a fluid particle with at least `min_neighbors` fluid neighbours,
    /// from the tank's left wall, m (None without one).
    #[pyo3(signature = (min_neighbors = 3))]
    fn front_position(&self, py: Python<'_>, min_neighbors: usize) -> Option<f64> {
        self.lock(py).sim.front_position(min_neighbors)
    }

    /// Total momentum of the fluid and the rigid bodies, kg·m/s per metre of depth.
    #[getter]
    fn momentum(&self, py: Python<'_>) -> (f32, f32) {
        let p = self.lock(py).sim.momentum();
        (p.x, p.y)
    }

    /// The rigid bodies' state: a list of dicts (`position` m, `angle` rad, `velocity` m/s,
    /// `angular_velocity` rad/s, `mass` kg/m, `spec` the body as a scene's `bodies` entry).
    #[getter]
    fn bodies<'py>(&self, py: Python<'py>) -> PyResult<Vec<Bound<'py, PyDict>>> {
        let states = self.lock(py).sim.rigid_bodies();
        states
            .into_iter()
            .map(|b| {
                let out = PyDict::new(py);
                out.set_item("position", (b.position.x, b.position.y))?;
                out.set_item("angle", b.angle)?;
                out.set_item("velocity", (b.velocity.x, b.velocity.y))?;
                out.set_item("angular_velocity", b.angular_velocity)?;
                out.set_item("mass", b.mass)?;
                out.set_item("spec", to_python(py, &b.spec)?)?;
                Ok(out)
            })
            .collect()
    }

    /// Shake the tank: -1 (left) to 1 (right); 0 lets it spring back.
    fn shake(&self, py: Python<'_>, direction: f32) -> PyResult<()> {
        self.act(py, "shake", Action::ShakeTank { direction })?;
        Ok(())
    }

    /// Set gravity, m/s².
    fn set_gravity(&self, py: Python<'_>, gx: f32, gy: f32) -> PyResult<()> {
        finite("gravity", &[gx, gy])?;
        self.act(
            py,
            "set_gravity",
            Action::SetGravity {
                gravity: Vec2::new(gx, gy),
            },
        )?;
        Ok(())
    }

    /// Push (strength > 0) or pull (< 0) the water around (x, y) within `radius` (m); the
    /// peak acceleration is `strength` m/s². Lasts until `release`.
    fn push(&self, py: Python<'_>, x: f32, y: f32, radius: f32, strength: f32) -> PyResult<()> {
        finite("push", &[x, y, radius, strength])?;
        let at = Vec2::new(x, y);
        self.act(
            py,
            "push",
            Action::Push {
                at,
                radius,
                strength,
            },
        )?;
        Ok(())
    }

    /// End a `push`.
    fn release(&self, py: Python<'_>) -> PyResult<()> {
        self.act(py, "release", Action::ReleasePointer)?;
        Ok(())
    }

    /// Pour water: fill a disc of `radius` (m) at (x, y) moving at (vx, vy) m/s. Returns the
    /// particles added.
    #[pyo3(signature = (x, y, radius, vx = 0.0, vy = 0.0))]
    fn pour(
        &self,
        py: Python<'_>,
        x: f32,
        y: f32,
        radius: f32,
        vx: f32,
        vy: f32,
    ) -> PyResult<usize> {
        finite("pour", &[x, y, radius, vx, vy])?;
        let action = Action::Emit {
            at: Vec2::new(x, y),
            radius,
            velocity: Vec2::new(vx, vy),
        };
        Ok(self.act(py, "pour", action)?.added)
    }

    /// Draw a wall along `points` ([(x, y), ...], m). Returns the boundary particles added.
    fn add_wall(&self, py: Python<'_>, points: Vec<(f32, f32)>) -> PyResult<isize> {
        let flat: Vec<f32> = points.iter().flat_map(|&(x, y)| [x, y]).collect();
        finite("add_wall", &flat)?;
        let polyline = points.into_iter().map(|(x, y)| Vec2::new(x, y)).collect();
        Ok(self
            .act(py, "add_wall", Action::AddWall { polyline })?
            .boundary_change)
    }

    /// Remove water and drawn walls within `radius` (m) of (x, y). Returns the fluid
    /// particles removed.
    fn erase(&self, py: Python<'_>, x: f32, y: f32, radius: f32) -> PyResult<usize> {
        finite("erase", &[x, y, radius])?;
        let action = Action::Erase {
            at: Vec2::new(x, y),
            radius,
        };
        Ok(self.act(py, "erase", action)?.removed)
    }

    /// Add a rigid body: a dict in the scene's `bodies` format.
    fn add_body(&self, py: Python<'_>, body: &Bound<'_, PyAny>) -> PyResult<()> {
        let text: String = py
            .import("json")?
            .call_method1("dumps", (body,))?
            .extract()?;
        let body: BodySpec = serde_json::from_str(&text).map_err(|e| {
            PyValueError::new_err(format!("add_body: {}", one_line(&e.to_string())))
        })?;
        self.act(py, "add_body", Action::AddBody { body })?;
        Ok(())
    }

    /// Start the scene over (time 0, the scene's particles).
    fn reset(&self, py: Python<'_>) -> PyResult<()> {
        self.act(py, "reset", Action::Reset { scene: None })?;
        Ok(())
    }

    fn __repr__(&self, py: Python<'_>) -> String {
        let state = self.lock(py);
        format!(
            "<dfsph2d.Simulation '{}': {} particles, t = {:.4} s, {} steps>",
            state.sim.scene().name,
            state.sim.fluid_count(),
            state.sim.time(),
            state.sim.step_count()
        )
    }
}

/// The scene a built-in name or a JSON file path names, as a dict (every default filled in).
#[pyfunction]
fn load_scene<'py>(py: Python<'py>, scene: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyAny>> {
    to_python(py, &scene_from(py, scene)?)
}

/// The built-in scenes: (name, description) pairs.
#[pyfunction]
fn scenes() -> Vec<(&'static str, &'static str)> {
    dfsph::scene::BUILTIN_SCENES
        .iter()
        .map(|b| (b.name, b.description))
        .collect()
}

#[pymodule]
fn _dfsph2d(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PySimulation>()?;
    m.add_function(wrap_pyfunction!(scenes, m)?)?;
    m.add_function(wrap_pyfunction!(load_scene, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
