//! Owen-scrambled Sobol' samples with pixels in Morton order (pbrt-v4's `ZSobolSampler`,
//! after Ahmed and Wonka, "Screen-space blue-noise diffusion of Monte Carlo sampling error via
//! hierarchical ordering of pixels", 2020).
//!
//! Every pixel sample is one point of a single (0, 2)-sequence in base 2, the first two Sobol'
//! dimensions: the index of sample `i` of pixel `(x, y)` is the Morton code of the pixel
//! followed by the bits of `i`, so the samples of one pixel form an elementary block of the
//! sequence (stratified in 2D whatever the dimension pair), and neighbouring pixels get
//! neighbouring blocks. Before it is used, the index's base-4 digits are shuffled by
//! permutations that depend on the higher digits, the dimension and the seed, which
//! decorrelates the dimensions and spreads the error across pixels as blue noise. Each
//! dimension's points are then Owen-scrambled (Laine–Karras hash, pbrt's
//! `FastOwenScrambler`), which keeps the nets' stratification and makes every point uniform.
//!
//! Differences from pbrt-v4: the seed also keys the digit permutations (pbrt keys only the
//! scrambling with it), so that two seeds give independent randomisations, which is what the
//! replicate-based tests need; values are the high 24 bits of the scrambled point, as the
//! independent sampler's, so they are exact in f32 and never reach 1.
//!
//! All of it is integer arithmetic: the samples are bit-identical on every target.

use super::{lanes_of, mix64, Sampler};
use glam::Vec2;

/// The generator matrices of Sobol's first two dimensions, as 32 columns of 32 bits (column
/// `k` is what bit `k` of the index contributes). Dimension 0 is the van der Corput sequence
/// (bit reversal); dimension 1 is Pascal's triangle mod 2.
const SOBOL_MATRICES: [[u32; 32]; 2] = {
    let mut m = [[0u32; 32]; 2];
    let mut k = 0;
    while k < 32 {
        m[0][k] = 1 << (31 - k);
        m[1][k] = if k == 0 {
            1 << 31
        } else {
            m[1][k - 1] ^ (m[1][k - 1] >> 1)
        };
        k += 1;
    }
    m
};

/// Dimension 1's matrix applied a byte at a time, bit-reversed: `SOBOL_1_BYTES_REVERSED[j][b]`
/// is the XOR of the columns selected by byte value `b` at byte position `j` of the index, its
/// bits reversed. The scramble starts by reversing its input, and reversal commutes with XOR,
/// so storing the columns reversed saves that reversal (dimension 0's point is the index
/// reversed, so its reversal is the index itself).
const SOBOL_1_BYTES_REVERSED: [[u32; 256]; 4] = {
    let mut t = [[0u32; 256]; 4];
    let mut j = 0;
    while j < 4 {
        let mut b = 0;
        while b < 256 {
            let mut v = 0u32;
            let mut k = 0;
            while k < 8 {
                if b & (1 << k) != 0 {
                    v ^= SOBOL_MATRICES[1][8 * j + k];
                }
                k += 1;
            }
            t[j][b] = v.reverse_bits();
            b += 1;
        }
        j += 1;
    }
    t
};

/// The Sobol' point `index` of dimension `dim` (0 or 1), unscrambled, as a 32-bit fraction.
/// Index bits beyond 32 select nothing at 32-bit precision.
#[inline]
#[must_use]
pub fn sobol_u32(index: u64, dim: usize) -> u32 {
    sobol_reversed(index, dim).reverse_bits()
}

/// [`sobol_u32`] with its bits reversed (what [`owen_scramble_reversed`] takes).
#[inline]
fn sobol_reversed(index: u64, dim: usize) -> u32 {
    let a = index as u32;
    if dim == 0 {
        return a;
    }
    let t = &SOBOL_1_BYTES_REVERSED;
    t[0][(a & 0xFF) as usize]
        ^ t[1][((a >> 8) & 0xFF) as usize]
        ^ t[2][((a >> 16) & 0xFF) as usize]
        ^ t[3][(a >> 24) as usize]
}

/// [`sobol_u32`] of dimension 1 column by column (the definition; the tests compare).
#[cfg(test)]
fn sobol_1_by_columns(index: u64) -> u32 {
    let mut a = index as u32;
    let mut v = 0u32;
    while a != 0 {
        v ^= SOBOL_MATRICES[1][a.trailing_zeros() as usize];
        a &= a - 1;
    }
    v
}

/// Laine and Karras's nested uniform scramble of a 32-bit fraction (pbrt-v4's
/// `FastOwenScrambler`): each output bit depends only on the bits above it and the seed, so
/// every elementary interval of a net is mapped onto one of the same size.
#[inline]
#[must_use]
pub const fn owen_scramble(v: u32, seed: u32) -> u32 {
    owen_scramble_reversed(v.reverse_bits(), seed)
}

/// [`owen_scramble`] of the fraction whose bit reversal is `r`.
#[inline]
const fn owen_scramble_reversed(r: u32, seed: u32) -> u32 {
    let mut v = r;
    v ^= v.wrapping_mul(0x3d20_adea);
    v = v.wrapping_add(seed);
    v = v.wrapping_mul((seed >> 16) | 1);
    v ^= v.wrapping_mul(0x0552_6c56);
    v ^= v.wrapping_mul(0x53a2_2864);
    v.reverse_bits()
}

/// A hash of the digits above one digit and the dimension's key: two multiplies, and the
/// digits' hashes do not depend on each other, so they overlap in the pipeline (pbrt's full
/// 64-bit finaliser for every digit made a Cornell box sample 2x slower than independent
/// sampling).
#[inline]
const fn permutation_hash(higher: u64, key: u64) -> u64 {
    let h = (higher ^ key).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    (h ^ (h >> 32)).wrapping_mul(0xD6E8_FEB8_6659_FD93)
}

/// Which of the 24 permutations a digit gets (multiply-shift range reduction of the hash's
/// high bits).
#[inline]
const fn permutation_of(higher: u64, key: u64) -> usize {
    (((permutation_hash(higher, key) >> 32) * 24) >> 32) as usize
}

/// The 24 permutations of four base-4 digits.
const PERMUTATIONS: [[u8; 4]; 24] = [
    [0, 1, 2, 3],
    [0, 1, 3, 2],
    [0, 2, 1, 3],
    [0, 2, 3, 1],
    [0, 3, 2, 1],
    [0, 3, 1, 2],
    [1, 0, 2, 3],
    [1, 0, 3, 2],
    [1, 2, 0, 3],
    [1, 2, 3, 0],
    [1, 3, 2, 0],
    [1, 3, 0, 2],
    [2, 1, 0, 3],
    [2, 1, 3, 0],
    [2, 0, 1, 3],
    [2, 0, 3, 1],
    [2, 3, 0, 1],
    [2, 3, 1, 0],
    [3, 1, 2, 0],
    [3, 1, 0, 2],
    [3, 2, 1, 0],
    [3, 2, 0, 1],
    [3, 0, 2, 1],
    [3, 0, 1, 2],
];

/// [`PERMUTATIONS`] packed two bits an entry, a byte a permutation, eight permutations a word:
/// permutation `p` is byte `p % 8` of word `p / 8`. So a lookup is a selection among three
/// words and a shift, which a loop over SIMD lanes computes without a gather.
const PERMUTATION_BITS: [u64; 3] = {
    let mut w = [0u64; 3];
    let mut p = 0;
    while p < 24 {
        let mut k = 0;
        while k < 4 {
            w[p / 8] |= (PERMUTATIONS[p][k] as u64) << (8 * (p % 8) + 2 * k);
            k += 1;
        }
        p += 1;
    }
    w
};

/// `PERMUTATIONS[p][digit]` (`p < 24`, `digit < 4`), branch-free ([`PERMUTATION_BITS`]).
#[inline(always)]
const fn permuted_digit(p: usize, digit: u64) -> u64 {
    let p = p as u64;
    let word = if p < 8 {
        PERMUTATION_BITS[0]
    } else if p < 16 {
        PERMUTATION_BITS[1]
    } else {
        PERMUTATION_BITS[2]
    };
    (word >> (8 * (p & 7) + 2 * digit)) & 3
}

/// Interleaves the bits of `x` (even bits) and `y` (odd bits).
#[inline]
#[must_use]
pub const fn morton2(x: u32, y: u32) -> u64 {
    const fn spread(v: u32) -> u64 {
        let mut v = v as u64;
        v = (v | (v << 16)) & 0x0000_FFFF_0000_FFFF;
        v = (v | (v << 8)) & 0x00FF_00FF_00FF_00FF;
        v = (v | (v << 4)) & 0x0F0F_0F0F_0F0F_0F0F;
        v = (v | (v << 2)) & 0x3333_3333_3333_3333;
        (v | (v << 1)) & 0x5555_5555_5555_5555
    }
    spread(x) | (spread(y) << 1)
}

/// The sequence's layout for one film and sample count: fixed for a render, so that a sample's
/// values depend only on (seed, pixel, sample index, dimension).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ZSobolLayout {
    seed: u64,
    log2_spp: u32,
    base4_digits: u32,
}

impl ZSobolLayout {
    /// The layout of a `width × height` film rendered with `spp` samples per pixel (rounded up
    /// to a power of two: sample indices must stay below it).
    #[must_use]
    pub fn new(seed: u64, spp: u32, width: u32, height: u32) -> Self {
        let log2_spp = spp.max(1).next_power_of_two().trailing_zeros();
        let res = width.max(height).max(1).next_power_of_two();
        let log2_res = res.trailing_zeros();
        Self {
            seed: mix64(seed ^ 0x2F5A_3C91_D1B5_4A32),
            log2_spp,
            base4_digits: log2_res + log2_spp.div_ceil(2),
        }
    }

    /// The samples per pixel the layout has room for (a power of two).
    #[inline]
    #[must_use]
    pub const fn capacity(&self) -> u32 {
        1 << self.log2_spp
    }

    /// Starts sample `index` of pixel `(x, y)` at dimension `dimension` (pbrt-v4's
    /// `StartPixelSample`). `index` must be below [`Self::capacity`]; beyond it the samples
    /// would repeat another pixel's.
    #[inline]
    #[must_use]
    pub fn start_pixel_sample(&self, x: u32, y: u32, index: u32, dimension: u32) -> ZSobolSampler {
        debug_assert!(
            index < self.capacity(),
            "ZSobol sample index past the layout"
        );
        ZSobolSampler {
            layout: *self,
            morton_index: self.morton_index(x, y, index),
            dimension,
        }
    }
}

/// The samples of one pixel sample: each draw moves on by the dimensions it uses.
#[derive(Clone, Copy, Debug)]
pub struct ZSobolSampler {
    layout: ZSobolLayout,
    morton_index: u64,
    dimension: u32,
}

impl ZSobolLayout {
    /// A hash of (seed, dimension): the scrambling seeds of dimensions `dimension` and
    /// `dimension + 1` are its halves, and it is the digit permutations' key (mixed with each
    /// digit's higher digits by [`permutation_hash`]).
    #[inline]
    fn dimension_key(&self, dimension: u32) -> u64 {
        mix64(self.seed ^ u64::from(dimension).wrapping_mul(0x9E37_79B9_7F4A_7C15))
    }

    /// Base-4 digits of the Morton index that hold sample-index bits (the bottom
    /// `log2 spp` bits, less the odd base-2 digit); the digits above them hold pixel bits only.
    #[inline]
    const fn sample_base4_digits(&self) -> u32 {
        self.log2_spp.div_ceil(2)
    }

    /// Permutes the base-4 digits of `morton_index` numbered `from..to` (digit `i` covers bits
    /// `2i − odd` and the one above), each by a permutation chosen by the digits above it and
    /// `key` (pbrt-v4's `GetSampleIndex`, one range of its loop).
    #[inline]
    fn permuted_digits(&self, morton_index: u64, key: u64, from: u32, to: u32) -> u64 {
        let odd = self.log2_spp & 1;
        let mut index = 0u64;
        let mut i = to;
        while i > from {
            i -= 1;
            let shift = 2 * i - odd;
            let digit = (morton_index >> shift) & 3;
            let p = permutation_of(morton_index >> (shift + 2), key);
            index |= u64::from(PERMUTATIONS[p][digit as usize]) << shift;
        }
        index
    }

    /// The permuted digits above the sample index's: a function of the pixel and the
    /// dimension only, the same for every sample of a pixel ([`ZSobolPixelSampler`] keeps them).
    #[inline]
    fn pixel_part(&self, morton_index: u64, key: u64) -> u64 {
        let from = self.sample_base4_digits();
        self.permuted_digits(morton_index, key, from, self.base4_digits)
    }

    /// The permuted digits of the sample index, and the odd base-2 digit at the bottom
    /// when `log2 spp` is odd, flipped by a hash of the same kind.
    #[inline]
    fn sample_part(&self, morton_index: u64, key: u64) -> u64 {
        self.upper_sample_part(morton_index, key) | self.lowest_sample_part(morton_index, key)
    }

    /// The Morton index bits that [`Self::upper_sample_part`] depends on: those above the
    /// lowest sample digit.
    #[inline]
    const fn upper_tag(&self, morton_index: u64) -> u64 {
        morton_index >> ((self.log2_spp & 1) + 2)
    }

    /// [`Self::sample_part`]'s permuted sample digits above the lowest one: a function of
    /// [`Self::upper_tag`] and the key.
    #[inline]
    fn upper_sample_part(&self, morton_index: u64, key: u64) -> u64 {
        let odd = self.log2_spp & 1;
        let to = self.sample_base4_digits();
        if to <= odd + 1 {
            return 0;
        }
        self.permuted_digits(morton_index, key, odd + 1, to)
    }

    /// [`Self::sample_part`]'s lowest sample digit, and the odd base-2 digit below it when
    /// `log2 spp` is odd.
    #[inline]
    fn lowest_sample_part(&self, morton_index: u64, key: u64) -> u64 {
        let permutation = self.lowest_permutation(morton_index, key);
        self.lowest_sample_part_with(morton_index, key, permutation)
    }

    /// The permutation of the lowest sample digit: a function of [`Self::upper_tag`] and the
    /// key, like the digits above it (so [`ZSobolPixelSampler`] keeps it with them).
    #[inline]
    fn lowest_permutation(&self, morton_index: u64, key: u64) -> usize {
        permutation_of(self.upper_tag(morton_index), key)
    }

    /// [`Self::lowest_sample_part`] given [`Self::lowest_permutation`] (one digit of
    /// [`Self::permuted_digits`]).
    #[inline]
    fn lowest_sample_part_with(&self, morton_index: u64, key: u64, permutation: usize) -> u64 {
        let odd = self.log2_spp & 1;
        let mut index = 0u64;
        if self.sample_base4_digits() > odd {
            let digit = (morton_index >> odd) & 3;
            index = u64::from(PERMUTATIONS[permutation][digit as usize]) << odd;
        }
        if odd == 1 {
            let flip = permutation_hash(morton_index >> 1, key) >> 63;
            index |= (morton_index & 1) ^ flip;
        }
        index
    }

    /// The index into the Sobol' sequence for `dimension`: the Morton index with its base-4
    /// digits permuted, each by a permutation chosen by the digits above it, the dimension and
    /// the seed (pbrt-v4's `GetSampleIndex`). An odd `log2 spp` leaves one base-2 digit at the
    /// bottom, flipped by a hash of the same kind.
    #[inline]
    fn sample_index(&self, morton_index: u64, key: u64) -> u64 {
        self.pixel_part(morton_index, key) | self.sample_part(morton_index, key)
    }

    /// The Morton index of sample `index` of pixel `(x, y)`.
    #[inline]
    pub(crate) fn morton_index(&self, x: u32, y: u32, index: u32) -> u64 {
        (morton2(x, y) << self.log2_spp) | u64::from(index)
    }

    /// The sampler of pixel `(x, y)`, for its samples one after another
    /// ([`ZSobolPixelSampler::start_sample`]); the same values as [`Self::start_pixel_sample`],
    /// with the per-pixel part of each dimension's index computed once per pixel.
    #[must_use]
    pub fn pixel_sampler(&self, x: u32, y: u32) -> ZSobolPixelSampler {
        ZSobolPixelSampler {
            layout: *self,
            pixel_index: self.morton_index(x, y, 0),
            morton_index: self.morton_index(x, y, 0),
            past_layout: false,
            dimension: 0,
            tags: [u32::MAX; MEMO_SLOTS],
            keys: [0; MEMO_SLOTS],
            pixel_parts: [0; MEMO_SLOTS],
            upper_tags: [u64::MAX; MEMO_SLOTS],
            upper_parts: [0; MEMO_SLOTS],
            lowest_permutations: [0; MEMO_SLOTS],
        }
    }
}

/// Draws `N` consecutive dimensions from `dimension` on, given the index into the sequence and
/// the dimension key: the scrambled Sobol' points of Sobol' dimensions `0..N`.
#[inline]
fn draw<const N: usize>(index: u64, key: u64) -> [f32; N] {
    let seeds = [key as u32, (key >> 32) as u32];
    core::array::from_fn(|k| to_unit(owen_scramble_reversed(sobol_reversed(index, k), seeds[k])))
}

impl ZSobolSampler {
    /// The next `N` (1 or 2) dimensions.
    #[inline]
    fn next<const N: usize>(&mut self) -> [f32; N] {
        let key = self.layout.dimension_key(self.dimension);
        let index = self.layout.sample_index(self.morton_index, key);
        self.dimension = self.dimension.wrapping_add(N as u32);
        draw(index, key)
    }
}

/// A scrambled 32-bit fraction as f32 in `[0, 1)`: its 24 high bits, exact.
#[inline]
fn to_unit(v: u32) -> f32 {
    (v >> 8) as f32 * (1.0 / (1u32 << 24) as f32)
}

/// [`Sampler`] for a type with `next::<N>()` (the next `N` dimensions) and a `dimension`.
macro_rules! sampler_from_next {
    ($t:ty) => {
        impl Sampler for $t {
            #[inline]
            fn next_1d(&mut self) -> f32 {
                let [u] = self.next::<1>();
                u
            }

            #[inline]
            fn next_2d(&mut self) -> Vec2 {
                Vec2::from_array(self.next::<2>())
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
    };
}

sampler_from_next!(ZSobolSampler);

/// Dimensions whose key and per-pixel index part a [`ZSobolPixelSampler`] remembers: slot
/// `dimension % MEMO_SLOTS` (direct-mapped, so BDPT's light-subpath dimensions far above the
/// camera subpath's are kept too, at the cost of an occasional eviction). A path tracer's
/// sample uses 2 + 7 per bounce, so 128 slots hold 18 bounces: on the project's Cornell box
/// (unbounded depth, 16 spp) 64 slots evicted often enough to cost 1% of the render's
/// instructions (1,621 M against 1,604 M at 128; 1,603 M at 256).
pub const MEMO_SLOTS: usize = 128;

/// The samples of one pixel, one sample after another (pbrt-v4's `StartPixelSample` on a
/// sampler kept for the pixel): the values of [`ZSobolLayout::start_pixel_sample`], bit for
/// bit, but each dimension's key and the permuted digits above the sample index, which depend
/// only on the pixel and the dimension, are computed once per pixel instead of once per
/// sample (the digits of a 320 × 240 film at 32 spp are nine of twelve). On TinyRender's
/// Cornell box (MIS), that takes the sampler's instructions beyond independent sampling's from
/// 520 M to 457 M at 2 samples per call (32 spp in 16 passes) and to 343 M at 32 per call,
/// which is why `ember render` makes a path tracer's passes of at least 8 samples.
#[derive(Clone, Debug)]
pub struct ZSobolPixelSampler {
    layout: ZSobolLayout,
    /// The pixel's Morton index with sample index 0.
    pixel_index: u64,
    morton_index: u64,
    /// The sample index is past the layout's capacity (see [`Self::start_sample`]).
    past_layout: bool,
    dimension: u32,
    /// The dimension each slot holds (`u32::MAX`: none).
    tags: [u32; MEMO_SLOTS],
    keys: [u64; MEMO_SLOTS],
    pixel_parts: [u64; MEMO_SLOTS],
    /// The slot's dimension's permuted sample digits above the lowest one
    /// ([`ZSobolLayout::upper_sample_part`]), for the Morton index bits above the lowest digit
    /// in `upper_tags` (`u64::MAX`: none; a tag is shifted right by at least 2, so never that).
    /// They change every fourth sample, so consecutive samples recompute one digit's
    /// permutation instead of all `log4 spp`.
    upper_tags: [u64; MEMO_SLOTS],
    upper_parts: [u64; MEMO_SLOTS],
    /// The slot's [`ZSobolLayout::lowest_permutation`] for the same tag: three of four
    /// consecutive samples share it, and its hash is the longest chain of a draw.
    lowest_permutations: [u8; MEMO_SLOTS],
}

impl ZSobolPixelSampler {
    /// Starts sample `index` of the pixel at dimension `dimension`. `index` must be below the
    /// layout's [`ZSobolLayout::capacity`].
    #[inline]
    pub fn start_sample(&mut self, index: u32, dimension: u32) {
        debug_assert!(
            index < self.layout.capacity(),
            "ZSobol sample index past the layout"
        );
        self.morton_index = self.pixel_index | u64::from(index);
        // An index past the layout runs into the pixel bits, as it does in
        // `start_pixel_sample`; its values are computed as there, without the memo, which holds
        // this pixel's parts.
        self.past_layout = index >= self.layout.capacity();
        self.dimension = dimension;
    }

    /// The next `N` (1 or 2) dimensions.
    #[inline]
    fn next<const N: usize>(&mut self) -> [f32; N] {
        let d = self.dimension;
        self.dimension = d.wrapping_add(N as u32);
        if self.past_layout {
            let key = self.layout.dimension_key(d);
            return draw(self.layout.sample_index(self.morton_index, key), key);
        }
        let (slot, key, pixel_part) = self.memo(d);
        let layout = &self.layout;
        let tag = layout.upper_tag(self.morton_index);
        if self.upper_tags[slot] != tag {
            self.upper_tags[slot] = tag;
            self.upper_parts[slot] = layout.upper_sample_part(self.morton_index, key);
            self.lowest_permutations[slot] =
                layout.lowest_permutation(self.morton_index, key) as u8;
        }
        let lowest = layout.lowest_sample_part_with(
            self.morton_index,
            key,
            usize::from(self.lowest_permutations[slot]),
        );
        let sample_part = self.upper_parts[slot] | lowest;
        draw(pixel_part | sample_part, key)
    }

    /// Dimension `d`'s key and the permuted digits of the pixel's part of its index, from the
    /// memo (computed and kept there on a miss).
    #[inline]
    fn memo(&mut self, d: u32) -> (usize, u64, u64) {
        let slot = d as usize % MEMO_SLOTS;
        if self.tags[slot] == d {
            return (slot, self.keys[slot], self.pixel_parts[slot]);
        }
        let key = self.layout.dimension_key(d);
        let part = self.layout.pixel_part(self.pixel_index, key);
        self.tags[slot] = d;
        self.keys[slot] = key;
        self.pixel_parts[slot] = part;
        // The upper sample digits held were another dimension's.
        self.upper_tags[slot] = u64::MAX;
        (slot, key, part)
    }

    /// The draw of `N` (1 or 2) dimensions from `dimension` on for several samples of the pixel
    /// at once: `out[k][lane]` is dimension `dimension + k` of sample `indices[lane]`, for the
    /// lanes whose bit is set in `live`, exactly what [`Self::start_sample`]`(indices[lane],
    /// dimension)` and a draw of `N` give (other lanes are left alone). The key and the pixel's
    /// digits are found once for all lanes, and the scramble runs in SIMD lanes
    /// (`scrambled_high_bits`); the sampler is left where it was. Always inlined, so that the
    /// scramble is compiled with its caller's instructions.
    #[inline(always)]
    pub fn draw_lanes<const N: usize>(
        &mut self,
        dimension: u32,
        indices: &[u32; DRAW_LANES],
        live: u32,
        lane_hashes: bool,
        out: &mut [[f32; DRAW_LANES]; N],
    ) {
        let (_, key, pixel_part) = self.memo(dimension);
        let capacity = self.layout.capacity();
        let mut lanes = live & ((1 << DRAW_LANES) - 1);
        for lane in lanes_of(lanes) {
            if indices[lane] >= capacity {
                // Past the layout, as `next` draws there.
                let morton_index = self.pixel_index | u64::from(indices[lane]);
                let key = self.layout.dimension_key(dimension);
                let v: [f32; N] = draw(self.layout.sample_index(morton_index, key), key);
                for k in 0..N {
                    out[k][lane] = v[k];
                }
                lanes &= !(1 << lane);
            }
        }
        let mortons = indices.map(|i| self.pixel_index | u64::from(i));
        let parts = self.layout.permuted_digits_lanes(
            &mortons,
            key,
            lanes,
            self.layout.sample_base4_digits(),
            lane_hashes,
        );
        let mut points = [[0u32; DRAW_LANES]; N];
        // Dimension 0's point, reversed, is the index; dimension 1's depends on the bytes of the
        // index, of which only the lowest differs between the lanes when the sample bits fit in
        // it (the pixel's bits above are the same for all).
        let shared_high = (self.layout.log2_spp <= 8).then(|| {
            let t = &SOBOL_1_BYTES_REVERSED;
            let a = pixel_part as u32;
            t[1][((a >> 8) & 0xFF) as usize]
                ^ t[2][((a >> 16) & 0xFF) as usize]
                ^ t[3][(a >> 24) as usize]
        });
        for lane in lanes_of(lanes) {
            let index = pixel_part | parts[lane];
            points[0][lane] = index as u32;
            if N == 2 {
                points[N - 1][lane] = match shared_high {
                    Some(high) => SOBOL_1_BYTES_REVERSED[0][(index & 0xFF) as usize] ^ high,
                    None => sobol_reversed(index, 1),
                };
            }
        }
        scramble_lanes(&points, key, lanes, out);
    }
}

impl ZSobolLayout {
    /// The permuted base-4 digits below digit `to` of the Morton indices `mortons[lane]`, and
    /// the odd base-2 digit at the bottom when `log2 spp` is odd, for the lanes of `lanes`
    /// (the rest are 0): [`Self::sample_part`] with `to` the sample digits'
    /// ([`Self::sample_base4_digits`]), [`Self::sample_index`] with `to` all of them. With
    /// `lane_hashes` (the caller's instructions multiply 64-bit integers in SIMD lanes:
    /// [`crate::simd::Isa::LANE_HASHES`]) in lanes, branch-free; otherwise each digit's
    /// permutation is chosen once per run of lanes that share the digits above it. The same
    /// parts either way. Always inlined, to be compiled with the caller's instructions.
    #[inline(always)]
    fn permuted_digits_lanes(
        &self,
        mortons: &[u64; DRAW_LANES],
        key: u64,
        lanes: u32,
        to: u32,
        lane_hashes: bool,
    ) -> [u64; DRAW_LANES] {
        let odd = self.log2_spp & 1;
        let mut parts = [0u64; DRAW_LANES];
        let mut i = to;
        if lane_hashes {
            // Every lane computes every digit's permutation: branch-free loops over the lanes,
            // which the compiler vectorises (AVX-512's 64-bit multiplies, the permutation a
            // selection and a shift: `permuted_digit`).
            while i > odd {
                i -= 1;
                let shift = 2 * i - odd;
                for (part, &m) in parts.iter_mut().zip(mortons) {
                    let p = permutation_of(m >> (shift + 2), key);
                    *part |= permuted_digit(p, (m >> shift) & 3) << shift;
                }
            }
            if odd == 1 {
                for (part, &m) in parts.iter_mut().zip(mortons) {
                    *part |= (m & 1) ^ (permutation_hash(m >> 1, key) >> 63);
                }
            }
            for (lane, part) in parts.iter_mut().enumerate() {
                if lanes >> lane & 1 == 0 {
                    *part = 0;
                }
            }
            return parts;
        }
        // Without 64-bit multiplies in lanes: each digit's permutation chosen once per run of
        // lanes with the same higher digits (a pixel's samples, and neighbouring pixels above
        // their lowest digits share them).
        while i > odd {
            i -= 1;
            let shift = 2 * i - odd;
            let mut last: Option<(u64, usize)> = None;
            for lane in lanes_of(lanes) {
                let m = mortons[lane];
                let higher = m >> (shift + 2);
                let p = match last {
                    Some((h, p)) if h == higher => p,
                    _ => {
                        let p = permutation_of(higher, key);
                        last = Some((higher, p));
                        p
                    }
                };
                let digit = (m >> shift) & 3;
                parts[lane] |= u64::from(PERMUTATIONS[p][digit as usize]) << shift;
            }
        }
        if odd == 1 {
            let mut last: Option<(u64, u64)> = None;
            for lane in lanes_of(lanes) {
                let m = mortons[lane];
                let flip = match last {
                    Some((h, f)) if h == m >> 1 => f,
                    _ => {
                        let f = permutation_hash(m >> 1, key) >> 63;
                        last = Some((m >> 1, f));
                        f
                    }
                };
                parts[lane] |= (m & 1) ^ flip;
            }
        }
        parts
    }

    /// Sample `index` of pixel `(x, y)` at dimension `dimension`, for any `index`: past
    /// [`Self::capacity`] it runs into the pixel bits, as [`ZSobolPixelSampler`] draws there
    /// ([`Self::start_pixel_sample`] refuses such an index in debug builds).
    #[inline]
    #[must_use]
    pub(crate) fn sampler_at(&self, x: u32, y: u32, index: u32, dimension: u32) -> ZSobolSampler {
        ZSobolSampler {
            layout: *self,
            morton_index: self.morton_index(x, y, index),
            dimension,
        }
    }

    /// The permuted digits that the Morton indices `mortons[lane]` of `lanes` share (those
    /// above the highest bit where any two differ: neighbouring pixels share their high
    /// digits), each digit's permutation chosen once; and the first digit they share, below
    /// which each lane's digits are its own. A row of a 4-spp render of 1024² pixels shares
    /// nine of its eleven digits: hashing all of them in every lane was 5% of its time.
    #[inline(always)]
    fn common_digits(&self, mortons: &[u64; DRAW_LANES], key: u64, lanes: u32) -> (u64, u32) {
        let odd = self.log2_spp & 1;
        if lanes == 0 {
            return (0, odd);
        }
        let first = mortons[lanes.trailing_zeros() as usize];
        let differ = lanes_of(lanes).fold(0, |d, lane| d | (mortons[lane] ^ first));
        // Digit `i` covers bits `2i − odd` and the one above: shared from the first digit
        // wholly above `differ`'s highest bit.
        let from = ((64 - differ.leading_zeros()) + odd)
            .div_ceil(2)
            .max(odd)
            .min(self.base4_digits);
        (
            self.permuted_digits(first, key, from, self.base4_digits),
            from,
        )
    }

    /// The draw of `N` (1 or 2) dimensions from `dimension` on for samples of any pixels:
    /// `out[k][lane]` is dimension `dimension + k` of the sample whose Morton index is
    /// `mortons[lane]` ([`Self::morton_index`]), for the lanes of `live`, exactly what
    /// [`Self::sampler_at`] and a draw of `N` give (other lanes are left alone). For a batch
    /// of a few samples of each of several neighbouring pixels (a low sample count's lanes):
    /// the key is found once, the digits all lanes share are permuted once
    /// ([`Self::common_digits`]), the rest as [`Self::permuted_digits_lanes`] does, and the
    /// scramble runs in SIMD lanes. Always inlined, so that the
    /// scramble is compiled with its caller's instructions.
    #[inline(always)]
    pub(crate) fn draw_lanes_at<const N: usize>(
        &self,
        mortons: &[u64; DRAW_LANES],
        dimension: u32,
        live: u32,
        lane_hashes: bool,
        out: &mut [[f32; DRAW_LANES]; N],
    ) {
        let key = self.dimension_key(dimension);
        let lanes = live & ((1 << DRAW_LANES) - 1);
        let (common, below) = self.common_digits(mortons, key, lanes);
        let mut index = self.permuted_digits_lanes(mortons, key, lanes, below, lane_hashes);
        for i in &mut index {
            *i |= common;
        }
        let mut points = [[0u32; DRAW_LANES]; N];
        for lane in lanes_of(lanes) {
            for (k, point) in points.iter_mut().enumerate() {
                point[lane] = sobol_reversed(index[lane], k);
            }
        }
        scramble_lanes(&points, key, lanes, out);
    }
}

/// `out[k][lane]` = the scrambled Sobol' point `points[k][lane]` of a dimension whose key is
/// `key`, as [`draw`] turns it into a number in `[0, 1)`, for the lanes of `lanes`.
#[inline(always)]
fn scramble_lanes<const N: usize>(
    points: &[[u32; DRAW_LANES]; N],
    key: u64,
    lanes: u32,
    out: &mut [[f32; DRAW_LANES]; N],
) {
    let seeds = [key as u32, (key >> 32) as u32];
    for k in 0..N {
        let high = scrambled_high_bits(points[k], seeds[k]);
        for lane in lanes_of(lanes) {
            out[k][lane] = high[lane] as f32 * (1.0 / (1u32 << 24) as f32);
        }
    }
}

/// Samples [`ZSobolPixelSampler::draw_lanes`] draws at once.
pub const DRAW_LANES: usize = 8;

/// The high 24 bits of [`owen_scramble_reversed`] of each lane, written as a loop over the
/// lanes for the compiler to vectorise with the instructions of the code it is inlined into:
/// the batched path tracer's, compiled for AVX2 where the CPU has it (`vpmulld`, eight lanes),
/// where `wide`'s `u32x8`, chosen when the kernel is compiled, emulated the 32-bit multiplies
/// of SSE2 with shuffles.
#[inline(always)]
fn scrambled_high_bits(points: [u32; DRAW_LANES], seed: u32) -> [u32; DRAW_LANES] {
    points.map(|r| owen_scramble_reversed(r, seed) >> 8)
}

sampler_from_next!(ZSobolPixelSampler);

#[cfg(test)]
mod tests {
    use super::*;
    use std::vec;
    use std::vec::Vec;

    #[test]
    fn sobol_matrices_match_pbrt() {
        // pbrt-v4's SobolMatrices32, dimension 1, first columns.
        let expected = [
            0x8000_0000u32,
            0xc000_0000,
            0xa000_0000,
            0xf000_0000,
            0x8800_0000,
            0xcc00_0000,
            0xaa00_0000,
            0xff00_0000,
            0x8080_0000,
            0xc0c0_0000,
            0xa0a0_0000,
            0xf0f0_0000,
            0x8888_0000,
        ];
        assert_eq!(&SOBOL_MATRICES[1][..expected.len()], &expected);
        assert_eq!(sobol_u32(1, 0), 0x8000_0000);
        assert_eq!(sobol_u32(2, 0), 0x4000_0000);
        assert_eq!(sobol_u32(3, 1), 0x4000_0000);
        for i in (0..100_000u64).chain([u64::from(u32::MAX), 0xDEAD_BEEF, 1 << 40]) {
            assert_eq!(sobol_u32(i, 1), sobol_1_by_columns(i), "{i}");
        }
    }

    #[test]
    fn the_packed_permutations_are_the_table() {
        for (p, perm) in PERMUTATIONS.iter().enumerate() {
            for (digit, &v) in perm.iter().enumerate() {
                assert_eq!(permuted_digit(p, digit as u64), u64::from(v), "{p} {digit}");
            }
            // Each is a permutation: the 24 are distinct and hold 0..4 once each.
            let mut seen = [false; 4];
            perm.iter().for_each(|&v| seen[usize::from(v)] = true);
            assert!(seen.iter().all(|&s| s), "{perm:?}");
        }
        for (a, pa) in PERMUTATIONS.iter().enumerate() {
            assert!(PERMUTATIONS[..a].iter().all(|pb| pb != pa), "{pa:?} twice");
        }
    }

    #[test]
    fn morton_interleaves() {
        assert_eq!(morton2(0, 0), 0);
        assert_eq!(morton2(1, 0), 1);
        assert_eq!(morton2(0, 1), 2);
        assert_eq!(morton2(3, 3), 15);
        assert_eq!(morton2(u32::MAX, 0), 0x5555_5555_5555_5555);
    }

    #[test]
    fn owen_scramble_is_a_nested_bijection() {
        // On the top 8 bits: a bijection of the 256 intervals of size 2^-8, and two points in
        // one interval of size 2^-k stay in one interval of size 2^-k.
        let seed = 0x1234_5678;
        let mut seen = [false; 256];
        for v in 0..256u32 {
            let s = owen_scramble(v << 24, seed) >> 24;
            assert!(!seen[s as usize]);
            seen[s as usize] = true;
        }
        for a in 0..256u32 {
            for b in 0..256u32 {
                let common = (a ^ b).leading_zeros() - 24; // shared top bits of 8
                let (sa, sb) = (owen_scramble(a << 24, seed), owen_scramble(b << 24, seed));
                assert!((sa ^ sb).leading_zeros() >= common, "{a} {b}");
            }
        }
    }

    /// The 24-bit values of `n` draws of pixel `(x, y)`: sample `0..spp`, each started at
    /// `dimension`, drawn with `next_2d` (or `next_1d` when `two_d` is false).
    fn points(
        layout: &ZSobolLayout,
        x: u32,
        y: u32,
        spp: u32,
        dim: u32,
        two_d: bool,
    ) -> Vec<(u32, u32)> {
        (0..spp)
            .map(|i| {
                let mut s = layout.start_pixel_sample(x, y, i, dim);
                let p = if two_d {
                    s.next_2d()
                } else {
                    Vec2::new(s.next_1d(), 0.0)
                };
                for v in [p.x, p.y] {
                    assert!((0.0..1.0).contains(&v));
                }
                ((p.x * 16_777_216.0) as u32, (p.y * 16_777_216.0) as u32)
            })
            .collect()
    }

    #[test]
    fn each_pixel_is_a_net_in_every_dimension_pair() {
        // The samples of one pixel are an aligned block of 2^m points of the (0, 2)-sequence,
        // Owen-scrambled: every elementary interval of area 2^-m, [a·2^-i, (a+1)·2^-i) ×
        // [b·2^-(m-i), (b+1)·2^-(m-i)), holds exactly one of them; in 1D every interval of
        // length 2^-m holds one.
        for m in 0..=8u32 {
            let spp = 1 << m;
            for (w, h) in [(1, 1), (37, 23), (640, 480)] {
                let layout = ZSobolLayout::new(0xC0FFEE ^ u64::from(m), spp, w, h);
                for (x, y) in [(0, 0), (w / 2, h / 3), (w - 1, h - 1)] {
                    for dim in [0, 2, 3, 7, 40, 1001] {
                        let pts = points(&layout, x, y, spp, dim, true);
                        for i in 0..=m {
                            let mut cells = vec![0u32; 1 << m];
                            for &(u, v) in &pts {
                                let (cu, cv) = (u >> (24 - i), v >> (24 - (m - i)));
                                cells[((cu << (m - i)) | cv) as usize] += 1;
                            }
                            assert!(
                                cells.iter().all(|&c| c == 1),
                                "m {m}, film {w}x{h}, pixel ({x}, {y}), dim {dim}, interval 2^-{i} x 2^-{}",
                                m - i
                            );
                        }
                        let pts = points(&layout, x, y, spp, dim, false);
                        let mut cells = vec![0u32; 1 << m];
                        for &(u, _) in &pts {
                            cells[(u >> (24 - m)) as usize] += 1;
                        }
                        assert!(cells.iter().all(|&c| c == 1), "1D, m {m}, dim {dim}");
                    }
                }
            }
        }
    }

    #[test]
    fn the_pixel_sampler_draws_what_start_pixel_sample_draws() {
        // Every sample of a pixel through one restarted ZSobolPixelSampler against a fresh
        // ZSobolSampler per sample, bit for bit: even and odd log2 spp (the odd base-2 digit),
        // 1 spp (no sample digits), films whose Morton codes reach the top digit, 1D and 2D
        // draws in a per-sample pattern, and jumps to dimensions that share a memo slot
        // (d and d + MEMO_SLOTS) or lie far beyond it, so that slots are evicted and refilled.
        let m = MEMO_SLOTS as u32;
        let jumps = [0u32, 5, m - 1, m, 2 * m - 1, 3, m * 7 + 5, 1001, 5, 2];
        for (spp, w, h) in [
            (1, 1, 1),
            (2, 3, 5),
            (4, 5, 3),
            (8, 64, 48),
            (16, 64, 64),
            (32, 320, 240),
            (256, 40, 30),
            (512, 17, 9),
        ] {
            for seed in [0u64, 0xC0FFEE] {
                let layout = ZSobolLayout::new(seed, spp, w, h);
                for (x, y) in [(0, 0), (w / 2, h / 3), (w - 1, h - 1)] {
                    let mut memo = layout.pixel_sampler(x, y);
                    for i in 0..spp {
                        let start = jumps[i as usize % jumps.len()];
                        let mut fresh = layout.start_pixel_sample(x, y, i, start);
                        memo.start_sample(i, start);
                        for k in 0..40u32 {
                            if k == 17 {
                                let d = jumps[(i + k) as usize % jumps.len()];
                                fresh.set_dimension(d);
                                memo.set_dimension(d);
                            }
                            if (k + i) % 3 == 0 {
                                let (a, b) = (fresh.next_1d(), memo.next_1d());
                                assert_eq!(
                                    a.to_bits(),
                                    b.to_bits(),
                                    "spp {spp} ({x}, {y}) i {i} k {k}"
                                );
                            } else {
                                let (a, b) = (fresh.next_2d(), memo.next_2d());
                                assert_eq!(
                                    a.to_array().map(f32::to_bits),
                                    b.to_array().map(f32::to_bits)
                                );
                            }
                            assert_eq!(fresh.dimension(), memo.dimension());
                        }
                    }
                    // The samples again, out of order and repeated (the memo of the digits
                    // above the lowest must follow the index, not the order of the calls).
                    for k in 0..2 * spp {
                        let i = (k * 7 + 3) % spp;
                        let start = jumps[k as usize % jumps.len()];
                        let mut fresh = layout.start_pixel_sample(x, y, i, start);
                        memo.start_sample(i, start);
                        for _ in 0..12 {
                            assert_eq!(
                                fresh.next_2d().to_array().map(f32::to_bits),
                                memo.next_2d().to_array().map(f32::to_bits),
                                "spp {spp} ({x}, {y}) i {i}, out of order"
                            );
                        }
                    }
                }
            }
        }
    }

    /// Sample indices past the layout (a contract violation, caught by a debug assertion) give
    /// `start_pixel_sample`'s values in release builds too, and do not spoil the memo for the
    /// valid samples after them.
    #[cfg(not(debug_assertions))]
    #[test]
    fn the_pixel_sampler_past_its_layout_draws_what_start_pixel_sample_draws() {
        let layout = ZSobolLayout::new(5, 8, 64, 48);
        let mut memo = layout.pixel_sampler(9, 4);
        for i in [0u32, 3, 8, 9, 13, 2, 700, 7, 1] {
            let mut fresh = layout.start_pixel_sample(9, 4, i, 0);
            memo.start_sample(i, 0);
            for _ in 0..30 {
                assert_eq!(fresh.next_2d(), memo.next_2d(), "index {i}");
            }
        }
    }

    #[test]
    fn a_negative_control_is_not_a_net() {
        // Independent samples are not stratified: the net test must be able to fail.
        let spp = 64u32;
        let mut s = crate::sampler::IndependentSampler::new(3, 0, 0);
        let mut cells = [0u32; 64];
        for _ in 0..spp {
            let p = s.next_2d();
            cells[((p.x * 8.0) as usize) * 8 + (p.y * 8.0) as usize] += 1;
        }
        assert!(cells.iter().any(|&c| c != 1));
    }

    #[test]
    fn values_are_a_pure_function_of_the_key() {
        let layout = ZSobolLayout::new(11, 16, 64, 48);
        let mut a = layout.start_pixel_sample(5, 7, 3, 0);
        let mut b = layout.start_pixel_sample(5, 7, 3, 0);
        for _ in 0..50 {
            assert_eq!(a.next_2d(), b.next_2d());
            assert_eq!(a.next_1d().to_bits(), b.next_1d().to_bits());
        }
        // Starting at dimension 5 is drawing 2 + 2 + 1 dimensions from 0 first.
        let mut c = layout.start_pixel_sample(5, 7, 3, 0);
        c.next_2d();
        c.next_2d();
        c.next_1d();
        assert_eq!(c.dimension(), 5);
        let mut d = layout.start_pixel_sample(5, 7, 3, 5);
        assert_eq!(c.next_2d(), d.next_2d());
        // Other seeds, pixels and indices give other values.
        let v = |seed: u64, x: u32, i: u32| {
            ZSobolLayout::new(seed, 16, 64, 48)
                .start_pixel_sample(x, 7, i, 0)
                .next_2d()
        };
        assert_ne!(v(11, 5, 3), v(12, 5, 3));
        assert_ne!(v(11, 5, 3), v(11, 6, 3));
        assert_ne!(v(11, 5, 3), v(11, 5, 4));
    }

    #[test]
    fn values_are_uniform_over_pixels_and_seeds() {
        // Mean and a 16-bin chi-square of dimensions 0, 1 and 9 over every sample of a film.
        let (w, h, spp) = (64u32, 64u32, 8u32);
        for dim in [0u32, 1, 9] {
            let mut hist = [0u32; 16];
            let mut sum = 0.0f64;
            let mut n = 0u32;
            for seed in 0..4u64 {
                let layout = ZSobolLayout::new(seed, spp, w, h);
                for y in 0..h {
                    for x in 0..w {
                        for i in 0..spp {
                            let v = layout.start_pixel_sample(x, y, i, dim).next_1d();
                            sum += f64::from(v);
                            hist[(v * 16.0) as usize] += 1;
                            n += 1;
                        }
                    }
                }
            }
            assert!((sum / f64::from(n) - 0.5).abs() < 0.002, "dim {dim}");
            let expected = f64::from(n) / 16.0;
            let chi2: f64 = hist
                .iter()
                .map(|&c| (f64::from(c) - expected).powi(2) / expected)
                .sum();
            // Stratified points are more uniform than random ones: far below the 0.001 point.
            assert!(chi2 < 37.7, "dim {dim}: chi2 {chi2}");
        }
    }

    /// Lane masks, dimensions and both ways of permuting the digits in lanes.
    fn lane_cases() -> impl Iterator<Item = (u32, u32, bool)> {
        [0xFFu32, 0xA5, 0x01, 0x80, 0x3C]
            .into_iter()
            .flat_map(|live| {
                [0u32, 1, 2, 7, 130, 1000]
                    .into_iter()
                    .flat_map(move |dim| [false, true].map(|h| (live, dim, h)))
            })
    }

    /// The lane-wise draw gives each lane what the pixel sampler started at that lane's sample
    /// and dimension draws, bit for bit: odd and even sample counts (one digit flipped or
    /// not), counts whose indices leave the lowest byte (the shared Sobol' bytes), films of a
    /// pixel and of many, lane masks with gaps, indices that are not consecutive or repeat,
    /// deep dimensions (memo evictions) and, in release builds, indices past the layout.
    #[test]
    fn lane_draws_are_the_pixel_samplers_draws() {
        let mut checked = 0usize;
        for spp in [1u32, 2, 3, 8, 16, 32, 128, 512, 1024] {
            for (w, h) in [(1u32, 1u32), (37, 23), (640, 480)] {
                let layout = ZSobolLayout::new(0xD1A5 ^ u64::from(spp), spp, w, h);
                let cap = layout.capacity();
                let past = if cfg!(debug_assertions) { 0 } else { cap + 5 };
                let index_sets: [[u32; DRAW_LANES]; 4] = [
                    core::array::from_fn(|l| l as u32 % cap),
                    core::array::from_fn(|l| (cap - 1).saturating_sub(3 * l as u32)),
                    core::array::from_fn(|l| (l as u32 * 7 + 1) % cap),
                    core::array::from_fn(|l| {
                        if l == 5 && past > 0 {
                            past
                        } else {
                            l as u32 / 3 % cap
                        }
                    }),
                ];
                for (x, y) in [(0, 0), (w / 2, h / 3), (w - 1, h - 1)] {
                    let mut lanes = layout.pixel_sampler(x, y);
                    let mut one = layout.pixel_sampler(x, y);
                    for indices in &index_sets {
                        for (live, dim, lane_hashes) in lane_cases() {
                            let mut pair = [[-1.0f32; DRAW_LANES]; 2];
                            let mut single = [[-1.0f32; DRAW_LANES]; 1];
                            lanes.draw_lanes::<2>(dim, indices, live, lane_hashes, &mut pair);
                            lanes.draw_lanes::<1>(dim, indices, live, lane_hashes, &mut single);
                            for lane in 0..DRAW_LANES {
                                if live >> lane & 1 == 0 {
                                    assert_eq!(pair[0][lane], -1.0);
                                    assert_eq!(single[0][lane], -1.0);
                                    continue;
                                }
                                one.start_sample(indices[lane], dim);
                                let want = one.next_2d();
                                one.start_sample(indices[lane], dim);
                                let want_1 = one.next_1d();
                                let what = std::format!(
                                        "spp {spp} film {w}x{h} pixel ({x}, {y}) index {} dim {dim} lane hashes {lane_hashes}",
                                        indices[lane]
                                    );
                                assert_eq!(pair[0][lane].to_bits(), want.x.to_bits(), "{what}");
                                assert_eq!(pair[1][lane].to_bits(), want.y.to_bits(), "{what}");
                                assert_eq!(single[0][lane].to_bits(), want_1.to_bits(), "{what}");
                                checked += 1;
                            }
                        }
                    }
                }
            }
        }
        assert!(checked > 10_000, "{checked}");
    }

    /// `draw_lanes_at` (samples of several pixels at once, the permuted digits the lanes share
    /// chosen once: `common_digits`) against the sampler of each lane's pixel and index, bit
    /// for bit: runs of neighbouring pixels in a row (which share all but their lowest
    /// digits, also across a Morton block's edge), pixels far apart (which share none), one
    /// sample repeated in every lane (which share all), odd and even sample counts, lane masks
    /// with gaps, both ways of permuting the digits in lanes.
    #[test]
    fn lane_draws_at_any_pixels_are_the_samplers_draws() {
        let mut checked = 0usize;
        let mut shared = [0usize; 2];
        for spp in [1u32, 2, 4, 8, 32, 128] {
            for (w, h) in [(1u32, 1u32), (37, 23), (640, 480)] {
                let layout = ZSobolLayout::new(0x5EED ^ u64::from(spp), spp, w, h);
                let pixel = |i: u32| (i % w, (i / w) % h);
                // (x, y, sample index) of each lane.
                let per_pixel = (DRAW_LANES as u32).div_ceil(spp).max(1);
                let row = |x0: u32, y: u32| -> [(u32, u32, u32); DRAW_LANES] {
                    core::array::from_fn(|l| {
                        let l = l as u32;
                        ((x0 + l / spp.min(DRAW_LANES as u32)) % w, y, l % spp)
                    })
                };
                let sets: [[(u32, u32, u32); DRAW_LANES]; 5] = [
                    row(0, 0),
                    row(31.min(w - 1), h / 2),
                    row(w.saturating_sub(per_pixel), h - 1),
                    core::array::from_fn(|l| {
                        let (x, y) = pixel(l as u32 * 7919 + 13);
                        (x, y, (l as u32 * 3) % spp)
                    }),
                    [(w / 3, h / 3, spp - 1); DRAW_LANES],
                ];
                for set in &sets {
                    let mortons = set.map(|(x, y, i)| layout.morton_index(x, y, i));
                    for (live, dim, lane_hashes) in lane_cases() {
                        let live = live & ((1 << DRAW_LANES) - 1);
                        let (_, from) =
                            layout.common_digits(&mortons, layout.dimension_key(dim), live);
                        shared[usize::from(from < layout.base4_digits)] += 1;
                        let mut pair = [[-1.0f32; DRAW_LANES]; 2];
                        let mut single = [[-1.0f32; DRAW_LANES]; 1];
                        layout.draw_lanes_at::<2>(&mortons, dim, live, lane_hashes, &mut pair);
                        layout.draw_lanes_at::<1>(&mortons, dim, live, lane_hashes, &mut single);
                        for lane in 0..DRAW_LANES {
                            if live >> lane & 1 == 0 {
                                assert_eq!(pair[0][lane], -1.0);
                                assert_eq!(single[0][lane], -1.0);
                                continue;
                            }
                            let (x, y, i) = set[lane];
                            let want = layout.sampler_at(x, y, i, dim).next_2d();
                            let want_1 = layout.sampler_at(x, y, i, dim).next_1d();
                            let what = std::format!(
                                "spp {spp} film {w}x{h} pixel ({x}, {y}) index {i} dim {dim} lane hashes {lane_hashes}"
                            );
                            assert_eq!(pair[0][lane].to_bits(), want.x.to_bits(), "{what}");
                            assert_eq!(pair[1][lane].to_bits(), want.y.to_bits(), "{what}");
                            assert_eq!(single[0][lane].to_bits(), want_1.to_bits(), "{what}");
                            checked += 1;
                        }
                    }
                }
            }
        }
        assert!(checked > 5_000, "{checked}");
        // Both kinds of batch were drawn: some sharing digits, some sharing none above the
        // lanes' own.
        assert!(shared[0] > 0 && shared[1] > 0, "{shared:?}");
    }
}
