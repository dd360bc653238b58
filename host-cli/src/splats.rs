//! Splat films shared by the render threads: the fixed-point sums of the kernel's
//! [`ember_kernel::splat`] in atomics, so that any number of threads add to one film and the
//! result does not depend on their order; and the per-strategy films of `--strategies`.

use crate::image::Image;
use ember_kernel::integrator::BdptSink;
use ember_kernel::splat::{pixel_of, to_fixed, SplatSink};
use ember_kernel::Rgb;
use glam::Vec2;
use std::sync::atomic::{AtomicI64, AtomicU64, Ordering};

/// Fixed-point splat sums of a film, one `[i64; 3]` per pixel, added to atomically (relaxed:
/// integer addition commutes, so no ordering is needed for a deterministic total).
#[derive(Debug)]
pub struct AtomicSplats {
    pub width: u32,
    pub height: u32,
    sums: Vec<[AtomicI64; 3]>,
    invalid: AtomicU64,
}

impl AtomicSplats {
    #[must_use]
    pub fn new(width: u32, height: u32) -> Self {
        let n = width as usize * height as usize;
        Self {
            width,
            height,
            sums: (0..n)
                .map(|_| [AtomicI64::new(0), AtomicI64::new(0), AtomicI64::new(0)])
                .collect(),
            invalid: AtomicU64::new(0),
        }
    }

    /// Bytes per pixel of one film.
    pub const BYTES_PER_PIXEL: u64 = 24;

    #[inline]
    fn add_fixed(&self, i: usize, v: [i64; 3]) {
        for (s, v) in self.sums[i].iter().zip(v) {
            // Saturating, as the kernel's SplatBuffer: a sum near 2^63 is garbage anyway.
            let _ = s.fetch_update(Ordering::Relaxed, Ordering::Relaxed, |x| {
                Some(x.saturating_add(v))
            });
        }
    }

    /// Adds `value` at `raster` (ignored outside the film; counted when not representable).
    #[inline]
    pub fn add(&self, raster: Vec2, value: Rgb) {
        let Some(i) = pixel_of(raster, self.width, self.height) else {
            return;
        };
        match [to_fixed(value.x), to_fixed(value.y), to_fixed(value.z)] {
            [Some(r), Some(g), Some(b)] => self.add_fixed(i, [r, g, b]),
            _ => {
                self.invalid.fetch_add(1, Ordering::Relaxed);
            }
        }
    }

    /// The sums as plain integers (call when no thread adds any more).
    #[must_use]
    pub fn snapshot(&self) -> Vec<[i64; 3]> {
        self.sums
            .iter()
            .map(|s| s.each_ref().map(|a| a.load(Ordering::Relaxed)))
            .collect()
    }

    /// Adds plain sums (another film, a shard's file) into this one.
    pub fn add_all(&self, other: &[[i64; 3]]) {
        for (i, v) in other.iter().enumerate() {
            if *v != [0; 3] {
                self.add_fixed(i, *v);
            }
        }
    }

    /// Resets every sum and the count of refused splats to 0.
    pub fn clear(&self) {
        for s in &self.sums {
            for a in s {
                a.store(0, Ordering::Relaxed);
            }
        }
        self.invalid.store(0, Ordering::Relaxed);
    }

    /// Splats that were refused (non-finite or too large).
    #[must_use]
    pub fn invalid(&self) -> u64 {
        self.invalid.load(Ordering::Relaxed)
    }
}

/// The sink a render thread hands the kernel: it splats into a shared film.
impl SplatSink for &AtomicSplats {
    #[inline]
    fn splat(&mut self, raster: Vec2, value: Rgb) {
        self.add(raster, value);
    }
}

impl BdptSink for &AtomicSplats {}

/// The value of a pixel from the running f32 sum of its own samples and the fixed-point sum of
/// the splats it received, over `spp` samples: the kernel's [`ember_kernel::splat::resolve`],
/// which every host (single render, merged shards, interrupted render, the C API) uses, so
/// that they agree bit for bit.
pub use ember_kernel::splat::resolve;

/// The per-strategy images of BDPT's `--strategies`: for every `(s, t)` up to a depth, the
/// unweighted contributions and the MIS-weighted ones, each a fixed-point film (so that
/// they, too, do not depend on thread order).
#[derive(Debug)]
pub struct StrategyFilms {
    pub max_depth: u32,
    /// Index `strategy_index(s, t)`: (unweighted, weighted).
    films: Vec<(AtomicSplats, AtomicSplats)>,
}

/// The number of strategies `(s, t)` with `t ≥ 1`, `s + t − 2 = d` for `d ≤ max_depth`,
/// without `(1, 1)`.
#[must_use]
pub fn strategy_count(max_depth: u32) -> usize {
    (0..=max_depth).map(|d| d as usize + 2).sum::<usize>() - 1
}

/// Where `(s, t)` is in [`StrategyFilms`], or `None` beyond its depth or for `(1, 1)`.
#[must_use]
pub fn strategy_index(s: u32, t: u32, max_depth: u32) -> Option<usize> {
    if t == 0 || (s == 1 && t == 1) {
        return None;
    }
    let d = (s + t).checked_sub(2)?;
    if d > max_depth {
        return None;
    }
    // Depths before d, each with d' + 2 strategies (s = 0 ..= d' + 1), minus the skipped (1, 1).
    let before: usize = (0..d).map(|e| e as usize + 2).sum();
    let i = before + s as usize;
    Some(if d == 0 { i } else { i - 1 })
}

impl StrategyFilms {
    #[must_use]
    pub fn new(width: u32, height: u32, max_depth: u32) -> Self {
        Self {
            max_depth,
            films: (0..strategy_count(max_depth))
                .map(|_| {
                    (
                        AtomicSplats::new(width, height),
                        AtomicSplats::new(width, height),
                    )
                })
                .collect(),
        }
    }

    /// Memory of the films, in bytes.
    #[must_use]
    pub fn memory(width: u32, height: u32, max_depth: u32) -> u64 {
        strategy_count(max_depth) as u64
            * 2
            * u64::from(width)
            * u64::from(height)
            * AtomicSplats::BYTES_PER_PIXEL
    }

    #[inline]
    fn add(&self, s: u32, t: u32, raster: Vec2, unweighted: Rgb, weight: f32) {
        if let Some(i) = strategy_index(s, t, self.max_depth) {
            let (u, w) = &self.films[i];
            u.add(raster, unweighted);
            w.add(raster, unweighted * weight);
        }
    }

    /// The images of strategy `(s, t)` over `spp` samples per pixel: (unweighted, weighted).
    #[must_use]
    pub fn images(&self, s: u32, t: u32, spp: u32) -> Option<(Image, Image)> {
        let (u, w) = &self.films[strategy_index(s, t, self.max_depth)?];
        let image = |f: &AtomicSplats| {
            let mut img = Image::new(f.width, f.height);
            for (p, v) in img.pixels.iter_mut().zip(f.snapshot()) {
                *p = resolve(Rgb::ZERO, v, spp);
            }
            img
        };
        Some((image(u), image(w)))
    }

    /// Every strategy `(s, t)` the films hold, depth by depth.
    pub fn strategies(&self) -> impl Iterator<Item = (u32, u32)> + '_ {
        (0..=self.max_depth).flat_map(|d| {
            (0..=d + 1)
                .map(move |s| (s, d + 2 - s))
                .filter(|&(s, t)| !(s == 1 && t == 1))
        })
    }
}

/// The sink of a BDPT render with strategy images.
#[derive(Clone, Copy, Debug)]
pub struct StrategySink<'a> {
    pub splats: &'a AtomicSplats,
    pub films: &'a StrategyFilms,
}

impl SplatSink for StrategySink<'_> {
    #[inline]
    fn splat(&mut self, raster: Vec2, value: Rgb) {
        self.splats.add(raster, value);
    }
}

impl BdptSink for StrategySink<'_> {
    #[inline]
    fn strategy(&mut self, s: u32, t: u32, raster: Vec2, unweighted: Rgb, weight: f32) {
        self.films.add(s, t, raster, unweighted, weight);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn strategy_indices_are_dense_and_distinct() {
        for max_depth in 0..6 {
            let films = StrategyFilms::new(1, 1, max_depth);
            let all: Vec<(u32, u32)> = films.strategies().collect();
            assert_eq!(all.len(), strategy_count(max_depth));
            for (k, &(s, t)) in all.iter().enumerate() {
                assert_eq!(strategy_index(s, t, max_depth), Some(k), "({s}, {t})");
            }
            assert_eq!(strategy_index(1, 1, max_depth), None);
            assert_eq!(strategy_index(0, max_depth + 3, max_depth), None);
        }
        assert_eq!(strategy_count(0), 1); // (0, 2)
        assert_eq!(strategy_count(1), 4); // + (0, 3), (1, 2), (2, 1)
    }

    #[test]
    fn atomic_sums_do_not_depend_on_the_order() {
        let values = [1e7f32, 0.1, -1e7, 3.25, 1e-6];
        let a = AtomicSplats::new(2, 1);
        let b = AtomicSplats::new(2, 1);
        for v in values {
            a.add(Vec2::new(1.5, 0.5), Rgb::splat(v));
        }
        std::thread::scope(|s| {
            for v in values.iter().rev() {
                let b = &b;
                s.spawn(move || b.add(Vec2::new(1.2, 0.1), Rgb::splat(*v)));
            }
        });
        assert_eq!(a.snapshot(), b.snapshot());
        assert_eq!(a.snapshot()[0], [0; 3]);
        let px = resolve(Rgb::splat(1.0), a.snapshot()[1], 2);
        assert!((px.x - (1.0 + 3.350001) / 2.0).abs() < 1e-6, "{px}");
        assert_eq!(px, resolve(Rgb::splat(1.0), b.snapshot()[1], 2));
        a.add(Vec2::new(0.5, 0.5), Rgb::new(f32::NAN, 0.0, 0.0));
        assert_eq!(a.invalid(), 1);
        a.clear();
        assert_eq!((a.invalid(), a.snapshot()), (0, vec![[0; 3]; 2]));
    }
}
