//! An engine embedding ember's kernel directly, with no host crate: the engine owns its arrays
//! (here `Vec`s), builds the BVH and the emitter table into buffers it sized from the kernel's
//! capacity functions, and asks the kernel for pixels and baked vertex colours, threading the
//! work itself. Run it with
//!
//!     cargo run --release -p ember-kernel --example embed
//!
//! It prints a small render of a lit room with a glossy block and a glass cube as ASCII art,
//! its mean radiance, and a baked value.

use ember_kernel::bvh::{self, Bvh, BvhNode};
use ember_kernel::camera::Camera;
use ember_kernel::emitter::{build_emitter_table, EmitterPolicy};
use ember_kernel::integrator::{
    bake_vertex, render_pixel, BakeEstimator, BakePoint, BakeSamples, Integrator, PathSettings,
    PixelStats,
};
use ember_kernel::sampler::{SamplerKind, DEFAULT_SEED};
use ember_kernel::scene::{Material, SceneView};
use ember_kernel::{Rgb, Vec3};

/// The engine's own mesh storage.
#[derive(Default)]
struct Mesh {
    positions: Vec<Vec3>,
    normals: Vec<Vec3>,
    triangles: Vec<[u32; 3]>,
    triangle_materials: Vec<u32>,
}

impl Mesh {
    /// Adds the quad `o`, `o + u`, `o + u + v`, `o + v` (front side: `u × v`).
    fn quad(&mut self, o: Vec3, u: Vec3, v: Vec3, material: u32) {
        let n = u.cross(v).normalize();
        let base = self.positions.len() as u32;
        for p in [o, o + u, o + u + v, o + v] {
            self.positions.push(p);
            self.normals.push(n);
        }
        self.triangles.push([base, base + 1, base + 2]);
        self.triangles.push([base, base + 2, base + 3]);
        self.triangle_materials.extend([material, material]);
    }

    /// An axis-aligned box without a bottom face, outward facing.
    fn cuboid(&mut self, lo: Vec3, hi: Vec3, material: u32) {
        let d = hi - lo;
        let (x, y, z) = (Vec3::X * d.x, Vec3::Y * d.y, Vec3::Z * d.z);
        self.quad(Vec3::new(lo.x, hi.y, lo.z), z, x, material); // top
        self.quad(Vec3::new(lo.x, lo.y, hi.z), x, y, material); // front
        self.quad(Vec3::new(hi.x, lo.y, lo.z), -x, y, material); // back
        self.quad(lo, z, y, material); // left, facing -x
        self.quad(Vec3::new(hi.x, lo.y, hi.z), -z, y, material); // right, facing +x
    }
}

fn main() {
    // Materials: the engine's own description, converted once into the kernel's.
    let white = Material::diffuse(Rgb::new(0.73, 0.71, 0.68));
    let blue = Material::diffuse(Rgb::new(0.1, 0.2, 0.6));
    let glossy = Material::mixture(Rgb::splat(0.3), Rgb::splat(0.5), 60.0);
    let light = Material::diffuse(Rgb::ZERO).with_emission(Rgb::new(12.0, 11.0, 9.0));
    // Smooth glass: relative IOR 1.5, untinted, roughness alpha 0.
    let glass = Material::dielectric(1.5, Rgb::ONE, 0.0);
    let materials = vec![white, blue, glossy, light, glass];

    // A room open toward +z with a ceiling light, a glossy block and a glass cube standing on
    // the floor (its open bottom is the floor: light refracts into it and out again).
    let mut mesh = Mesh::default();
    let (x, y, z) = (Vec3::X * 2.0, Vec3::Y * 2.0, Vec3::Z * 2.0);
    let c = Vec3::new(-1.0, 0.0, -1.0);
    mesh.quad(c, z, x, 0); // floor, facing up
    mesh.quad(c + y, x, z, 0); // ceiling, facing down
    mesh.quad(c, x, y, 0); // back wall
    mesh.quad(c, y, z, 1); // left wall (blue), facing +x
    mesh.quad(c + x, z, y, 0); // right wall, facing -x
    mesh.quad(Vec3::new(-0.3, 1.99, -0.3), Vec3::X * 0.6, Vec3::Z * 0.6, 3); // light, facing down
    mesh.cuboid(Vec3::new(-0.2, 0.0, -0.5), Vec3::new(0.5, 0.8, 0.2), 2);
    mesh.cuboid(Vec3::new(-0.8, 0.0, 0.1), Vec3::new(-0.3, 0.5, 0.6), 4);

    // The BVH into buffers sized by the kernel; no bounds array needed.
    let mut nodes = vec![BvhNode::default(); bvh::max_nodes(mesh.triangles.len())];
    let mut order = vec![0u32; mesh.triangles.len()];
    let used = bvh::build_triangles(&mesh.positions, &mesh.triangles, &mut nodes, &mut order)
        .expect("BVH build");
    nodes.truncate(used);

    // The emitter table: ask for its size with empty slices, then fill it.
    let emission = |m: u32| materials[m as usize].emission;
    let count = match build_emitter_table(
        &mesh.positions,
        &mesh.triangles,
        &mesh.triangle_materials,
        emission,
        EmitterPolicy::Area,
        &mut [],
        &mut [],
    ) {
        Ok(n) => n,
        Err(ember_kernel::emitter::EmitterTableError::Capacity { needed, .. }) => needed,
        Err(e) => panic!("{e}"),
    };
    let mut emitter_triangles = vec![0u32; count];
    let mut emitter_cdf = vec![0.0f32; count];
    build_emitter_table(
        &mesh.positions,
        &mesh.triangles,
        &mesh.triangle_materials,
        emission,
        EmitterPolicy::Area,
        &mut emitter_triangles,
        &mut emitter_cdf,
    )
    .expect("emitter table");

    let scene = SceneView {
        positions: &mesh.positions,
        normals: &mesh.normals,
        triangles: &mesh.triangles,
        triangle_materials: &mesh.triangle_materials,
        materials: &materials,
        emitter_triangles: &emitter_triangles,
        emitter_cdf: &emitter_cdf,
        bvh: Bvh {
            nodes: &nodes,
            prim_order: &order,
        }
        .into(),
        textures: ember_kernel::texture::Textures::NONE,
    };
    scene.validate().expect("consistent scene");

    // Render 36x36 pixels at 16 spp, one thread per half of the rows: each pixel is a pure
    // function of (scene, camera, settings, seed, pixel), so the split cannot change a bit.
    let (w, h, spp) = (36u32, 36u32, 16u32);
    let camera = Camera::look_at(
        Vec3::new(0.0, 1.0, 3.5),
        Vec3::new(0.0, 1.0, 0.0),
        Vec3::Y,
        40.0,
        w,
        h,
    );
    let settings = PathSettings::default();
    let mut image = vec![Rgb::ZERO; (w * h) as usize];
    std::thread::scope(|s| {
        for (half, rows) in image.chunks_mut((w * h / 2) as usize).enumerate() {
            let (scene, camera, settings) = (&scene, &camera, &settings);
            s.spawn(move || {
                for (i, px) in rows.iter_mut().enumerate() {
                    let (x, y) = (i as u32 % w, half as u32 * h / 2 + i as u32 / w);
                    let stats = render_pixel(
                        Integrator::PathMis,
                        scene,
                        camera,
                        settings,
                        &ember_kernel::sampler::Sampling::independent(DEFAULT_SEED),
                        x,
                        y,
                        0,
                        spp,
                        PixelStats::default(),
                        None,
                        &mut ember_kernel::splat::NoSplats,
                    );
                    *px = stats.sum / spp as f32;
                }
            });
        }
    });

    let ramp = b" .:-=+*#%@";
    for row in image.chunks(w as usize) {
        let line: String = row
            .iter()
            .flat_map(|l| {
                let v = (l.x + l.y + l.z) / 3.0;
                let v = (2.0 * v / (1.0 + 2.0 * v)).clamp(0.0, 0.999); // Reinhard
                let c = ramp[(v * ramp.len() as f32) as usize] as char;
                [c, c] // two characters per pixel: a terminal cell is twice as tall as wide
            })
            .collect();
        println!("{line}");
    }
    let mean = image.iter().copied().sum::<Rgb>() / image.len() as f32;
    println!("mean radiance {mean:.4}");

    // Bake the floor in front of the block (the diffuse GI a vertex-lit engine would store).
    let point = BakePoint {
        p: Vec3::new(0.0, 0.0, 0.6),
        n: Vec3::Y,
        material: 0,
        uv: ember_kernel::Vec2::ZERO,
    };
    let baked = bake_vertex(
        &scene,
        &point,
        &PathSettings {
            max_depth: 5,
            ..PathSettings::default()
        },
        BakeEstimator::Mis,
        &BakeSamples {
            sampler: SamplerKind::ZSobol,
            seed: DEFAULT_SEED,
            per_vertex: 256,
        },
        0,
    );
    println!("baked radiance at the floor point {baked:.4}");
}
