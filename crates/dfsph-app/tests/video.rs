//! `dfsph2d run --format gif,mp4`: one video of the run's snapshots, each frame the PNG
//! renderer's picture stamped with its simulated time and shown for `--every` seconds; MP4
//! through ffmpeg, refused up front without it; a failing ffmpeg stops the run with the
//! other outputs kept and no video claiming to be complete.

use std::path::Path;
use std::process::Output;

mod common;

use common::{coarse_scene, csv_rows, dfsph2d, dfsph2d_with, text};

/// Width of the test videos; the legend band is `max(width / 20, 16)` = 16 pixels high and
/// its right half holds the time stamp.
const WIDTH: u32 = 200;
const BAND: u32 = 16;

/// `dfsph2d run` on the 200-particle scene for `until` s into `out`, with `extra` arguments.
fn run(tmp: &Path, out: &Path, until: &str, extra: &[&str], env: &[(&str, &str)]) -> Output {
    let scene = coarse_scene(tmp);
    let mut args = vec![
        "run",
        scene.to_str().unwrap(),
        "--until",
        until,
        "--png-width",
        "200",
        "--threads",
        "2",
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    dfsph2d_with(&args, env)
}

/// The frames of a GIF, each as (delay in 1/100 s, RGBA pixels, width, height).
fn gif_frames(path: &Path) -> Vec<(u16, Vec<u8>, u16, u16)> {
    let mut opts = gif::DecodeOptions::new();
    opts.set_color_output(gif::ColorOutput::RGBA);
    let file = std::fs::File::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut decoder = opts.read_info(file).expect("a GIF");
    let mut frames = Vec::new();
    while let Some(f) = decoder.read_next_frame().expect("frames decode") {
        frames.push((f.delay, f.buffer.to_vec(), f.width, f.height));
    }
    frames
}

/// The snapshot times listed in `out/particles/index.csv`.
fn index_times(out: &Path) -> Vec<f64> {
    csv_rows(&out.join("particles/index.csv"))[1..]
        .iter()
        .map(|r| r[1].parse().unwrap())
        .collect()
}

#[test]
fn a_gif_has_a_frame_per_snapshot_shown_for_the_interval_and_stamped_with_its_time() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    let o = run(
        tmp.path(),
        &out,
        "0.2",
        &["--every", "0.05", "--format", "csv,png,gif"],
        &[],
    );
    assert!(o.status.success(), "{}", text(&o.stderr));
    assert_eq!(text(&o.stderr), "");
    let times = index_times(&out);
    assert!(times.len() >= 5, "{times:?}");

    let frames = gif_frames(&out.join("video.gif"));
    assert_eq!(frames.len(), times.len(), "one GIF frame per snapshot");
    for (k, (delay, rgba, w, h)) in frames.iter().enumerate() {
        // 0.05 s of simulated time per frame: 5/100 s, real-time speed.
        assert_eq!(*delay, 5, "frame {k}");
        // The PNG renderer's picture: the same size, and the same pixels up to the GIF's
        // palette, outside the stamp (the PNG has none).
        let png = tiny_skia::Pixmap::load_png(out.join(format!("particles/{k:05}.png"))).unwrap();
        assert_eq!((u32::from(*w), u32::from(*h)), (png.width(), png.height()));
        assert_eq!(png.width(), WIDTH);
        let mut diff = 0u64;
        let mut counted = 0u64;
        for y in 0..png.height() {
            for x in 0..png.width() {
                if y < BAND && x >= WIDTH / 2 {
                    continue;
                }
                let p = png.pixel(x, y).unwrap();
                let i = 4 * (y * png.width() + x) as usize;
                for (a, b) in [p.red(), p.green(), p.blue()].iter().zip(&rgba[i..i + 3]) {
                    diff += u64::from(a.abs_diff(*b));
                }
                counted += 3;
            }
        }
        let mean = diff as f64 / counted as f64;
        assert!(mean < 2.0, "frame {k}: mean colour difference {mean}");
    }
    // The stamp: something is written in the band's right half (dark pixels), and it differs
    // from frame to frame as the time does.
    let stamp = |rgba: &Vec<u8>| -> Vec<u8> {
        (0..BAND)
            .flat_map(|y| {
                let start = 4 * (y * WIDTH + WIDTH / 2) as usize;
                rgba[start..start + 4 * (WIDTH / 2) as usize].to_vec()
            })
            .collect()
    };
    for k in 0..frames.len() {
        let s = stamp(&frames[k].1);
        assert!(
            s.chunks(4).any(|c| c[0] < 100),
            "frame {k} has no time stamp"
        );
        if k > 0 {
            let same = s == stamp(&frames[k - 1].1);
            assert!(!same, "frames {} and {k} have the same time stamp", k - 1);
        }
    }
    let manifest = std::fs::read_to_string(out.join(".dfsph2d-manifest")).unwrap();
    assert!(manifest.lines().any(|l| l == "video.gif"), "{manifest}");
    assert!(!out.join("video.gif.tmp").exists());

    // A rerun without the GIF removes it: it is ours, listed in the manifest.
    let o = run(tmp.path(), &out, "0.05", &[], &[]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    assert!(!out.join("video.gif").exists());
}

#[test]
fn a_gif_alone_lists_frames_without_files_and_snapshots_under_20_ms_play_in_slow_motion() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    let o = run(
        tmp.path(),
        &out,
        "0.04",
        &["--every", "0.01", "--format", "gif"],
        &[],
    );
    assert!(o.status.success(), "{}", text(&o.stderr));
    let stderr = text(&o.stderr);
    assert!(
        stderr.contains("plays at 0.500× real time"),
        "the slow motion is announced: {stderr}"
    );
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(!stderr.contains("  "), "{stderr}");
    let rows = csv_rows(&out.join("particles/index.csv"));
    let frames = gif_frames(&out.join("video.gif"));
    assert_eq!(frames.len(), rows.len() - 1);
    assert!(frames.len() >= 5);
    // Every snapshot kept, each at the shortest delay a GIF plays reliably.
    assert!(
        frames.iter().all(|f| f.0 == 2),
        "{:?}",
        frames.iter().map(|f| f.0).collect::<Vec<_>>()
    );
    // No per-snapshot file: the rows name none.
    assert!(rows[1..].iter().all(|r| r[2].is_empty()), "{rows:?}");
    let mut files: Vec<String> = std::fs::read_dir(out.join("particles"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    files.sort();
    assert_eq!(files, ["index.csv"]);
}

/// `ffprobe`'s count of the video frames in `path`, and their rate.
fn ffprobe(path: &Path) -> (usize, String) {
    let o = std::process::Command::new("ffprobe")
        .args(["-v", "error", "-count_frames", "-select_streams", "v:0"])
        .args([
            "-show_entries",
            "stream=nb_read_frames,r_frame_rate,pix_fmt,codec_name",
        ])
        .args(["-of", "default=noprint_wrappers=1"])
        .arg(path)
        .output()
        .expect("ffprobe runs");
    assert!(o.status.success(), "{}", text(&o.stderr));
    let report = text(&o.stdout);
    let field = |k: &str| {
        report
            .lines()
            .find_map(|l| l.strip_prefix(&format!("{k}=")))
            .unwrap_or_else(|| panic!("no {k} in {report}"))
            .to_string()
    };
    assert_eq!(field("codec_name"), "h264");
    assert_eq!(field("pix_fmt"), "yuv420p");
    (
        field("nb_read_frames").parse().unwrap(),
        field("r_frame_rate"),
    )
}

/// True when ffmpeg is installed; on CI (which installs it, `.ci/run`) it must be.
fn have_ffmpeg() -> bool {
    let found = dfsph_io::video::find_ffmpeg().is_some();
    assert!(
        found || std::env::var_os("CI").is_none(),
        "CI installs ffmpeg (.ci/run); it is missing"
    );
    if !found {
        eprintln!("ffmpeg is not installed: the MP4 encoding test did not run");
    }
    found
}

#[test]
fn an_mp4_has_a_frame_per_snapshot_at_the_snapshot_rate() {
    if !have_ffmpeg() {
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    let o = run(
        tmp.path(),
        &out,
        "0.2",
        &["--every", "0.05", "--format", "gif,mp4"],
        &[],
    );
    assert!(o.status.success(), "{}", text(&o.stderr));
    let snapshots = index_times(&out).len();
    let (frames, rate) = ffprobe(&out.join("video.mp4"));
    assert_eq!(frames, snapshots);
    assert_eq!(rate, "20/1");
    assert_eq!(gif_frames(&out.join("video.gif")).len(), snapshots);
    assert!(!out.join("video.mp4.tmp").exists());
    let manifest = std::fs::read_to_string(out.join(".dfsph2d-manifest")).unwrap();
    assert!(manifest.lines().any(|l| l == "video.mp4"), "{manifest}");
}

#[test]
fn mp4_without_ffmpeg_is_refused_before_anything_is_simulated_or_written() {
    let tmp = tempfile::tempdir().unwrap();
    let empty = tmp.path().join("no-tools");
    std::fs::create_dir(&empty).unwrap();
    let out = tmp.path().join("out");
    let o = run(
        tmp.path(),
        &out,
        "0.1",
        &["--format", "csv,mp4"],
        &[("PATH", empty.to_str().unwrap())],
    );
    assert_eq!(o.status.code(), Some(2), "{}", text(&o.stderr));
    let stderr = text(&o.stderr);
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(stderr.starts_with("error: --format mp4"), "{stderr}");
    assert!(stderr.contains("ffmpeg"), "{stderr}");
    assert!(stderr.contains("apt-get install ffmpeg"), "{stderr}");
    assert_eq!(text(&o.stdout), "", "no run summary");
    assert!(!out.exists(), "nothing written");
}

#[cfg(unix)]
#[test]
fn an_ffmpeg_that_fails_mid_run_is_named_and_the_other_outputs_are_kept() {
    use std::os::unix::fs::PermissionsExt;
    let tmp = tempfile::tempdir().unwrap();
    let bin = tmp.path().join("bin");
    std::fs::create_dir(&bin).unwrap();
    // An "ffmpeg" that reads two and a half frames (200 x 166 RGB, 99,600 bytes each) and
    // gives up: the run has stepped by then.
    let fake = bin.join("ffmpeg");
    std::fs::write(
        &fake,
        "#!/bin/sh\nhead -c 250000 >/dev/null\necho 'fake encoder: out of memory' >&2\nexit 1\n",
    )
    .unwrap();
    std::fs::set_permissions(&fake, std::fs::Permissions::from_mode(0o755)).unwrap();
    let path = format!("{}:/usr/bin:/bin", bin.display());
    let out = tmp.path().join("out");
    let o = run(
        tmp.path(),
        &out,
        "0.2",
        &["--every", "0.05", "--format", "csv,gif,mp4"],
        &[("PATH", &path)],
    );
    let stderr = text(&o.stderr);
    // A failed write: exit code 74, one line naming ffmpeg, what it said, and the file.
    assert_eq!(o.status.code(), Some(74), "{stderr}");
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(stderr.contains("ffmpeg failed"), "{stderr}");
    assert!(stderr.contains("fake encoder: out of memory"), "{stderr}");
    assert!(stderr.contains("video.mp4"), "{stderr}");
    // No video claims to be complete, and no temporary file is left.
    for name in ["video.mp4", "video.mp4.tmp", "video.gif", "video.gif.tmp"] {
        assert!(!out.join(name).exists(), "{name} left behind");
    }
    // What was completed is kept: the statistics of every step taken, and the frames listed.
    let stats = csv_rows(&out.join("stats.csv"));
    assert!(stats.len() > 1, "stats.csv has its rows");
    let index = csv_rows(&out.join("particles/index.csv"));
    assert!(
        index.len() > 2,
        "frames before the failure are listed: {index:?}"
    );
    for row in &index[1..] {
        assert!(out.join("particles").join(&row[2]).exists(), "{row:?}");
    }
}

#[test]
fn run_help_names_the_video_formats() {
    let o = dfsph2d(&["run", "--help"]);
    let help = text(&o.stdout);
    assert!(help.contains("gif") && help.contains("mp4"), "{help}");
    assert!(help.contains("ffmpeg"), "{help}");
}

/// Ctrl-C in a terminal signals the whole foreground process group, ffmpeg included: the run
/// must still stop after its step with both videos complete (ffmpeg runs in a group of its
/// own, so only the run hears it and closes the video properly).
#[cfg(unix)]
#[test]
fn ctrl_c_to_the_process_group_completes_the_videos() {
    use std::os::unix::process::CommandExt;
    use std::process::{Command, Stdio};
    use std::time::{Duration, Instant};
    if !have_ffmpeg() {
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let scene = coarse_scene(tmp.path());
    let out = tmp.path().join("out");
    let mut child = Command::new(common::BIN)
        .args(["run", scene.to_str().unwrap(), "--until", "1000"])
        .args(["--every", "0.02", "--png-width", "200", "--threads", "2"])
        .args(["--format", "csv,gif,mp4", "--out"])
        .arg(&out)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .process_group(0)
        .spawn()
        .unwrap();
    let deadline = Instant::now() + Duration::from_secs(60);
    while !out.join("particles/00010.csv").exists() {
        assert!(Instant::now() < deadline, "no frames appeared");
        assert!(child.try_wait().unwrap().is_none(), "the run ended early");
        std::thread::sleep(Duration::from_millis(20));
    }
    // `kill -INT -PGID`: the whole group, as the terminal does.
    let status = Command::new("kill")
        .args(["-INT", "--", &format!("-{}", child.id())])
        .status()
        .unwrap();
    assert!(status.success());
    let o = child.wait_with_output().unwrap();
    let stderr = text(&o.stderr);
    assert_eq!(o.status.code(), Some(130), "{stderr}");
    assert!(
        stderr.starts_with("error: interrupted at step "),
        "{stderr}"
    );
    let snapshots = index_times(&out).len();
    assert!(snapshots > 10);
    assert_eq!(gif_frames(&out.join("video.gif")).len(), snapshots);
    assert_eq!(ffprobe(&out.join("video.mp4")).0, snapshots);
}
