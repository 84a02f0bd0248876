//! Undo (Ctrl+Z, the panel's Undo): the walls drawn and the water poured, newest last, each
//! taken away by an action the solver records and replays like any other
//! ([`Action::RemoveDrawnWall`], [`Action::RemoveParticles`]).
//!
//! A pour is one stroke: the emits of consecutive frames, from the frame the pour began to
//! the first frame without one. Its particles are taken away wherever they have flowed
//! since; those already erased are simply gone. A wall is taken away as much of it as is
//! left. The water a wall displaced does not come back, and nothing else is undone (shaking,
//! pushing and the time passed are the simulation's own course).

use dfsph::actions::ActionOutcome;
use dfsph::{Action, Simulation};

/// The most strokes remembered: older ones can no longer be undone.
pub const MAX_STROKES: usize = 64;

/// One thing the user added that undo can take away.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stroke {
    /// The `index`-th wall drawn ([`dfsph::world::World::drawn_wall_count`]).
    Wall { index: usize },
    /// The particles poured with ids `from..to`.
    Pour { from: u32, to: u32 },
}

impl Stroke {
    /// What undo does, for the panel's button and the status line.
    pub fn label(self) -> &'static str {
        match self {
            Stroke::Wall { .. } => "the last wall",
            Stroke::Pour { .. } => "the last pour",
        }
    }

    /// The action that takes it away.
    pub fn undo_action(self) -> Action {
        match self {
            Stroke::Wall { index } => Action::RemoveDrawnWall { index },
            Stroke::Pour { from, to } => Action::RemoveParticles { from, to },
        }
    }
}

/// The strokes that can be undone, and the pour under way.
#[derive(Clone, Debug, Default)]
pub struct UndoHistory {
    strokes: Vec<Stroke>,
    /// The first id of the pour under way.
    pouring: Option<u32>,
    /// An emit was applied this frame (the pour goes on).
    poured_this_frame: bool,
}

impl UndoHistory {
    /// Note `action`, about to be applied to `sim`.
    pub fn before(&mut self, sim: &Simulation, action: &Action) {
        if let Action::Emit { .. } = action {
            self.pouring.get_or_insert(sim.next_particle_id());
            self.poured_this_frame = true;
        }
    }

    /// Note `action`, applied to `sim` with `outcome`.
    pub fn after(&mut self, sim: &Simulation, action: &Action, outcome: &ActionOutcome) {
        if let (Action::AddWall { .. }, None) = (action, outcome.rejected) {
            // A pour still under way came first.
            self.close_pour(sim);
            let index = sim.drawn_wall_count().saturating_sub(1);
            self.push(Stroke::Wall { index });
        }
    }

    /// The frame's actions are done: a pour without an emit this frame has ended.
    pub fn end_frame(&mut self, sim: &Simulation) {
        if !self.poured_this_frame {
            self.close_pour(sim);
        }
        self.poured_this_frame = false;
    }

    /// The stroke undo would take away now (a pour under way counts as done).
    pub fn last(&self, sim: &Simulation) -> Option<Stroke> {
        match self.pouring {
            Some(from) if sim.next_particle_id() > from => Some(Stroke::Pour {
                from,
                to: sim.next_particle_id(),
            }),
            _ => self.strokes.last().copied(),
        }
    }

    /// Take the last stroke off the history: the caller applies its
    /// [`Stroke::undo_action`].
    pub fn pop(&mut self, sim: &Simulation) -> Option<Stroke> {
        self.close_pour(sim);
        self.strokes.pop()
    }

    /// Forget everything (another scene, a reset).
    pub fn clear(&mut self) {
        *self = Self::default();
    }

    fn close_pour(&mut self, sim: &Simulation) {
        if let Some(from) = self.pouring.take() {
            let to = sim.next_particle_id();
            if to > from {
                self.push(Stroke::Pour { from, to });
            }
        }
    }

    fn push(&mut self, stroke: Stroke) {
        if self.strokes.len() == MAX_STROKES {
            self.strokes.remove(0);
        }
        self.strokes.push(stroke);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use dfsph::Vec2;

    fn sim() -> Simulation {
        let mut s = dfsph::scene::builtin("dam-break").unwrap();
        s.particle_radius = 0.05;
        Simulation::new(&s).unwrap()
    }

    fn act(h: &mut UndoHistory, sim: &mut Simulation, action: Action) -> ActionOutcome {
        h.before(sim, &action);
        let out = sim.apply(&action);
        h.after(sim, &action, &out);
        out
    }

    fn pour(at: f32) -> Action {
        Action::Emit {
            at: Vec2::new(at, 2.0),
            radius: 0.2,
            velocity: Vec2::ZERO,
        }
    }

    /// Two frames of pouring are one stroke; a wall after it is undone first, then the
    /// whole pour; then nothing is left to undo.
    #[test]
    fn undo_takes_away_the_last_wall_then_the_last_whole_pour() {
        let (mut h, mut sim) = (UndoHistory::default(), sim());
        let n = sim.fluid_count();
        assert_eq!(h.last(&sim), None);
        let mut poured = 0;
        for at in [3.0, 3.5] {
            poured += act(&mut h, &mut sim, pour(at)).added;
            assert!(h.last(&sim).is_some(), "a pour under way can be undone");
            h.end_frame(&sim);
            sim.step();
        }
        assert!(poured > 0);
        h.end_frame(&sim);
        let wall = Action::AddWall {
            polyline: vec![Vec2::new(2.5, 0.5), Vec2::new(3.0, 0.5)],
        };
        let drawn = act(&mut h, &mut sim, wall).boundary_change;
        h.end_frame(&sim);
        assert_eq!(h.last(&sim), Some(Stroke::Wall { index: 0 }));

        let stroke = h.pop(&sim).unwrap();
        assert_eq!(sim.apply(&stroke.undo_action()).boundary_change, -drawn);
        let stroke = h.pop(&sim).unwrap();
        assert_eq!(stroke.label(), "the last pour");
        assert_eq!(sim.apply(&stroke.undo_action()).removed, poured);
        assert_eq!(sim.fluid_count(), n);
        assert_eq!(h.pop(&sim), None);
    }

    /// A refused wall is not a stroke; a pour that added nothing is none either; the
    /// history keeps the newest [`MAX_STROKES`].
    #[test]
    fn only_what_was_added_is_remembered_and_only_so_much() {
        let (mut h, mut sim) = (UndoHistory::default(), sim());
        let refused = Action::AddWall {
            polyline: vec![Vec2::new(2.5, 0.5)],
        };
        assert!(act(&mut h, &mut sim, refused).rejected.is_some());
        h.end_frame(&sim);
        assert_eq!(h.last(&sim), None);
        // Into the water's own sites (the column at the left): nothing added.
        let into_water = Action::Emit {
            at: Vec2::new(0.3, 0.3),
            radius: 0.1,
            velocity: Vec2::ZERO,
        };
        assert_eq!(act(&mut h, &mut sim, into_water).added, 0);
        h.end_frame(&sim);
        h.end_frame(&sim);
        assert_eq!(h.last(&sim), None);
        for k in 0..(MAX_STROKES + 5) {
            let y = 0.3 + 0.02 * (k % 50) as f32;
            let wall = Action::AddWall {
                polyline: vec![Vec2::new(3.5, y), Vec2::new(3.6, y)],
            };
            act(&mut h, &mut sim, wall);
        }
        assert_eq!(h.strokes.len(), MAX_STROKES);
        assert_eq!(
            h.last(&sim),
            Some(Stroke::Wall {
                index: MAX_STROKES + 4
            })
        );
    }
}
