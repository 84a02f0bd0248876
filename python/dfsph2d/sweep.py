"""Independent runs fanned out over a Dask cluster, gathered as one pandas DataFrame.

A sweep is a list of runs. Each run is a dict with a ``"scene"`` (anything
:class:`dfsph2d.Simulation` takes: a built-in name, a JSON path or a scene dict) and any other
keys, which label the run and become columns of the result. :func:`grid` builds such a list
from a base scene and the values to try::

    from dfsph2d import sweep

    if __name__ == "__main__":  # a local cluster's workers import this script again
        runs = sweep.grid("dam-break", particle_radius=[0.02, 0.01, 0.005])
        table = sweep.sweep(runs, until=0.4)             # a LocalCluster on this machine
        table = sweep.sweep(runs, until=0.4, address="tcp://scheduler:8786")  # any cluster
        table.groupby("particle_radius").front.last()

Each run steps its own simulation on ``threads`` threads (1 by default: the cluster's workers
are the parallelism) and records :func:`default_measure` (or ``measure(sim)``) at t = 0 and
every ``every`` simulated seconds up to ``until``. The result has one row per run and sample:
the run's labels, ``run`` (its index in ``runs``), ``wall_s`` and ``steps`` (the run's whole
wall time and step count) and the measured columns. A run's samples do not depend on where it
ran: the solver gives the same numbers for the same scene and thread count.

Dask (``dask[distributed]``) and pandas are needed here only: ``pip install ./python[sweep]``.
"""

from __future__ import annotations

import copy
import itertools
import math
import time
from typing import Any, Callable, Dict, Iterable, List, Mapping, Optional, Sequence

from . import Simulation, load_scene

Run = Dict[str, Any]
Measure = Callable[[Simulation], Mapping[str, Any]]

__all__ = ["grid", "run_one", "sweep", "default_measure"]


def default_measure(sim: Simulation) -> Dict[str, Any]:
    """What a sweep records by default: the surge front (m from the tank's left wall, NaN
    when no particle has 3 neighbours), the fastest particle (m/s), the kinetic energy (J per
    metre of depth), the density solve's average error (percent) and the clamps so far."""
    d = sim.diagnostics
    front = sim.front_position()
    return {
        "front": math.nan if front is None else front,
        "max_speed": d["max_speed"],
        "kinetic_energy": d["kinetic_energy"],
        "avg_density_error_pct": d["avg_density_error_pct"],
        "clamped": d["total_clamped"],
    }


def grid(scene: Any, **values: Sequence[Any]) -> List[Run]:
    """Every combination of ``values`` applied to ``scene``.

    Keys are scene keys; a dotted key reaches into a section (``time_step.cfl``,
    ``viscosity.xsph``; ``__`` may stand for the dot in a keyword: ``time_step__cfl``). A
    built-in scene name or a JSON path is loaded first. Each run carries its values as labels.
    """
    base = copy.deepcopy(dict(scene)) if isinstance(scene, Mapping) else load_scene(scene)
    keys = list(values)
    runs = []
    for combo in itertools.product(*(values[k] for k in keys)):
        s = copy.deepcopy(base)
        labels = {}
        for key, value in zip(keys, combo):
            path = key.replace("__", ".").split(".")
            section = s
            for part in path[:-1]:
                section = section.setdefault(part, {})
            section[path[-1]] = value
            labels[".".join(path)] = value
        runs.append({"scene": s, **labels})
    return runs


def run_one(
    run: Run,
    until: float,
    every: float = 0.05,
    measure: Optional[Measure] = None,
    threads: int = 1,
) -> List[Dict[str, Any]]:
    """One run of a sweep, here: its rows (labels, ``run`` excluded, plus ``time``,
    ``wall_s``, ``steps`` and the measured columns)."""
    if not (every > 0 and math.isfinite(every)):
        raise ValueError(f"every must be a positive number of seconds, not {every}")
    labels = {k: v for k, v in run.items() if k != "scene"}
    measure = measure or default_measure
    start = time.perf_counter()
    sim = Simulation(run["scene"], threads=threads)
    rows = [{**labels, "time": sim.time, **measure(sim)}]
    samples = max(0, math.ceil(until / every - 1e-9))
    for k in range(1, samples + 1):
        sim.advance(min(k * every, until) - sim.time)
        rows.append({**labels, "time": sim.time, **measure(sim)})
    wall = time.perf_counter() - start
    for row in rows:
        row["wall_s"] = wall
        row["steps"] = sim.step_count
    return rows


def sweep(
    runs: Iterable[Run],
    *,
    until: float,
    every: float = 0.05,
    measure: Optional[Measure] = None,
    threads: int = 1,
    address: Optional[str] = None,
    client: Any = None,
    serial: bool = False,
):
    """Run every run of ``runs`` for ``until`` simulated seconds and gather the samples as a
    pandas DataFrame (see the module's documentation for its columns).

    Where they run: on ``client`` (a ``dask.distributed.Client``) if given; else on the Dask
    cluster at ``address`` (``"tcp://host:8786"``); else on a ``LocalCluster`` started for
    this sweep (one single-threaded worker process per core) and closed after it. With
    ``serial=True`` the runs go one after another in this process, without Dask.
    """
    import pandas as pd

    runs = list(runs)
    for i, run in enumerate(runs):
        if "scene" not in run:
            raise ValueError(f"runs[{i}] has no 'scene'")
    args = dict(until=until, every=every, measure=measure, threads=threads)
    if serial:
        results = [run_one(run, **args) for run in runs]
    else:
        results = _on_dask(runs, args, address, client)
    rows = [{"run": i, **row} for i, result in enumerate(results) for row in result]
    return pd.DataFrame(rows)


def _on_dask(runs: List[Run], args: Dict[str, Any], address: Optional[str], client: Any):
    from dask.distributed import Client, LocalCluster

    if client is not None:
        return _gather(client, runs, args)
    if address is not None:
        with Client(address) as c:
            return _gather(c, runs, args)
    try:
        cluster = LocalCluster(threads_per_worker=1, dashboard_address=None)
    except Exception as e:
        raise RuntimeError(
            f"could not start a local Dask cluster ({e}); in a script, call dfsph2d.sweep "
            "under `if __name__ == \"__main__\":`, since the cluster's worker processes "
            "import the script again (docs/python.md, Sweeps)"
        ) from e
    with cluster:
        with Client(cluster) as c:
            return _gather(c, runs, args)


def _gather(client: Any, runs: List[Run], args: Dict[str, Any]):
    # pure=False: two identical runs are still two runs (a repeat to measure wall time).
    futures = [client.submit(run_one, run, pure=False, **args) for run in runs]
    return client.gather(futures)
