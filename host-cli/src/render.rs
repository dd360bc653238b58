//! Parallel rendering on the host: rayon over tiles, the kernel per pixel.

use crate::image::Image;
use ember_kernel::camera::Camera;
use ember_kernel::integrator::{render_pixel, Integrator, PathSettings, PixelStats};
use ember_kernel::scene::SceneView;
use ember_kernel::Rgb;
use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;

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
}

/// A rendered image with its per-pixel variance of the mean and counters.
#[derive(Clone, Debug)]
pub struct Rendered {
    /// Mean radiance per pixel.
    pub image: Image,
    /// Estimated variance of each pixel's mean (sample variance / spp).
    pub variance: Image,
    /// Samples that were NaN or infinite (counted as 0).
    pub invalid_samples: u64,
    pub seconds: f64,
}

/// Renders the scene. The result depends only on the scene, camera, integrator settings, spp
/// and seed: every pixel sums its samples in sample order, whatever the tiling or threads.
///
/// # Panics
/// If the rayon thread pool cannot be created.
#[must_use]
pub fn render(scene: &SceneView<'_>, camera: &Camera, s: &RenderSettings) -> Rendered {
    let start = std::time::Instant::now();
    let (w, h) = (camera.width, camera.height);
    let tile = s.tile.max(1);
    let tiles: Vec<(u32, u32)> = (0..h.div_ceil(tile))
        .flat_map(|ty| (0..w.div_ceil(tile)).map(move |tx| (tx * tile, ty * tile)))
        .collect();
    let bar = if s.progress {
        let b = ProgressBar::new(tiles.len() as u64);
        b.set_style(
            ProgressStyle::with_template(
                "{spinner} [{elapsed_precise}] {wide_bar} {pos}/{len} tiles, ETA {eta}",
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
    let results: Vec<((u32, u32), Vec<PixelStats>)> = pool.install(|| {
        tiles
            .par_iter()
            .map(|&(x0, y0)| {
                let mut out = Vec::with_capacity((tile * tile) as usize);
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
                            0,
                            s.spp,
                        ));
                    }
                }
                bar.inc(1);
                ((x0, y0), out)
            })
            .collect()
    });
    bar.finish_and_clear();
    let mut image = Image::new(w, h);
    let mut variance = Image::new(w, h);
    let mut invalid = 0u64;
    let n = s.spp as f32;
    for ((x0, y0), stats) in results {
        let mut it = stats.into_iter();
        for y in y0..(y0 + tile).min(h) {
            for x in x0..(x0 + tile).min(w) {
                let Some(p) = it.next() else { continue };
                let mean = p.sum / n;
                let var = if s.spp > 1 {
                    ((p.sum_sq - p.sum * mean) / (n - 1.0)).max(Rgb::ZERO) / n
                } else {
                    Rgb::ZERO
                };
                let i = (y * w + x) as usize;
                image.pixels[i] = mean;
                variance.pixels[i] = var;
                invalid += u64::from(p.invalid);
            }
        }
    }
    Rendered {
        image,
        variance,
        invalid_samples: invalid,
        seconds: start.elapsed().as_secs_f64(),
    }
}
