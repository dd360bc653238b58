//! `ember-view` in real windows under Xvfb on the machine's Vulkan driver (lavapipe without a
//! GPU): screenshots of the window against `ember render`'s image (through the library, the
//! same `Progressive` code) and against the headless frame, synthetic keys and mouse drags,
//! titles, the files the O key writes, and how quickly closing stops the rendering threads.
//!
//! Each test starts its own Xvfb on a free display and kills it at the end. Nothing is
//! skipped: no Xvfb, xdotool, ImageMagick or adapter, or a window that does not open, fails.

mod xvfb;

use ember_cli::image::{read_exr, srgb8, Image};
use ember_cli::render::{render, RenderSettings, Shard};
use ember_cli::LoadedScene;
use ember_kernel::integrator::Integrator;
use ember_kernel::sampler::DEFAULT_SEED;
use std::path::Path;
use std::time::{Duration, Instant};
use xvfb::{read_png_rgb8, serial, title_spp, TempDir, Viewer, Xvfb};

const W: u32 = 160;
const H: u32 = 120;
const LONG: Duration = Duration::from_secs(90);

/// `ember render`'s image of a scene at W×H (the scene camera), as the library renders it.
fn ember_render(
    toml: &Path,
    integrator: Option<Integrator>,
    gi: bool,
    spp: u32,
    seed: u64,
) -> Image {
    let scene = LoadedScene::load(toml).unwrap();
    let (scene_integrator, path) = if gi {
        (Integrator::PathMis, scene.gi_settings().0)
    } else {
        let (i, p, _) = scene.path_settings().unwrap();
        (i, p)
    };
    let s = RenderSettings {
        integrator: integrator.unwrap_or(scene_integrator),
        path,
        spp,
        seed,
        sampler: ember_kernel::sampler::SamplerKind::Independent,
        tile: 16,
        threads: 0,
        progress: false,
        shard: Shard::WHOLE,
        strategies: None,
    };
    render(&scene.data.view(), &scene.camera(W, H), &s).image
}

fn exposed(img: &Image, stops: f32) -> Image {
    let m = ember_viewer::display::exposure_multiplier(stops);
    Image {
        pixels: img.pixels.iter().map(|&p| p * m).collect(),
        ..img.clone()
    }
}

fn assert_matches(shot: &xvfb::Shot, want: &[u8], what: &str) {
    assert_eq!(
        (shot.width, shot.height),
        (W, H),
        "{what}: the window is film-sized"
    );
    let (max, over) = shot.diff(want);
    assert!(
        max <= 1,
        "{what}: screenshot differs from the expected sRGB image by up to {max} (channels off by more than 1: {over})"
    );
}

fn done(spp: u32) -> impl Fn(&str) -> bool {
    move |t: &str| t.contains(&format!(" {spp}/{spp} spp (done)"))
}

/// The rendering threads' stop time from the summary line, in ms.
fn stop_ms(stderr: &str) -> f64 {
    let at = stderr
        .find("rendering threads stopped ")
        .unwrap_or_else(|| panic!("no stop time in: {stderr}"));
    let rest = &stderr[at + "rendering threads stopped ".len()..];
    rest.split(' ').next().unwrap().parse().unwrap()
}

#[test]
fn path_scene_window_is_ember_render_and_follows_the_keys() {
    let _serial = serial();
    let start = Instant::now();
    let tmp = TempDir::new("window-path");
    let dir = tmp.0.as_path();
    let toml = tmp.cornell_box().join("cornell_box.toml");
    let x = Xvfb::start();
    let (w, h) = (W.to_string(), H.to_string());
    let mut v = Viewer::start(
        &x,
        &[
            toml.to_str().unwrap(),
            "--width",
            &w,
            "--height",
            &h,
            "--spp",
            "16",
            "--seed",
            "5",
        ],
    );
    // The scene says isExplicit = true.
    let title = v.wait_title("16/16 spp", LONG, done(16));
    assert!(title.contains("path tracing (explicit)"), "{title}");
    let reference = ember_render(&toml, None, false, 16, 5);
    let want = srgb8(&reference);
    assert_matches(
        &v.screenshot_matching(dir, &want),
        &want,
        "16 spp, explicit",
    );

    // O writes the accumulation beside the scene: ember render's image bit for bit.
    v.key(&["o"]);
    let exr = toml.with_file_name("cornell_box_16spp.exr");
    let png = exr.with_extension("png");
    let deadline = Instant::now() + Duration::from_secs(20);
    while !(exr.is_file() && png.is_file()) {
        assert!(Instant::now() < deadline, "O wrote nothing: {}", v.stderr());
        std::thread::sleep(Duration::from_millis(50));
    }
    std::thread::sleep(Duration::from_millis(200));
    assert_eq!(
        read_exr(&exr).unwrap(),
        reference,
        "the saved EXR is ember render's"
    );
    assert_eq!(
        read_png_rgb8(&png).rgb,
        want,
        "the saved PNG is ember render's"
    );

    // Exposure: half a stop up, then back to 0; no restart.
    v.key(&["bracketright"]);
    v.wait_title("exposure +0.5", LONG, |t| t.contains("exposure +0.5"));
    let bright = srgb8(&exposed(&reference, 0.5));
    assert_matches(
        &v.screenshot_matching(dir, &bright),
        &bright,
        "exposure +0.5",
    );
    v.key(&["minus", "minus"]);
    v.wait_title("exposure -0.5", LONG, |t| t.contains("exposure -0.5"));
    let dark = srgb8(&exposed(&reference, -0.5));
    assert_matches(&v.screenshot_matching(dir, &dark), &dark, "exposure -0.5");
    v.key(&["0"]);
    let t = v.wait_title("exposure reset", LONG, |t| !t.contains("exposure"));
    assert!(
        done(16)(&t),
        "exposure does not restart the accumulation: {t}"
    );
    assert_matches(&v.screenshot_matching(dir, &want), &want, "exposure reset");

    // F: the relative error in false colour (nothing like the image), and back.
    v.key(&["f"]);
    v.wait_title("relative error", LONG, |t| t.contains("relative error"));
    std::thread::sleep(Duration::from_millis(300));
    let errors = v.screenshot(dir);
    assert!(
        errors.mean_abs_diff(&want) > 20.0,
        "the error view looks like the image ({:.1})",
        errors.mean_abs_diff(&want)
    );
    v.key(&["f"]);
    v.wait_title("radiance", LONG, |t| !t.contains("relative error"));
    assert_matches(&v.screenshot_matching(dir, &want), &want, "radiance again");

    // A drag orbits the camera: another image, converged again...
    v.drag((80, 60), (40, 10), 10);
    let deadline = Instant::now() + LONG;
    let moved = loop {
        let t = v.title();
        let s = v.screenshot(dir);
        if done(16)(&t) && s.mean_abs_diff(&want) > 2.0 {
            break s;
        }
        assert!(Instant::now() < deadline, "the view did not change: {t}");
        std::thread::sleep(Duration::from_millis(100));
    };
    // ...and R returns to the scene camera, where the restarted accumulation is ember
    // render's image again, bit for bit.
    v.key(&["r"]);
    let deadline = Instant::now() + LONG;
    loop {
        let s = v.screenshot(dir);
        if s.diff(&want).0 <= 1 && done(16)(&v.title()) {
            break;
        }
        assert!(
            Instant::now() < deadline,
            "R did not return to ember render's image: {}",
            v.title()
        );
        std::thread::sleep(Duration::from_millis(100));
    }
    assert!(moved.mean_abs_diff(&want) > 2.0);

    // I cycles the integrator: explicit → mis restarts and converges to MIS's image.
    v.key(&["i"]);
    v.wait_title("mis at 16 spp", LONG, |t| {
        t.contains("path tracing (mis)") && done(16)(t)
    });
    let mis = srgb8(&ember_render(
        &toml,
        Some(Integrator::PathMis),
        false,
        16,
        5,
    ));
    assert_ne!(mis, want, "MIS and explicit differ in their noise");
    assert_matches(&v.screenshot_matching(dir, &mis), &mis, "16 spp, mis");

    v.key(&["Escape"]);
    let status = v.wait_exit(Duration::from_secs(20));
    let stderr = v.stderr();
    assert!(status.success(), "{status}: {stderr}");
    assert!(
        stderr.contains("wrote ") && stderr.contains("cornell_box_16spp.exr"),
        "{stderr}"
    );
    eprintln!("{stderr}");
    eprintln!("test took {:.1} s", start.elapsed().as_secs_f64());
}

#[test]
fn camera_moves_restart_the_accumulation_and_closing_stops_the_workers_promptly() {
    let _serial = serial();
    let start = Instant::now();
    let tmp = TempDir::new("window-moves");
    let toml = tmp.cornell_box().join("cornell_box.toml");
    let x = Xvfb::start();
    let (w, h) = (W.to_string(), H.to_string());
    // A target that is never reached during the test.
    let out = tmp.0.join("saved.exr");
    let mut v = Viewer::start(
        &x,
        &[
            toml.to_str().unwrap(),
            "--width",
            &w,
            "--height",
            &h,
            "--spp",
            "1000000",
            "-o",
            out.to_str().unwrap(),
        ],
    );
    let spp = |t: &str| title_spp(t).map_or(0, |(n, _)| n);
    v.wait_title("16+ spp", LONG, |t| spp(t) >= 16);
    // Exposure changes only the display: the count keeps growing.
    let before = spp(&v.title());
    v.key(&["bracketright"]);
    let t = v.wait_title("exposure", LONG, |t| t.contains("exposure +0.5"));
    assert!(
        spp(&t) >= before,
        "exposure restarted the accumulation: {t}"
    );
    let shot = v.screenshot(&tmp.0);

    // O in the middle of the accumulation writes --output: ember render's image at whatever
    // spp the view had reached, bit for bit.
    v.key(&["o"]);
    let deadline = Instant::now() + Duration::from_secs(20);
    let saved_spp = loop {
        let err = v.stderr();
        if let Some(line) = err
            .lines()
            .find(|l| l.contains("wrote ") && l.contains("saved.exr"))
        {
            let n = line.rsplit('(').next().unwrap().trim_end_matches(" spp)");
            break n.parse::<u32>().unwrap_or_else(|_| panic!("{line}"));
        }
        assert!(Instant::now() < deadline, "O wrote nothing: {err}");
        std::thread::sleep(Duration::from_millis(50));
    };
    assert!(saved_spp >= 16, "{saved_spp}");
    assert_eq!(
        read_exr(&out).unwrap(),
        ember_render(&toml, None, false, saved_spp, DEFAULT_SEED),
        "the accumulation at {saved_spp} spp"
    );
    assert!(out.with_extension("png").is_file());

    // A mouse drag: the count drops (to the preview or the first passes), then grows again.
    let s1 = spp(&v.title());
    v.drag((80, 60), (-30, 0), 8);
    let t = v.wait_title("a restart after the drag", LONG, |t| spp(t) < s1);
    eprintln!("after the drag: {t}");
    let t = v.wait_title("16+ spp again", LONG, |t| spp(t) >= 16);
    assert!(t.contains("path tracing"), "{t}");
    let moved = v.screenshot(&tmp.0);
    assert!(
        moved.mean_abs_diff(&shot.rgb) > 2.0,
        "the drag did not change the view"
    );

    // Flying with a held key restarts it too.
    let s2 = spp(&v.title());
    v.hold_key("w", 300);
    v.wait_title("a restart after flying", LONG, |t| spp(t) < s2);
    v.wait_title("16+ spp after flying", LONG, |t| spp(t) >= 16);

    // Esc in the middle of a pass: the rendering threads stop promptly.
    std::thread::sleep(Duration::from_millis(500));
    v.key(&["Escape"]);
    let status = v.wait_exit(Duration::from_secs(20));
    let stderr = v.stderr();
    assert!(status.success(), "{status}: {stderr}");
    let ms = stop_ms(&stderr);
    eprintln!("{stderr}");
    assert!(ms < 1000.0, "the rendering threads took {ms} ms to stop");
    eprintln!("test took {:.1} s", start.elapsed().as_secs_f64());
}

#[test]
fn gi_scene_baked_window_is_the_headless_frame_and_p_switches_to_path_tracing() {
    let _serial = serial();
    let start = Instant::now();
    let tmp = TempDir::new("window-gi");
    let dir = tmp.0.as_path();
    let toml = tmp.cornell_box().join("cornell_box_gi.toml");
    let t = toml.to_str().unwrap();
    let (w, h) = (W.to_string(), H.to_string());
    // The headless frame (this also stores the bake the window reuses).
    let headless = dir.join("headless.exr");
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_ember-view"))
        .args([
            t,
            "--headless",
            "-q",
            "--width",
            &w,
            "--height",
            &h,
            "-o",
            headless.to_str().unwrap(),
        ])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let baked = read_png_rgb8(&headless.with_extension("png")).rgb;

    let x = Xvfb::start();
    let mut v = Viewer::start(&x, &[t, "--width", &w, "--height", &h, "--spp", "8"]);
    let title = v.wait_title("baked GI", LONG, |t| t.contains("baked GI"));
    assert!(!title.contains("spp"), "{title}");
    assert!(v.stderr().contains("reusing the bake"), "{}", v.stderr());
    assert_matches(&v.screenshot_matching(dir, &baked), &baked, "baked view");

    // P: the path-traced view from the same camera, the gi path settings with MIS.
    v.key(&["p"]);
    let title = v.wait_title("8/8 spp", LONG, done(8));
    assert!(title.contains("path tracing (mis)"), "{title}");
    let traced = srgb8(&ember_render(&toml, None, true, 8, DEFAULT_SEED));
    assert_matches(
        &v.screenshot_matching(dir, &traced),
        &traced,
        "path-traced view",
    );
    // The bake's error is what the two views differ by: small, but not nothing.
    let d = xvfb::Shot {
        width: W,
        height: H,
        rgb: baked.clone(),
    }
    .mean_abs_diff(&traced);
    assert!(d > 0.5 && d < 40.0, "baked vs traced: mean difference {d}");

    // P again: back to the baked frame.
    v.key(&["p"]);
    v.wait_title("baked GI", LONG, |t| t.contains("baked GI"));
    assert_matches(
        &v.screenshot_matching(dir, &baked),
        &baked,
        "baked view again",
    );

    // Move in the baked view, then P: the path-traced view follows the moved camera.
    v.drag((80, 60), (30, -10), 6);
    let deadline = Instant::now() + LONG;
    let moved_baked = loop {
        std::thread::sleep(Duration::from_millis(200));
        let s = v.screenshot(dir);
        if s.mean_abs_diff(&baked) > 2.0 {
            break s;
        }
        assert!(
            Instant::now() < deadline,
            "the drag did not move the baked view"
        );
    };
    v.key(&["p"]);
    v.wait_title("8/8 spp after moving", LONG, |t| {
        t.contains("path tracing") && done(8)(t)
    });
    std::thread::sleep(Duration::from_millis(300));
    let moved_traced = v.screenshot(dir);
    let same_camera = moved_traced.mean_abs_diff(&moved_baked.rgb);
    let old_camera = moved_traced.mean_abs_diff(&traced);
    assert!(
        same_camera < old_camera,
        "the path-traced view is not from the moved camera ({same_camera:.1} vs {old_camera:.1})"
    );

    v.key(&["Escape"]);
    let status = v.wait_exit(Duration::from_secs(20));
    let stderr = v.stderr();
    assert!(status.success(), "{status}: {stderr}");
    assert!(stop_ms(&stderr) < 1000.0, "{stderr}");
    eprintln!("{stderr}");
    eprintln!("test took {:.1} s", start.elapsed().as_secs_f64());
}

/// stderr of a failed run: exactly one line, `error: ...` containing `what`.
fn assert_one_error_line(o: &std::process::Output, code: i32, what: &str) {
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(code), "{stderr}");
    let lines: Vec<&str> = stderr.lines().collect();
    assert_eq!(lines.len(), 1, "one line: {stderr}");
    assert!(
        lines[0].starts_with("error: ") && lines[0].contains(what),
        "{what}: {stderr}"
    );
}

#[test]
fn window_errors_are_one_clear_line() {
    let _serial = serial();
    let tmp = TempDir::new("window-errors");
    let toml = tmp.cornell_box().join("cornell_box.toml");
    let view = || {
        let mut c = std::process::Command::new(env!("CARGO_BIN_EXE_ember-view"));
        c.env_remove("WAYLAND_DISPLAY");
        c
    };
    // An unreadable scene (a directory).
    let o = view()
        .args([tmp.0.to_str().unwrap(), "-q"])
        .env_remove("DISPLAY")
        .output()
        .unwrap();
    assert_one_error_line(&o, 2, "cannot read scene file: Is a directory");
    // A missing one.
    let missing = tmp.0.join("missing.toml");
    let o = view()
        .args([missing.to_str().unwrap(), "-q"])
        .env_remove("DISPLAY")
        .output()
        .unwrap();
    assert_one_error_line(&o, 2, "missing.toml: cannot read scene file");
    // No display at all.
    let o = view()
        .args([
            toml.to_str().unwrap(),
            "-q",
            "--width",
            "32",
            "--height",
            "24",
        ])
        .env_remove("DISPLAY")
        .output()
        .unwrap();
    assert_one_error_line(&o, 1, "cannot open a window");
    // A display but no adapter: a backend this build does not have.
    let x = Xvfb::start();
    let o = view()
        .args([
            toml.to_str().unwrap(),
            "-q",
            "--width",
            "32",
            "--height",
            "24",
        ])
        .env("DISPLAY", &x.display)
        .env("WGPU_BACKEND", "dx12")
        .output()
        .unwrap();
    assert_one_error_line(&o, 1, "no GPU adapter found");
    // Bad values are refused before any window opens.
    let o = view()
        .args([toml.to_str().unwrap(), "--spp", "0"])
        .env("DISPLAY", &x.display)
        .output()
        .unwrap();
    assert_one_error_line(&o, 2, "--spp 0: must be at least 1");
    let o = view()
        .args([toml.to_str().unwrap(), "--headless"])
        .env("DISPLAY", &x.display)
        .output()
        .unwrap();
    assert_one_error_line(&o, 2, "not a real-time \"gi\" scene");
}
