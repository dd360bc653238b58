//! Warps from the unit square, each paired with its density and, where useful, its inverse
//! (Nori's `squareTo*`/`squareTo*Pdf`, pbrt's `Sample*`/`*PDF`/`Invert*Sample`).
//! Densities are per unit solid angle for directions and per unit barycentric area for the
//! triangle warp.

use super::{safe_sqrt, INV_2PI, INV_PI, PI};
use glam::{Vec2, Vec3};

/// Concentric (Shirley–Chiu) map from the square to the unit disk.
#[inline]
#[must_use]
pub fn sample_concentric_disk(u: Vec2) -> Vec2 {
    let o = 2.0 * u - Vec2::ONE;
    if o.x == 0.0 && o.y == 0.0 {
        return Vec2::ZERO;
    }
    let (r, theta) = if o.x.abs() > o.y.abs() {
        (o.x, core::f32::consts::FRAC_PI_4 * (o.y / o.x))
    } else {
        (
            o.y,
            core::f32::consts::FRAC_PI_2 - core::f32::consts::FRAC_PI_4 * (o.x / o.y),
        )
    };
    let (sin, cos) = super::sin_cos(theta);
    Vec2::new(r * cos, r * sin)
}

/// Inverse of [`sample_concentric_disk`].
#[must_use]
pub fn invert_concentric_disk(p: Vec2) -> Vec2 {
    let theta = libm::atan2f(p.y, p.x);
    let r = p.length();
    let (ox, oy);
    if p == Vec2::ZERO {
        return Vec2::splat(0.5);
    }
    // Which of the four wedges of the concentric map the point came from.
    let t = if theta < -core::f32::consts::FRAC_PI_4 {
        theta + 2.0 * PI
    } else {
        theta
    };
    if t < core::f32::consts::FRAC_PI_4 {
        ox = r;
        oy = r * t / core::f32::consts::FRAC_PI_4;
    } else if t < 3.0 * core::f32::consts::FRAC_PI_4 {
        oy = r;
        ox = r * (core::f32::consts::FRAC_PI_2 - t) / core::f32::consts::FRAC_PI_4;
    } else if t < 5.0 * core::f32::consts::FRAC_PI_4 {
        ox = -r;
        oy = -r * (t - PI) / core::f32::consts::FRAC_PI_4;
    } else {
        oy = -r;
        ox = -r * (3.0 * core::f32::consts::FRAC_PI_2 - t) / core::f32::consts::FRAC_PI_4;
    }
    Vec2::new((ox + 1.0) * 0.5, (oy + 1.0) * 0.5)
}

/// Cosine-weighted direction on the +z hemisphere (Malley's method).
#[inline]
#[must_use]
pub fn sample_cosine_hemisphere(u: Vec2) -> Vec3 {
    let d = sample_concentric_disk(u);
    let z = safe_sqrt(1.0 - d.x * d.x - d.y * d.y);
    Vec3::new(d.x, d.y, z)
}

/// Density of [`sample_cosine_hemisphere`]: cosθ/π above the horizon, 0 below.
#[inline]
#[must_use]
pub fn cosine_hemisphere_pdf(cos_theta: f32) -> f32 {
    if cos_theta > 0.0 {
        cos_theta * INV_PI
    } else {
        0.0
    }
}

/// Inverse of [`sample_cosine_hemisphere`].
#[must_use]
pub fn invert_cosine_hemisphere_sample(w: Vec3) -> Vec2 {
    invert_concentric_disk(Vec2::new(w.x, w.y))
}

/// Cosine-power ("Phong lobe") direction about +z with exponent `n`:
/// cosθ = u₀^(1/(n+1)), φ = 2π u₁.
#[inline]
#[must_use]
pub fn sample_phong_lobe(u: Vec2, n: f32) -> Vec3 {
    let cos_theta = libm::powf(u.x, 1.0 / (n + 1.0));
    let sin_theta = safe_sqrt(1.0 - cos_theta * cos_theta);
    let (sin_phi, cos_phi) = super::sin_cos(2.0 * PI * u.y);
    Vec3::new(sin_theta * cos_phi, sin_theta * sin_phi, cos_theta)
}

/// Density of [`sample_phong_lobe`]: (n+1)/(2π)·cosⁿθ for cosθ > 0.
#[inline]
#[must_use]
pub fn phong_lobe_pdf(cos_theta: f32, n: f32) -> f32 {
    let power = if cos_theta > 0.0 {
        libm::powf(cos_theta, n)
    } else {
        0.0
    };
    phong_lobe_pdf_of_power(cos_theta, power, n)
}

/// [`phong_lobe_pdf`] given `power = cos_theta^n` (computed once for the BSDF value too).
#[inline]
#[must_use]
pub fn phong_lobe_pdf_of_power(cos_theta: f32, power: f32, n: f32) -> f32 {
    if cos_theta > 0.0 {
        (n + 1.0) * INV_2PI * power
    } else {
        0.0
    }
}

/// Inverse of [`sample_phong_lobe`].
#[must_use]
pub fn invert_phong_lobe_sample(w: Vec3, n: f32) -> Vec2 {
    let mut phi = libm::atan2f(w.y, w.x);
    if phi < 0.0 {
        phi += 2.0 * PI;
    }
    Vec2::new(libm::powf(w.z.max(0.0), n + 1.0), phi * INV_2PI)
}

/// Uniform barycentrics `(b1, b2)` on a triangle, as TinyRender's `squareToUniformTriangle`:
/// `(1 − √(1−u₀), √(1−u₀)·u₁)`. The point is `p0·(1−b1−b2) + p1·b1 + p2·b2`.
#[inline]
#[must_use]
pub fn sample_uniform_triangle(u: Vec2) -> Vec2 {
    let s = safe_sqrt(1.0 - u.x);
    Vec2::new(1.0 - s, s * u.y)
}

/// Density of [`sample_uniform_triangle`] per unit area of a triangle of area `area`.
#[inline]
#[must_use]
pub fn uniform_triangle_pdf(area: f32) -> f32 {
    1.0 / area
}

/// Inverse of [`sample_uniform_triangle`].
#[must_use]
pub fn invert_uniform_triangle_sample(b: Vec2) -> Vec2 {
    let s = 1.0 - b.x;
    let u1 = if s > 0.0 { b.y / s } else { 0.0 };
    Vec2::new(1.0 - s * s, u1)
}

/// Uniform direction on the unit sphere (used by tests and light tracing).
#[inline]
#[must_use]
pub fn sample_uniform_sphere(u: Vec2) -> Vec3 {
    let z = 1.0 - 2.0 * u.x;
    let r = safe_sqrt(1.0 - z * z);
    let (sin_phi, cos_phi) = super::sin_cos(2.0 * PI * u.y);
    Vec3::new(r * cos_phi, r * sin_phi, z)
}

/// Density of [`sample_uniform_sphere`].
#[inline]
#[must_use]
pub fn uniform_sphere_pdf() -> f32 {
    0.25 * INV_PI
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(n: usize) -> impl Iterator<Item = Vec2> {
        (0..n * n).map(move |i| {
            Vec2::new(
                ((i % n) as f32 + 0.5) / n as f32,
                ((i / n) as f32 + 0.5) / n as f32,
            )
        })
    }

    #[test]
    fn cosine_hemisphere_round_trips() {
        for u in grid(37) {
            let w = sample_cosine_hemisphere(u);
            assert!((w.length() - 1.0).abs() < 1e-5);
            let v = invert_cosine_hemisphere_sample(w);
            assert!((u - v).abs().max_element() < 1e-3, "{u} -> {w} -> {v}");
        }
    }

    #[test]
    fn phong_lobe_round_trips() {
        for n in [1.0, 30.0, 1000.0] {
            for u in grid(23) {
                let w = sample_phong_lobe(u, n);
                assert!((w.length() - 1.0).abs() < 1e-5);
                let v = invert_phong_lobe_sample(w, n);
                assert!((u - v).abs().max_element() < 2e-3, "n={n} {u} -> {v}");
            }
        }
    }

    #[test]
    fn uniform_triangle_round_trips_and_stays_inside() {
        for u in grid(31) {
            let b = sample_uniform_triangle(u);
            assert!(b.x >= 0.0 && b.y >= 0.0 && b.x + b.y <= 1.0 + 1e-6);
            let v = invert_uniform_triangle_sample(b);
            assert!((u - v).abs().max_element() < 1e-3);
        }
    }

    /// Midpoint-rule integral of a direction pdf over the sphere in (cosθ, φ).
    fn integrate_sphere(pdf: impl Fn(Vec3) -> f32) -> f64 {
        let (nt, np) = (2000, 64);
        let mut sum = 0.0f64;
        for i in 0..nt {
            let z = -1.0 + 2.0 * (i as f32 + 0.5) / nt as f32;
            let r = safe_sqrt(1.0 - z * z);
            for j in 0..np {
                let phi = 2.0 * PI * (j as f32 + 0.5) / np as f32;
                let w = Vec3::new(r * libm::cosf(phi), r * libm::sinf(phi), z);
                sum += f64::from(pdf(w));
            }
        }
        sum * (2.0 / nt as f64) * (2.0 * core::f64::consts::PI / np as f64)
    }

    #[test]
    fn pdfs_integrate_to_one() {
        let c = integrate_sphere(|w| cosine_hemisphere_pdf(w.z));
        assert!((c - 1.0).abs() < 1e-3, "{c}");
        for n in [0.0, 1.0, 30.0, 300.0] {
            let p = integrate_sphere(|w| phong_lobe_pdf(w.z, n));
            assert!((p - 1.0).abs() < 1e-2, "n={n}: {p}");
        }
        let s = integrate_sphere(|_| uniform_sphere_pdf());
        assert!((s - 1.0).abs() < 1e-4);
    }
}
