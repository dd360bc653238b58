use crate::math::gamma;
use glam::{DVec3, Vec3};

/// A ray–triangle hit: distance along the ray and barycentrics of vertices 1 and 2
/// (the point is `p0·(1−b1−b2) + p1·b1 + p2·b2`, as in TinyRender).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriangleHit {
    pub t: f32,
    pub b1: f32,
    pub b2: f32,
}

#[inline]
fn permute(v: Vec3, kx: usize, ky: usize, kz: usize) -> Vec3 {
    Vec3::new(v[kx], v[ky], v[kz])
}

#[inline]
fn max_dimension(v: Vec3) -> usize {
    if v.x > v.y {
        if v.x > v.z {
            0
        } else {
            2
        }
    } else if v.y > v.z {
        1
    } else {
        2
    }
}

/// Watertight ray–triangle intersection (Woop, Benthin and Wald, JCGT 2013, as in pbrt-v4):
/// rays through a shared edge or vertex hit at least one of the triangles that share it, and
/// `t` is accepted only when it is provably positive given the rounding error.
#[inline]
#[must_use]
pub fn intersect_triangle(
    o: Vec3,
    d: Vec3,
    t_max: f32,
    p0: Vec3,
    p1: Vec3,
    p2: Vec3,
) -> Option<TriangleHit> {
    let kz = max_dimension(d.abs());
    let kx = if kz == 2 { 0 } else { kz + 1 };
    let ky = if kx == 2 { 0 } else { kx + 1 };
    let dp = permute(d, kx, ky, kz);
    let mut a = permute(p0 - o, kx, ky, kz);
    let mut b = permute(p1 - o, kx, ky, kz);
    let mut c = permute(p2 - o, kx, ky, kz);
    // Shear so the ray direction becomes +z.
    let sz = 1.0 / dp.z;
    let sx = -dp.x * sz;
    let sy = -dp.y * sz;
    a.x += sx * a.z;
    a.y += sy * a.z;
    b.x += sx * b.z;
    b.y += sy * b.z;
    c.x += sx * c.z;
    c.y += sy * c.z;
    // Edge functions. Plain products (no FMA) keep e exactly antisymmetric between the two
    // triangles that share an edge, which is what makes the test watertight.
    let mut e0 = b.x * c.y - b.y * c.x;
    let mut e1 = c.x * a.y - c.y * a.x;
    let mut e2 = a.x * b.y - a.y * b.x;
    if e0 == 0.0 || e1 == 0.0 || e2 == 0.0 {
        // Exactly on an edge in f32: decide in f64.
        let (ad, bd, cd) = (a.as_dvec3(), b.as_dvec3(), c.as_dvec3());
        let ed = |p: DVec3, q: DVec3| (p.x * q.y - p.y * q.x) as f32;
        e0 = ed(bd, cd);
        e1 = ed(cd, ad);
        e2 = ed(ad, bd);
    }
    if (e0 < 0.0 || e1 < 0.0 || e2 < 0.0) && (e0 > 0.0 || e1 > 0.0 || e2 > 0.0) {
        return None;
    }
    let det = e0 + e1 + e2;
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    a.z *= sz;
    b.z *= sz;
    c.z *= sz;
    let t_scaled = e0 * a.z + e1 * b.z + e2 * c.z;
    if det < 0.0 && (t_scaled >= 0.0 || t_scaled < t_max * det) {
        return None;
    }
    if det > 0.0 && (t_scaled <= 0.0 || t_scaled > t_max * det) {
        return None;
    }
    let inv_det = 1.0 / det;
    let b1 = e1 * inv_det;
    let b2 = e2 * inv_det;
    let t = t_scaled * inv_det;
    // Conservative check that t > 0 (pbrt-v4 §6.8.4).
    let max_zt = a.z.abs().max(b.z.abs()).max(c.z.abs());
    let delta_z = gamma(3) * max_zt;
    let max_xt = a.x.abs().max(b.x.abs()).max(c.x.abs());
    let max_yt = a.y.abs().max(b.y.abs()).max(c.y.abs());
    let delta_x = gamma(5) * (max_xt + max_zt);
    let delta_y = gamma(5) * (max_yt + max_zt);
    let delta_e = 2.0 * (gamma(2) * max_xt * max_yt + delta_y * max_xt + delta_x * max_yt);
    let max_e = e0.abs().max(e1.abs()).max(e2.abs());
    let delta_t =
        3.0 * (gamma(3) * max_e * max_zt + delta_e * max_zt + delta_z * max_e) * inv_det.abs();
    if t <= delta_t {
        return None;
    }
    Some(TriangleHit { t, b1, b2 })
}

/// Absolute error bound of a point computed as `b0·p0 + b1·p1 + b2·p2` (pbrt-v4 §6.8.5).
#[inline]
#[must_use]
pub fn triangle_point_error(b0: f32, b1: f32, b2: f32, p0: Vec3, p1: Vec3, p2: Vec3) -> Vec3 {
    ((p0 * b0).abs() + (p1 * b1).abs() + (p2 * b2).abs()) * gamma(7)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hits_inside_and_misses_outside() {
        let (p0, p1, p2) = (Vec3::ZERO, Vec3::X, Vec3::Y);
        let h = intersect_triangle(
            Vec3::new(0.25, 0.25, 1.0),
            -Vec3::Z,
            f32::INFINITY,
            p0,
            p1,
            p2,
        )
        .unwrap();
        assert!((h.t - 1.0).abs() < 1e-6);
        assert!((h.b1 - 0.25).abs() < 1e-6 && (h.b2 - 0.25).abs() < 1e-6);
        assert!(intersect_triangle(
            Vec3::new(0.75, 0.75, 1.0),
            -Vec3::Z,
            f32::INFINITY,
            p0,
            p1,
            p2
        )
        .is_none());
        // Behind the origin and beyond t_max.
        assert!(intersect_triangle(Vec3::new(0.2, 0.2, 1.0), Vec3::Z, 10.0, p0, p1, p2).is_none());
        assert!(intersect_triangle(Vec3::new(0.2, 0.2, 1.0), -Vec3::Z, 0.5, p0, p1, p2).is_none());
        // Degenerate triangle never hits.
        assert!(intersect_triangle(Vec3::new(0.0, 0.0, 1.0), -Vec3::Z, 10.0, p0, p0, p1).is_none());
    }

    #[test]
    fn shared_edge_is_watertight() {
        // Two triangles sharing the diagonal of the unit square; rays exactly on the diagonal.
        let (a, b, c, d) = (Vec3::ZERO, Vec3::X, Vec3::ONE.with_z(0.0), Vec3::Y);
        for i in 0..=1000 {
            let s = i as f32 / 1000.0;
            let dir = Vec3::new(0.013, -0.007, -1.0);
            let o = Vec3::new(s, s, 0.0) - dir * 2.0;
            let h1 = intersect_triangle(o, dir, f32::INFINITY, a, b, c);
            let h2 = intersect_triangle(o, dir, f32::INFINITY, a, c, d);
            if (0.001..0.999).contains(&s) {
                assert!(h1.is_some() || h2.is_some(), "leak at s = {s}");
            }
        }
    }
}
