//! `dfsph2d` and `dfsph2d view`: open the interactive viewer (crate `dfsph-viewer`).

use std::path::PathBuf;

use anyhow::Result;
use dfsph::Scene;

/// Open the viewer on `scene`, read from the file `scene_file` (`None`: a built-in scene);
/// returns when the window closes. `fit_to_machine`: the scene's particle size is fitted to
/// this machine's speed ([`dfsph_viewer::resolution`]); `backend` makes the backend of every
/// scene the window loads (`None`: the CPU's).
pub fn open(
    scene: Scene,
    scene_file: Option<String>,
    exit_after: Option<f64>,
    save_on_exit: Option<PathBuf>,
    record: Option<PathBuf>,
    fit_to_machine: bool,
    backend: Option<dfsph::simulation::BackendFactory>,
) -> Result<()> {
    dfsph_viewer::run(dfsph_viewer::ViewerOptions {
        scene,
        exit_after,
        save_on_exit,
        record,
        fit_to_machine,
        scene_file,
        backend,
    })
}

/// The name the scene list shows for the SCENE argument `arg`: its file name, or `None` for
/// a built-in scene (a built-in name wins over a file of that name, as when loading).
pub fn scene_file_name(arg: &str) -> Option<String> {
    if dfsph::scene::builtin(arg).is_some() {
        return None;
    }
    Some(dfsph_viewer::scene_file::file_label(arg))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_scene_list_names_a_file_by_its_name_and_a_built_in_scene_not_at_all() {
        assert_eq!(scene_file_name("dam-break"), None);
        assert_eq!(
            scene_file_name("scenes/my tank.json").as_deref(),
            Some("my tank.json")
        );
        assert_eq!(scene_file_name("./dam-break").as_deref(), Some("dam-break"));
    }
}
