//! How a command fails: an exit code and one `error: ...` line.

/// A failure with its exit code; printed as one `error: ...` line.
pub(crate) struct Failure {
    pub(crate) code: u8,
    pub(crate) message: String,
}

impl Failure {
    /// Bad input (arguments, scene, output path): exit code 2.
    pub(crate) fn input(message: impl Into<String>) -> Self {
        Self {
            code: 2,
            message: message.into(),
        }
    }

    /// A file-system call that failed (an output directory that cannot be created: no
    /// permission, a read-only disk): exit code [`IO_ERROR`].
    pub(crate) fn io(message: impl Into<String>) -> Self {
        Self {
            code: IO_ERROR,
            message: message.into(),
        }
    }

    /// Anything else: exit code [`IO_ERROR`] when a read or write failed (a full disk), 1
    /// otherwise.
    pub(crate) fn runtime(error: anyhow::Error) -> Self {
        let io = error
            .chain()
            .any(|e| e.downcast_ref::<std::io::Error>().is_some());
        Self {
            code: if io { IO_ERROR } else { 1 },
            message: format!("{error:#}"),
        }
    }
}

/// Exit code of a command stopped by an I/O error (a full disk, a file that cannot be
/// written): `EX_IOERR` of sysexits.h.
pub(crate) const IO_ERROR: u8 = 74;

/// Refuse, before anything big is allocated, a scene whose `estimate` is more than this
/// process may use (the memory available, a cgroup's limit, the address-space limit that
/// `ulimit -v` sets, `--max-memory`): one error line, exit code 2, nothing written. Without
/// it a 49-million-particle scene died at 6.3 GB with an allocation failure and a backtrace.
pub(crate) fn check_memory(
    what: &str,
    estimate: &dfsph::memory::MemoryEstimate,
    max_memory: Option<u64>,
) -> Result<(), Failure> {
    dfsph::memory::MemoryLimits::of_this_process(max_memory)
        .check(estimate)
        .map_err(|e| Failure::input(format!("{what}: {e}")))
}
