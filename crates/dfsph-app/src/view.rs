//! `dfsph2d` and `dfsph2d view`: open the interactive viewer (crate `dfsph-viewer`).

use std::path::PathBuf;

use anyhow::Result;
use dfsph::Scene;

/// Open the viewer on `scene`; returns when the window closes. `fit_to_machine`: the
/// scene's particle size is fitted to this machine's speed ([`dfsph_viewer::resolution`]).
pub fn open(
    scene: Scene,
    exit_after: Option<f64>,
    save_on_exit: Option<PathBuf>,
    record: Option<PathBuf>,
    fit_to_machine: bool,
) -> Result<()> {
    dfsph_viewer::run(dfsph_viewer::ViewerOptions {
        scene,
        exit_after,
        save_on_exit,
        record,
        fit_to_machine,
    })
}
