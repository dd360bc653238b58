//! `ember bench`: run time against error. Renders a scene at a ladder of sample counts
//! (1, 2, 4, … spp) with each chosen integrator, times each rung and measures its error against
//! a reference image, then writes `bench.csv` and a log-log plot `bench.svg` of relative MSE
//! against wall time, one curve per integrator.
//!
//! - Every rung is a separate render with its own seed ([`rung_seed`]), so the rungs are
//!   independent estimates; the ladder stops after the first rung whose wall time exceeds the
//!   budget, or at the largest power of two not above `--max-spp`.
//! - Errors are [`crate::compare::compare`]'s: RMSE, relative MSE (`(a−b)²/(b²+0.01)`) and mean
//!   bias against the reference. The reference must be an independent render (another seed,
//!   many more samples); a rung identical to it is refused, since it would measure nothing.
//! - Rays per second count every ray the integrators trace (camera, continuation and shadow
//!   rays; `PixelStats::rays`) over the rung's wall time.
//! - Wall time is that of the whole render call (thread pool, tiles, image assembly), as
//!   `ember render` spends it; one untimed 1-spp render warms caches and the allocator first.

use crate::compare::compare;
use crate::error::{Error, Result};
use crate::image::{read_exr, write_atomically, Image};
use crate::render::{render, RenderSettings, Shard};
use crate::scene_file::MAX_FILM_SIDE;
use crate::LoadedScene;
use ember_kernel::integrator::{Integrator, PathSettings};
use ember_kernel::sampler::{mix64, SamplerKind, DEFAULT_SEED};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Columns of `bench.csv`, in order.
pub const CSV_COLUMNS: [&str; 9] = [
    "scene",
    "integrator",
    "spp",
    "seconds",
    "samples_per_second",
    "rays_per_second",
    "rmse",
    "rel_mse",
    "bias",
];

/// The name of an integrator in the CSV, the plot and on the command line.
#[must_use]
pub fn integrator_name(i: Integrator) -> &'static str {
    match i {
        Integrator::PathImplicit => "implicit",
        Integrator::PathExplicit => "explicit",
        Integrator::PathMis => "mis",
        Integrator::LightTracing => "lighttracer",
        Integrator::Bdpt(ember_kernel::integrator::MisHeuristic::Power) => "bdpt",
        Integrator::Bdpt(ember_kernel::integrator::MisHeuristic::Balance) => "bdpt-balance",
    }
}

/// The integrator names of the command line and the scene file's `type`, with
/// [`integrator_name`] their inverse.
pub const INTEGRATOR_NAMES: &str = "implicit, explicit, mis, lighttracer, bdpt or bdpt-balance";

/// Parses an integrator name ([`INTEGRATOR_NAMES`]).
///
/// # Errors
/// For any other name.
pub fn parse_integrator(s: &str) -> std::result::Result<Integrator, String> {
    use ember_kernel::integrator::MisHeuristic;
    match s.trim() {
        "implicit" => Ok(Integrator::PathImplicit),
        "explicit" => Ok(Integrator::PathExplicit),
        "mis" => Ok(Integrator::PathMis),
        "lighttracer" => Ok(Integrator::LightTracing),
        "bdpt" => Ok(Integrator::Bdpt(MisHeuristic::Power)),
        "bdpt-balance" => Ok(Integrator::Bdpt(MisHeuristic::Balance)),
        other => Err(format!(
            "{other:?} is not an integrator ({INTEGRATOR_NAMES})"
        )),
    }
}

/// Parses a sampler name (`independent` or `zsobol`).
///
/// # Errors
/// For any other name.
pub fn parse_sampler(s: &str) -> std::result::Result<SamplerKind, String> {
    match s.trim() {
        "independent" => Ok(SamplerKind::Independent),
        "zsobol" => Ok(SamplerKind::ZSobol),
        other => Err(format!(
            "{other:?} is not a sampler (independent or zsobol)"
        )),
    }
}

/// The command-line name of a sampler ([`parse_sampler`]'s inverse).
#[must_use]
pub const fn sampler_name(s: SamplerKind) -> &'static str {
    match s {
        SamplerKind::Independent => "independent",
        SamplerKind::ZSobol => "zsobol",
    }
}

/// Seed of rung `rung` (0 for 1 spp, 1 for 2 spp, …): a hash of the base seed and the rung, so
/// the rungs are independent of each other and of a reference rendered with any small or
/// default seed.
#[must_use]
pub fn rung_seed(base: u64, rung: u32) -> u64 {
    mix64(base ^ mix64(0x62_65_6E_63_68 ^ u64::from(rung)))
}

/// What to measure.
#[derive(Clone, Debug)]
pub struct BenchSettings {
    pub integrators: Vec<Integrator>,
    pub path: PathSettings,
    pub width: u32,
    pub height: u32,
    /// Stop after the first rung slower than this (wall seconds).
    pub budget_seconds: f64,
    /// Largest sample count of the ladder (rounded down to a power of two).
    pub max_spp: u32,
    /// Worker threads; 0 = one per core.
    pub threads: usize,
    pub tile: u32,
    /// Base seed; rung `k` renders with [`rung_seed`]`(seed, k)`.
    pub seed: u64,
    /// The sampler of every integrator; `None`: each integrator's
    /// [`Integrator::default_sampler`].
    pub sampler: Option<SamplerKind>,
}

/// One measured rung.
#[derive(Clone, Debug, PartialEq)]
pub struct BenchRow {
    pub scene: String,
    pub integrator: String,
    pub spp: u32,
    pub seconds: f64,
    pub samples_per_second: f64,
    pub rays_per_second: f64,
    pub rmse: f64,
    pub rel_mse: f64,
    pub bias: f64,
}

impl BenchRow {
    /// The row as a CSV line (no newline), in [`CSV_COLUMNS`] order.
    #[must_use]
    pub fn csv_line(&self) -> String {
        format!(
            "{},{},{},{:.6},{:.1},{:.1},{:.6e},{:.6e},{:.6e}",
            self.scene,
            self.integrator,
            self.spp,
            self.seconds,
            self.samples_per_second,
            self.rays_per_second,
            self.rmse,
            self.rel_mse,
            self.bias
        )
    }
}

/// Runs the ladder for every integrator and calls `on_row` as each rung is measured.
///
/// # Errors
/// When the reference's size differs from the film, or a rung reproduces the reference exactly
/// (the reference was rendered with a rung's seed and settings, so it measures nothing).
pub fn run_bench(
    scene: &LoadedScene,
    scene_name: &str,
    reference: &Image,
    s: &BenchSettings,
    mut on_row: impl FnMut(&BenchRow),
) -> Result<Vec<BenchRow>> {
    if (reference.width, reference.height) != (s.width, s.height) {
        return Err(Error::new(format!(
            "the reference is {}x{} but the bench renders {}x{}",
            reference.width, reference.height, s.width, s.height
        )));
    }
    let camera = scene.camera(s.width, s.height);
    let view = scene.data.view();
    let settings = |integrator, spp, seed| RenderSettings {
        integrator,
        path: s.path,
        spp,
        seed,
        sampler: s
            .sampler
            .unwrap_or_else(|| Integrator::default_sampler(integrator)),
        tile: s.tile.max(1),
        threads: s.threads,
        progress: false,
        shard: Shard::WHOLE,
        strategies: None,
    };
    // Warm-up: page in the scene, start the allocator's arenas; not measured.
    if let Some(&first) = s.integrators.first() {
        let _ = render(&view, &camera, &settings(first, 1, !s.seed));
    }
    let max_spp = s.max_spp.max(1);
    let pixels = f64::from(s.width) * f64::from(s.height);
    let mut rows = Vec::new();
    for &integrator in &s.integrators {
        let mut spp = 1u32;
        let mut rung = 0u32;
        loop {
            let start = Instant::now();
            let r = render(
                &view,
                &camera,
                &settings(integrator, spp, rung_seed(s.seed, rung)),
            );
            let seconds = start.elapsed().as_secs_f64().max(1e-9);
            let m = compare(&r.image, reference)?;
            if m.rmse == 0.0 {
                return Err(Error::new(format!(
                    "{} at {spp} spp is identical to the reference: render the reference with another seed",
                    integrator_name(integrator)
                )));
            }
            let row = BenchRow {
                scene: scene_name.to_string(),
                integrator: integrator_name(integrator).to_string(),
                spp,
                seconds,
                samples_per_second: pixels * f64::from(spp) / seconds,
                rays_per_second: r.rays as f64 / seconds,
                rmse: m.rmse,
                rel_mse: m.rel_mse,
                bias: m.mean_bias,
            };
            on_row(&row);
            rows.push(row);
            if seconds > s.budget_seconds || spp > max_spp / 2 {
                break;
            }
            spp *= 2;
            rung += 1;
        }
    }
    Ok(rows)
}

/// The CSV text: a header of [`CSV_COLUMNS`] and one line per row.
#[must_use]
pub fn csv_text(rows: &[BenchRow]) -> String {
    let mut out = CSV_COLUMNS.join(",");
    out.push('\n');
    for r in rows {
        out.push_str(&r.csv_line());
        out.push('\n');
    }
    out
}

/// Writes `rows` as CSV (atomically).
///
/// # Errors
/// When the file cannot be written.
pub fn write_csv(path: &Path, rows: &[BenchRow]) -> Result<()> {
    let text = csv_text(rows);
    write_atomically(path, |tmp| {
        std::fs::write(tmp, &text).map_err(|e| Error::in_file(path, format!("cannot write: {e}")))
    })
}

/// One curve of the plot: a label and (seconds, relative MSE) points in ladder order.
#[derive(Clone, Debug, PartialEq)]
pub struct Series {
    pub label: String,
    pub points: Vec<(f64, f64)>,
}

/// Groups rows by integrator, in order of first appearance, as plot series.
#[must_use]
pub fn series_of(rows: &[BenchRow]) -> Vec<Series> {
    let mut out: Vec<Series> = Vec::new();
    for r in rows {
        let point = (r.seconds, r.rel_mse);
        match out.iter_mut().find(|s| s.label == r.integrator) {
            Some(s) => s.points.push(point),
            None => out.push(Series {
                label: r.integrator.clone(),
                points: vec![point],
            }),
        }
    }
    out
}

/// Reads series from a CSV with (at least) the columns `integrator`, `seconds` and `rel_mse`,
/// e.g. another `bench.csv` or `bench/mitsuba/results.csv`; rows with a non-finite or
/// non-positive time or error are skipped.
///
/// # Errors
/// When the file cannot be read or lacks one of those columns.
pub fn read_series_csv(path: &Path) -> Result<Vec<Series>> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| Error::in_file(path, format!("cannot read: {e}")))?;
    let mut lines = text.lines().filter(|l| !l.trim().is_empty());
    let header: Vec<&str> = lines
        .next()
        .ok_or_else(|| Error::in_file(path, "empty CSV"))?
        .split(',')
        .map(str::trim)
        .collect();
    let col = |name: &str| {
        header
            .iter()
            .position(|h| *h == name)
            .ok_or_else(|| Error::in_file(path, format!("no column {name:?}")))
    };
    let (ci, cs, ce) = (col("integrator")?, col("seconds")?, col("rel_mse")?);
    let mut out: Vec<Series> = Vec::new();
    for line in lines {
        let f: Vec<&str> = line.split(',').map(str::trim).collect();
        let get = |i: usize| f.get(i).and_then(|v| v.parse::<f64>().ok());
        let (Some(label), Some(t), Some(e)) = (f.get(ci), get(cs), get(ce)) else {
            continue;
        };
        if !(t.is_finite() && e.is_finite() && t > 0.0 && e > 0.0) {
            continue;
        }
        match out.iter_mut().find(|s| s.label == *label) {
            Some(s) => s.points.push((t, e)),
            None => out.push(Series {
                label: (*label).to_string(),
                points: vec![(t, e)],
            }),
        }
    }
    Ok(out)
}

/// Writes a log-log SVG of relative MSE against wall time, one curve (line and markers) per
/// series, with axis labels and a legend. Text is written as SVG `<text>` elements (no font
/// files are read; the viewer picks a sans-serif font).
///
/// # Errors
/// When there is nothing to plot or the file cannot be written.
pub fn write_svg(path: &Path, title: &str, series: &[Series]) -> Result<()> {
    use plotters::prelude::*;
    let points = || series.iter().flat_map(|s| s.points.iter().copied());
    let positive = |v: f64| v.is_finite() && v > 0.0;
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for (x, y) in points().filter(|&(x, y)| positive(x) && positive(y)) {
        (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
    }
    if x0 > x1 {
        return Err(Error::in_file(path, "nothing to plot"));
    }
    // Whole decades around the data (and a hair beyond, so the end decades get their labels).
    let decade_below = |v: f64| 10f64.powf(v.log10().floor()) * 0.999;
    let decade_above = |v: f64| 10f64.powf((v.log10() + 1e-9).ceil()) * 1.001;
    let (x0, x1) = (decade_below(x0), decade_above(x1 * 1.05));
    let (y0, y1) = (decade_below(y0), decade_above(y1 * 1.05));
    const COLOURS: [RGBColor; 8] = [
        RGBColor(0x1f, 0x77, 0xb4),
        RGBColor(0xd6, 0x27, 0x28),
        RGBColor(0x2c, 0xa0, 0x2c),
        RGBColor(0xff, 0x7f, 0x0e),
        RGBColor(0x94, 0x67, 0xbd),
        RGBColor(0x8c, 0x56, 0x4b),
        RGBColor(0xe3, 0x77, 0xc2),
        RGBColor(0x17, 0xbe, 0xcf),
    ];
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (900, 620)).into_drawing_area();
        let draw = |e: &dyn std::fmt::Display| Error::in_file(path, format!("cannot plot: {e}"));
        root.fill(&WHITE).map_err(|e| draw(&e))?;
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 20))
            .margin(16)
            .x_label_area_size(48)
            .y_label_area_size(80)
            .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())
            .map_err(|e| draw(&e))?;
        chart
            .configure_mesh()
            .x_desc("wall time (s)")
            .y_desc("relative MSE")
            .x_label_formatter(&|v| format!("{v:.0e}"))
            .y_label_formatter(&|v| format!("{v:.0e}"))
            .label_style(("sans-serif", 14))
            .axis_desc_style(("sans-serif", 16))
            .draw()
            .map_err(|e| draw(&e))?;
        for (i, s) in series.iter().enumerate() {
            let colour = COLOURS[i % COLOURS.len()];
            let pts: Vec<(f64, f64)> = s
                .points
                .iter()
                .copied()
                .filter(|&(x, y)| positive(x) && positive(y))
                .collect();
            chart
                .draw_series(LineSeries::new(pts.clone(), colour.stroke_width(2)))
                .map_err(|e| draw(&e))?
                .label(s.label.as_str())
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 24, y)], colour.stroke_width(2))
                });
            chart
                .draw_series(pts.into_iter().map(|p| Circle::new(p, 3, colour.filled())))
                .map_err(|e| draw(&e))?;
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .label_font(("sans-serif", 14))
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .draw()
            .map_err(|e| draw(&e))?;
        root.present().map_err(|e| draw(&e))?;
    }
    write_atomically(path, |tmp| {
        std::fs::write(tmp, &svg).map_err(|e| Error::in_file(path, format!("cannot write: {e}")))
    })
}

/// `ember bench` arguments.
#[derive(Clone, Debug, clap::Args)]
pub struct BenchArgs {
    /// TinyRender scene file (.toml) of a path-traced scene; its maxDepth, rrDepth and rrProb
    /// are used.
    pub scene: PathBuf,
    /// Reference image (EXR): an independent long render of the same scene and film size,
    /// e.g. `ember render SCENE --integrator mis --spp 4096 --seed 1 -o ref.exr`.
    #[arg(long)]
    pub reference: PathBuf,
    /// Integrators to measure, comma-separated.
    #[arg(long, value_delimiter = ',', value_parser = parse_integrator, default_value = "explicit,mis,implicit")]
    pub integrators: Vec<Integrator>,
    /// The ladder stops after the first rung whose wall time exceeds this many seconds.
    #[arg(long, default_value_t = 10.0)]
    pub budget: f64,
    /// Largest samples per pixel of the ladder.
    #[arg(long, default_value_t = 65536)]
    pub max_spp: u32,
    /// Worker threads (default: one per core).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Film width (default: the reference's).
    #[arg(long)]
    pub width: Option<u32>,
    /// Film height (default: the reference's).
    #[arg(long)]
    pub height: Option<u32>,
    /// Base seed; rung k renders with a hash of it and k.
    #[arg(long, default_value_t = DEFAULT_SEED)]
    pub seed: u64,
    /// Sample sequence of every integrator: independent, or zsobol (Owen-scrambled Sobol' in
    /// Morton order). Default: each integrator's own, as `ember render`.
    #[arg(long, value_parser = parse_sampler)]
    pub sampler: Option<SamplerKind>,
    /// Tile side in pixels.
    #[arg(long, default_value_t = 16)]
    pub tile: u32,
    /// Also plot the curves of these CSVs (columns integrator, seconds, rel_mse; e.g. another
    /// renderer's results measured against the same reference).
    #[arg(long)]
    pub plot_also: Vec<PathBuf>,
    /// Output directory for bench.csv and bench.svg (created if missing).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Print only the summary, not a line per rung.
    #[arg(short, long)]
    pub quiet: bool,
    /// Run the general kernel code, without the shortcuts the scene allows (the image is
    /// bit-identical; for measuring what they save).
    #[arg(long)]
    pub no_shortcuts: bool,
}

/// Runs `ember bench`.
///
/// # Errors
/// Bad input (scene, reference, arguments) or unwritable output.
pub fn run(a: &BenchArgs) -> Result<()> {
    if !(a.budget.is_finite() && a.budget > 0.0) {
        return Err(Error::in_file(
            &a.scene,
            format!(
                "--budget {}: must be a positive number of seconds",
                a.budget
            ),
        ));
    }
    if a.max_spp == 0 {
        return Err(Error::in_file(&a.scene, "--max-spp 0: must be at least 1"));
    }
    if a.integrators.is_empty() {
        return Err(Error::in_file(&a.scene, "--integrators: none given"));
    }
    let reference = read_exr(&a.reference)?;
    let width = a.width.unwrap_or(reference.width);
    let height = a.height.unwrap_or(reference.height);
    for (flag, v) in [("--width", width), ("--height", height)] {
        if v == 0 || v > MAX_FILM_SIDE {
            return Err(Error::in_file(
                &a.scene,
                format!("{flag} {v} is out of range 1..={MAX_FILM_SIDE}"),
            ));
        }
    }
    if (reference.width, reference.height) != (width, height) {
        return Err(Error::in_file(
            &a.reference,
            format!(
                "the reference is {}x{}, the bench film {width}x{height}: render the reference at the film size",
                reference.width, reference.height
            ),
        ));
    }
    let extra = a
        .plot_also
        .iter()
        .map(|p| read_series_csv(p))
        .collect::<Result<Vec<_>>>()?;
    let scene = LoadedScene::load(&a.scene)?;
    let (_, mut path, _) = scene.path_settings()?;
    if a.no_shortcuts {
        path.shortcuts = ember_kernel::integrator::Shortcuts::NONE;
    }
    std::fs::create_dir_all(&a.output)
        .map_err(|e| Error::in_file(&a.output, format!("cannot create output directory: {e}")))?;
    let name = a
        .scene
        .file_stem()
        .map_or_else(|| "scene".into(), |s| s.to_string_lossy().replace(',', "_"));
    let settings = BenchSettings {
        integrators: a.integrators.clone(),
        path,
        width,
        height,
        budget_seconds: a.budget,
        max_spp: a.max_spp,
        threads: a.threads,
        tile: a.tile,
        seed: a.seed,
        sampler: a.sampler,
    };
    let threads = if a.threads == 0 {
        std::thread::available_parallelism().map_or(1, std::num::NonZero::get)
    } else {
        a.threads
    };
    eprintln!(
        "ember bench: {name}, {width}x{height}, {threads} threads, maxDepth {}, budget {} s per rung, up to {} spp",
        path.max_depth, a.budget, a.max_spp
    );
    eprintln!("ember bench: CPU {}", crate::simd::cpu_summary());
    if !a.quiet {
        eprintln!(
            "{:<9} {:>6} {:>10} {:>12} {:>11} {:>11} {:>11} {:>11}",
            "integr.", "spp", "seconds", "Msamples/s", "Mrays/s", "rmse", "rel_mse", "bias"
        );
    }
    let rows = run_bench(&scene, &name, &reference, &settings, |r| {
        if !a.quiet {
            eprintln!(
                "{:<9} {:>6} {:>10.4} {:>12.3} {:>11.3} {:>11.4e} {:>11.4e} {:>+11.3e}",
                r.integrator,
                r.spp,
                r.seconds,
                r.samples_per_second / 1e6,
                r.rays_per_second / 1e6,
                r.rmse,
                r.rel_mse,
                r.bias
            );
        }
    })?;
    let csv = a.output.join("bench.csv");
    write_csv(&csv, &rows)?;
    let mut series = series_of(&rows);
    if !extra.is_empty() {
        // Beside another renderer's curves, say which are ember's.
        for s in &mut series {
            s.label = format!("ember {}", s.label);
        }
    }
    series.extend(extra.into_iter().flatten());
    let svg = a.output.join("bench.svg");
    let mut title = String::new();
    let _ = write!(
        title,
        "{name} {width}x{height}, {threads} threads: relative MSE vs time"
    );
    write_svg(&svg, &title, &series)?;
    eprintln!("ember bench: wrote {} and {}", csv.display(), svg.display());
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn csv_round_trips_through_the_series_reader() {
        let row = |integrator: &str, spp, seconds, rel_mse| BenchRow {
            scene: "s".into(),
            integrator: integrator.into(),
            spp,
            seconds,
            samples_per_second: 1.0,
            rays_per_second: 2.0,
            rmse: 0.5,
            rel_mse,
            bias: -0.25,
        };
        let rows = vec![
            row("mis", 1, 0.5, 0.1),
            row("mis", 2, 1.0, 0.05),
            row("implicit", 1, 0.25, 0.4),
        ];
        let text = csv_text(&rows);
        assert_eq!(text.lines().next().unwrap(), CSV_COLUMNS.join(","));
        let dir = std::env::temp_dir().join(format!("ember-bench-unit-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("b.csv");
        write_csv(&p, &rows).unwrap();
        let series = read_series_csv(&p).unwrap();
        assert_eq!(series, series_of(&rows));
        assert_eq!(series[0].points, vec![(0.5, 0.1), (1.0, 0.05)]);
        let svg = dir.join("b.svg");
        write_svg(&svg, "test", &series).unwrap();
        let s = std::fs::read_to_string(&svg).unwrap();
        for text in ["relative MSE", "wall time (s)", "mis", "implicit"] {
            assert!(s.contains(text), "{text} missing from the SVG");
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn rung_seeds_differ() {
        let seeds: Vec<u64> = (0..20).map(|k| rung_seed(DEFAULT_SEED, k)).collect();
        for (i, a) in seeds.iter().enumerate() {
            assert!(seeds[i + 1..].iter().all(|b| b != a));
            assert!(*a != DEFAULT_SEED && *a > 1000);
        }
    }
}
