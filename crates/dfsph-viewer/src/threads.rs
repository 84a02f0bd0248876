//! How the window shares the cores between the water and the drawing.
//!
//! Under a software OpenGL rasteriser (Mesa's llvmpipe: no GPU, a virtual display, a remote
//! session) the drawing is CPU work too. Left alone, llvmpipe starts a thread per core and the
//! solver's pool another per core, and on two cores the four of them, each waiting at its
//! own barriers, gave the water 0.056–0.066 times real time at 20k particles. With one
//! rasteriser thread and one solver thread the same window ran at 0.074–0.084, about what
//! the solver makes of one core headless (0.081 over the same 1.1 s), at the same 18–21 frames
//! a second (Zen 5 host, Xvfb, 2026-11-27). So: llvmpipe gets a quarter of the cores (at
//! least one) unless `LP_NUM_THREADS` says otherwise, and under it the solver steps on the
//! rest. With a GPU the solver keeps every core. `RAYON_NUM_THREADS`, when set, decides the
//! solver's threads as everywhere else.

/// The variable Mesa's llvmpipe reads for its rasteriser threads.
pub const SOFTWARE_RASTERISER_THREADS: &str = "LP_NUM_THREADS";

/// The cores this process may use.
pub fn cores() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

/// Rasteriser threads a software renderer gets on `cores` cores.
pub fn software_draw_threads(cores: usize) -> usize {
    (cores / 4).max(1)
}

/// Threads the solver steps on, on `cores` cores, when the renderer is `software`; `None`
/// when the user chose (`RAYON_NUM_THREADS`): rayon's pool, sized by them.
pub fn solver_threads(cores: usize, software: bool) -> Option<usize> {
    if std::env::var_os("RAYON_NUM_THREADS").is_some() {
        return None;
    }
    Some(if software {
        cores.saturating_sub(software_draw_threads(cores)).max(1)
    } else {
        cores
    })
}

/// Whether an OpenGL `GL_RENDERER` string names a software rasteriser.
pub fn is_software_renderer(renderer: &str) -> bool {
    let r = renderer.to_ascii_lowercase();
    [
        "llvmpipe",
        "softpipe",
        "swiftshader",
        "software rasterizer",
        "swrast",
    ]
    .iter()
    .any(|name| r.contains(name))
}

/// Give a software rasteriser its share of the cores ([`software_draw_threads`]) unless the
/// user set [`SOFTWARE_RASTERISER_THREADS`]. Called before the window (and its OpenGL
/// context) exists, while the process has no other thread that reads the environment.
pub fn limit_software_rasteriser() {
    if std::env::var_os(SOFTWARE_RASTERISER_THREADS).is_none() {
        std::env::set_var(
            SOFTWARE_RASTERISER_THREADS,
            software_draw_threads(cores()).to_string(),
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_software_renderer_leaves_the_solver_all_but_its_share() {
        assert_eq!(software_draw_threads(1), 1);
        assert_eq!(software_draw_threads(2), 1);
        assert_eq!(software_draw_threads(8), 2);
        if std::env::var_os("RAYON_NUM_THREADS").is_none() {
            assert_eq!(solver_threads(1, true), Some(1));
            assert_eq!(solver_threads(2, true), Some(1));
            assert_eq!(solver_threads(8, true), Some(6));
            assert_eq!(solver_threads(2, false), Some(2));
        }
    }

    #[test]
    fn software_renderers_are_recognised() {
        assert!(is_software_renderer("llvmpipe (LLVM 15.0.6, 256 bits)"));
        assert!(is_software_renderer("Google SwiftShader"));
        assert!(is_software_renderer("Software Rasterizer"));
        assert!(!is_software_renderer("NVIDIA GeForce RTX 4070/PCIe/SSE2"));
        assert!(!is_software_renderer(
            "Mesa Intel(R) UHD Graphics 620 (KBL GT2)"
        ));
    }
}
