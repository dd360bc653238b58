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

/// A ray prepared for [`intersect_triangle`]: the permutation that makes the largest
/// direction component z and the shear that maps the direction to +z depend only on the ray,
/// so a traversal computes them once instead of once per triangle (same values, bit for bit).
#[derive(Clone, Copy, Debug)]
pub struct WatertightRay {
    pub(super) o: Vec3,
    pub(super) k: [usize; 3],
    pub(super) sx: f32,
    pub(super) sy: f32,
    pub(super) sz: f32,
}

impl WatertightRay {
    #[inline]
    #[must_use]
    pub fn new(o: Vec3, d: Vec3) -> Self {
        let kz = max_dimension(d.abs());
        let kx = if kz == 2 { 0 } else { kz + 1 };
        let ky = if kx == 2 { 0 } else { kx + 1 };
        let dp = permute(d, kx, ky, kz);
        // Shear so the ray direction becomes +z.
        let sz = 1.0 / dp.z;
        Self {
            o,
            k: [kx, ky, kz],
            sx: -dp.x * sz,
            sy: -dp.y * sz,
            sz,
        }
    }

    /// Watertight ray–triangle intersection (Woop, Benthin and Wald, JCGT 2013, as in
    /// pbrt-v4): rays through a shared edge or vertex hit at least one of the triangles that
    /// share it, and `t` is accepted only when it is provably positive given the rounding error.
    #[inline(always)]
    #[must_use]
    pub fn intersect(&self, t_max: f32, p0: Vec3, p1: Vec3, p2: Vec3) -> Option<TriangleHit> {
        let [kx, ky, kz] = self.k;
        let (o, sx, sy, sz) = (self.o, self.sx, self.sy, self.sz);
        let mut a = permute(p0 - o, kx, ky, kz);
        let mut b = permute(p1 - o, kx, ky, kz);
        let mut c = permute(p2 - o, kx, ky, kz);
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
        // Largest |z| of the translated vertices in world units, before z is scaled to ray
        // parameter units below: the shear `x + Sx·z` (|Sx| ≤ 1) carries an error of this size.
        let max_z_world = a.z.abs().max(b.z.abs()).max(c.z.abs());
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
        // Conservative check that t > 0 (pbrt-v4 §6.8.4). `max_zt` is in units of the ray
        // parameter (z scaled by 1/d.z), x, y and the sheared-coordinate errors are in world units.
        // pbrt-v4 adds `max_zt` to the x and y errors, which mixes the two and is only right for
        // |d| ≈ 1: for a short unnormalised direction (a shadow ray `target − origin` in a scene of
        // size 1e-4) the bound grew as 1/|d| and rejected every hit with t below ~0.04, and for a
        // long one it shrank as 1/|d|. The shear error is bounded with the unscaled z instead.
        let max_zt = a.z.abs().max(b.z.abs()).max(c.z.abs());
        let delta_z = gamma(3) * max_zt;
        let max_xt = a.x.abs().max(b.x.abs()).max(c.x.abs());
        let max_yt = a.y.abs().max(b.y.abs()).max(c.y.abs());
        let delta_x = gamma(5) * (max_xt + max_z_world);
        let delta_y = gamma(5) * (max_yt + max_z_world);
        let delta_e = 2.0 * (gamma(2) * max_xt * max_yt + delta_y * max_xt + delta_x * max_yt);
        let max_e = e0.abs().max(e1.abs()).max(e2.abs());
        let delta_t =
            3.0 * (gamma(3) * max_e * max_zt + delta_e * max_zt + delta_z * max_e) * inv_det.abs();
        if t <= delta_t {
            return None;
        }
        Some(TriangleHit { t, b1, b2 })
    }
}

/// [`WatertightRay::intersect`] for a single triangle.
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
    WatertightRay::new(o, d).intersect(t_max, p0, p1, p2)
}

/// Absolute error bound of a point computed as `b0·p0 + b1·p1 + b2·p2` (pbrt-v4 §6.8.5).
/// [`triangle_point`] computes the same point with a much smaller error far from the origin.
#[inline]
#[must_use]
pub fn triangle_point_error(b0: f32, b1: f32, b2: f32, p0: Vec3, p1: Vec3, p2: Vec3) -> Vec3 {
    ((p0 * b0).abs() + (p1 * b1).abs() + (p2 * b2).abs()) * gamma(7)
}

/// The point with barycentrics `(b1, b2)`, computed as `p0 + (b1·(p1 − p0) + b2·(p2 − p0))`,
/// and its absolute error bound per axis, `γ₁·|p0| + γ₆·(|b1·(p1 − p0)| + |b2·(p2 − p0)|)`:
/// half an ulp of the coordinates plus a few ulps of the offset within the triangle.
///
/// The symmetric form `b0·p0 + b1·p1 + b2·p2` rounds three products of the size of the
/// coordinates, and its bound (`γ₇·Σ|bᵢ·pᵢ|`, pbrt-v4) is 7 half-ulps of the coordinates. Far
/// from the origin, where the coordinates are large and the triangle small in comparison, ray
/// origins are offset by that bound, so the form set the offsets: at 1e5 they were 0.04, 2%
/// of a Cornell box, enough to move its shadows visibly (a translated box rendered 16% darker
/// in a penumbra). Differences of nearby vertices are nearly exact, and only the final
/// addition rounds at the scale of the coordinates.
#[inline]
#[must_use]
pub fn triangle_point(b1: f32, b2: f32, p0: Vec3, p1: Vec3, p2: Vec3) -> (Vec3, Vec3) {
    let x = (p1 - p0) * b1;
    let y = (p2 - p0) * b2;
    let p = p0 + (x + y);
    (p, p0.abs() * gamma(1) + (x.abs() + y.abs()) * gamma(6))
}

/// Barycentrics of a point of the triangle from which rays can leave safely: `b` itself when
/// it lies far enough inside every edge, otherwise `b` moved inside (only the coordinates
/// below their margin grow; the others give up the excess in proportion to their slack).
///
/// Why: near an edge where another surface meets the triangle (the corner of a room), a ray
/// leaving the triangle toward that surface escapes through the corner in two ways:
/// - The point, computed with an error of up to `p_err` in every direction (tangentially
///   too), lies on or beyond the other surface's plane. The offset along the normal
///   ([`super::offset_ray_origin`]) only handles the triangle's own plane. At large
///   coordinates this is common: at 1e5 the spacing of f32 is 0.0078, and a white furnace
///   translated there lost 1% of its energy through its edges.
/// - The point is inside, but so close to the other surface that [`intersect_triangle`]
///   cannot prove the hit's t positive and rejects it. Its bound is about 60·ε times the size
///   of the triangle hit (measured worst case); a furnace scaled by 1e-4 leaked this way.
///
/// The margin from edge i is therefore `2·|m_i|·p_err + γ₂₅₆·L`, where `m_i` is the edge's
/// in-plane unit normal and `L` the longest edge (a stand-in for the size of the neighbouring
/// triangle; a much larger neighbour can still leak, rarely). In barycentrics, with the
/// distance to edge i being `b_i·2A/|e_i|`: `β_i = (2·(|n × e_i|·p_err) + γ₂₅₆·L·|e_i|)/2A`.
/// Both terms are a few ulps of the coordinates or of the triangle. A triangle too thin for
/// the margins (Σβ ≥ 1) gets them scaled down to fit: the point moves to mid-width.
#[inline]
#[must_use]
pub fn inset_barycentrics(b: [f32; 3], p: [Vec3; 3], ng: Vec3, p_err: Vec3) -> [f32; 3] {
    let area2 = (p[1] - p[0]).cross(p[2] - p[0]).length();
    if !(area2 > 0.0 && area2.is_finite()) || ng == Vec3::ZERO {
        return b;
    }
    let e = [p[2] - p[1], p[0] - p[2], p[1] - p[0]];
    let longest = crate::math::sqrt(
        e[0].length_squared()
            .max(e[1].length_squared())
            .max(e[2].length_squared()),
    );
    // Most points lie far inside: every margin below is at most
    // `longest·(2·Σp_err + γ₂₅₆·longest)/area2` (each component of `n × e` is at most |e|), so
    // a point above that bound, with 1% to spare for rounding, is returned without the
    // per-edge work. The result is the same as the full computation's.
    let bound = longest * (2.0 * (p_err.x + p_err.y + p_err.z) + gamma(256) * longest) / area2;
    if b[0].min(b[1]).min(b[2]) >= 1.01 * bound {
        return b;
    }
    inset_with_margins(b, e, longest, area2, ng, p_err)
}

/// [`inset_barycentrics`] from its edge vectors, longest edge and doubled area, without the
/// fast acceptance (kept separate so a test can check that the two agree).
#[inline]
fn inset_with_margins(
    b: [f32; 3],
    e: [Vec3; 3],
    longest: f32,
    area2: f32,
    ng: Vec3,
    p_err: Vec3,
) -> [f32; 3] {
    let mut beta = [0.0f32; 3];
    for (m, e) in beta.iter_mut().zip(e) {
        let dist_err = 2.0 * ng.cross(e).abs().dot(p_err);
        *m = (dist_err + gamma(256) * longest * e.length()) / area2;
    }
    let sum_beta = beta[0] + beta[1] + beta[2];
    if !sum_beta.is_finite() {
        return b;
    }
    if sum_beta >= 0.5 {
        // Too thin for the margins: keep their proportions, leave room to move.
        beta = beta.map(|m| m * (0.5 / sum_beta));
    }
    if (0..3).all(|i| b[i] >= beta[i]) {
        return b;
    }
    let c = [b[0].max(beta[0]), b[1].max(beta[1]), b[2].max(beta[2])];
    let slack = [c[0] - beta[0], c[1] - beta[1], c[2] - beta[2]];
    // Σc − 1 ≤ Σβ < Σslack = Σc − Σβ (as Σβ ≤ 1/2 and Σc ≥ 1), so every coordinate keeps
    // part of its slack and stays at or above its margin.
    let excess = c[0] + c[1] + c[2] - 1.0;
    let k = excess / (slack[0] + slack[1] + slack[2]);
    [
        c[0] - slack[0] * k,
        c[1] - slack[1] * k,
        c[2] - slack[2] * k,
    ]
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
    fn inset_keeps_interior_points_and_moves_edge_points_inside() {
        let p = [Vec3::ZERO, Vec3::X, Vec3::Y];
        let err = Vec3::splat(1e-3);
        // Far from the edges: unchanged, bit for bit.
        assert_eq!(
            inset_barycentrics([0.4, 0.3, 0.3], p, Vec3::Z, err),
            [0.4, 0.3, 0.3]
        );
        // On (and beyond) an edge and at a vertex: inside by the margin, summing to 1.
        for b in [[0.5, 0.5, 0.0], [0.5, 0.5000001, -1e-7], [1.0, 0.0, 0.0]] {
            let c = inset_barycentrics(b, p, Vec3::Z, err);
            assert!(c.iter().all(|&x| x >= 1.9e-3), "{b:?} -> {c:?}");
            assert!((c.iter().sum::<f32>() - 1.0).abs() < 1e-6, "{c:?}");
            let moved = (p[1] * c[1] + p[2] * c[2]) - (p[1] * b[1] + p[2] * b[2]);
            assert!(moved.length() < 1e-2, "{b:?} moved by {moved}");
        }
        // A triangle narrower than its error: inside all the same, summing to 1.
        let c = inset_barycentrics([1.0, 0.0, 0.0], p, Vec3::Z, Vec3::splat(1.0));
        assert!(c.iter().all(|&x| x > 0.1), "{c:?}");
        assert!((c.iter().sum::<f32>() - 1.0).abs() < 1e-6, "{c:?}");
    }

    #[test]
    fn inset_fast_acceptance_agrees_with_the_margins() {
        // Random triangles (some thin), points inside, near and on edges, and error bounds
        // from tiny to large: the fast path must return what the full computation returns.
        let mut state = 0x1234_5678_9abc_def0u64;
        let mut rnd = || {
            state = crate::sampler::mix64(state.wrapping_add(0x9E37_79B9_7F4A_7C15));
            (state >> 40) as f32 / (1u64 << 24) as f32
        };
        let mut fast = 0;
        for _ in 0..200_000 {
            let scale = 10f32.powf(rnd() * 8.0 - 4.0);
            let mut v = || Vec3::new(rnd(), rnd(), rnd()) * scale;
            let p = [v(), v(), v()];
            let ng = (p[1] - p[0]).cross(p[2] - p[0]).normalize_or_zero();
            let (x, y) = (rnd().powi(4), rnd().powi(4));
            let b = if x + y <= 1.0 {
                [1.0 - x - y, x, y]
            } else {
                [0.0, 1.0 - y, y]
            };
            let p_err = Vec3::new(rnd(), rnd(), rnd()) * scale * 10f32.powf(-7.0 + rnd() * 6.0);
            let area2 = (p[1] - p[0]).cross(p[2] - p[0]).length();
            if !(area2 > 0.0 && area2.is_finite()) || ng == Vec3::ZERO {
                continue;
            }
            let e = [p[2] - p[1], p[0] - p[2], p[1] - p[0]];
            let longest = e[0].length().max(e[1].length()).max(e[2].length());
            let full = inset_with_margins(b, e, longest, area2, ng, p_err);
            let got = inset_barycentrics(b, p, ng, p_err);
            assert_eq!(
                got.map(f32::to_bits),
                full.map(f32::to_bits),
                "{p:?} {b:?} {p_err:?}"
            );
            fast += usize::from(got == b);
        }
        // Both outcomes were exercised.
        assert!(fast > 10_000 && fast < 190_000, "{fast} unchanged");
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
