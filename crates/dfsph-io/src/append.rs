//! Files that grow one line at a time and survive a hard stop: `stats.csv`, `probes.csv` and
//! the frame index. Each line goes to the file in one write as soon as it is appended (no
//! buffer held in the process), so a run killed by SIGKILL, a timeout or a second Ctrl-C
//! leaves every line it completed. A write that fails half-way (a full disk) is cut back to
//! the last complete line, so the file never ends in a partial row.

use std::fs::File;
use std::io::{self, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};

/// Where an [`AppendFile`] writes: a [`File`], or in tests a writer that fails on purpose.
pub trait Sink: Write {
    /// Cut the content back to `len` bytes and continue writing there.
    fn cut_to(&mut self, len: u64) -> io::Result<()>;
    /// Make what was written durable (`fsync`).
    fn sync(&mut self) -> io::Result<()>;
}

impl Sink for File {
    fn cut_to(&mut self, len: u64) -> io::Result<()> {
        self.set_len(len)?;
        self.seek(SeekFrom::Start(len)).map(|_| ())
    }

    fn sync(&mut self) -> io::Result<()> {
        self.sync_all()
    }
}

/// A file written line by line, each line complete on disk when [`AppendFile::append`]
/// returns.
pub struct AppendFile<W: Sink = File> {
    path: PathBuf,
    out: W,
    /// Bytes of complete lines written.
    len: u64,
}

impl AppendFile<File> {
    /// Create (or truncate) `path`, never through a symbolic link ([`create_file`]).
    pub fn create(path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref().to_path_buf();
        let file =
            create_file(&path).with_context(|| format!("cannot create `{}`", path.display()))?;
        Ok(Self::new(file, path))
    }
}

/// Create (or truncate) the file `path` for writing. A symbolic link at `path` is replaced
/// by the new file, never written through: an output directory is the user's, but a link
/// planted in it as `stats.csv` must not make a run overwrite the file it points to,
/// outside the directory. On Unix the file is opened with `O_NOFOLLOW`, so a link made
/// between the check and the open fails the open instead of being followed.
pub fn create_file(path: &Path) -> std::io::Result<File> {
    if std::fs::symlink_metadata(path).is_ok_and(|m| m.file_type().is_symlink()) {
        std::fs::remove_file(path)?;
    }
    let mut options = std::fs::OpenOptions::new();
    options.write(true).create(true).truncate(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        options.custom_flags(libc::O_NOFOLLOW);
    }
    options.open(path)
}

impl<W: Sink> AppendFile<W> {
    /// Append to `out`, which is empty; `path` names it in errors.
    pub fn new(out: W, path: PathBuf) -> Self {
        Self { path, out, len: 0 }
    }

    /// The file's path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Append `line` and a newline in one write. On failure the file is cut back to the lines
    /// before it, and the error names the file.
    pub fn append(&mut self, line: &str) -> Result<()> {
        let mut bytes = Vec::with_capacity(line.len() + 1);
        bytes.extend_from_slice(line.as_bytes());
        bytes.push(b'\n');
        match self.out.write_all(&bytes).and_then(|()| self.out.flush()) {
            Ok(()) => {
                self.len += bytes.len() as u64;
                Ok(())
            }
            Err(e) => {
                // Best effort: on a full disk, shrinking the file needs no space.
                let _ = self.out.cut_to(self.len);
                Err(e).with_context(|| format!("cannot write `{}`", self.path.display()))
            }
        }
    }

    /// Make the file durable (`fsync`); it is complete after every [`AppendFile::append`]
    /// already.
    pub fn finish(mut self) -> Result<()> {
        self.out
            .sync()
            .with_context(|| format!("cannot write `{}`", self.path.display()))
    }

    /// The writer (tests).
    pub fn into_inner(self) -> W {
        self.out
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// An in-memory disk of `room` bytes: a write past it stores what fits and then fails
    /// like a full disk (`ENOSPC`).
    #[derive(Default)]
    pub struct SmallDisk {
        pub data: Vec<u8>,
        pub room: usize,
    }

    impl Write for SmallDisk {
        fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
            let free = self.room.saturating_sub(self.data.len());
            if free == 0 {
                return Err(io::Error::from_raw_os_error(28));
            }
            let n = buf.len().min(free);
            self.data.extend_from_slice(&buf[..n]);
            Ok(n)
        }

        fn flush(&mut self) -> io::Result<()> {
            Ok(())
        }
    }

    impl Sink for SmallDisk {
        fn cut_to(&mut self, len: u64) -> io::Result<()> {
            self.data.truncate(len as usize);
            Ok(())
        }

        fn sync(&mut self) -> io::Result<()> {
            Ok(())
        }
    }

    #[test]
    fn lines_are_in_the_file_as_soon_as_appended() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.csv");
        let mut f = AppendFile::create(&path).unwrap();
        f.append("h").unwrap();
        f.append("1").unwrap();
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "h\n1\n");
        f.finish().unwrap();
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "h\n1\n");
    }

    #[test]
    fn a_full_disk_keeps_the_complete_lines_only() {
        let disk = SmallDisk {
            room: 10,
            ..Default::default()
        };
        let mut f = AppendFile::new(disk, PathBuf::from("out/a.csv"));
        f.append("abc").unwrap();
        f.append("def").unwrap();
        let msg = format!("{:#}", f.append("ghijkl").unwrap_err());
        assert!(msg.starts_with("cannot write `out/a.csv`: "), "{msg}");
        assert_eq!(f.into_inner().data, b"abc\ndef\n");
    }

    /// A link planted where the file goes is replaced, and the file it pointed to is left
    /// as it was.
    #[cfg(unix)]
    #[test]
    fn a_symbolic_link_at_the_path_is_replaced_not_written_through() {
        let dir = tempfile::tempdir().unwrap();
        let victim = dir.path().join("victim.txt");
        std::fs::write(&victim, "keep me\n").unwrap();
        let path = dir.path().join("stats.csv");
        std::os::unix::fs::symlink(&victim, &path).unwrap();
        let mut f = AppendFile::create(&path).unwrap();
        f.append("a,b").unwrap();
        assert_eq!(std::fs::read_to_string(&victim).unwrap(), "keep me\n");
        assert!(!std::fs::symlink_metadata(&path)
            .unwrap()
            .file_type()
            .is_symlink());
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "a,b\n");
    }
}
