//! Area emitters: emissive triangles sampled from a CDF in a caller slice (FORMAT.md §5).

use crate::geometry::triangle_point_error;
use crate::math::{warp, AreaPdf};
use crate::scene::SceneView;
use crate::Rgb;
use glam::{Vec2, Vec3};

/// A point sampled on an emitter.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EmitterSample {
    pub p: Vec3,
    pub p_err: Vec3,
    /// Geometric normal of the emitting triangle.
    pub ng: Vec3,
    /// Interpolated shading normal: the side it points to is the emitting side.
    pub n: Vec3,
    pub radiance: Rgb,
    /// Density of `p` per unit area over all emitters. The integrator converts it to solid
    /// angle with [`AreaPdf::to_solid_angle`].
    pub pdf: AreaPdf,
    pub triangle: u32,
}

/// Index of the first CDF entry above `u·total`, skipping zero-probability entries.
#[inline]
fn find_interval(cdf: &[f32], u: f32) -> usize {
    let total = cdf[cdf.len() - 1];
    let target = u * total;
    // partition_point: number of entries <= target.
    cdf.partition_point(|&c| c <= target).min(cdf.len() - 1)
}

/// Picks an emissive triangle with `u_select` from the scene's emitter CDF, then a uniform point
/// on it with `u_pos`. `None` when the scene has no emitter with positive area.
#[inline]
#[must_use]
pub fn sample_emitter(scene: &SceneView<'_>, u_select: f32, u_pos: Vec2) -> Option<EmitterSample> {
    let cdf = scene.emitter_cdf;
    // Written so that a NaN total also means "no emitter".
    if cdf.is_empty() || cdf[cdf.len() - 1].is_nan() || cdf[cdf.len() - 1] <= 0.0 {
        return None;
    }
    let i = find_interval(cdf, u_select);
    let prob = (cdf[i] - if i > 0 { cdf[i - 1] } else { 0.0 }) / cdf[cdf.len() - 1];
    let triangle = scene.emitter_triangles[i];
    let [p0, p1, p2] = scene.triangle_vertices(triangle);
    let cross = (p1 - p0).cross(p2 - p0);
    let area = 0.5 * cross.length();
    if area.is_nan() || area <= 0.0 || prob.is_nan() || prob <= 0.0 {
        return None;
    }
    let b = warp::sample_uniform_triangle(u_pos);
    let b0 = 1.0 - b.x - b.y;
    let p = p0 * b0 + p1 * b.x + p2 * b.y;
    let [i0, i1, i2] = scene.triangles[triangle as usize];
    let nrm = |k: u32| scene.normals[k as usize];
    let ng = cross / (2.0 * area);
    let n = (nrm(i0) * b0 + nrm(i1) * b.x + nrm(i2) * b.y).normalize_or_zero();
    let material = scene.material(scene.triangle_materials[triangle as usize]);
    Some(EmitterSample {
        p,
        p_err: triangle_point_error(b0, b.x, b.y, p0, p1, p2),
        ng,
        n: if n == Vec3::ZERO { ng } else { n },
        radiance: material.emission,
        pdf: AreaPdf(prob / area),
        triangle,
    })
}

/// Density per unit area with which [`sample_emitter`] picks points on `triangle` (0 for a
/// triangle that is not sampled). `emitter_triangles` is sorted ascending, so this is a binary
/// search; multiple importance sampling calls it for emitters hit by BSDF sampling.
#[inline]
#[must_use]
pub fn emitter_pdf(scene: &SceneView<'_>, triangle: u32) -> AreaPdf {
    let cdf = scene.emitter_cdf;
    let Ok(i) = scene.emitter_triangles.binary_search(&triangle) else {
        return AreaPdf(0.0);
    };
    let total = cdf[cdf.len() - 1];
    let prob = (cdf[i] - if i > 0 { cdf[i - 1] } else { 0.0 }) / total;
    let [p0, p1, p2] = scene.triangle_vertices(triangle);
    let area = 0.5 * (p1 - p0).cross(p2 - p0).length();
    if area > 0.0 && prob > 0.0 {
        AreaPdf(prob / area)
    } else {
        AreaPdf(0.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interval_search_skips_empty_entries() {
        let cdf = [0.25, 0.25, 0.75, 1.0];
        assert_eq!(find_interval(&cdf, 0.0), 0);
        assert_eq!(find_interval(&cdf, 0.2499), 0);
        assert_eq!(find_interval(&cdf, 0.25), 2);
        assert_eq!(find_interval(&cdf, 0.8), 3);
        assert_eq!(find_interval(&cdf, 0.999_999_9), 3);
    }
}
