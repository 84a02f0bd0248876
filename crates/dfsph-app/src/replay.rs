//! `dfsph2d run SCENE --replay FILE`: replay a recording (`view --record`, `stress --record`)
//! headless. The run starts from the scene exactly as recorded (its header), applies every
//! action before the step it was recorded at, and, unless `--until` says otherwise, stops when
//! the recording ends and compares the final state with the recording's fingerprint.

use std::path::Path;

use anyhow::Result;
use dfsph::recording::{fingerprint_hex, Entry, Recording};
use dfsph::simd::SimdPath;
use dfsph::{Action, Scene, Simulation};

use crate::run::{self, Driver, RunOutcome, RunPlan};
use dfsph_io::input::{read_input_file, InputRefusal};

/// Recordings larger than this are refused, and no more than this is ever read, whatever the
/// file claims (a long viewer session is a few MB; docs/recording.md).
const MAX_RECORDING_BYTES: u64 = 256 * 1024 * 1024;

/// Read and check the recording at `path` for a run of `scene` (named `scene_arg` on the
/// command line): the recording must have been made on the same scene, up to its name,
/// description and particle budget. Every failure is one line naming the file. A recording
/// whose last line was cut short (a full disk, a killed recorder) loads without that line,
/// with a warning saying where it stops.
pub fn load(
    path: &Path,
    scene_arg: &str,
    scene: &Scene,
) -> Result<(Recording, Option<String>), String> {
    let shown = path.display();
    let bytes = read_input_file(path, MAX_RECORDING_BYTES).map_err(|refusal| match refusal {
        InputRefusal::Missing => format!("recording `{shown}` does not exist"),
        InputRefusal::Directory => format!(
            "`{shown}` is a directory, not a recording (a file from `view --record` or `stress --record`)"
        ),
        InputRefusal::NotRegular => format!(
            "recording `{shown}` is not a regular file (a FIFO, socket or device); a recording is \
             a file from `view --record` or `stress --record`"
        ),
        InputRefusal::TooLarge => format!(
            "recording `{shown}` has more than the {MAX_RECORDING_BYTES} bytes a recording may have"
        ),
        InputRefusal::Io(e) => format!("cannot read recording `{shown}`: {e}"),
    })?;
    let text = match String::from_utf8(bytes) {
        Ok(text) => text,
        // Cut in the middle of a character: the line is cut short, which parsing reports.
        Err(e) if e.utf8_error().error_len().is_none() => {
            let valid = e.utf8_error().valid_up_to();
            let mut bytes = e.into_bytes();
            bytes.truncate(valid);
            String::from_utf8(bytes).expect("valid up to here")
        }
        Err(_) => {
            return Err(format!(
                "recording `{shown}` is not UTF-8 text (expected JSON lines)"
            ))
        }
    };
    let (recording, cut) =
        Recording::parse_cut_short(&text).map_err(|e| format!("recording `{shown}`: {e}"))?;
    let warning = cut.map(|cut| {
        format!(
            "recording `{shown}` is cut short: line {} is incomplete (the disk filled up or the \
             recorder was stopped while writing it); replaying the {} complete lines before it, \
             {} actions up to step {}",
            cut.line,
            cut.line - 1,
            recording.entries.len(),
            recording.steps()
        )
    });
    if let Some(key) = first_difference(&recording.header.scene, scene) {
        return Err(format!(
            "recording `{shown}` was made on a different scene than `{scene_arg}`: `{key}` differs \
             (replay it with the scene it was recorded on, `{}`)",
            recording.header.scene.name
        ));
    }
    Ok((recording, warning))
}

/// The first top-level key in which two scenes differ, ignoring `name`, `description` and
/// `max_particles` (the viewer and `stress` set their own pour budget).
fn first_difference(a: &Scene, b: &Scene) -> Option<String> {
    let (Ok(serde_json::Value::Object(a)), Ok(serde_json::Value::Object(b))) =
        (serde_json::to_value(a), serde_json::to_value(b))
    else {
        return Some("(unserialisable)".into());
    };
    a.iter()
        .filter(|(k, _)| !matches!(k.as_str(), "name" | "description" | "max_particles"))
        .find(|(k, v)| b.get(*k) != Some(*v))
        .map(|(k, _)| k.clone())
}

/// Applies a recording's actions between the steps of a run.
pub struct ReplayDriver {
    entries: Vec<Entry>,
    next: usize,
    /// Steps taken, resets included (the recording's clock).
    done: u64,
    /// Steps in the recording.
    end: u64,
    /// `--until` was given: run by simulated time instead of to the recording's end.
    by_time: bool,
    applied: usize,
    /// The last `before_step` applied an action.
    acted: bool,
    rejected: usize,
    resets: usize,
    /// Fingerprint of the final state, when the run reached the recording's end.
    final_fingerprint: Option<String>,
}

impl ReplayDriver {
    pub fn new(recording: &Recording, by_time: bool) -> Self {
        Self {
            entries: recording.entries.clone(),
            next: 0,
            done: 0,
            end: recording.steps(),
            by_time,
            applied: 0,
            acted: false,
            rejected: 0,
            resets: 0,
            final_fingerprint: None,
        }
    }

    /// Apply every action due now; true when one of them rebuilt the simulation. Stops
    /// early on Ctrl-C: a recording may hold a million actions at one step.
    fn apply_due(&mut self, sim: &mut Simulation) -> bool {
        let mut reset = false;
        while let Some(e) = self.entries.get(self.next) {
            if e.step > self.done || crate::interrupt::requested() {
                break;
            }
            let outcome = sim.apply(&e.action);
            self.applied += 1;
            if outcome.rejected.is_some() {
                self.rejected += 1;
            } else if matches!(e.action, Action::Reset { .. }) {
                self.resets += 1;
                reset = true;
            }
            self.next += 1;
        }
        reset
    }
}

impl Driver for ReplayDriver {
    fn before_step(&mut self, sim: &mut Simulation) -> Result<bool> {
        let applied = self.applied;
        let reset = self.apply_due(sim);
        self.acted = self.applied > applied;
        self.done += 1;
        Ok(reset)
    }

    fn acted(&self) -> bool {
        self.acted
    }

    fn finished(&self) -> bool {
        !self.by_time && self.done >= self.end
    }

    fn after_last_step(&mut self, sim: &mut Simulation) -> Result<bool> {
        if self.by_time || self.done < self.end {
            return Ok(false);
        }
        let reset = self.apply_due(sim);
        if !crate::interrupt::requested() {
            self.final_fingerprint = Some(fingerprint_hex(sim));
        }
        Ok(reset)
    }

    fn progress(&self) -> Option<f64> {
        (!self.by_time && self.end > 0).then(|| self.done as f64 / self.end as f64)
    }
}

/// How a replay went.
pub struct ReplayReport {
    /// Appended to the run's summary line.
    pub note: String,
    /// The final state differs from the recording's: why, in one line.
    pub diverged: Option<String>,
}

/// Run `plan` replaying `recording` (`by_time`: `--until` was given).
pub fn execute(
    plan: &RunPlan,
    sim: Simulation,
    recording: &Recording,
    by_time: bool,
) -> Result<(RunOutcome, ReplayReport)> {
    let mut driver = ReplayDriver::new(recording, by_time);
    let outcome = run::execute_with(plan, sim, &mut driver)?;
    let mut note = format!(
        "replayed {} of {} actions over {} steps ({} rejected, {} resets)",
        driver.applied,
        recording.entries.len(),
        driver.done,
        driver.rejected,
        driver.resets
    );
    // Bits match only on the same SIMD path: a replay on another one says so.
    let here = SimdPath::in_use();
    let other_path = recording
        .header
        .simd_path()
        .filter(|&recorded| recorded != here);
    if let Some(recorded) = other_path {
        note.push_str(&format!(
            "; recorded on the {recorded} SIMD path, replayed on {here} (set {}={recorded} to \
             replay it bit for bit)",
            dfsph::simd::ENV
        ));
    }
    let mut diverged = None;
    match (&recording.end, &driver.final_fingerprint) {
        _ if by_time => note.push_str("; --until given, final state not compared"),
        (None, _) => note.push_str("; the recording has no end line, final state not compared"),
        (Some(_), None) => note.push_str("; stopped before the recording's end"),
        (Some(end), Some(got)) if *got == end.fingerprint => {
            note.push_str(&format!("; final state matches the recording ({got})"))
        }
        (Some(end), Some(got)) => {
            let threads = rayon::current_num_threads();
            note.push_str(&format!("; final state DIFFERS from the recording ({got})"));
            let why = if let Some(recorded) = other_path {
                format!(
                    " (results are bit-identical only on the same SIMD path: recorded on \
                     {recorded}, replayed on {here}; try {}={recorded})",
                    dfsph::simd::ENV
                )
            } else if recording.header.threads != threads {
                " (results are bit-identical only for the same thread count: try --threads)".into()
            } else {
                String::new()
            };
            diverged = Some(format!(
                "the replay diverged from the recording: final state {got} (t = {:.6} s, {} \
                 fluid particles), recorded {} (t = {:.6} s, {} fluid particles); recorded with \
                 {} threads, replayed with {threads}{why}",
                outcome.time,
                outcome.n_fluid,
                end.fingerprint,
                end.time,
                end.n_fluid,
                recording.header.threads,
            ));
        }
    }
    Ok((outcome, ReplayReport { note, diverged }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use dfsph::recording::{End, Header};
    use dfsph::scene;

    fn coarse() -> Scene {
        let mut s = scene::builtin("hydrostatic").unwrap();
        s.particle_radius = 0.05;
        s
    }

    #[test]
    fn scenes_differing_only_in_name_or_budget_match() {
        let a = coarse();
        let mut b = a.clone();
        b.name = "other".into();
        b.description = "x".into();
        b.max_particles = 7777;
        assert_eq!(first_difference(&a, &b), None);
        b.particle_radius = 0.04;
        assert_eq!(first_difference(&a, &b).as_deref(), Some("particle_radius"));
    }

    #[test]
    fn driver_applies_actions_at_their_steps_and_stops_at_the_end() {
        let scene = coarse();
        let rec = Recording {
            header: Header::new("t", 1, &scene),
            entries: vec![
                Entry {
                    step: 0,
                    action: Action::ShakeTank { direction: 1.0 },
                },
                Entry {
                    step: 2,
                    action: Action::Reset { scene: None },
                },
                Entry {
                    step: 4,
                    action: Action::ShakeTank { direction: -1.0 },
                },
            ],
            end: Some(End {
                end: 4,
                time: 0.0,
                n_fluid: 0,
                fingerprint: String::new(),
            }),
        };
        let mut sim = Simulation::new(&scene).unwrap();
        let mut d = ReplayDriver::new(&rec, false);
        let mut resets = Vec::new();
        while !d.finished() {
            resets.push(d.before_step(&mut sim).unwrap());
            sim.step();
        }
        assert_eq!(resets, [false, false, true, false]);
        assert_eq!(sim.step_count(), 2, "two steps after the reset");
        assert_eq!(sim.shake_direction(), 0.0, "the reset ended the shaking");
        d.after_last_step(&mut sim).unwrap();
        assert_eq!(
            sim.shake_direction(),
            -1.0,
            "the action at the end step applies"
        );
        assert_eq!((d.applied, d.resets), (3, 1));
        assert!(d.final_fingerprint.is_some());
    }
}
