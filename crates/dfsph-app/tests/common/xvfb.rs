//! A virtual X display for the tests that drive the viewer's window (`Xvfb`, `xdotool`;
//! Debian: `xvfb xdotool libgl1-mesa-dri libegl1`), and the processes they start.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicU32, Ordering};
use std::thread::sleep;
use std::time::{Duration, Instant};

/// The tools these tests need that are not installed; a test without them prints a note and
/// passes.
pub fn missing_tools() -> Vec<&'static str> {
    ["Xvfb", "xdotool"]
        .into_iter()
        .filter(|t| !on_path(t))
        .collect()
}

/// Kills a child process when dropped (a viewer that outlived the test).
pub struct KillOnDrop(pub Child, pub &'static str);

impl Drop for KillOnDrop {
    fn drop(&mut self) {
        if let Ok(None) = self.0.try_wait() {
            eprintln!("killing {}", self.1);
            let _ = self.0.kill();
        }
        let _ = self.0.wait();
    }
}

/// Whether an executable is on PATH.
pub fn on_path(name: &str) -> bool {
    std::env::var_os("PATH")
        .map(|p| std::env::split_paths(&p).any(|d| d.join(name).is_file()))
        .unwrap_or(false)
}

/// A display number with no X server or lock file, starting from a pid-dependent number so
/// concurrent test runs do not collide, and ten further on for each display this process
/// started before: tests of one file run in parallel, and two that looked at once would find
/// the same free number.
fn free_display() -> u32 {
    static STARTED: AtomicU32 = AtomicU32::new(0);
    let start = 100 + std::process::id() % 300 + 10 * STARTED.fetch_add(1, Ordering::Relaxed);
    (start..start + 300)
        .find(|n| {
            !Path::new(&format!("/tmp/.X11-unix/X{n}")).exists()
                && !Path::new(&format!("/tmp/.X{n}-lock")).exists()
        })
        .expect("no free X display number")
}

/// A running `Xvfb`, stopped with SIGTERM (so that it removes its socket and lock file) when
/// dropped, and killed if that does not work.
pub struct Xvfb {
    child: Child,
    number: u32,
}

impl Xvfb {
    pub fn start() -> Self {
        let number = free_display();
        let child = Command::new("Xvfb")
            .arg(format!(":{number}"))
            .args(["-screen", "0", "1280x800x24", "-nolisten", "tcp"])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("starting Xvfb");
        let mut xvfb = Xvfb { child, number };
        // A minute: the first server on a fresh machine compiles its keymap, and a CI run
        // once saw 20 s pass under a loaded host.
        let deadline = Instant::now() + Duration::from_secs(60);
        // The socket file appears before the server accepts connections (a viewer started
        // in between fails to connect on a loaded machine): wait until a client gets in.
        while !(xvfb.socket().exists() && xvfb.accepts_clients()) {
            if let Ok(Some(status)) = xvfb.child.try_wait() {
                panic!("Xvfb :{number} exited at start: {status}");
            }
            assert!(Instant::now() < deadline, "Xvfb :{number} did not start");
            sleep(Duration::from_millis(50));
        }
        xvfb
    }

    fn accepts_clients(&self) -> bool {
        Command::new("xdotool")
            .arg("getdisplaygeometry")
            .env("DISPLAY", self.display())
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .status()
            .is_ok_and(|s| s.success())
    }

    pub fn display(&self) -> String {
        format!(":{}", self.number)
    }

    fn socket(&self) -> PathBuf {
        PathBuf::from(format!("/tmp/.X11-unix/X{}", self.number))
    }
}

impl Drop for Xvfb {
    fn drop(&mut self) {
        let _ = Command::new("kill")
            .args(["-TERM", &self.child.id().to_string()])
            .status();
        for _ in 0..50 {
            if let Ok(Some(_)) = self.child.try_wait() {
                return;
            }
            sleep(Duration::from_millis(50));
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
        let _ = std::fs::remove_file(self.socket());
        let _ = std::fs::remove_file(format!("/tmp/.X{}-lock", self.number));
    }
}

pub fn xdotool(display: &str, args: &[&str]) -> String {
    let out = Command::new("xdotool")
        .args(args)
        .env("DISPLAY", display)
        .output()
        .expect("running xdotool");
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// Give the window the keyboard focus (there is no window manager to do it) and check that
/// it has it.
pub fn focus(display: &str, wid: &str) {
    for _ in 0..50 {
        xdotool(display, &["windowfocus", "--sync", wid]);
        if xdotool(display, &["getwindowfocus"]).trim() == wid {
            // Let the viewer see the focus change before the keys come.
            sleep(Duration::from_millis(300));
            return;
        }
        sleep(Duration::from_millis(100));
    }
    panic!("could not focus window {wid}");
}

/// The viewer's window once it is mapped, or how the viewer exited first. (`xdotool search
/// --sync` would wait forever for a viewer that failed to start, so this polls, watching the
/// viewer.)
pub fn find_window(
    display: &str,
    viewer: &mut KillOnDrop,
) -> Result<String, std::process::ExitStatus> {
    let deadline = Instant::now() + Duration::from_secs(60);
    loop {
        let found = xdotool(display, &["search", "--onlyvisible", "--name", "dfsph2d"]);
        if let Some(w) = found.lines().next() {
            return Ok(w.trim().to_string());
        }
        if let Ok(Some(status)) = viewer.0.try_wait() {
            return Err(status);
        }
        assert!(Instant::now() < deadline, "no dfsph2d window appeared");
        sleep(Duration::from_millis(100));
    }
}
