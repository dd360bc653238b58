//! Image error metrics, shared by `ember compare`, the benchmarks and the tests.
//!
//! Definitions (per channel, averaged over the three channels and all pixels):
//! - RMSE: `sqrt(mean((a − b)²))`.
//! - relative MSE: `mean((a − b)² / (b² + ε))` with ε = 0.01, the definition of pbrt-v4's
//!   `imgtool diff` and of Mitsuba's test suite (ε keeps black reference pixels finite).
//! - mean bias: `mean(a) − mean(b)` (signed), and relative to `mean(b)`.
//! - MAE: `mean(|a − b|)`; max: the largest `|a − b|`.

use crate::error::{Error, Result};
use crate::image::Image;
use ember_kernel::Rgb;
use std::path::Path;

/// ε in the relative MSE denominator.
pub const REL_MSE_EPSILON: f64 = 0.01;

/// Differences between an image and a reference.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Metrics {
    pub rmse: f64,
    pub rel_mse: f64,
    pub mae: f64,
    pub max_abs: f64,
    pub mean: Rgb,
    pub reference_mean: Rgb,
    /// `mean(a) − mean(b)`, averaged over channels.
    pub mean_bias: f64,
    /// `mean_bias / mean(b)`.
    pub relative_bias: f64,
    /// Pixels of `a` that are NaN or infinite (excluded from the sums).
    pub non_finite: usize,
}

/// Compares `a` with the reference `b`.
///
/// # Errors
/// When the sizes differ.
pub fn compare(a: &Image, b: &Image) -> Result<Metrics> {
    if (a.width, a.height) != (b.width, b.height) {
        return Err(Error::new(format!(
            "images differ in size: {}x{} and {}x{}",
            a.width, a.height, b.width, b.height
        )));
    }
    let (mut se, mut rel, mut ae, mut max_abs) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    let mut non_finite = 0;
    let mut count = 0u64;
    for (pa, pb) in a.pixels.iter().zip(&b.pixels) {
        if !pa.is_finite() || !pb.is_finite() {
            non_finite += 1;
            continue;
        }
        count += 1;
        for c in 0..3 {
            let (x, y) = (f64::from(pa[c]), f64::from(pb[c]));
            let d = x - y;
            se += d * d;
            rel += d * d / (y * y + REL_MSE_EPSILON);
            ae += d.abs();
            max_abs = max_abs.max(d.abs());
        }
    }
    let n = (3 * count).max(1) as f64;
    let (ma, mb) = (a.mean(), b.mean());
    let bias = f64::from((ma - mb).element_sum()) / 3.0;
    let ref_level = f64::from(mb.element_sum()) / 3.0;
    Ok(Metrics {
        rmse: (se / n).sqrt(),
        rel_mse: rel / n,
        mae: ae / n,
        max_abs,
        mean: ma,
        reference_mean: mb,
        mean_bias: bias,
        relative_bias: if ref_level > 0.0 {
            bias / ref_level
        } else {
            0.0
        },
        non_finite,
    })
}

/// A colour ramp (viridis, 5 stops) for `t` in [0, 1].
fn ramp(t: f32) -> Rgb {
    const STOPS: [[f32; 3]; 5] = [
        [0.267, 0.005, 0.329],
        [0.230, 0.322, 0.546],
        [0.128, 0.567, 0.551],
        [0.369, 0.789, 0.383],
        [0.993, 0.906, 0.144],
    ];
    let t = if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        1.0
    } * 4.0;
    let i = (t as usize).min(3);
    let f = t - i as f32;
    Rgb::from_array(STOPS[i]).lerp(Rgb::from_array(STOPS[i + 1]), f)
}

/// False-colour image of the per-pixel relative error `|a − b| / (|b| + 0.1)` (mean over
/// channels), on a log scale from 10⁻³ (dark) to 1 (bright). Its values are display values:
/// write it with [`write_error_png`].
#[must_use]
pub fn error_image(a: &Image, b: &Image) -> Image {
    let mut out = Image::new(a.width, a.height);
    for (o, (pa, pb)) in out.pixels.iter_mut().zip(a.pixels.iter().zip(&b.pixels)) {
        let e = ((*pa - *pb).abs() / (pb.abs() + Rgb::splat(0.1))).element_sum() / 3.0;
        let t = (e.max(1e-3).log10() + 3.0) / 3.0;
        *o = ramp(t);
    }
    out
}

/// Writes the false-colour error image as an 8-bit PNG (its values are display values).
///
/// # Errors
/// When the file cannot be written.
pub fn write_error_png(path: &Path, a: &Image, b: &Image) -> Result<()> {
    let mut img = error_image(a, b);
    // write_png applies the sRGB curve to linear values; undo it so the ramp is shown as is.
    for p in &mut img.pixels {
        *p = p.map(crate::image::srgb_to_linear);
    }
    crate::image::write_png(path, &img)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_differences_give_known_metrics() {
        let mut b = Image::new(4, 2);
        for (i, p) in b.pixels.iter_mut().enumerate() {
            *p = Rgb::splat(0.1 * i as f32);
        }
        let mut a = b.clone();
        for p in &mut a.pixels {
            *p += Rgb::splat(0.1);
        }
        let m = compare(&a, &b).unwrap();
        assert!((m.rmse - 0.1).abs() < 1e-6);
        assert!((m.mae - 0.1).abs() < 1e-6);
        assert!((m.mean_bias - 0.1).abs() < 1e-6);
        assert!((m.max_abs - 0.1).abs() < 1e-6);
        let expected_rel: f64 = (0..8)
            .map(|i| 0.01 / ((0.1 * f64::from(i)).powi(2) + REL_MSE_EPSILON))
            .sum::<f64>()
            / 8.0;
        assert!((m.rel_mse - expected_rel).abs() < 1e-5, "{}", m.rel_mse);
        let same = compare(&b, &b).unwrap();
        assert_eq!((same.rmse, same.rel_mse, same.mean_bias), (0.0, 0.0, 0.0));
        // A NaN pixel is counted, not summed.
        a.pixels[3] = Rgb::new(f32::NAN, 0.0, 0.0);
        assert_eq!(compare(&a, &b).unwrap().non_finite, 1);
        assert!(compare(&a, &Image::new(2, 2)).is_err());
        let e = error_image(&a, &b);
        assert!(e.pixels.iter().all(|p| p.is_finite()));
    }
}
