//! `ember`: renders TinyRender scenes.

use clap::{Parser, Subcommand};
use ember_cli::bake::{bake, default_bake_path, write_ply, BakeSettings, BAKE_INSET};
use ember_cli::compare::{compare, write_error_png};
use ember_cli::image::{read_exr, write_exr, write_exr_and_png, write_png};
use ember_cli::render::{render_interruptible, render_memory, RenderSettings, Shard};
use ember_cli::scene_file::{RendererDesc, MAX_FILM_SIDE};
use ember_cli::shard::{merge, read_partial, render_key, write_partial};
use ember_cli::{Error, LoadedScene, Result};
use ember_kernel::integrator::{Integrator, Shortcuts};
use ember_kernel::sampler::DEFAULT_SEED;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};

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
    /// Render a scene to a linear EXR and an sRGB PNG preview beside it. Real-time `gi`
    /// scenes are handed to `ember-view --headless` (installed beside `ember`).
    Render(RenderArgs),
    /// Bake per-vertex global illumination of a scene to a PLY file.
    Bake(BakeArgs),
    /// Error metrics of an image against a reference (RMSE, relative MSE, bias).
    Compare(CompareArgs),
    /// Convert an EXR to an sRGB PNG preview (values clamped to [0, 1]).
    Convert {
        /// Input EXR.
        input: PathBuf,
        /// Output PNG.
        output: PathBuf,
    },
    /// Merge the partial EXRs of `ember render --shard I/N` into one image, bit-identical to
    /// an unsharded render.
    Merge(MergeArgs),
    /// Run time against error: renders at 1, 2, 4, … spp per integrator until a rung exceeds
    /// the time budget, and writes bench.csv and a log-log plot bench.svg of relative MSE
    /// against wall time.
    Bench(ember_cli::bench::BenchArgs),
}

#[derive(clap::Args)]
struct CompareArgs {
    /// The image to judge (EXR).
    image: PathBuf,
    /// The reference (EXR).
    reference: PathBuf,
    /// Also write a false-colour PNG of the per-pixel relative error.
    #[arg(long)]
    error_png: Option<PathBuf>,
}

fn run_compare(a: &CompareArgs) -> Result<()> {
    let img = read_exr(&a.image)?;
    let reference = read_exr(&a.reference)?;
    let m = compare(&img, &reference).map_err(|e| Error::in_file(&a.image, e.message))?;
    println!("image      {}", a.image.display());
    println!("reference  {}", a.reference.display());
    println!(
        "mean       {:.6} {:.6} {:.6}  (reference {:.6} {:.6} {:.6})",
        m.mean.x, m.mean.y, m.mean.z, m.reference_mean.x, m.reference_mean.y, m.reference_mean.z
    );
    println!(
        "bias       {:+.6} ({:+.3}%)",
        m.mean_bias,
        100.0 * m.relative_bias
    );
    println!("rmse       {:.6}", m.rmse);
    println!("rel_mse    {:.6}", m.rel_mse);
    println!("mae        {:.6}", m.mae);
    println!("max_abs    {:.6}", m.max_abs);
    println!("non_finite {}", m.non_finite);
    if let Some(p) = &a.error_png {
        write_error_png(p, &img, &reference)?;
        println!("error map  {}", p.display());
    }
    Ok(())
}

#[derive(clap::Args)]
struct BakeArgs {
    /// TinyRender scene file (.toml); a `gi` scene's settings are used, TinyRender's `gi`
    /// defaults otherwise.
    scene: PathBuf,
    /// Output PLY (default: `<scene stem>.bake.ply` beside the TOML, where ember-view looks).
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Samples per vertex (default: the scene's `samplesByVertex`).
    #[arg(long)]
    samples_per_vertex: Option<u32>,
    /// Seed of the sampler; the same seed gives the same bake bit for bit.
    #[arg(long, default_value_t = DEFAULT_SEED)]
    seed: u64,
    /// Worker threads (default: one per core). Does not change the result.
    #[arg(long, default_value_t = 0)]
    threads: usize,
    /// No progress bar.
    #[arg(short, long)]
    quiet: bool,
    /// Bake each vertex this fraction of the way toward an adjacent triangle's centroid;
    /// 0 bakes the vertex itself, as TinyRender does (see README).
    #[arg(long, default_value_t = BAKE_INSET)]
    vertex_inset: f32,
    /// Path tracer of the bake: `mis` (default; low variance at room edges) or `explicit`
    /// (TinyRender's, next-event estimation only). With `--vertex-inset 0 --bake-estimator
    /// explicit` the bake is TinyRender's.
    #[arg(long, value_parser = ember_cli::bake::parse_estimator, default_value = "mis")]
    bake_estimator: ember_kernel::integrator::BakeEstimator,
    /// Sample sequence of each vertex: zsobol (default), Owen-scrambled Sobol' points of its
    /// own (about a third of independent's error at 300 samples per vertex), or independent.
    #[arg(long, value_parser = ember_cli::bench::parse_sampler, default_value = "zsobol")]
    sampler: ember_kernel::sampler::SamplerKind,
    /// Run the general kernel code, without the shortcuts the scene allows (the image is
    /// bit-identical; for measuring what they save).
    #[arg(long)]
    no_shortcuts: bool,
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
    /// Sample sequence: zsobol, Owen-scrambled Sobol' points with pixels in Morton order, laid
    /// out for the render's spp (stratified within pixels, blue-noise error across them), or
    /// independent. Default: zsobol for explicit and MIS path tracing and BDPT, independent for
    /// implicit path tracing and the light tracer (whose error at equal time ZSobol does not
    /// lower).
    #[arg(long, value_parser = ember_cli::bench::parse_sampler)]
    sampler: Option<ember_kernel::sampler::SamplerKind>,
    /// Worker threads (default: one per core). Does not change the image.
    #[arg(long, default_value_t = 0)]
    threads: usize,
    /// Film width in pixels (default: the scene's).
    #[arg(long)]
    width: Option<u32>,
    /// Film height in pixels (default: the scene's).
    #[arg(long)]
    height: Option<u32>,
    /// Tile side in pixels (default 16). Does not change the image.
    #[arg(long)]
    tile: Option<u32>,
    /// Integrator (default: the scene's `type`, `isExplicit` choosing explicit or implicit for
    /// `path`): implicit, explicit, mis (emitter and BSDF sampling combined by multiple
    /// importance sampling), lighttracer, bdpt (power heuristic) or bdpt-balance.
    #[arg(long, value_parser = ember_cli::bench::parse_integrator)]
    integrator: Option<Integrator>,
    /// No progress bar.
    #[arg(short, long)]
    quiet: bool,
    /// Refuse renders whose image buffers would need more than this many GiB (default 16).
    #[arg(long)]
    max_memory_gib: Option<f64>,
    /// BDPT only: also write one image per connection strategy (s, t) into DIR, unweighted
    /// (`s<s>_t<t>.exr`) and MIS-weighted (`s<s>_t<t>_weighted.exr`), with PNG previews: the
    /// weighted images of one depth sum to the render's image of that depth.
    #[arg(long)]
    strategies: Option<PathBuf>,
    /// Deepest strategies written by --strategies (scattering vertices; each depth d has
    /// d + 2 strategies, and their films take 48 bytes per pixel each).
    #[arg(long, default_value_t = 4, requires = "strategies")]
    strategies_depth: u32,
    /// Render only shard I of N (tiles t with t mod N = I) to a partial EXR with sample counts,
    /// for `ember merge` (default output: `<stem>.shard-I-of-N.exr`).
    #[arg(long, value_parser = parse_shard)]
    shard: Option<Shard>,
    /// Run the general kernel code, without the shortcuts the scene allows (the image is
    /// bit-identical; for measuring what they save).
    #[arg(long)]
    no_shortcuts: bool,
}

fn parse_shard(s: &str) -> std::result::Result<Shard, String> {
    let (i, n) = s
        .split_once('/')
        .ok_or_else(|| format!("{s:?}: expected I/N, e.g. 0/4"))?;
    let index: u32 = i.parse().map_err(|_| format!("{s:?}: I is not a number"))?;
    let count: u32 = n.parse().map_err(|_| format!("{s:?}: N is not a number"))?;
    if count == 0 || index >= count {
        return Err(format!("{s:?}: need 0 <= I < N"));
    }
    Ok(Shard { index, count })
}

#[derive(clap::Args)]
struct MergeArgs {
    /// Partial EXRs written by `ember render --shard I/N`, all N of them.
    parts: Vec<PathBuf>,
    /// The merged EXR (a PNG preview is written beside it).
    #[arg(short, long)]
    output: PathBuf,
}

fn run_merge(a: &MergeArgs) -> Result<()> {
    let parts = a
        .parts
        .iter()
        .map(|p| read_partial(p).map(|part| (p.clone(), part)))
        .collect::<Result<Vec<_>>>()?;
    let image = merge(&parts)?;
    write_exr(&a.output, &image)?;
    let png = a.output.with_extension("png");
    if let Err(e) = write_png(&png, &image) {
        let _ = std::fs::remove_file(&a.output);
        return Err(e);
    }
    eprintln!(
        "ember: merged {} shards into {} and {}",
        parts.len(),
        a.output.display(),
        png.display()
    );
    Ok(())
}

/// Renders asking for more samples than this (width × height × spp) are refused as typos:
/// 10¹³ samples is weeks of work on a workstation.
const MAX_TOTAL_SAMPLES: u64 = 10_000_000_000_000;

/// Set by Ctrl-C; the renderer stops at the next tile and keeps the passes completed.
static INTERRUPTED: AtomicBool = AtomicBool::new(false);

/// More worker threads than this is a typo, not a machine.
const MAX_THREADS: usize = 4096;

/// `--tile` and `--max-memory-gib` when not given.
const DEFAULT_TILE: u32 = 16;
const DEFAULT_MAX_MEMORY_GIB: f64 = 16.0;

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
        return render_with_viewer(a);
    }
    let (integrator, mut path, scene_spp) = scene.path_settings()?;
    if a.no_shortcuts {
        path.shortcuts = Shortcuts::NONE;
    }
    let integrator = a.integrator.unwrap_or(integrator);
    if let Integrator::Bdpt(_) = integrator {
        ember_kernel::integrator::bdpt::check_depth(path.max_depth).map_err(|e| {
            Error::in_file(
                &a.scene,
                format!("[renderer].maxDepth with --integrator bdpt: {e}"),
            )
        })?;
    }
    let spp = a.spp.unwrap_or(scene_spp);
    let width = a.width.unwrap_or(scene.file.width);
    let height = a.height.unwrap_or(scene.file.height);
    let shard = a.shard.unwrap_or(Shard::WHOLE);
    let out = a.output.clone().unwrap_or_else(|| match a.shard {
        Some(s) => a
            .scene
            .with_extension(format!("shard-{}-of-{}.exr", s.index, s.count)),
        None => a.scene.with_extension("exr"),
    });
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
    let samples = u64::from(width) * u64::from(height) * u64::from(spp);
    if samples > MAX_TOTAL_SAMPLES {
        return Err(Error::in_file(
            &a.scene,
            format!(
                "{width}x{height} pixels x {spp} spp = {samples} samples is more than the limit of {MAX_TOTAL_SAMPLES}"
            ),
        ));
    }
    if a.strategies.is_some() && !matches!(integrator, Integrator::Bdpt(_)) {
        return Err(Error::in_file(
            &a.scene,
            format!(
                "--strategies writes the images of BDPT's (s, t) strategies; the integrator is {}",
                ember_cli::bench::integrator_name(integrator)
            ),
        ));
    }
    if let Some(dir) = &a.strategies {
        if !dir.is_dir() {
            return Err(Error::in_file(
                dir,
                "--strategies: the directory does not exist",
            ));
        }
    }
    let settings = RenderSettings {
        integrator,
        path,
        spp,
        seed: a.seed,
        sampler: a.sampler.unwrap_or(integrator.default_sampler()),
        tile: a.tile.unwrap_or(DEFAULT_TILE).max(1),
        threads: a.threads,
        progress: !a.quiet,
        shard,
        strategies: a.strategies.as_ref().map(|_| a.strategies_depth),
    };
    let memory = render_memory(width, height, &settings);
    let max_memory_gib = a.max_memory_gib.unwrap_or(DEFAULT_MAX_MEMORY_GIB);
    if memory as f64 > max_memory_gib * f64::from(1u32 << 30) {
        return Err(Error::in_file(
            &a.scene,
            format!(
                "a {width}x{height} render needs {:.1} GiB of image buffers, more than --max-memory-gib {}",
                memory as f64 / f64::from(1u32 << 30),
                max_memory_gib
            ),
        ));
    }
    let camera = scene.camera(width, height);
    let view = scene.data.view();
    if !a.quiet {
        eprintln!(
            "ember: {} triangles ({} {}-wide BVH nodes in {:.1} ms, {:.0} bytes/triangle), {} emitters, {width}x{height}, {spp} spp, {integrator:?}, maxDepth {}",
            scene.data.triangles.len(),
            scene.data.bvh_nodes.len(),
            ember_kernel::bvh::WIDTH,
            scene.data.bvh_build_seconds * 1e3,
            scene.data.kernel_bytes() as f64 / scene.data.triangles.len() as f64,
            scene.data.emitter_count,
            path.max_depth
        );
    }
    // Ctrl-C stops the render at the next tile; the completed passes are still written. A
    // handler that cannot be installed (e.g. one is already set) only loses that feature.
    let _ = ctrlc::set_handler(|| INTERRUPTED.store(true, Ordering::Relaxed));
    let r = render_interruptible(&view, &camera, &settings, &INTERRUPTED);
    if a.shard.is_some() {
        if r.spp < spp {
            eprintln!("ember: interrupted; a shard is written only when complete");
            std::process::exit(130);
        }
        let key = render_key(&a.scene, width, height, &settings);
        write_partial(&out, &r, &settings, &key)?;
        eprintln!(
            "ember: shard {}/{} in {:.2} s; wrote {}",
            shard.index,
            shard.count,
            r.seconds,
            out.display()
        );
        return Ok(());
    }
    if r.spp < spp {
        if r.spp == 0 {
            eprintln!("ember: interrupted before the first pass finished; nothing written");
            std::process::exit(130);
        }
        // The partial image is named by its sample count, never mistaken for the full render.
        let stem = out.file_stem().unwrap_or_default().to_string_lossy();
        let partial = out.with_file_name(format!("{stem}_partial_{}spp.exr", r.spp));
        write_exr_and_png(&partial, &r.image)?;
        eprintln!(
            "ember: interrupted after {} of {spp} spp; wrote {}",
            r.spp,
            partial.display()
        );
        std::process::exit(130);
    }
    write_exr_and_png(&out, &r.image)?;
    if let (Some(dir), Some(films)) = (&a.strategies, &r.strategies) {
        let mut written = 0;
        for (s, t) in films.strategies() {
            let Some((unweighted, weighted)) = films.images(s, t, r.spp) else {
                continue;
            };
            write_exr_and_png(&dir.join(format!("s{s}_t{t}.exr")), &unweighted)?;
            write_exr_and_png(&dir.join(format!("s{s}_t{t}_weighted.exr")), &weighted)?;
            written += 2;
        }
        eprintln!(
            "ember: wrote {written} strategy images (depth 0 to {}) to {}",
            films.max_depth,
            dir.display()
        );
    }
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

/// Hands a real-time scene to `ember-view --headless`, which sits beside this binary: the
/// GPU stack stays out of `ember` (render nodes and embedders need not link wgpu).
fn render_with_viewer(a: &RenderArgs) -> Result<()> {
    // Options of the offline path tracer that a rasterised frame of the bake has no use for
    // are refused rather than dropped: the user asked for something this render cannot do.
    let not_applicable = [
        (
            a.integrator.is_some(),
            "--integrator",
            "the bake's path tracer is ember-view's --bake-estimator",
        ),
        (
            a.shard.is_some(),
            "--shard",
            "the frame is drawn whole; the bake is not split",
        ),
        (a.tile.is_some(), "--tile", "the frame has no tiles"),
        (
            a.sampler.is_some(),
            "--sampler",
            "the bake draws independent samples",
        ),
        (
            a.max_memory_gib.is_some(),
            "--max-memory-gib",
            "there are no path-tracing image buffers",
        ),
    ];
    if let Some((_, flag, why)) = not_applicable.iter().find(|(given, _, _)| *given) {
        return Err(Error::in_file(
            &a.scene,
            format!(
                "{flag} does not apply to a real-time \"gi\" scene, whose frame is rasterised from its bake ({why})"
            ),
        ));
    }
    let exe = std::env::current_exe()
        .map_err(|e| Error::new(format!("cannot locate the ember binary: {e}")))?;
    let viewer = exe.with_file_name(format!("ember-view{}", std::env::consts::EXE_SUFFIX));
    if !viewer.is_file() {
        return Err(Error::in_file(
            &a.scene,
            format!(
                "real-time \"gi\" scenes are drawn by ember-view, which was not found at {} (build it: cargo build --release -p ember-viewer)",
                viewer.display()
            ),
        ));
    }
    let mut cmd = std::process::Command::new(&viewer);
    cmd.arg(&a.scene).arg("--headless");
    if let Some(o) = &a.output {
        cmd.arg("-o").arg(o);
    }
    if let Some(n) = a.spp {
        cmd.arg("--samples-per-vertex").arg(n.to_string());
    }
    if let Some(w) = a.width {
        cmd.arg("--width").arg(w.to_string());
    }
    if let Some(h) = a.height {
        cmd.arg("--height").arg(h.to_string());
    }
    cmd.arg("--seed").arg(a.seed.to_string());
    cmd.arg("--threads").arg(a.threads.to_string());
    if a.no_shortcuts {
        cmd.arg("--no-shortcuts");
    }
    if a.quiet {
        cmd.arg("-q");
    }
    let status = cmd
        .status()
        .map_err(|e| Error::in_file(&viewer, format!("cannot run: {e}")))?;
    if status.success() {
        Ok(())
    } else {
        // ember-view has printed its own error line.
        std::process::exit(status.code().unwrap_or(1));
    }
}

fn run_bake(a: &BakeArgs) -> Result<()> {
    if a.samples_per_vertex == Some(0) {
        return Err(Error::in_file(
            &a.scene,
            "--samples-per-vertex 0: must be at least 1",
        ));
    }
    if a.threads > MAX_THREADS {
        return Err(Error::in_file(
            &a.scene,
            format!("--threads {} is more than {MAX_THREADS}", a.threads),
        ));
    }
    let scene = LoadedScene::load(&a.scene)?;
    let (mut path, spv) = scene.gi_settings();
    if a.no_shortcuts {
        path.shortcuts = Shortcuts::NONE;
    }
    let settings = BakeSettings {
        path,
        samples_per_vertex: a.samples_per_vertex.unwrap_or(spv),
        seed: a.seed,
        threads: a.threads,
        progress: !a.quiet,
        vertex_inset: a.vertex_inset,
        estimator: a.bake_estimator,
        sampler: a.sampler,
    };
    let out = a
        .output
        .clone()
        .unwrap_or_else(|| default_bake_path(&a.scene));
    let (mesh, r) = bake(&scene, &settings)?;
    write_ply(&out, &mesh)?;
    eprintln!(
        "ember: baked {} vertex keys ({} face corners, {} vertices) x {} samples in {:.2} s, {:.2} M paths/s; deduplication saved {} paths ({:.1}%)",
        r.unique_keys,
        r.face_corners,
        mesh.positions.len(),
        settings.samples_per_vertex,
        r.seconds,
        r.paths_traced as f64 / r.seconds / 1e6,
        r.paths_saved,
        100.0 * r.paths_saved as f64 / (r.paths_saved + r.paths_traced).max(1) as f64
    );
    eprintln!("ember: wrote {}", out.display());
    Ok(())
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    if let Err(e) = ember_cli::simd::apply_env() {
        eprintln!("error: {e}");
        return ExitCode::from(2);
    }
    let result = match &cli.command {
        Command::Render(a) => run_render(a),
        Command::Bake(a) => run_bake(a),
        Command::Compare(a) => run_compare(a),
        Command::Merge(a) => run_merge(a),
        Command::Bench(a) => ember_cli::bench::run(a),
        Command::Convert { input, output } => read_exr(input).and_then(|i| write_png(output, &i)),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(2)
        }
    }
}
