//! The README's "Library" section, built as a user would: a new project whose `Cargo.toml`
//! holds the README's `toml` block (its path pointed at this crate) and whose `src/main.rs`
//! is the README's `rust` block, built and run with `cargo`. The README cannot show an
//! example that does not compile or does not print what it says.
//!
//! Not built for WebAssembly (scripts/test-wasm.sh runs this crate's tests under Node's
//! WASI, which cannot start cargo); every native `cargo test` runs it.
#![cfg(not(target_family = "wasm"))]

use std::path::{Path, PathBuf};
use std::process::Command;

/// The body of the first fenced block of `lang` after `## Library` in the README.
fn library_block(readme: &str, lang: &str) -> String {
    let section = &readme[readme.find("## Library\n").expect("a Library section")..];
    let fence = format!("```{lang}\n");
    let start = section.find(&fence).expect("a fenced block") + fence.len();
    let end = start + section[start..].find("```").expect("a closing fence");
    section[start..end].to_string()
}

#[test]
fn the_readme_embedding_example_builds_and_runs_in_a_new_project() {
    let crate_dir = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let root = crate_dir.join("../..");
    let readme = std::fs::read_to_string(root.join("README.md")).unwrap();
    let manifest = library_block(&readme, "toml");
    let source = library_block(&readme, "rust");
    let placeholder = r#"path = "../dfsph2d/crates/dfsph""#;
    assert!(
        manifest.contains(placeholder),
        "the README's Cargo.toml block names the crate by {placeholder}"
    );
    let path = crate_dir.canonicalize().unwrap();
    let manifest = manifest.replace(placeholder, &format!("path = {:?}", path.to_str().unwrap()));

    let project = std::env::temp_dir().join(format!("dfsph2d-embedding-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&project);
    std::fs::create_dir_all(project.join("src")).unwrap();
    std::fs::write(
        project.join("Cargo.toml"),
        format!(
            "[package]\nname = \"my-sim\"\nversion = \"0.1.0\"\nedition = \"2021\"\n\n{manifest}"
        ),
    )
    .unwrap();
    std::fs::write(project.join("src/main.rs"), &source).unwrap();
    // The workspace's lock file pins the versions this checkout builds with, so the project
    // builds offline from the crates already downloaded.
    std::fs::copy(root.join("Cargo.lock"), project.join("Cargo.lock")).unwrap();
    // Its own target directory, kept between runs: the one of the `cargo test` running this
    // test is locked while it runs.
    let target = std::env::var_os("HOME")
        .map(|home| Path::new(&home).join(".cache/dfsph2d-embed-target"))
        .unwrap_or_else(|| std::env::temp_dir().join("dfsph2d-embed-target"));
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let out = Command::new(cargo)
        .args(["run", "--offline", "--quiet"])
        .current_dir(&project)
        .env("CARGO_TARGET_DIR", &target)
        .env_remove("RUSTFLAGS")
        .output()
        .unwrap();
    let _ = std::fs::remove_dir_all(&project);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "the README's project failed: {}\n{stdout}{}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    // What the README says it prints.
    assert_eq!(stdout.trim(), "5022 particles at t = 0.100 s");
    assert!(readme.contains("prints `5022 particles at t = 0.100 s`"));
}
