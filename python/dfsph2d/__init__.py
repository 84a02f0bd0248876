"""dfsph2d: 2D water (Divergence-Free SPH) from Python.

    >>> import dfsph2d
    >>> sim = dfsph2d.Simulation("hydrostatic")
    >>> sim.advance(0.1)["avg_density_error_pct"] < 0.1
    True
    >>> sim.positions.shape == (sim.particle_count, 2)
    True

``Simulation(scene)`` takes a built-in scene name (``dfsph2d.scenes()``), the path of a JSON
scene file or a dict in the same format (docs/scenes.md). Units are SI: metres, seconds,
kg/m³, pascals. Runs fanned out over a Dask cluster: :mod:`dfsph2d.sweep`.
"""

from ._dfsph2d import Simulation, __version__, load_scene, scenes

__all__ = ["Simulation", "load_scene", "scenes", "__version__"]
