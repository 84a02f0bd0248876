//! `probes.csv`: the readings of the scene's probes (see `dfsph::probes`), one row per step.
//!
//! ```text
//! time,p_wall,h_1m
//! 0,0,1.0012
//! 0.001,3.2,1.0010
//! ```
//!
//! The first row is the initial state (t = 0). Pressure probes are in Pa, water-level gauges
//! in m above the tank floor. Each row is on disk as soon as it is written (a run stopped at
//! any point keeps its complete rows); absent when the scene has no probes.

use std::path::Path;

use anyhow::Result;
use dfsph::{probes, Simulation};
use dfsph_io::AppendFile;

/// Appends probe readings to `probes.csv`.
pub struct ProbesCsvWriter {
    file: AppendFile,
}

impl ProbesCsvWriter {
    /// `None` when the simulation's scene has no probes; otherwise starts `path` with the
    /// header `time,<probe names>`.
    pub fn create(path: impl AsRef<Path>, sim: &Simulation) -> Result<Option<Self>> {
        let probes = &sim.scene().probes;
        if probes.is_empty() {
            return Ok(None);
        }
        let mut file = AppendFile::create(path)?;
        let mut header = String::from("time");
        for p in probes {
            header.push(',');
            header.push_str(p.name());
        }
        file.append(&header)?;
        Ok(Some(Self { file }))
    }

    /// Append one row: the simulation's time and every probe's reading now.
    pub fn push(&mut self, sim: &Simulation) -> Result<()> {
        let mut row = dfsph_io::numbers::seconds(sim.time()).to_string();
        for v in probes::sample_all(sim) {
            row.push(',');
            row.push_str(&v.to_string());
        }
        self.file.append(&row)
    }

    /// Make the file durable (`fsync`).
    pub fn finish(self) -> Result<()> {
        self.file.finish()
    }
}
