//! Area emitters: emissive triangles sampled from a CDF in a caller slice (FORMAT.md §5).

use crate::geometry::triangle_point;
use crate::math::{warp, AreaPdf, Frame, SolidAnglePdf};
use crate::sampler::lanes_of;
use crate::scene::SceneView;
use crate::simd::{Isa, Lanes};
use crate::vec_lanes::{max_zero, triangle_point as triangle_point_lanes, N as LANES, V3};
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
///
/// That is the number of entries `<= u·total` (a prefix, the CDF being non-decreasing:
/// `SceneView::validate`), found by galloping out from the entry a CDF of equal steps would
/// give, and then a binary search between the last two probes: the answer of a binary search
/// over the whole CDF, with one or two comparisons instead of `log2 n` dependent ones when the
/// emitters have nearly equal power, as a light's triangles of a subdivided quad do.
#[inline]
fn find_interval(cdf: &[f32], u: f32) -> usize {
    let n = cdf.len();
    let target = u * cdf[n - 1];
    let below = |i: usize| cdf[i] <= target;
    let guess = ((u * n as f32) as usize).min(n - 1);
    // Entries before `lo` are `<= target`, entries from `hi` on are above it.
    let (lo, hi) = if below(guess) {
        let (mut lo, mut step) = (guess + 1, 1);
        loop {
            let probe = guess + step;
            if probe >= n {
                break (lo, n);
            }
            if !below(probe) {
                break (lo, probe);
            }
            lo = probe + 1;
            step *= 2;
        }
    } else {
        let (mut hi, mut step) = (guess, 1);
        loop {
            if step > guess {
                break (0, hi);
            }
            let probe = guess - step;
            if below(probe) {
                break (probe + 1, hi);
            }
            hi = probe;
            step *= 2;
        }
    };
    (lo + cdf[lo..hi].partition_point(|&c| c <= target)).min(n - 1)
}

/// Largest CDF that [`find_intervals`] searches in lanes.
const LANE_SEARCH_MAX: usize = 16;

/// [`find_interval`] of each lane's `u[l]`, in lanes for a CDF of at most
/// [`LANE_SEARCH_MAX`] entries: the number of entries `<= u·total` (the same product), counted
/// by one comparison per entry in every lane instead of a search whose branches go each lane's
/// own way (mispredicted half the time on a light of two triangles); a search per lane for
/// longer CDFs. The same indices for the lanes of `lanes` (other lanes: any valid index).
#[inline(always)]
fn find_intervals<L: Lanes<LANES>>(
    isa: L::Isa,
    cdf: &[f32],
    u: &[f32; LANES],
    lanes: u32,
) -> [usize; LANES] {
    let n = cdf.len();
    let mut index = [0usize; LANES];
    if n > LANE_SEARCH_MAX {
        for l in lanes_of(lanes) {
            index[l] = find_interval(cdf, u[l]);
        }
        return index;
    }
    let target = L::new(isa, *u) * L::splat(isa, cdf[n - 1]);
    let (zero, one) = (L::splat(isa, 0.0), L::splat(isa, 1.0));
    // Counts of at most 16 as floats: exact.
    let mut count = zero;
    for &c in cdf {
        count += L::select(L::splat(isa, c).simd_le(target), one, zero);
    }
    for (i, c) in index.iter_mut().zip(count.to_array()) {
        *i = (c as usize).min(n - 1);
    }
    index
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
    let (p, p_err) = triangle_point(b.x, b.y, p0, p1, p2);
    let [i0, i1, i2] = scene.triangles[triangle as usize];
    let nrm = |k: u32| scene.normals[k as usize];
    let ng = cross / (2.0 * area);
    let n = (nrm(i0) * b0 + nrm(i1) * b.x + nrm(i2) * b.y).normalize_or_zero();
    let material = scene.material(scene.triangle_materials[triangle as usize]);
    Some(EmitterSample {
        p,
        p_err,
        ng,
        n: if n == Vec3::ZERO { ng } else { n },
        radiance: material.emission,
        pdf: AreaPdf(prob / area),
        triangle,
    })
}

/// Eight points sampled on the emitters ([`sample_emitter_lanes`]), a lane each.
#[derive(Clone, Copy)]
pub(crate) struct EmitterLanes<L> {
    pub p: V3<L>,
    pub p_err: V3<L>,
    pub ng: V3<L>,
    pub n: V3<L>,
    pub radiance: V3<L>,
    /// The density of `p` per unit area over all emitters.
    pub pdf: L,
}

/// [`sample_emitter`] for the lanes of `lanes`, with `u_select[l]` and `(u_pos[0][l],
/// u_pos[1][l])` in lane `l`: the same samples, bit for bit, the search of the CDF and the
/// gather of the triangle lane by lane, the arithmetic in the lanes of `isa`. Returns them and
/// the lanes that have one (bits).
#[inline(always)]
pub(crate) fn sample_emitter_lanes<I: Isa>(
    isa: I,
    scene: &SceneView<'_>,
    lanes: u32,
    u_select: &[f32; LANES],
    u_pos: [&[f32; LANES]; 2],
) -> Option<(EmitterLanes<I::Eight>, u32)> {
    type L<I> = <I as Isa>::Eight;
    let cdf = scene.emitter_cdf;
    if lanes == 0 || cdf.is_empty() || cdf[cdf.len() - 1].is_nan() || cdf[cdf.len() - 1] <= 0.0 {
        return None;
    }
    let index = find_intervals::<L<I>>(isa, cdf, u_select, lanes);
    Some(EmitterTable::<L<I>>::of_entries(isa, scene, &index).sample(isa, lanes, u_pos))
}

/// The emitter CDF's entries of a scene with at most [`LANES`] of them, entry `j` in lane
/// `j`: what [`sample_emitter_lanes`] gathers and derives per lane from the triangle a lane
/// picks (its corners, edges, area, geometric normal, vertex normals and radiance, and the
/// probability of picking it), computed once for the lanes of many draws
/// ([`sample_emitter_table`]), which then move each entry to the lanes that picked it
/// ([`Lanes::permute`]) instead of gathering it lane by lane. The Cornell boxes' lights are
/// two triangles.
///
/// Measured (AMD EPYC Zen 5, sse4_2 avx avx2 fma avx512f/dq/bw/vl, 2026-12-07, `ember render
/// --integrator mis --threads 1`, 5 alternating runs against the per-lane gather, the same
/// EXRs): the project's Cornell box at 512², 16 spp, 2.93–2.99 s against 3.12–3.19 with
/// AVX-512 and 3.42–3.49 against 3.54–3.69 with `EMBER_SIMD=avx2`; at 4 spp 0.73–0.74
/// against 0.79–0.81; TinyRender's `cbox.obj` (320 × 240, 16 spp) 0.96–0.98 against
/// 1.01–1.02. The gather was 5% of a render; the table's samples are 1%.
#[derive(Clone, Copy)]
pub(crate) struct EmitterTable<L> {
    p0: V3<L>,
    e1: V3<L>,
    e2: V3<L>,
    cross: V3<L>,
    area: L,
    normals: [V3<L>; 3],
    radiance: V3<L>,
    prob: L,
}

impl<L: Lanes<LANES>> EmitterTable<L> {
    /// The table of `scene`'s emitters: `None` without emitters of positive total power or
    /// with more than [`LANES`] CDF entries.
    #[inline(always)]
    pub(crate) fn new(isa: L::Isa, scene: &SceneView<'_>) -> Option<Self> {
        let cdf = scene.emitter_cdf;
        let n = cdf.len();
        if n == 0 || n > LANES || cdf[n - 1].is_nan() || cdf[n - 1] <= 0.0 {
            return None;
        }
        // Lanes past the last entry repeat it (no lane picks them: `find_intervals` < n).
        let entries = core::array::from_fn(|j| j.min(n - 1));
        Some(Self::of_entries(isa, scene, &entries))
    }

    /// Lane `l` holding the CDF entry `entries[l]` of `scene` (each below the CDF's length,
    /// whose last entry is positive).
    #[inline(always)]
    fn of_entries(isa: L::Isa, scene: &SceneView<'_>, entries: &[usize; LANES]) -> Self {
        let cdf = scene.emitter_cdf;
        let upper: [f32; LANES] = entries.map(|i| cdf[i]);
        let lower: [f32; LANES] = entries.map(|i| if i > 0 { cdf[i - 1] } else { 0.0 });
        let triangles: [u32; LANES] = entries.map(|i| scene.emitter_triangles[i]);
        let corners = triangles.map(|t| scene.triangles[t as usize]);
        let vertex = |k: usize| V3::<L>::new(isa, |j| scene.positions[corners[j][k] as usize]);
        let normal = |k: usize| V3::<L>::new(isa, |j| scene.normals[corners[j][k] as usize]);
        let (p0, p1, p2) = (vertex(0), vertex(1), vertex(2));
        let (e1, e2) = (p1.sub(p0), p2.sub(p0));
        let cross = e1.cross(e2);
        let total = L::splat(isa, cdf[cdf.len() - 1]);
        Self {
            p0,
            e1,
            e2,
            cross,
            area: L::splat(isa, 0.5) * cross.dot(cross).sqrt(),
            normals: [normal(0), normal(1), normal(2)],
            radiance: V3::<L>::new(isa, |j| {
                let material = scene.triangle_materials[triangles[j] as usize];
                scene.material(material).emission
            }),
            prob: (L::new(isa, upper) - L::new(isa, lower)) / total,
        }
    }

    /// Lane `l` holding entry `index[l]` (below [`LANES`]) of the table.
    #[inline(always)]
    fn permuted(&self, isa: L::Isa, index: &[u32; LANES]) -> Self {
        let pick = |v: L| v.permute(isa, index);
        let pick3 = |v: &V3<L>| V3 {
            x: pick(v.x),
            y: pick(v.y),
            z: pick(v.z),
        };
        Self {
            p0: pick3(&self.p0),
            e1: pick3(&self.e1),
            e2: pick3(&self.e2),
            cross: pick3(&self.cross),
            area: pick(self.area),
            // Spelt out: a closure given to `map` may be left out of line, outside the AVX
            // function, and its lane operations become calls.
            normals: [
                pick3(&self.normals[0]),
                pick3(&self.normals[1]),
                pick3(&self.normals[2]),
            ],
            radiance: pick3(&self.radiance),
            prob: pick(self.prob),
        }
    }

    /// [`sample_emitter`]'s point on the triangle of each lane of `lanes`, from the numbers
    /// `u_pos`, and the lanes that have one (a positive area and pick probability).
    #[inline(always)]
    fn sample(&self, isa: L::Isa, lanes: u32, u_pos: [&[f32; LANES]; 2]) -> (EmitterLanes<L>, u32) {
        let lane = |x: f32| L::splat(isa, x);
        let (zero, one) = (lane(0.0), lane(1.0));
        let Self { area, prob, .. } = *self;
        // Refused where `area` or `prob` is NaN or not positive.
        let ok = area.simd_gt(zero) & prob.simd_gt(zero);
        // `warp::sample_uniform_triangle` and `triangle_point`.
        let s = max_zero(one - L::new(isa, *u_pos[0]), zero).sqrt();
        let (b1, b2) = (one - s, s * L::new(isa, *u_pos[1]));
        let b0 = one - b1 - b2;
        let (p, p_err) = triangle_point_lanes(isa, b1, b2, self.p0, self.e1, self.e2);
        let ng = self.cross.div(lane(2.0) * area);
        let n = V3::interpolated_normal(self.normals, [b0, b1, b2], ng, one, zero);
        let samples = EmitterLanes {
            p,
            p_err,
            ng,
            n,
            radiance: self.radiance,
            pdf: prob / area,
        };
        (samples, ok.to_bitmask() & lanes)
    }
}

/// [`sample_emitter_lanes`] from the scene's [`EmitterTable`] (`table`, made for `scene`):
/// the same samples, bit for bit.
#[inline(always)]
pub(crate) fn sample_emitter_table<I: Isa>(
    isa: I,
    scene: &SceneView<'_>,
    table: &EmitterTable<I::Eight>,
    lanes: u32,
    u_select: &[f32; LANES],
    u_pos: [&[f32; LANES]; 2],
) -> Option<(EmitterLanes<I::Eight>, u32)> {
    type L<I> = <I as Isa>::Eight;
    if lanes == 0 {
        return None;
    }
    let found = find_intervals::<L<I>>(isa, scene.emitter_cdf, u_select, lanes);
    let index = found.map(|i| i as u32);
    Some(table.permuted(isa, &index).sample(isa, lanes, u_pos))
}

/// Light leaving an emitter, for paths traced from the lights ([`sample_le`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EmissionSample {
    /// The point on the emitter (with its normals and error bound).
    pub point: EmitterSample,
    /// Unit world direction of the emitted light, on the emitting side.
    pub w: Vec3,
    /// Density of `w` per unit solid angle: cosine-weighted about the shading normal.
    pub pdf_dir: SolidAnglePdf,
}

/// Samples light leaving the emitters (pbrt's `SampleLe`): a point chosen as
/// [`sample_emitter`] does (`u_select`, `u_pos`; its `pdf` is the area density over all
/// emitters), then a cosine-weighted direction about its shading normal (`u_dir`), the side
/// it emits to (FORMAT.md §5; TinyRender's `sampleEmitterDirection`). `None` without
/// emitters, or when the direction falls behind the geometric surface (possible only where
/// the interpolated normal tilts away from it: such light would leak through the surface).
#[inline]
#[must_use]
pub fn sample_le(
    scene: &SceneView<'_>,
    u_select: f32,
    u_pos: Vec2,
    u_dir: Vec2,
) -> Option<EmissionSample> {
    let point = sample_emitter(scene, u_select, u_pos)?;
    let local = warp::sample_cosine_hemisphere(u_dir);
    let w = Frame::from_normal(point.n).to_world(local);
    let pdf_dir = SolidAnglePdf(warp::cosine_hemisphere_pdf(local.z));
    if w.dot(point.ng) <= 0.0 || pdf_dir.0 <= 0.0 {
        return None;
    }
    Some(EmissionSample { point, w, pdf_dir })
}

/// Density with which [`sample_le`] emits toward unit direction `w` from a point with shading
/// normal `n`, per unit solid angle (the position density is [`emitter_pdf`]).
#[inline]
#[must_use]
pub fn pdf_le_direction(n: Vec3, w: Vec3) -> SolidAnglePdf {
    SolidAnglePdf(warp::cosine_hemisphere_pdf(n.dot(w)))
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

/// Why [`build_emitter_table`] could not fill the table.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EmitterTableError {
    /// A triangle refers to a missing vertex.
    VertexIndex { triangle: usize, index: u32 },
    /// `triangle_materials` is not one entry per triangle.
    MaterialCount { triangles: usize, materials: usize },
    /// The output slices hold fewer than `needed` entries (or differ in length).
    Capacity { needed: usize, given: usize },
    /// `UniformPerObject` was given an object id count that differs from the triangle count.
    ObjectCount { triangles: usize, objects: usize },
    /// The weights do not sum to a finite number (an emitter's area overflows `f32`).
    NonFinite,
}

impl core::fmt::Display for EmitterTableError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            Self::VertexIndex { triangle, index } => {
                write!(f, "triangle {triangle} refers to missing vertex {index}")
            }
            Self::MaterialCount {
                triangles,
                materials,
            } => write!(f, "{triangles} triangles but {materials} material ids"),
            Self::Capacity { needed, given } => {
                write!(
                    f,
                    "emitter table needs {needed} entries but {given} were provided"
                )
            }
            Self::ObjectCount { triangles, objects } => {
                write!(f, "{triangles} triangles but {objects} object ids")
            }
            Self::NonFinite => write!(
                f,
                "the emitters' total weight is not finite (coordinates too large for f32)"
            ),
        }
    }
}

/// Area of a triangle, as the samplers compute it.
#[inline]
fn triangle_area(positions: &[Vec3], t: [u32; 3]) -> f32 {
    let [p0, p1, p2] = t.map(|i| positions[i as usize]);
    0.5 * (p1 - p0).cross(p2 - p0).length()
}

/// How [`build_emitter_table`] weights the emissive triangles it lists.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EmitterPolicy<'a> {
    /// Each triangle in proportion to its area: the same density over all emitting surface.
    Area,
    /// Each triangle in proportion to the power it emits, area × the average of its `Ke`
    /// components (pbrt-v4's power light sampler; brighter emitters get more samples).
    Power,
    /// TinyRender's rule: an emitter uniformly, then a triangle of it in proportion to area.
    /// `objects[t]` names the emitter (object) triangle `t` belongs to; an object is a run of
    /// consecutive triangles with one id (as an OBJ's objects are). An object emits when its triangles' material does (FORMAT.md §5)
    /// and its emitting area is positive.
    UniformPerObject { objects: &'a [u32] },
}

/// Fills the emitter table of [`SceneView`] (`emitter_triangles`, `emitter_cdf`) with every
/// triangle whose material emits (`emission(material id)` non-zero) and whose area is
/// positive, in ascending triangle order, weighted by `policy`. Returns the number of entries
/// written (0 when nothing emits). The weights are summed in f64 in triangle order, so the
/// table is a pure function of its inputs on every target.
///
/// # Errors
/// Missing vertices, a material id count (or object id count) that differs from the triangle
/// count, a non-finite total weight (coordinates near the `f32` limit), or output slices
/// shorter than the number of emitting triangles (the error says how many are needed; pass
/// empty slices to ask).
pub fn build_emitter_table(
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    triangle_materials: &[u32],
    emission: impl Fn(u32) -> Rgb,
    policy: EmitterPolicy<'_>,
    out_triangles: &mut [u32],
    out_cdf: &mut [f32],
) -> Result<usize, EmitterTableError> {
    if triangle_materials.len() != triangles.len() {
        return Err(EmitterTableError::MaterialCount {
            triangles: triangles.len(),
            materials: triangle_materials.len(),
        });
    }
    if let EmitterPolicy::UniformPerObject { objects } = policy {
        if objects.len() != triangles.len() {
            return Err(EmitterTableError::ObjectCount {
                triangles: triangles.len(),
                objects: objects.len(),
            });
        }
    }
    for (t, tri) in triangles.iter().enumerate() {
        if let Some(&index) = tri.iter().find(|&&v| v as usize >= positions.len()) {
            return Err(EmitterTableError::VertexIndex { triangle: t, index });
        }
    }
    // The area and emission of each emitting triangle, or `None` for the others.
    let emitting = |t: usize| {
        let area = triangle_area(positions, triangles[t]);
        let le = emission(triangle_materials[t]);
        (le != Rgb::ZERO && area > 0.0).then_some((area, le))
    };
    let needed = (0..triangles.len()).filter_map(emitting).count();
    let given = out_triangles.len().min(out_cdf.len());
    if given < needed {
        return Err(EmitterTableError::Capacity { needed, given });
    }
    let mut written = 0usize;
    let mut push = |t: usize, c: f64| {
        out_triangles[written] = t as u32;
        out_cdf[written] = c as f32;
        written += 1;
    };
    let mut acc = 0.0f64;
    match policy {
        EmitterPolicy::Area | EmitterPolicy::Power => {
            let weight = |area: f32, le: Rgb| match policy {
                EmitterPolicy::Power => f64::from(area) * (f64::from(le.x + le.y + le.z) / 3.0),
                _ => f64::from(area),
            };
            let total: f64 = (0..triangles.len())
                .filter_map(emitting)
                .map(|(a, le)| weight(a, le))
                .sum();
            if !total.is_finite() {
                return Err(EmitterTableError::NonFinite);
            }
            for t in 0..triangles.len() {
                if let Some((a, le)) = emitting(t) {
                    acc += weight(a, le) / total;
                    push(t, acc);
                }
            }
        }
        EmitterPolicy::UniformPerObject { objects } => {
            // Objects are runs of consecutive triangles (as an OBJ's objects are), so each
            // one's area is a sum over its run: linear time, no scratch memory.
            let runs = || {
                let mut start = 0usize;
                core::iter::from_fn(move || {
                    if start >= objects.len() {
                        return None;
                    }
                    let id = objects[start];
                    let len = objects[start..].iter().take_while(|&&o| o == id).count();
                    let run = start..start + len;
                    start += len;
                    Some(run)
                })
            };
            let area_of = |run: core::ops::Range<usize>| -> f64 {
                run.filter_map(emitting).map(|(a, _)| f64::from(a)).sum()
            };
            let mut count = 0usize;
            for run in runs() {
                let area = area_of(run.clone());
                if !area.is_finite() {
                    return Err(EmitterTableError::NonFinite);
                }
                if area > 0.0 {
                    count += 1;
                }
            }
            let n = count as f64;
            for run in runs() {
                let area = area_of(run.clone());
                for t in run {
                    if let Some((a, _)) = emitting(t) {
                        acc += f64::from(a) / area / n;
                        push(t, acc);
                    }
                }
            }
        }
    }
    debug_assert_eq!(written, needed);
    Ok(needed)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::Bvh;
    use crate::material::Material;
    use crate::texture::Textures;
    use std::vec::Vec;

    /// A scene's triangles and emitter table, owned.
    #[derive(Default)]
    struct Emitters {
        positions: Vec<Vec3>,
        normals: Vec<Vec3>,
        triangles: Vec<[u32; 3]>,
        materials_of: Vec<u32>,
        emitters: Vec<u32>,
        cdf: Vec<f32>,
    }

    /// Emitter tables of 1 to 9 entries (9: no table), with a degenerate triangle, an entry of
    /// zero power (never picked), vertex normals that agree, differ and cancel, triangles far
    /// from the origin, and two radiances.
    fn emitter_scene(entries: usize) -> Emitters {
        let mut e = Emitters::default();
        let mut total = 0.0f32;
        for j in 0..entries {
            let f = j as f32;
            let offset = Vec3::new(f * 0.37, if j % 3 == 1 { 1.0e4 } else { 0.5 }, -f * 0.11);
            let mut p = [
                offset,
                offset + Vec3::new(0.3 + 0.1 * f, 0.02 * f, 0.0),
                offset + Vec3::new(0.05, 0.01, 0.2 + 0.05 * f),
            ];
            if j == 4 {
                p[2] = p[0]; // no area
            }
            let n = match j % 3 {
                0 => [Vec3::NEG_Y; 3],
                1 => [
                    Vec3::NEG_Y,
                    Vec3::new(0.6, -0.8, 0.0),
                    Vec3::new(0.0, -0.6, 0.8),
                ],
                _ => [Vec3::Y, Vec3::NEG_Y, Vec3::ZERO], // cancel at some points
            };
            let base = e.positions.len() as u32;
            e.positions.extend(p);
            e.normals.extend(n);
            e.triangles.push([base, base + 1, base + 2]);
            e.materials_of.push((j % 2) as u32);
            e.emitters.push(j as u32);
            total += if j == 2 { 0.0 } else { 1.0 + f };
            e.cdf.push(total);
        }
        e
    }

    /// [`sample_emitter_table`] and [`sample_emitter_lanes`] against [`sample_emitter`], bit
    /// for bit, lane by lane, in the baseline's lanes and in AVX2's and AVX-512's where the CPU
    /// has them; lanes left out stay out.
    #[test]
    fn emitter_lanes_are_the_scalar_samples() {
        let materials = [
            Material {
                emission: Rgb::new(5.0, 4.0, 3.0),
                ..Material::diffuse(Rgb::ZERO)
            },
            Material {
                emission: Rgb::new(0.5, 1.0, 2.0),
                ..Material::diffuse(Rgb::ZERO)
            },
        ];
        let mut checked = 0usize;
        for entries in 1..=LANES + 1 {
            let e = emitter_scene(entries);
            let scene = SceneView {
                positions: &e.positions,
                normals: &e.normals,
                triangles: &e.triangles,
                triangle_materials: &e.materials_of,
                materials: &materials,
                emitter_triangles: &e.emitters,
                emitter_cdf: &e.cdf,
                bvh: Bvh {
                    nodes: &[],
                    prim_order: &[],
                }
                .into(),
                textures: Textures::NONE,
            };
            for round in 0..64u32 {
                let u = |l: usize, k: u32| {
                    let h = crate::sampler::mix64(u64::from(round * 97 + k) << 8 | l as u64);
                    match (round + k) % 7 {
                        0 => 0.0,
                        1 => ONE_BELOW,
                        _ => (h >> 40) as f32 / (1u64 << 24) as f32,
                    }
                };
                let u_select: [f32; LANES] = core::array::from_fn(|l| u(l, 0));
                let u_pos: [[f32; LANES]; 2] = [
                    core::array::from_fn(|l| u(l, 1)),
                    core::array::from_fn(|l| u(l, 2)),
                ];
                let lanes = 0xFF & !(1 << (round % 9));
                let check = |found: Option<(EmitterLanes<[f32; LANES]>, u32)>, what: &str| {
                    let mut count = 0;
                    for l in 0..LANES {
                        let want = sample_emitter(
                            &scene,
                            u_select[l],
                            Vec2::new(u_pos[0][l], u_pos[1][l]),
                        );
                        let got = found.as_ref().and_then(|(s, ok)| {
                            (ok >> l & 1 != 0).then(|| {
                                let v = |a: &V3<[f32; LANES]>| Vec3::new(a.x[l], a.y[l], a.z[l]);
                                (
                                    v(&s.p),
                                    v(&s.p_err),
                                    v(&s.ng),
                                    v(&s.n),
                                    v(&s.radiance),
                                    s.pdf[l],
                                )
                            })
                        });
                        if lanes >> l & 1 == 0 {
                            assert!(got.is_none(), "{what}: lane {l} left out");
                            continue;
                        }
                        let bits = |v: Vec3| v.to_array().map(f32::to_bits);
                        let want = want.map(|w| {
                            (
                                bits(w.p),
                                bits(w.p_err),
                                bits(w.ng),
                                bits(w.n),
                                bits(w.radiance),
                                w.pdf.0.to_bits(),
                            )
                        });
                        let got = got.map(|g| {
                            (
                                bits(g.0),
                                bits(g.1),
                                bits(g.2),
                                bits(g.3),
                                bits(g.4),
                                g.5.to_bits(),
                            )
                        });
                        assert_eq!(
                            got, want,
                            "{what}: {entries} entries, round {round}, lane {l}"
                        );
                        count += 1;
                    }
                    count
                };
                checked += run_each_isa(&scene, lanes, &u_select, &u_pos, check);
            }
        }
        // 7,735 lanes with the baseline's lanes alone (aarch64, wasm32), more with AVX.
        assert!(checked > 7_000, "{checked}");
    }

    /// The largest `f32` below 1.
    const ONE_BELOW: f32 = 1.0 - f32::EPSILON / 2.0;

    /// Both lane samplers in the lanes of each instruction set this CPU has, their samples
    /// given to `check` as arrays; the number of lanes checked.
    fn run_each_isa(
        scene: &SceneView<'_>,
        lanes: u32,
        u_select: &[f32; LANES],
        u_pos: &[[f32; LANES]; 2],
        check: impl Fn(Option<(EmitterLanes<[f32; LANES]>, u32)>, &str) -> usize,
    ) -> usize {
        fn arrays<L: Lanes<LANES>>(
            s: Option<(EmitterLanes<L>, u32)>,
        ) -> Option<(EmitterLanes<[f32; LANES]>, u32)> {
            let v = |a: V3<L>| V3 {
                x: a.x.to_array(),
                y: a.y.to_array(),
                z: a.z.to_array(),
            };
            s.map(|(s, ok)| {
                (
                    EmitterLanes {
                        p: v(s.p),
                        p_err: v(s.p_err),
                        ng: v(s.ng),
                        n: v(s.n),
                        radiance: v(s.radiance),
                        pdf: s.pdf.to_array(),
                    },
                    ok,
                )
            })
        }
        #[inline(always)]
        fn both<I: Isa>(
            isa: I,
            scene: &SceneView<'_>,
            lanes: u32,
            u_select: &[f32; LANES],
            u_pos: &[[f32; LANES]; 2],
        ) -> [Option<(EmitterLanes<[f32; LANES]>, u32)>; 2] {
            let u_pos = [&u_pos[0], &u_pos[1]];
            let table = EmitterTable::<I::Eight>::new(isa, scene);
            let from_table = table
                .as_ref()
                .and_then(|t| sample_emitter_table(isa, scene, t, lanes, u_select, u_pos));
            let gathered = sample_emitter_lanes(isa, scene, lanes, u_select, u_pos);
            [arrays(from_table), arrays(gathered)]
        }
        let mut count = 0;
        let mut run = |found: [Option<(EmitterLanes<[f32; LANES]>, u32)>; 2], isa: &str| {
            if scene.emitter_cdf.len() <= LANES {
                count += check(found[0], &std::format!("table, {isa}"));
            } else {
                assert!(found[0].is_none(), "no table past {LANES} entries");
            }
            count += check(found[1], &std::format!("gathered, {isa}"));
        };
        run(
            both(crate::simd::Baseline, scene, lanes, u_select, u_pos),
            "baseline",
        );
        #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
        {
            if let Some(avx) = crate::simd::Avx::detect() {
                let found = avx.run(
                    #[inline(always)]
                    |avx| both(avx, scene, lanes, u_select, u_pos),
                );
                run(found, "AVX2");
            }
            if let Some(avx512) = crate::simd::Avx512::detect() {
                let found = avx512.run(
                    #[inline(always)]
                    |avx512| both(avx512, scene, lanes, u_select, u_pos),
                );
                run(found, "AVX-512");
            }
        }
        count
    }

    #[test]
    fn interval_search_skips_empty_entries() {
        let cdf = [0.25, 0.25, 0.75, 1.0];
        assert_eq!(find_interval(&cdf, 0.0), 0);
        assert_eq!(find_interval(&cdf, 0.2499), 0);
        assert_eq!(find_interval(&cdf, 0.25), 2);
        assert_eq!(find_interval(&cdf, 0.8), 3);
        assert_eq!(find_interval(&cdf, 0.999_999_9), 3);
    }

    /// The galloping search against a binary search over the whole CDF: equal steps, skewed
    /// ones, runs of empty entries, a single entry, long tables, and `u` at 0, near 1 and on
    /// the entries' own fractions.
    #[test]
    fn interval_search_is_the_binary_search() {
        let reference = |cdf: &[f32], u: f32| {
            cdf.partition_point(|&c| c <= u * cdf[cdf.len() - 1])
                .min(cdf.len() - 1)
        };
        let mut state = 0x2545_F491_4F6C_DD1Du64;
        let mut rnd = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 40) as f32 / (1u64 << 24) as f32
        };
        let mut buffer = [0.0f32; 4097];
        for n in [1usize, 2, 3, 7, 16, 200, 1000, 4097] {
            for shape in 0..5 {
                let mut sum = 0.0f32;
                for (i, c) in buffer[..n].iter_mut().enumerate() {
                    sum += match shape {
                        0 => 1.0,
                        1 => (i + 1) as f32,
                        2 => 1.0 / ((i + 1) as f32 * (i + 1) as f32 * (i + 1) as f32),
                        3 if i % 5 < 3 => 0.0,
                        _ => rnd() * rnd() * 100.0,
                    };
                    *c = sum;
                }
                let cdf = &buffer[..n];
                if cdf[n - 1] <= 0.0 {
                    continue;
                }
                let fixed = [0.0, 0.999_999_94, 0.5];
                let randoms: [f32; 500] = core::array::from_fn(|_| rnd());
                let own = cdf.iter().map(|&c| c / cdf[n - 1]).filter(|&u| u < 1.0);
                let us: std::vec::Vec<f32> = fixed.into_iter().chain(randoms).chain(own).collect();
                for &u in &us {
                    assert_eq!(
                        find_interval(cdf, u),
                        reference(cdf, u),
                        "n {n} shape {shape} u {u}"
                    );
                }
                // The lanes' search, eight at a time, with a lane left out.
                for chunk in us.chunks(LANES) {
                    let mut u = [0.5; LANES];
                    u[..chunk.len()].copy_from_slice(chunk);
                    let lanes = ((1u32 << chunk.len()) - 1) & !0b100;
                    type Eight = <crate::simd::Baseline as Isa>::Eight;
                    let index = find_intervals::<Eight>(crate::simd::Baseline, cdf, &u, lanes);
                    for l in lanes_of(lanes) {
                        assert_eq!(
                            index[l],
                            reference(cdf, u[l]),
                            "n {n} shape {shape} u {}",
                            u[l]
                        );
                    }
                }
            }
        }
    }
}
