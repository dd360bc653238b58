//! Parallel rendering on the host: rayon over tiles, the kernel per pixel, in passes of
//! samples so that a render can be interrupted and still yield an image.

use crate::image::Image;
use ember_kernel::camera::Camera;
use ember_kernel::integrator::{render_pixel, Integrator, PathSettings, PixelStats};
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
    /// Square tile side in pixels; has no effect on the result, only on scheduling.
    pub tile: u32,
    /// Worker threads; 0 means one per core. Has no effect on the result.
    pub threads: usize,
    pub progress: bool,
    /// Render only the tiles of this shard (see [`Shard`]); other pixels stay 0.
    pub shard: Shard,
}

/// A deterministic part of a render for splitting it across processes or machines: tile `t`
/// (in row-major tile order) belongs to shard `t mod count`. Every pixel's value depends only
/// on its own samples, so the shards of a render, merged, are bit-identical to the whole.
/// (Splitting by sample ranges instead would change the order in which each pixel's f32 sums
/// are added, and with it the last bits.)
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
    /// Estimated variance of each pixel's mean (sample variance / spp).
    pub variance: Image,
    /// Samples per pixel actually in the image (fewer than asked if interrupted).
    pub spp: u32,
    /// Samples that were NaN or infinite (counted as 0).
    pub invalid_samples: u64,
    /// Rays traced (camera, continuation and shadow rays).
    pub rays: u64,
    pub seconds: f64,
}

/// Bytes the host allocates per pixel: running sums (`PixelStats`), one pass's results, and the
/// mean and variance images.
pub const BYTES_PER_PIXEL: u64 = 2 * std::mem::size_of::<PixelStats>() as u64 + 2 * 12;

/// Memory a render of `width × height` needs, in bytes.
#[must_use]
pub fn render_memory(width: u32, height: u32) -> u64 {
    u64::from(width) * u64::from(height) * BYTES_PER_PIXEL
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

/// Samples per pixel in each pass: about 16 passes, so an interrupt loses at most ~1/16 of the
/// work, and at least 1 sample.
fn pass_size(spp: u32) -> u32 {
    spp.div_ceil(16).max(1)
}

/// Like [`render`], but checks `stop` between tiles: once it is set, the pass in flight is
/// abandoned and the image holds the passes completed so far (`Rendered::spp` says how many
/// samples; 0 if not even one pass finished).
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
    let (w, h) = (camera.width, camera.height);
    let tile = s.tile.max(1);
    let tiles: Vec<(u32, u32)> = tiles(w, h, tile)
        .into_iter()
        .enumerate()
        .filter(|(t, _)| s.shard.owns(*t))
        .map(|(_, corner)| corner)
        .collect();
    let bar = if s.progress {
        let pixels: u64 = tiles
            .iter()
            .map(|&(x0, y0)| u64::from(((x0 + tile).min(w) - x0) * ((y0 + tile).min(h) - y0)))
            .sum();
        let b = ProgressBar::new(pixels * u64::from(s.spp));
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
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(s.threads)
        .build()
        .expect("cannot create the rayon thread pool");
    // Running sums in tile order: tile i owns the slice starting at its first pixel index.
    let tile_pixels = |(x0, y0): (u32, u32)| ((x0 + tile).min(w) - x0) * ((y0 + tile).min(h) - y0);
    let mut sums: Vec<Vec<PixelStats>> = tiles
        .iter()
        .map(|&t| vec![PixelStats::default(); tile_pixels(t) as usize])
        .collect();
    let mut done = 0u32;
    while done < s.spp && !stop.load(Ordering::Relaxed) {
        let count = pass_size(s.spp).min(s.spp - done);
        let pass: Option<Vec<Vec<PixelStats>>> = pool.install(|| {
            tiles
                .par_iter()
                .zip(sums.par_iter())
                .map(|(&(x0, y0), acc)| {
                    if stop.load(Ordering::Relaxed) {
                        return None;
                    }
                    let mut out = Vec::with_capacity(acc.len());
                    let mut k = 0;
                    for y in y0..(y0 + tile).min(h) {
                        for x in x0..(x0 + tile).min(w) {
                            out.push(render_pixel(
                                s.integrator,
                                scene,
                                camera,
                                &s.path,
                                s.seed,
                                x,
                                y,
                                done,
                                count,
                                acc[k],
                                None,
                                &mut ember_kernel::splat::NoSplats,
                            ));
                            k += 1;
                        }
                    }
                    bar.inc(u64::from(count) * out.len() as u64);
                    Some(out)
                })
                .collect()
        });
        // An interrupted pass is dropped whole: every pixel keeps the same sample count.
        let Some(pass) = pass else { break };
        sums = pass;
        done += count;
    }
    bar.finish_and_clear();

    let mut image = Image::new(w, h);
    let mut variance = Image::new(w, h);
    let mut invalid = 0u64;
    let mut rays = 0u64;
    let n = done as f32;
    for (&(x0, y0), stats) in tiles.iter().zip(&sums) {
        let mut it = stats.iter();
        for y in y0..(y0 + tile).min(h) {
            for x in x0..(x0 + tile).min(w) {
                let Some(p) = it.next() else { continue };
                let i = (y * w + x) as usize;
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
    Rendered {
        image,
        variance,
        spp: done,
        invalid_samples: invalid,
        rays,
        seconds: start.elapsed().as_secs_f64(),
    }
}
