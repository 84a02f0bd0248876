//! What the viewer is asked to show, and for how long.

use std::path::PathBuf;

/// What to show and how long.
#[derive(Clone)]
pub struct ViewerOptions {
    /// The scene to run.
    pub scene: dfsph::Scene,
    /// Close the window after this many seconds of wall time.
    pub exit_after: Option<f64>,
    /// When closing because of `exit_after` (and only then), write `particles.csv` (`x,y,vx,vy,density,
    /// pressure`), `screenshot.png`, `session.json` (run statistics and the applied
    /// actions) and `scene.json` (the state as a scene that `run` and `view` load) into this
    /// directory.
    pub save_on_exit: Option<PathBuf>,
    /// Record every action with the step at which it applies into this file (JSON lines,
    /// `docs/recording.md`), for `dfsph2d run SCENE --replay FILE`.
    pub record: Option<PathBuf>,
    /// Fit the scene's particle size to this machine's speed in the first seconds
    /// ([`crate::resolution`]): for the built-in scene the window opens with when none is named;
    /// a scene the user names keeps its resolution.
    pub fit_to_machine: bool,
    /// The file the scene was read from (`view FILE`): the scene list names it, as after
    /// Open, rather than the scene's own `name`. `None` for a built-in scene.
    pub scene_file: Option<String>,
    /// Makes the backend that steps the water, for every scene the window loads (`None`:
    /// the CPU backend; `--backend` of the command line).
    pub backend: Option<dfsph::simulation::BackendFactory>,
}

impl ViewerOptions {
    /// Show `scene` until the user closes the window.
    pub fn new(scene: dfsph::Scene) -> Self {
        Self {
            scene,
            exit_after: None,
            save_on_exit: None,
            record: None,
            fit_to_machine: false,
            scene_file: None,
            backend: None,
        }
    }
}
