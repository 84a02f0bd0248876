//! `docs/scenes.md` stays true: its example scene loads, every key of a resolved scene is
//! documented, and every built-in scene is listed.

use dfsph::scene::{self, Obstacle};
use dfsph::Scene;

const DOC: &str = include_str!("../../../docs/scenes.md");

/// The ```json blocks of the page.
fn json_blocks() -> Vec<String> {
    let mut blocks = Vec::new();
    let mut current: Option<String> = None;
    for line in DOC.lines() {
        match (&mut current, line.trim_start()) {
            (None, "```json") => current = Some(String::new()),
            (Some(_), "```") => blocks.extend(current.take()),
            (Some(block), _) => {
                block.push_str(line);
                block.push('\n');
            }
            _ => {}
        }
    }
    blocks
}

/// Dotted key paths of a JSON value: `solver.method`, `fluid[i].min`, ...
fn key_paths(value: &serde_json::Value, prefix: &str, out: &mut Vec<String>) {
    match value {
        serde_json::Value::Object(map) => {
            for (k, v) in map {
                let path = if prefix.is_empty() {
                    k.clone()
                } else {
                    format!("{prefix}.{k}")
                };
                out.push(path.clone());
                key_paths(v, &path, out);
            }
        }
        serde_json::Value::Array(items) => {
            for item in items.iter().filter(|i| i.is_object()) {
                key_paths(item, &format!("{prefix}[i]"), out);
            }
        }
        _ => {}
    }
}

#[test]
fn example_scene_loads() {
    let blocks = json_blocks();
    assert!(!blocks.is_empty(), "no ```json example in docs/scenes.md");
    for block in blocks {
        let scene = Scene::from_json(&block).unwrap_or_else(|e| panic!("{e}\n{block}"));
        dfsph::Simulation::new(&scene).unwrap();
    }
}

#[test]
fn every_key_is_documented() {
    let scene = Scene {
        obstacles: vec![
            Obstacle::Rect {
                min: [1.0, 0.0],
                max: [1.1, 0.2],
            },
            Obstacle::Polyline {
                points: vec![[2.0, 0.0], [3.0, 1.0]],
            },
            Obstacle::Particles {
                positions: vec![[2.5, 1.5]],
            },
        ],
        bodies: vec![
            scene::BodySpec::new_box([0.4, 0.2], 500.0, [2.0, 1.0]),
            scene::BodySpec {
                joint: Some(scene::BodyJoint::Hinge { anchor: [1.0, 1.0] }),
                ..scene::BodySpec::new_circle(0.1, 250.0, [1.0, 1.5])
            },
            scene::BodySpec {
                shape: scene::BodyShape::Polygon,
                points: Some(vec![[-0.1, -0.1], [0.1, -0.1], [0.0, 0.1]]),
                size: None,
                density: None,
                mass: Some(10.0),
                ..scene::BodySpec::new_box([0.0, 0.0], 0.0, [3.0, 1.0])
            },
        ],
        particles: scene::ParticleList {
            positions: vec![[3.5, 2.5]],
            velocities: vec![[1.0, 0.0]],
        },
        ..Scene::default()
    };
    let value: serde_json::Value = serde_json::from_str(&scene.to_json()).unwrap();
    let mut keys = Vec::new();
    key_paths(&value, "", &mut keys);
    assert!(keys.len() > 25, "{keys:?}");
    for key in keys {
        assert!(
            DOC.contains(&format!("`{key}`")),
            "docs/scenes.md does not document `{key}`"
        );
    }
}

#[test]
fn every_builtin_scene_is_listed() {
    for b in scene::BUILTIN_SCENES {
        assert!(
            DOC.contains(&format!("| `{}` |", b.name)),
            "docs/scenes.md does not list `{}`",
            b.name
        );
    }
}
