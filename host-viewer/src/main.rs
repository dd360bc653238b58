//! `ember-view`: shows a scene in a window — the baked global illumination of a real-time `gi`
//! scene, and the progressive path-traced view of any scene — or writes one headless frame of
//! a `gi` scene like TinyRender's first real-time frame.

use clap::Parser;
use ember_cli::bake::{bake, default_bake_path, load_or_bake, BakeSettings};
use ember_cli::image::write_exr;
use ember_cli::scene_file::{RendererDesc, MAX_FILM_SIDE};
use ember_cli::{Error, LoadedScene};
use ember_kernel::integrator::{Integrator, Shortcuts};
use ember_kernel::sampler::DEFAULT_SEED;
use ember_viewer::trace::TraceSetup;
use ember_viewer::window::TraceOptions;
use ember_viewer::{gpu, window, HeadlessGpu, ViewerError};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::Arc;

/// Target spp of the path-traced view of a `gi` scene (which has no `spp` of its own).
const GI_TRACE_SPP: u32 = 64;

#[derive(Clone, Copy, clap::ValueEnum)]
enum IntegratorArg {
    Implicit,
    Explicit,
    Mis,
}

impl From<IntegratorArg> for Integrator {
    fn from(a: IntegratorArg) -> Self {
        match a {
            IntegratorArg::Implicit => Self::PathImplicit,
            IntegratorArg::Explicit => Self::PathExplicit,
            IntegratorArg::Mis => Self::PathMis,
        }
    }
}

#[derive(Parser)]
#[command(
    name = "ember-view",
    version,
    about = "Shows a TinyRender scene: baked global illumination of a \"gi\" scene, and a progressive path-traced view",
    long_about = "Shows a TinyRender scene in a window.\n\n\
        A real-time \"gi\" scene is baked (per-vertex radiance, Gouraud shading); the bake is \
        stored beside the scene (or at --bake) and reused while it was made from the same \
        scene data and settings. P switches to a progressive path-traced view of it (the \
        scene's gi path settings, MIS unless --integrator says otherwise). An offline \"path\" \
        scene opens in the path-traced view: the CPU renders passes of samples, the window \
        shows them converging, and the accumulation at N spp is bit for bit `ember render` at \
        N spp with the same camera, seed and integrator.\n\n\
        Controls: left-drag orbits, wheel zooms, W/A/S/D/Q/E fly (Shift: faster), right-drag \
        looks around, R resets the camera, F toggles false colour (baked: log luminance; \
        path-traced: relative standard error), P baked/path-traced (gi scenes), Esc quits. \
        Path-traced view: +/= or ] and - or [ change the exposure by half a stop (0 resets), \
        I cycles the integrator, O writes the accumulation as <stem>_<N>spp.exr + .png beside \
        the scene (or --output).\n\n\
        --headless writes one baked frame of a gi scene (EXR + PNG) instead of opening a window."
)]
struct Cli {
    /// TinyRender scene file (.toml): a real-time `gi` scene (baked view; P path-traces) or an
    /// offline `path` scene (path-traced view).
    scene: PathBuf,
    /// Render one frame offscreen and write it (EXR, linear, and a PNG preview beside it)
    /// instead of opening a window.
    #[arg(long)]
    headless: bool,
    /// Output EXR (a PNG is written beside it): of --headless (default: next to the TOML
    /// with the same stem, as TinyRender), or of the path-traced view's O key (default:
    /// `<stem>_<N>spp.exr` beside the TOML).
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Path-traced view: stop at this many samples per pixel (default: the scene's `spp`; 64
    /// for a gi scene).
    #[arg(long)]
    spp: Option<u32>,
    /// Path-traced view: the integrator (default: the scene's, `isExplicit` choosing explicit
    /// or implicit; mis for a gi scene). I cycles it in the window.
    #[arg(long, value_enum)]
    integrator: Option<IntegratorArg>,
    /// Path-traced view: initial exposure in stops (the radiance is multiplied by 2^stops).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    exposure: f32,
    /// Run the general kernel code, without the shortcuts the scene allows (bake and
    /// path-traced view; bit-identical results).
    #[arg(long)]
    no_shortcuts: bool,
    /// Paths per vertex of the bake (default: the scene's `samplesByVertex`).
    #[arg(long)]
    samples_per_vertex: Option<u32>,
    /// Seed of the bake's and the path-traced view's sampler.
    #[arg(long, default_value_t = DEFAULT_SEED)]
    seed: u64,
    /// Sample sequence of the path-traced view: independent (the default here, unlike `ember
    /// render`: the view is progressive, and with independent samples its image at any N spp
    /// equals `ember render --sampler independent --spp N`), or zsobol, laid out for the target
    /// spp up front (the image at the target N equals `ember render --sampler zsobol --spp N`;
    /// before it, the first samples of that layout).
    #[arg(long, value_parser = ember_cli::bench::parse_sampler, default_value = "independent")]
    sampler: ember_kernel::sampler::SamplerKind,
    /// Bake and path-tracing threads (default: one per core). Does not change the results.
    #[arg(long, default_value_t = 0)]
    threads: usize,
    /// Film (or initial window) width in pixels (default: the scene's).
    #[arg(long)]
    width: Option<u32>,
    /// Film (or initial window) height in pixels (default: the scene's).
    #[arg(long)]
    height: Option<u32>,
    /// Where the bake is stored (default: `<scene stem>.bake.ply` beside the TOML).
    #[arg(long)]
    bake: Option<PathBuf>,
    /// Show the baked luminance on a log-scale colour ramp (turbo) instead of the radiance.
    #[arg(long, alias = "false-color")]
    false_colour: bool,
    /// No progress bar and fewer messages.
    #[arg(short, long)]
    quiet: bool,
    /// Bake each vertex this fraction of the way toward an adjacent triangle's centroid;
    /// 0 bakes the vertex itself, as TinyRender does.
    #[arg(long, default_value_t = ember_cli::bake::BAKE_INSET)]
    vertex_inset: f32,
    /// Path tracer of the bake: `mis` (default; low variance at room edges) or `explicit`
    /// (TinyRender's, next-event estimation only). With `--vertex-inset 0 --bake-estimator
    /// explicit` the bake is TinyRender's.
    #[arg(long, value_parser = ember_cli::bake::parse_estimator, default_value = "mis")]
    bake_estimator: ember_kernel::integrator::BakeEstimator,
    /// Sample sequence of each vertex of the bake: zsobol (default), Owen-scrambled Sobol'
    /// points of its own, or independent.
    #[arg(long, value_parser = ember_cli::bench::parse_sampler, default_value = "zsobol")]
    bake_sampler: ember_kernel::sampler::SamplerKind,
}

/// More worker threads than this is a typo, not a machine.
const MAX_THREADS: usize = 4096;

fn bad(scene: &Path, msg: impl Into<String>) -> ViewerError {
    ViewerError::Input(Error::in_file(scene, msg))
}

fn run(a: &Cli) -> Result<(), ViewerError> {
    // Command-line values are checked before any work.
    if a.samples_per_vertex == Some(0) {
        return Err(bad(&a.scene, "--samples-per-vertex 0: must be at least 1"));
    }
    if a.spp == Some(0) {
        return Err(bad(&a.scene, "--spp 0: must be at least 1"));
    }
    for (flag, v) in [("--width", a.width), ("--height", a.height)] {
        if let Some(v) = v.filter(|&v| v == 0 || v > MAX_FILM_SIDE) {
            return Err(bad(
                &a.scene,
                format!("{flag} {v} is out of range 1..={MAX_FILM_SIDE}"),
            ));
        }
    }
    if a.threads > MAX_THREADS {
        return Err(bad(
            &a.scene,
            format!("--threads {} is more than {MAX_THREADS}", a.threads),
        ));
    }
    if !a.exposure.is_finite() || a.exposure.abs() > 64.0 {
        return Err(bad(
            &a.scene,
            format!(
                "--exposure {} must be a number of stops in -64..=64",
                a.exposure
            ),
        ));
    }
    if a.headless {
        // The headless frame is the bake's; the path-traced view is the window's.
        for (given, flag) in [
            (a.spp.is_some(), "--spp"),
            (a.integrator.is_some(), "--integrator"),
            (a.exposure != 0.0, "--exposure"),
        ] {
            if given {
                return Err(bad(
                    &a.scene,
                    format!(
                        "{flag} applies to the path-traced window view, not to --headless (which draws the bake; `ember render` path-traces offline)"
                    ),
                ));
            }
        }
    }
    let outputs = if a.headless {
        Some(output_paths(a)?)
    } else {
        if let Some(o) = &a.output {
            check_output(o)?;
        }
        None
    };

    let scene = LoadedScene::load(&a.scene)?;
    for w in &scene.data.warnings {
        eprintln!("warning: {}: {w}", scene.file.objfile.display());
    }
    let width = a.width.unwrap_or(scene.file.width);
    let height = a.height.unwrap_or(scene.file.height);
    let name = a.scene.file_name().map_or_else(
        || a.scene.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    );
    let no_shortcuts = |mut p: ember_kernel::integrator::PathSettings| {
        if a.no_shortcuts {
            p.shortcuts = Shortcuts::NONE;
        }
        p
    };
    let RendererDesc::Gi { path, .. } = scene.file.renderer else {
        // An offline scene: the path-traced view only.
        if a.headless {
            return Err(bad(
                &a.scene,
                "not a real-time \"gi\" scene (realtime = true, type = \"gi\"): --headless draws \
                 baked global illumination; render offline scenes with `ember render`, or open \
                 them in a window without --headless",
            ));
        }
        for (given, flag) in [
            (a.samples_per_vertex.is_some(), "--samples-per-vertex"),
            (a.bake.is_some(), "--bake"),
        ] {
            if given {
                return Err(bad(
                    &a.scene,
                    format!("{flag} applies to real-time \"gi\" scenes only; this is a path-traced scene"),
                ));
            }
        }
        let (integrator, path, spp) = scene.path_settings()?;
        let camera = scene.file.camera.clone();
        let trace = trace_options(
            a,
            Arc::new(scene),
            width,
            height,
            no_shortcuts(path),
            spp,
            integrator,
        );
        return window::run(
            None,
            &camera,
            window_options(a, name, width, height, Some(trace)),
        );
    };
    let (gi_path, samples_by_vertex) = scene.gi_settings();
    let settings = BakeSettings {
        path: no_shortcuts(gi_path),
        samples_per_vertex: a.samples_per_vertex.unwrap_or(samples_by_vertex),
        seed: a.seed,
        threads: a.threads,
        progress: !a.quiet,
        vertex_inset: a.vertex_inset,
        estimator: a.bake_estimator,
        sampler: a.bake_sampler,
    };
    // The default bake file sits beside the scene. A folder marked read-only (the shared
    // TinyRender data) is respected even by root, who could write there: the bake is then
    // made in memory only.
    let default_read_only = a.bake.is_none()
        && a.scene
            .parent()
            .map(|d| {
                if d.as_os_str().is_empty() {
                    Path::new(".")
                } else {
                    d
                }
            })
            .and_then(|d| std::fs::metadata(d).ok())
            .is_some_and(|m| m.permissions().readonly());
    let bake_path = a
        .bake
        .clone()
        .unwrap_or_else(|| default_bake_path(&a.scene));
    if !a.quiet {
        eprintln!(
            "ember-view: {} triangles, {} vertices; bake: {} paths/vertex, maxDepth {}, rrDepth {}, rrProb {}",
            scene.data.triangles.len(),
            scene.data.positions.len(),
            settings.samples_per_vertex,
            path.max_depth,
            path.rr_depth,
            path.rr_prob
        );
    }
    let modified = |p: &Path| std::fs::metadata(p).and_then(|m| m.modified()).ok();
    let before = modified(&bake_path);
    let (mesh, report) = if default_read_only {
        let (mesh, report) = bake(&scene, &settings)?;
        (mesh, Some(report))
    } else {
        load_or_bake(&scene, &bake_path, &settings)?
    };
    match report {
        Some(r) => {
            let after = modified(&bake_path);
            let stored = !default_read_only && after.is_some() && after != before;
            eprintln!(
                "ember-view: baked {} face corners as {} unique vertices in {:.2} s: {} paths traced, {} saved; {}",
                r.face_corners,
                r.unique_keys,
                r.seconds,
                r.paths_traced,
                r.paths_saved,
                if stored {
                    format!("stored at {}", bake_path.display())
                } else if default_read_only {
                    format!(
                        "not stored: {} is read-only (--bake PATH keeps it)",
                        bake_path.parent().unwrap_or(Path::new(".")).display()
                    )
                } else {
                    "not stored".to_string()
                }
            );
        }
        None => eprintln!("ember-view: reusing the bake at {}", bake_path.display()),
    }

    let camera = scene.file.camera.clone();
    let Some((exr, png)) = outputs else {
        // The path-traced view of a gi scene: its gi path settings, MIS unless told otherwise.
        let trace = trace_options(
            a,
            Arc::new(scene),
            width,
            height,
            settings.path,
            GI_TRACE_SPP,
            Integrator::PathMis,
        );
        return window::run(
            Some(mesh),
            &camera,
            window_options(a, name, width, height, Some(trace)),
        );
    };

    let gpu = HeadlessGpu::new()?;
    eprintln!(
        "ember-view: adapter {} (set up in {:.0} ms)",
        gpu::describe(&gpu.info()),
        gpu.setup_ms
    );
    let frame = gpu.render(&mesh, &camera, width, height, a.false_colour)?;
    if a.false_colour && !a.quiet {
        let [lo, hi] = gpu::false_colour_range(&mesh);
        eprintln!(
            "ember-view: false colour: luminance {:.3e} (blue) to {:.3e} (red), log scale",
            10f32.powf(lo),
            10f32.powf(hi)
        );
    }
    write_exr(&exr, &frame.image)?;
    if let Err(e) = write_png_srgb8(&png, width, height, &frame.srgb8) {
        // Leave no half of the output behind.
        let _ = std::fs::remove_file(&exr);
        return Err(e.into());
    }
    let mean = frame.image.mean();
    eprintln!(
        "ember-view: {width}x{height} frame in {:.2} ms (submit to read-back mapped; upload and pipeline {:.1} ms), mean RGB ({:.5}, {:.5}, {:.5})",
        frame.info.frame_ms, frame.info.upload_ms, mean.x, mean.y, mean.z
    );
    eprintln!("ember-view: wrote {} and {}", exr.display(), png.display());
    Ok(())
}

/// The path-traced view of `scene`: `default_spp` and `default_integrator` unless the command
/// line says otherwise.
fn trace_options(
    a: &Cli,
    scene: Arc<LoadedScene>,
    width: u32,
    height: u32,
    path: ember_kernel::integrator::PathSettings,
    default_spp: u32,
    default_integrator: Integrator,
) -> TraceOptions {
    TraceOptions {
        setup: TraceSetup {
            scene,
            width,
            height,
            path,
            seed: a.seed,
            sampler: a.sampler,
            threads: a.threads,
            tile: TRACE_TILE,
            target_spp: a.spp.unwrap_or(default_spp),
        },
        integrator: a.integrator.map_or(default_integrator, Integrator::from),
        output: a.output.clone(),
        scene_path: a.scene.clone(),
        exposure_stops: a.exposure,
    }
}

fn window_options(
    a: &Cli,
    name: String,
    width: u32,
    height: u32,
    trace: Option<TraceOptions>,
) -> window::WindowOptions {
    window::WindowOptions {
        name,
        width,
        height,
        false_colour: a.false_colour,
        trace,
        quiet: a.quiet,
    }
}

/// Tile side of the path-traced view: small, so that a camera move abandons the pass in
/// flight within a fraction of a millisecond of work per thread.
const TRACE_TILE: u32 = 16;

/// An output EXR must not be a PNG, and its folder must exist.
fn check_output(exr: &Path) -> Result<(), ViewerError> {
    if exr.with_extension("png") == exr {
        return Err(bad(
            exr,
            "the output must be the EXR (a .png preview is written beside it); use -o NAME.exr",
        ));
    }
    let dir = exr
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    if !dir.is_dir() {
        return Err(bad(
            exr,
            format!("output directory {} does not exist", dir.display()),
        ));
    }
    Ok(())
}

/// The EXR (given, or `<scene stem>.exr` beside the TOML) and the PNG beside it; the folder must
/// exist.
fn output_paths(a: &Cli) -> Result<(PathBuf, PathBuf), ViewerError> {
    let exr = a
        .output
        .clone()
        .unwrap_or_else(|| a.scene.with_extension("exr"));
    check_output(&exr)?;
    let png = exr.with_extension("png");
    Ok((exr, png))
}

/// Writes the GPU's 8-bit sRGB bytes as they are (RGB, row 0 at the top), atomically.
fn write_png_srgb8(path: &Path, width: u32, height: u32, rgb: &[u8]) -> ember_cli::Result<()> {
    let err = |e: &dyn std::fmt::Display| Error::in_file(path, format!("cannot write PNG: {e}"));
    ember_cli::image::write_atomically(path, |tmp| {
        let file = std::fs::File::create(tmp).map_err(|e| err(&e))?;
        let mut enc = png::Encoder::new(std::io::BufWriter::new(&file), width, height);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        enc.set_source_srgb(png::SrgbRenderingIntent::Perceptual);
        let mut w = enc.write_header().map_err(|e| err(&e))?;
        w.write_image_data(rgb).map_err(|e| err(&e))?;
        w.finish().map_err(|e| err(&e))?;
        file.sync_all().map_err(|e| err(&e))
    })
}

fn main() -> ExitCode {
    // Mesa's Vulkan device-selection layer connects to Wayland to order the devices and, with
    // no session (XDG_RUNTIME_DIR unset: ssh, CI, containers), prints "error: XDG_RUNTIME_DIR
    // is invalid" although nothing fails. wgpu chooses the adapter itself, so the layer is
    // turned off there. (Set before any thread starts.)
    if std::env::var_os("XDG_RUNTIME_DIR").is_none()
        && std::env::var_os("NODEVICE_SELECT").is_none()
    {
        std::env::set_var("NODEVICE_SELECT", "1");
    }
    let cli = Cli::parse();
    match run(&cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(e.exit_code())
        }
    }
}
