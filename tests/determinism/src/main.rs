//! Renders and bakes the determinism scene with N threads and prints the hashes:
//!
//!     ember-determinism [--threads N] [--ppm PREFIX]
//!
//! prints `render <16 hex digits>` and `bake <16 hex digits>`. Threads take rows in turn
//! (row y goes to thread y mod N); the hashes must not depend on N. `--ppm` also writes the
//! three renders as `PREFIX-<integrator>.ppm` (sRGB, clamped) to look at.

use ember_determinism::{
    bake_point, hash_results, render_pixel_rgb, Scene, BAKE_ESTIMATORS, BAKE_POINTS, HEIGHT,
    INTEGRATORS, WIDTH,
};

/// A row of an image and its index.
type Row<'a> = (usize, &'a mut [[f32; 3]]);

fn main() {
    let usage = || -> ! {
        eprintln!("usage: ember-determinism [--threads N] [--ppm PREFIX]  (N >= 1)");
        std::process::exit(2);
    };
    let mut threads = 1;
    let mut ppm = None;
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match (a.as_str(), args.next()) {
            ("--threads", Some(n)) => {
                threads = n
                    .parse::<usize>()
                    .ok()
                    .filter(|&n| n > 0)
                    .unwrap_or_else(|| usage());
            }
            ("--ppm", Some(p)) => ppm = Some(p),
            _ => usage(),
        }
    }

    let scene = Scene::new();
    let view = scene.view();
    let (w, h) = (WIDTH as usize, HEIGHT as usize);
    let mut images = vec![vec![[0.0f32; 3]; w * h]; INTEGRATORS.len()];
    for (image, &integrator) in images.iter_mut().zip(&INTEGRATORS) {
        // Row y goes to thread y mod N.
        let mut per_thread: Vec<Vec<Row<'_>>> = (0..threads).map(|_| Vec::new()).collect();
        for (y, row) in image.chunks_mut(w).enumerate() {
            per_thread[y % threads].push((y, row));
        }
        std::thread::scope(|s| {
            for rows in per_thread {
                let view = &view;
                s.spawn(move || {
                    for (y, row) in rows {
                        for (x, px) in row.iter_mut().enumerate() {
                            *px = render_pixel_rgb(view, integrator, x as u32, y as u32);
                        }
                    }
                });
            }
        });
    }
    let bakes: Vec<Vec<[f32; 3]>> = BAKE_ESTIMATORS
        .iter()
        .map(|&e| {
            (0..BAKE_POINTS.len())
                .map(|i| bake_point(&view, e, i))
                .collect()
        })
        .collect();
    if let Some(prefix) = ppm {
        for (image, name) in images.iter().zip(["implicit", "explicit", "mis"]) {
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
            let path = format!("{prefix}-{name}.ppm");
            std::fs::write(&path, out).unwrap_or_else(|e| panic!("cannot write {path}: {e}"));
        }
    }
    let images: Vec<&[[f32; 3]]> = images.iter().map(Vec::as_slice).collect();
    let bakes: Vec<&[[f32; 3]]> = bakes.iter().map(Vec::as_slice).collect();
    let h = hash_results(&images, &bakes);
    println!("render {:016x}", h.render);
    println!("bake {:016x}", h.bake);
}
