//! Kernel shortcuts ([`Shortcuts`]): the scene analysis turns on only what is exact for the
//! scene, and images and bakes made with the shortcuts are bit-identical to the general code's
//! wherever both apply.

mod common;

use common::*;
use ember_cli::bake::{bake, BakeSettings, BAKE_INSET};
use ember_cli::render::{render, RenderSettings, Rendered, Shard};
use ember_cli::LoadedScene;
use ember_kernel::bvh::{self, Bvh, BvhNode};
use ember_kernel::geometry::Ray;
use ember_kernel::integrator::{
    BakeEstimator, Integrator, PathSettings, Shortcuts, TERMINAL_TEST_MAX_EMITTERS,
};
use ember_kernel::scene::{Material, SceneView};
use ember_kernel::Rgb;
use glam::Vec3;
use std::path::Path;

fn render_with(
    scene: &LoadedScene,
    integrator: Integrator,
    path: PathSettings,
    spp: u32,
) -> Rendered {
    render(
        &scene.data.view(),
        &scene.camera(48, 48),
        &RenderSettings {
            integrator,
            path,
            spp,
            seed: 11,
            sampler: ember_kernel::sampler::SamplerKind::Independent,
            tile: 16,
            threads: 0,
            progress: false,
            shard: Shard::WHOLE,
            strategies: None,
        },
    )
}

fn bits(img: &ember_cli::image::Image) -> Vec<u32> {
    img.pixels
        .iter()
        .flat_map(|p| p.to_array())
        .map(f32::to_bits)
        .collect()
}

fn assert_identical(toml: &Path, integrator: Integrator, max_depth: i32) {
    let scene = LoadedScene::load(toml).unwrap();
    let (_, scene_path, _) = scene.path_settings().unwrap();
    assert!(
        scene_path.shortcuts.terminal_emitter_test,
        "{}: the analysis should allow the terminal emitter test here, or this compares the general code with itself",
        toml.display()
    );
    let fast = PathSettings {
        max_depth,
        ..scene_path
    };
    let general = PathSettings {
        shortcuts: Shortcuts::NONE,
        ..fast
    };
    let a = render_with(&scene, integrator, fast, 8);
    let b = render_with(&scene, integrator, general, 8);
    let what = format!("{} {integrator:?} maxDepth {max_depth}", toml.display());
    let mean = a.image.mean();
    assert!(
        mean.min_element() > 0.01,
        "{what}: image mean {mean}: a black image would compare trivially"
    );
    assert!(bits(&a.image) == bits(&b.image), "{what}: images differ");
    assert!(
        bits(&a.variance) == bits(&b.variance),
        "{what}: variances differ"
    );
    assert_eq!(a.rays, b.rays, "{what}: ray counts differ");
    assert_eq!(a.invalid_samples, 0, "{what}");
}

#[test]
fn terminal_emitter_test_is_bit_identical_on_tinyrender_scenes() {
    // Bounded implicit and MIS paths end in terminal rays; explicit ones never trace them and
    // unbounded ones only at the bounce cap, so those must be unchanged too.
    let implicit = cbox_scene("cbox_path_implicit_1_bounce.toml");
    for depth in [1, 2, 4] {
        assert_identical(&implicit, Integrator::PathImplicit, depth);
        assert_identical(&implicit, Integrator::PathMis, depth);
    }
    assert_identical(&implicit, Integrator::PathMis, -1);
    assert_identical(&implicit, Integrator::PathExplicit, 2);
}

#[test]
fn terminal_emitter_test_is_bit_identical_on_the_project_cornell_box() {
    let scene = project_data("cornell-box/cornell_box.toml");
    assert_identical(&scene, Integrator::PathMis, 1);
    assert_identical(&scene, Integrator::PathImplicit, 3);
}

#[test]
fn bake_with_shortcuts_is_bit_identical() {
    let scene = LoadedScene::load(&cbox_scene("cbox_gi_low_realtime.toml")).unwrap();
    let (path, _) = scene.gi_settings();
    assert!(path.shortcuts.terminal_emitter_test);
    // A short maxDepth makes terminal rays a large share of the bake.
    let path = PathSettings {
        max_depth: 2,
        ..path
    };
    let baked = |path: PathSettings| {
        bake(
            &scene,
            &BakeSettings {
                path,
                samples_per_vertex: 4,
                seed: 5,
                threads: 0,
                progress: false,
                vertex_inset: BAKE_INSET,
                estimator: BakeEstimator::Mis,
                sampler: ember_kernel::sampler::SamplerKind::ZSobol,
            },
        )
        .unwrap()
        .0
    };
    let a = baked(path);
    let b = baked(PathSettings {
        shortcuts: Shortcuts::NONE,
        ..path
    });
    let flat = |m: &ember_cli::bake::BakedMesh| {
        m.colors
            .iter()
            .flatten()
            .map(|c| c.to_bits())
            .collect::<Vec<_>>()
    };
    assert!(a.colors.iter().flatten().any(|&c| c > 0.0));
    assert!(flat(&a) == flat(&b), "bakes differ");
}

/// A floor (two triangles, y = 0) and a small emitter quad facing down at y = 1.
struct Room {
    positions: Vec<Vec3>,
    normals: Vec<Vec3>,
    triangles: Vec<[u32; 3]>,
    materials_of: Vec<u32>,
    materials: [Material; 2],
    nodes: Vec<BvhNode>,
    order: Vec<u32>,
}

impl Room {
    /// The floor plus `lights` emitter quads side by side (two triangles each).
    fn new(lights: usize) -> Self {
        let mut positions = vec![
            Vec3::new(-5.0, 0.0, -5.0),
            Vec3::new(5.0, 0.0, -5.0),
            Vec3::new(5.0, 0.0, 5.0),
            Vec3::new(-5.0, 0.0, 5.0),
        ];
        let mut normals = vec![Vec3::Y; 4];
        let mut triangles = vec![[0, 2, 1], [0, 3, 2]];
        let mut materials_of = vec![0, 0];
        for k in 0..lights {
            let x = k as f32 * 0.2;
            let base = positions.len() as u32;
            positions.extend([
                Vec3::new(x, 1.0, 0.0),
                Vec3::new(x + 0.1, 1.0, 0.0),
                Vec3::new(x + 0.1, 1.0, 0.1),
                Vec3::new(x, 1.0, 0.1),
            ]);
            normals.extend([Vec3::NEG_Y; 4]);
            triangles.extend([[base, base + 1, base + 2], [base, base + 2, base + 3]]);
            materials_of.extend([1, 1]);
        }
        let diffuse = Material::diffuse(Rgb::splat(0.5));
        let materials = [diffuse, diffuse.with_emission(Rgb::splat(4.0))];
        let mut nodes = vec![BvhNode::default(); bvh::max_nodes(triangles.len())];
        let mut order = vec![0u32; triangles.len()];
        let used = bvh::build_triangles(&positions, &triangles, &mut nodes, &mut order).unwrap();
        nodes.truncate(used);
        Self {
            positions,
            normals,
            triangles,
            materials_of,
            materials,
            nodes,
            order,
        }
    }

    fn view<'a>(&'a self, emitter_triangles: &'a [u32], cdf: &'a [f32]) -> SceneView<'a> {
        SceneView {
            positions: &self.positions,
            normals: &self.normals,
            triangles: &self.triangles,
            triangle_materials: &self.materials_of,
            materials: &self.materials,
            emitter_triangles,
            emitter_cdf: cdf,
            bvh: Bvh {
                nodes: &self.nodes,
                prim_order: &self.order,
            }
            .into(),
            textures: ember_kernel::texture::Textures::NONE,
        }
    }
}

fn uniform_table(first: u32, n: usize) -> (Vec<u32>, Vec<f32>) {
    let tris = (first..first + n as u32).collect();
    let cdf = (1..=n).map(|i| i as f32 / n as f32).collect();
    (tris, cdf)
}

#[test]
fn analysis_allows_the_terminal_test_only_when_it_is_exact_and_cheap() {
    // One quad: two listed emitters, all emissive triangles listed.
    let room = Room::new(1);
    let (t, c) = uniform_table(2, 2);
    assert!(Shortcuts::analyse(&room.view(&t, &c)).terminal_emitter_test);
    // An emissive triangle missing from the table (a host's own weights left it out): a ray
    // could land on it without the test seeing it, so no shortcut.
    let (t, c) = uniform_table(2, 1);
    assert!(!Shortcuts::analyse(&room.view(&t, &c)).terminal_emitter_test);
    // As many entries as emissive triangles, but one of them is the floor: emitter 3 is
    // still missing, so no shortcut (a count alone would be fooled).
    let (t, c) = (vec![1, 2], vec![0.5, 1.0]);
    assert!(room.view(&t, &c).validate().is_ok());
    assert!(!Shortcuts::analyse(&room.view(&t, &c)).terminal_emitter_test);
    // At the limit, and one quad beyond it.
    let lights = TERMINAL_TEST_MAX_EMITTERS / 2;
    let room = Room::new(lights);
    let (t, c) = uniform_table(2, 2 * lights);
    assert!(Shortcuts::analyse(&room.view(&t, &c)).terminal_emitter_test);
    let room = Room::new(lights + 1);
    let (t, c) = uniform_table(2, 2 * lights + 2);
    assert!(!Shortcuts::analyse(&room.view(&t, &c)).terminal_emitter_test);
}

#[test]
fn may_hit_emitter_sees_only_emitters_within_the_ray() {
    let room = Room::new(1);
    let (t, c) = uniform_table(2, 2);
    let scene = room.view(&t, &c);
    let up = |o: Vec3, t_max: f32| Ray {
        o,
        d: Vec3::Y,
        t_max,
    };
    // From the floor straight up through the quad (0..0.1 in x and z).
    assert!(scene.may_hit_emitter(&up(Vec3::new(0.05, 0.0, 0.05), f32::INFINITY)));
    // The same ray stopped short of the quad, and one beside it.
    assert!(!scene.may_hit_emitter(&up(Vec3::new(0.05, 0.0, 0.05), 0.99)));
    assert!(!scene.may_hit_emitter(&up(Vec3::new(0.3, 0.0, 0.05), f32::INFINITY)));
    // From above, down onto the quad's back: still a hit (emission is decided later).
    let down = Ray {
        o: Vec3::new(0.05, 2.0, 0.05),
        d: Vec3::NEG_Y,
        t_max: f32::INFINITY,
    };
    assert!(scene.may_hit_emitter(&down));
    // The floor is not an emitter.
    let to_floor = Ray {
        o: Vec3::new(2.0, 0.5, 2.0),
        d: Vec3::NEG_Y,
        t_max: f32::INFINITY,
    };
    assert!(!scene.may_hit_emitter(&to_floor));
}
