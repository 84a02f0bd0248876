//! The files a user hands in: a scene (a built-in scene name, or the path of a JSON scene
//! file) and recordings, read with limits, and the checks on output paths. Shared by the
//! command line and the Python package, so both say the same thing about the same file.
//!
//! Every failure is a one-line message that names the file and the problem (for a scene that
//! does not validate, the offending key, from [`dfsph::SceneError`]).

use std::path::Path;

use dfsph::{scene, Scene};

/// Scene files larger than this are refused unread: a scene is a few hundred bytes.
const MAX_SCENE_BYTES: u64 = 16 * 1024 * 1024;

/// The scene named by `arg`. A built-in name wins over a file of the same name (write
/// `./dam-break` for the file).
pub fn load_scene(arg: &str) -> Result<Scene, String> {
    if let Some(scene) = scene::builtin(arg) {
        return Ok(scene);
    }
    let path = Path::new(arg);
    let shown = path.display();
    let bytes = read_input_file(path, MAX_SCENE_BYTES).map_err(|refusal| match refusal {
        InputRefusal::Missing => {
            if looks_like_a_name(arg) {
                format!(
                    "unknown scene `{arg}`: not a built-in scene ({}) and no such file",
                    builtin_names()
                )
            } else {
                format!("scene file `{shown}` does not exist")
            }
        }
        InputRefusal::Directory => format!(
            "`{shown}` is a directory, not a scene file (expected a .json file or one of: {})",
            builtin_names()
        ),
        InputRefusal::NotRegular => format!("`{shown}` is not a regular file"),
        InputRefusal::TooLarge => format!(
            "scene file `{shown}` is too large to be a scene (more than {MAX_SCENE_BYTES} bytes)"
        ),
        InputRefusal::Io(e) => format!("cannot read scene file `{shown}`: {e}"),
    })?;
    let text = String::from_utf8(bytes)
        .map_err(|_| format!("scene file `{shown}` is not UTF-8 text (expected a JSON scene)"))?;
    let text = text.strip_prefix('\u{feff}').unwrap_or(&text);
    let mut scene = Scene::from_json(text)
        .map_err(|e| format!("scene file `{shown}`: {}", one_line(&e.to_string())))?;
    name_after_file(&mut scene, text, path);
    Ok(scene)
}

/// Why [`read_input_file`] did not return a file's bytes.
#[derive(Debug)]
pub enum InputRefusal {
    /// No such file.
    Missing,
    /// A directory.
    Directory,
    /// A FIFO, socket or device (`/dev/zero`, `/dev/stdin`): reading one can block for ever
    /// or never end.
    NotRegular,
    /// More bytes than the limit.
    TooLarge,
    /// Any other I/O error.
    Io(std::io::Error),
}

/// The bytes of the regular file at `path`, at most `limit` of them. The file type is checked
/// before the file is opened, and again on the open file (opened non-blocking, so a FIFO put
/// in its place meanwhile cannot block the open), and at most `limit + 1` bytes are read
/// whatever the file's reported length: a FIFO blocked the scene or recording loader for ever
/// and `/dev/zero` (length 0) was read until memory ran out.
pub fn read_input_file(path: &Path, limit: u64) -> Result<Vec<u8>, InputRefusal> {
    use std::io::Read;
    let kind = |meta: &std::fs::Metadata| {
        if meta.is_dir() {
            Err(InputRefusal::Directory)
        } else if !meta.is_file() {
            Err(InputRefusal::NotRegular)
        } else if meta.len() > limit {
            Err(InputRefusal::TooLarge)
        } else {
            Ok(())
        }
    };
    let meta = std::fs::metadata(path).map_err(|e| match e.kind() {
        std::io::ErrorKind::NotFound => InputRefusal::Missing,
        _ => InputRefusal::Io(e),
    })?;
    kind(&meta)?;
    let mut options = std::fs::OpenOptions::new();
    options.read(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        options.custom_flags(libc::O_NONBLOCK);
    }
    let file = options.open(path).map_err(|e| match e.kind() {
        std::io::ErrorKind::NotFound => InputRefusal::Missing,
        _ => InputRefusal::Io(e),
    })?;
    kind(&file.metadata().map_err(InputRefusal::Io)?)?;
    let mut bytes = Vec::new();
    file.take(limit.saturating_add(1))
        .read_to_end(&mut bytes)
        .map_err(InputRefusal::Io)?;
    if bytes.len() as u64 > limit {
        return Err(InputRefusal::TooLarge);
    }
    Ok(bytes)
}

/// Refuse an output path that exists and is not a regular file (a directory, a FIFO, a
/// device): writing into a FIFO blocks until someone reads it, and into `/dev/null` or
/// `/dev/zero` loses the output while the command reports success. `what` names the file in
/// the message (`--record`).
pub fn check_output_file(path: &Path, what: &str) -> Result<(), String> {
    let shown = path.display();
    match std::fs::metadata(path) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(()),
        Err(e) => Err(format!("cannot use {what} `{shown}`: {e}")),
        Ok(meta) if meta.is_dir() => Err(format!("{what} `{shown}` is a directory, not a file")),
        Ok(meta) if !meta.is_file() => Err(format!(
            "{what} `{shown}` is not a regular file (a FIFO, socket or device); give the path of a file"
        )),
        Ok(_) => Ok(()),
    }
}

/// A scene file that does not set `name` / `description` would inherit the dam break's;
/// name it after the file instead, so outputs and the viewer say what actually ran.
fn name_after_file(scene: &mut Scene, text: &str, path: &Path) {
    let Ok(serde_json::Value::Object(keys)) = serde_json::from_str::<serde_json::Value>(text)
    else {
        return;
    };
    if !keys.contains_key("name") {
        if let Some(stem) = path.file_stem() {
            scene.name = stem.to_string_lossy().into_owned();
        }
    }
    if !keys.contains_key("description") {
        scene.description = format!("scene file {}", path.display());
    }
}

/// `dam-break, hydrostatic, ...`
pub fn builtin_names() -> String {
    scene::BUILTIN_SCENES
        .iter()
        .map(|b| b.name)
        .collect::<Vec<_>>()
        .join(", ")
}

/// A bare word such as `dambreak` (no directory, no extension) was meant as a scene name.
fn looks_like_a_name(arg: &str) -> bool {
    !arg.contains(['/', '\\', '.'])
}

/// Messages are printed on one line.
pub fn one_line(s: &str) -> String {
    s.split_whitespace().collect::<Vec<_>>().join(" ")
}

/// `s` safe to print on a terminal: every control character (`char::is_control`: ESC, BEL,
/// CR, ...) is written as its Rust escape (`\u{1b}`, `\r`), other text as it is. Names and
/// paths come from scene files, recordings and the command line, and printed raw an ANSI
/// sequence in a scene's `name` cleared the terminal or retitled its window. Everything the
/// CLI prints that may hold user text goes through this.
pub fn terminal_safe(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        if c.is_control() {
            out.extend(c.escape_debug());
        } else {
            out.push(c);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(dir: &tempfile::TempDir, name: &str, content: &[u8]) -> String {
        let path = dir.path().join(name);
        std::fs::write(&path, content).unwrap();
        path.to_string_lossy().into_owned()
    }

    #[test]
    fn builtin_names_resolve() {
        for b in scene::BUILTIN_SCENES {
            assert_eq!(load_scene(b.name).unwrap(), b.scene());
        }
    }

    #[test]
    fn a_file_is_read_and_named_after_itself() {
        let dir = tempfile::tempdir().unwrap();
        let path = write(&dir, "coarse.json", br#"{"particle_radius": 0.05}"#);
        let scene = load_scene(&path).unwrap();
        assert_eq!(scene.particle_radius, 0.05);
        assert_eq!(scene.name, "coarse");
        let path = write(
            &dir,
            "named.json",
            "\u{feff}{\"name\": \"mine\"}".as_bytes(),
        );
        assert_eq!(load_scene(&path).unwrap().name, "mine");
    }

    #[test]
    fn errors_name_the_file_and_problem() {
        let dir = tempfile::tempdir().unwrap();
        let cases: Vec<(String, &str)> = vec![
            ("dambreak".into(), "unknown scene `dambreak`"),
            ("no/such.json".into(), "`no/such.json` does not exist"),
            (dir.path().to_string_lossy().into_owned(), "is a directory"),
            (
                write(&dir, "bin.json", &[0xff, 0xfe, 0x00, 0x9f]),
                "not UTF-8",
            ),
            (write(&dir, "empty.json", b""), "empty"),
            (write(&dir, "key.json", br#"{"radius": 1}"#), "radius"),
            (
                write(&dir, "neg.json", br#"{"particle_radius": -1}"#),
                "particle_radius",
            ),
        ];
        for (arg, needle) in cases {
            let msg = load_scene(&arg).unwrap_err();
            assert!(msg.contains(needle), "{arg}: {msg}");
            assert!(!msg.contains('\n'), "{msg}");
        }
    }

    #[test]
    fn no_more_than_the_limit_is_read_whatever_the_length_says() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("ten.txt");
        std::fs::write(&path, b"0123456789").unwrap();
        assert_eq!(read_input_file(&path, 10).unwrap(), b"0123456789");
        assert!(matches!(
            read_input_file(&path, 9),
            Err(InputRefusal::TooLarge)
        ));
        // A regular file whose length is 0 but whose reads go on (procfs): the cap, not the
        // length, stops the reading.
        #[cfg(target_os = "linux")]
        {
            let maps = Path::new("/proc/self/maps");
            assert_eq!(std::fs::metadata(maps).unwrap().len(), 0);
            assert!(matches!(
                read_input_file(maps, 16),
                Err(InputRefusal::TooLarge)
            ));
        }
        assert!(matches!(
            read_input_file(Path::new("/dev/zero"), 16),
            Err(InputRefusal::NotRegular)
        ));
    }

    #[test]
    fn one_line_collapses_whitespace() {
        assert_eq!(one_line("a\n  b\tc "), "a b c");
    }

    #[test]
    fn terminal_safe_escapes_control_characters_only() {
        assert_eq!(
            terminal_safe("\u{1b}]0;pwned\u{7}\u{1b}[2J déjà \"vu\" 水\r\u{9b}"),
            "\\u{1b}]0;pwned\\u{7}\\u{1b}[2J déjà \"vu\" 水\\r\\u{9b}"
        );
    }
}
