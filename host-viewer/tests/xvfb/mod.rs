//! Real windows for the tests: an Xvfb server on a free display (chosen by Xvfb itself with
//! `-displayfd`), `ember-view` started on it, and xdotool / ImageMagick to read titles, send
//! keys and mouse drags and take screenshots. Nothing is installed here: `scripts/test.sh`
//! installs xvfb, xdotool and imagemagick, and a missing tool fails the test.

#![allow(dead_code)]

use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::{Arc, Mutex, MutexGuard, OnceLock};
use std::time::{Duration, Instant};

/// One window test at a time: each starts a viewer whose render threads use both cores, and
/// the tests read timings (stop times) that a second viewer would distort.
pub fn serial() -> MutexGuard<'static, ()> {
    static LOCK: OnceLock<Mutex<()>> = OnceLock::new();
    LOCK.get_or_init(|| Mutex::new(()))
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
}

fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// A fresh folder under the system temporary directory, removed on drop.
pub struct TempDir(pub PathBuf);

impl TempDir {
    pub fn new(name: &str) -> Self {
        let d = std::env::temp_dir().join(format!("ember-view-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        Self(d)
    }

    /// A copy of `data/cornell-box` (TOMLs and meshes) inside; returns the folder.
    pub fn cornell_box(&self) -> PathBuf {
        let src = workspace().join("data/cornell-box");
        let dst = self.0.join("cornell-box");
        std::fs::create_dir_all(dst.join("mesh")).unwrap();
        for f in ["cornell_box.toml", "cornell_box_gi.toml"] {
            std::fs::copy(src.join(f), dst.join(f)).unwrap();
        }
        for e in std::fs::read_dir(src.join("mesh")).unwrap().flatten() {
            std::fs::copy(e.path(), dst.join("mesh").join(e.file_name())).unwrap();
        }
        dst
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        if !std::thread::panicking() {
            let _ = std::fs::remove_dir_all(&self.0);
        } else {
            eprintln!("kept {} for inspection", self.0.display());
        }
    }
}

/// An Xvfb server; killed on drop.
pub struct Xvfb {
    child: Child,
    pub display: String,
}

impl Xvfb {
    /// Starts `Xvfb -displayfd 1 -noreset` (1024x768, 24 bits) and waits for the display
    /// number it chose.
    pub fn start() -> Self {
        let mut child = Command::new("Xvfb")
            .args([
                "-displayfd",
                "1",
                "-screen",
                "0",
                "1024x768x24",
                "-nolisten",
                "tcp",
                // Without it the server resets when its last client disconnects (the
                // readiness probe below), and a client connecting during the reset is
                // refused: the "Failed to open connection to X server" CI saw once.
                "-noreset",
            ])
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .unwrap_or_else(|e| {
                panic!("cannot start Xvfb ({e}); scripts/test.sh installs it (Debian: xvfb)")
            });
        let stdout = child.stdout.take().unwrap();
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            let mut line = String::new();
            let _ = BufReader::new(stdout).read_line(&mut line);
            let _ = tx.send(line);
        });
        let line = rx
            .recv_timeout(Duration::from_secs(30))
            .expect("Xvfb did not report a display within 30 s");
        let n: u32 = line
            .trim()
            .parse()
            .unwrap_or_else(|_| panic!("Xvfb reported {line:?} as its display"));
        let x = Self {
            child,
            display: format!(":{n}"),
        };
        // Wait until clients can connect.
        let deadline = Instant::now() + Duration::from_secs(30);
        while !x.run("xdotool", &["getdisplaygeometry"]).status.success() {
            assert!(
                Instant::now() < deadline,
                "Xvfb on {} accepts no connection",
                x.display
            );
            std::thread::sleep(Duration::from_millis(50));
        }
        x
    }

    /// Runs an X client (xdotool, import) on this display; panics if it cannot run.
    pub fn run(&self, program: &str, args: &[&str]) -> std::process::Output {
        Command::new(program)
            .args(args)
            .env("DISPLAY", &self.display)
            .output()
            .unwrap_or_else(|e| {
                panic!(
                    "cannot run {program} ({e}); scripts/test.sh installs xdotool and imagemagick"
                )
            })
    }
}

impl Drop for Xvfb {
    fn drop(&mut self) {
        // SIGTERM first, so that the server removes its socket and lock file; SIGKILL if it
        // has not ended within 5 s.
        let _ = Command::new("kill")
            .args(["-TERM", &self.child.id().to_string()])
            .status();
        let deadline = Instant::now() + Duration::from_secs(5);
        while Instant::now() < deadline {
            if let Ok(Some(_)) = self.child.try_wait() {
                return;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// `ember-view` running in a window on an [`Xvfb`].
pub struct Viewer<'a> {
    x: &'a Xvfb,
    child: Child,
    stderr: Arc<Mutex<String>>,
    pub window: String,
}

/// An RGB8 screenshot.
#[derive(Clone, Debug, PartialEq)]
pub struct Shot {
    pub width: u32,
    pub height: u32,
    pub rgb: Vec<u8>,
}

impl Shot {
    /// Largest per-channel difference and the number of channels that differ by more than 1.
    pub fn diff(&self, rgb: &[u8]) -> (u8, usize) {
        assert_eq!(self.rgb.len(), rgb.len(), "image sizes differ");
        let mut max = 0;
        let mut over = 0;
        for (a, b) in self.rgb.iter().zip(rgb) {
            let d = a.abs_diff(*b);
            max = max.max(d);
            over += usize::from(d > 1);
        }
        (max, over)
    }

    pub fn mean_abs_diff(&self, rgb: &[u8]) -> f64 {
        assert_eq!(self.rgb.len(), rgb.len());
        self.rgb
            .iter()
            .zip(rgb)
            .map(|(a, b)| f64::from(a.abs_diff(*b)))
            .sum::<f64>()
            / rgb.len() as f64
    }

    pub fn mean(&self) -> f64 {
        self.rgb.iter().map(|&v| f64::from(v)).sum::<f64>() / self.rgb.len() as f64
    }
}

/// Decodes a PNG to RGB8.
pub fn read_png_rgb8(path: &Path) -> Shot {
    let mut decoder = png::Decoder::new(std::io::BufReader::new(
        std::fs::File::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display())),
    ));
    decoder.set_transformations(png::Transformations::EXPAND | png::Transformations::STRIP_16);
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).unwrap();
    let channels = match info.color_type {
        png::ColorType::Rgb => 3,
        png::ColorType::Rgba => 4,
        png::ColorType::Grayscale => 1,
        png::ColorType::GrayscaleAlpha => 2,
        png::ColorType::Indexed => unreachable!("expanded"),
    };
    let rgb = buf[..info.buffer_size()]
        .chunks_exact(channels)
        .flat_map(|p| {
            if channels >= 3 {
                [p[0], p[1], p[2]]
            } else {
                [p[0]; 3]
            }
        })
        .collect();
    Shot {
        width: info.width,
        height: info.height,
        rgb,
    }
}

impl<'a> Viewer<'a> {
    /// Starts `ember-view ARGS` on the display and waits (up to 60 s) for its window.
    pub fn start(x: &'a Xvfb, args: &[&str]) -> Self {
        let mut child = Command::new(env!("CARGO_BIN_EXE_ember-view"))
            .args(args)
            .env("DISPLAY", &x.display)
            .env_remove("WAYLAND_DISPLAY")
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .expect("cannot run ember-view");
        let stderr = Arc::new(Mutex::new(String::new()));
        let mut pipe = child.stderr.take().unwrap();
        let sink = stderr.clone();
        std::thread::spawn(move || {
            let mut buf = [0u8; 4096];
            while let Ok(n) = pipe.read(&mut buf) {
                if n == 0 {
                    break;
                }
                sink.lock()
                    .unwrap()
                    .push_str(&String::from_utf8_lossy(&buf[..n]));
            }
        });
        let mut v = Self {
            x,
            child,
            stderr,
            window: String::new(),
        };
        let deadline = Instant::now() + Duration::from_secs(60);
        loop {
            if let Ok(Some(status)) = v.child.try_wait() {
                panic!(
                    "ember-view exited ({status}) before its window appeared: {}",
                    v.stderr()
                );
            }
            assert!(
                Instant::now() < deadline,
                "no ember-view window within 60 s: {}",
                v.stderr()
            );
            let o = x.run("xdotool", &["search", "--name", "^ember-view"]);
            if let Some(id) = String::from_utf8_lossy(&o.stdout).lines().next() {
                v.window = id.trim().to_string();
                break;
            }
            std::thread::sleep(Duration::from_millis(100));
        }
        // Focus the window once, and let it see the focus change: a key sent in the same
        // moment as the focus (from PointerRoot, Xvfb's initial focus) is dropped.
        let o = x.run("xdotool", &["windowfocus", "--sync", &v.window]);
        assert!(
            o.status.success(),
            "xdotool windowfocus: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        std::thread::sleep(Duration::from_millis(300));
        v
    }

    pub fn stderr(&self) -> String {
        self.stderr.lock().unwrap().clone()
    }

    pub fn title(&self) -> String {
        let o = self.x.run("xdotool", &["getwindowname", &self.window]);
        String::from_utf8_lossy(&o.stdout).trim().to_string()
    }

    /// Polls the title until `pred` holds (every 20 ms, up to `timeout`); returns it.
    pub fn wait_title(
        &mut self,
        what: &str,
        timeout: Duration,
        pred: impl Fn(&str) -> bool,
    ) -> String {
        let deadline = Instant::now() + timeout;
        loop {
            let t = self.title();
            if pred(&t) {
                return t;
            }
            if let Ok(Some(status)) = self.child.try_wait() {
                panic!(
                    "ember-view exited ({status}) waiting for {what}: {}",
                    self.stderr()
                );
            }
            assert!(
                Instant::now() < deadline,
                "title never showed {what} within {timeout:?}; last: {t:?}; stderr: {}",
                self.stderr()
            );
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// Presses and releases keys (xdotool key names), with the window focused.
    pub fn key(&self, keys: &[&str]) {
        let mut args = vec!["windowfocus", self.window.as_str(), "key", "--delay", "30"];
        args.extend_from_slice(keys);
        let o = self.x.run("xdotool", &args);
        assert!(
            o.status.success(),
            "xdotool {args:?}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
    }

    /// Holds a key down for `ms` milliseconds.
    pub fn hold_key(&self, key: &str, ms: u32) {
        let secs = format!("{:.3}", f64::from(ms) / 1e3);
        let args = [
            "windowfocus",
            self.window.as_str(),
            "keydown",
            key,
            "sleep",
            secs.as_str(),
            "keyup",
            key,
        ];
        let o = self.x.run("xdotool", &args);
        assert!(
            o.status.success(),
            "xdotool {args:?}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
    }

    /// A left-button drag from (x0, y0) by (dx, dy) window pixels in `steps` moves 20 ms apart.
    pub fn drag(&self, (x0, y0): (i32, i32), (dx, dy): (i32, i32), steps: i32) {
        let w = self.window.as_str();
        let mut args: Vec<String> = ["mousemove", "--window", w, &x0.to_string(), &y0.to_string()]
            .iter()
            .map(ToString::to_string)
            .collect();
        args.extend(["mousedown", "1"].map(String::from));
        for i in 1..=steps {
            args.extend([
                "sleep".to_string(),
                "0.02".to_string(),
                "mousemove".to_string(),
                "--window".to_string(),
                w.to_string(),
                (x0 + dx * i / steps).to_string(),
                (y0 + dy * i / steps).to_string(),
            ]);
        }
        args.extend(["mouseup", "1"].map(String::from));
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let o = self.x.run("xdotool", &args);
        assert!(
            o.status.success(),
            "xdotool drag: {}",
            String::from_utf8_lossy(&o.stderr)
        );
    }

    /// A screenshot of the window's contents (ImageMagick `import -window`).
    pub fn screenshot(&self, dir: &Path) -> Shot {
        let path = dir.join("shot.png");
        let target = format!("png24:{}", path.display());
        let o = self.x.run("import", &["-window", &self.window, &target]);
        assert!(
            o.status.success(),
            "import -window {}: {}",
            self.window,
            String::from_utf8_lossy(&o.stderr)
        );
        read_png_rgb8(&path)
    }

    /// Takes screenshots (for up to 3 s) until one is within ±1 of `rgb`; returns the last.
    /// (The title is set after the frame is presented, but the X server may draw the
    /// presented image a moment later.)
    pub fn screenshot_matching(&self, dir: &Path, rgb: &[u8]) -> Shot {
        let deadline = Instant::now() + Duration::from_secs(3);
        loop {
            let s = self.screenshot(dir);
            if s.rgb.len() == rgb.len() && s.diff(rgb).0 <= 1 || Instant::now() > deadline {
                return s;
            }
            std::thread::sleep(Duration::from_millis(100));
        }
    }

    /// Waits (up to `timeout`) for the process to end.
    pub fn wait_exit(&mut self, timeout: Duration) -> ExitStatus {
        let deadline = Instant::now() + timeout;
        loop {
            if let Some(s) = self.child.try_wait().unwrap() {
                // Let the reader thread take the last lines.
                std::thread::sleep(Duration::from_millis(100));
                return s;
            }
            assert!(
                Instant::now() < deadline,
                "ember-view still running {timeout:?} after being asked to quit: {}",
                self.stderr()
            );
            std::thread::sleep(Duration::from_millis(20));
        }
    }
}

impl Drop for Viewer<'_> {
    fn drop(&mut self) {
        if self.child.try_wait().ok().flatten().is_none() {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
}

/// `(spp, target)` from a title's "N/M spp".
pub fn title_spp(title: &str) -> Option<(u32, u32)> {
    let before = &title[..title.find(" spp")?];
    let token = before.rsplit(' ').next()?;
    let (n, m) = token.split_once('/')?;
    Some((n.parse().ok()?, m.parse().ok()?))
}
