//! Deterministic sampling keyed by (seed, pixel, sample index, dimension): independent
//! numbers ([`IndependentSampler`]) or Owen-scrambled Sobol' points ([`ZSobolSampler`]).
//!
//! Like pbrt-v4's `IndependentSampler::StartPixelSample`, every sample value is a pure function
//! of its key, so an image does not depend on thread count, tile order or scheduling. Instead of
//! advancing a PCG stream we hash the key directly (a counter-based generator): the value of
//! dimension `d` of sample `i` of pixel `p` is `hash(seed, p, i, d)`.

use glam::Vec2;

mod zsobol;
pub use zsobol::{
    morton2, owen_scramble, sobol_u32, ZSobolLayout, ZSobolPixelSampler, ZSobolSampler, DRAW_LANES,
    MEMO_SLOTS,
};

/// Which sequence a render's samples come from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SamplerKind {
    /// Independent uniform numbers, hashed from (seed, pixel, sample index, dimension)
    /// ([`IndependentSampler`]): the default.
    #[default]
    Independent,
    /// Owen-scrambled Sobol' points with pixels in Morton order ([`ZSobolSampler`]): stratified
    /// per pixel and blue-noise across pixels. Needs the render's samples per pixel up front.
    ZSobol,
}

/// Everything a render's samples are keyed by besides (pixel, sample index, dimension): the
/// sampler, the seed and, for [`SamplerKind::ZSobol`], the film and the samples per pixel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Sampling {
    pub kind: SamplerKind,
    pub seed: u64,
    layout: ZSobolLayout,
}

impl Sampling {
    /// Samples of a `width × height` film rendered with `spp` samples per pixel (sample
    /// indices `0..spp`; the independent sampler ignores the film and `spp`).
    #[must_use]
    pub fn new(kind: SamplerKind, seed: u64, spp: u32, width: u32, height: u32) -> Self {
        Self {
            kind,
            seed,
            layout: ZSobolLayout::new(seed, spp, width, height),
        }
    }

    /// Independent samples with `seed`.
    #[must_use]
    pub fn independent(seed: u64) -> Self {
        Self::new(SamplerKind::Independent, seed, 1, 1, 1)
    }

    /// The Sobol' layout (meaningful for [`SamplerKind::ZSobol`]).
    #[inline]
    #[must_use]
    pub const fn zsobol(&self) -> &ZSobolLayout {
        &self.layout
    }
}

/// The source of uniform random numbers in `[0, 1)` for integrators and warps: the numbers of
/// one pixel sample, dimension after dimension (pbrt-v4's `Sampler` after `StartPixelSample`).
pub trait Sampler {
    fn next_1d(&mut self) -> f32;
    #[inline]
    fn next_2d(&mut self) -> Vec2 {
        let x = self.next_1d();
        let y = self.next_1d();
        Vec2::new(x, y)
    }
    /// Moves to dimension `d`: the next number drawn is dimension `d`'s (for layouts with
    /// fixed dimension slots, [`crate::integrator::dims`]).
    fn set_dimension(&mut self, d: u32);
    /// The dimension the next number drawn belongs to.
    fn dimension(&self) -> u32;
}

/// The lanes whose bits are set in `mask`, lowest first (the lane masks of batched draws,
/// [`ZSobolPixelSampler::draw_lanes`]).
#[inline(always)]
pub fn lanes_of(mask: u32) -> impl Iterator<Item = usize> {
    let mut rest = mask;
    core::iter::from_fn(move || {
        (rest != 0).then(|| {
            let lane = rest.trailing_zeros() as usize;
            rest &= rest - 1;
            lane
        })
    })
}

/// The default seed of the command-line renderer (`--seed`): 0x656D626572, "ember" in ASCII.
pub const DEFAULT_SEED: u64 = 0x65_6D_62_65_72;

/// Largest f32 below 1; sample values never reach 1.
pub const ONE_MINUS_EPSILON: f32 = 1.0 - f32::EPSILON * 0.5;

/// A 64-bit finaliser with full avalanche (the `splitmix64` output function).
#[inline]
#[must_use]
pub const fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Independent uniform samples for one (seed, pixel, sample index); each call to
/// [`Sampler::next_1d`] moves to the next dimension.
#[derive(Clone, Copy, Debug)]
pub struct IndependentSampler {
    key: u64,
    dimension: u32,
}

impl IndependentSampler {
    /// Starts sample `sample_index` of the pixel (or baked vertex) with linear index `pixel`,
    /// at dimension 0.
    #[inline]
    #[must_use]
    pub fn new(seed: u64, pixel: u64, sample_index: u32) -> Self {
        let k = mix64(seed ^ 0x6A09_E667_F3BC_C909);
        let k = mix64(k ^ pixel);
        let k = mix64(k ^ u64::from(sample_index));
        Self {
            key: k,
            dimension: 0,
        }
    }
}

impl Sampler for IndependentSampler {
    #[inline]
    fn next_1d(&mut self) -> f32 {
        let h = mix64(self.key ^ u64::from(self.dimension).wrapping_mul(0x9E37_79B9_7F4A_7C15));
        self.dimension = self.dimension.wrapping_add(1);
        // 24 high bits: exactly representable, in [0, 1 - 2^-24].
        (h >> 40) as f32 * (1.0 / (1u64 << 24) as f32)
    }

    #[inline]
    fn set_dimension(&mut self, d: u32) {
        self.dimension = d;
    }

    #[inline]
    fn dimension(&self) -> u32 {
        self.dimension
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn values_are_a_pure_function_of_the_key() {
        let mut a = IndependentSampler::new(7, 1234, 5);
        let mut b = IndependentSampler::new(7, 1234, 5);
        for _ in 0..100 {
            assert_eq!(a.next_1d().to_bits(), b.next_1d().to_bits());
        }
        let mut c = IndependentSampler::new(7, 1234, 5);
        c.set_dimension(10);
        let mut d = IndependentSampler::new(7, 1234, 5);
        for _ in 0..10 {
            d.next_1d();
        }
        assert_eq!(c.next_1d().to_bits(), d.next_1d().to_bits());
    }

    #[test]
    fn different_keys_differ_and_values_are_uniform() {
        let n = 200_000;
        let mut hist = [0u32; 16];
        let mut sum = 0.0f64;
        for i in 0..n {
            let mut s = IndependentSampler::new(1, u64::from(i % 997), i / 997);
            let v = s.next_1d();
            assert!((0.0..1.0).contains(&v));
            sum += f64::from(v);
            hist[(v * 16.0) as usize] += 1;
        }
        assert!((sum / f64::from(n) - 0.5).abs() < 0.005);
        let expected = f64::from(n) / 16.0;
        let chi2: f64 = hist
            .iter()
            .map(|&h| (f64::from(h) - expected).powi(2) / expected)
            .sum();
        // 15 degrees of freedom, p = 0.001 critical value is 37.7.
        assert!(chi2 < 37.7, "chi2 = {chi2}");
        let x = IndependentSampler::new(1, 2, 3).next_1d();
        let y = IndependentSampler::new(2, 2, 3).next_1d();
        let z = IndependentSampler::new(1, 3, 3).next_1d();
        assert!(x != y && x != z);
    }
}
