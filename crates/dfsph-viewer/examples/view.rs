//! Open the viewer without the `dfsph2d` CLI:
//! `cargo run --release -p dfsph-viewer --example view -- [SCENE] [--exit-after S] [--save-on-exit DIR]`
//! where SCENE is a built-in scene name (default `dam-break`).

use dfsph_viewer::{run, ViewerOptions};

fn main() -> anyhow::Result<()> {
    let mut args = std::env::args().skip(1);
    let mut opts = ViewerOptions::new(dfsph::Scene::default());
    while let Some(a) = args.next() {
        match a.as_str() {
            "--exit-after" => opts.exit_after = Some(args.next().unwrap_or_default().parse()?),
            "--save-on-exit" => opts.save_on_exit = args.next().map(Into::into),
            name => {
                opts.scene = dfsph::scene::builtin(name)
                    .ok_or_else(|| anyhow::anyhow!("unknown scene `{name}`"))?
            }
        }
    }
    run(opts)
}
