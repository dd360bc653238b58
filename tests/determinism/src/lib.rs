//! The scene of ember's determinism checks: a small Cornell box built in arrays (no files),
//! rendered at 32×32 with every material of the kernel (diffuse walls, a Phong box, a mixture
//! box, a smooth mirror, a rough metal panel, a glass box with one frosted face, a floor with a
//! diffuse texture and a picture with a textured Phong material) by each path integrator,
//! by the light tracer and by BDPT with both MIS heuristics (their splats accumulated in
//! fixed-size fixed-point buffers, [`SplatBuffer`]), plus a bake of surface points on each of
//! them with both bake estimators. Each integrator renders with its default sampler
//! ([`Integrator::default_sampler`]: Owen-scrambled Sobol' points for explicit and MIS path
//! tracing and BDPT, independent numbers for implicit path tracing and the light tracer),
//! as `ember render` and the C API do. The pixels and baked values are hashed bit for bit
//! (FNV-1a over the little-endian bytes of each f32).
//!
//! `#![no_std]` and allocation-free: the same code runs on the host (any thread count), on
//! aarch64 under qemu, as a wasm32 module under Node.js and in the `no_std` check. The C API
//! test (`tests/capi/cornell.c`) builds the same box in C from the same literal quads,
//! materials, texels and texture coordinates.
#![no_std]

use ember_kernel::bvh::{self, BvhNode, WideBvh, WideNode};
use ember_kernel::camera::Camera;
use ember_kernel::emitter::{build_emitter_table, EmitterPolicy};
use ember_kernel::geometry::{TriangleGroup, GROUP_WIDTH};
use ember_kernel::integrator::{
    bake_vertex, render_pixel, render_row, BakeEstimator, BakePoint, BakeSamples, BdptScratch,
    Integrator, MisHeuristic, PathSettings, PixelStats, Shortcuts,
};
use ember_kernel::material::{PhongParams, Reflectance, Surface};
use ember_kernel::sampler::{SamplerKind, Sampling, DEFAULT_SEED};
use ember_kernel::scene::{Material, SceneView};
pub use ember_kernel::splat::SplatBuffer;
use ember_kernel::texture::{Texture, Textures, NO_TEXTURE};
use ember_kernel::{Rgb, Vec2, Vec3};

/// Film size of the determinism render.
pub const WIDTH: u32 = 32;
pub const HEIGHT: u32 = 32;
/// Samples per pixel of each integrator's render.
pub const SPP: u32 = 4;
/// Samples per baked point.
pub const BAKE_SAMPLES: u32 = 16;
/// The seed of every render and bake (the command line's default).
pub const SEED: u64 = DEFAULT_SEED;
/// Render settings: unbounded depth, so Russian roulette is exercised too.
pub const RENDER_PATH: PathSettings = PathSettings {
    max_depth: -1,
    rr_depth: 3,
    rr_prob: 0.9,
    shortcuts: Shortcuts::NONE,
};
/// Bake settings: TinyRender's `gi` defaults, with the shortcut the scene allows (checked by
/// `tests/tests/golden.rs`), so every target also checks that it leaves the bake unchanged.
pub const BAKE_PATH: PathSettings = PathSettings {
    max_depth: 5,
    rr_depth: 5,
    rr_prob: 0.95,
    shortcuts: Shortcuts {
        terminal_emitter_test: true,
    },
};
/// The integrators rendered, in hashing order.
pub const INTEGRATORS: [Integrator; 3] = [
    Integrator::PathImplicit,
    Integrator::PathExplicit,
    Integrator::PathMis,
];
/// The splatting integrators rendered (same film, samples and settings as the path tracers),
/// in hashing order.
pub const SPLAT_INTEGRATORS: [Integrator; 3] = [
    Integrator::LightTracing,
    Integrator::Bdpt(MisHeuristic::Power),
    Integrator::Bdpt(MisHeuristic::Balance),
];
/// Pixels of the film: the entries of a splat buffer.
pub const PIXELS: usize = WIDTH as usize * HEIGHT as usize;
/// The bake estimators, in hashing order.
pub const BAKE_ESTIMATORS: [BakeEstimator; 2] = [BakeEstimator::Mis, BakeEstimator::Explicit];

/// Material kinds, numbered as the C API's `EMBER_MATERIAL_*`.
pub const DIFFUSE: u32 = 0;
pub const PHONG: u32 = 1;
pub const MIXTURE: u32 = 2;
pub const CONDUCTOR: u32 = 3;
pub const DIELECTRIC: u32 = 4;

/// A material as the C API's `EmberMaterial` describes it (without its `struct_size`): `kind`
/// says which fields are read; texture ids are [`NO_TEXTURE`] for constants.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MaterialDesc {
    pub kind: u32,
    pub kd: [f32; 3],
    pub kd_texture: u32,
    pub ks: [f32; 3],
    pub ks_texture: u32,
    pub ns: f32,
    pub ke: [f32; 3],
    pub ior: f32,
    pub tf: [f32; 3],
    pub alpha: f32,
}

impl MaterialDesc {
    /// The kernel material (what the C API converts it to); a textured Phong material's clamp
    /// and weight come from the texels in `textures`.
    ///
    /// # Panics
    /// If a texture id is not in `textures`.
    #[must_use]
    pub fn material(&self, textures: &Textures<'_>) -> Material {
        let reflectance = |value: [f32; 3], texture: u32| {
            if texture == NO_TEXTURE {
                Reflectance::constant(Rgb::from_array(value))
            } else {
                Reflectance::texture(texture)
            }
        };
        let (kd, ks) = (
            reflectance(self.kd, self.kd_texture),
            reflectance(self.ks, self.ks_texture),
        );
        let phong = || PhongParams::new(kd, ks, self.ns, textures).expect("texture ids");
        let surface = match self.kind {
            DIFFUSE => Surface::Diffuse { kd },
            PHONG => Surface::Phong(phong()),
            MIXTURE => Surface::Mixture(phong()),
            CONDUCTOR => Surface::Conductor {
                ks,
                alpha: self.alpha,
            },
            _ => Surface::Dielectric {
                eta: self.ior,
                tf: Rgb::from_array(self.tf),
                alpha: self.alpha,
            },
        };
        Material::new(surface).with_emission(Rgb::from_array(self.ke))
    }
}

/// A material of `kind` with constant `kd` and `ks`, exponent `ns` and emission `ke`.
const fn basic(kind: u32, kd: [f32; 3], ks: [f32; 3], ns: f32, ke: [f32; 3]) -> MaterialDesc {
    MaterialDesc {
        kind,
        kd,
        kd_texture: NO_TEXTURE,
        ks,
        ks_texture: NO_TEXTURE,
        ns,
        ke,
        ior: 1.0,
        tf: [1.0; 3],
        alpha: 0.0,
    }
}

const fn diffuse(kd: [f32; 3]) -> MaterialDesc {
    basic(DIFFUSE, kd, [0.0; 3], 1.0, [0.0; 3])
}

const fn conductor(ks: [f32; 3], alpha: f32) -> MaterialDesc {
    MaterialDesc {
        alpha,
        ..basic(CONDUCTOR, [0.0; 3], ks, 1.0, [0.0; 3])
    }
}

const fn dielectric(ior: f32, tf: [f32; 3], alpha: f32) -> MaterialDesc {
    MaterialDesc {
        ior,
        tf,
        alpha,
        ..basic(DIELECTRIC, [0.0; 3], [0.0; 3], 1.0, [0.0; 3])
    }
}

/// White, red and green walls, the light, a Phong box, a mixture box, the textured floor
/// (texture 0), a smooth mirror, a rough metal (alpha 0.2), smooth glass (IOR 1.5, slightly
/// tinted), frosted glass (IOR 1.5, alpha 0.15) and a Phong picture whose `Kd` and `Ks` are
/// textures 1 and 2 (their maxima add up to more than 1, so its energy clamp applies).
pub const MATERIALS: [MaterialDesc; 12] = [
    diffuse([0.725, 0.71, 0.68]),
    diffuse([0.63, 0.065, 0.05]),
    diffuse([0.14, 0.45, 0.091]),
    basic(DIFFUSE, [0.0; 3], [0.0; 3], 1.0, [17.0, 12.0, 4.0]),
    basic(PHONG, [0.1, 0.1, 0.1], [0.7, 0.7, 0.7], 40.0, [0.0; 3]),
    basic(MIXTURE, [0.5, 0.4, 0.3], [0.3, 0.3, 0.3], 15.0, [0.0; 3]),
    MaterialDesc {
        kd_texture: 0,
        ..diffuse([0.0; 3])
    },
    conductor([0.95, 0.93, 0.88], 0.0),
    conductor([0.9, 0.6, 0.35], 0.2),
    dielectric(1.5, [0.95, 0.97, 1.0], 0.0),
    dielectric(1.5, [1.0, 1.0, 1.0], 0.15),
    MaterialDesc {
        kd_texture: 1,
        ks_texture: 2,
        ..basic(PHONG, [0.0; 3], [0.0; 3], 30.0, [0.0; 3])
    },
];

/// The texels of the three textures, each bottom row first: 0 is a 4×4 checker of light and
/// dark with one reddish corner texel (top right), 1 a 4×4 colour ramp, 2 a 2×2 specular map.
pub const TEXELS: [[f32; 3]; 36] = [
    // Texture 0: 4×4.
    [0.8, 0.78, 0.74],
    [0.25, 0.25, 0.3],
    [0.8, 0.78, 0.74],
    [0.25, 0.25, 0.3],
    [0.25, 0.25, 0.3],
    [0.8, 0.78, 0.74],
    [0.25, 0.25, 0.3],
    [0.8, 0.78, 0.74],
    [0.8, 0.78, 0.74],
    [0.25, 0.25, 0.3],
    [0.8, 0.78, 0.74],
    [0.25, 0.25, 0.3],
    [0.25, 0.25, 0.3],
    [0.8, 0.78, 0.74],
    [0.25, 0.25, 0.3],
    [0.7, 0.2, 0.15],
    // Texture 1: 4×4.
    [0.1, 0.1, 0.5],
    [0.2, 0.1, 0.45],
    [0.3, 0.15, 0.4],
    [0.4, 0.2, 0.35],
    [0.1, 0.3, 0.4],
    [0.2, 0.35, 0.35],
    [0.35, 0.35, 0.3],
    [0.5, 0.4, 0.25],
    [0.1, 0.5, 0.3],
    [0.25, 0.55, 0.25],
    [0.45, 0.55, 0.2],
    [0.65, 0.55, 0.15],
    [0.1, 0.7, 0.2],
    [0.3, 0.7, 0.15],
    [0.55, 0.7, 0.1],
    [0.8, 0.7, 0.05],
    // Texture 2: 2×2.
    [0.6, 0.6, 0.6],
    [0.2, 0.2, 0.2],
    [0.4, 0.3, 0.2],
    [0.05, 0.05, 0.05],
];

/// The textures: the floor's checker repeated twice each way and shifted by an eighth, the
/// picture's two maps as they are.
pub const TEXTURES: [Texture; 3] = [
    Texture {
        width: 4,
        height: 4,
        first_texel: 0,
        uv_scale: Vec2::new(2.0, 2.0),
        uv_offset: Vec2::new(0.125, 0.0),
    },
    Texture {
        width: 4,
        height: 4,
        first_texel: 16,
        uv_scale: Vec2::ONE,
        uv_offset: Vec2::ZERO,
    },
    Texture {
        width: 2,
        height: 2,
        first_texel: 32,
        uv_scale: Vec2::ONE,
        uv_offset: Vec2::ZERO,
    },
];

/// The texture coordinates of every quad's four corners, in corner order.
pub const QUAD_UVS: [[f32; 2]; 4] = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];

/// A flat quad: corners counter-clockwise seen from the side its normal points to.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Quad {
    pub corners: [[f32; 3]; 4],
    pub normal: [f32; 3],
    pub material: u32,
}

/// The room (x in [-1, 1], y in [0, 2], z in [-1, 1], open toward +z) with a textured floor,
/// the light just below the ceiling, a short mixture box and a tall Phong box (five faces
/// each), a mirror on the left wall, a rough metal panel on the right wall, a textured Phong
/// picture on the back wall, and a glass box (five faces, standing on the floor) whose front
/// face is frosted.
pub const QUADS: [Quad; 24] = [
    Quad {
        corners: [
            [-1.0, 0.0, 1.0],
            [1.0, 0.0, 1.0],
            [1.0, 0.0, -1.0],
            [-1.0, 0.0, -1.0],
        ],
        normal: [0.0, 1.0, 0.0],
        material: 6,
    },
    Quad {
        corners: [
            [-1.0, 2.0, -1.0],
            [1.0, 2.0, -1.0],
            [1.0, 2.0, 1.0],
            [-1.0, 2.0, 1.0],
        ],
        normal: [0.0, -1.0, 0.0],
        material: 0,
    },
    Quad {
        corners: [
            [-1.0, 0.0, -1.0],
            [1.0, 0.0, -1.0],
            [1.0, 2.0, -1.0],
            [-1.0, 2.0, -1.0],
        ],
        normal: [0.0, 0.0, 1.0],
        material: 0,
    },
    Quad {
        corners: [
            [-1.0, 0.0, 1.0],
            [-1.0, 0.0, -1.0],
            [-1.0, 2.0, -1.0],
            [-1.0, 2.0, 1.0],
        ],
        normal: [1.0, 0.0, 0.0],
        material: 1,
    },
    Quad {
        corners: [
            [1.0, 0.0, -1.0],
            [1.0, 0.0, 1.0],
            [1.0, 2.0, 1.0],
            [1.0, 2.0, -1.0],
        ],
        normal: [-1.0, 0.0, 0.0],
        material: 2,
    },
    Quad {
        corners: [
            [-0.25, 1.98, -0.25],
            [0.25, 1.98, -0.25],
            [0.25, 1.98, 0.25],
            [-0.25, 1.98, 0.25],
        ],
        normal: [0.0, -1.0, 0.0],
        material: 3,
    },
    Quad {
        corners: [
            [-0.75, 0.6, 0.4],
            [-0.15, 0.6, 0.4],
            [-0.15, 0.6, -0.2],
            [-0.75, 0.6, -0.2],
        ],
        normal: [0.0, 1.0, 0.0],
        material: 5,
    },
    Quad {
        corners: [
            [-0.75, 0.0, 0.4],
            [-0.15, 0.0, 0.4],
            [-0.15, 0.6, 0.4],
            [-0.75, 0.6, 0.4],
        ],
        normal: [0.0, 0.0, 1.0],
        material: 5,
    },
    Quad {
        corners: [
            [-0.15, 0.0, -0.2],
            [-0.75, 0.0, -0.2],
            [-0.75, 0.6, -0.2],
            [-0.15, 0.6, -0.2],
        ],
        normal: [0.0, 0.0, -1.0],
        material: 5,
    },
    Quad {
        corners: [
            [-0.75, 0.0, -0.2],
            [-0.75, 0.0, 0.4],
            [-0.75, 0.6, 0.4],
            [-0.75, 0.6, -0.2],
        ],
        normal: [-1.0, 0.0, 0.0],
        material: 5,
    },
    Quad {
        corners: [
            [-0.15, 0.0, 0.4],
            [-0.15, 0.0, -0.2],
            [-0.15, 0.6, -0.2],
            [-0.15, 0.6, 0.4],
        ],
        normal: [1.0, 0.0, 0.0],
        material: 5,
    },
    Quad {
        corners: [
            [0.1, 1.2, -0.1],
            [0.7, 1.2, -0.1],
            [0.7, 1.2, -0.7],
            [0.1, 1.2, -0.7],
        ],
        normal: [0.0, 1.0, 0.0],
        material: 4,
    },
    Quad {
        corners: [
            [0.1, 0.0, -0.1],
            [0.7, 0.0, -0.1],
            [0.7, 1.2, -0.1],
            [0.1, 1.2, -0.1],
        ],
        normal: [0.0, 0.0, 1.0],
        material: 4,
    },
    Quad {
        corners: [
            [0.7, 0.0, -0.7],
            [0.1, 0.0, -0.7],
            [0.1, 1.2, -0.7],
            [0.7, 1.2, -0.7],
        ],
        normal: [0.0, 0.0, -1.0],
        material: 4,
    },
    Quad {
        corners: [
            [0.1, 0.0, -0.7],
            [0.1, 0.0, -0.1],
            [0.1, 1.2, -0.1],
            [0.1, 1.2, -0.7],
        ],
        normal: [-1.0, 0.0, 0.0],
        material: 4,
    },
    Quad {
        corners: [
            [0.7, 0.0, -0.1],
            [0.7, 0.0, -0.7],
            [0.7, 1.2, -0.7],
            [0.7, 1.2, -0.1],
        ],
        normal: [1.0, 0.0, 0.0],
        material: 4,
    },
    Quad {
        corners: [
            [-0.99, 0.7, 0.2],
            [-0.99, 0.7, -0.8],
            [-0.99, 1.7, -0.8],
            [-0.99, 1.7, 0.2],
        ],
        normal: [1.0, 0.0, 0.0],
        material: 7,
    },
    Quad {
        corners: [
            [0.99, 0.7, -0.3],
            [0.99, 0.7, 0.7],
            [0.99, 1.5, 0.7],
            [0.99, 1.5, -0.3],
        ],
        normal: [-1.0, 0.0, 0.0],
        material: 8,
    },
    Quad {
        corners: [
            [0.1, 1.3, -0.99],
            [0.9, 1.3, -0.99],
            [0.9, 1.9, -0.99],
            [0.1, 1.9, -0.99],
        ],
        normal: [0.0, 0.0, 1.0],
        material: 11,
    },
    Quad {
        corners: [
            [-0.05, 0.45, 0.65],
            [0.4, 0.45, 0.65],
            [0.4, 0.45, 0.25],
            [-0.05, 0.45, 0.25],
        ],
        normal: [0.0, 1.0, 0.0],
        material: 9,
    },
    Quad {
        corners: [
            [-0.05, 0.0, 0.65],
            [0.4, 0.0, 0.65],
            [0.4, 0.45, 0.65],
            [-0.05, 0.45, 0.65],
        ],
        normal: [0.0, 0.0, 1.0],
        material: 10,
    },
    Quad {
        corners: [
            [0.4, 0.0, 0.25],
            [-0.05, 0.0, 0.25],
            [-0.05, 0.45, 0.25],
            [0.4, 0.45, 0.25],
        ],
        normal: [0.0, 0.0, -1.0],
        material: 9,
    },
    Quad {
        corners: [
            [-0.05, 0.0, 0.25],
            [-0.05, 0.0, 0.65],
            [-0.05, 0.45, 0.65],
            [-0.05, 0.45, 0.25],
        ],
        normal: [-1.0, 0.0, 0.0],
        material: 9,
    },
    Quad {
        corners: [
            [0.4, 0.0, 0.65],
            [0.4, 0.0, 0.25],
            [0.4, 0.45, 0.25],
            [0.4, 0.45, 0.65],
        ],
        normal: [1.0, 0.0, 0.0],
        material: 9,
    },
];

pub const VERTICES: usize = 4 * QUADS.len();
pub const TRIANGLES: usize = 2 * QUADS.len();
pub const BVH_NODES: usize = bvh::max_nodes(TRIANGLES);
pub const WIDE_NODES: usize = bvh::max_wide_nodes(BVH_NODES);
/// Room for the wide tree's aligned order: every leaf holds at least one triangle and is
/// padded to at most a group of four per triangle.
pub const WIDE_ORDER: usize = GROUP_WIDTH * TRIANGLES;

/// A surface point to bake: position, normal, material and texture coordinates. Key `i` for
/// point `i`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BakeDesc {
    pub p: [f32; 3],
    pub n: [f32; 3],
    pub uv: [f32; 2],
    pub material: u32,
}

const fn bake(p: [f32; 3], n: [f32; 3], uv: [f32; 2], material: u32) -> BakeDesc {
    BakeDesc { p, n, uv, material }
}

/// Surface points baked: on the walls, the boxes and the ceiling, on the textured floor (at
/// its texture coordinates), the mirror, the metal panel, both glass surfaces and the picture.
pub const BAKE_POINTS: [BakeDesc; 14] = [
    bake([0.0, 0.0, 0.7], [0.0, 1.0, 0.0], [0.5, 0.15], 6),
    bake([0.0, 1.0, -1.0], [0.0, 0.0, 1.0], [0.0, 0.0], 0),
    bake([-1.0, 0.4, 0.6], [1.0, 0.0, 0.0], [0.0, 0.0], 1),
    bake([1.0, 1.8, -0.6], [-1.0, 0.0, 0.0], [0.0, 0.0], 2),
    bake([0.6, 2.0, 0.6], [0.0, -1.0, 0.0], [0.0, 0.0], 0),
    bake([0.4, 1.2, -0.4], [0.0, 1.0, 0.0], [0.0, 0.0], 4),
    bake([-0.45, 0.6, 0.1], [0.0, 1.0, 0.0], [0.0, 0.0], 5),
    bake([-1.0, 0.0, -1.0], [0.0, 1.0, 0.0], [0.0, 1.0], 6),
    bake([-0.99, 1.2, -0.3], [1.0, 0.0, 0.0], [0.5, 0.5], 7),
    bake([0.99, 1.1, 0.2], [-1.0, 0.0, 0.0], [0.5, 0.5], 8),
    bake([0.175, 0.45, 0.45], [0.0, 1.0, 0.0], [0.5, 0.5], 9),
    bake([0.175, 0.2, 0.65], [0.0, 0.0, 1.0], [0.5, 0.5], 10),
    bake([0.5, 1.6, -0.99], [0.0, 0.0, 1.0], [0.5, 0.5], 11),
    bake([0.6, 0.0, 0.4], [0.0, 1.0, 0.0], [0.8, 0.3], 6),
];

/// The camera: in front of the open side, looking at the middle of the room.
#[must_use]
pub fn camera() -> Camera {
    Camera::look_at(
        Vec3::new(0.0, 1.0, 3.4),
        Vec3::new(0.0, 1.0, 0.0),
        Vec3::Y,
        40.0,
        WIDTH,
        HEIGHT,
    )
}

/// The scene's arrays, built without allocation: four vertices and two triangles per quad,
/// the emitter table by area and the BVH from the kernel's builders.
#[derive(Clone, Debug)]
pub struct Scene {
    pub positions: [Vec3; VERTICES],
    pub normals: [Vec3; VERTICES],
    pub uvs: [Vec2; VERTICES],
    pub texels: [Rgb; TEXELS.len()],
    pub triangles: [[u32; 3]; TRIANGLES],
    pub triangle_materials: [u32; TRIANGLES],
    pub materials: [Material; MATERIALS.len()],
    pub emitter_triangles: [u32; TRIANGLES],
    pub emitter_cdf: [f32; TRIANGLES],
    pub emitter_count: usize,
    /// The wide BVH the command line traces with (the C API traces the binary one; both
    /// must give the golden hashes).
    pub bvh_nodes: [WideNode; WIDE_NODES],
    pub bvh_node_count: usize,
    /// The binary build's primitive order (the C API's).
    pub bvh_prim_order: [u32; TRIANGLES],
    /// The wide tree's order with leaves aligned to groups, and its triangle groups, as
    /// the command line traces them.
    pub bvh_wide_order: [u32; WIDE_ORDER],
    pub bvh_wide_order_len: usize,
    pub bvh_leaf_groups: [TriangleGroup; TRIANGLES],
}

impl Default for Scene {
    fn default() -> Self {
        Self::new()
    }
}

impl Scene {
    /// Builds the arrays.
    ///
    /// # Panics
    /// Never for this scene (the kernel's builders accept it).
    #[must_use]
    pub fn new() -> Self {
        let mut s = Self {
            positions: [Vec3::ZERO; VERTICES],
            normals: [Vec3::ZERO; VERTICES],
            uvs: [Vec2::ZERO; VERTICES],
            texels: TEXELS.map(Rgb::from_array),
            triangles: [[0; 3]; TRIANGLES],
            triangle_materials: [0; TRIANGLES],
            materials: [Material::BLACK; MATERIALS.len()],
            emitter_triangles: [0; TRIANGLES],
            emitter_cdf: [0.0; TRIANGLES],
            emitter_count: 0,
            bvh_nodes: [WideNode::default(); WIDE_NODES],
            bvh_node_count: 0,
            bvh_prim_order: [0; TRIANGLES],
            bvh_wide_order: [0; WIDE_ORDER],
            bvh_wide_order_len: 0,
            bvh_leaf_groups: [TriangleGroup::default(); TRIANGLES],
        };
        for (q, quad) in QUADS.iter().enumerate() {
            for (c, corner) in quad.corners.iter().enumerate() {
                s.positions[4 * q + c] = Vec3::from_array(*corner);
                s.normals[4 * q + c] = Vec3::from_array(quad.normal);
                s.uvs[4 * q + c] = Vec2::from_array(QUAD_UVS[c]);
            }
            let v = 4 * q as u32;
            s.triangles[2 * q] = [v, v + 1, v + 2];
            s.triangles[2 * q + 1] = [v, v + 2, v + 3];
            s.triangle_materials[2 * q] = quad.material;
            s.triangle_materials[2 * q + 1] = quad.material;
        }
        let textures = Textures {
            uvs: &s.uvs,
            textures: &TEXTURES,
            texels: &s.texels,
        };
        s.materials = MATERIALS.map(|m| m.material(&textures));
        s.emitter_count = build_emitter_table(
            &s.positions,
            &s.triangles,
            &s.triangle_materials,
            |m| Rgb::from_array(MATERIALS[m as usize].ke),
            EmitterPolicy::Area,
            &mut s.emitter_triangles,
            &mut s.emitter_cdf,
        )
        .expect("emitter table");
        let mut binary = [BvhNode::default(); BVH_NODES];
        let used = bvh::build_triangles(
            &s.positions,
            &s.triangles,
            &mut binary,
            &mut s.bvh_prim_order,
        )
        .expect("BVH build");
        s.bvh_node_count = bvh::collapse(&binary[..used], &mut s.bvh_nodes).expect("BVH collapse");
        s.bvh_wide_order_len = bvh::align_leaves(
            &mut s.bvh_nodes[..s.bvh_node_count],
            &s.bvh_prim_order,
            &mut s.bvh_wide_order,
        )
        .expect("aligned leaves");
        let groups = s.bvh_wide_order_len / GROUP_WIDTH;
        bvh::gather_leaf_groups(
            &s.positions,
            &s.triangles,
            &s.bvh_wide_order[..s.bvh_wide_order_len],
            &mut s.bvh_leaf_groups[..groups],
        )
        .expect("leaf groups");
        s
    }

    /// The kernel's view of the arrays.
    #[must_use]
    pub fn view(&self) -> SceneView<'_> {
        SceneView {
            positions: &self.positions,
            normals: &self.normals,
            triangles: &self.triangles,
            triangle_materials: &self.triangle_materials,
            materials: &self.materials,
            emitter_triangles: &self.emitter_triangles[..self.emitter_count],
            emitter_cdf: &self.emitter_cdf[..self.emitter_count],
            bvh: WideBvh {
                nodes: &self.bvh_nodes[..self.bvh_node_count],
                prim_order: &self.bvh_wide_order[..self.bvh_wide_order_len],
                leaf_groups: &self.bvh_leaf_groups[..self.bvh_wide_order_len / GROUP_WIDTH],
            }
            .into(),
            textures: Textures {
                uvs: &self.uvs,
                textures: &TEXTURES,
                texels: &self.texels,
            },
        }
    }
}

/// The mean radiance of pixel `(x, y)` over samples `0..spp`, as the C API and the command
/// line compute it (`sum / spp`).
#[must_use]
pub fn pixel(
    scene: &SceneView<'_>,
    camera: &Camera,
    integrator: Integrator,
    settings: &PathSettings,
    spp: u32,
    seed: u64,
    x: u32,
    y: u32,
) -> [f32; 3] {
    let stats = render_pixel(
        integrator,
        scene,
        camera,
        settings,
        &Sampling::new(
            integrator.default_sampler(),
            seed,
            spp,
            camera.width,
            camera.height,
        ),
        x,
        y,
        0,
        spp,
        PixelStats::default(),
        None,
        &mut ember_kernel::splat::NoSplats,
    );
    (stats.sum / spp as f32).to_array()
}

/// The determinism render's pixel `(x, y)` with `integrator`.
#[must_use]
pub fn render_pixel_rgb(scene: &SceneView<'_>, integrator: Integrator, x: u32, y: u32) -> [f32; 3] {
    pixel(scene, &camera(), integrator, &RENDER_PATH, SPP, SEED, x, y)
}

/// The determinism render's pixels `(x0 + k, y)` with `integrator` into `out[k]` (at most
/// [`WIDTH`] of them), by one [`render_row`] call: under MIS, whose batches fill their lanes
/// with neighbouring pixels' samples ([`SPP`] is too few for one pixel's), as `ember render`
/// and the C API render a tile's rows. The values are [`render_pixel_rgb`]'s, bit for bit.
pub fn render_row_rgb(
    scene: &SceneView<'_>,
    integrator: Integrator,
    x0: u32,
    y: u32,
    out: &mut [[f32; 3]],
) {
    let mut stats = [PixelStats::default(); WIDTH as usize];
    let stats = &mut stats[..out.len()];
    render_row(
        integrator,
        scene,
        &camera(),
        &RENDER_PATH,
        &Sampling::new(integrator.default_sampler(), SEED, SPP, WIDTH, HEIGHT),
        (x0, y),
        0,
        SPP,
        stats,
        None,
        &mut ember_kernel::splat::NoSplats,
    );
    for (o, s) in out.iter_mut().zip(stats.iter()) {
        *o = (s.sum / SPP as f32).to_array();
    }
}

/// Sample sums of the determinism render's pixel `(x, y)` with a splatting integrator of
/// [`SPLAT_INTEGRATORS`] (what the C API's `ember_render_tile_splats` writes); its splats are
/// added to `splats`. `scratch` holds BDPT's subpaths.
#[must_use]
pub fn render_pixel_sum(
    scene: &SceneView<'_>,
    integrator: Integrator,
    x: u32,
    y: u32,
    scratch: &mut BdptScratch,
    splats: &mut SplatBuffer<'_>,
) -> [f32; 3] {
    let stats = render_pixel(
        integrator,
        scene,
        &camera(),
        &RENDER_PATH,
        &Sampling::new(integrator.default_sampler(), SEED, SPP, WIDTH, HEIGHT),
        x,
        y,
        0,
        SPP,
        PixelStats::default(),
        Some(scratch),
        splats,
    );
    stats.sum.to_array()
}

/// A pixel of a splatting render from its sample sum and its (merged) splat sums: the kernel's
/// [`ember_kernel::splat::resolve`] with [`SPP`], as every host and the C API compute it.
#[must_use]
pub fn resolve_pixel(sum: [f32; 3], splats: [i64; 3]) -> [f32; 3] {
    ember_kernel::splat::resolve(Rgb::from_array(sum), splats, SPP).to_array()
}

/// Renders the whole film with a splatting integrator on the calling thread, pixel after
/// pixel: the sample sums into `sums` and the splats added to `splats` (zero it first).
pub fn render_splat_image(
    scene: &SceneView<'_>,
    integrator: Integrator,
    sums: &mut [[f32; 3]; PIXELS],
    splats: &mut [[i64; 3]; PIXELS],
) {
    let mut scratch = BdptScratch::default();
    let mut buffer = SplatBuffer::new(WIDTH, HEIGHT, splats).expect("film-sized buffer");
    for (i, sum) in sums.iter_mut().enumerate() {
        let (x, y) = ((i % WIDTH as usize) as u32, (i / WIDTH as usize) as u32);
        *sum = render_pixel_sum(scene, integrator, x, y, &mut scratch, &mut buffer);
    }
    assert_eq!(buffer.invalid, 0, "{integrator:?}: non-finite splats");
}

/// The baked value of point `i` of [`BAKE_POINTS`] with `estimator`.
#[must_use]
pub fn bake_point(scene: &SceneView<'_>, estimator: BakeEstimator, i: usize) -> [f32; 3] {
    let b = BAKE_POINTS[i];
    let point = BakePoint {
        p: Vec3::from_array(b.p),
        n: Vec3::from_array(b.n),
        material: b.material,
        uv: Vec2::from_array(b.uv),
    };
    bake_vertex(
        scene,
        &point,
        &BAKE_PATH,
        estimator,
        &BakeSamples {
            sampler: SamplerKind::ZSobol,
            seed: SEED,
            per_vertex: BAKE_SAMPLES,
        },
        i as u64,
    )
    .to_array()
}

/// 64-bit FNV-1a over the bits of f32 values (little-endian bytes).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Fnv1a(pub u64);

impl Default for Fnv1a {
    fn default() -> Self {
        Self(0xcbf2_9ce4_8422_2325)
    }
}

impl Fnv1a {
    pub fn write_bytes(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 ^= u64::from(b);
            self.0 = self.0.wrapping_mul(0x0100_0000_01b3);
        }
    }

    pub fn write_f32s(&mut self, values: &[f32]) {
        for v in values {
            self.write_bytes(&v.to_bits().to_le_bytes());
        }
    }

    #[must_use]
    pub fn finish(&self) -> u64 {
        self.0
    }
}

/// The hashes the determinism checks compare.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Hashes {
    /// All pixels of the three path-traced renders (implicit, explicit, MIS), row-major, RGB.
    pub render: u64,
    /// The baked values (MIS, then explicit; points in order), RGB.
    pub bake: u64,
    /// All pixels of the three splatting renders (light tracer, BDPT power, BDPT balance),
    /// resolved (`(sum + splats) / spp`), row-major, RGB.
    pub splat: u64,
}

fn hash_images(images: &[&[[f32; 3]]]) -> u64 {
    let mut h = Fnv1a::default();
    for image in images {
        for px in *image {
            h.write_f32s(px);
        }
    }
    h.finish()
}

/// Hashes of already computed images (`images[k]` row-major, of [`INTEGRATORS`]`[k]`), bakes
/// (`bakes[k][i]`, of [`BAKE_ESTIMATORS`]`[k]` at point `i`) and resolved splatting images
/// (`splat_images[k]`, of [`SPLAT_INTEGRATORS`]`[k]`).
#[must_use]
pub fn hash_results(
    images: &[&[[f32; 3]]],
    bakes: &[&[[f32; 3]]],
    splat_images: &[&[[f32; 3]]],
) -> Hashes {
    Hashes {
        render: hash_images(images),
        bake: hash_images(bakes),
        splat: hash_images(splat_images),
    }
}

/// The hash of the path-traced renders ([`Hashes::render`]), on the calling thread, a row at
/// a time ([`render_row_rgb`]), hashing as it goes.
#[must_use]
pub fn render_hash(view: &SceneView<'_>) -> u64 {
    let mut h = Fnv1a::default();
    let mut row = [[0.0f32; 3]; WIDTH as usize];
    for integrator in INTEGRATORS {
        for y in 0..HEIGHT {
            render_row_rgb(view, integrator, 0, y, &mut row);
            for px in &row {
                h.write_f32s(px);
            }
        }
    }
    h.finish()
}

/// The hash of the bake ([`Hashes::bake`]).
#[must_use]
pub fn bake_hash(view: &SceneView<'_>) -> u64 {
    let mut h = Fnv1a::default();
    for estimator in BAKE_ESTIMATORS {
        for i in 0..BAKE_POINTS.len() {
            h.write_f32s(&bake_point(view, estimator, i));
        }
    }
    h.finish()
}

/// The hash of the splatting renders ([`Hashes::splat`]), on the calling thread. They need
/// the sums and splats of the whole film before the first pixel is final: fixed-size arrays
/// (12 KiB of sums, 24 KiB of splats) and a BDPT scratch (24 KiB) on the stack, no allocation.
#[must_use]
pub fn splat_hash(view: &SceneView<'_>) -> u64 {
    let mut h = Fnv1a::default();
    let mut sums = [[0.0f32; 3]; PIXELS];
    for integrator in SPLAT_INTEGRATORS {
        let mut splats = [[0i64; 3]; PIXELS];
        render_splat_image(view, integrator, &mut sums, &mut splats);
        for (sum, s) in sums.iter().zip(&splats) {
            h.write_f32s(&resolve_pixel(*sum, *s));
        }
    }
    h.finish()
}

/// Renders and bakes everything on the calling thread.
#[must_use]
pub fn hashes() -> Hashes {
    let scene = Scene::new();
    let view = scene.view();
    Hashes {
        render: render_hash(&view),
        bake: bake_hash(&view),
        splat: splat_hash(&view),
    }
}
