//! A scene in a link: the part of a page address after `#` that reproduces a scene.
//!
//! - `scene=NAME`: a built-in scene as it ships (`#scene=dam-break`);
//! - `s=DATA`: any other scene, its JSON deflated and base64url-encoded (a few hundred
//!   characters for a built-in scene with drawn walls or changed settings).
//!
//! What is shared ([`shared_scene`]) is the scene being played: its tank, walls (drawn ones
//! included), gravity, radius and solver settings, with the water as the scene started it,
//! not the particles' current state (that is what "Save scene" is for).

use anyhow::{anyhow, bail, Context as _};
use base64::engine::general_purpose::URL_SAFE_NO_PAD;
use base64::Engine as _;
use dfsph::scene::BUILTIN_SCENES;
use dfsph::{Scene, Simulation};

/// The largest scene a link may unpack to, bytes of JSON: a hostile link cannot make the
/// page inflate gigabytes.
pub const MAX_SHARED_JSON: usize = 16 << 20;

/// The scene to share from a running simulation: as it stands (walls drawn, settings, gravity,
/// radius), with the water of `loaded`, the scene as loaded.
pub fn shared_scene(sim: &Simulation, loaded: &Scene) -> Scene {
    let mut scene = sim.to_scene();
    scene.fluid = loaded.fluid.clone();
    scene.particles = loaded.particles.clone();
    scene.max_particles = loaded.max_particles;
    scene
}

/// The address fragment (without `#`) that reproduces `scene`.
pub fn fragment(scene: &Scene) -> String {
    if let Some(b) = BUILTIN_SCENES.iter().find(|b| b.scene() == *scene) {
        return format!("scene={}", b.name);
    }
    let json = serde_json::to_string(scene).expect("a scene serialises");
    let packed = miniz_oxide::deflate::compress_to_vec(json.as_bytes(), 9);
    format!("s={}", URL_SAFE_NO_PAD.encode(packed))
}

/// The scene an address fragment (without `#`) names; `Ok(None)` for a fragment that names
/// none (empty, or another key). Errors say what is wrong with the link.
pub fn scene_from_fragment(fragment: &str) -> anyhow::Result<Option<Scene>> {
    let fragment = fragment.trim_start_matches('#');
    if let Some(name) = fragment.strip_prefix("scene=") {
        let name = percent_decode(name);
        return dfsph::scene::builtin(&name).map(Some).ok_or_else(|| {
            let names: Vec<_> = BUILTIN_SCENES.iter().map(|b| b.name).collect();
            anyhow!(
                "the link names scene `{name}`, which is not one of {}",
                names.join(", ")
            )
        });
    }
    let Some(data) = fragment.strip_prefix("s=") else {
        return Ok(None);
    };
    let packed = URL_SAFE_NO_PAD
        .decode(data.trim_end_matches('='))
        .context("the link's scene is not base64url (was the link cut short?)")?;
    let json = miniz_oxide::inflate::decompress_to_vec_with_limit(&packed, MAX_SHARED_JSON)
        .map_err(|e| match e.status {
            miniz_oxide::inflate::TINFLStatus::HasMoreOutput => anyhow!(
                "the link's scene unpacks to more than {} MiB",
                MAX_SHARED_JSON >> 20
            ),
            _ => anyhow!("the link's scene is damaged (was the link cut short?)"),
        })?;
    let text = std::str::from_utf8(&json).context("the link's scene is not UTF-8 text")?;
    match Scene::from_json(text) {
        Ok(scene) => Ok(Some(scene)),
        Err(e) => bail!("the link's scene: {e}"),
    }
}

/// The scene a page opens with.
#[derive(Clone, Debug, PartialEq)]
pub struct InitialScene {
    pub scene: Scene,
    /// Why the link's scene was not used, if it was not.
    pub note: Option<String>,
    /// The page's own default scene, fitted to this machine as the window's is
    /// ([`crate::resolution`]); a scene a link names keeps its resolution.
    pub fit_to_machine: bool,
}

/// The scene a page opens with: the one its address names, or the default dam break (with a
/// note saying why the link's scene was not used, when there was one).
pub fn initial_scene(fragment: &str) -> InitialScene {
    let default = || dfsph::scene::builtin("dam-break").expect("the dam break is built in");
    let (scene, note) = match scene_from_fragment(fragment) {
        Ok(Some(scene)) => {
            return InitialScene {
                scene,
                note: None,
                fit_to_machine: false,
            }
        }
        Ok(None) => (default(), None),
        Err(e) => (default(), Some(format!("{e:#}; showing the dam break"))),
    };
    InitialScene {
        scene,
        note,
        fit_to_machine: true,
    }
}

/// `%XX` escapes decoded (a browser may escape a name typed into the address bar).
fn percent_decode(s: &str) -> String {
    let bytes = s.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        let hex = |b: u8| (b as char).to_digit(16);
        if bytes[i] == b'%' && i + 2 < bytes.len() {
            if let (Some(h), Some(l)) = (hex(bytes[i + 1]), hex(bytes[i + 2])) {
                out.push((h * 16 + l) as u8);
                i += 3;
                continue;
            }
        }
        out.push(bytes[i]);
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_builtin_scene_is_shared_by_name_and_comes_back_equal() {
        for b in BUILTIN_SCENES {
            let f = fragment(&b.scene());
            assert_eq!(f, format!("scene={}", b.name));
            assert_eq!(scene_from_fragment(&f).unwrap(), Some(b.scene()));
        }
        assert_eq!(
            scene_from_fragment("#scene=dam%2Dbreak").unwrap(),
            dfsph::scene::builtin("dam-break")
        );
    }

    #[test]
    fn a_changed_scene_with_a_drawn_wall_survives_the_link() {
        let loaded = dfsph::scene::builtin("dam-break").unwrap();
        let mut sim = Simulation::new(&loaded).unwrap();
        sim.apply(&dfsph::Action::AddWall {
            polyline: vec![dfsph::Vec2::new(2.5, 0.2), dfsph::Vec2::new(3.0, 0.8)],
        });
        sim.apply(&dfsph::Action::SetGravity {
            gravity: dfsph::Vec2::new(1.0, -9.0),
        });
        for _ in 0..3 {
            sim.step();
        }
        let shared = shared_scene(&sim, &loaded);
        assert_eq!(
            shared.fluid, loaded.fluid,
            "the water as the scene started it"
        );
        assert!(shared.particles.positions.is_empty());
        assert_eq!(shared.obstacles.len(), loaded.obstacles.len() + 1);
        let f = fragment(&shared);
        assert!(f.starts_with("s="), "{f}");
        assert!(f.len() < 2000, "a link of {} characters", f.len());
        let back = scene_from_fragment(&f).unwrap().unwrap();
        assert_eq!(back, shared);
        // And it runs: the same first step as the scene it came from.
        let mut a = Simulation::new(&back).unwrap();
        let mut b = Simulation::new(&shared).unwrap();
        assert_eq!(a.step().dt, b.step().dt);
    }

    #[test]
    fn bad_links_say_what_is_wrong_and_fall_back_to_the_dam_break() {
        let msg = |f: &str| format!("{:#}", scene_from_fragment(f).unwrap_err());
        assert!(
            msg("scene=ocean").contains("`ocean`"),
            "{}",
            msg("scene=ocean")
        );
        assert!(msg("s=!!!").contains("base64url"));
        let f = fragment(&{
            let mut s = dfsph::scene::builtin("dam-break").unwrap();
            s.gravity = [0.5, -9.81];
            s
        });
        assert!(msg(&f[..f.len() / 2]).contains("cut short"));
        // A valid link to JSON that is not a valid scene names the key.
        let bad = miniz_oxide::deflate::compress_to_vec(br#"{"particle_radius": -1}"#, 9);
        let bad = format!("s={}", URL_SAFE_NO_PAD.encode(bad));
        assert!(msg(&bad).contains("particle_radius"), "{}", msg(&bad));
        // A deflate bomb is refused before it is unpacked whole.
        let bomb = vec![b' '; MAX_SHARED_JSON + 1];
        let bomb = miniz_oxide::deflate::compress_to_vec(&bomb, 9);
        let bomb = format!("s={}", URL_SAFE_NO_PAD.encode(bomb));
        assert!(bomb.len() < 100_000);
        assert!(msg(&bomb).contains("more than 16 MiB"), "{}", msg(&bomb));

        let bad_link = initial_scene("scene=ocean");
        assert_eq!(bad_link.scene.name, "dam-break");
        assert!(bad_link.note.unwrap().contains("showing the dam break"));
        assert!(bad_link.fit_to_machine);
        let plain = initial_scene("");
        assert_eq!(plain.scene, bad_link.scene);
        assert_eq!(plain.note, None);
        assert!(plain.fit_to_machine, "the page's own default is fitted");
        let named = initial_scene("scene=hydrostatic");
        assert_eq!(named.scene.name, "hydrostatic");
        assert!(
            !named.fit_to_machine,
            "a scene a link names keeps its resolution"
        );
        assert!(scene_from_fragment("other=1").unwrap().is_none());
    }
}
