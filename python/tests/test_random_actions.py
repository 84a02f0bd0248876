"""Random actions with extreme values through the Python methods (a property test, with
Hypothesis): whatever the numbers (0, ±1e308, the smallest subnormal, ±f32's largest, NaN,
±infinity, ordinary ones), each call either raises one ValueError with a one-line message and
changes nothing, or is applied; then the particle count is what the call says (nothing added
or lost silently), and every position and velocity is finite, inside the tank as it stands
and no faster than MAX_SOUND_SPEED; no step finds a non-finite particle. The same values go through the recording format in crates/dfsph/tests/random_actions.rs.
"""

import math

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import dfsph2d

F32_MAX = 3.4028234663852886e38
F32_TINY = 1.1754943508222875e-38
# Ten times the cap on every speed a user can give (water, pours, bodies: 100 m/s), m/s; as
# in crates/dfsph/tests/random_actions.rs.
MAX_SOUND_SPEED = 1000.0
# How far a shaken tank moves from where it stands (simulation::MAX_SHAKE_OFFSET), m.
MAX_SHAKE_OFFSET = 0.4

# Hypothesis draws a list's first entries more often: the large finite ones come first.
EXTREMES = [
    # Large, yet their squares are finite in single precision.
    1e4,
    -3e6,
    1e15,
    -1e19,
    0.0,
    -0.0,
    1e308,
    -1e308,
    5e-324,
    F32_MAX,
    -F32_MAX,
    F32_TINY,
    1e30,
    -1e30,
    1e-30,
    math.nan,
    math.inf,
    -math.inf,
]
# A value: half of them extreme.
value = st.one_of(st.sampled_from(EXTREMES), st.floats(-200.0, 200.0))
number = st.one_of(st.sampled_from(EXTREMES), st.floats(-200.0, 200.0), st.floats(0.0, 3.0))
# A coordinate: mostly inside the tanks (0–3 m), so that actions often land in the water;
# a radius: mostly one that reaches a few particles.
inside = st.floats(0.1, 2.9)
coord = st.one_of(inside, inside, inside, number)
reach = st.floats(0.05, 1.0)
radius = st.one_of(reach, reach, number)

BODIES = [
    # At least 3 spacings across (0.3 m in these coarse scenes).
    {"shape": "box", "size": [0.4, 0.3], "density": 500, "position": [1.5, 2.0]},
    {"shape": "circle", "radius": 0.2, "mass": 30, "position": [2.0, 2.5], "angle": 0.3},
    {
        "shape": "polygon",
        "points": [[0, 0], [0.4, 0], [0.2, 0.4]],
        "density": 800,
        "position": [3.0, 2.0],
        "velocity": [1, 0],
        "angular_velocity": 2,
    },
]


@st.composite
def body(draw):
    """One of BODIES with one number replaced."""
    spec = json_copy(draw(st.sampled_from(BODIES)))
    slots = []
    for key, value in spec.items():
        if isinstance(value, (int, float)):
            slots.append((spec, key))
        elif isinstance(value, list):
            for i, item in enumerate(value):
                if isinstance(item, list):
                    slots.extend((item, j) for j in range(len(item)))
                else:
                    slots.append((value, i))
    where, key = draw(st.sampled_from(slots))
    where[key] = draw(number)
    return spec


def json_copy(value):
    if isinstance(value, dict):
        return {k: json_copy(v) for k, v in value.items()}
    if isinstance(value, list):
        return [json_copy(v) for v in value]
    return value


action = st.one_of(
    st.tuples(st.just("shake"), value),
    st.tuples(st.just("set_gravity"), value, value),
    st.tuples(st.just("push"), coord, coord, radius, value),
    st.tuples(st.just("release")),
    st.tuples(st.just("pour"), coord, coord, radius, value, value),
    st.tuples(st.just("add_wall"), st.lists(st.tuples(coord, coord), max_size=4)),
    st.tuples(st.just("erase"), coord, coord, radius),
    st.tuples(st.just("add_body"), body()),
    st.tuples(st.just("reset")),
    st.tuples(st.just("step"), st.integers(0, 3)),
)


def coarse(name):
    scene = dfsph2d.load_scene(name)
    scene["particle_radius"] = 0.05
    return scene


def assert_sound(sim, context):
    positions, velocities = sim.positions, sim.velocities
    assert np.isfinite(positions).all() and np.isfinite(velocities).all(), context
    fastest = np.hypot(*velocities.T).max(initial=0.0)
    assert fastest <= MAX_SOUND_SPEED, (context, fastest)
    tank = sim.scene["tank"]
    margin = MAX_SHAKE_OFFSET + 2 * sim.particle_radius
    lo = np.array(tank["min"]) - margin
    hi = np.array(tank["max"]) + margin
    inside = ((positions >= lo) & (positions <= hi)).all(axis=1)
    assert inside.all(), (context, positions[~inside][:5])


@settings(
    max_examples=500,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow],
    derandomize=True,
    database=None,
)
@given(
    name=st.sampled_from(["dam-break", "floating", "drop"]),
    actions=st.lists(action, min_size=1, max_size=8),
)
def test_random_extreme_actions_leave_a_sound_state(name, actions):
    sim = dfsph2d.Simulation(coarse(name), threads=1)
    for call in actions:
        method, args = call[0], call[1:]
        before = len(sim)
        context = f"{name}: {method}{args!r}"
        try:
            result = getattr(sim, method)(*args)
        except ValueError as e:
            message = str(e)
            assert message and "\n" not in message, context
            assert len(sim) == before, f"{context}: refused, yet changed the water"
            continue
        if method == "pour":
            assert len(sim) == before + result, context
        elif method == "erase":
            assert len(sim) == before - result, context
        elif method in ("step", "shake", "set_gravity", "push", "release"):
            assert len(sim) == before, context
        assert_sound(sim, context)
        count = len(sim)
        assert sim.step()["non_finite"] == 0, f"{context}: non-finite particles"
        assert len(sim) == count, f"{context}: particles lost in a step"
        assert_sound(sim, f"{context}, then a step")
