//! `ember`: renders TinyRender scenes.

use clap::{Parser, Subcommand};
use ember_cli::image::{write_exr, write_png};
use ember_cli::render::{render, RenderSettings};
use ember_cli::scene_file::{RendererDesc, MAX_FILM_SIDE};
use ember_cli::{Error, LoadedScene, Result};
use ember_kernel::sampler::DEFAULT_SEED;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

#[derive(Parser)]
#[command(
    name = "ember",
    version,
    about = "ember: a physically based renderer for TinyRender scenes"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render a scene to a linear EXR and an sRGB PNG preview beside it.
    Render(RenderArgs),
}

#[derive(clap::Args)]
struct RenderArgs {
    /// TinyRender scene file (.toml).
    scene: PathBuf,
    /// Output EXR (default: next to the TOML with the same stem, as TinyRender does).
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Samples per pixel (default: the scene's `spp`).
    #[arg(long)]
    spp: Option<u32>,
    /// Seed of the sampler; the same seed gives the same image bit for bit.
    #[arg(long, default_value_t = DEFAULT_SEED)]
    seed: u64,
    /// Worker threads (default: one per core). Does not change the image.
    #[arg(long, default_value_t = 0)]
    threads: usize,
    /// Film width in pixels (default: the scene's).
    #[arg(long)]
    width: Option<u32>,
    /// Film height in pixels (default: the scene's).
    #[arg(long)]
    height: Option<u32>,
    /// Tile side in pixels. Does not change the image.
    #[arg(long, default_value_t = 16)]
    tile: u32,
    /// No progress bar.
    #[arg(short, long)]
    quiet: bool,
}

/// More worker threads than this is a typo, not a machine.
const MAX_THREADS: usize = 4096;

fn run_render(a: &RenderArgs) -> Result<()> {
    // Command-line values are checked before any work; errors name the scene being rendered.
    if a.spp == Some(0) {
        return Err(Error::in_file(&a.scene, "--spp 0: must be at least 1"));
    }
    for (flag, v) in [("--width", a.width), ("--height", a.height)] {
        if let Some(v) = v.filter(|&v| v == 0 || v > MAX_FILM_SIDE) {
            return Err(Error::in_file(
                &a.scene,
                format!("{flag} {v} is out of range 1..={MAX_FILM_SIDE}"),
            ));
        }
    }
    if a.threads > MAX_THREADS {
        return Err(Error::in_file(
            &a.scene,
            format!("--threads {} is more than {MAX_THREADS}", a.threads),
        ));
    }
    let scene = LoadedScene::load(&a.scene)?;
    for w in &scene.data.warnings {
        eprintln!("warning: {}: {w}", scene.file.objfile.display());
    }
    if let RendererDesc::Gi { .. } = scene.file.renderer {
        return Err(Error::in_file(
            &a.scene,
            "real-time \"gi\" scenes are drawn by ember-view (baked GI viewer), which is not built yet",
        ));
    }
    let (integrator, path, scene_spp) = scene.path_settings()?;
    let spp = a.spp.unwrap_or(scene_spp);
    let width = a.width.unwrap_or(scene.file.width);
    let height = a.height.unwrap_or(scene.file.height);
    let out = a
        .output
        .clone()
        .unwrap_or_else(|| a.scene.with_extension("exr"));
    let png = out.with_extension("png");
    if png == out {
        return Err(Error::in_file(
            &out,
            "the output must be the EXR (a .png preview is written beside it); use -o NAME.exr",
        ));
    }
    let out_dir = out
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    if !out_dir.is_dir() {
        return Err(Error::in_file(
            &out,
            format!("output directory {} does not exist", out_dir.display()),
        ));
    }
    let camera = scene.camera(width, height);
    let settings = RenderSettings {
        integrator,
        path,
        spp,
        seed: a.seed,
        tile: a.tile.max(1),
        threads: a.threads,
        progress: !a.quiet,
    };
    let view = scene.data.view();
    if !a.quiet {
        eprintln!(
            "ember: {} triangles ({} BVH nodes in {:.1} ms, {:.0} bytes/triangle), {} emitters, {width}x{height}, {spp} spp, {integrator:?}, maxDepth {}",
            scene.data.triangles.len(),
            scene.data.bvh_nodes.len(),
            scene.data.bvh_build_seconds * 1e3,
            scene.data.kernel_bytes() as f64 / scene.data.triangles.len() as f64,
            scene.data.emitter_count,
            path.max_depth
        );
    }
    let r = render(&view, &camera, &settings);
    write_exr(&out, &r.image)?;
    if let Err(e) = write_png(&png, &r.image) {
        // Leave no half of the output behind.
        let _ = std::fs::remove_file(&out);
        return Err(e);
    }
    let samples = u64::from(width) * u64::from(height) * u64::from(spp);
    let mean = r.image.mean();
    eprintln!(
        "ember: {:.2} s, {:.2} M samples/s, mean RGB ({:.5}, {:.5}, {:.5}), {} invalid samples",
        r.seconds,
        samples as f64 / r.seconds / 1e6,
        mean.x,
        mean.y,
        mean.z,
        r.invalid_samples
    );
    eprintln!("ember: wrote {} and {}", out.display(), png.display());
    Ok(())
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match &cli.command {
        Command::Render(a) => run_render(a),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(2)
        }
    }
}
