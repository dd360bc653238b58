//! The path tracers run [`BATCH`] samples of a pixel at a time, a bounce at a time: issue 14's
//! lever 3 (many paths in SIMD lanes, the way Mitsuba 3's vectorised variants run), and what
//! [`super::render_pixel`] runs for MIS path tracing. The MIS bake runs the same driver from the
//! vertex it bakes ([`super::bake_vertex_batched`]): a batch's paths start where its
//! [`Origin`] puts them, at the camera or at the vertex. The paths' state is stored lane by lane
//! ([`PathLanes`]: radiance, throughput and the vertex, field by field), and a bounce runs in
//! SIMD lanes, with AVX where the CPU has it, for the paths at diffuse vertices under MIS
//! (`super::path_lanes`: emitter sampling, the BSDF's value and pdf, the shadow ray, the
//! power heuristic, cosine sampling, roulette, the next ray; the whole bounce of the benchmark
//! scenes). A path at any other vertex, or of another path tracer, runs the one-path loop's
//! own stages ([`PathState::light`], [`PathState::add_light`], [`PathState::scatter`]) on a
//! [`PathState`] taken out of the lanes and put back. What every path does alike is done once
//! for all: at a given bounce every lane draws the same dimensions, so their numbers are drawn
//! together ([`PixelSamples::draw_lanes`]), and the surface interactions of the rays that land
//! are computed together in lanes, into the lanes' storage ([`SceneView::interactions_in`]).
//! The rays are traced one by one: packets through the wide tree
//! ([`SceneView::intersect_packet`], [`SceneView::occluded_packet`]) are available for the first
//! segments of the paths ([`PACKET_SEGMENTS`]) but did not pay.
//!
//! Each lane computes what the one-path loop computes, bit for bit, so a batched render is the
//! scalar render (tests/tests/batched.rs: every path tracer, both samplers, every BSDF; the
//! determinism script renders through it on every target).
//!
//! Measured on an AMD EPYC (Zen 5; sse4_2 avx avx2 fma avx512f/dq/bw/vl), 2026-12-07, `cargo
//! bench -p ember-tests --bench batch` (64 × 64, 16 spp, MIS, Sobol', one thread, shipped
//! x86-64 build with the AVX dispatch), batched film time over the one-path loop's (the
//! project's Cornell box; TinyRender's `cbox.obj`):
//! - packets for the camera rays and the first bounce's, the interactions one lane at a time:
//!   1.21 and 1.21; without packets, the interactions in lanes: 1.13–1.16 and 1.12–1.14; the
//!   queries' rays built in place: 1.10–1.14 and 1.07. The interaction stage cost as much in
//!   lanes as one lane at a time (33 against 36 ns): its inputs were gathered from eight hits and
//!   its outputs written back to eight `SurfaceInteraction`s that the scalar stages read.
//! - the path state in lanes and the diffuse bounce in lanes: 1.11 (the ulp steps of the ray
//!   origins and a closure left out of line cost 15%); with those in lanes: 0.89–0.91 and
//!   0.93–0.97; with the Sobol' scramble compiled in the caller's AVX2 lanes and the emitter
//!   samples in lanes, three runs of the final build: 0.86–0.87 and 0.87–0.94 (54.6–56.5 ms
//!   against 63.6–64.9, 64.2–68.4 against 72.2–73.9).
//!   `ember render` (one thread): the Cornell box at 256², 64 spp, 3.54–3.59 s against the
//!   one-path loop's 4.11–4.15 s; `cbox.obj` at 32 spp 14.6–14.7 s against 16.9–17.1 s, with
//!   identical EXRs.
//! - the bake through this driver (`ember bake`, the cubebox-sized scene of `bench/bake`, 2
//!   threads, 3 alternating runs): 3.14–3.16 s against the one-sample loop's 3.81–3.89 s with
//!   MIS's roulette, 5.48–5.60 against 6.43–6.52 with roulette off, identical PLY data.
//!
//! The emitters of a scene with at most eight emitter triangles are a table held in lanes,
//! made once per call ([`EmitterTable`]); with more, each lane gathers its emitter's triangle.
//! Still one lane at a time: the gathers of the surface interactions' triangle data, the
//! arrival at the next vertex (its emission and BSDF), the ray queries, and every non-diffuse
//! BSDF (Phong and mixtures with a lobe, conductors, dielectrics).

use super::path::{li_path, NextRay, PathState, ShadowQuery};
use super::path_lanes::{
    add_light_lanes, next_event_diffuse, scatter_diffuse, PathLanes, RayLanes, ShadowLanes, Vertex,
};
use super::{dims, PathSettings, PathStrategy, PixelStats, SampleResult};
use crate::bsdf::Bsdf;
use crate::camera::Camera;
use crate::emitter::EmitterTable;
use crate::geometry::Ray;
use crate::math::SolidAnglePdf;
use crate::sampler::{
    lanes_of, IndependentSampler, Sampler, SamplerKind, Sampling, ZSobolLayout, ZSobolPixelSampler,
    ZSobolSampler,
};
use crate::scene::{Hit, SceneView};
use crate::simd::Isa;
use crate::surface_lanes::SurfaceLanes;
use crate::Rgb;
use glam::{Vec2, Vec3};

/// Samples in flight together.
///
/// A batch's lanes start together and run until the last of their paths ends, so they run
/// part empty: on the project's Cornell box (MIS, 16 spp) 4.8 of 8 lanes live per bounce on
/// average. Timed with batches of 8, 4, 2 and 1 samples (AMD EPYC Zen 5, 2026-12-07), a bounce
/// costs about 510 ns whatever its lanes hold (the lane stages, the draws, the glue) plus 145 ns
/// per live lane (the ray queries, the lanes' own loops). Refilling a lane with the pixel's
/// next sample as soon as its path ended (its results reordered to sample order) kept 6.6 lanes
/// live and cut the bounces by 27%, but was no faster (2026-12-07, the same EXRs): the lanes,
/// at different bounces, draw different dimensions, and each lane's key and pixel digits had to
/// be looked up instead of one per draw; that ate the saving. Waves kept every lane at the
/// same bounce instead (2026-12-07, AMD EPYC Zen 3 with AVX2, the same EXRs): four groups of
/// eight lanes ran their bounces in step and, after each bounce, the live paths were packed
/// into the fewest groups (a lane's whole state moved), over a row's pixels or a pixel's 32
/// samples. That took 25% of the group bounces and 3% of the instructions away (679 k to
/// 512 k bounces, Cornell box, 256², 16 spp), but no time: 0.99 and 1.02 times the batches'
/// (medians of 12 alternating pairs); the moves, the larger frame and the row runs' sampler
/// ate it.
pub const BATCH: usize = 8;

/// The fewest samples a batch runs in lanes: fewer (a call of fewer samples, or the last of a
/// call's batches) run one at a time through the one-path loop, which gives the same bits in
/// less time than lanes that run mostly empty (a progressive view's passes of 1 spp, its
/// previews, low-spp renders). [`super::render_row`] fills the lanes of such calls with the
/// samples of neighbouring pixels instead ([`render_run_batched`]). Measured (`cargo bench -p ember-tests --bench batch`, `calls/…`,
/// AMD EPYC Zen 5, one thread, MIS, Sobol'): a film rendered in calls of n samples per pixel
/// took, batched in lanes over one at a time, 1.77 / 1.69 (the Cornell box / `cbox.obj`) at
/// n = 1, 1.35 / 1.34 at 2, 1.06 / 1.05 at 4, 0.96 / 0.98 at 5, 0.89 / 0.91 at 6, 0.89 / 0.90
/// at 7 and 0.86 / 0.90 at 8.
pub const MIN_LANES: usize = 5;

/// A pixel's samples, any sample at any dimension: the source a batch draws from.
pub trait PixelSamples: Sampler {
    /// Moves to dimension `dimension` of sample `index` of the pixel.
    fn start_sample(&mut self, index: u32, dimension: u32);

    /// `out[k][lane]` = dimension `dimension + k` of sample `indices[lane]` for the lanes of
    /// `live`, drawn as one draw of `N` (1 or 2) numbers ([`Sampler::next_1d`],
    /// [`Sampler::next_2d`]); by default lane after lane. `lane_hashes`: the caller's
    /// instructions multiply 64-bit integers in lanes ([`Isa::LANE_HASHES`]), which changes how
    /// the numbers are computed, never what they are.
    #[inline(always)]
    fn draw_lanes<const N: usize>(
        &mut self,
        dimension: u32,
        indices: &[u32; BATCH],
        live: u32,
        _lane_hashes: bool,
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
        lane_hashes: bool,
        out: &mut [[f32; BATCH]; N],
    ) {
        ZSobolPixelSampler::draw_lanes(self, dimension, indices, live, lane_hashes, out);
    }
}

const _: () = assert!(BATCH == crate::sampler::DRAW_LANES);

/// How a driver's sample numbers map to pixels and samples: number `j` is sample
/// `first + j % count` of pixel `j / count` of a run of pixels (the samples
/// `first .. first + count` of each pixel, pixel after pixel), or, for [`Self::ONE_PIXEL`],
/// sample `j` of the only pixel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Span {
    first: u32,
    count: u32,
}

impl Span {
    /// Number `j` is sample `j` of one pixel.
    pub const ONE_PIXEL: Self = Self {
        first: 0,
        count: u32::MAX,
    };

    /// Samples `first .. first + count` (`count ≥ 1`) of each pixel of a run.
    #[must_use]
    pub fn run(first: u32, count: u32) -> Self {
        Self {
            first,
            count: count.max(1),
        }
    }

    /// The pixel (counted from the run's first) and the sample of number `j`.
    #[inline(always)]
    #[must_use]
    pub fn locate(self, j: u32) -> (u32, u32) {
        if self.count == u32::MAX {
            // No division for a lone pixel's numbers, which are its sample indices.
            return (0, j);
        }
        (j / self.count, self.first.wrapping_add(j % self.count))
    }
}

/// The independent sampler of a run of pixels with consecutive linear indices from `pixel`
/// on (one pixel: [`Self::new`]), restarted per sample.
#[derive(Clone, Copy, Debug)]
pub struct IndependentPixels {
    seed: u64,
    pixel: u64,
    span: Span,
    sampler: IndependentSampler,
}

impl IndependentPixels {
    /// The samples of pixel `pixel`, numbered by their index.
    #[must_use]
    pub fn new(seed: u64, pixel: u64) -> Self {
        Self::run(seed, pixel, Span::ONE_PIXEL)
    }

    /// The samples of the pixels `pixel, pixel + 1, …` numbered as `span` says.
    #[must_use]
    pub fn run(seed: u64, pixel: u64, span: Span) -> Self {
        Self {
            seed,
            pixel,
            span,
            sampler: IndependentSampler::new(seed, pixel, 0),
        }
    }
}

/// [`Sampler`] for a type whose `sampler` field holds the sample started last.
macro_rules! sampler_of_started {
    ($t:ty) => {
        impl Sampler for $t {
            #[inline(always)]
            fn next_1d(&mut self) -> f32 {
                self.sampler.next_1d()
            }
            #[inline(always)]
            fn next_2d(&mut self) -> Vec2 {
                self.sampler.next_2d()
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
    };
}

sampler_of_started!(IndependentPixels);
sampler_of_started!(ZSobolPixels);

impl PixelSamples for IndependentPixels {
    #[inline(always)]
    fn start_sample(&mut self, index: u32, dimension: u32) {
        let (k, sample) = self.span.locate(index);
        self.sampler = IndependentSampler::new(self.seed, self.pixel + u64::from(k), sample);
        self.sampler.set_dimension(dimension);
    }
}

/// The Sobol' samples of a run of pixels of one row, from `(x, y)` on, numbered as `span`
/// says: for a few samples of each of several pixels, where [`ZSobolPixelSampler`]'s memo of
/// one pixel's digits would serve a few draws; neighbouring pixels share most digits' permutations
/// instead ([`ZSobolLayout::draw_lanes_at`]).
#[derive(Clone, Copy, Debug)]
pub struct ZSobolPixels {
    layout: ZSobolLayout,
    x: u32,
    y: u32,
    span: Span,
    sampler: ZSobolSampler,
    /// The Morton indices of the numbers last drawn in lanes (`mortons[lane]` of
    /// `numbers[lane]`): a batch draws every dimension for the same numbers, so they are found
    /// once per batch rather than once per draw.
    numbers: [u32; BATCH],
    mortons: [u64; BATCH],
}

impl ZSobolPixels {
    #[must_use]
    pub fn run(layout: &ZSobolLayout, x: u32, y: u32, span: Span) -> Self {
        let numbers = [0; BATCH];
        let mut run = Self {
            layout: *layout,
            x,
            y,
            span,
            sampler: layout.sampler_at(x, y, 0, 0),
            numbers,
            mortons: [0; BATCH],
        };
        run.mortons = numbers.map(|j| run.morton_index(j));
        run
    }

    /// The Morton index of number `j`.
    #[inline(always)]
    fn morton_index(&self, j: u32) -> u64 {
        let (k, sample) = self.span.locate(j);
        self.layout
            .morton_index(self.x.wrapping_add(k), self.y, sample)
    }
}

impl PixelSamples for ZSobolPixels {
    #[inline(always)]
    fn start_sample(&mut self, index: u32, dimension: u32) {
        let (k, sample) = self.span.locate(index);
        self.sampler = self
            .layout
            .sampler_at(self.x.wrapping_add(k), self.y, sample, dimension);
    }

    /// Computed together ([`ZSobolLayout::draw_lanes_at`]).
    #[inline(always)]
    fn draw_lanes<const N: usize>(
        &mut self,
        dimension: u32,
        indices: &[u32; BATCH],
        live: u32,
        lane_hashes: bool,
        out: &mut [[f32; BATCH]; N],
    ) {
        if *indices != self.numbers {
            let mut mortons = [0; BATCH];
            for (morton, &j) in mortons.iter_mut().zip(indices) {
                *morton = self.morton_index(j);
            }
            (self.numbers, self.mortons) = (*indices, mortons);
        }
        self.layout
            .draw_lanes_at(&self.mortons, dimension, live, lane_hashes, out);
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

impl<'a, P> LaneSampler<'a, P> {
    /// Lane `lane` (sample `index`) at the bounce whose dimensions start at `base`.
    #[inline(always)]
    fn at(
        numbers: &'a BounceNumbers,
        lane: usize,
        index: u32,
        base: u32,
        pixel: &'a mut P,
    ) -> Self {
        Self {
            numbers,
            lane,
            index,
            dimension: base,
            pixel,
        }
    }
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
fn draw_bounce<I: Isa, P: PixelSamples>(
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
                pixel.draw_lanes::<2>(base + offset, indices, live, I::LANE_HASHES, pair);
            }
            o &= !(1 << (offset + 1));
        } else if let Ok(one) = <&mut [[f32; BATCH]; 1]>::try_from(&mut numbers.values[at..at + 1])
        {
            pixel.draw_lanes::<1>(base + offset, indices, live, I::LANE_HASHES, one);
        }
    }
}

/// Renders samples `first .. first + count` of pixel `(x, y)` with the path tracer `strategy`,
/// [`BATCH`] at a time (a last batch of fewer than [`MIN_LANES`] one at a time through the
/// one-path loop), and adds them in sample order to `stats`: the sums
/// [`super::render_pixel`] gives, bit for bit. The first `packet_segments` segments of the
/// paths are traced as packets ([`PACKET_SEGMENTS`] is the measured choice). The lanes run
/// with AVX where the CPU has it ([`crate::simd`]).
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
    packet_segments: u32,
) -> PixelStats {
    let job = Job::from_camera(
        strategy,
        scene,
        camera,
        settings,
        (x, y),
        Span::ONE_PIXEL,
        packet_segments,
    );
    let (mut independent, mut zsobol);
    let pixel = match sampling.kind {
        SamplerKind::Independent => {
            independent = IndependentPixels::new(sampling.seed, pixel_number(camera, x, y));
            Pixel::Independent(&mut independent)
        }
        SamplerKind::ZSobol => {
            zsobol = sampling.zsobol().pixel_sampler(x, y);
            Pixel::ZSobol(&mut zsobol)
        }
    };
    let mut stats = stats;
    let add = |r: &SampleResult| {
        stats.add(r.l);
        stats.rays += u64::from(r.rays);
    };
    job.dispatch(pixel, first, count, add);
    stats
}

/// Renders samples `first .. first + count` of each pixel `(x + k, y)` with MIS path tracing
/// and adds them in sample order to `stats[k]`: what [`render_pixel_batched`] gives each
/// pixel, bit for bit, for calls of fewer samples per pixel than fill a batch's lanes
/// ([`MIN_LANES`]: a progressive view's passes, previews, renders of 1 to 4 spp). A batch holds
/// the samples of neighbouring pixels, pixel after pixel, so that its lanes run full.
#[allow(clippy::too_many_arguments)]
pub fn render_run_batched(
    strategy: &PathStrategy,
    scene: &SceneView<'_>,
    camera: &Camera,
    settings: &PathSettings,
    sampling: &Sampling,
    (x, y): (u32, u32),
    first: u32,
    count: u32,
    stats: &mut [PixelStats],
) {
    let Some(numbers) = u32::try_from(stats.len())
        .ok()
        .and_then(|n| n.checked_mul(count))
    else {
        // More samples than a call numbers: pixel by pixel.
        for (k, s) in stats.iter_mut().enumerate() {
            let x = x.wrapping_add(k as u32);
            *s = render_pixel_batched(
                strategy, scene, camera, settings, sampling, x, y, first, count, *s, 0,
            );
        }
        return;
    };
    let span = Span::run(first, count);
    let job = Job::from_camera(strategy, scene, camera, settings, (x, y), span, 0);
    let (mut independent, mut zsobol);
    let pixel = match sampling.kind {
        SamplerKind::Independent => {
            independent = IndependentPixels::run(sampling.seed, pixel_number(camera, x, y), span);
            Pixel::Independent(&mut independent)
        }
        SamplerKind::ZSobol => {
            zsobol = ZSobolPixels::run(sampling.zsobol(), x, y, span);
            Pixel::ZSobolRun(&mut zsobol)
        }
    };
    let mut j = 0u32;
    let add = |r: &SampleResult| {
        let s = &mut stats[(j / count) as usize];
        s.add(r.l);
        s.rays += u64::from(r.rays);
        j += 1;
    };
    job.dispatch(pixel, 0, numbers, add);
}

/// The independent sampler's number of pixel `(x, y)` ([`super::render_sample`]'s).
fn pixel_number(camera: &Camera, x: u32, y: u32) -> u64 {
    u64::from(y) * u64::from(camera.width) + u64::from(x)
}

/// A batch's sampler (chosen once per call, the lanes compiled for each).
pub(super) enum Pixel<'p> {
    Independent(&'p mut IndependentPixels),
    ZSobol(&'p mut ZSobolPixelSampler),
    ZSobolRun(&'p mut ZSobolPixels),
}

/// What every batch of a pixel shares: the path tracer, the scene, where the paths start, the
/// packets.
pub(super) struct Job<'a, 'b, O> {
    pub strategy: &'a PathStrategy,
    pub scene: &'a SceneView<'b>,
    pub settings: &'a PathSettings,
    pub origin: O,
    pub packet_segments: u32,
}

/// Where the paths of a batch start: at the camera ([`CameraOrigin`]), or at a vertex to bake.
pub(super) trait Origin {
    /// The dimensions a sample draws before its first bounce.
    const DIMENSIONS: u32;

    /// Starts the paths of the lanes of `used` (sample `indices[lane]`, `pixel` at dimension
    /// 0 of it): their first vertex and BSDF in `state` ([`PathLanes::start`]), the emission
    /// seen before it in `seen`, the rays traced in `results`. Returns the lanes that have a
    /// first vertex.
    #[allow(clippy::too_many_arguments)]
    fn start<I: Isa, P: PixelSamples>(
        &self,
        isa: I,
        scene: &SceneView<'_>,
        pixel: &mut P,
        indices: &[u32; BATCH],
        used: u32,
        state: &mut PathLanes,
        seen: &mut [Rgb; BATCH],
        results: &mut [SampleResult; BATCH],
    ) -> u32;

    /// Sample `index`, which `pixel` was started at (dimension 0), traced alone by the
    /// one-path loop: what its lane would compute, for the samples too few to fill a batch's
    /// lanes ([`MIN_LANES`]).
    fn one<P: PixelSamples>(
        &self,
        index: u32,
        strategy: &PathStrategy,
        scene: &SceneView<'_>,
        settings: &PathSettings,
        pixel: &mut P,
    ) -> SampleResult;
}

/// Paths that start at the camera, through the pixels `(x + k, y)`, a sample's pixel `k` as
/// `span` numbers it; their first rays traced as a packet if `packet`.
pub(super) struct CameraOrigin<'a> {
    camera: &'a Camera,
    x: u32,
    y: u32,
    span: Span,
    packet: bool,
}

impl CameraOrigin<'_> {
    /// The camera ray of sample number `j` for its camera numbers `u` ([`dims::camera`]).
    #[inline(always)]
    fn ray(&self, j: u32, u: Vec2) -> Ray {
        let (k, _) = self.span.locate(j);
        self.camera.generate_ray(self.x.wrapping_add(k), self.y, u)
    }
}

impl<'a, 'b> Job<'a, 'b, CameraOrigin<'a>> {
    /// Paths from the camera through the pixels `(x + k, y)` numbered by `span`, their first
    /// `packet_segments` segments traced as packets.
    fn from_camera(
        strategy: &'a PathStrategy,
        scene: &'a SceneView<'b>,
        camera: &'a Camera,
        settings: &'a PathSettings,
        (x, y): (u32, u32),
        span: Span,
        packet_segments: u32,
    ) -> Self {
        Self {
            strategy,
            scene,
            settings,
            origin: CameraOrigin {
                camera,
                x,
                y,
                span,
                packet: packet_segments > 0,
            },
            packet_segments,
        }
    }
}

impl Origin for CameraOrigin<'_> {
    const DIMENSIONS: u32 = dims::CAMERA;

    #[inline(always)]
    fn start<I: Isa, P: PixelSamples>(
        &self,
        isa: I,
        scene: &SceneView<'_>,
        pixel: &mut P,
        indices: &[u32; BATCH],
        used: u32,
        state: &mut PathLanes,
        seen: &mut [Rgb; BATCH],
        results: &mut [SampleResult; BATCH],
    ) -> u32 {
        // Every lane's camera numbers in one draw: those `Self::ray` draws, the same bits.
        let mut u = [[0.0; BATCH]; dims::CAMERA as usize];
        pixel.draw_lanes::<2>(0, indices, used, I::LANE_HASHES, &mut u);
        let mut camera_rays = [Ray::new(Vec3::ZERO, Vec3::Z); BATCH];
        for lane in lanes_of(used) {
            camera_rays[lane] = self.ray(indices[lane], Vec2::new(u[0][lane], u[1][lane]));
            results[lane].rays += 1;
        }
        // A pixel's camera rays are nearly one ray: a packet can walk the tree once for them.
        let hits = if self.packet {
            scene.intersect_packet(&camera_rays, used)
        } else {
            let mut hits = [None; BATCH];
            for lane in lanes_of(used) {
                scene.intersect_with(isa, &camera_rays[lane], &mut hits[lane]);
            }
            hits
        };
        let live = scene.interactions_in(isa, &camera_rays, &hits, used, &mut state.si);
        for lane in lanes_of(live) {
            // Emission seen from the camera, added to each path's radiance at the end as
            // `li_path` adds it.
            seen[lane] = scene.emitted(&state.si.get(lane));
            state.start(lane, bsdf_of(scene, &state.si, lane));
        }
        live
    }

    #[inline(always)]
    fn one<P: PixelSamples>(
        &self,
        index: u32,
        strategy: &PathStrategy,
        scene: &SceneView<'_>,
        settings: &PathSettings,
        pixel: &mut P,
    ) -> SampleResult {
        let ray = self.ray(index, dims::camera(pixel));
        let mut rays = 0;
        let l = li_path(scene, &ray, settings, strategy, pixel, &mut rays);
        SampleResult { l, rays }
    }
}

impl<O: Origin> Job<'_, '_, O> {
    /// Samples `first .. first + count` drawn from `pixel`, [`BATCH`] at a time in SIMD lanes
    /// (AVX where the CPU has it), each given to `add` in sample order.
    #[inline(always)]
    pub fn dispatch(
        &self,
        pixel: Pixel<'_>,
        first: u32,
        count: u32,
        mut add: impl FnMut(&SampleResult),
    ) {
        match pixel {
            Pixel::Independent(p) => self.dispatch_with(p, first, count, &mut add),
            Pixel::ZSobol(p) => self.dispatch_with(p, first, count, &mut add),
            Pixel::ZSobolRun(p) => self.dispatch_with(p, first, count, &mut add),
        }
    }

    /// [`Self::dispatch`] for one sampler type: each type's lanes are compiled in a function of
    /// their own. In one function for all three samplers, LLVM left AVX intrinsics out of line
    /// (`_mm256_mul_ps` as a call: the batched film took 67 ms instead of 55).
    #[inline(always)]
    fn dispatch_with<P: PixelSamples>(
        &self,
        pixel: &mut P,
        first: u32,
        count: u32,
        add: &mut impl FnMut(&SampleResult),
    ) {
        #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
        if let Some(avx512) = crate::simd::Avx512::detect() {
            return avx512.run(
                #[inline(always)]
                |avx512| self.samples_from(avx512, pixel, first, count, add),
            );
        }
        #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
        if let Some(avx) = crate::simd::Avx::detect() {
            return avx.run(
                #[inline(always)]
                |avx| self.samples_from(avx, pixel, first, count, add),
            );
        }
        self.samples_baseline(pixel, first, count, add);
    }

    /// [`Self::samples_from`] in the baseline's lanes, out of line: inlined, its frame (the
    /// whole batch's state) would sit under the AVX function's on every call, 16 KB of stack
    /// that an embedder's threads would need for nothing (tests/capi/cornell.c measures the
    /// stack).
    #[inline(never)]
    fn samples_baseline<P: PixelSamples>(
        &self,
        pixel: &mut P,
        first: u32,
        count: u32,
        add: &mut impl FnMut(&SampleResult),
    ) {
        self.samples_from(crate::simd::Baseline, pixel, first, count, add);
    }

    /// Samples `first .. first + count` of `pixel`, [`BATCH`] at a time in the lanes of `isa`,
    /// each given to `add` in sample order.
    #[inline(always)]
    fn samples_from<I: Isa, P: PixelSamples>(
        &self,
        isa: I,
        pixel: &mut P,
        first: u32,
        count: u32,
        add: &mut impl FnMut(&SampleResult),
    ) {
        let end = first.saturating_add(count);
        let mut start = first;
        // Made once for the call's batches (a lane stage's worth of work).
        let emitters = if end - first >= MIN_LANES as u32 {
            EmitterTable::new(isa, self.scene)
        } else {
            None
        };
        while start < end {
            let n = (end - start).min(BATCH as u32) as usize;
            if n < MIN_LANES {
                for index in start..end {
                    pixel.start_sample(index, 0);
                    add(&self
                        .origin
                        .one(index, self.strategy, self.scene, self.settings, pixel));
                }
                break;
            }
            let results = self.batch(isa, pixel, start, n, emitters.as_ref());
            for r in &results[..n] {
                add(r);
            }
            start += n as u32;
        }
    }

    /// Samples `start .. start + n` (`n ≤ BATCH`) of the pixel, one lane each.
    #[inline(always)]
    fn batch<I: Isa, P: PixelSamples>(
        &self,
        isa: I,
        pixel: &mut P,
        start: u32,
        n: usize,
        emitters: Option<&EmitterTable<I::Eight>>,
    ) -> [SampleResult; BATCH] {
        let Self {
            strategy,
            scene,
            settings,
            packet_segments,
            ..
        } = *self;
        let indices: [u32; BATCH] = core::array::from_fn(|l| start.wrapping_add(l as u32));
        let mut results = [SampleResult::default(); BATCH];
        let mut seen = [Rgb::ZERO; BATCH];
        let mut state = PathLanes::new();
        let used = (1u32 << n) - 1;
        let mut live = self.origin.start(
            isa,
            scene,
            pixel,
            &indices,
            used,
            &mut state,
            &mut seen,
            &mut results,
        );
        let started = live;
        // Diffuse vertices under MIS run their bounce in lanes; every other lane runs the
        // one-path loop's stages on its own.
        let in_lanes = *strategy == PathStrategy::MIS;
        let mut numbers = BounceNumbers {
            base: 0,
            drawn: 0,
            values: [[0.0; BATCH]; dims::PER_BOUNCE as usize],
        };
        let mut base = O::DIMENSIONS;
        let mut bounces = 0u32;
        let mut us = [None; BATCH];
        let mut paths: [Option<PathState>; BATCH] = [None; BATCH];
        let mut shadows = [None; BATCH];
        let mut shadow_lanes = ShadowLanes::default();
        let mut nexts = [None; BATCH];
        let mut ray_lanes = RayLanes::default();
        while live != 0 {
            bounces += 1;
            // `PathState::light` ends every path here alike.
            if !settings.allows(bounces) {
                break;
            }
            let vector = if in_lanes { live & state.diffuse } else { 0 };
            let scalar = live & !vector;
            let offsets = bounce_offsets(strategy, settings, bounces, &state.bsdf, live);
            draw_bounce::<I, P>(pixel, &indices, live, base, offsets, &mut numbers);
            let values = &numbers.values;
            // Each lane's next-event estimate, then all their shadow rays.
            let mut shadow_scalar = 0u32;
            for lane in lanes_of(scalar) {
                let mut path = state.path(lane, bounces - 1);
                let sampler = &mut LaneSampler::at(&numbers, lane, indices[lane], base, pixel);
                if let Some((u, shadow)) = path.light(scene, settings, strategy, sampler) {
                    us[lane] = Some(u);
                    shadows[lane] = shadow;
                    if shadow.is_some() {
                        shadow_scalar |= 1 << lane;
                    }
                }
                paths[lane] = Some(path);
            }
            // The diffuse vertices, read once for both lane stages of the bounce.
            // Not in a closure: LLVM may leave a closure out of line, outside the AVX function,
            // and its lane operations become calls (`_mm256_mul_ps`, measured 11% of a render).
            let vertex = if vector != 0 {
                Some(Vertex::<I::Eight>::load(isa, &state))
            } else {
                None
            };
            let shadow_vector = if let Some(vertex) = &vertex {
                let light = dims::LIGHT_POSITION as usize;
                next_event_diffuse(
                    isa,
                    scene,
                    emitters,
                    vertex,
                    vector,
                    &values[dims::LIGHT_SELECT as usize],
                    [&values[light], &values[light + 1]],
                    &mut shadow_lanes,
                )
            } else {
                0
            };
            let shadow_rays: [Ray; BATCH] = core::array::from_fn(|l| {
                if shadow_vector >> l & 1 != 0 {
                    let s = &shadow_lanes;
                    Ray {
                        o: s.o.get(l),
                        d: s.d.get(l),
                        t_max: s.t_max[l],
                    }
                } else {
                    shadows[l]
                        .as_ref()
                        .map_or(Ray::new(Vec3::ZERO, Vec3::Z), |s: &ShadowQuery| s.ray)
                }
            });
            for lane in lanes_of(shadow_scalar | shadow_vector) {
                results[lane].rays += 1;
            }
            let packet = bounces < packet_segments;
            let occluded = trace_shadows(
                isa,
                scene,
                &shadow_rays,
                shadow_scalar | shadow_vector,
                packet,
            );
            for lane in lanes_of(shadow_scalar) {
                if let (Some(path), Some(shadow)) = (paths[lane].as_mut(), shadows[lane].as_ref()) {
                    path.add_light(shadow, occluded >> lane & 1 == 0);
                }
            }
            if shadow_vector != 0 {
                add_light_lanes(isa, &mut state, &shadow_lanes, shadow_vector, occluded);
            }
            // Each lane's scattered ray, then all of them.
            for lane in lanes_of(scalar) {
                let (Some(path), Some(u)) = (paths[lane].as_mut(), us[lane]) else {
                    live &= !(1 << lane);
                    continue;
                };
                nexts[lane] = path.scatter(
                    settings,
                    strategy,
                    &mut LaneSampler::at(&numbers, lane, indices[lane], base, pixel),
                    u,
                );
                state.put(lane, path);
                if nexts[lane].is_none() {
                    live &= !(1 << lane);
                }
            }
            if let Some(vertex) = &vertex {
                let direction = dims::BSDF_DIRECTION as usize;
                let goes_on = scatter_diffuse(
                    isa,
                    settings,
                    bounces,
                    &mut state,
                    vertex,
                    vector,
                    [&values[direction], &values[direction + 1]],
                    &values[dims::ROULETTE as usize],
                    &mut ray_lanes,
                );
                let terminal = settings.is_terminal(bounces);
                for lane in lanes_of(vector) {
                    if goes_on >> lane & 1 == 0 {
                        live &= !(1 << lane);
                        continue;
                    }
                    nexts[lane] = Some(NextRay {
                        ray: Ray::new(ray_lanes.o.get(lane), ray_lanes.d.get(lane)),
                        terminal,
                        counts_emission: true,
                        specular: false,
                        pdf: SolidAnglePdf(ray_lanes.pdf[lane]),
                    });
                }
            }
            for lane in lanes_of(live) {
                results[lane].rays += 1;
            }
            let hits = trace_next(isa, scene, settings, &nexts, live, packet);
            let rays = rays_of(&nexts, |n| n.ray);
            let prev_p = state.si.p;
            let arrived = scene.interactions_in(isa, &rays, &hits, live, &mut state.si);
            for lane in lanes_of(live) {
                let Some(next) = nexts[lane].as_ref().filter(|_| arrived >> lane & 1 != 0) else {
                    // The ray left the scene.
                    live &= !(1 << lane);
                    continue;
                };
                // `PathState::arrive_at`.
                let material = scene.material(state.si.material[lane]);
                if next.counts_emission && material.is_emissive() {
                    let si = state.si.get(lane);
                    if let Some((le, w)) =
                        next.emission_found(scene, strategy, prev_p.get(lane), &si)
                    {
                        let l = state.l.get(lane) + state.beta.get(lane) * le * w;
                        state.l.set(lane, l);
                    }
                }
                if next.terminal {
                    live &= !(1 << lane);
                    continue;
                }
                state.set_bsdf(lane, bsdf_of(scene, &state.si, lane));
            }
            base = base.wrapping_add(dims::PER_BOUNCE);
        }
        for lane in lanes_of(started) {
            results[lane].l = seen[lane] + state.l.get(lane);
        }
        results
    }
}

/// The BSDF at lane `l`'s vertex ([`SceneView::bsdf_at`]).
#[inline(always)]
fn bsdf_of(scene: &SceneView<'_>, si: &SurfaceLanes, l: usize) -> Bsdf {
    scene.material(si.material[l]).bsdf(&scene.textures, || {
        scene.uv_at(si.triangle[l], si.b1[l], si.b2[l])
    })
}

/// The segments of its paths a batch traces as packets ([`SceneView::intersect_packet`],
/// [`SceneView::occluded_packet`]), from the camera's (segment 0; segment `k` leaves bounce
/// `k`): a pixel's paths start close together and spread out as they bounce. None, because
/// packets did not pay on the AMD EPYC (Zen 5) of 2026-12-07 (`cargo bench -p ember-tests
/// --bench batch`, MIS, one thread, 3 alternating runs): the batched film took 1.21–1.24 times
/// the one-path loop's time with packets for the camera rays, 1.25–1.28 with the first
/// bounce's rays too, 1.13–1.16 without (`cbox.obj`: 1.15–1.21, 1.28, 1.12–1.14). Packets
/// test one triangle against eight rays in `wide`'s lanes, compiled for the baseline (SSE2 on
/// x86-64), where a single ray tests eight triangles with AVX.
pub const PACKET_SEGMENTS: u32 = 0;

/// The ray of each lane's query (a placeholder where there is none), built in place: an array
/// `map` over the queries copied them, 3% of a batched render.
#[inline(always)]
fn rays_of<T>(queries: &[Option<T>; BATCH], ray: impl Fn(&T) -> Ray) -> [Ray; BATCH] {
    core::array::from_fn(|l| {
        queries[l]
            .as_ref()
            .map_or(Ray::new(Vec3::ZERO, Vec3::Z), &ray)
    })
}

/// Whether the shadow rays of `lanes` are occluded (bits), traced as a packet if `packet`.
#[inline(always)]
fn trace_shadows<I: Isa>(
    isa: I,
    scene: &SceneView<'_>,
    rays: &[Ray; BATCH],
    lanes: u32,
    packet: bool,
) -> u32 {
    if packet && lanes.count_ones() > 1 {
        return scene.occluded_packet(rays, lanes);
    }
    lanes_of(lanes).fold(0, |m, lane| {
        m | u32::from(scene.occluded_with(isa, &rays[lane])) << lane
    })
}

/// Where the rays of `lanes` land ([`NextRay::trace`]), traced as a packet if `packet`.
#[inline(always)]
fn trace_next<I: Isa>(
    isa: I,
    scene: &SceneView<'_>,
    settings: &PathSettings,
    nexts: &[Option<NextRay>; BATCH],
    lanes: u32,
    packet: bool,
) -> [Option<Hit>; BATCH] {
    let mut hits = [None; BATCH];
    let mut rest = lanes;
    if packet {
        // Terminal rays take their own shortcut; the others go as a packet.
        let mut packed = 0u32;
        for lane in lanes_of(lanes) {
            if nexts[lane].is_some_and(|n| !n.terminal) {
                packed |= 1 << lane;
            }
        }
        if packed.count_ones() > 1 {
            let rays = rays_of(nexts, |n| n.ray);
            hits = scene.intersect_packet(&rays, packed);
            rest &= !packed;
        }
    }
    for lane in lanes_of(rest) {
        if let Some(next) = &nexts[lane] {
            let intersect = |ray: &Ray, hit: &mut Option<Hit>| scene.intersect_with(isa, ray, hit);
            next.trace_by(scene, settings, intersect, &mut hits[lane]);
        }
    }
    hits
}

/// The dimensions (bits: offsets of [`dims`]) some lane of `live` may draw at bounce number
/// `bounces`: the emitter's when the strategy samples emitters, the lobe choice when a BSDF
/// has lobes to choose from, the direction, the roulette number once roulette is played.
#[inline(always)]
fn bounce_offsets(
    strategy: &PathStrategy,
    settings: &PathSettings,
    bounces: u32,
    bsdfs: &[Bsdf; BATCH],
    live: u32,
) -> u32 {
    let mut offsets = 0b11 << dims::BSDF_DIRECTION;
    if strategy.direct != super::DirectLighting::BsdfSampling {
        offsets |= 0b111 << dims::LIGHT_SELECT;
    }
    if settings.roulette_applies(strategy.roulette, bounces) {
        offsets |= 1 << dims::ROULETTE;
    }
    for lane in lanes_of(live) {
        if bsdfs[lane].uses_lobe_choice() {
            offsets |= 1 << dims::BSDF_LOBE;
            break;
        }
    }
    offsets
}
