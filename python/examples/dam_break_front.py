"""The dam-break surge front against Martin & Moyce (1952), from Python.

A column a = 1 m wide and 2a high (n² = 2) collapses into an 18a-long tank; the front (the
largest x of a particle with 3 fluid neighbours) is plotted as Z = x/a against
T = t·√(2g/a) with Martin & Moyce's Fig. 3 measurements, as `dfsph2d validate` does
(docs/validation/dambreak_front_mm_fig3.png).

    pip install ./python[examples]
    python python/examples/dam_break_front.py --out front.png [--radius 0.01]

The default radius (2 cm, 1,250 particles) runs in a few seconds; 1 cm (5,000) in under a
minute on two cores.
"""

import argparse
import csv
import math
import pathlib
import time

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

import dfsph2d  # noqa: E402

G = 9.81
A = 1.0  # column width, m
DATA = (
    pathlib.Path(__file__).resolve().parents[2]
    / "crates/dfsph-app/data/validation/martin_moyce_1952_front_n2_fig3_long.csv"
)


def measurements(path):
    """Martin & Moyce's (T, Z) points per column width a (inches)."""
    series = {}
    with open(path) as f:
        rows = csv.DictReader(line for line in f if not line.startswith("#"))
        for row in rows:
            series.setdefault(row["a_inch"], []).append((float(row["T"]), float(row["Z"])))
    return series


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--radius", type=float, default=0.02, help="particle radius, m")
    parser.add_argument("--until", type=float, default=8.0, help="last T = t*sqrt(2g/a)")
    parser.add_argument("--out", default="dam_break_front.png", help="PNG to write")
    parser.add_argument("--data", default=str(DATA), help="Martin & Moyce Fig. 3 CSV")
    args = parser.parse_args()

    scene = {
        "name": "dam-break-n2",
        "particle_radius": args.radius,
        "tank": {"min": [0, 0], "max": [18 * A, 3 * A]},
        "fluid": [{"min": [0, 0], "max": [A, 2 * A]}],
    }
    sim = dfsph2d.Simulation(scene)
    k = math.sqrt(2 * G / A)
    ts, zs = [], []
    start = time.perf_counter()
    while sim.time * k < args.until:
        sim.advance(0.01)
        front = sim.front_position(3)
        if front is not None:
            ts.append(sim.time * k)
            zs.append(front / A)
    wall = time.perf_counter() - start
    print(
        f"{len(sim)} particles, {sim.step_count} steps to t = {sim.time:.3f} s "
        f"in {wall:.1f} s; front Z = {zs[-1]:.2f} at T = {ts[-1]:.2f}"
    )

    fig, ax = plt.subplots(figsize=(7, 4.5))
    ax.plot(ts, zs, label=f"dfsph2d, r = {args.radius} m ({len(sim)} particles)")
    for a_inch, points in measurements(args.data).items():
        t, z = zip(*points)
        ax.plot(t, z, "o", ms=4, label=f"Martin & Moyce 1952, a = {a_inch} in")
    ax.set_xlabel("T = t·√(2g/a)")
    ax.set_ylabel("Z = front / a")
    ax.set_title("Dam break, n² = 2: surge front")
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(args.out, dpi=120)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
