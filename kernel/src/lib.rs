//! ember's rendering kernel: `#![no_std]`, no allocation, everything on caller-provided slices.
//!
//! The host (see `host-cli`) loads scenes, allocates buffers and threads the work; the kernel
//! only reads and writes the slices it is handed. Modules, one concept each:
//! - [`math`]: shading frames, warps paired with their pdfs, float error bounds, colour helpers.
//! - [`sampler`]: the deterministic sampler keyed by (seed, pixel, sample index, dimension).
//! - [`geometry`]: rays, watertight triangle intersection, robust ray origins.
//! - [`bvh`]: binned-SAH BVH built into caller slices, fixed-stack traversal.
//! - [`simd`]: the SIMD lanes of the ray queries and of the batched shading, and their run-time
//!   choice of AVX2 on x86-64; `vec_lanes`: eight 3-vectors in lanes ([`Soa3`] stores them by
//!   axis), with glam's operations as glam computes them.
//! - [`camera`]: the TinyRender pinhole camera.
//! - [`bsdf`]: the closed set of BSDFs (enum dispatch, local shading frame) and the
//!   [`bsdf::SurfaceBsdf`] wrapper integrators use them through.
//! - [`material`]: materials, turned into BSDFs at surface points; [`texture`]: image textures.
//! - [`emitter`]: area emitters and the table they are sampled from.
//! - [`scene`]: [`scene::SceneView`], the borrowed scene every integrator works on; its surface
//!   interactions of eight hits at once in SIMD lanes are in `surface_lanes`.
//! - [`splat`]: order-independent (fixed-point) accumulation of light-tracing splats.
//! - [`integrator`]: the path tracers (one loop, three strategies) and the GI bake.
//! - `capi` (feature `capi`): the C API over caller-owned arrays (`kernel/include/ember.h`).
#![no_std]
// No `unsafe` anywhere, except in three audited modules, every block with its SAFETY argument:
// the C API when it is compiled in (raw pointers from C turned into slices), `prefetch`
// (cache hints for the BVH walk, measured there) and `simd`'s `avx` (CPU detection and AVX
// intrinsics behind a token that only detection makes, measured there).
#![deny(unsafe_code)]

#[cfg(test)]
extern crate std;

pub mod bsdf;
pub mod bvh;
pub mod camera;
#[cfg(feature = "capi")]
#[allow(unsafe_code)]
pub mod capi;
pub mod emitter;
pub mod geometry;
pub mod integrator;
pub mod material;
pub mod math;
#[allow(unsafe_code)]
mod prefetch;
pub mod sampler;
pub mod scene;
pub mod simd;
pub mod splat;
mod surface_lanes;
pub use surface_lanes::SurfaceLanes;
pub mod texture;
mod vec_lanes;
pub use vec_lanes::Soa3;

pub use glam;
pub use glam::{Vec2, Vec3};

/// Linear RGB radiance or reflectance.
pub type Rgb = Vec3;
