//! How finely the step's passes are cut into rayon tasks.
//!
//! A pass that rayon splits between two workers pays for the hand-over: the second worker
//! has to notice the task, steal it, and signal its end. On the 2-core virtual machine of
//! docs/PERFORMANCE.md that costs 5–8 µs per pass, where scaling 5,000 floats in place
//! takes 0.5 µs on one thread. A step runs some fifty passes; about twenty of them do a
//! few operations per particle (scale an array, advect, reorder, take a maximum), and at a
//! few thousand particles splitting them makes each slower than not splitting it.

/// Fewest items a task of a light pass (a few arithmetic operations, or one copy, per
/// item) is given: such a pass over fewer items than this runs on one worker. At about
/// 0.2 ns per item this is some 6 µs of work, about what handing a task to another worker
/// costs.
pub const LIGHT_PASS_MIN_ITEMS: usize = 32 * 1024;
