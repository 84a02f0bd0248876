//! The Python package's own tests (`python/tests`, pytest), run from the test command.
//!
//! They need a Python with the package built from this tree and its test dependencies
//! installed, named by `DFSPH2D_PYTHON`: `.ci/run` builds the wheel into a virtualenv
//! (`pip install ./python[test]`) and sets it. Without it the test says so and passes, except
//! on CI, which must have it. The errors the package raises are compared with this build's
//! `dfsph2d` binary (`DFSPH2D_CLI`).

use std::path::Path;
use std::process::Command;

#[test]
fn the_python_package_passes_its_tests() {
    let Some(python) = std::env::var_os("DFSPH2D_PYTHON") else {
        assert!(
            std::env::var_os("CI").is_none(),
            "CI builds the Python package into a virtualenv and sets DFSPH2D_PYTHON (.ci/run)"
        );
        eprintln!(
            "DFSPH2D_PYTHON is not set: the Python package's tests did not run \
             (README, \"Python\": pip install './python[test]' into a virtualenv, then \
             DFSPH2D_PYTHON=venv/bin/python cargo test --release --test python)"
        );
        return;
    };
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let out = Command::new(&python)
        .args([
            "-m",
            "pytest",
            "-q",
            "-p",
            "no:cacheprovider",
            "python/tests",
        ])
        .current_dir(&root)
        .env("DFSPH2D_CLI", env!("CARGO_BIN_EXE_dfsph2d"))
        .output()
        .unwrap_or_else(|e| panic!("cannot run DFSPH2D_PYTHON={python:?}: {e}"));
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    eprintln!("{stdout}");
    assert!(out.status.success(), "pytest failed:\n{stdout}\n{stderr}");
    // Every test ran: none skipped (the comparison with the binary needs DFSPH2D_CLI).
    let summary = stdout.lines().last().unwrap_or_default();
    assert!(
        summary.contains(" passed") && !summary.contains("skipped"),
        "{summary}"
    );
}
