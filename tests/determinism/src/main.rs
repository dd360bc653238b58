//! Renders and bakes the determinism scene with N threads and prints the hashes:
//!
//!     ember-determinism [--threads N] [--tile S] [--ppm PREFIX]
//!
//! prints `render <16 hex digits>`, `bake <16 hex digits>` and `splat <16 hex digits>`. The
//! film is cut into work items, rows (the default) or `S×S` tiles (`--tile`, the last ones in
//! each row and column smaller), and threads take them in turn (item k goes to thread k mod N).
//! Each thread renders the splatting integrators (light tracer, BDPT) into its own fixed-point
//! splat buffer and BDPT scratch; the buffers are summed after the threads are joined (in
//! reverse thread order, to differ from the order they were filled in) and the image resolved.
//! The hashes must not depend on N or S. `--ppm` also writes the six renders as
//! `PREFIX-<integrator>.ppm` (sRGB, clamped) to look at.

use ember_determinism::{
    bake_point, hash_results, render_pixel_sum, render_row_rgb, resolve_pixel, Scene, SplatBuffer,
    BAKE_ESTIMATORS, BAKE_POINTS, HEIGHT, INTEGRATORS, PIXELS, SPLAT_INTEGRATORS, WIDTH,
};
use ember_kernel::integrator::{BdptScratch, Integrator};
use ember_kernel::scene::SceneView;

/// A rectangle of the film: `x0, y0, w, h`.
type Item = (u32, u32, u32, u32);

/// The work items: rows, or `tile × tile` tiles in row-major order.
fn items(tile: Option<u32>) -> Vec<Item> {
    match tile {
        None => (0..HEIGHT).map(|y| (0, y, WIDTH, 1)).collect(),
        Some(s) => (0..HEIGHT.div_ceil(s))
            .flat_map(|ty| (0..WIDTH.div_ceil(s)).map(move |tx| (tx * s, ty * s)))
            .map(|(x0, y0)| (x0, y0, s.min(WIDTH - x0), s.min(HEIGHT - y0)))
            .collect(),
    }
}

/// What one thread renders of an image: the pixels of its items (index, value) and, for a
/// splatting integrator, its splat buffer.
struct Part {
    pixels: Vec<(usize, [f32; 3])>,
    splats: Vec<[i64; 3]>,
}

/// Renders `integrator`'s image with `threads` threads over `items`; for a splatting
/// integrator the pixel values are the sample sums and the merged splat buffer comes back too.
fn render(
    view: &SceneView<'_>,
    integrator: Integrator,
    items: &[Item],
    threads: usize,
) -> (Vec<[f32; 3]>, Vec<[i64; 3]>) {
    let parts: Vec<Part> = std::thread::scope(|s| {
        let handles: Vec<_> = (0..threads)
            .map(|t| {
                s.spawn(move || {
                    let mut splats = vec![[0i64; 3]; PIXELS];
                    let mut buffer = SplatBuffer::new(WIDTH, HEIGHT, &mut splats).unwrap();
                    let mut scratch = Box::<BdptScratch>::default();
                    let mut pixels = Vec::new();
                    for &(x0, y0, w, h) in items.iter().skip(t).step_by(threads) {
                        for y in y0..y0 + h {
                            let at = |x: u32| (y * WIDTH + x) as usize;
                            if integrator.splats() {
                                for x in x0..x0 + w {
                                    let v = render_pixel_sum(
                                        view,
                                        integrator,
                                        x,
                                        y,
                                        &mut scratch,
                                        &mut buffer,
                                    );
                                    pixels.push((at(x), v));
                                }
                            } else {
                                // The item's row as one run (its lanes filled with
                                // neighbouring pixels' samples), whatever the item's size.
                                let mut row = vec![[0.0f32; 3]; w as usize];
                                render_row_rgb(view, integrator, x0, y, &mut row);
                                pixels.extend((x0..).map(at).zip(row));
                            }
                        }
                    }
                    assert_eq!(buffer.invalid, 0, "{integrator:?}: non-finite splats");
                    Part { pixels, splats }
                })
            })
            .collect();
        handles.into_iter().map(|h| h.join().unwrap()).collect()
    });
    let mut image = vec![[f32::NAN; 3]; PIXELS];
    let mut merged = vec![[0i64; 3]; PIXELS];
    let mut total = SplatBuffer::new(WIDTH, HEIGHT, &mut merged).unwrap();
    for part in parts.iter().rev() {
        for &(i, v) in &part.pixels {
            image[i] = v;
        }
        total.add(&part.splats);
    }
    assert!(
        image.iter().flatten().all(|c| !c.is_nan()),
        "a pixel was not rendered"
    );
    (image, merged)
}

fn write_ppm(path: &str, image: &[[f32; 3]]) {
    let (w, h) = (WIDTH as usize, HEIGHT as usize);
    let mut out = format!("P3\n{w} {h}\n255\n").into_bytes();
    for px in image {
        for c in px {
            let c = c.clamp(0.0, 1.0);
            let s = if c <= 0.003_130_8 {
                12.92 * c
            } else {
                1.055 * c.powf(1.0 / 2.4) - 0.055
            };
            out.extend_from_slice(format!("{} ", (s * 255.0).round() as u8).as_bytes());
        }
    }
    std::fs::write(path, out).unwrap_or_else(|e| panic!("cannot write {path}: {e}"));
}

fn main() {
    let usage = || -> ! {
        eprintln!(
            "usage: ember-determinism [--threads N] [--tile S] [--ppm PREFIX] [--simd auto|avx2|baseline]  (N, S >= 1)"
        );
        std::process::exit(2);
    };
    let mut threads = 1;
    let mut tile = None;
    let mut ppm = None;
    let mut args = std::env::args().skip(1);
    let positive = |n: String| n.parse::<usize>().ok().filter(|&n| n > 0);
    while let Some(a) = args.next() {
        match (a.as_str(), args.next()) {
            ("--threads", Some(n)) => threads = positive(n).unwrap_or_else(|| usage()),
            ("--tile", Some(s)) => {
                let s = positive(s).and_then(|s| u32::try_from(s).ok());
                tile = Some(s.unwrap_or_else(|| usage()));
            }
            ("--ppm", Some(p)) => ppm = Some(p),
            // The ray queries' instructions (`ember_kernel::simd`): AVX-512 or AVX2 where the
            // CPU has it, at most AVX2, or the build's baseline only.
            ("--simd", Some(s)) if s == "auto" => {}
            ("--simd", Some(s)) if s == "avx2" => {
                #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
                ember_kernel::simd::limit_to_avx2();
            }
            ("--simd", Some(s)) if s == "baseline" => {
                #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
                ember_kernel::simd::limit_to_baseline();
            }
            _ => usage(),
        }
    }

    let scene = Scene::new();
    let view = scene.view();
    let items = items(tile);
    let images: Vec<Vec<[f32; 3]>> = INTEGRATORS
        .iter()
        .map(|&integrator| render(&view, integrator, &items, threads).0)
        .collect();
    let splat_images: Vec<Vec<[f32; 3]>> = SPLAT_INTEGRATORS
        .iter()
        .map(|&integrator| {
            let (sums, splats) = render(&view, integrator, &items, threads);
            sums.iter()
                .zip(&splats)
                .map(|(sum, s)| resolve_pixel(*sum, *s))
                .collect()
        })
        .collect();
    let bakes: Vec<Vec<[f32; 3]>> = BAKE_ESTIMATORS
        .iter()
        .map(|&e| {
            (0..BAKE_POINTS.len())
                .map(|i| bake_point(&view, e, i))
                .collect()
        })
        .collect();
    if let Some(prefix) = ppm {
        let names = [
            "implicit",
            "explicit",
            "mis",
            "lighttracer",
            "bdpt",
            "bdpt-balance",
        ];
        for (image, name) in images.iter().chain(&splat_images).zip(names) {
            write_ppm(&format!("{prefix}-{name}.ppm"), image);
        }
    }
    fn as_slices(v: &[Vec<[f32; 3]>]) -> Vec<&[[f32; 3]]> {
        v.iter().map(Vec::as_slice).collect()
    }
    let h = hash_results(
        &as_slices(&images),
        &as_slices(&bakes),
        &as_slices(&splat_images),
    );
    println!("render {:016x}", h.render);
    println!("bake {:016x}", h.bake);
    println!("splat {:016x}", h.splat);
}
