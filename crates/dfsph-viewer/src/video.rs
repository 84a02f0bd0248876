//! Recording a video of the simulation (the Record button, key V): the frames `dfsph2d run
//! --format gif,mp4` writes, drawn by the same CPU rasteriser ([`dfsph_io::render`]) from the
//! simulation's state rather than read from the window, so they look the same as a run's and
//! need no GPU; each stamped with its simulated time and shown for the simulated time until
//! the next, so the video plays at simulated speed whatever the window's frame rate.
//!
//! The window only copies what a frame needs (positions, velocities, walls) when simulated
//! time has moved on by [`FRAME_INTERVAL`]; drawing and encoding happen on a thread of their
//! own, so recording never stalls the window, and a short queue between them bounds the
//! memory a slow encoder could take. The GIF (and the MP4, when ffmpeg is on PATH)
//! is written under a hidden temporary name and, once complete, given a timestamped name in
//! the current directory, `dfsph2d-YYYYMMDD-HHMMSS.gif`, never replacing an existing file.

use std::path::Path;
#[cfg(not(target_arch = "wasm32"))]
use std::path::PathBuf;
#[cfg(not(target_arch = "wasm32"))]
use std::sync::mpsc;
#[cfg(not(target_arch = "wasm32"))]
use std::thread::JoinHandle;

use anyhow::Result;
#[cfg(not(target_arch = "wasm32"))]
use anyhow::{anyhow, Context as _};
use dfsph::{Simulation, Snapshot};
use dfsph_io::render::{FrameField, RenderGeometry, RenderOptions, WaterLook};
use dfsph_io::video::{GifWriter, Mp4Writer};

/// Simulated time between recorded frames, s: 25 frames per simulated second.
pub const FRAME_INTERVAL: f64 = 0.04;
/// Width of the recorded frames, pixels (`run`'s default PNG width).
pub const FRAME_WIDTH: u32 = 800;
#[cfg(not(target_arch = "wasm32"))]
/// Frames waiting to be encoded at most. When the encoder falls behind (a large scene), a
/// frame is skipped rather than queued without bound; the frame before it is then shown
/// longer, so the video keeps simulated speed with fewer frames.
const QUEUE: usize = 8;

#[cfg(not(target_arch = "wasm32"))]
/// What the encoding thread is sent.
enum Message {
    Frame(Box<Frame>),
    /// Recording stopped at this simulated time.
    Stop(f64),
}

/// Whether a frame is due at simulated time `t` after one at `last`: simulated time has moved
/// on by [`FRAME_INTERVAL`], or went back (a reset).
fn frame_due(last: f64, t: f64) -> bool {
    t >= last + FRAME_INTERVAL || t < last
}

/// A copy of what one frame draws: the fluid, and the tank, walls and rigid bodies.
struct Frame {
    snapshot: Snapshot,
    geometry: RenderGeometry<'static>,
}

impl Frame {
    fn of(sim: &Simulation) -> Self {
        Self {
            snapshot: sim.snapshot(),
            geometry: RenderGeometry::of(sim).into_owned(),
        }
    }
}

#[cfg(not(target_arch = "wasm32"))]
/// A recording in progress.
pub struct Recording {
    messages: mpsc::SyncSender<Message>,
    worker: JoinHandle<Result<Vec<PathBuf>>>,
    /// Simulated time of the last frame sent.
    last: f64,
}

#[cfg(not(target_arch = "wasm32"))]
/// The viewer's recorder: idle, recording, or finishing a recording on its thread.
#[derive(Default)]
pub struct VideoRecorder {
    recording: Option<Recording>,
    /// Recordings stopped whose files are still being finished.
    finishing: Vec<JoinHandle<Result<Vec<PathBuf>>>>,
}

#[cfg(not(target_arch = "wasm32"))]
impl VideoRecorder {
    /// True while recording.
    pub fn is_recording(&self) -> bool {
        self.recording.is_some()
    }

    /// Start recording into `dir` (with the simulation's current state as the first frame),
    /// or stop. Returns what to tell the user.
    pub fn toggle(
        &mut self,
        sim: &Simulation,
        dir: &Path,
        field: FrameField,
        look: WaterLook,
    ) -> String {
        if self.recording.is_some() {
            self.stop(sim.time());
            return "recording stopped; finishing the video…".into();
        }
        let mp4 = dfsph_io::video::find_ffmpeg();
        let with_mp4 = mp4.is_some();
        let (messages, inbox) = mpsc::sync_channel(QUEUE);
        let options = RenderOptions {
            width: FRAME_WIDTH,
            field,
            scale_max: dfsph_io::render::field_scale(sim.scene(), field),
            look,
        };
        let dir = dir.to_path_buf();
        let spawned = std::thread::Builder::new()
            .name("dfsph2d-video".into())
            .spawn(move || encode(inbox, &dir, options, mp4));
        match spawned {
            Ok(worker) => {
                let mut recording = Recording {
                    messages,
                    worker,
                    last: sim.time(),
                };
                let _ = recording
                    .messages
                    .send(Message::Frame(Box::new(Frame::of(sim))));
                recording.last = sim.time();
                self.recording = Some(recording);
                if with_mp4 {
                    "recording a GIF and an MP4 (V or Stop to end)".into()
                } else {
                    "recording a GIF (V or Stop to end; MP4 needs ffmpeg)".into()
                }
            }
            Err(e) => format!("cannot start recording: {e}"),
        }
    }

    /// Called every window frame with the simulation at home: sends a frame when simulated
    /// time has moved on by [`FRAME_INTERVAL`] (or went back: a reset).
    pub fn capture(&mut self, sim: &Simulation) {
        let Some(rec) = &mut self.recording else {
            return;
        };
        let t = sim.time();
        if frame_due(rec.last, t) {
            match rec
                .messages
                .try_send(Message::Frame(Box::new(Frame::of(sim))))
            {
                Ok(()) => rec.last = t,
                // Encoding is behind: this frame is skipped, the next window frame tries
                // again; the window never waits.
                Err(mpsc::TrySendError::Full(_)) => {}
                Err(mpsc::TrySendError::Disconnected(_)) => {
                    // The thread ended early (a failed write); `poll` reports why.
                    let rec = self.recording.take().expect("checked above");
                    self.finishing.push(rec.worker);
                }
            }
        }
    }

    fn stop(&mut self, time: f64) {
        if let Some(rec) = self.recording.take() {
            // Waits, at most for one frame's encoding, when the queue is full.
            let _ = rec.messages.send(Message::Stop(time));
            self.finishing.push(rec.worker);
        }
    }

    /// What finished since the last call: "saved dfsph2d-….gif" or the error.
    pub fn poll(&mut self) -> Option<String> {
        let done = self.finishing.iter().position(|w| w.is_finished())?;
        Some(report(self.finishing.remove(done).join()))
    }

    /// Stop recording and wait for every video to be finished (the window is closing).
    /// Returns what happened to each.
    pub fn finish_all(&mut self, time: f64) -> Vec<String> {
        self.stop(time);
        self.finishing.drain(..).map(|w| report(w.join())).collect()
    }
}

#[cfg(not(target_arch = "wasm32"))]
fn report(joined: std::thread::Result<Result<Vec<PathBuf>>>) -> String {
    match joined {
        Ok(Ok(paths)) if paths.is_empty() => "recording ended without frames".into(),
        Ok(Ok(paths)) => {
            let names: Vec<String> = paths.iter().map(|p| p.display().to_string()).collect();
            format!("saved {}", names.join(" and "))
        }
        Ok(Err(e)) => format!("recording failed: {e:#}"),
        Err(panic) => format!("recording failed: {}", crate::panic_message(panic.as_ref())),
    }
}

/// Draws recorded frames and writes each once the next one (or the stop) says how long it is
/// shown: the window's encoding thread and the page's recorder share it.
struct FrameEncoder {
    gif: GifWriter,
    mp4: Option<Mp4Writer>,
    options: RenderOptions,
    decimals: usize,
    /// The frame drawn last, waiting for the next one's time to know how long it is shown.
    pending: Option<(tiny_skia::Pixmap, f64)>,
}

impl FrameEncoder {
    fn new(gif: GifWriter, mp4: Option<Mp4Writer>, options: RenderOptions) -> Self {
        Self {
            gif,
            mp4,
            options,
            decimals: dfsph_io::video::stamp_decimals(FRAME_INTERVAL),
            pending: None,
        }
    }

    /// Draw `frame` with its time stamped; write the one before it.
    fn frame(&mut self, frame: &Frame) -> Result<()> {
        let mut picture = dfsph_io::render_frame(&frame.geometry, &frame.snapshot, &self.options)?;
        let time = frame.snapshot.time;
        dfsph_io::render::stamp_time(&mut picture, time, self.decimals);
        if let Some((previous, t0)) = self.pending.take() {
            // After a reset time starts again: the frame gets the usual interval.
            let shown = if time > t0 { time - t0 } else { FRAME_INTERVAL };
            self.write(&previous, shown)?;
        }
        self.pending = Some((picture, time));
        Ok(())
    }

    /// Stopped at simulated `time`: the last frame is shown until then, and at least one
    /// frame interval (stopping right after it must not make it flash by).
    fn stop(&mut self, time: f64) -> Result<()> {
        match self.pending.take() {
            Some((last, t0)) => self.write(&last, (time - t0).max(FRAME_INTERVAL)),
            None => Ok(()),
        }
    }

    /// Ended without a stop: the last frame is shown for one interval.
    #[cfg(not(target_arch = "wasm32"))]
    fn stop_unannounced(&mut self) -> Result<()> {
        match self.pending.take() {
            Some((last, _)) => self.write(&last, FRAME_INTERVAL),
            None => Ok(()),
        }
    }

    fn write(&mut self, picture: &tiny_skia::Pixmap, shown: f64) -> Result<()> {
        self.gif.push(picture, shown)?;
        if let Some(mp4) = self.mp4.as_mut() {
            mp4.push(picture, shown)?;
        }
        Ok(())
    }
}

#[cfg(not(target_arch = "wasm32"))]
/// The encoding thread: draws each frame, stamps its time and writes it once the next frame
/// (or the stop) says how long it lasts; then names the files.
fn encode(
    inbox: mpsc::Receiver<Message>,
    dir: &Path,
    options: RenderOptions,
    ffmpeg: Option<PathBuf>,
) -> Result<Vec<PathBuf>> {
    // Hidden while written: a name of their own per process and recording start.
    let unique = format!(
        ".dfsph2d-recording-{}-{:?}",
        std::process::id(),
        std::thread::current().id()
    )
    .replace(
        |c: char| !c.is_ascii_alphanumeric() && c != '.' && c != '-',
        "",
    );
    let gif_tmp = dir.join(format!("{unique}.gif"));
    let mp4_tmp = dir.join(format!("{unique}.mp4"));
    let mp4 = ffmpeg.map(|f| Mp4Writer::new(&mp4_tmp, f, FRAME_INTERVAL));
    let gif = GifWriter::new(&gif_tmp).for_field(options.field);
    let mut encoder = FrameEncoder::new(gif, mp4, options);
    for message in inbox {
        match message {
            Message::Frame(frame) => encoder.frame(&frame)?,
            Message::Stop(time) => {
                encoder.stop(time)?;
                break;
            }
        }
    }
    // The window went away without a stop (it panicked): keep what was recorded.
    encoder.stop_unannounced()?;
    let FrameEncoder { gif, mp4, .. } = encoder;
    let mut saved = Vec::new();
    if gif.frames() > 0 {
        gif.finish()?;
        saved.push(place(&gif_tmp, dir, "gif", None)?);
    }
    if let Some(mp4) = mp4 {
        if mp4.frames() > 0 {
            mp4.finish()?;
            let beside_the_gif = saved.first().map(|g: &PathBuf| g.with_extension("mp4"));
            saved.push(place(&mp4_tmp, dir, "mp4", beside_the_gif)?);
        }
    }
    Ok(saved)
}

#[cfg(not(target_arch = "wasm32"))]
/// Give the finished `file` its name: `first` when given and free (the MP4 takes the GIF's
/// name), else `dfsph2d-YYYYMMDD-HHMMSS.EXT` in `dir` (`-2`, `-3`, … when taken). A hard link
/// fails rather than replace a file that appeared meanwhile.
fn place(file: &Path, dir: &Path, ext: &str, first: Option<PathBuf>) -> Result<PathBuf> {
    let mut candidate = first.unwrap_or_else(|| crate::file_names::timestamped_file(dir, ext));
    for _ in 0..1000 {
        match std::fs::hard_link(file, &candidate) {
            Ok(()) => {
                let _ = std::fs::remove_file(file);
                return Ok(candidate);
            }
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
                candidate = crate::file_names::timestamped_file(dir, ext);
            }
            Err(e) => {
                // No hard links here (some network or FAT file systems): a rename, after
                // checking the name is free, is the best that remains.
                if candidate.exists() {
                    return Err(anyhow!("`{}` exists", candidate.display()));
                }
                return std::fs::rename(file, &candidate)
                    .map(|()| candidate.clone())
                    .with_context(|| {
                        format!("cannot name the video `{}` ({e})", candidate.display())
                    });
            }
        }
    }
    Err(anyhow!("no free name for the video in `{}`", dir.display()))
}

/// The page's recorder: each frame drawn and encoded when it is captured (the page has no
/// thread to spare; a frame costs the page some tens of milliseconds every 0.04 s of
/// simulated time), the GIF kept in memory and downloaded as `dfsph2d-<time>.gif` when the
/// recording stops. No MP4: the browser has no ffmpeg.
#[cfg(target_arch = "wasm32")]
#[derive(Default)]
pub struct VideoRecorder {
    recording: Option<PageRecording>,
    /// What to tell the user at the next [`Self::poll`] (a recording that failed).
    said: Option<String>,
}

/// A recording in progress in the page.
#[cfg(target_arch = "wasm32")]
struct PageRecording {
    encoder: FrameEncoder,
    /// Simulated time of the last frame captured.
    last: f64,
}

#[cfg(target_arch = "wasm32")]
impl VideoRecorder {
    /// True while recording.
    pub fn is_recording(&self) -> bool {
        self.recording.is_some()
    }

    /// Start recording (with the simulation's current state as the first frame), or stop and
    /// download the GIF. Returns what to tell the user. (`_dir`: the page has none.)
    pub fn toggle(
        &mut self,
        sim: &Simulation,
        _dir: &Path,
        field: FrameField,
        look: WaterLook,
    ) -> String {
        if let Some(recording) = self.recording.take() {
            return download(recording, sim.time());
        }
        let options = RenderOptions {
            width: FRAME_WIDTH,
            field,
            scale_max: dfsph_io::render::field_scale(sim.scene(), field),
            look,
        };
        let gif = GifWriter::in_memory().for_field(field);
        let mut encoder = FrameEncoder::new(gif, None, options);
        match encoder.frame(&Frame::of(sim)) {
            Ok(()) => {
                self.recording = Some(PageRecording {
                    encoder,
                    last: sim.time(),
                });
                "recording a GIF (V or Stop to end and download it)".into()
            }
            Err(e) => format!("cannot start recording: {e:#}"),
        }
    }

    /// Called every frame with the simulation at home: draws and encodes a frame when
    /// simulated time has moved on by [`FRAME_INTERVAL`] (or went back: a reset).
    pub fn capture(&mut self, sim: &Simulation) {
        let Some(recording) = &mut self.recording else {
            return;
        };
        let t = sim.time();
        if frame_due(recording.last, t) {
            recording.last = t;
            if let Err(e) = recording.encoder.frame(&Frame::of(sim)) {
                self.recording = None;
                self.said = Some(format!("recording failed: {e:#}"));
            }
        }
    }

    /// A recording that failed since the last call.
    pub fn poll(&mut self) -> Option<String> {
        self.said.take()
    }

    /// Stop recording and download what was recorded (the page is closing).
    pub fn finish_all(&mut self, time: f64) -> Vec<String> {
        self.recording
            .take()
            .map(|recording| download(recording, time))
            .into_iter()
            .collect()
    }
}

/// End `recording` at simulated `time` and hand the GIF to the browser as a download.
#[cfg(target_arch = "wasm32")]
fn download(recording: PageRecording, time: f64) -> String {
    let mut encoder = recording.encoder;
    let gif = encoder.stop(time).and_then(|()| {
        let frames = encoder.gif.frames();
        let FrameEncoder { gif, .. } = encoder;
        gif.finish_in_memory().map(|bytes| (bytes, frames))
    });
    let name = format!("dfsph2d-{}.gif", crate::file_names::utc_stamp_now());
    match gif {
        Ok((bytes, frames)) => match crate::web::download(&name, "image/gif", &bytes) {
            Ok(()) => format!("downloaded {name} ({frames} frames)"),
            Err(e) => format!("the browser refused the download: {e}"),
        },
        Err(e) => format!("recording failed: {e:#}"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sim() -> Simulation {
        let mut scene = dfsph::scene::builtin("dam-break").unwrap();
        scene.particle_radius = 0.05;
        Simulation::new(&scene).unwrap()
    }

    fn gif_delays(path: &Path) -> Vec<u16> {
        let mut d = gif::DecodeOptions::new()
            .read_info(std::fs::File::open(path).unwrap())
            .unwrap();
        let mut delays = Vec::new();
        while let Some(f) = d.read_next_frame().unwrap() {
            delays.push(f.delay);
        }
        delays
    }

    /// A recording follows the viewer's colouring: recorded while colouring by density
    /// error, the GIF's palette holds that scale's blue end, which speed's viridis has not.
    #[test]
    fn a_recording_is_coloured_as_the_viewer_colours_the_water() {
        let blue_end = [59u8, 76, 192];
        let palette_of = |field: FrameField| -> Vec<[u8; 3]> {
            let dir = tempfile::tempdir().unwrap();
            let mut sim = sim();
            let mut rec = VideoRecorder::default();
            rec.toggle(&sim, dir.path(), field, WaterLook::Surface);
            sim.step();
            rec.capture(&sim);
            rec.toggle(&sim, dir.path(), field, WaterLook::Surface);
            for _ in 0..500 {
                if rec.poll().is_some() {
                    break;
                }
                std::thread::sleep(std::time::Duration::from_millis(10));
            }
            let gif = std::fs::read_dir(dir.path())
                .unwrap()
                .map(|e| e.unwrap().path())
                .find(|p| p.extension().is_some_and(|e| e == "gif"))
                .expect("a GIF");
            let d = gif::DecodeOptions::new()
                .read_info(std::fs::File::open(gif).unwrap())
                .unwrap();
            d.global_palette()
                .unwrap()
                .chunks(3)
                .map(|c| [c[0], c[1], c[2]])
                .collect()
        };
        assert!(palette_of(FrameField::DensityError).contains(&blue_end));
        assert!(!palette_of(FrameField::Speed).contains(&blue_end));
    }

    #[test]
    fn a_recording_has_a_frame_per_interval_of_simulated_time_and_a_new_name() {
        let dir = tempfile::tempdir().unwrap();
        let mut sim = sim();
        let mut rec = VideoRecorder::default();
        // Someone's file of the name the recording would take is kept.
        let taken = crate::file_names::timestamped_file(dir.path(), "gif");
        std::fs::write(&taken, "mine").unwrap();
        rec.toggle(&sim, dir.path(), FrameField::Speed, WaterLook::Surface);
        assert!(rec.is_recording());
        while sim.time() < 0.2 {
            sim.step();
            rec.capture(&sim);
        }
        rec.toggle(&sim, dir.path(), FrameField::Speed, WaterLook::Surface);
        assert!(!rec.is_recording());
        let mut said = None;
        for _ in 0..500 {
            said = rec.poll();
            if said.is_some() {
                break;
            }
            std::thread::sleep(std::time::Duration::from_millis(10));
        }
        let said = said.expect("the video is finished");
        assert!(said.starts_with("saved "), "{said}");
        assert_eq!(std::fs::read_to_string(&taken).unwrap(), "mine");
        let mut gifs: Vec<PathBuf> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|e| e == "gif") && *p != taken)
            .collect();
        assert_eq!(gifs.len(), 1, "{gifs:?}");
        let gif = gifs.pop().unwrap();
        assert!(said.contains(&gif.display().to_string()), "{said}");
        // With ffmpeg, the MP4 of the same recording has the same name.
        if dfsph_io::video::find_ffmpeg().is_some() {
            let mp4 = gif.with_extension("mp4");
            assert!(said.contains(&mp4.display().to_string()), "{said}");
        }
        // 0.2 s at a frame per 0.04 s: 5 or 6 frames (steps do not land on the grid),
        // together 0.2 s long.
        let delays = gif_delays(&gif);
        assert!((5..=7).contains(&delays.len()), "{delays:?}");
        let total: u32 = delays.iter().map(|&d| u32::from(d)).sum();
        assert!((19..=26).contains(&total), "{delays:?}");
        // Nothing hidden is left behind.
        let hidden = std::fs::read_dir(dir.path())
            .unwrap()
            .filter(|e| {
                e.as_ref()
                    .unwrap()
                    .file_name()
                    .to_string_lossy()
                    .starts_with('.')
            })
            .count();
        assert_eq!(hidden, 0);
    }

    #[test]
    fn each_frame_is_shown_until_the_next_a_reset_for_an_interval_the_last_until_the_stop() {
        let dir = tempfile::tempdir().unwrap();
        let sim = sim();
        let (tx, rx) = mpsc::sync_channel(QUEUE);
        // 0.08 to 0.16 skipped (a busy encoder), then a reset to 0.1, stopped 0.01 s after
        // the last frame.
        for t in [0.0, 0.04, 0.2, 0.1, 0.14] {
            let mut frame = Frame::of(&sim);
            frame.snapshot.time = t;
            tx.send(Message::Frame(Box::new(frame))).unwrap();
        }
        tx.send(Message::Stop(0.15)).unwrap();
        let options = RenderOptions {
            width: 100,
            field: dfsph_io::render::FrameField::Speed,
            scale_max: None,
            look: WaterLook::Surface,
        };
        let saved = encode(rx, dir.path(), options, None).unwrap();
        assert_eq!(saved.len(), 1, "{saved:?}");
        assert_eq!(gif_delays(&saved[0]), [4, 16, 4, 4, 4]);
    }

    /// Waits for the recording to be finished and returns the GIF's delays.
    fn finished_gif(rec: &mut VideoRecorder, dir: &Path) -> Vec<u16> {
        for _ in 0..2000 {
            if let Some(said) = rec.poll() {
                assert!(said.starts_with("saved "), "{said}");
                let gif = std::fs::read_dir(dir)
                    .unwrap()
                    .map(|e| e.unwrap().path())
                    .find(|p| p.extension().is_some_and(|e| e == "gif"))
                    .unwrap();
                return gif_delays(&gif);
            }
            std::thread::sleep(std::time::Duration::from_millis(10));
        }
        panic!("the recording did not finish");
    }

    #[test]
    fn frames_skipped_by_a_busy_encoder_keep_the_video_on_simulated_time() {
        // Stepping as fast as the machine goes asks for frames faster than they are drawn:
        // whichever are skipped, the frames shown last the simulated time between them.
        let dir = tempfile::tempdir().unwrap();
        let mut sim = sim();
        let mut rec = VideoRecorder::default();
        rec.toggle(&sim, dir.path(), FrameField::Speed, WaterLook::Surface);
        while sim.time() < 1.0 {
            sim.step();
            rec.capture(&sim);
        }
        let end = sim.time();
        rec.toggle(&sim, dir.path(), FrameField::Speed, WaterLook::Surface);
        let delays = finished_gif(&mut rec, dir.path());
        assert!(delays.len() <= 27, "{delays:?}");
        // The recorded time, plus at most one interval for the last frame (the state at the
        // stop, shown at least that long).
        let total: u32 = delays.iter().map(|&d| u32::from(d)).sum();
        let least = (end * 100.0).round() as u32;
        assert!(
            (least..=least + 4).contains(&total),
            "{total} vs {least}: {delays:?}"
        );
    }
}
