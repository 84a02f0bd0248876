"""python/examples/dam_break_front.py runs and draws its plot."""

import pathlib
import subprocess
import sys

import pytest

pytest.importorskip("matplotlib")

EXAMPLE = pathlib.Path(__file__).resolve().parents[1] / "examples" / "dam_break_front.py"


def test_the_dam_break_front_example_plots_the_front(tmp_path):
    out = tmp_path / "front.png"
    run = subprocess.run([sys.executable, str(EXAMPLE), "--until", "2", "--out", str(out)],
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    # T = 2: the front has left the column (Z = 1) and is near Martin & Moyce's Z ≈ 2.3.
    z = float(run.stdout.split("front Z = ")[1].split()[0])
    assert 2.0 < z < 3.2, run.stdout
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert out.stat().st_size > 10_000
