"""dfsph2d.sweep: runs fanned out over Dask give what the same runs give one after another."""

import numpy as np
import pytest

pytest.importorskip("dask.distributed")
pytest.importorskip("pandas")

from dask.distributed import Client, LocalCluster  # noqa: E402

from dfsph2d import sweep  # noqa: E402


def four_runs():
    # A resolution pair times two longest steps: 1,250 and 2,222 particles, 0.3 s each.
    return sweep.grid("dam-break", particle_radius=[0.02, 0.015], time_step__max=[1e-3, 5e-4])


def test_grid_labels_every_combination():
    runs = four_runs()
    assert len(runs) == 4
    assert {(r["particle_radius"], r["time_step.max"]) for r in runs} == {
        (0.02, 1e-3), (0.02, 5e-4), (0.015, 1e-3), (0.015, 5e-4)}
    for r in runs:
        assert r["scene"]["particle_radius"] == r["particle_radius"]
        assert r["scene"]["time_step"]["max"] == r["time_step.max"]
        assert r["scene"]["time_step"]["cfl"] == 0.4  # the rest of the section is kept
        # The rest of the built-in scene is kept.
        assert r["scene"]["tank"] == {"min": [0.0, 0.0], "max": [4.0, 3.0]}


def columns(table):
    return table[["run", "particle_radius", "time_step.max", "time", "front", "max_speed",
                  "kinetic_energy", "steps"]]


def test_a_sweep_on_a_local_cluster_gives_the_serial_fronts():
    runs = four_runs()
    serial = sweep.sweep(runs, until=0.3, every=0.1, serial=True)
    assert len(serial) == 4 * 4  # t = 0, 0.1, 0.2, 0.3 per run
    assert serial.front.notna().all()
    # The surge went from the column's 1 m to past 1.5 m in every run.
    last = serial[serial.time > 0.29]
    assert (last.front > 1.5).all()
    # The longest step set the steps taken.
    steps = serial.groupby("run").steps.first()
    assert steps[1] > steps[0] and steps[3] > steps[2]
    # A LocalCluster started by the sweep, and one reached by its address.
    on_dask = sweep.sweep(runs, until=0.3, every=0.1)
    assert columns(on_dask).equals(columns(serial))
    with LocalCluster(n_workers=2, threads_per_worker=1, dashboard_address=None) as cluster:
        by_address = sweep.sweep(runs, until=0.3, every=0.1, address=cluster.scheduler_address)
        with Client(cluster) as client:
            by_client = sweep.sweep(runs, until=0.3, every=0.1, client=client,
                                    measure=lambda sim: {"n": len(sim), "t2": sim.time ** 2})
    assert columns(by_address).equals(columns(serial))
    assert np.allclose(by_client.t2, by_client.time ** 2)
    assert (by_client.n[by_client.particle_radius == 0.02] == 1250).all()


def test_a_run_without_a_scene_is_refused():
    with pytest.raises(ValueError, match=r"runs\[1\] has no 'scene'"):
        sweep.sweep([{"scene": "dam-break"}, {"cfl": 1}], until=0.1, serial=True)


def docs_snippet():
    """The sweep example of docs/python.md ("Sweeps on a Dask cluster"), as written."""
    import pathlib
    import re

    docs = pathlib.Path(__file__).resolve().parents[2] / "docs" / "python.md"
    text = docs.read_text()
    section = text[text.index("## Sweeps on a Dask cluster"):]
    return re.search(r"```python\n(.*?)```", section, re.S).group(1)


def run_script(path, code):
    import subprocess
    import sys

    path.write_text(code)
    return subprocess.run([sys.executable, str(path)], capture_output=True, text=True,
                          timeout=300)


def test_the_docs_sweep_runs_as_a_script(tmp_path):
    run = run_script(tmp_path / "sweep_script.py", docs_snippet())
    assert run.returncode == 0, run.stderr
    # Two radii, each with its mean front at t = 0.4 s, past the column's 1 m width.
    fronts = [line.split() for line in run.stdout.splitlines() if line.startswith("0.0")]
    assert [f[0] for f in fronts] == ["0.02", "0.04"], run.stdout
    assert all(1.5 < float(f[1]) < 3.0 for f in fronts), run.stdout


def test_a_script_without_the_guard_is_told_to_add_it(tmp_path):
    lines = []
    for line in docs_snippet().splitlines():
        if line.startswith("if __name__"):
            continue
        lines.append(line[4:] if line.startswith("    ") else line)
    run = run_script(tmp_path / "unguarded.py", "\n".join(lines) + "\n")
    assert run.returncode != 0
    last = run.stderr.strip().splitlines()[-1]
    assert last.startswith("RuntimeError: could not start a local Dask cluster"), last
    assert 'under `if __name__ == "__main__":`' in last, last
