//! Fuzzing the scene parser (and the recording parser) with proptest: whatever the text —
//! random bytes, random JSON, or a valid scene with random edits — parsing returns `Ok` or an
//! error with a one-line message, never panics; a scene it accepts validates, and when it is
//! small enough to build, builds and steps without panicking or leaving the tank.

use dfsph::recording::Recording;
use dfsph::{Scene, Simulation};
use proptest::prelude::*;
use serde_json::Value;

/// Valid scenes to mutate: the built-ins, coarse, as resolved JSON.
fn seeds() -> Vec<String> {
    dfsph::scene::BUILTIN_SCENES
        .iter()
        .map(|b| {
            let mut s = b.scene();
            s.particle_radius = 0.05;
            s.to_json()
        })
        .collect()
}

/// Check one input: no panic, a one-line error, and an accepted scene that behaves.
fn check(text: &str) {
    match Scene::from_json(text) {
        Err(e) => {
            let msg = e.to_string();
            assert!(!msg.is_empty());
        }
        Ok(scene) => {
            scene.validate().expect("an accepted scene validates");
            // Build and step only what is cheap: few particles, a small tank.
            let d = scene.spacing();
            let sites = (scene.tank.max[0] - scene.tank.min[0]) / d
                * ((scene.tank.max[1] - scene.tank.min[1]) / d);
            if scene.fluid_particle_count() <= 3000 && sites <= 1.0e5 && scene.obstacles.len() <= 20
            {
                let mut sim = Simulation::new(&scene).expect("a valid scene builds");
                // Sites under obstacles stay empty, so the lattice count is an upper bound.
                let n = sim.fluid_count();
                assert!(n <= scene.fluid_particle_count());
                if scene.obstacles.is_empty() {
                    assert_eq!(n, scene.fluid_particle_count());
                }
                for _ in 0..3 {
                    let s = *sim.step();
                    assert_eq!(s.n_fluid, n);
                }
                assert!(sim.positions().iter().all(|p| p.is_finite()));
            }
        }
    }
}

/// Random JSON values, a few levels deep, with the scene's own key names mixed in.
fn json_value() -> impl Strategy<Value = Value> {
    let key = prop_oneof![
        Just("particle_radius".to_string()),
        Just("tank".to_string()),
        Just("min".to_string()),
        Just("max".to_string()),
        Just("fluid".to_string()),
        Just("obstacles".to_string()),
        Just("type".to_string()),
        Just("points".to_string()),
        Just("solver".to_string()),
        Just("max_particles".to_string()),
        Just("gravity".to_string()),
        "[a-z_]{1,12}",
    ];
    let leaf = prop_oneof![
        Just(Value::Null),
        any::<bool>().prop_map(Value::Bool),
        any::<i64>().prop_map(Value::from),
        any::<f64>()
            .prop_filter("JSON numbers are finite", |f| f.is_finite())
            .prop_map(Value::from),
        (-10.0f64..10.0).prop_map(Value::from),
        "[a-z]{0,8}".prop_map(Value::String),
    ];
    leaf.prop_recursive(4, 64, 8, move |inner| {
        prop_oneof![
            prop::collection::vec(inner.clone(), 0..6).prop_map(Value::Array),
            prop::collection::vec((key.clone(), inner), 0..6)
                .prop_map(|kv| Value::Object(kv.into_iter().collect())),
        ]
    })
}

/// An edit of a valid scene's text.
#[derive(Clone, Debug)]
enum Edit {
    Delete(usize, usize),
    Insert(usize, String),
    /// Replace the n-th number with this text.
    Number(usize, String),
    Truncate(usize),
}

fn edit() -> impl Strategy<Value = Edit> {
    let number = prop_oneof![
        Just("0".to_string()),
        Just("-1".to_string()),
        Just("1e308".to_string()),
        Just("1e400".to_string()),
        Just("-0.0".to_string()),
        Just("18446744073709551616".to_string()),
        Just("0.0000001".to_string()),
        Just("\"x\"".to_string()),
        Just("null".to_string()),
        Just("[]".to_string()),
        any::<f64>()
            .prop_filter("finite", |f| f.is_finite())
            .prop_map(|f| format!("{f:e}")),
        (-5.0f64..5.0).prop_map(|f| f.to_string()),
    ];
    prop_oneof![
        (any::<usize>(), 1usize..20).prop_map(|(a, n)| Edit::Delete(a, n)),
        (any::<usize>(), "[\\[\\]{}\",:0-9a-z. -]{1,6}").prop_map(|(a, s)| Edit::Insert(a, s)),
        (any::<usize>(), number).prop_map(|(i, s)| Edit::Number(i, s)),
        any::<usize>().prop_map(Edit::Truncate),
    ]
}

fn apply(text: &str, e: &Edit) -> String {
    let chars: Vec<char> = text.chars().collect();
    let at = |a: usize| a % (chars.len() + 1);
    match e {
        Edit::Delete(a, n) => {
            let a = at(*a);
            let b = (a + n).min(chars.len());
            chars[..a].iter().chain(&chars[b..]).collect()
        }
        Edit::Insert(a, s) => {
            let a = at(*a);
            let mut out: String = chars[..a].iter().collect();
            out.push_str(s);
            out.extend(&chars[a..]);
            out
        }
        Edit::Truncate(a) => chars[..at(*a)].iter().collect(),
        Edit::Number(i, s) => {
            // Spans of number characters.
            let mut spans = Vec::new();
            let mut k = 0;
            while k < chars.len() {
                if chars[k].is_ascii_digit() || chars[k] == '-' {
                    let start = k;
                    while k < chars.len()
                        && (chars[k].is_ascii_digit() || "-+.eE".contains(chars[k]))
                    {
                        k += 1;
                    }
                    spans.push((start, k));
                } else {
                    k += 1;
                }
            }
            if spans.is_empty() {
                return text.to_string();
            }
            let (a, b) = spans[i % spans.len()];
            let mut out: String = chars[..a].iter().collect();
            out.push_str(s);
            out.extend(&chars[b..]);
            out
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn random_bytes_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..512)) {
        check(&String::from_utf8_lossy(&bytes));
        let _ = Recording::parse(&String::from_utf8_lossy(&bytes));
    }

    #[test]
    fn random_json_never_panics(value in json_value()) {
        check(&value.to_string());
        let _ = Recording::parse(&value.to_string());
    }

    #[test]
    fn edited_scenes_never_panic(
        which in 0usize..5,
        edits in prop::collection::vec(edit(), 1..4),
    ) {
        let seeds = seeds();
        let mut text = seeds[which % seeds.len()].clone();
        for e in &edits {
            text = apply(&text, e);
        }
        check(&text);
    }

    #[test]
    fn edited_recordings_never_panic(
        edits in prop::collection::vec(edit(), 1..4),
    ) {
        let mut s = dfsph::scene::builtin("drop").unwrap();
        s.particle_radius = 0.05;
        let header = dfsph::recording::Header::new("fuzz", 1, &s);
        let mut text = serde_json::to_string(&header).unwrap();
        text.push_str("\n{\"step\":0,\"action\":\"shake_tank\",\"direction\":1.0}\n");
        text.push_str("{\"step\":5,\"action\":\"add_wall\",\"polyline\":[[1,1],[2,0.5]]}\n");
        text.push_str("{\"end\":9,\"time\":0.009,\"n_fluid\":1,\"fingerprint\":\"00\"}\n");
        for e in &edits {
            text = apply(&text, e);
        }
        if let Err(e) = Recording::parse(&text) {
            prop_assert!(e.to_string().starts_with("line "));
            prop_assert!(!e.to_string().contains('\n'));
        }
    }
}
