//! `dfsph2d` and `dfsph2d view`: open the interactive viewer (crate `dfsph-viewer`).

use std::path::PathBuf;

use anyhow::Result;
use dfsph::Scene;

/// Open the viewer on `scene`; returns when the window closes.
pub fn open(
    scene: Scene,
    exit_after: Option<f64>,
    save_on_exit: Option<PathBuf>,
    record: Option<PathBuf>,
) -> Result<()> {
    dfsph_viewer::run(dfsph_viewer::ViewerOptions {
        scene,
        exit_after,
        save_on_exit,
        record,
    })
}
