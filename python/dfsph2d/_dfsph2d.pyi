"""Type stubs of the extension module (python/src/lib.rs). Units are SI throughout: m, s,
kg/m³, Pa; per-metre quantities are per metre of depth (the simulation is 2D)."""

import os
from typing import Any, Dict, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

__version__: str

SceneArg = Union[str, "os.PathLike[str]", Mapping[str, Any]]

def scenes() -> List[Tuple[str, str]]:
    """The built-in scenes as (name, description) pairs."""

def load_scene(scene: SceneArg) -> Dict[str, Any]:
    """The scene a built-in name or JSON file names, as a dict with every default filled in
    (the format of docs/scenes.md). Raises ValueError as `Simulation` does."""

class Simulation:
    """One running scene.

    ``scene``: a built-in scene name (see :func:`scenes`), the path of a JSON scene file, or
    a dict in the same format (docs/scenes.md). A scene that does not validate raises
    ``ValueError`` with the message ``dfsph2d run`` prints after ``error:``, naming the key
    (``scene: `fluid[0].max`: ...``); a file that cannot be read names the file.

    ``threads``: worker threads of this simulation's own pool (``None``: the process-wide
    pool, one thread per core). Steps run with the GIL released, so other Python threads run
    meanwhile, and several simulations can step in parallel threads. One simulation may be
    read and acted on from other threads while it steps: each such call waits for the end of
    the stepper's current chunk of steps (0.1 s at most).

    ``max_memory``: bytes (or a size such as ``"2G"``) the simulation may use, besides the
    machine's own limits (available memory, a container's limit, ``ulimit -v``). A scene that
    needs more raises ``MemoryError`` naming the limit, before anything large is allocated;
    ``reset`` to another scene is held to the same limits.

    ``backend``: what steps the water, as the command line's ``--backend``: ``"cpu"``;
    ``"gpu"``, on a hardware GPU, else on a software one such as Mesa's lavapipe (right, but
    slow), ``RuntimeError`` listing the adapters found where there is neither; ``"auto"``, a
    hardware GPU, else the CPU. The GPU backend runs the Jacobi solves (the built-in collapsing
    columns); a scene it does not do yet steps on the CPU, and :attr:`backend` says why.

    Particle arrays (``positions``, ``velocities``, ``densities``, ``pressures``, ``ids``)
    are fresh NumPy copies in increasing particle-id order, taken when read: the solver
    re-sorts its particles by grid cell every step, into buffers it swaps, so a view of its
    memory would not stay valid. Reading one costs a copy (0.3–0.5 ms for 20,000 particles;
    ``pressures`` 2 ms, interpolated over the neighbours); read it once per sample, not once
    per particle.
    """

    def __init__(
        self,
        scene: SceneArg,
        *,
        threads: Optional[int] = None,
        max_memory: Optional[Union[int, str]] = None,
        backend: str = "cpu",
    ) -> None: ...
    def step(self, n: int = 1) -> Dict[str, Any]:
        """Take ``n`` steps (each of the CFL Δt the solver chooses); returns the last step's
        diagnostics (see :attr:`diagnostics`). Ctrl-C (``KeyboardInterrupt``) ends the step
        in progress within one solver iteration, its pressure solve cut short, and raises
        when that step is over; the simulation goes on normally with the next call."""
    def advance(self, seconds: float) -> Dict[str, Any]:
        """Step until ``seconds`` more of simulated time have passed (the last step may end a
        little after); returns the last step's diagnostics. Ctrl-C interrupts it as it does
        :meth:`step`: within one solver iteration, at the end of the step in progress."""
    @property
    def backend(self) -> str:
        """What steps the water: ``"cpu"``, or ``"gpu: "`` and the adapter, or, where the GPU
        backend hands the scene to the CPU, ``"cpu (...)"`` saying why."""
    @property
    def time(self) -> float:
        """Simulated time, s."""
    @property
    def step_count(self) -> int:
        """Steps taken since the start."""
    @property
    def particle_count(self) -> int:
        """Fluid particles (also ``len(sim)``)."""
    def __len__(self) -> int: ...
    @property
    def particle_radius(self) -> float:
        """Particle radius r, m; the lattice spacing is d = 2r, the kernel support 4r."""
    @property
    def particle_mass(self) -> float:
        """Mass of one fluid particle, kg per metre of depth."""
    @property
    def rest_density(self) -> float:
        """Rest density ρ0, kg/m³."""
    @property
    def scene(self) -> Dict[str, Any]:
        """The scene as a dict, every default filled in."""
    @property
    def diagnostics(self) -> Dict[str, Any]:
        """The last step's diagnostics: ``step``, ``time`` (s), ``dt`` (s), ``n_fluid``,
        ``n_boundary``, ``density_iterations``, ``divergence_iterations``,
        ``avg_density_error_pct`` and ``max_density_error_pct`` (compression at the end of the
        density solve, %), ``divergence_error_pct`` (%), ``max_speed`` (m/s),
        ``kinetic_energy`` (J/m), ``clamped`` and ``non_finite`` (particles the step put back
        into the tank or reset; both should stay 0), ``avg_neighbors``, ``retries``, and
        ``total_clamped`` / ``total_non_finite`` over the whole run."""
    @property
    def ids(self) -> npt.NDArray[np.uint32]:
        """Particle ids, shape (N,), increasing; a particle keeps its id for life."""
    @property
    def positions(self) -> npt.NDArray[np.float32]:
        """Positions, m, shape (N, 2), in id order (a copy)."""
    @property
    def velocities(self) -> npt.NDArray[np.float32]:
        """Velocities, m/s, shape (N, 2), in id order (a copy)."""
    @property
    def densities(self) -> npt.NDArray[np.float32]:
        """Densities, kg/m³, shape (N,), in id order (a copy)."""
    @property
    def pressures(self) -> npt.NDArray[np.float32]:
        """Pressures, Pa, shape (N,), in id order (a copy): both solves' pressures
        interpolated at the particles, as ``run --format csv`` writes them."""
    def snapshot(self) -> Dict[str, Any]:
        """One instant: ``time`` (s) and the arrays ``ids``, ``positions``, ``velocities``,
        ``densities``, ``pressures`` as above."""
    @property
    def probes(self) -> Dict[str, float]:
        """The scene's probes (``probes`` key), name → reading: pressure probes in Pa,
        water-level gauges in m above the tank floor."""
    @property
    def probe_units(self) -> Dict[str, str]:
        """The unit of each probe, name → ``"Pa"`` or ``"m"``."""
    def front_position(self, min_neighbors: int = 3) -> Optional[float]:
        """The largest x, from the tank's left wall, of a fluid particle with at least
        ``min_neighbors`` fluid neighbours (a lone splash is not the front), m; None when
        none qualifies."""
    @property
    def momentum(self) -> Tuple[float, float]:
        """Total momentum of the fluid and the rigid bodies, kg·m/s per metre of depth."""
    @property
    def bodies(self) -> List[Dict[str, Any]]:
        """The rigid bodies: ``position`` (m), ``angle`` (rad, counter-clockwise),
        ``velocity`` (m/s), ``angular_velocity`` (rad/s), ``mass`` (kg/m) and ``spec`` (the
        body as a scene's ``bodies`` entry)."""
    # Actions, applied between steps as the viewer's keys and mouse do. A refused action
    # raises ValueError with the reason.
    def shake(self, direction: float) -> None:
        """Drive the tank sideways: -1 (left) to 1 (right); 0 lets it spring back."""
    def set_gravity(self, gx: float, gy: float) -> None:
        """Set gravity, m/s²."""
    def push(self, x: float, y: float, radius: float, strength: float) -> None:
        """Push (``strength`` > 0) or pull (< 0) the water within ``radius`` (m) of (x, y)
        (m), the peak acceleration ``strength`` m/s², until :meth:`release`."""
    def release(self) -> None:
        """End a :meth:`push`."""
    def pour(self, x: float, y: float, radius: float, vx: float = 0.0, vy: float = 0.0) -> int:
        """Pour: fill a disc of ``radius`` (m) at (x, y) with water moving at (vx, vy) m/s,
        where there is room (at most 100 m/s, as a scene's water; faster raises ValueError).
        Returns the particles added."""
    def add_wall(self, points: Sequence[Tuple[float, float]]) -> int:
        """Draw a wall along the polyline ``points`` (m). Returns the wall particles
        added."""
    def erase(self, x: float, y: float, radius: float) -> int:
        """Remove water and drawn walls within ``radius`` (m) of (x, y). Returns the fluid
        particles removed."""
    def add_body(self, body: Mapping[str, Any]) -> None:
        """Add a rigid body given as a scene's ``bodies`` entry, e.g.
        ``{"shape": "box", "size": [0.2, 0.1], "density": 500, "position": [1, 1.5]}``."""
    def reset(self) -> None:
        """Start the scene over from t = 0."""
