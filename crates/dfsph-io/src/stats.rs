//! The per-step statistics CSV (`stats.csv`).

use std::io::Write;
use std::path::Path;

use anyhow::{Context, Result};
use dfsph::StepStats;

use crate::atomic::AtomicFile;

/// Header of `stats.csv`. The first ten columns are the stable contract (DESIGN.md); the
/// rest follow in this order.
pub const STATS_HEADER: &str = "step,time,dt,n_fluid,density_iterations,divergence_iterations,\
avg_density_error_pct,max_density_error_pct,max_speed,kinetic_energy,divergence_error_pct,\
clamped,non_finite,avg_neighbors,n_boundary,retries";

/// Streams [`StepStats`] rows to `NAME.tmp` and renames it to `NAME` on
/// [`StatsCsvWriter::finish`], so a long run does not hold its statistics in memory and a
/// reader never sees a partial `stats.csv`.
pub struct StatsCsvWriter {
    file: AtomicFile,
    rows: u64,
}

impl StatsCsvWriter {
    /// Start `path` with the header.
    pub fn create(path: impl AsRef<Path>) -> Result<Self> {
        let mut file = AtomicFile::create(path)?;
        writeln!(file, "{STATS_HEADER}")
            .with_context(|| format!("cannot write `{}`", file.path().display()))?;
        Ok(Self { file, rows: 0 })
    }

    /// Append one row.
    pub fn push(&mut self, s: &StepStats) -> Result<()> {
        writeln!(
            self.file,
            "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
            s.step,
            s.time,
            s.dt,
            s.n_fluid,
            s.density_iterations,
            s.divergence_iterations,
            s.avg_density_error_pct,
            s.max_density_error_pct,
            s.max_speed,
            s.kinetic_energy,
            s.divergence_error_pct,
            s.clamped,
            s.non_finite,
            s.avg_neighbors,
            s.n_boundary,
            s.retries,
        )
        .with_context(|| format!("cannot write `{}`", self.file.path().display()))?;
        self.rows += 1;
        Ok(())
    }

    /// Rows written so far.
    pub fn rows(&self) -> u64 {
        self.rows
    }

    /// Flush and move the file into place.
    pub fn finish(self) -> Result<()> {
        self.file.commit()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn header_starts_with_the_contract_columns() {
        assert!(STATS_HEADER.starts_with(
            "step,time,dt,n_fluid,density_iterations,divergence_iterations,\
             avg_density_error_pct,max_density_error_pct,max_speed,kinetic_energy,"
        ));
        assert!(STATS_HEADER.ends_with(
            ",divergence_error_pct,clamped,non_finite,avg_neighbors,n_boundary,retries"
        ));
    }

    #[test]
    fn rows_follow_the_header_and_appear_only_on_finish() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("stats.csv");
        let mut w = StatsCsvWriter::create(&path).unwrap();
        for step in 1..=3u64 {
            w.push(&StepStats {
                step,
                time: step as f64 * 0.005,
                dt: 0.005,
                n_fluid: 200,
                n_boundary: 80,
                density_iterations: 2,
                divergence_iterations: 1,
                avg_density_error_pct: 0.01,
                max_density_error_pct: 0.5,
                divergence_error_pct: 0.05,
                max_speed: 0.25,
                kinetic_energy: 1.5,
                clamped: 0,
                non_finite: 0,
                avg_neighbors: 12.5,
                retries: 1,
            })
            .unwrap();
        }
        assert_eq!(w.rows(), 3);
        assert!(!path.exists(), "stats.csv must appear only when complete");
        w.finish().unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len(), 4);
        assert_eq!(lines[0], STATS_HEADER);
        assert_eq!(
            lines[1],
            "1,0.005,0.005,200,2,1,0.01,0.5,0.25,1.5,0.05,0,0,12.5,80,1"
        );
        let columns = STATS_HEADER.split(',').count();
        assert!(lines.iter().all(|l| l.split(',').count() == columns));
    }
}
