//! BVH micro-benchmarks (criterion): build time and rays per second of closest-hit and shadow
//! (any-hit) queries on procedural scenes of about 1k, 10k, 100k and 1M triangles.
//!
//! The scenes are those of `shared/bench-embree/make_data.py`, regenerated here: a cube-sphere
//! (n × n quads per cube face, projected to the unit sphere, welded, 12·n² triangles) displaced
//! radially by band-limited noise (random plane waves, 6 octaves, radius 1 ± ~0.3), inside the
//! closed box [−1.5, 1.5]³ (12 triangles facing in). The noise waves come from ember's hash, not
//! numpy's generator, so the surfaces are alike but not identical to the Embree set.
//!
//! Ray sets, 65,536 rays each, traced one at a time on one thread through `SceneView::intersect`
//! and `SceneView::occluded` (the renderer's own queries, triangle tests included):
//! - `camera`: a 256 × 256 pinhole camera inside the box looking at the sphere (pixel centres);
//! - `incoherent`: origins uniform in the box, directions uniform on the sphere;
//! - `shadow`: segments between two surface points chosen uniformly by area, both ends pulled
//!   in by 1e-4 of the box diagonal (any-hit; most are blocked by the sphere).
//!
//! Build time includes the triangle bounds, the node and index arrays and the wide collapse (8-wide
//! on x86-64, 4 elsewhere), as `ember` builds. Ray sets are traced through the wide tree the
//! renderer uses with its leaves' triangles tested four at a time in SIMD lanes (`wide/...`),
//! through the same tree testing one triangle at a time through the index buffer
//! (`wide-scalar/...`: what the lane test buys), through the binary tree as built (`binary/...`),
//! and through the renderer's tree eight rays at a time (`wide-packet/...`:
//! `SceneView::intersect_packet` and `occluded_packet` on consecutive rays of the set, which are
//! neighbouring pixels for the camera set and unrelated rays for the others).
//! Before the benchmarks the kernel scene memory per triangle is printed, and after them (under
//! `cargo bench`) a summary of Mrays/s per scene with the ratio to the 1k scene.
//!
//!     cargo bench -p ember-tests --bench bvh                 # everything, about 2-3 minutes
//!     cargo bench -p ember-tests --bench bvh -- --quick      # shorter
//!     cargo bench -p ember-tests --bench bvh -- 'closest/incoherent'   # a filter

use criterion::{BatchSize, BenchmarkId, Criterion, SamplingMode, Throughput};
use ember_kernel::bvh::{self, Bvh, BvhNode, WideBvh, WideNode};
use ember_kernel::camera::Camera;
use ember_kernel::geometry::{Aabb, Ray, TriangleGroup, GROUP_WIDTH, PACKET};
use ember_kernel::sampler::mix64;
use ember_kernel::scene::{Material, SceneView};
use ember_kernel::{Rgb, Vec2, Vec3};
use std::collections::HashMap;
use std::hint::black_box;
use std::sync::OnceLock;
use std::time::{Duration, Instant};

/// Cube-sphere resolutions: 12·n² sphere triangles (+ 12 for the box).
const SCENES: [(&str, u32); 4] = [("1k", 9), ("10k", 29), ("100k", 91), ("1M", 289)];
const BOX_HALF: f32 = 1.5;
const RAYS: usize = 1 << 16;
const CAMERA_SIDE: u32 = 256;

/// Deterministic uniform numbers in [0, 1) from a counter.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> f64 {
        self.0 += 1;
        (mix64(self.0 ^ 0x5EED_F0B7_E5A1) >> 11) as f64 / (1u64 << 53) as f64
    }
    fn normal(&mut self) -> f64 {
        let (u, v) = (self.next().max(1e-300), self.next());
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }
    fn unit_vector(&mut self) -> Vec3 {
        let z = 1.0 - 2.0 * self.next();
        let r = (1.0 - z * z).max(0.0).sqrt();
        let phi = std::f64::consts::TAU * self.next();
        Vec3::new((r * phi.cos()) as f32, (r * phi.sin()) as f32, z as f32)
    }
}

/// make_data.py's `noise_radius`: 6 octaves (f = 2..64) of 8 plane waves, amplitude f^−0.6.
struct Noise {
    waves: Vec<([f64; 3], f64, f64)>,
}

impl Noise {
    fn new() -> Self {
        let mut rng = Rng(12345 << 20);
        let mut waves = Vec::new();
        for octave in 0..6 {
            let freq = 2.0 * f64::from(1u32 << octave);
            for _ in 0..8 {
                let k = [rng.normal(), rng.normal(), rng.normal()];
                let len = (k[0] * k[0] + k[1] * k[1] + k[2] * k[2]).sqrt();
                let k = k.map(|c| c * freq / len);
                let phase = std::f64::consts::TAU * rng.next();
                waves.push((k, phase, freq.powf(-0.6)));
            }
        }
        Self { waves }
    }

    fn radius(&self, p: [f64; 3]) -> f64 {
        let r: f64 = self
            .waves
            .iter()
            .map(|(k, phase, a)| (p[0] * k[0] + p[1] * k[1] + p[2] * k[2] + phase).sin() * a)
            .sum();
        1.0 + 0.05 * r
    }
}

/// Host-owned scene buffers, as `ember_cli::mesh::SceneData` holds them.
struct Scene {
    name: &'static str,
    positions: Vec<Vec3>,
    normals: Vec<Vec3>,
    triangles: Vec<[u32; 3]>,
    triangle_materials: Vec<u32>,
    materials: Vec<Material>,
    nodes: Vec<BvhNode>,
    wide: Vec<WideNode>,
    prim_order: Vec<u32>,
    /// The wide tree's order with leaves aligned to groups, and its triangle groups.
    wide_order: Vec<u32>,
    leaf_groups: Vec<TriangleGroup>,
    build_seconds: f64,
}

fn triangle_bounds(positions: &[Vec3], triangles: &[[u32; 3]]) -> Vec<Aabb> {
    triangles
        .iter()
        .map(|&[a, b, c]| {
            Aabb::from_points(
                positions[a as usize],
                positions[b as usize],
                positions[c as usize],
            )
        })
        .collect()
}

/// Bounds, node and index arrays, the build and the wide collapse, as the host does it;
/// returns the trimmed binary and wide nodes.
fn build_bvh(
    positions: &[Vec3],
    triangles: &[[u32; 3]],
) -> (Vec<BvhNode>, Vec<WideNode>, Vec<u32>) {
    let bounds = triangle_bounds(positions, triangles);
    let mut nodes = vec![BvhNode::default(); bvh::max_nodes(bounds.len())];
    let mut order = vec![0u32; bounds.len()];
    let used = bvh::build(&bounds, &mut nodes, &mut order).expect("BVH build");
    nodes.truncate(used);
    nodes.shrink_to_fit();
    let mut wide = vec![WideNode::default(); bvh::max_wide_nodes(used)];
    let used = bvh::collapse(&nodes, &mut wide).expect("BVH collapse");
    wide.truncate(used);
    wide.shrink_to_fit();
    (nodes, wide, order)
}

impl Scene {
    /// The displaced cube-sphere of resolution `n` inside the closed box.
    fn generate(name: &'static str, n: u32) -> Self {
        let noise = Noise::new();
        let mut positions: Vec<Vec3> = Vec::new();
        let mut triangles: Vec<[u32; 3]> = Vec::new();
        // Weld the points shared by cube faces (edges and corners) by their exact cube position.
        let mut welded: HashMap<[i64; 3], u32> = HashMap::new();
        let grid = |i: u32| -1.0 + 2.0 * f64::from(i) / f64::from(n);
        for axis in 0..3 {
            for sign in [-1.0f64, 1.0] {
                let others = [(axis + 1) % 3, (axis + 2) % 3];
                let mut index = vec![0u32; ((n + 1) * (n + 1)) as usize];
                for i in 0..=n {
                    for j in 0..=n {
                        let mut c = [0.0f64; 3];
                        c[axis] = sign;
                        c[others[0]] = grid(i);
                        c[others[1]] = grid(j);
                        let key = c.map(|v| (v * 1e9).round() as i64);
                        let id = *welded.entry(key).or_insert_with(|| {
                            let len = (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt();
                            let p = c.map(|v| v / len);
                            let r = noise.radius(p);
                            positions.push(Vec3::new(
                                (p[0] * r) as f32,
                                (p[1] * r) as f32,
                                (p[2] * r) as f32,
                            ));
                            (positions.len() - 1) as u32
                        });
                        index[(i * (n + 1) + j) as usize] = id;
                    }
                }
                for i in 0..n {
                    for j in 0..n {
                        let v = |a: u32, b: u32| index[(a * (n + 1) + b) as usize];
                        let (q0, q1, q2, q3) = (v(i, j), v(i + 1, j), v(i + 1, j + 1), v(i, j + 1));
                        for mut t in [[q0, q1, q2], [q0, q2, q3]] {
                            // Outward: the normal points away from the centre.
                            let [a, b, c] = t.map(|k| positions[k as usize]);
                            if (b - a).cross(c - a).dot(a + b + c) < 0.0 {
                                t.swap(1, 2);
                            }
                            triangles.push(t);
                        }
                    }
                }
            }
        }
        // The closed box, two triangles per face, facing in.
        let h = BOX_HALF;
        let base = positions.len() as u32;
        for k in 0..8u32 {
            let s = |bit: u32| if k & bit != 0 { h } else { -h };
            positions.push(Vec3::new(s(1), s(2), s(4)));
        }
        for axis in 0..3usize {
            for side in [0u32, 1] {
                let bit = 1u32 << axis;
                let (b1, b2) = (1u32 << ((axis + 1) % 3), 1u32 << ((axis + 2) % 3));
                let o = if side == 1 { bit } else { 0 };
                let quad = [o, o | b1, o | b1 | b2, o | b2].map(|c| base + c);
                for mut t in [[quad[0], quad[1], quad[2]], [quad[0], quad[2], quad[3]]] {
                    let [a, b, c] = t.map(|k| positions[k as usize]);
                    if (b - a).cross(c - a).dot(a + b + c) > 0.0 {
                        t.swap(1, 2);
                    }
                    triangles.push(t);
                }
            }
        }
        let normals = positions.iter().map(|p| p.normalize_or_zero()).collect();
        let start = Instant::now();
        let (nodes, wide, prim_order) = build_bvh(&positions, &triangles);
        let mut wide = wide;
        let mut wide_order = vec![0u32; bvh::aligned_order_len(&wide)];
        bvh::align_leaves(&mut wide, &prim_order, &mut wide_order).expect("aligned leaves");
        let mut leaf_groups = vec![TriangleGroup::default(); wide_order.len() / GROUP_WIDTH];
        bvh::gather_leaf_groups(&positions, &triangles, &wide_order, &mut leaf_groups)
            .expect("leaf groups");
        let build_seconds = start.elapsed().as_secs_f64();
        Self {
            name,
            normals,
            triangle_materials: vec![0; triangles.len()],
            materials: vec![Material::diffuse(Rgb::splat(0.5))],
            positions,
            triangles,
            nodes,
            wide,
            prim_order,
            wide_order,
            leaf_groups,
            build_seconds,
        }
    }

    /// The view of `layout`: the wide tree with or without its triangle groups, or the
    /// binary tree as built.
    fn view(&self, layout: Layout) -> SceneView<'_> {
        SceneView {
            positions: &self.positions,
            normals: &self.normals,
            triangles: &self.triangles,
            triangle_materials: &self.triangle_materials,
            materials: &self.materials,
            emitter_triangles: &[],
            emitter_cdf: &[],
            bvh: match layout {
                Layout::Binary => Bvh {
                    nodes: &self.nodes,
                    prim_order: &self.prim_order,
                }
                .into(),
                Layout::Wide | Layout::WideScalar | Layout::Packet => WideBvh {
                    nodes: &self.wide,
                    prim_order: &self.wide_order,
                    leaf_groups: if layout != Layout::WideScalar {
                        &self.leaf_groups
                    } else {
                        &[]
                    },
                }
                .into(),
            },
            textures: ember_kernel::texture::Textures::NONE,
        }
    }

    fn camera_rays(&self) -> Vec<Ray> {
        let cam = Camera::look_at(
            Vec3::new(1.3, 1.0, 1.4),
            Vec3::ZERO,
            Vec3::Y,
            70.0,
            CAMERA_SIDE,
            CAMERA_SIDE,
        );
        (0..CAMERA_SIDE * CAMERA_SIDE)
            .map(|i| cam.generate_ray(i % CAMERA_SIDE, i / CAMERA_SIDE, Vec2::splat(0.5)))
            .collect()
    }

    fn incoherent_rays(&self) -> Vec<Ray> {
        let mut rng = Rng(1 << 40);
        (0..RAYS)
            .map(|_| {
                let o = Vec3::new(
                    (rng.next() * 2.0 - 1.0) as f32,
                    (rng.next() * 2.0 - 1.0) as f32,
                    (rng.next() * 2.0 - 1.0) as f32,
                ) * (BOX_HALF * 0.999);
                Ray::new(o, rng.unit_vector())
            })
            .collect()
    }

    fn shadow_rays(&self) -> Vec<Ray> {
        let mut rng = Rng(2 << 40);
        let mut cdf = Vec::with_capacity(self.triangles.len());
        let mut acc = 0.0f64;
        for &[a, b, c] in &self.triangles {
            let [a, b, c] = [a, b, c].map(|k| self.positions[k as usize]);
            acc += f64::from(0.5 * (b - a).cross(c - a).length());
            cdf.push(acc);
        }
        let eps = 1e-4 * (2.0 * BOX_HALF * 3f32.sqrt());
        let point = |rng: &mut Rng| {
            let u = rng.next() * acc;
            let t = cdf.partition_point(|&c| c < u).min(cdf.len() - 1);
            let [a, b, c] = self.triangles[t].map(|k| self.positions[k as usize]);
            let (mut s, mut r) = (rng.next() as f32, rng.next() as f32);
            if s + r > 1.0 {
                (s, r) = (1.0 - s, 1.0 - r);
            }
            a + (b - a) * s + (c - a) * r
        };
        let mut rays = Vec::with_capacity(RAYS);
        while rays.len() < RAYS {
            let (p, q) = (point(&mut rng), point(&mut rng));
            let len = (q - p).length();
            if len <= 4.0 * eps {
                continue;
            }
            let d = (q - p) / len;
            rays.push(Ray {
                o: p + d * eps,
                d,
                t_max: len - 2.0 * eps,
            });
        }
        rays
    }

    /// Bytes of the data the renderer keeps and traverses: (wide nodes, triangle indices,
    /// positions, aligned prim order, triangle groups); the binary nodes are dropped after the
    /// collapse.
    fn bytes(&self) -> [usize; 5] {
        use std::mem::size_of_val;
        [
            size_of_val(self.wide.as_slice()),
            size_of_val(self.triangles.as_slice()),
            size_of_val(self.positions.as_slice()),
            size_of_val(self.wide_order.as_slice()),
            size_of_val(self.leaf_groups.as_slice()),
        ]
    }
}

/// The scenes, generated (and their BVH built) on first use, so that a filtered run makes only
/// the scenes it needs.
static SCENE_CELLS: [OnceLock<Scene>; 4] = [const { OnceLock::new() }; 4];

fn scene(i: usize) -> &'static Scene {
    SCENE_CELLS[i].get_or_init(|| {
        let (name, n) = SCENES[i];
        let s = Scene::generate(name, n);
        print_memory(&s);
        s
    })
}

fn print_memory(s: &Scene) {
    let [nodes, tris, pos, order, leaf] = s.bytes();
    let n = s.triangles.len() as f64;
    println!(
        "scene {:>4}: {:>9} triangles, {:>8} vertices, {:>9} {}-wide BVH nodes, build {:.3} s; kernel bytes per triangle: {:.1} (nodes {:.1} + indices {:.1} + positions {:.1} + prim order {:.1} + triangle groups {:.1}); + normals {:.1} + material ids 4.0 for shading",
        s.name,
        s.triangles.len(),
        s.positions.len(),
        s.wide.len(),
        ember_kernel::bvh::WIDTH,
        s.build_seconds,
        (nodes + tris + pos + order + leaf) as f64 / n,
        nodes as f64 / n,
        tris as f64 / n,
        pos as f64 / n,
        order as f64 / n,
        leaf as f64 / n,
        std::mem::size_of_val(s.normals.as_slice()) as f64 / n,
    );
}

fn trace_closest(view: &SceneView<'_>, rays: &[Ray]) -> u32 {
    let mut hits = 0u32;
    for r in rays {
        if let Some(h) = view.intersect(black_box(r)) {
            hits = hits.wrapping_add(h.triangle);
        }
    }
    hits
}

fn trace_shadow(view: &SceneView<'_>, rays: &[Ray]) -> u32 {
    rays.iter()
        .map(|r| u32::from(view.occluded(black_box(r))))
        .sum()
}

fn trace_closest_packets(view: &SceneView<'_>, rays: &[Ray]) -> u32 {
    let mut hits = 0u32;
    for chunk in rays.chunks_exact(PACKET) {
        let packet: &[Ray; PACKET] = chunk.try_into().expect("chunks of PACKET");
        for h in view
            .intersect_packet(black_box(packet), 0xFF)
            .into_iter()
            .flatten()
        {
            hits = hits.wrapping_add(h.triangle);
        }
    }
    hits
}

fn trace_shadow_packets(view: &SceneView<'_>, rays: &[Ray]) -> u32 {
    rays.chunks_exact(PACKET)
        .map(|chunk| {
            let packet: &[Ray; PACKET] = chunk.try_into().expect("chunks of PACKET");
            view.occluded_packet(black_box(packet), 0xFF).count_ones()
        })
        .sum()
}

/// The set's rays traced as `layout` traces them.
fn trace(view: &SceneView<'_>, layout: Layout, shadow: bool, rays: &[Ray]) -> u32 {
    match (layout == Layout::Packet, shadow) {
        (false, false) => trace_closest(view, rays),
        (false, true) => trace_shadow(view, rays),
        (true, false) => trace_closest_packets(view, rays),
        (true, true) => trace_shadow_packets(view, rays),
    }
}

type RaySet = (&'static str, fn(&Scene) -> Vec<Ray>, bool);

const RAY_SETS: [RaySet; 3] = [
    ("closest/camera", Scene::camera_rays, false),
    ("closest/incoherent", Scene::incoherent_rays, false),
    ("shadow/surface_pairs", Scene::shadow_rays, true),
];

fn bench_build(c: &mut Criterion) {
    let mut g = c.benchmark_group("build");
    // Flat sampling: every sample is one build (1M triangles take seconds), 10 samples.
    g.sample_size(10)
        .sampling_mode(SamplingMode::Flat)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(3));
    for (i, (name, n)) in SCENES.iter().enumerate() {
        let triangles = 12 * u64::from(n * n) + 12;
        // Ten builds of 1M triangles take about 15 s; the others fit in 3 s.
        g.measurement_time(Duration::from_secs(if triangles > 500_000 {
            20
        } else {
            3
        }));
        g.throughput(Throughput::Elements(triangles));
        g.bench_function(BenchmarkId::from_parameter(name), |b| {
            let s = scene(i);
            b.iter_batched(
                || (),
                |()| build_bvh(&s.positions, &s.triangles),
                BatchSize::PerIteration,
            );
        });
    }
    g.finish();
}

/// How a scene's BVH is traced.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Layout {
    /// The wide tree with its triangle groups (the renderer's).
    Wide,
    /// The wide tree, one triangle test at a time.
    WideScalar,
    /// The binary tree as built.
    Binary,
    /// The renderer's tree, rays traced eight at a time in packets (consecutive rays of the
    /// set: neighbouring pixels for camera rays, unrelated rays for the other sets).
    Packet,
}

const LAYOUTS: [(&str, Layout); 4] = [
    ("wide", Layout::Wide),
    ("wide-packet", Layout::Packet),
    ("wide-scalar", Layout::WideScalar),
    ("binary", Layout::Binary),
];

fn bench_rays(c: &mut Criterion) {
    for (set, make, shadow) in RAY_SETS {
        let mut g = c.benchmark_group(set);
        // Flat sampling: a batch of 65,536 rays takes tens of milliseconds.
        g.sample_size(10)
            .sampling_mode(SamplingMode::Flat)
            .warm_up_time(Duration::from_millis(500))
            .measurement_time(Duration::from_secs(3))
            .throughput(Throughput::Elements(RAYS as u64));
        for (i, (name, _)) in SCENES.iter().enumerate() {
            for (label, layout) in LAYOUTS {
                g.bench_function(BenchmarkId::new(label, name), |b| {
                    let s = scene(i);
                    let view = s.view(layout);
                    let rays = make(s);
                    assert_eq!(rays.len(), RAYS);
                    b.iter(|| trace(&view, layout, shadow, &rays));
                });
            }
        }
        g.finish();
    }
}

/// Mrays/s of every generated scene and ray set (best of 5 passes), and the ratio to the
/// smallest scene: how traversal cost grows with the triangle count (ideally like log N).
fn summary() {
    let generated: Vec<&Scene> = SCENE_CELLS.iter().filter_map(OnceLock::get).collect();
    if generated.is_empty() {
        return;
    }
    println!("\nsummary (one thread, best of 5 passes of {RAYS} rays; ratio to the first scene):");
    for ((set, make, shadow), (label, layout)) in
        RAY_SETS.into_iter().flat_map(|r| LAYOUTS.map(|l| (r, l)))
    {
        let mut first = None;
        let mut line = format!("{:<29}", format!("{set} {label}"));
        for s in &generated {
            let view = s.view(layout);
            let rays = make(s);
            let best = (0..5)
                .map(|_| {
                    let t = Instant::now();
                    black_box(trace(&view, layout, shadow, &rays));
                    t.elapsed().as_secs_f64()
                })
                .fold(f64::MAX, f64::min);
            let mrays = rays.len() as f64 / best / 1e6;
            let base = *first.get_or_insert(mrays);
            line += &format!("  {}: {mrays:7.2} Mrays/s ({:.2})", s.name, mrays / base);
        }
        println!("{line}");
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let benchmarking =
        args.iter().any(|a| a == "--bench") && !args.iter().any(|a| a == "--test" || a == "--list");
    // Every figure carries the CPU it was measured on.
    eprintln!("CPU: {}", ember_cli::simd::cpu_summary());
    let mut c = Criterion::default().configure_from_args();
    bench_build(&mut c);
    bench_rays(&mut c);
    c.final_summary();
    if benchmarking {
        summary();
    }
}
