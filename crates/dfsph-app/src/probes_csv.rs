//! `probes.csv`: the readings of the scene's probes (see `dfsph::probes`), one row per step.
//!
//! ```text
//! time,p_wall,h_1m
//! 0,0,1.0012
//! 0.001,3.2,1.0010
//! ```
//!
//! The first row is the initial state (t = 0). Pressure probes are in Pa, water-level gauges
//! in m above the tank floor. Written atomically when the run ends; absent when the scene has
//! no probes.

use std::io::Write;
use std::path::Path;

use anyhow::{Context, Result};
use dfsph::{probes, Simulation};
use dfsph_io::AtomicFile;

/// Streams probe readings to `probes.csv`.
pub struct ProbesCsvWriter {
    file: AtomicFile,
}

impl ProbesCsvWriter {
    /// `None` when the simulation's scene has no probes; otherwise starts `path` with the
    /// header `time,<probe names>`.
    pub fn create(path: impl AsRef<Path>, sim: &Simulation) -> Result<Option<Self>> {
        let probes = &sim.scene().probes;
        if probes.is_empty() {
            return Ok(None);
        }
        let mut file = AtomicFile::create(path)?;
        let mut header = String::from("time");
        for p in probes {
            header.push(',');
            header.push_str(p.name());
        }
        writeln!(file, "{header}")
            .with_context(|| format!("cannot write `{}`", file.path().display()))?;
        Ok(Some(Self { file }))
    }

    /// Append one row: the simulation's time and every probe's reading now.
    pub fn push(&mut self, sim: &Simulation) -> Result<()> {
        let mut row = sim.time().to_string();
        for v in probes::sample_all(sim) {
            row.push(',');
            row.push_str(&v.to_string());
        }
        writeln!(self.file, "{row}")
            .with_context(|| format!("cannot write `{}`", self.file.path().display()))
    }

    /// Flush and move the file into place.
    pub fn finish(self) -> Result<()> {
        self.file.commit()
    }
}
