//! `dfsph2d validate [--quick] --out DIR`: run the validation cases, compare them with the
//! experiments in `data/validation/` (embedded), and write `DIR/report.md` with one PNG plot
//! per comparison and a table of checks, each with its tolerance and PASS/FAIL.
//!
//! Cases (see [`cases`]): the hydrostatic tank, the dam break against Martin & Moyce (1952)
//! and Koshizuka & Oka (1996), the dam break of Lobovsky et al. (2014) with water-level gauges
//! and far-wall pressure sensors, a resolution study, and DFSPH beside WCSPH.
//!
//! `--quick` uses coarse resolutions and shorter runs (seconds): a smoke test. It checks what a
//! coarse run can honestly show (every run completes without non-finite values or leaks, water
//! at rest stays at rest with its pressure field, DFSPH stays less compressed than WCSPH, the
//! front converges with resolution) and reports the comparisons with experiments and exact
//! solutions without checking them, as those need the full resolution ([`Check::full_run_only`]).
//! The full report takes a few minutes and is committed as `docs/validation/`.

mod case;
mod cases;
mod data;
mod plot;
mod report;

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Result;

use case::CaseReport;
pub use case::Settings;
pub use cases::scenes;
pub use report::write_report;

/// The outcome of `dfsph2d validate`.
pub struct Outcome {
    pub report: PathBuf,
    /// Checks that decide the outcome (in `--quick`, the smoke checks).
    pub checks: usize,
    /// Of those, the failed ones.
    pub failed: usize,
    /// Checks reported but not counted (`--quick`: those that need the full resolution).
    pub reported_only: usize,
    pub wall_s: f64,
}

/// Run every case, write the plots and `out/report.md`. `out` must exist.
pub fn run(out: &Path, settings: Settings) -> Result<Outcome> {
    let started = Instant::now();
    let mut reports = Vec::new();
    type CaseFn = fn(Settings) -> Result<Vec<CaseReport>>;
    let all: [(&str, CaseFn); 3] = [
        ("hydrostatic tank", cases::hydrostatic),
        (
            "dam break (Martin & Moyce, Koshizuka & Oka, resolution, WCSPH)",
            cases::dam_break,
        ),
        ("dam break (Lobovsky et al. 2014)", cases::lobovsky),
    ];
    for (label, case) in all {
        let t0 = Instant::now();
        eprintln!("validate: {label} ...");
        let sections = case(settings)?;
        let mut n = 0;
        let mut failed = 0;
        for r in &sections {
            for p in &r.plots {
                plot::render(p, out)?;
            }
            n += r.checks.iter().filter(|c| c.counts(settings)).count();
            failed += r
                .checks
                .iter()
                .filter(|c| c.counts(settings) && !c.pass)
                .count();
        }
        eprintln!(
            "validate: {label}: {n} checks, {failed} failed ({:.1} s)",
            t0.elapsed().as_secs_f64()
        );
        reports.extend(sections);
    }
    let wall_s = started.elapsed().as_secs_f64();
    let report = out.join("report.md");
    write_report(&report, settings, &reports, wall_s)?;
    let all = || reports.iter().flat_map(|r| &r.checks);
    let checks = all().filter(|c| c.counts(settings)).count();
    let failed = all().filter(|c| c.counts(settings) && !c.pass).count();
    Ok(Outcome {
        report,
        checks,
        failed,
        reported_only: all().count() - checks,
        wall_s,
    })
}
