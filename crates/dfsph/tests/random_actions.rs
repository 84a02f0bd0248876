//! Random actions with extreme but representable values, through the recording format: each
//! case writes its actions with the [`Recorder`], reads the recording back with
//! [`Recording::parse`], and replays it on a small simulation, each action after its step.
//! Whatever the values (0, ±f32::MAX, the smallest normal number, ±1e30, ordinary ones):
//!
//! - the recording reads back exactly as written;
//! - applying an action gives an outcome or a refusal with its reason, never a panic;
//! - the fluid count is what the outcomes say (nothing added or lost silently), after every
//!   action and across every step;
//! - after every step every position and velocity is finite, no particle was found
//!   non-finite, every particle is inside the tank as it stands, and none moves faster than
//!   [`MAX_SOUND_SPEED`].
//!
//! (Python's methods get the same values in python/tests/test_random_actions.py.)

use dfsph::recording::{Header, Recorder, Recording};
use dfsph::rigid::BodySpec;
use dfsph::scene::{SolverParams, TimeStepParams, ViscosityParams};
use dfsph::{Action, Scene, Simulation, Vec2};
use proptest::prelude::*;
use serde_json::Value;

/// No water moves faster than this in a sound state, m/s: ten times the cap on every speed a
/// user can give (a scene's water, a pour, a body: 100 m/s), where gravity (at most 100 m/s²),
/// the pointer (80 m/s²) and shaking add little over a few steps. A pour at 1e19 m/s (the cap
/// taken away) left finite particles that moved this fast in steps of 5e-21 s.
const MAX_SOUND_SPEED: f32 = 1000.0;

/// A number an action may carry: extreme ones and ordinary ones, never NaN or infinite (JSON
/// cannot hold those; the recorder refuses them).
fn number() -> impl Strategy<Value = f32> {
    prop_oneof![
        1 => Just(0.0f32),
        1 => Just(-0.0f32),
        1 => Just(f32::MAX),
        1 => Just(f32::MIN),
        1 => Just(f32::MIN_POSITIVE),
        1 => Just(-f32::MIN_POSITIVE),
        1 => Just(1e30f32),
        1 => Just(-1e30f32),
        1 => Just(1e-30f32),
        // Large, yet their squares are finite in f32.
        1 => Just(1e4f32),
        1 => Just(-3e6f32),
        1 => Just(1e15f32),
        1 => Just(-1e19f32),
        3 => -200.0f32..200.0,
        // In the tanks' range, so that positions often fall inside.
        12 => 0.0f32..3.0,
    ]
}

fn point() -> impl Strategy<Value = Vec2> {
    (number(), number()).prop_map(|(x, y)| Vec2::new(x, y))
}

/// `value` with its `leaf`-th numeric leaf (depth first, modulo their count) set to `x`; the
/// value itself where it has none.
fn with_leaf(mut value: Value, leaf: usize, x: f64) -> Value {
    fn count(v: &Value) -> usize {
        match v {
            Value::Number(_) => 1,
            Value::Array(a) => a.iter().map(count).sum(),
            Value::Object(o) => o.values().map(count).sum(),
            _ => 0,
        }
    }
    /// Set the `n`-th leaf; true once it is set.
    fn set(v: &mut Value, n: &mut usize, x: &Value) -> bool {
        match v {
            Value::Number(_) if *n == 0 => {
                *v = x.clone();
                true
            }
            Value::Number(_) => {
                *n -= 1;
                false
            }
            Value::Array(a) => a.iter_mut().any(|v| set(v, n, x)),
            Value::Object(o) => o.values_mut().any(|v| set(v, n, x)),
            _ => false,
        }
    }
    let leaves = count(&value);
    if leaves > 0 {
        let x = serde_json::Number::from_f64(x).map_or(Value::Null, Value::Number);
        set(&mut value, &mut (leaf % leaves), &x);
    }
    value
}

/// Default parameters of type `T` with one numeric field set to `x`, or `None` where that
/// does not deserialise (a fraction or negative number in a whole-number field).
fn one_field<T: serde::Serialize + serde::de::DeserializeOwned>(
    defaults: &T,
    leaf: usize,
    x: f32,
) -> Option<T> {
    let value = with_leaf(serde_json::to_value(defaults).unwrap(), leaf, x as f64);
    serde_json::from_value(value).ok()
}

/// A body the scene format accepts in shape, with one numeric field set to `x`.
fn body(shape: usize, leaf: usize, x: f32) -> Option<BodySpec> {
    let bodies = [
        // At least 3 spacings across (0.3 m in these coarse scenes).
        r#"{"shape": "box", "size": [0.4, 0.3], "density": 500, "position": [1.5, 2.0]}"#,
        r#"{"shape": "circle", "radius": 0.2, "mass": 30, "position": [2.0, 2.5], "angle": 0.3}"#,
        r#"{"shape": "polygon", "points": [[0, 0], [0.4, 0], [0.2, 0.4]], "density": 800,
            "position": [3.0, 2.0], "velocity": [1, 0], "angular_velocity": 2}"#,
    ];
    let value: Value = serde_json::from_str(bodies[shape % bodies.len()]).unwrap();
    serde_json::from_value(with_leaf(value, leaf, x as f64)).ok()
}

fn action() -> impl Strategy<Value = Option<Action>> {
    let solver = SolverParams::default();
    let viscosity = ViscosityParams::default();
    let time_step = TimeStepParams::default();
    prop_oneof![
        number().prop_map(|direction| Some(Action::ShakeTank { direction })),
        point().prop_map(|gravity| Some(Action::SetGravity { gravity })),
        (point(), number(), number()).prop_map(|(at, radius, strength)| Some(Action::Push {
            at,
            radius,
            strength
        })),
        Just(Some(Action::ReleasePointer)),
        (point(), number(), point()).prop_map(|(at, radius, velocity)| Some(Action::Emit {
            at,
            radius,
            velocity
        })),
        prop::collection::vec(point(), 0..5)
            .prop_map(|polyline| Some(Action::AddWall { polyline })),
        (point(), number()).prop_map(|(at, radius)| Some(Action::Erase { at, radius })),
        (0usize..3, 0usize..16, number())
            .prop_map(|(s, l, x)| body(s, l, x).map(|body| Action::AddBody { body })),
        point().prop_map(|at| Some(Action::GrabBody { at })),
        point().prop_map(|target| Some(Action::DragBody { target })),
        Just(Some(Action::ReleaseBody)),
        (0usize..16, number()).prop_map(
            move |(l, x)| one_field(&solver, l, x).map(|solver| Action::SetSolver { solver })
        ),
        (0usize..4, number()).prop_map(move |(l, x)| one_field(&viscosity, l, x)
            .map(|viscosity| Action::SetViscosity { viscosity })),
        (0usize..4, number()).prop_map(move |(l, x)| one_field(&time_step, l, x)
            .map(|time_step| Action::SetTimeStep { time_step })),
        Just(Some(Action::Reset { scene: None })),
        (0usize..4).prop_map(|index| Some(Action::RemoveDrawnWall { index })),
        (0u32..6000, 0u32..6000).prop_map(|(from, to)| Some(Action::RemoveParticles { from, to })),
    ]
}

/// The scenes the actions are replayed on: few particles, one with bodies.
fn scene(which: usize) -> Scene {
    let name = ["dam-break", "floating", "drop"][which % 3];
    let mut s = dfsph::scene::builtin(name).unwrap();
    s.particle_radius = 0.05;
    s
}

/// Every particle finite and in the tank as it stands, none found non-finite.
fn assert_sound(sim: &Simulation, context: &str) {
    assert_eq!(sim.total_non_finite(), 0, "{context}: non-finite particles");
    let (lo, hi) = sim.tank_containment();
    for (x, v) in sim.positions().iter().zip(sim.velocities()) {
        assert!(x.is_finite() && v.is_finite(), "{context}: {x} {v}");
        assert!(v.length() <= MAX_SOUND_SPEED, "{context}: {v} m/s");
        let inside = x.x >= lo.x && x.y >= lo.y && x.x <= hi.x && x.y <= hi.y;
        assert!(inside, "{context}: {x} outside the tank {lo}..{hi}");
    }
}

fn replay(which: usize, actions: &[(u64, Action)]) {
    let scene = scene(which);
    // Through the recording format: written, read back, the same.
    let mut bytes = Vec::new();
    let header = Header::new("random-actions", 1, &scene);
    {
        let mut recorder = Recorder::new(&mut bytes, &header).unwrap();
        let mut step = 0;
        for (gap, action) in actions {
            step += gap;
            recorder.record(step, action).unwrap();
        }
    }
    let text = String::from_utf8(bytes).unwrap();
    let recording = Recording::parse(&text).unwrap_or_else(|e| panic!("{e}\n{text}"));
    let read: Vec<Action> = recording.entries.iter().map(|e| e.action.clone()).collect();
    let written: Vec<Action> = actions.iter().map(|(_, a)| a.clone()).collect();
    assert_eq!(read, written);

    let mut sim = Simulation::new(&recording.header.scene).unwrap();
    let mut entries = recording.entries.iter().peekable();
    let end = recording.steps() + 3;
    for step in 0..=end {
        while let Some(entry) = entries.next_if(|e| e.step == step) {
            let before = sim.fluid_count();
            let outcome = sim.apply(&entry.action);
            let context = format!("{:?} at step {step}: {outcome:?}", entry.action);
            if let Some(reason) = outcome.rejected {
                assert!(!reason.is_empty() && !reason.contains('\n'), "{context}");
                assert_eq!(sim.fluid_count(), before, "{context}: refused, yet changed");
            } else {
                assert_eq!(
                    sim.fluid_count(),
                    before + outcome.added - outcome.removed,
                    "{context}"
                );
            }
        }
        if step == end {
            break;
        }
        let before = sim.fluid_count();
        sim.step();
        let context = format!("step {step} of {text}");
        assert_eq!(
            sim.fluid_count(),
            before,
            "{context}: particles lost in a step"
        );
        assert_sound(&sim, &context);
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn random_extreme_actions_replay_soundly(
        which in 0usize..3,
        actions in prop::collection::vec((0u64..4, action()), 1..8),
    ) {
        let actions: Vec<(u64, Action)> =
            actions.into_iter().filter_map(|(gap, a)| a.map(|a| (gap, a))).collect();
        replay(which, &actions);
    }
}
