//! The scene of ember's determinism checks: a small Cornell box built in arrays (no files),
//! rendered at 32×32 with every BSDF (diffuse walls, a Phong box, a mixture box) by each path
//! integrator, plus a bake of a few surface points with both bake estimators. The pixels and
//! baked values are hashed bit for bit (FNV-1a over the little-endian bytes of each f32).
//!
//! `#![no_std]` and allocation-free: the same code runs on the host (any thread count), on
//! aarch64 under qemu, as a wasm32 module under Node.js and in the `no_std` check. The C API
//! test (`tests/capi/cornell.c`) builds the same box in C from the same literal quads.
#![no_std]

use ember_kernel::bvh::{self, BvhNode, WideBvh, WideNode};
use ember_kernel::camera::Camera;
use ember_kernel::emitter::{build_emitter_table, EmitterPolicy};
use ember_kernel::integrator::{
    bake_vertex, render_pixel, BakeEstimator, BakePoint, Integrator, PathSettings, PixelStats,
    Shortcuts,
};
use ember_kernel::sampler::DEFAULT_SEED;
use ember_kernel::scene::{Material, SceneView};
use ember_kernel::{Rgb, Vec3};

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
/// The bake estimators, in hashing order.
pub const BAKE_ESTIMATORS: [BakeEstimator; 2] = [BakeEstimator::Mis, BakeEstimator::Explicit];

/// A material as the C API describes it: `kind` 0 diffuse, 1 Phong, 2 mixture.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MaterialDesc {
    pub kind: u32,
    pub kd: [f32; 3],
    pub ks: [f32; 3],
    pub ns: f32,
    pub ke: [f32; 3],
}

impl MaterialDesc {
    /// The kernel material (what the C API converts it to).
    #[must_use]
    pub fn material(&self) -> Material {
        let (kd, ks) = (Rgb::from_array(self.kd), Rgb::from_array(self.ks));
        let material = match self.kind {
            0 => Material::diffuse(kd),
            1 => Material::phong(kd, ks, self.ns),
            _ => Material::mixture(kd, ks, self.ns),
        };
        material.with_emission(Rgb::from_array(self.ke))
    }
}

const fn diffuse(kd: [f32; 3]) -> MaterialDesc {
    MaterialDesc {
        kind: 0,
        kd,
        ks: [0.0; 3],
        ns: 1.0,
        ke: [0.0; 3],
    }
}

/// White, red and green walls, the light, a Phong box and a mixture box.
pub const MATERIALS: [MaterialDesc; 6] = [
    diffuse([0.725, 0.71, 0.68]),
    diffuse([0.63, 0.065, 0.05]),
    diffuse([0.14, 0.45, 0.091]),
    MaterialDesc {
        kind: 0,
        kd: [0.0; 3],
        ks: [0.0; 3],
        ns: 1.0,
        ke: [17.0, 12.0, 4.0],
    },
    MaterialDesc {
        kind: 1,
        kd: [0.1, 0.1, 0.1],
        ks: [0.7, 0.7, 0.7],
        ns: 40.0,
        ke: [0.0; 3],
    },
    MaterialDesc {
        kind: 2,
        kd: [0.5, 0.4, 0.3],
        ks: [0.3, 0.3, 0.3],
        ns: 15.0,
        ke: [0.0; 3],
    },
];

/// A flat quad: corners counter-clockwise seen from the side its normal points to.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Quad {
    pub corners: [[f32; 3]; 4],
    pub normal: [f32; 3],
    pub material: u32,
}

/// The room (x in [-1, 1], y in [0, 2], z in [-1, 1], open toward +z), the light just below the
/// ceiling, a short mixture box and a tall Phong box (five faces each).
pub const QUADS: [Quad; 16] = [
    Quad {
        corners: [
            [-1.0, 0.0, 1.0],
            [1.0, 0.0, 1.0],
            [1.0, 0.0, -1.0],
            [-1.0, 0.0, -1.0],
        ],
        normal: [0.0, 1.0, 0.0],
        material: 0,
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
];

pub const VERTICES: usize = 4 * QUADS.len();
pub const TRIANGLES: usize = 2 * QUADS.len();
pub const BVH_NODES: usize = bvh::max_nodes(TRIANGLES);
pub const WIDE_NODES: usize = bvh::max_wide_nodes(BVH_NODES);

/// Surface points baked: (position, normal, material). Key `i` for point `i`.
pub const BAKE_POINTS: [([f32; 3], [f32; 3], u32); 8] = [
    ([0.0, 0.0, 0.7], [0.0, 1.0, 0.0], 0),
    ([0.0, 1.0, -1.0], [0.0, 0.0, 1.0], 0),
    ([-1.0, 1.0, 0.0], [1.0, 0.0, 0.0], 1),
    ([1.0, 1.0, 0.0], [-1.0, 0.0, 0.0], 2),
    ([0.6, 2.0, 0.6], [0.0, -1.0, 0.0], 0),
    ([0.4, 1.2, -0.4], [0.0, 1.0, 0.0], 4),
    ([-0.45, 0.6, 0.1], [0.0, 1.0, 0.0], 5),
    ([-1.0, 0.0, -1.0], [0.0, 1.0, 0.0], 0),
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
    pub triangles: [[u32; 3]; TRIANGLES],
    pub triangle_materials: [u32; TRIANGLES],
    pub materials: [Material; MATERIALS.len()],
    pub emitter_triangles: [u32; TRIANGLES],
    pub emitter_cdf: [f32; TRIANGLES],
    pub emitter_count: usize,
    /// The four-wide BVH the command line traces with (the C API traces the binary one; both
    /// must give the golden hashes).
    pub bvh_nodes: [WideNode; WIDE_NODES],
    pub bvh_node_count: usize,
    pub bvh_prim_order: [u32; TRIANGLES],
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
            triangles: [[0; 3]; TRIANGLES],
            triangle_materials: [0; TRIANGLES],
            materials: MATERIALS.map(|m| m.material()),
            emitter_triangles: [0; TRIANGLES],
            emitter_cdf: [0.0; TRIANGLES],
            emitter_count: 0,
            bvh_nodes: [WideNode::default(); WIDE_NODES],
            bvh_node_count: 0,
            bvh_prim_order: [0; TRIANGLES],
        };
        for (q, quad) in QUADS.iter().enumerate() {
            for (c, corner) in quad.corners.iter().enumerate() {
                s.positions[4 * q + c] = Vec3::from_array(*corner);
                s.normals[4 * q + c] = Vec3::from_array(quad.normal);
            }
            let v = 4 * q as u32;
            s.triangles[2 * q] = [v, v + 1, v + 2];
            s.triangles[2 * q + 1] = [v, v + 2, v + 3];
            s.triangle_materials[2 * q] = quad.material;
            s.triangle_materials[2 * q + 1] = quad.material;
        }
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
                prim_order: &self.bvh_prim_order,
            }
            .into(),
            textures: ember_kernel::texture::Textures::NONE,
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
        seed,
        x,
        y,
        0,
        spp,
        PixelStats::default(),
    );
    (stats.sum / spp as f32).to_array()
}

/// The determinism render's pixel `(x, y)` with `integrator`.
#[must_use]
pub fn render_pixel_rgb(scene: &SceneView<'_>, integrator: Integrator, x: u32, y: u32) -> [f32; 3] {
    pixel(scene, &camera(), integrator, &RENDER_PATH, SPP, SEED, x, y)
}

/// The baked value of point `i` of [`BAKE_POINTS`] with `estimator`.
#[must_use]
pub fn bake_point(scene: &SceneView<'_>, estimator: BakeEstimator, i: usize) -> [f32; 3] {
    let (p, n, material) = BAKE_POINTS[i];
    let point = BakePoint {
        p: Vec3::from_array(p),
        n: Vec3::from_array(n),
        material,
        uv: ember_kernel::Vec2::ZERO,
    };
    bake_vertex(
        scene,
        &point,
        &BAKE_PATH,
        estimator,
        SEED,
        i as u64,
        BAKE_SAMPLES,
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
    /// All pixels of the three renders (implicit, explicit, MIS), row-major, RGB.
    pub render: u64,
    /// The baked values (MIS, then explicit; points in order), RGB.
    pub bake: u64,
}

/// Hashes of already computed images (`images[k]` row-major, of [`INTEGRATORS`]`[k]`) and
/// bakes (`bakes[k][i]`, of [`BAKE_ESTIMATORS`]`[k]` at point `i`).
#[must_use]
pub fn hash_results(images: &[&[[f32; 3]]], bakes: &[&[[f32; 3]]]) -> Hashes {
    let mut render = Fnv1a::default();
    for image in images {
        for px in *image {
            render.write_f32s(px);
        }
    }
    let mut bake = Fnv1a::default();
    for values in bakes {
        for v in *values {
            bake.write_f32s(v);
        }
    }
    Hashes {
        render: render.finish(),
        bake: bake.finish(),
    }
}

/// Renders and bakes everything on the calling thread, hashing as it goes (no buffers).
#[must_use]
pub fn hashes() -> Hashes {
    let scene = Scene::new();
    let view = scene.view();
    let mut render = Fnv1a::default();
    for integrator in INTEGRATORS {
        for y in 0..HEIGHT {
            for x in 0..WIDTH {
                render.write_f32s(&render_pixel_rgb(&view, integrator, x, y));
            }
        }
    }
    let mut bake = Fnv1a::default();
    for estimator in BAKE_ESTIMATORS {
        for i in 0..BAKE_POINTS.len() {
            bake.write_f32s(&bake_point(&view, estimator, i));
        }
    }
    Hashes {
        render: render.finish(),
        bake: bake.finish(),
    }
}
