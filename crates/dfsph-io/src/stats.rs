//! The per-step statistics CSV (`stats.csv`).

use std::fs::File;
use std::path::Path;

use anyhow::Result;
use dfsph::StepStats;

use crate::append::{AppendFile, Sink};
use crate::numbers::{seconds, single};

/// Header of `stats.csv`. The first ten columns are the stable contract (DESIGN.md); the
/// rest follow in this order.
pub const STATS_HEADER: &str = "step,time,dt,n_fluid,density_iterations,divergence_iterations,\
avg_density_error_pct,max_density_error_pct,max_speed,kinetic_energy,divergence_error_pct,\
clamped,non_finite,avg_neighbors,n_boundary,retries";

/// Appends [`StepStats`] rows to `stats.csv`, each row on disk as soon as it is pushed (see
/// [`crate::append`]): a run stopped at any point (SIGKILL, a full disk) leaves the header and
/// one complete row per completed step, and a long run does not hold its statistics in memory.
pub struct StatsCsvWriter<W: Sink = File> {
    file: AppendFile<W>,
    rows: u64,
}

impl StatsCsvWriter<File> {
    /// Create (or truncate) `path` and write the header.
    pub fn create(path: impl AsRef<Path>) -> Result<Self> {
        Self::new(AppendFile::create(path)?)
    }
}

impl<W: Sink> StatsCsvWriter<W> {
    /// Start `file` (empty) with the header.
    pub fn new(mut file: AppendFile<W>) -> Result<Self> {
        file.append(STATS_HEADER)?;
        Ok(Self { file, rows: 0 })
    }

    /// Append one row.
    pub fn push(&mut self, s: &StepStats) -> Result<()> {
        self.file.append(&format!(
            "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
            s.step,
            seconds(s.time),
            seconds(s.dt),
            s.n_fluid,
            s.density_iterations,
            s.divergence_iterations,
            single(s.avg_density_error_pct),
            single(s.max_density_error_pct),
            single(s.max_speed),
            single(s.kinetic_energy),
            single(s.divergence_error_pct),
            s.clamped,
            s.non_finite,
            single(s.avg_neighbors),
            s.n_boundary,
            s.retries,
        ))?;
        self.rows += 1;
        Ok(())
    }

    /// Rows written so far.
    pub fn rows(&self) -> u64 {
        self.rows
    }

    /// Make the file durable (`fsync`).
    pub fn finish(self) -> Result<()> {
        self.file.finish()
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

    fn row(step: u64) -> StepStats {
        StepStats {
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
        }
    }

    #[test]
    fn rows_follow_the_header_and_are_on_disk_when_pushed() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("stats.csv");
        let mut w = StatsCsvWriter::create(&path).unwrap();
        for step in 1..=3u64 {
            w.push(&row(step)).unwrap();
            // Without finish (a run killed now), the rows pushed so far are in the file.
            let text = std::fs::read_to_string(&path).unwrap();
            assert_eq!(text.lines().count(), 1 + step as usize);
        }
        assert_eq!(w.rows(), 3);
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

    /// A full disk in the middle of a row: the error names the file and the file keeps the
    /// header and every complete row, nothing of the cut one.
    #[test]
    fn a_write_error_keeps_the_completed_rows() {
        let header_and_two_rows = STATS_HEADER.len() + 1 + 59 + 58;
        let disk = crate::append::tests::SmallDisk {
            room: header_and_two_rows + 20,
            ..Default::default()
        };
        let mut w = StatsCsvWriter::new(AppendFile::new(disk, "out/stats.csv".into())).unwrap();
        w.push(&row(1)).unwrap();
        w.push(&row(2)).unwrap();
        let msg = format!("{:#}", w.push(&row(3)).unwrap_err());
        assert_eq!(
            msg,
            "cannot write `out/stats.csv`: No space left on device (os error 28)"
        );
        assert_eq!(w.rows(), 2);
        let text = String::from_utf8(w.file.into_inner().data).unwrap();
        assert_eq!(text.len(), header_and_two_rows, "{text}");
        assert!(text.ends_with("\n2,0.01,0.005,200,2,1,0.01,0.5,0.25,1.5,0.05,0,0,12.5,80,1\n"));
    }
}
