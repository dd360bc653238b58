//! The path tracers run [`BATCH`] samples of a pixel at a time, a bounce at a time: the
//! driver of issue 14's lever 3 (many paths in SIMD lanes, the way Mitsuba 3's vectorised
//! variants run). Each lane runs the one-path loop's own bounce ([`PathState::bounce`]), so a
//! batched render is the scalar render bit for bit (tests/tests/batched.rs: every path tracer,
//! both samplers, every BSDF). What the lanes share is done once for all of them: at a given
//! bounce every lane draws the same dimensions, so their numbers are drawn together
//! ([`PixelSamples::draw_lanes`]; for Sobol' samples the key and the pixel's digits once, the
//! digit permutations once per run of lanes that share them, the scramble in SIMD lanes)
//! before the lanes scatter one after another.
//!
//! Status: not used by the hosts yet, because it does not pay yet. On the project's Cornell box
//! (MIS, 64 × 64, 16 spp, one thread) it executes 3.6% more instructions than the one-path loop
//! in an x86-64-v3 build (1,377 M against 1,325 M; the sampler's share falls from about 241 M
//! to 199 M, the lockstep costs more than that) and 9% more in the baseline build (1,748 M
//! against 1,605 M); wall time
//! is equal in the baseline build (256 × 256, 64 spp: 5.04 s against 5.10 s) but 1.5 times the
//! scalar loop's in the v3 build (6.8 s against 4.55 s), a stall that cachegrind's counts
//! (instructions +1.7%, branch mispredictions +0.8 M, D1 misses equal) do not show and that is
//! not yet understood. The stages to vectorise next are the surface interaction, emitter
//! sampling and the BSDFs.

use super::path::PathState;
use super::{dims, PathSettings, PathStrategy, PixelStats, SampleResult};
use crate::camera::Camera;
use crate::sampler::{
    lanes_of, IndependentSampler, Sampler, SamplerKind, Sampling, ZSobolPixelSampler,
};
use crate::scene::SceneView;
use crate::Rgb;
use glam::Vec2;

/// Samples in flight together.
pub const BATCH: usize = 8;

/// A pixel's samples, any sample at any dimension: the source a batch draws from.
pub trait PixelSamples: Sampler {
    /// Moves to dimension `dimension` of sample `index` of the pixel.
    fn start_sample(&mut self, index: u32, dimension: u32);

    /// `out[k][lane]` = dimension `dimension + k` of sample `indices[lane]` for the lanes of
    /// `live`, drawn as one draw of `N` (1 or 2) numbers ([`Sampler::next_1d`],
    /// [`Sampler::next_2d`]); by default lane after lane.
    #[inline(always)]
    fn draw_lanes<const N: usize>(
        &mut self,
        dimension: u32,
        indices: &[u32; BATCH],
        live: u32,
        out: &mut [[f32; BATCH]; N],
    ) {
        for lane in lanes_of(live) {
            self.start_sample(indices[lane], dimension);
            if N == 2 {
                let v = self.next_2d();
                out[0][lane] = v.x;
                out[N - 1][lane] = v.y;
            } else {
                out[0][lane] = self.next_1d();
            }
        }
    }
}

impl PixelSamples for ZSobolPixelSampler {
    #[inline(always)]
    fn start_sample(&mut self, index: u32, dimension: u32) {
        ZSobolPixelSampler::start_sample(self, index, dimension);
    }

    /// Computed together ([`ZSobolPixelSampler::draw_lanes`]).
    #[inline(always)]
    fn draw_lanes<const N: usize>(
        &mut self,
        dimension: u32,
        indices: &[u32; BATCH],
        live: u32,
        out: &mut [[f32; BATCH]; N],
    ) {
        ZSobolPixelSampler::draw_lanes(self, dimension, indices, live, out);
    }
}

const _: () = assert!(BATCH == crate::sampler::DRAW_LANES);

/// The independent sampler of one pixel (its linear index), restarted per sample.
#[derive(Clone, Copy, Debug)]
pub struct IndependentPixel {
    seed: u64,
    pixel: u64,
    sampler: IndependentSampler,
}

impl IndependentPixel {
    #[must_use]
    pub fn new(seed: u64, pixel: u64) -> Self {
        Self {
            seed,
            pixel,
            sampler: IndependentSampler::new(seed, pixel, 0),
        }
    }
}

impl Sampler for IndependentPixel {
    #[inline(always)]
    fn next_1d(&mut self) -> f32 {
        self.sampler.next_1d()
    }
    #[inline(always)]
    fn set_dimension(&mut self, d: u32) {
        self.sampler.set_dimension(d);
    }
    #[inline(always)]
    fn dimension(&self) -> u32 {
        self.sampler.dimension()
    }
}

impl PixelSamples for IndependentPixel {
    #[inline(always)]
    fn start_sample(&mut self, index: u32, dimension: u32) {
        self.sampler = IndependentSampler::new(self.seed, self.pixel, index);
        self.sampler.set_dimension(dimension);
    }
}

/// The numbers of one bounce of every lane, drawn before the lanes scatter: `values[o][lane]`
/// is dimension `base + o`, for the offsets `o` whose bit is set in `drawn` (both bits of a
/// 2D draw, [`PAIRS`]).
#[derive(Clone, Copy, Debug)]
struct BounceNumbers {
    base: u32,
    drawn: u32,
    values: [[f32; BATCH]; dims::PER_BOUNCE as usize],
}

/// The sampler a lane scatters with: its bounce's numbers where they were drawn ahead, and the
/// pixel's sampler for any other dimension (each number is a function of its sample and
/// dimension only, so where it comes from changes nothing).
struct LaneSampler<'a, P> {
    numbers: &'a BounceNumbers,
    lane: usize,
    index: u32,
    dimension: u32,
    pixel: &'a mut P,
}

impl<P: PixelSamples> Sampler for LaneSampler<'_, P> {
    #[inline(always)]
    fn next_1d(&mut self) -> f32 {
        let d = self.dimension;
        self.dimension = d.wrapping_add(1);
        let offset = d.wrapping_sub(self.numbers.base);
        if offset < dims::PER_BOUNCE && self.numbers.drawn >> offset & 1 != 0 {
            return self.numbers.values[offset as usize][self.lane];
        }
        self.pixel.start_sample(self.index, d);
        self.pixel.next_1d()
    }

    /// A 2D draw is its own pair of numbers (the sampler's `next_2d` need not be two
    /// `next_1d`s): taken from the table only where the table drew that pair as one.
    #[inline(always)]
    fn next_2d(&mut self) -> Vec2 {
        let d = self.dimension;
        self.dimension = d.wrapping_add(2);
        let offset = d.wrapping_sub(self.numbers.base);
        if offset < dims::PER_BOUNCE
            && self.numbers.drawn >> offset & 1 != 0
            && PAIRS >> offset & 1 != 0
        {
            let v = &self.numbers.values;
            return Vec2::new(
                v[offset as usize][self.lane],
                v[offset as usize + 1][self.lane],
            );
        }
        self.pixel.start_sample(self.index, d);
        self.pixel.next_2d()
    }

    #[inline(always)]
    fn set_dimension(&mut self, d: u32) {
        self.dimension = d;
    }

    #[inline(always)]
    fn dimension(&self) -> u32 {
        self.dimension
    }
}

/// The offsets of [`dims`] that start a 2D draw (the pair is drawn as one).
const PAIRS: u32 = 1 << dims::LIGHT_POSITION | 1 << dims::BSDF_DIRECTION;

/// Draws the numbers the lanes of `live` need at the bounce whose dimensions start at `base`:
/// `offsets` (bit `o`: offset `o` of [`dims`]) for every lane.
#[inline(always)]
fn draw_bounce<P: PixelSamples>(
    pixel: &mut P,
    indices: &[u32; BATCH],
    live: u32,
    base: u32,
    offsets: u32,
    numbers: &mut BounceNumbers,
) {
    numbers.base = base;
    numbers.drawn = offsets;
    let mut o = offsets;
    while o != 0 {
        let offset = o.trailing_zeros();
        o &= o - 1;
        let at = offset as usize;
        // Drawn in place (`PAIRS` are never at the last offset).
        if PAIRS >> offset & 1 != 0 {
            if let Ok(pair) = <&mut [[f32; BATCH]; 2]>::try_from(&mut numbers.values[at..at + 2]) {
                pixel.draw_lanes::<2>(base + offset, indices, live, pair);
            }
            o &= !(1 << (offset + 1));
        } else if let Ok(one) = <&mut [[f32; BATCH]; 1]>::try_from(&mut numbers.values[at..at + 1])
        {
            pixel.draw_lanes::<1>(base + offset, indices, live, one);
        }
    }
}

/// Renders samples `first .. first + count` of pixel `(x, y)` with the path tracer `strategy`,
/// [`BATCH`] at a time, and adds them in sample order to `stats`: the sums
/// [`super::render_pixel`] gives, bit for bit.
#[allow(clippy::too_many_arguments)]
#[must_use]
pub fn render_pixel_batched(
    strategy: &PathStrategy,
    scene: &SceneView<'_>,
    camera: &Camera,
    settings: &PathSettings,
    sampling: &Sampling,
    x: u32,
    y: u32,
    first: u32,
    count: u32,
    stats: PixelStats,
) -> PixelStats {
    match sampling.kind {
        SamplerKind::Independent => {
            let pixel = u64::from(y) * u64::from(camera.width) + u64::from(x);
            let mut p = IndependentPixel::new(sampling.seed, pixel);
            batches(
                strategy, scene, camera, settings, &mut p, x, y, first, count, stats,
            )
        }
        SamplerKind::ZSobol => {
            let mut p = sampling.zsobol().pixel_sampler(x, y);
            batches(
                strategy, scene, camera, settings, &mut p, x, y, first, count, stats,
            )
        }
    }
}

#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn batches<P: PixelSamples>(
    strategy: &PathStrategy,
    scene: &SceneView<'_>,
    camera: &Camera,
    settings: &PathSettings,
    pixel: &mut P,
    x: u32,
    y: u32,
    first: u32,
    count: u32,
    mut stats: PixelStats,
) -> PixelStats {
    let end = first.saturating_add(count);
    let mut start = first;
    while start < end {
        let n = (end - start).min(BATCH as u32) as usize;
        let results = batch(strategy, scene, camera, settings, pixel, x, y, start, n);
        for r in &results[..n] {
            stats.add(r.l);
            stats.rays += u64::from(r.rays);
        }
        start += n as u32;
    }
    stats
}

/// Samples `start .. start + n` (`n ≤ BATCH`) of the pixel, one lane each.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn batch<P: PixelSamples>(
    strategy: &PathStrategy,
    scene: &SceneView<'_>,
    camera: &Camera,
    settings: &PathSettings,
    pixel: &mut P,
    x: u32,
    y: u32,
    start: u32,
    n: usize,
) -> [SampleResult; BATCH] {
    let indices: [u32; BATCH] = core::array::from_fn(|l| start.wrapping_add(l as u32));
    let mut results = [SampleResult::default(); BATCH];
    // Emission seen from the camera, added to each path's radiance at the end as `li_path` adds
    // it.
    let mut seen = [Rgb::ZERO; BATCH];
    let mut paths: [Option<PathState>; BATCH] = [None; BATCH];
    let mut live = 0u32;
    for lane in 0..n {
        pixel.start_sample(indices[lane], 0);
        let ray = camera.generate_ray(x, y, dims::camera(pixel));
        results[lane].rays += 1;
        let Some(hit) = scene.intersect(&ray) else {
            continue;
        };
        let si = scene.interaction(&ray, &hit);
        let bsdf = scene.bsdf_at(&si);
        seen[lane] = scene.emitted(&si);
        paths[lane] = Some(PathState::new(si, bsdf));
        live |= 1 << lane;
    }
    let mut numbers = BounceNumbers {
        base: 0,
        drawn: 0,
        values: [[0.0; BATCH]; dims::PER_BOUNCE as usize],
    };
    let mut base = dims::CAMERA;
    let mut bounces = 0u32;
    while live != 0 {
        bounces += 1;
        let offsets = bounce_offsets(strategy, settings, bounces, &paths, live);
        draw_bounce(pixel, &indices, live, base, offsets, &mut numbers);
        for lane in lanes_of(live) {
            let Some(path) = paths[lane].as_mut() else {
                continue;
            };
            let mut sampler = LaneSampler {
                numbers: &numbers,
                lane,
                index: indices[lane],
                dimension: base,
                pixel: &mut *pixel,
            };
            if !path.bounce(
                scene,
                settings,
                strategy,
                &mut sampler,
                &mut results[lane].rays,
            ) {
                live &= !(1 << lane);
            }
        }
        base = base.wrapping_add(dims::PER_BOUNCE);
    }
    for lane in 0..n {
        results[lane].l = paths[lane].as_ref().map_or(Rgb::ZERO, |p| seen[lane] + p.l);
    }
    results
}

/// The dimensions (bits: offsets of [`dims`]) some lane of `live` may draw at bounce number
/// `bounces`: the emitter's when the strategy samples emitters, the lobe choice when a BSDF
/// has lobes to choose from, the direction, the roulette number once roulette is played.
#[inline(always)]
fn bounce_offsets(
    strategy: &PathStrategy,
    settings: &PathSettings,
    bounces: u32,
    paths: &[Option<PathState>; BATCH],
    live: u32,
) -> u32 {
    let mut offsets = 0b11 << dims::BSDF_DIRECTION;
    if strategy.direct != super::DirectLighting::BsdfSampling {
        offsets |= 0b111 << dims::LIGHT_SELECT;
    }
    if settings.roulette_applies(bounces) {
        offsets |= 1 << dims::ROULETTE;
    }
    for lane in lanes_of(live) {
        if paths[lane].is_some_and(|p| p.bsdf.uses_lobe_choice()) {
            offsets |= 1 << dims::BSDF_LOBE;
            break;
        }
    }
    offsets
}
