//! The web page in a real browser: `scripts/build-web.sh` builds the site, a small server in
//! this process serves it, and headless Chromium, driven over WebDriver (chromedriver), opens
//! it. The page must start, simulate, draw the water, and take the keyboard: holding `d`
//! shakes the tank right, so the water ends up further right than in a run without the key.
//!
//! Needs `chromium` and `chromedriver` (Debian: `apt-get install chromium chromium-driver`);
//! without them the test says so and passes, except under CI (`.ci/run` installs them).
//! WebGL runs in software (SwiftShader), so the page is slow here: the test checks what
//! happened at equal simulated time, never frame rates.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use base64::Engine as _;
use serde_json::{json, Value};

/// Simulated time (s) at which the key goes down in the shaken run.
const KEY_DOWN_AT: f64 = 0.1;
/// Simulated seconds the key stays held, at least.
const HOLD: f64 = 0.35;
/// How much further right (m) the water's mean x must be with the key held than without, at
/// the same simulated time. Holding `d` drives the tank towards 0.4 m right (about 0.25 m in
/// 0.35 s), its left wall pushing the water along; the two runs otherwise take the same steps.
/// (Seen: 0.18 m further right, and 0.000 m apart with no key in either run.)
const MIN_SHIFT: f64 = 0.05;
/// Longest wait for the page to draw its first frame (compiling the module included).
const START_TIMEOUT: Duration = Duration::from_secs(120);
/// Longest wait for the page to reach a simulated time (software rendering on a busy
/// machine has run it at 1.5 % of real time).
const RUN_TIMEOUT: Duration = Duration::from_secs(240);
/// Longest the page's simulated time may stand still before the test gives up on it (a
/// panic in the page stops it for good; a frame, even in software, takes well under this).
const STALL: Duration = Duration::from_secs(20);
/// Wall time the default page has to fit its scene to the machine (it measures over its
/// first 2.5 s, and may fit up to three times).
const FIT_WAIT: Duration = Duration::from_secs(30);
/// The page's background (`index.html`, the viewer's central panel): #12141a.
const BACKGROUND: [u8; 3] = [0x12, 0x14, 0x1a];

/// Path of a program on `PATH`.
fn on_path(name: &str) -> Option<PathBuf> {
    std::env::split_paths(&std::env::var_os("PATH")?)
        .map(|dir| dir.join(name))
        .find(|p| p.is_file())
}

/// Chromium and chromedriver, or `None` (with a message) where they are not installed.
fn browser_tools() -> Option<(PathBuf, PathBuf)> {
    // On PATH, or where Debian's packages put them.
    let tool = |name: &str| {
        on_path(name).or_else(|| {
            let p = Path::new("/usr/bin").join(name);
            p.is_file().then_some(p)
        })
    };
    let found = tool("chromium").zip(tool("chromedriver"));
    assert!(
        found.is_some() || std::env::var_os("CI").is_none(),
        "CI installs chromium and chromedriver (.ci/run); they are missing"
    );
    if found.is_none() {
        eprintln!(
            "chromium or chromedriver is not installed: the browser test did not run \
             (apt-get install chromium chromium-driver)"
        );
    }
    found
}

/// Serve the files of `dir` (no subfolders) on 127.0.0.1, from a thread that lives as long
/// as the test; returns the address's port. `isolated`: with the headers that make the page
/// cross-origin isolated, so that it loads its threaded build (`threads/`).
fn serve(dir: PathBuf, isolated: bool) -> u16 {
    let listener = TcpListener::bind("127.0.0.1:0").expect("bind a local port");
    let port = listener.local_addr().unwrap().port();
    std::thread::spawn(move || {
        for stream in listener.incoming().flatten() {
            let dir = dir.clone();
            std::thread::spawn(move || {
                let _ = answer(stream, &dir, isolated);
            });
        }
    });
    port
}

/// Answer one HTTP request: GET of a file under `dir`, or 404.
fn answer(mut stream: TcpStream, dir: &Path, isolated: bool) -> std::io::Result<()> {
    let mut reader = BufReader::new(stream.try_clone()?);
    let mut request = String::new();
    reader.read_line(&mut request)?;
    // Headers, up to the blank line (a GET has no body).
    let mut line = String::new();
    while reader.read_line(&mut line)? > 2 {
        line.clear();
    }
    let mut words = request.split_whitespace();
    let (method, target) = (words.next().unwrap_or(""), words.next().unwrap_or(""));
    let name = target.split(['?', '#']).next().unwrap_or("");
    let name = match name.trim_start_matches('/') {
        "" => "index.html",
        n => n,
    };
    let kind = match name.rsplit('.').next() {
        Some("html") => Some("text/html; charset=utf-8"),
        Some("js") => Some("text/javascript"),
        Some("wasm") => Some("application/wasm"),
        _ => None,
    };
    let file = kind
        .filter(|_| method == "GET" && !name.contains(".."))
        .and_then(|kind| Some((kind, std::fs::read(dir.join(name)).ok()?)));
    let (status, kind, body) = match file {
        Some((kind, body)) => ("200 OK", kind, body),
        None => ("404 Not Found", "text/plain", b"not found".to_vec()),
    };
    let isolation = if isolated {
        "Cross-Origin-Opener-Policy: same-origin\r\nCross-Origin-Embedder-Policy: require-corp\r\n"
    } else {
        ""
    };
    write!(
        stream,
        "HTTP/1.1 {status}\r\nContent-Type: {kind}\r\nContent-Length: {}\r\n\
         {isolation}Cache-Control: no-store\r\nConnection: close\r\n\r\n",
        body.len()
    )?;
    stream.write_all(&body)?;
    stream.flush()
}

/// A free local port (free when asked: chromedriver takes it straight after).
fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .expect("a free local port")
        .port()
}

/// A W3C WebDriver session on a chromedriver this test started; dropping it ends the
/// session, chromedriver and every browser process of its profile, whatever the test did.
struct Browser {
    agent: ureq::Agent,
    base: String,
    session: Option<String>,
    driver: Child,
    /// The browser's profile folder: unique to this test, it names its processes.
    profile: tempfile::TempDir,
}

impl Browser {
    fn start(chromium: &Path, chromedriver: &Path) -> Browser {
        Self::start_with(chromium, chromedriver, &[])
    }

    /// [`Self::start`] with more command-line switches for Chromium.
    fn start_with(chromium: &Path, chromedriver: &Path, extra: &[&str]) -> Browser {
        let port = free_port();
        let log = std::env::temp_dir().join("dfsph2d-browser-test-chromedriver.log");
        let driver = Command::new(chromedriver)
            .arg(format!("--port={port}"))
            .arg(format!("--log-path={}", log.display()))
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap_or_else(|e| panic!("{}: {e}", chromedriver.display()));
        let mut browser = Browser {
            agent: ureq::AgentBuilder::new()
                .timeout_connect(Duration::from_secs(5))
                .timeout_read(Duration::from_secs(90))
                .build(),
            base: format!("http://127.0.0.1:{port}"),
            session: None,
            driver,
            profile: tempfile::Builder::new()
                .prefix("dfsph2d-chromium-")
                .tempdir()
                .unwrap(),
        };
        let ready = Instant::now();
        while browser
            .call("GET", "/status", None)
            .map(|v| v["ready"] == true)
            != Ok(true)
        {
            assert!(
                ready.elapsed() < Duration::from_secs(20),
                "chromedriver did not come up on port {port} (log: {})",
                log.display()
            );
            std::thread::sleep(Duration::from_millis(100));
        }
        let mut args = vec![
            "--headless=new".to_string(),
            "--no-sandbox".into(),
            "--disable-gpu-sandbox".into(),
            "--disable-quic".into(),
            "--no-first-run".into(),
            "--disable-background-networking".into(),
            "--disable-component-update".into(),
            "--disable-sync".into(),
            "--disable-dev-shm-usage".into(),
            // WebGL 2 without a GPU: ANGLE over SwiftShader.
            "--use-angle=swiftshader".into(),
            "--enable-unsafe-swiftshader".into(),
            "--window-size=1280,800".into(),
            format!("--user-data-dir={}", browser.profile.path().display()),
        ];
        args.extend(extra.iter().map(|a| a.to_string()));
        let caps = json!({"capabilities": {"alwaysMatch": {
            "browserName": "chrome",
            "goog:chromeOptions": {"binary": chromium, "args": args},
            "goog:loggingPrefs": {"browser": "ALL"},
        }}});
        let session = browser
            .call("POST", "/session", Some(caps))
            .unwrap_or_else(|e| panic!("starting Chromium over WebDriver: {e}"));
        browser.session = Some(session["sessionId"].as_str().unwrap().to_string());
        browser
    }

    /// One WebDriver command; its `value`, or the error's message.
    fn call(&self, method: &str, path: &str, body: Option<Value>) -> Result<Value, String> {
        let request = self
            .agent
            .request(method, &format!("{}{path}", self.base))
            .set("Content-Type", "application/json");
        let response = match body {
            Some(body) => request.send_string(&body.to_string()),
            None => request.call(),
        };
        let (ok, response) = match response {
            Ok(r) => (true, r),
            Err(ureq::Error::Status(_, r)) => (false, r),
            Err(e) => return Err(format!("{method} {path}: {e}")),
        };
        let mut text = String::new();
        response
            .into_reader()
            .read_to_string(&mut text)
            .map_err(|e| format!("{method} {path}: {e}"))?;
        let value: Value =
            serde_json::from_str(&text).map_err(|e| format!("{method} {path}: {e}: {text}"))?;
        let value = value["value"].clone();
        if ok {
            Ok(value)
        } else {
            Err(format!("{method} {path}: {value}"))
        }
    }

    /// A command on the session, which must succeed.
    fn session(&self, method: &str, path: &str, body: Option<Value>) -> Value {
        let id = self.session.as_deref().unwrap();
        self.call(method, &format!("/session/{id}{path}"), body)
            .unwrap_or_else(|e| panic!("{e}{}", self.diagnostics()))
    }

    /// Run a script in the page, returning its value.
    fn eval(&self, script: &str) -> Value {
        self.session(
            "POST",
            "/execute/sync",
            Some(json!({"script": script, "args": []})),
        )
    }

    fn open(&self, url: &str) {
        self.session("POST", "/url", Some(json!({ "url": url })));
    }

    /// `window.dfsph2d.state()`, or `None` before the first frame.
    fn state(&self) -> Option<State> {
        let v = self.eval("return window.dfsph2d ? window.dfsph2d.state() : null;");
        (!v.is_null()).then(|| State {
            particles: v["particles"].as_f64().unwrap() as u64,
            time: v["time"].as_f64().unwrap(),
            mean_x: v["mean_x"].as_f64().unwrap(),
            scene: v["scene"].as_str().unwrap_or("").to_string(),
            fitted: v["fitted"].as_str().map(str::to_string),
            realtime: v["realtime"].as_f64().unwrap_or(0.0),
            wall: Instant::now(),
        })
    }

    /// Wait until the page has simulated `time` seconds; its state then.
    fn wait_for_time(&self, time: f64, timeout: Duration, what: &str) -> State {
        let started = Instant::now();
        // The last time the page reported, and since when (a page that panicked keeps
        // reporting its last frame).
        let mut last: Option<(f64, Instant)> = None;
        loop {
            let state = self.state();
            if let Some(s) = state.as_ref().filter(|s| s.time >= time) {
                return s.clone();
            }
            if let Some(s) = &state {
                if last.is_none_or(|(t, _)| t != s.time) {
                    last = Some((s.time, Instant::now()));
                }
            }
            let stalled = last.is_some_and(|(_, since)| since.elapsed() > STALL);
            assert!(
                started.elapsed() < timeout && !stalled,
                "{what}: the page did not reach {time} s of simulated time ({}; state: {}){}",
                if stalled {
                    format!("its simulated time stood still for {STALL:?}")
                } else {
                    format!("waited {timeout:?}")
                },
                self.eval("return window.dfsph2d ? window.dfsph2d.state() : null;"),
                self.diagnostics()
            );
            std::thread::sleep(Duration::from_millis(50));
        }
    }

    /// Hold (`down`) or release the key `key` on the focused element.
    fn key(&self, key: &str, down: bool) {
        let kind = if down { "keyDown" } else { "keyUp" };
        self.session(
            "POST",
            "/actions",
            Some(json!({"actions": [{"type": "key", "id": "keyboard",
                "actions": [{"type": kind, "value": key}]}]})),
        );
    }

    /// The page's error, and the browser's console, for failure messages.
    fn diagnostics(&self) -> String {
        let Some(id) = self.session.as_deref() else {
            return String::new();
        };
        let error = self
            .call(
                "POST",
                &format!("/session/{id}/execute/sync"),
                Some(
                    json!({"script": "return window.dfsph2d ? window.dfsph2d.error : \
                    'window.dfsph2d is not defined'", "args": []}),
                ),
            )
            .unwrap_or_else(Value::String);
        let console = self
            .call(
                "POST",
                &format!("/session/{id}/se/log"),
                Some(json!({"type": "browser"})),
            )
            .map(|log| {
                log.as_array()
                    .into_iter()
                    .flatten()
                    .map(|e| format!("\n  {} {}", e["level"], e["message"]))
                    .collect::<String>()
            })
            .unwrap_or_else(|e| e);
        format!("\nwindow.dfsph2d.error: {error}\nbrowser console:{console}")
    }
}

impl Drop for Browser {
    fn drop(&mut self) {
        if let Some(id) = self.session.take() {
            let _ = self.call("DELETE", &format!("/session/{id}"), None);
        }
        let _ = self.driver.kill();
        let _ = self.driver.wait();
        // Whatever of the browser outlived its driver: the processes started on this test's
        // own profile folder.
        let profile = self.profile.path().to_string_lossy().into_owned();
        for entry in std::fs::read_dir("/proc").into_iter().flatten().flatten() {
            let Ok(pid) = entry.file_name().to_string_lossy().parse::<u32>() else {
                continue;
            };
            let cmdline = std::fs::read(entry.path().join("cmdline")).unwrap_or_default();
            if String::from_utf8_lossy(&cmdline).contains(&profile) {
                let _ = Command::new("kill").arg("-9").arg(pid.to_string()).status();
            }
        }
    }
}

/// What the page reported at one moment.
#[derive(Clone, Debug)]
struct State {
    particles: u64,
    time: f64,
    mean_x: f64,
    scene: String,
    /// What fitting the default scene to this machine did, once it has.
    fitted: Option<String>,
    realtime: f64,
    wall: Instant,
}

/// Mean x at simulated time `t`, linearly between the samples around it.
fn mean_x_at(samples: &[State], t: f64) -> f64 {
    let k = samples
        .windows(2)
        .position(|w| w[0].time <= t && t <= w[1].time)
        .unwrap_or_else(|| panic!("no samples around t = {t} s"));
    let (a, b) = (&samples[k], &samples[k + 1]);
    let f = if b.time > a.time {
        (t - a.time) / (b.time - a.time)
    } else {
        0.0
    };
    a.mean_x + f * (b.mean_x - a.mean_x)
}

/// Pixels of the screenshot in the water's colours (blues to light cyan), and ones of the
/// page's background.
fn count_pixels(png: &[u8]) -> (usize, usize, usize) {
    let img = image::load_from_memory(png)
        .expect("the screenshot is a PNG")
        .to_rgb8();
    let (mut water, mut background) = (0, 0);
    for p in img.pixels() {
        let [r, g, b] = p.0.map(i32::from);
        if b >= 100 && b >= r + 50 && g >= r {
            water += 1;
        }
        if p.0
            .iter()
            .zip(BACKGROUND)
            .all(|(&c, bg)| c.abs_diff(bg) <= 3)
        {
            background += 1;
        }
    }
    (water, background, (img.width() * img.height()) as usize)
}

#[test]
fn the_page_runs_draws_the_water_and_d_shakes_the_tank_right() {
    let Some((chromium, chromedriver)) = browser_tools() else {
        return;
    };
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let site = tempfile::tempdir().unwrap();
    let built = Instant::now();
    let status = Command::new("bash")
        .arg(root.join("scripts/build-web.sh"))
        .arg(site.path())
        .current_dir(&root)
        .stdout(Stdio::inherit())
        .stderr(Stdio::inherit())
        .status()
        .expect("run scripts/build-web.sh");
    assert!(status.success(), "scripts/build-web.sh failed: {status}");
    let wasm = site.path().join("dfsph_web_bg.wasm");
    let size = std::fs::metadata(&wasm)
        .expect("the site has its module")
        .len();
    let gzipped = Command::new("gzip")
        .args(["-9c"])
        .arg(&wasm)
        .output()
        .ok()
        .filter(|o| o.status.success())
        .map_or("?".to_string(), |o| o.stdout.len().to_string());
    eprintln!(
        "browser test: site built in {:.0?}; dfsph_web_bg.wasm: {size} bytes, {gzipped} gzipped",
        built.elapsed()
    );

    let run_started = Instant::now();
    let port = serve(site.path().to_path_buf(), false);
    // The dam break named in the address keeps its resolution: the page's own default is
    // fitted to the machine (a reset partway), checked last.
    let url = format!("http://127.0.0.1:{port}/#scene=dam-break");
    let plain = format!("http://127.0.0.1:{port}/");
    let browser = Browser::start(&chromium, &chromedriver);

    // The shaken run: the key goes down at KEY_DOWN_AT s and stays down for HOLD s.
    browser.open(&url);
    let first = browser.wait_for_time(0.0, START_TIMEOUT, "starting");
    eprintln!(
        "browser test: first frame after {:.1?} (scene {:?}, {} particles)",
        run_started.elapsed(),
        first.scene,
        first.particles
    );
    assert!(first.particles > 0, "the page shows no water: {first:?}");
    browser.wait_for_time(KEY_DOWN_AT, RUN_TIMEOUT, "before the key");
    // The page focuses its canvas once started; make sure the keys go there.
    browser.eval("document.getElementById('dfsph2d-canvas').focus();");
    browser.key("d", true);
    let down = browser.state().unwrap();
    let held = browser.wait_for_time(down.time + HOLD, RUN_TIMEOUT, "holding d");
    browser.key("d", false);
    browser.session("DELETE", "/actions", None);
    let screenshot = browser.session("GET", "/screenshot", None);
    let png = base64::engine::general_purpose::STANDARD
        .decode(screenshot.as_str().expect("a base64 screenshot"))
        .expect("WebDriver's screenshot is base64");

    // The same scene without the key, up to the same simulated time (another query: the
    // same address with only its fragment would not reload the page).
    browser.open(&format!("http://127.0.0.1:{port}/?still#scene=dam-break"));
    let mut samples = vec![browser.wait_for_time(0.0, START_TIMEOUT, "reloading")];
    while samples.last().unwrap().time < held.time {
        assert!(
            samples[0].wall.elapsed() < RUN_TIMEOUT,
            "the run without the key did not reach {} s of simulated time in {RUN_TIMEOUT:?} \
             (at {:?}){}",
            held.time,
            samples.last(),
            browser.diagnostics()
        );
        std::thread::sleep(Duration::from_millis(50));
        samples.extend(browser.state());
    }
    let last = samples.last().unwrap();
    let realtime =
        (last.time - samples[0].time) / last.wall.duration_since(samples[0].wall).as_secs_f64();
    let still = mean_x_at(&samples, held.time);

    // Served cross-origin isolated, the page loads its threaded build (when the site has
    // one: build-web.sh skips it without a nightly toolchain, and says so) and steps the
    // water on a pool of Web Workers.
    let threaded = site.path().join("threads/dfsph_web.js").is_file();
    let isolated = format!(
        "http://127.0.0.1:{}/#scene=dam-break",
        serve(site.path().to_path_buf(), true)
    );
    browser.open(&isolated);
    let start = browser.wait_for_time(0.0, START_TIMEOUT, "starting isolated");
    let on = browser.wait_for_time(start.time + 0.1, RUN_TIMEOUT, "running isolated");
    let build = browser.eval("return window.dfsph2d.build;");
    let threads = browser.eval("return window.dfsph2d.state().threads;");
    let isolated_realtime =
        (on.time - start.time) / on.wall.duration_since(start.wall).as_secs_f64();

    // The page's own default scene, fitted to this machine within its first seconds (as
    // the window's): fewer particles, said on the HUD and in state().fitted; or, on a
    // machine fast enough, the 5k dam break kept in real time.
    browser.open(&plain);
    let opened = browser.wait_for_time(0.0, START_TIMEOUT, "starting the default page");
    let fitted = loop {
        let now = browser.state().expect("the page keeps reporting");
        if now.fitted.is_some() || opened.wall.elapsed() > FIT_WAIT {
            break now;
        }
        std::thread::sleep(Duration::from_millis(200));
    };
    drop(browser);
    eprintln!(
        "browser test: default page after {:.1?}: {} particles (opened with {}), fitted: \
         {:?}, real-time factor {:.2}",
        opened.wall.elapsed(),
        fitted.particles,
        opened.particles,
        fitted.fitted,
        fitted.realtime
    );
    match &fitted.fitted {
        Some(note) => {
            assert!(
                fitted.particles < opened.particles,
                "fitted to more particles: {fitted:?}"
            );
            assert!(note.contains("fitted to this machine"), "{note}");
        }
        None => assert!(
            fitted.realtime >= 0.9,
            "the default page neither fitted its scene nor kept real time: {fitted:?}"
        ),
    }
    eprintln!(
        "browser test: isolated page: build {build}, {threads} pool threads, real-time factor \
         {isolated_realtime:.3} (from {:.3} s to {:.3} s)",
        start.time, on.time
    );
    assert_eq!(
        on.particles, first.particles,
        "the threaded page lost water"
    );
    if threaded {
        assert_eq!(
            build,
            json!("threads"),
            "the isolated page did not load threads/"
        );
        assert!(threads.as_f64().is_some_and(|n| n >= 1.0), "{threads}");
    } else {
        eprintln!("browser test: the site has no threaded build; the isolated page ran {build}");
    }
    eprintln!(
        "browser test: real-time factor {realtime:.3} (simulated s per wall s, no key); \
         d held from {:.3} s to {:.3} s: mean x {:.3} m, {still:.3} m without the key \
         (at {:.3} s: {:.3} m)",
        down.time, held.time, held.mean_x, first.time, first.mean_x
    );

    // Without WebGL (Chromium's default where it blocklists a software GL) the page says
    // why it shows nothing, where it was blank.
    let without_webgl = Browser::start_with(
        &chromium,
        &chromedriver,
        &["--disable-webgl", "--disable-3d-apis"],
    );
    without_webgl.open(&url);
    let asked = Instant::now();
    let error = loop {
        let error = without_webgl.eval("return window.dfsph2d && window.dfsph2d.error;");
        if let Some(text) = error.as_str() {
            break text.to_string();
        }
        assert!(
            asked.elapsed() < START_TIMEOUT,
            "the page without WebGL gave no error{}",
            without_webgl.diagnostics()
        );
        std::thread::sleep(Duration::from_millis(100));
    };
    let shown = without_webgl.eval(
        "const m = document.getElementById('loading'); \
         return m && m.offsetParent !== null ? m.textContent : null;",
    );
    drop(without_webgl);
    eprintln!("browser test: without WebGL the page says: {shown}");
    assert!(error.contains("WebGL"), "{error}");
    assert_eq!(
        shown.as_str(),
        Some(error.as_str()),
        "the message is not on the page"
    );

    let shot = Path::new(env!("CARGO_TARGET_TMPDIR")).join("browser-screenshot.png");
    std::fs::write(&shot, &png).unwrap();
    let (water, background, total) = count_pixels(&png);
    eprintln!(
        "browser test: screenshot {} ({water} water pixels, {background} background, of \
         {total}); browser part {:.1?}",
        shot.display(),
        run_started.elapsed()
    );

    assert!(
        held.time > down.time && last.time > first.time,
        "simulated time did not advance"
    );
    for s in [&down, &held, last] {
        assert_eq!(s.particles, first.particles, "water was lost or gained");
    }
    assert!(
        held.mean_x - still >= MIN_SHIFT,
        "holding d did not move the water right: mean x {:.3} m with it, {still:.3} m \
         without, at {:.3} s",
        held.mean_x,
        held.time
    );
    assert!(
        water >= total / 100,
        "the page drew little or no water: {water} of {total} pixels in its colours \
         (screenshot: {})",
        shot.display()
    );
}
