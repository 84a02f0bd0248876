//! Ctrl-C (SIGINT), SIGTERM and SIGHUP (the terminal closed): the first one asks a running
//! `run` or `stress` to stop after the step in progress, so it can finish its files (the last
//! snapshot, `particles.pvd`, the recording's end line) and exit with code 130; a second one
//! ends the process at once. Either way the statistics, probe readings and frame index of every
//! completed step are already on disk (they are appended line by line), and only a snapshot
//! being written when the second signal came is lost (its `NAME.tmp`, removed by the next run).

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, OnceLock};

/// Set by the handlers. Created by [`install`] before any handler can run (a handler must not
/// allocate), shared with the solver by [`flag`].
static REQUESTED: OnceLock<Arc<AtomicBool>> = OnceLock::new();

fn requested_flag() -> &'static Arc<AtomicBool> {
    REQUESTED.get_or_init(|| Arc::new(AtomicBool::new(false)))
}

/// Exit code of a run stopped by Ctrl-C, SIGTERM or SIGHUP (128 + SIGINT, as shells report
/// Ctrl-C).
pub const EXIT_CODE: u8 = 130;

/// Install the handlers (Unix; elsewhere Ctrl-C keeps its default meaning).
pub fn install() {
    requested_flag();
    #[cfg(unix)]
    {
        extern "C" fn on_signal(_: libc::c_int) {
            // `get` is one atomic load: the flag was created before the handler was installed.
            let Some(requested) = REQUESTED.get() else {
                return;
            };
            if requested.swap(true, Ordering::SeqCst) {
                // Second signal: the user insists. `_exit` is async-signal-safe.
                unsafe { libc::_exit(EXIT_CODE as libc::c_int) };
            }
        }
        let handler = on_signal as extern "C" fn(libc::c_int) as libc::sighandler_t;
        // SAFETY: the handler only touches an atomic and calls `_exit`, both
        // async-signal-safe.
        unsafe {
            libc::signal(libc::SIGINT, handler);
            libc::signal(libc::SIGTERM, handler);
            libc::signal(libc::SIGHUP, handler);
        }
    }
}

/// The flag the handlers set, for the solver to read between iterations
/// (`Simulation::set_stop_flag`): a step whose solve runs to thousands of iterations ends
/// within one after the first Ctrl-C.
pub fn flag() -> Arc<AtomicBool> {
    Arc::clone(requested_flag())
}

/// Has Ctrl-C (or SIGTERM, SIGHUP) been received?
pub fn requested() -> bool {
    requested_flag().load(Ordering::SeqCst)
}
