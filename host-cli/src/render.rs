//! Parallel rendering on the host: rayon over tiles, the kernel per pixel, in passes of
//! samples so that a render can be interrupted and still yield an image.

use crate::image::Image;
use crate::splats::{resolve, AtomicSplats, StrategyFilms, StrategySink};
use ember_kernel::camera::Camera;
use ember_kernel::integrator::{
    render_pixel, render_row, BdptScratch, BdptSink, Integrator, PathSettings, PixelStats,
};
use ember_kernel::sampler::{SamplerKind, Sampling};
use ember_kernel::scene::SceneView;
use ember_kernel::Rgb;
use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, Ordering};

/// Everything that determines an image besides the scene and the camera.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderSettings {
    pub integrator: Integrator,
    pub path: PathSettings,
    pub spp: u32,
    pub seed: u64,
    /// The sample sequence (`--sampler`); Sobol' samples are laid out for `spp` samples of
    /// this film, so a render's first `n` samples equal a render of `n` only with the
    /// independent sampler.
    pub sampler: SamplerKind,
    /// Square tile side in pixels; has no effect on the result, only on scheduling.
    pub tile: u32,
    /// Worker threads; 0 means one per core. Has no effect on the result.
    pub threads: usize,
    pub progress: bool,
    /// Render only the tiles of this shard (see [`Shard`]); other pixels stay 0.
    pub shard: Shard,
    /// BDPT only: also accumulate each strategy `(s, t)` up to this depth, unweighted and
    /// weighted (`--strategies`). Does not change the image.
    pub strategies: Option<u32>,
}

impl RenderSettings {
    /// What the samples of a `width × height` film are keyed by.
    #[must_use]
    pub fn sampling(&self, width: u32, height: u32) -> Sampling {
        Sampling::new(self.sampler, self.seed, self.spp, width, height)
    }
}

/// A deterministic part of a render for splitting it across processes or machines: tile `t`
/// (in row-major tile order) belongs to shard `t mod count`. A pixel's own samples are
/// rendered by the shard of its tile, so the shards of a render, merged, are bit-identical to
/// the whole. (Splitting by sample ranges instead would change the order in which each
/// pixel's f32 sums are added, and with it the last bits.) Light tracing and BDPT also splat
/// onto other shards' pixels; those contributions are fixed-point integers, summed over the
/// shards exactly.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    pub index: u32,
    pub count: u32,
}

impl Shard {
    pub const WHOLE: Self = Self { index: 0, count: 1 };

    /// Whether tile number `t` is rendered by this shard.
    #[must_use]
    pub fn owns(&self, t: usize) -> bool {
        t % self.count.max(1) as usize == self.index as usize
    }
}

/// Top-left corners of the `tile × tile` tiles of a `width × height` film, row-major.
#[must_use]
pub fn tiles(width: u32, height: u32, tile: u32) -> Vec<(u32, u32)> {
    let tile = tile.max(1);
    (0..height.div_ceil(tile))
        .flat_map(|ty| (0..width.div_ceil(tile)).map(move |tx| (tx * tile, ty * tile)))
        .collect()
}

/// Which pixels (row-major) a shard renders.
#[must_use]
pub fn shard_coverage(width: u32, height: u32, tile: u32, shard: Shard) -> Vec<bool> {
    let tile = tile.max(1);
    let mut covered = vec![false; width as usize * height as usize];
    for (t, &(x0, y0)) in tiles(width, height, tile).iter().enumerate() {
        if shard.owns(t) {
            for y in y0..(y0 + tile).min(height) {
                for x in x0..(x0 + tile).min(width) {
                    covered[(y * width + x) as usize] = true;
                }
            }
        }
    }
    covered
}

/// A rendered image with its per-pixel variance of the mean and counters.
#[derive(Clone, Debug)]
pub struct Rendered {
    /// Mean radiance per pixel.
    pub image: Image,
    /// Estimated variance of each pixel's mean: the sample variance / spp for the path
    /// tracers; for light tracing and BDPT, whose splats make samples of one pixel
    /// non-independent of other pixels', from the spread of the passes' estimates (batch
    /// means; 0 with a single pass).
    pub variance: Image,
    /// Per-pixel sums of the pixels' own samples (what `image` is resolved from).
    pub sums: Image,
    /// Fixed-point splat sums (light tracing, BDPT), for the whole film.
    pub splats: Option<Vec<[i64; 3]>>,
    /// Per-strategy films of a BDPT render with [`RenderSettings::strategies`].
    pub strategies: Option<std::sync::Arc<StrategyFilms>>,
    /// Samples per pixel actually in the image (fewer than asked if interrupted).
    pub spp: u32,
    /// Samples that were NaN or infinite (counted as 0).
    pub invalid_samples: u64,
    /// Rays traced (camera, continuation and shadow rays).
    pub rays: u64,
    pub seconds: f64,
}

/// Bytes the host allocates per pixel: running sums (`PixelStats`), one pass's results, and the
/// mean, variance and sum images.
pub const BYTES_PER_PIXEL: u64 = 2 * std::mem::size_of::<PixelStats>() as u64 + 3 * 12;

/// Bytes per pixel that splatting integrators add: the splat sums, the pass's atomic splat
/// film and the batch statistics of the variance.
pub const SPLAT_BYTES_PER_PIXEL: u64 = 2 * AtomicSplats::BYTES_PER_PIXEL + 24;

/// Memory a render of `width × height` with `integrator` needs, in bytes (and its strategy
/// films, if asked for).
#[must_use]
pub fn render_memory(width: u32, height: u32, s: &RenderSettings) -> u64 {
    let pixels = u64::from(width) * u64::from(height);
    let mut bytes = pixels * BYTES_PER_PIXEL;
    if s.integrator.splats() {
        bytes += pixels * SPLAT_BYTES_PER_PIXEL;
    }
    if let Some(depth) = s.strategies {
        bytes += StrategyFilms::memory(width, height, depth);
    }
    bytes
}

/// Renders the scene. The result depends only on the scene, camera, integrator settings, spp
/// and seed: every pixel sums its samples in sample order, whatever the tiling, threads or
/// passes.
///
/// # Panics
/// If the rayon thread pool cannot be created.
#[must_use]
pub fn render(scene: &SceneView<'_>, camera: &Camera, s: &RenderSettings) -> Rendered {
    render_interruptible(scene, camera, s, &AtomicBool::new(false))
}

/// Samples per pixel in each pass of `ember render`: about 16 passes, so an interrupt loses at
/// most ~1/16 of the work, and at least 1 sample; and for the integrators that do not splat
/// ([`ember_kernel::integrator::Integrator::splats`]), at least [`MIN_PIXEL_PASS`] (or all of
/// `spp`).
#[must_use]
pub fn pass_size(spp: u32, splats: bool) -> u32 {
    let size = spp.div_ceil(16).max(1);
    if splats {
        size
    } else {
        size.max(MIN_PIXEL_PASS.min(spp))
    }
}

/// The fewest samples per pass of a render whose samples stay in their pixel. A pass is one
/// `render_pixel` call per pixel, and the ZSobol sampler computes the per-pixel part of each
/// dimension's index once per call: at 32 spp in 16 passes of 2, the sampler was 15% of the
/// render's cycles, against 7% at 32 samples per call (TinyRender's Cornell box, MIS). The
/// splatting integrators keep their ~16 passes: their pixel variance is estimated from the
/// spread of the passes (batch means).
pub const MIN_PIXEL_PASS: u32 = 8;

/// Like [`render`], but checks `stop` between tiles: once it is set, the pass in flight is
/// abandoned and the image holds the passes completed so far (`Rendered::spp` says how many
/// samples; 0 if not even one pass finished). This is [`Progressive`] driven pass after pass
/// up to `s.spp`, the same code the interactive view runs.
///
/// # Panics
/// If the rayon thread pool cannot be created.
#[must_use]
pub fn render_interruptible(
    scene: &SceneView<'_>,
    camera: &Camera,
    s: &RenderSettings,
    stop: &AtomicBool,
) -> Rendered {
    let start = std::time::Instant::now();
    let mut progressive = Progressive::new(*camera, s);
    let bar = if s.progress {
        let b = ProgressBar::new(progressive.pixels() * u64::from(s.spp));
        b.set_style(
            ProgressStyle::with_template(
                "{spinner} [{elapsed_precise}] {wide_bar} {percent}% of samples, ETA {eta}",
            )
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        b
    } else {
        ProgressBar::hidden()
    };
    while progressive.spp() < s.spp && !stop.load(Ordering::Relaxed) {
        let count = pass_size(s.spp, s.integrator.splats()).min(s.spp - progressive.spp());
        let completed =
            progressive.render_pass(scene, count, &|| stop.load(Ordering::Relaxed), &|samples| {
                bar.inc(samples)
            });
        if !completed {
            break;
        }
    }
    bar.finish_and_clear();
    let mut r = progressive.snapshot();
    r.seconds = start.elapsed().as_secs_f64();
    r
}

/// A render in progress: per-pixel running sums ([`PixelStats`]) of samples `0..spp` of one
/// camera and settings, extended pass after pass. This is the only place the host calls the
/// kernel's per-pixel entry point: `ember render` ([`render_interruptible`]) and the
/// interactive view of `ember-view` both drive it, so the view's accumulation at N spp is
/// `ember render`'s image at N spp by construction.
///
/// Each pass renders samples `spp..spp + count` of every pixel of the shard, tile by tile on the
/// rayon pool, and adds them in sample order to the pixel's sums (see
/// [`ember_kernel::integrator::render_pixel`]), so any sequence of passes that reaches N spp
/// gives the same bits as one pass of N. A pass that is stopped is dropped whole: every pixel
/// always holds the same number of samples.
#[derive(Debug)]
pub struct Progressive {
    camera: Camera,
    settings: RenderSettings,
    /// Top-left corners of the shard's tiles, row-major.
    tiles: Vec<(u32, u32)>,
    /// Running sums in tile order: `sums[i]` holds tile `i`'s pixels, row-major in the tile.
    sums: Vec<Vec<PixelStats>>,
    spp: u32,
    /// Light tracing and BDPT: the splats of the completed passes and of the pass in flight.
    splats: Option<Splats>,
    /// Wall time of the completed passes since the last (re)start.
    seconds: f64,
    pool: rayon::ThreadPool,
}

/// The splat state of a splatting integrator's accumulation.
#[derive(Debug)]
struct Splats {
    /// Fixed-point sums of the completed passes, per pixel of the film.
    total: Vec<[i64; 3]>,
    /// The pass in flight (added to `total` when it completes, cleared when it is dropped).
    pass: AtomicSplats,
    /// Batch means for the variance: per pixel, Σ over passes of n_p · X_p², where X_p is the
    /// pass's estimate (own samples and splats over its n_p samples); and the pass count.
    batch_sq: Vec<glam::DVec3>,
    passes: u32,
    /// Splats of the completed passes that were refused (not finite or too large).
    invalid: u64,
    strategies: Option<std::sync::Arc<StrategyFilms>>,
}

impl Splats {
    fn new(width: u32, height: u32, s: &RenderSettings) -> Self {
        let n = width as usize * height as usize;
        let strategies = match (s.integrator, s.strategies) {
            (Integrator::Bdpt(_), Some(depth)) => Some(std::sync::Arc::new(StrategyFilms::new(
                width, height, depth,
            ))),
            _ => None,
        };
        Self {
            total: vec![[0; 3]; n],
            pass: AtomicSplats::new(width, height),
            batch_sq: vec![glam::DVec3::ZERO; n],
            passes: 0,
            invalid: 0,
            strategies,
        }
    }
}

/// One tile of one pass: samples `first..first + count` of its pixels, added to `acc`.
struct TileJob<'a, 'b> {
    scene: &'a SceneView<'b>,
    camera: &'a Camera,
    settings: &'a RenderSettings,
    corner: (u32, u32),
    first: u32,
    count: u32,
    acc: &'a [PixelStats],
}

impl TileJob<'_, '_> {
    /// The tile's new sums, pixel by pixel in row-major order; splats go to `sink`.
    fn render<K: BdptSink>(
        &self,
        mut scratch: Option<&mut BdptScratch>,
        sink: &mut K,
    ) -> Vec<PixelStats> {
        let (camera, s) = (self.camera, self.settings);
        let (w, h, tile) = (camera.width, camera.height, s.tile.max(1));
        let sampling = s.sampling(w, h);
        let (x0, y0) = self.corner;
        let row = ((x0 + tile).min(w) - x0) as usize;
        // At 0 spp the sums may hold a previous accumulation (see `Progressive::restart`): the
        // first pass starts from zero.
        let mut out = if self.first == 0 {
            vec![PixelStats::default(); self.acc.len()]
        } else {
            self.acc.to_vec()
        };
        for (y, sums) in (y0..(y0 + tile).min(h)).zip(out.chunks_mut(row)) {
            render_row(
                s.integrator,
                self.scene,
                camera,
                &s.path,
                &sampling,
                (x0, y),
                self.first,
                self.count,
                sums,
                scratch.as_deref_mut(),
                sink,
            );
        }
        out
    }
}

/// Adds one completed pass to the batch statistics of the variance: for every pixel of the
/// film, `n · X²` with `X` the pass's estimate (the pass's own samples, from the difference of
/// the running sums, plus its splats, over its `n` samples).
#[allow(clippy::too_many_arguments)]
fn add_batch(
    batch_sq: &mut [glam::DVec3],
    tiles: &[(u32, u32)],
    before: &[Vec<PixelStats>],
    after: &[Vec<PixelStats>],
    first: u32,
    pass_splats: &[[i64; 3]],
    count: u32,
    (w, h, tile): (u32, u32, u32),
) {
    let n = f64::from(count);
    let mut own = vec![glam::DVec3::ZERO; batch_sq.len()];
    for ((&(x0, y0), b), a) in tiles.iter().zip(before).zip(after) {
        let mut k = 0;
        for y in y0..(y0 + tile).min(h) {
            for x in x0..(x0 + tile).min(w) {
                let prev = if first == 0 { Rgb::ZERO } else { b[k].sum };
                own[(y * w + x) as usize] = (a[k].sum - prev).as_dvec3();
                k += 1;
            }
        }
    }
    for ((b, o), sp) in batch_sq.iter_mut().zip(own).zip(pass_splats) {
        let splat = glam::DVec3::new(
            ember_kernel::splat::from_fixed(sp[0]),
            ember_kernel::splat::from_fixed(sp[1]),
            ember_kernel::splat::from_fixed(sp[2]),
        );
        let x = (o + splat) / n;
        *b += n * x * x;
    }
}

impl Progressive {
    /// An empty accumulation (0 spp) of `camera` (whose size is the film's) with `settings`;
    /// `settings.spp` is not used (the caller decides how many passes of which size), and
    /// `settings.progress` neither.
    ///
    /// # Panics
    /// If the rayon thread pool (`settings.threads`) cannot be created.
    #[must_use]
    pub fn new(camera: Camera, settings: &RenderSettings) -> Self {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(settings.threads)
            .thread_name(|i| format!("ember-render-{i}"))
            .build()
            .expect("cannot create the rayon thread pool");
        let mut p = Self {
            camera,
            settings: *settings,
            tiles: Vec::new(),
            sums: Vec::new(),
            spp: 0,
            splats: None,
            seconds: 0.0,
            pool,
        };
        p.restart(camera, settings);
        p
    }

    /// Drops the accumulation and starts again at 0 spp with another camera or settings (the
    /// thread pool is kept: `settings.threads` is not read again). Cheap when the film, tiles
    /// and shard stay the same (an interactive camera move): the old sums are not cleared,
    /// the next pass starts from zero instead.
    pub fn restart(&mut self, camera: Camera, settings: &RenderSettings) {
        let tile = settings.tile.max(1);
        let (w, h) = (camera.width, camera.height);
        let same_layout = !self.sums.is_empty()
            && (w, h) == (self.camera.width, self.camera.height)
            && tile == self.settings.tile.max(1)
            && settings.shard == self.settings.shard;
        if !same_layout {
            self.tiles = tiles(w, h, tile)
                .into_iter()
                .enumerate()
                .filter(|(t, _)| settings.shard.owns(*t))
                .map(|(_, corner)| corner)
                .collect();
            let tile_pixels =
                |(x0, y0): (u32, u32)| ((x0 + tile).min(w) - x0) * ((y0 + tile).min(h) - y0);
            self.sums = self
                .tiles
                .iter()
                .map(|&t| vec![PixelStats::default(); tile_pixels(t) as usize])
                .collect();
        }
        self.camera = camera;
        self.settings = *settings;
        self.spp = 0;
        self.seconds = 0.0;
        // Splat films are whole-film buffers: made for a splatting integrator, cleared on a
        // restart with the same size, dropped for a path tracer.
        self.splats = if settings.integrator.splats() {
            match self.splats.take() {
                Some(mut sp)
                    if same_layout && sp.strategies.is_none() && settings.strategies.is_none() =>
                {
                    sp.total.iter_mut().for_each(|t| *t = [0; 3]);
                    sp.batch_sq.iter_mut().for_each(|b| *b = glam::DVec3::ZERO);
                    sp.pass.clear();
                    sp.passes = 0;
                    sp.invalid = 0;
                    Some(sp)
                }
                _ => Some(Splats::new(w, h, settings)),
            }
        } else {
            None
        };
    }

    /// Samples per pixel accumulated.
    #[must_use]
    pub fn spp(&self) -> u32 {
        self.spp
    }

    #[must_use]
    pub fn camera(&self) -> &Camera {
        &self.camera
    }

    #[must_use]
    pub fn settings(&self) -> &RenderSettings {
        &self.settings
    }

    /// Pixels this accumulation renders (the shard's).
    #[must_use]
    pub fn pixels(&self) -> u64 {
        self.sums.iter().map(|t| t.len() as u64).sum()
    }

    /// Wall time of the passes completed since the last (re)start, in seconds.
    #[must_use]
    pub fn seconds(&self) -> f64 {
        self.seconds
    }

    /// Renders samples `spp..spp + count` of every pixel and adds them to the sums. `stop` is
    /// checked before each tile: when it returns true the pass is abandoned, the sums stay as
    /// they were, and the result is false. `progress` is told the samples of each finished
    /// tile. The scene must be the one the previous passes rendered.
    pub fn render_pass(
        &mut self,
        scene: &SceneView<'_>,
        count: u32,
        stop: &(dyn Fn() -> bool + Sync),
        progress: &(dyn Fn(u64) + Sync),
    ) -> bool {
        if count == 0 {
            return true;
        }
        let start = std::time::Instant::now();
        let (camera, s, first) = (&self.camera, &self.settings, self.spp);
        let (w, h, tile) = (camera.width, camera.height, s.tile.max(1));
        let tiles = &self.tiles;
        let sums = &self.sums;
        let splats = self.splats.as_ref();
        let bdpt = matches!(s.integrator, Integrator::Bdpt(_));
        let pass: Option<Vec<Vec<PixelStats>>> = self.pool.install(|| {
            tiles
                .par_iter()
                .zip(sums.par_iter())
                .map(|(&(x0, y0), acc)| {
                    if stop() {
                        return None;
                    }
                    // BDPT's subpaths, reused by every sample of the tile.
                    let mut scratch = bdpt.then(Box::<BdptScratch>::default);
                    let job = TileJob {
                        scene,
                        camera,
                        settings: s,
                        corner: (x0, y0),
                        first,
                        count,
                        acc,
                    };
                    let scratch = scratch.as_deref_mut();
                    let out = match splats {
                        None => job.render(scratch, &mut ember_kernel::splat::NoSplats),
                        Some(sp) => match &sp.strategies {
                            None => job.render(scratch, &mut &sp.pass),
                            Some(films) => job.render(
                                scratch,
                                &mut StrategySink {
                                    splats: &sp.pass,
                                    films,
                                },
                            ),
                        },
                    };
                    progress(u64::from(count) * out.len() as u64);
                    Some(out)
                })
                .collect()
        });
        // An interrupted pass is dropped whole, with its splats and refused splats: every
        // pixel keeps the same sample count.
        let Some(pass) = pass else {
            if let Some(sp) = &self.splats {
                sp.pass.clear();
            }
            return false;
        };
        if let Some(sp) = &mut self.splats {
            let pass_splats = sp.pass.snapshot();
            sp.invalid += sp.pass.invalid();
            sp.pass.clear();
            add_batch(
                &mut sp.batch_sq,
                &self.tiles,
                &self.sums,
                &pass,
                first,
                &pass_splats,
                count,
                (w, h, tile),
            );
            for (t, p) in sp.total.iter_mut().zip(&pass_splats) {
                for c in 0..3 {
                    t[c] = t[c].saturating_add(p[c]);
                }
            }
            sp.passes += 1;
        }
        self.sums = pass;
        self.spp += count;
        self.seconds += start.elapsed().as_secs_f64();
        true
    }

    /// A quick low-resolution look for a moving camera: sample 0 of the top-left pixel of
    /// every `block × block` block (a quarter of the pixels for 2), copied over its block.
    /// Each value is exactly that pixel's first sample in a full render; for light tracing
    /// and BDPT, whose samples land on other pixels, the MIS path tracer's. `stop` is checked
    /// before each row of blocks; `None` if it stopped. The accumulation is not changed.
    #[must_use]
    pub fn preview(
        &self,
        scene: &SceneView<'_>,
        block: u32,
        stop: &(dyn Fn() -> bool + Sync),
    ) -> Option<Image> {
        let block = block.max(1);
        let (camera, s) = (&self.camera, &self.settings);
        let (w, h) = (camera.width, camera.height);
        let sampling = s.sampling(w, h);
        let rows: Option<Vec<Vec<Rgb>>> = self.pool.install(|| {
            (0..h.div_ceil(block))
                .into_par_iter()
                .map(|by| {
                    if stop() {
                        return None;
                    }
                    let y = by * block;
                    Some(
                        (0..w.div_ceil(block))
                            .map(|bx| {
                                let x = bx * block;
                                let integrator = if s.integrator.splats() {
                                    Integrator::PathMis
                                } else {
                                    s.integrator
                                };
                                let p = render_pixel(
                                    integrator,
                                    scene,
                                    camera,
                                    &s.path,
                                    &sampling,
                                    x,
                                    y,
                                    0,
                                    1,
                                    PixelStats::default(),
                                    None,
                                    &mut ember_kernel::splat::NoSplats,
                                );
                                p.sum
                            })
                            .collect(),
                    )
                })
                .collect()
        });
        let rows = rows?;
        let mut image = Image::new(w, h);
        for y in 0..h {
            let row = &rows[(y / block) as usize];
            for x in 0..w {
                image.pixels[(y * w + x) as usize] = row[(x / block) as usize];
            }
        }
        Some(image)
    }

    /// The image so far: mean and variance of the mean per pixel (pixels outside the shard and
    /// every pixel at 0 spp are 0, but for the splats light tracing and BDPT put there),
    /// invalid samples and rays; `seconds` is [`Self::seconds`]. Pixels are resolved from
    /// their own sums and splat sums by [`resolve`], as the C API and merged shards do.
    #[must_use]
    pub fn snapshot(&self) -> Rendered {
        let (w, h) = (self.camera.width, self.camera.height);
        let tile = self.settings.tile.max(1);
        let done = self.spp;
        let mut image = Image::new(w, h);
        let mut variance = Image::new(w, h);
        let mut sums = Image::new(w, h);
        let mut invalid = 0u64;
        let mut rays = 0u64;
        let n = done as f32;
        // At 0 spp the sums may be a previous accumulation's (see `restart`).
        let stats: &[Vec<PixelStats>] = if done == 0 { &[] } else { &self.sums };
        for (&(x0, y0), stats) in self.tiles.iter().zip(stats) {
            let mut it = stats.iter();
            for y in y0..(y0 + tile).min(h) {
                for x in x0..(x0 + tile).min(w) {
                    let Some(p) = it.next() else { continue };
                    let i = (y * w + x) as usize;
                    sums.pixels[i] = p.sum;
                    if done > 0 {
                        let mean = p.sum / n;
                        image.pixels[i] = mean;
                        variance.pixels[i] = if done > 1 {
                            ((p.sum_sq - p.sum * mean) / (n - 1.0)).max(Rgb::ZERO) / n
                        } else {
                            Rgb::ZERO
                        };
                    }
                    invalid += u64::from(p.invalid);
                    rays += p.rays;
                }
            }
        }
        let (mut splats, mut strategies) = (None, None);
        if let (Some(sp), true) = (&self.splats, done > 0) {
            // Batch means: Var(mean) ≈ (Σ n_p X_p² − N μ²) / ((P − 1) N).
            let big_n = f64::from(done);
            let passes = f64::from(sp.passes);
            for i in 0..image.pixels.len() {
                let mean = resolve(sums.pixels[i], sp.total[i], done);
                image.pixels[i] = mean;
                variance.pixels[i] = if sp.passes > 1 {
                    let mu = mean.as_dvec3();
                    ((sp.batch_sq[i] - big_n * mu * mu) / ((passes - 1.0) * big_n))
                        .max(glam::DVec3::ZERO)
                        .as_vec3()
                } else {
                    Rgb::ZERO
                };
            }
            invalid += sp.invalid;
            splats = Some(sp.total.clone());
            strategies = sp.strategies.clone();
        }
        Rendered {
            image,
            variance,
            sums,
            splats,
            strategies,
            spp: done,
            invalid_samples: invalid,
            rays,
            seconds: self.seconds,
        }
    }
}
