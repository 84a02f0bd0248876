//! Animations: frames drawn by [`crate::render`] (each stamped with its simulated time by the
//! caller, [`crate::render::stamp_time`]) written as an animated GIF with the pure-Rust `gif`
//! crate, or as an H.264 MP4 by piping raw frames to `ffmpeg`.
//!
//! Both play at simulated speed: each frame is shown for the simulated time it stands for.
//! Frame durations are whole ticks (1/100 s in a GIF, one frame period in an MP4), so the
//! rounding is carried from frame to frame and the total stays on the simulated clock. A GIF
//! frame lasts at least [`GIF_MIN_DELAY_CS`] hundredths of a second: browsers show shorter
//! delays as 1/10 s, so snapshots closer together than 0.02 s play in slow motion, at
//! `interval / 0.02` of real time, rather than at an unpredictable speed.
//!
//! Like every other output, a video is written under `NAME.tmp` and renamed to `NAME` only
//! when complete: a run that fails or is killed leaves no file claiming to be a finished video.

use std::collections::HashMap;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, Command, Stdio};
use std::thread::JoinHandle;

use anyhow::{anyhow, Context, Result};
use tiny_skia::Pixmap;

use crate::atomic::{tmp_path, AtomicFile};
use crate::colormap::{body_ramp, BODY_EDGE};
use crate::render::{field_colour, FrameField};

/// Shortest GIF frame delay, 1/100 s: browsers and most viewers replace 0 and 1 with 10.
pub const GIF_MIN_DELAY_CS: u64 = 2;

/// What to tell a user who asked for an MP4 on a machine without ffmpeg.
pub const FFMPEG_MISSING: &str = "MP4 output needs ffmpeg, which is not on PATH; install it \
     (Debian/Ubuntu: `apt-get install ffmpeg`) or leave mp4 out";

/// Turns frame durations in seconds into whole ticks, carrying the rounding so that the
/// ticks shown so far stay within half a tick of the time covered (unless `min` forces
/// longer frames).
#[derive(Clone, Debug)]
struct Ticks {
    per_second: f64,
    min: u64,
    covered: f64,
    shown: u64,
}

impl Ticks {
    fn new(per_second: f64, min: u64) -> Self {
        Self {
            per_second,
            min,
            covered: 0.0,
            shown: 0,
        }
    }

    /// Ticks for the next frame, which stands for `seconds` of simulated time.
    fn next(&mut self, seconds: f64) -> u64 {
        if seconds.is_finite() && seconds > 0.0 {
            self.covered += seconds;
        }
        let due = (self.covered * self.per_second).round() as u64;
        let ticks = due.saturating_sub(self.shown).max(self.min);
        self.shown += ticks;
        ticks
    }
}

/// The digits after the point that tell apart stamps `interval` seconds apart: 3 (ms) at
/// least, more for shorter intervals.
pub fn stamp_decimals(interval: f64) -> usize {
    if !(interval.is_finite() && interval > 0.0) {
        return 3;
    }
    (-interval.log10()).ceil().clamp(3.0, 9.0) as usize
}

/// Copy `pixmap` into an RGB buffer of `width` × `height` (the video's size, fixed by its
/// first frame): a larger frame is cropped, a smaller one padded with white (the renderer's
/// background). The picture's size follows the walls, which the viewer's user may draw.
fn to_rgb(pixmap: &Pixmap, width: u32, height: u32, out: &mut Vec<u8>) {
    out.clear();
    out.resize(3 * width as usize * height as usize, 255);
    let w = pixmap.width().min(width) as usize;
    let h = pixmap.height().min(height) as usize;
    let src = pixmap.data();
    for y in 0..h {
        let row = &src[4 * y * pixmap.width() as usize..][..4 * w];
        let dst = &mut out[3 * y * width as usize..][..3 * w];
        // The renderer's pixels are opaque, so premultiplied RGBA is plain RGBA.
        for (d, s) in dst.chunks_exact_mut(3).zip(row.chunks_exact(4)) {
            d.copy_from_slice(&s[..3]);
        }
    }
}

/// The GIF's one palette, shared by every frame: 136 steps of the field's colour scale
/// (viridis for speed and pressure, blue–white–red for the density error: the fluid's colours),
/// 64 steps of it lightened as the surface's rim is ([`crate::surface::RIM_LIGHTENING`]), 24 steps of the rigid bodies' fills and their edge colour, and 31 greys (background,
/// walls, text, and their anti-aliased edges). The renderer draws from these colours only,
/// so a fixed palette keeps them stable from frame to frame, where a per-frame quantiser
/// would make the colour of still water flicker. (A body's fill is the nearest of the 24:
/// at most about 3 levels off in each channel.)
fn palette(field: FrameField) -> Vec<[u8; 3]> {
    const FLUID_STEPS: usize = 136;
    const RIM_STEPS: usize = 64;
    const BODY_STEPS: usize = 24;
    let mut colors: Vec<[u8; 3]> = (0..FLUID_STEPS)
        .map(|k| field_colour(field, k as f32 / (FLUID_STEPS - 1) as f32))
        .collect();
    // The surface's light rim (`crate::surface`): the ramp lightened as at the edge.
    let light = crate::surface::RIM_LIGHTENING;
    colors.extend((0..RIM_STEPS).map(|k| {
        let c = field_colour(field, k as f32 / (RIM_STEPS - 1) as f32);
        c.map(|v| (v as f32 + light * (255.0 - v as f32)).round() as u8)
    }));
    colors.extend((0..BODY_STEPS).map(|k| body_ramp(k as f32 / (BODY_STEPS - 1) as f32)));
    colors.push(BODY_EDGE);
    // The renderer's exact greys first (background, walls, text), then an even ramp.
    colors.extend([[255; 3], [150; 3], [40; 3]]);
    let ramp = 256 - colors.len();
    colors.extend((0..ramp).map(|i| [(i * 255 / (ramp - 1)) as u8; 3]));
    colors
}

/// Nearest palette entry of each colour, remembered: a frame has a few thousand distinct
/// colours (flat fills and their edges), so each is searched for once.
struct Quantizer {
    palette: Vec<[u8; 3]>,
    memo: HashMap<[u8; 3], u8>,
}

impl Quantizer {
    /// Colours remembered at most; past it the memo starts again (bounded memory).
    const MEMO_LIMIT: usize = 1 << 20;

    fn new(field: FrameField) -> Self {
        Self {
            palette: palette(field),
            memo: HashMap::new(),
        }
    }

    fn index(&mut self, c: [u8; 3]) -> u8 {
        if let Some(&i) = self.memo.get(&c) {
            return i;
        }
        let d2 = |p: &[u8; 3]| -> i32 {
            (0..3)
                .map(|k| (i32::from(p[k]) - i32::from(c[k])).pow(2))
                .sum()
        };
        let best = (0..self.palette.len())
            .min_by_key(|&i| d2(&self.palette[i]))
            .unwrap_or(0) as u8;
        if self.memo.len() >= Self::MEMO_LIMIT {
            self.memo.clear();
        }
        self.memo.insert(c, best);
        best
    }
}

/// Where a GIF's bytes go: a file, atomically, or memory (a page's download).
enum GifSink {
    File(AtomicFile),
    Memory(Vec<u8>),
}

impl Write for GifSink {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        match self {
            GifSink::File(f) => f.write(buf),
            GifSink::Memory(v) => v.write(buf),
        }
    }

    fn flush(&mut self) -> std::io::Result<()> {
        match self {
            GifSink::File(f) => f.flush(),
            GifSink::Memory(_) => Ok(()),
        }
    }
}

/// An animated GIF written frame by frame to `NAME.tmp`, renamed to `NAME` by
/// [`GifWriter::finish`] (or kept in memory: [`GifWriter::in_memory`]). Dropped unfinished
/// (an error on the way), it removes `NAME.tmp`.
pub struct GifWriter {
    /// `None`: in memory.
    path: Option<PathBuf>,
    encoder: Option<gif::Encoder<GifSink>>,
    size: (u32, u32),
    ticks: Ticks,
    quantizer: Quantizer,
    rgb: Vec<u8>,
    indices: Vec<u8>,
    frames: usize,
}

impl GifWriter {
    /// A GIF at `path`; the file is created with the first frame, whose size is the video's.
    pub fn new(path: impl AsRef<Path>) -> Self {
        Self::to(Some(path.as_ref().to_path_buf()))
    }

    /// A GIF kept in memory, for [`Self::finish_in_memory`] (the browser, which has no files).
    pub fn in_memory() -> Self {
        Self::to(None)
    }

    fn to(path: Option<PathBuf>) -> Self {
        Self {
            path,
            encoder: None,
            size: (0, 0),
            ticks: Ticks::new(100.0, GIF_MIN_DELAY_CS),
            quantizer: Quantizer::new(FrameField::Speed),
            rgb: Vec::new(),
            indices: Vec::new(),
            frames: 0,
        }
    }

    /// The same GIF with its palette made for frames coloured by `field` (the default is
    /// speed); before the first frame.
    pub fn for_field(mut self, field: FrameField) -> Self {
        self.quantizer = Quantizer::new(field);
        self
    }

    /// What errors call the GIF: its file, or "the GIF" in memory.
    fn name(&self) -> String {
        self.path
            .as_ref()
            .map_or("the GIF".into(), |p| format!("`{}`", p.display()))
    }

    /// Frames written so far.
    pub fn frames(&self) -> usize {
        self.frames
    }

    /// Append `frame`, shown for `seconds` (its share of simulated time).
    pub fn push(&mut self, frame: &Pixmap, seconds: f64) -> Result<()> {
        if self.encoder.is_none() {
            let (w, h) = (frame.width(), frame.height());
            let (Ok(gw), Ok(gh)) = (u16::try_from(w), u16::try_from(h)) else {
                return Err(anyhow!("a {w}x{h} frame is too large for a GIF"));
            };
            let sink = match &self.path {
                Some(path) => GifSink::File(AtomicFile::create(path)?),
                None => GifSink::Memory(Vec::new()),
            };
            let flat: Vec<u8> = self.quantizer.palette.iter().flatten().copied().collect();
            let mut encoder = gif::Encoder::new(sink, gw, gh, &flat)
                .with_context(|| format!("cannot write {}", self.name()))?;
            encoder
                .set_repeat(gif::Repeat::Infinite)
                .with_context(|| format!("cannot write {}", self.name()))?;
            self.encoder = Some(encoder);
            self.size = (w, h);
        }
        let (w, h) = self.size;
        to_rgb(frame, w, h, &mut self.rgb);
        self.indices.clear();
        let quantizer = &mut self.quantizer;
        // Most pixels repeat their left neighbour (background, walls, fills): no lookup.
        let mut last = None;
        self.indices.extend(self.rgb.chunks_exact(3).map(|c| {
            let c = [c[0], c[1], c[2]];
            match last {
                Some((l, i)) if l == c => i,
                _ => {
                    let i = quantizer.index(c);
                    last = Some((c, i));
                    i
                }
            }
        }));
        let delay = self.ticks.next(seconds).min(u64::from(u16::MAX)) as u16;
        let frame = gif::Frame {
            width: w as u16,
            height: h as u16,
            delay,
            buffer: std::borrow::Cow::Borrowed(&self.indices),
            ..gif::Frame::default()
        };
        let name = self.name();
        let encoder = self.encoder.as_mut().expect("created above");
        encoder
            .write_frame(&frame)
            .with_context(|| format!("cannot write {name}"))?;
        self.frames += 1;
        Ok(())
    }

    /// The GIF's trailer written, the sink it went to (`None` without frames).
    fn close(mut self) -> Result<Option<GifSink>> {
        let name = self.name();
        let Some(encoder) = self.encoder.take() else {
            return Ok(None);
        };
        let sink = encoder
            .into_inner()
            .with_context(|| format!("cannot write {name}"))?;
        Ok(Some(sink))
    }

    /// Write the GIF's trailer and rename it into place. Without frames, no file is written.
    pub fn finish(self) -> Result<()> {
        match self.close()? {
            Some(GifSink::File(file)) => file.commit(),
            Some(GifSink::Memory(_)) | None => Ok(()),
        }
    }

    /// Write the GIF's trailer and return the GIF (empty without frames).
    pub fn finish_in_memory(self) -> Result<Vec<u8>> {
        match self.close()? {
            Some(GifSink::Memory(bytes)) => Ok(bytes),
            Some(GifSink::File(_)) => Err(anyhow!("this GIF is written to a file")),
            None => Ok(Vec::new()),
        }
    }
}

/// `ffmpeg` on `PATH`, as the run would start it; `None` when there is none.
pub fn find_ffmpeg() -> Option<PathBuf> {
    let path = std::env::var_os("PATH")?;
    std::env::split_paths(&path)
        .map(|dir| dir.join("ffmpeg"))
        .find(|p| is_executable(p))
}

#[cfg(unix)]
fn is_executable(p: &Path) -> bool {
    use std::os::unix::fs::PermissionsExt;
    std::fs::metadata(p).is_ok_and(|m| m.is_file() && m.permissions().mode() & 0o111 != 0)
}

#[cfg(not(unix))]
fn is_executable(p: &Path) -> bool {
    p.is_file() || p.with_extension("exe").is_file()
}

/// ffmpeg's frame rate for frames `interval` seconds apart, as the exact fraction
/// `1000000/µs` that `-framerate` takes.
fn frame_rate(interval: f64) -> String {
    let micros = (interval * 1e6).round().max(1.0) as u64;
    format!("1000000/{micros}")
}

/// An H.264 MP4 (yuv420p, which every player reads) encoded by an `ffmpeg` child process
/// from raw RGB frames on its standard input, at one frame per `interval` of simulated
/// time. ffmpeg writes `NAME.tmp`; [`Mp4Writer::finish`] renames it to `NAME` once ffmpeg has
/// exited cleanly. Dropped unfinished, it stops ffmpeg and removes `NAME.tmp`.
pub struct Mp4Writer {
    path: PathBuf,
    ffmpeg: PathBuf,
    interval: f64,
    running: Option<Running>,
    size: (u32, u32),
    ticks: Ticks,
    rgb: Vec<u8>,
    frames: usize,
}

/// The ffmpeg process and the thread collecting what it says on stderr.
struct Running {
    child: Child,
    stdin: Option<ChildStdin>,
    stderr: Option<JoinHandle<String>>,
}

impl Running {
    /// Close ffmpeg's input, wait for it and return its exit status and its last words.
    fn wait(&mut self) -> (std::io::Result<std::process::ExitStatus>, String) {
        self.stdin = None;
        let status = self.child.wait();
        let said = self
            .stderr
            .take()
            .and_then(|t| t.join().ok())
            .unwrap_or_default();
        (status, said)
    }
}

impl Mp4Writer {
    /// An MP4 at `path` with frames `interval` seconds of simulated time apart, encoded by
    /// the `ffmpeg` at `ffmpeg` ([`find_ffmpeg`]), started with the first frame.
    pub fn new(path: impl AsRef<Path>, ffmpeg: PathBuf, interval: f64) -> Self {
        Self {
            path: path.as_ref().to_path_buf(),
            ffmpeg,
            interval,
            running: None,
            size: (0, 0),
            ticks: Ticks::new(1.0 / interval, 0),
            rgb: Vec::new(),
            frames: 0,
        }
    }

    /// Frames given so far.
    pub fn frames(&self) -> usize {
        self.frames
    }

    fn start(&mut self, width: u32, height: u32) -> Result<()> {
        let tmp = tmp_path(&self.path);
        let mut command = Command::new(&self.ffmpeg);
        // A group of its own: Ctrl-C in a terminal signals the whole foreground group, and an
        // ffmpeg that heard it would quit before the run had written its last frame. The run
        // handles Ctrl-C, then closes ffmpeg's input, which ends the video properly.
        #[cfg(unix)]
        std::os::unix::process::CommandExt::process_group(&mut command, 0);
        let mut child = command
            .args(["-hide_banner", "-loglevel", "error", "-y"])
            .args(["-f", "rawvideo", "-pix_fmt", "rgb24"])
            .args(["-s", &format!("{width}x{height}")])
            .args(["-framerate", &frame_rate(self.interval)])
            .args(["-i", "pipe:0"])
            .args(["-c:v", "libx264", "-pix_fmt", "yuv420p", "-crf", "20"])
            // The index at the front: players start before the whole file is read.
            .args(["-movflags", "+faststart", "-f", "mp4"])
            .arg(&tmp)
            .stdin(Stdio::piped())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .with_context(|| {
                format!(
                    "cannot start ffmpeg (`{}`) for `{}`",
                    self.ffmpeg.display(),
                    self.path.display()
                )
            })?;
        let stdin = child.stdin.take();
        // Read on a thread of its own: a chatty ffmpeg must never block on a full pipe.
        let stderr = child.stderr.take().map(|mut err| {
            std::thread::spawn(move || {
                let mut text = String::new();
                let _ = err.read_to_string(&mut text);
                text
            })
        });
        self.running = Some(Running {
            child,
            stdin,
            stderr,
        });
        Ok(())
    }

    /// Append `frame`, shown for `seconds` of simulated time: repeated as many frame periods
    /// as that covers (once for a frame `interval` long, at least once).
    pub fn push(&mut self, frame: &Pixmap, seconds: f64) -> Result<()> {
        if self.running.is_none() {
            // yuv420p halves the chroma resolution: both sides must be even.
            let (w, h) = (
                frame.width().next_multiple_of(2),
                frame.height().next_multiple_of(2),
            );
            self.start(w, h)?;
            self.size = (w, h);
        }
        let (w, h) = self.size;
        to_rgb(frame, w, h, &mut self.rgb);
        let repeats = self.ticks.next(seconds).max(1);
        let running = self.running.as_mut().expect("started above");
        let mut result = Ok(());
        if let Some(stdin) = running.stdin.as_mut() {
            for _ in 0..repeats {
                result = stdin.write_all(&self.rgb);
                if result.is_err() {
                    break;
                }
            }
        }
        if let Err(e) = result {
            // ffmpeg stopped reading: it failed. Say what it said.
            let (status, said) = running.wait();
            self.running = None;
            let _ = std::fs::remove_file(tmp_path(&self.path));
            return Err(anyhow::Error::new(e).context(ffmpeg_failed(&self.path, status, &said)));
        }
        self.frames += 1;
        Ok(())
    }

    /// Let ffmpeg finish the file and rename it into place. Without frames, no file is
    /// written.
    pub fn finish(mut self) -> Result<()> {
        let Some(mut running) = self.running.take() else {
            return Ok(());
        };
        let tmp = tmp_path(&self.path);
        let (status, said) = running.wait();
        match status {
            Ok(s) if s.success() => {}
            status => {
                let _ = std::fs::remove_file(&tmp);
                return Err(std::io::Error::other(ffmpeg_failed(&self.path, status, &said)).into());
            }
        }
        std::fs::File::open(&tmp)
            .and_then(|f| f.sync_all())
            .and_then(|()| std::fs::rename(&tmp, &self.path))
            .with_context(|| {
                format!(
                    "cannot move ffmpeg's `{}` to `{}`",
                    tmp.display(),
                    self.path.display()
                )
            })
    }
}

impl Drop for Mp4Writer {
    fn drop(&mut self) {
        if let Some(mut running) = self.running.take() {
            // Not finished: an error elsewhere stopped the run. No half-encoded file stays.
            let _ = running.child.kill();
            let _ = running.wait();
            let _ = std::fs::remove_file(tmp_path(&self.path));
        }
    }
}

/// "ffmpeg failed (exit status 1) writing `out/video.mp4`: <its last line>".
fn ffmpeg_failed(
    path: &Path,
    status: std::io::Result<std::process::ExitStatus>,
    said: &str,
) -> String {
    let how = match status {
        Ok(s) => s.to_string(),
        Err(e) => format!("cannot wait for it: {e}"),
    };
    let last = said
        .lines()
        .rev()
        .find(|l| !l.trim().is_empty())
        .map(|l| format!(": {}", l.trim()))
        .unwrap_or_default();
    format!("ffmpeg failed ({how}) writing `{}`{last}", path.display())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_carry_rounding_and_respect_the_minimum() {
        let mut t = Ticks::new(100.0, GIF_MIN_DELAY_CS);
        let d: Vec<u64> = (0..4).map(|_| t.next(0.025)).collect();
        assert_eq!(d.iter().sum::<u64>(), 10);
        assert!(d.iter().all(|&x| x == 2 || x == 3), "{d:?}");
        let mut t = Ticks::new(100.0, GIF_MIN_DELAY_CS);
        assert_eq!((0..3).map(|_| t.next(0.05)).collect::<Vec<_>>(), [5, 5, 5]);
        // Below the minimum: slow motion, every frame kept at 2/100 s.
        let mut t = Ticks::new(100.0, GIF_MIN_DELAY_CS);
        assert_eq!((0..3).map(|_| t.next(0.005)).collect::<Vec<_>>(), [2, 2, 2]);
    }

    #[test]
    fn palette_holds_the_renderers_colours() {
        for field in [FrameField::Speed, FrameField::DensityError] {
            let p = palette(field);
            assert_eq!(p.len(), 256);
            for c in [
                [255; 3],
                [150; 3],
                [40; 3],
                field_colour(field, 0.0),
                field_colour(field, 1.0),
                BODY_EDGE,
            ] {
                assert!(p.contains(&c), "{field:?}: {c:?}");
            }
        }
        // A density-error frame's white (water at ρ0) is in its palette, not in speed's.
        let white = field_colour(FrameField::DensityError, 0.5);
        let mut q = Quantizer::new(FrameField::DensityError);
        let k = q.index(white) as usize;
        let near = q.palette[k];
        assert!((0..3).all(|c| near[c].abs_diff(white[c]) <= 3), "{near:?}");
        let p = palette(FrameField::Speed);
        // Every body's fill is within a few levels of an entry.
        let mut q = Quantizer::new(FrameField::Speed);
        for k in 0..=100 {
            let fill = body_ramp(k as f32 / 100.0);
            let near = p[q.index(fill) as usize];
            assert!(
                (0..3).all(|c| near[c].abs_diff(fill[c]) <= 3),
                "{fill:?} -> {near:?}"
            );
        }
        let mut q = Quantizer::new(FrameField::Speed);
        assert_eq!(p[q.index([255; 3]) as usize], [255; 3]);
        assert_eq!(p[q.index([254, 255, 253]) as usize], [255; 3]);
    }

    #[test]
    fn decimals_follow_the_interval() {
        assert_eq!(stamp_decimals(0.05), 3);
        assert_eq!(stamp_decimals(0.0001), 4);
        assert_eq!(stamp_decimals(f64::NAN), 3);
        assert_eq!(frame_rate(0.05), "1000000/50000");
    }

    #[test]
    fn gif_has_one_frame_per_push_with_the_delays() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("v.gif");
        let mut w = GifWriter::new(&path);
        let mut memory = GifWriter::in_memory();
        assert!(GifWriter::in_memory()
            .finish_in_memory()
            .unwrap()
            .is_empty());
        let mut a = Pixmap::new(40, 30).unwrap();
        a.fill(tiny_skia::Color::WHITE);
        // A different size is cropped/padded to the first frame's.
        let b = Pixmap::new(41, 29).unwrap();
        for frame in [&a, &b] {
            w.push(frame, 0.05).unwrap();
            memory.push(frame, 0.05).unwrap();
        }
        assert!(!path.exists(), "complete only once finished");
        w.finish().unwrap();
        assert!(!tmp_path(&path).exists());
        // The browser's GIF, kept in memory, is the same file.
        assert_eq!(
            memory.finish_in_memory().unwrap(),
            std::fs::read(&path).unwrap()
        );
        let mut opts = gif::DecodeOptions::new();
        opts.set_color_output(gif::ColorOutput::RGBA);
        let mut d = opts.read_info(std::fs::File::open(&path).unwrap()).unwrap();
        let mut delays = Vec::new();
        while let Some(f) = d.read_next_frame().unwrap() {
            assert_eq!((f.width, f.height), (40, 30));
            delays.push(f.delay);
        }
        assert_eq!(delays, [5, 5]);
    }

    #[test]
    fn an_unfinished_gif_leaves_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("v.gif");
        let mut w = GifWriter::new(&path);
        w.push(&Pixmap::new(8, 8).unwrap(), 0.05).unwrap();
        assert!(tmp_path(&path).exists());
        drop(w);
        assert!(!tmp_path(&path).exists());
        assert!(!path.exists());
    }
}
