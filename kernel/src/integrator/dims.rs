//! The layout of a path sample's dimensions: which uniform number is used for what.
//!
//! A camera sample starts with [`CAMERA`] dimensions (the offset within the pixel); then every
//! scattering vertex of the path owns [`PER_BOUNCE`] dimensions at the offsets below, so that
//! dimension `CAMERA + k·PER_BOUNCE + o` always has the same meaning. BDPT's camera subpath
//! draws all of them ([`Bounce::draw`]); the path tracers draw only those they use
//! ([`BounceDims`]), which gives the same numbers since each is a function of its dimension. A
//! bake sample starts with [`BAKE_VIEW`] dimensions instead (the view direction), then the same
//! per-bounce layout. A light path starts with [`LIGHT_START`] dimensions and draws
//! [`PER_LIGHT_BOUNCE`] per vertex: at dimension 0 in light tracing, at [`BDPT_LIGHT_SUBPATH`]
//! in BDPT, past every dimension the longest camera subpath can draw, so that a light vertex's
//! numbers keep their dimensions whatever the length of the camera subpath (a quasi-random
//! sampler stratifies a dimension pair over a pixel's samples only when they all use it for the
//! same thing). In BDPT the camera subpath's per-bounce emitter numbers are those of its
//! `s = 1` connection (next-event estimation) at that vertex.

use crate::sampler::Sampler;
use glam::Vec2;

/// Dimensions of the camera sample: the 2D offset within the pixel.
pub const CAMERA: u32 = 2;
/// Dimensions of a bake sample before its first bounce: the 2D view direction.
pub const BAKE_VIEW: u32 = 2;

/// Offset of the 1D number that selects an emitter for next-event estimation.
pub const LIGHT_SELECT: u32 = 0;
/// Offset of the 2D point on the selected emitter.
pub const LIGHT_POSITION: u32 = 1;
/// Offset of the 1D number that chooses the BSDF lobe (`uc` of [`crate::bsdf::Bsdf::sample`]).
pub const BSDF_LOBE: u32 = 3;
/// Offset of the 2D number that chooses the direction within the lobe.
pub const BSDF_DIRECTION: u32 = 4;
/// Offset of the 1D number of Russian roulette.
pub const ROULETTE: u32 = 6;
/// Dimensions drawn per scattering vertex.
pub const PER_BOUNCE: u32 = 7;

/// The numbers of one scattering vertex, drawn in the layout's order.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bounce {
    pub light_select: f32,
    pub light: Vec2,
    pub lobe: f32,
    pub direction: Vec2,
    pub roulette: f32,
}

impl Bounce {
    /// Draws the [`PER_BOUNCE`] numbers of the next vertex.
    #[inline]
    pub fn draw<S: Sampler>(sampler: &mut S) -> Self {
        let light_select = sampler.next_1d();
        let light = sampler.next_2d();
        let lobe = sampler.next_1d();
        let direction = sampler.next_2d();
        let roulette = sampler.next_1d();
        Self {
            light_select,
            light,
            lobe,
            direction,
            roulette,
        }
    }
}

/// The numbers of one scattering vertex drawn one by one where they are used, each from its
/// slot of the layout: a number that is not needed (the emitter numbers without next-event
/// estimation, the lobe choice of a single-lobe BSDF, the roulette number before roulette
/// starts) is not drawn. That changes no other number, since each is a pure function of its
/// dimension, so a path gets the numbers [`Bounce::draw`] would give it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BounceDims {
    base: u32,
}

impl BounceDims {
    /// The vertex whose numbers start at the sampler's current dimension.
    #[inline]
    pub fn start<S: Sampler>(sampler: &S) -> Self {
        Self {
            base: sampler.dimension(),
        }
    }

    #[inline]
    fn at<S: Sampler>(&self, sampler: &mut S, offset: u32) {
        sampler.set_dimension(self.base.wrapping_add(offset));
    }

    /// The emitter choice and the point on it ([`LIGHT_SELECT`], [`LIGHT_POSITION`]).
    #[inline]
    pub fn light<S: Sampler>(&self, sampler: &mut S) -> (f32, Vec2) {
        self.at(sampler, LIGHT_SELECT);
        let select = sampler.next_1d();
        (select, sampler.next_2d())
    }

    /// The lobe choice ([`BSDF_LOBE`]).
    #[inline]
    pub fn lobe<S: Sampler>(&self, sampler: &mut S) -> f32 {
        self.at(sampler, BSDF_LOBE);
        sampler.next_1d()
    }

    /// The direction within the lobe ([`BSDF_DIRECTION`]).
    #[inline]
    pub fn direction<S: Sampler>(&self, sampler: &mut S) -> Vec2 {
        self.at(sampler, BSDF_DIRECTION);
        sampler.next_2d()
    }

    /// The roulette number ([`ROULETTE`]).
    #[inline]
    pub fn roulette<S: Sampler>(&self, sampler: &mut S) -> f32 {
        self.at(sampler, ROULETTE);
        sampler.next_1d()
    }

    /// Moves the sampler to the next vertex's first dimension.
    #[inline]
    pub fn finish<S: Sampler>(&self, sampler: &mut S) {
        self.at(sampler, PER_BOUNCE);
    }
}

/// Draws the camera sample's [`CAMERA`] numbers.
#[inline]
pub fn camera<S: Sampler>(sampler: &mut S) -> Vec2 {
    sampler.next_2d()
}

// The offsets are the order `Bounce::draw` draws in.
const _: () = assert!(
    LIGHT_SELECT + 1 == LIGHT_POSITION
        && LIGHT_POSITION + 2 == BSDF_LOBE
        && BSDF_LOBE + 1 == BSDF_DIRECTION
        && BSDF_DIRECTION + 2 == ROULETTE
        && ROULETTE + 1 == PER_BOUNCE
);

/// Draws a bake sample's [`BAKE_VIEW`] numbers.
#[inline]
pub fn bake_view<S: Sampler>(sampler: &mut S) -> Vec2 {
    sampler.next_2d()
}

/// Dimensions that start a light path (light tracing, BDPT's light subpath): the emitter
/// choice (1), the point on it (2) and the direction of emission (2).
pub const LIGHT_START: u32 = 5;
/// Dimensions per scattering vertex of a light path: the lobe (1), the direction (2) and
/// Russian roulette (1). A light path has no next-event estimation.
pub const PER_LIGHT_BOUNCE: u32 = 4;

/// The numbers that start a light path, drawn in the layout's order.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightStart {
    pub select: f32,
    pub position: Vec2,
    pub direction: Vec2,
}

impl LightStart {
    #[inline]
    pub fn draw<S: Sampler>(sampler: &mut S) -> Self {
        let select = sampler.next_1d();
        let position = sampler.next_2d();
        let direction = sampler.next_2d();
        Self {
            select,
            position,
            direction,
        }
    }
}

/// The numbers of one scattering vertex of a light path.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightBounce {
    pub lobe: f32,
    pub direction: Vec2,
    pub roulette: f32,
}

impl LightBounce {
    #[inline]
    pub fn draw<S: Sampler>(sampler: &mut S) -> Self {
        let lobe = sampler.next_1d();
        let direction = sampler.next_2d();
        let roulette = sampler.next_1d();
        Self {
            lobe,
            direction,
            roulette,
        }
    }
}

/// The first dimension of BDPT's light subpath: past the [`CAMERA`] numbers and the
/// [`PER_BOUNCE`] numbers of every scattering vertex a camera subpath can hold.
pub const BDPT_LIGHT_SUBPATH: u32 =
    CAMERA + (crate::integrator::bdpt::CAMERA_PATH_VERTICES as u32 - 1) * PER_BOUNCE;
