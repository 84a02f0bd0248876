//! Atomic file writes: the data goes to `NAME.tmp` next to the target and is renamed over
//! `NAME` only once it is complete, so a reader (ParaView, a plotting script watching the
//! directory) never sees a truncated file, and a failed write leaves the old file intact.

use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};

/// The temporary path used while writing `path`: the same file name with `.tmp` appended,
/// in the same directory (so the final rename never crosses file systems).
pub fn tmp_path(path: &Path) -> PathBuf {
    let mut name = path
        .file_name()
        .map(|n| n.to_os_string())
        .unwrap_or_default();
    name.push(".tmp");
    path.with_file_name(name)
}

/// A file being written atomically. Write to it like any [`Write`]r, then call
/// [`AtomicFile::commit`]; dropping it without committing removes the temporary file and
/// leaves the target untouched.
pub struct AtomicFile {
    target: PathBuf,
    tmp: PathBuf,
    writer: Option<BufWriter<File>>,
}

impl AtomicFile {
    /// Start writing `path` (creates or truncates `path.tmp`).
    pub fn create(path: impl AsRef<Path>) -> Result<Self> {
        let target = path.as_ref().to_path_buf();
        let tmp = tmp_path(&target);
        let file = crate::append::create_file(&tmp)
            .with_context(|| format!("cannot create `{}`", tmp.display()))?;
        Ok(Self {
            target,
            tmp,
            writer: Some(BufWriter::new(file)),
        })
    }

    /// The final path.
    pub fn path(&self) -> &Path {
        &self.target
    }

    /// Flush everything, make it durable (`fsync`) and rename the temporary file over the
    /// target. On any failure the temporary file is removed and the target left as it was.
    pub fn commit(mut self) -> Result<()> {
        // The writer stays in `self` until the data is on disk: if the flush or the sync
        // fails (a full disk), `Drop` still sees it and removes the temporary file.
        let writer = self.writer.as_mut().expect("writer present until commit");
        writer
            .flush()
            .with_context(|| format!("cannot write `{}`", self.tmp.display()))?;
        writer
            .get_ref()
            .sync_all()
            .with_context(|| format!("cannot write `{}`", self.tmp.display()))?;
        drop(self.writer.take());
        std::fs::rename(&self.tmp, &self.target).map_err(|e| {
            let _ = std::fs::remove_file(&self.tmp);
            anyhow::Error::new(e).context(format!(
                "cannot rename `{}` to `{}`",
                self.tmp.display(),
                self.target.display()
            ))
        })
    }
}

impl Write for AtomicFile {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.writer.as_mut().expect("not committed").write(buf)
    }

    fn flush(&mut self) -> io::Result<()> {
        self.writer.as_mut().expect("not committed").flush()
    }
}

impl Drop for AtomicFile {
    fn drop(&mut self) {
        if self.writer.take().is_some() {
            // Not committed: an error happened on the way. Leave the target as it was.
            let _ = std::fs::remove_file(&self.tmp);
        }
    }
}

/// Write `path` atomically with the content produced by `fill`.
pub fn write_atomic(
    path: impl AsRef<Path>,
    fill: impl FnOnce(&mut dyn Write) -> io::Result<()>,
) -> Result<()> {
    let mut file = AtomicFile::create(path)?;
    fill(&mut file).with_context(|| format!("cannot write `{}`", file.path().display()))?;
    file.commit()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tmp_path_appends_suffix_in_same_dir() {
        assert_eq!(
            tmp_path(Path::new("out/stats.csv")),
            PathBuf::from("out/stats.csv.tmp")
        );
    }

    #[test]
    fn commit_replaces_target_and_removes_tmp() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.txt");
        std::fs::write(&path, "old").unwrap();
        write_atomic(&path, |w| w.write_all(b"new")).unwrap();
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "new");
        assert!(!tmp_path(&path).exists());
    }

    #[test]
    fn failed_write_keeps_old_file_and_no_tmp() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.txt");
        std::fs::write(&path, "old").unwrap();
        let err = write_atomic(&path, |w| {
            w.write_all(b"partial")?;
            Err(io::Error::other("boom"))
        });
        assert!(err.is_err());
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "old");
        assert!(!tmp_path(&path).exists());
    }

    /// A failed final flush (the data fits the buffer, the disk is full when it is written
    /// out): no `.tmp` is left and the target keeps its old content.
    #[cfg(target_os = "linux")]
    #[test]
    fn failed_final_flush_leaves_no_tmp() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.txt");
        std::fs::write(&path, "old").unwrap();
        // The temporary file is /dev/full, where every write fails with ENOSPC. (A link
        // planted at `a.txt.tmp` would be replaced, not followed: `create_file`.)
        let full = std::fs::OpenOptions::new()
            .write(true)
            .open("/dev/full")
            .unwrap();
        let mut file = AtomicFile {
            target: path.clone(),
            tmp: tmp_path(&path),
            writer: Some(BufWriter::new(full)),
        };
        file.write_all(b"new, small enough to stay in the buffer")
            .unwrap();
        let msg = format!("{:#}", file.commit().unwrap_err());
        assert!(msg.contains("a.txt.tmp`: No space left on device"), "{msg}");
        assert!(std::fs::symlink_metadata(tmp_path(&path)).is_err());
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "old");
    }

    #[test]
    fn missing_directory_is_an_error_naming_the_path() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("no/such/dir/a.txt");
        let msg = format!("{:#}", write_atomic(&path, |_| Ok(())).unwrap_err());
        assert!(msg.contains("a.txt.tmp"), "{msg}");
    }
}
