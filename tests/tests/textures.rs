//! Texture maps end to end: a textured diffuse floor under a uniform emitter covering its
//! whole hemisphere renders, texel by texel, to the closed form `Kd_texel · L`; the same
//! picture as PNG gives the same image bit for bit; the bake reads each vertex's texel.
//!
//! The scene is a closed box: the floor `z = 0`, `[-1, 1]²`, is diffuse (`illum 7`) with a
//! 4×4 checker texture (`map_Kd`), and the five other walls are emitters with `Ke = L` and
//! `Kd = 0`, facing inside. Every direction above a floor point reaches an emitter, so its
//! outgoing radiance is `∫ Kd/π · L · cos θ dω = Kd · L` (the walls reflect nothing, so this
//! holds for any depth; the scene uses `maxDepth = 1`). The camera looks straight down at the
//! floor and sees nothing else.

mod cli_util;
mod common;

use cli_util::TempDir;
use common::{critical_z, render_scene_full, z_scores};
use ember_cli::bake::{bake, BakeSettings};
use ember_cli::LoadedScene;
use ember_kernel::camera::Camera;
use ember_kernel::integrator::{BakeEstimator, Integrator, PathSettings};
use ember_kernel::Rgb;
use glam::{Vec2, Vec3};
use std::fmt::Write;
use std::path::PathBuf;

/// Emitted radiance of the walls.
const L: f32 = 2.0;
/// The checker's two colours (8-bit codes): each has a channel at 0, so a texel of the wrong
/// colour is told apart exactly, not only statistically.
const A: [u8; 3] = [255, 128, 0];
const B: [u8; 3] = [0, 64, 255];
const SIDE: u32 = 24;

/// TinyRender's linearisation of an 8-bit colour.
fn linear(c: [u8; 3]) -> Rgb {
    Rgb::from_array(c.map(|c| (f32::from(c) / 255.0).powf(2.2)))
}

/// The checker colour of texel `(i, j)`, `j` counted from the bottom of the picture.
fn checker(i: u32, j: u32) -> [u8; 3] {
    if (i + j) & 1 == 0 {
        A
    } else {
        B
    }
}

/// The checker as the file stores it: rows from the top (`j = 3` first).
fn checker_rows() -> Vec<u8> {
    (0..4)
        .rev()
        .flat_map(|j| (0..4).flat_map(move |i| checker(i, j)))
        .collect()
}

fn checker_ppm() -> Vec<u8> {
    let mut b = b"P6\n4 4\n255\n".to_vec();
    b.extend(checker_rows());
    b
}

fn checker_png() -> Vec<u8> {
    let mut out = Vec::new();
    let mut enc = png::Encoder::new(&mut out, 4, 4);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    let mut w = enc.write_header().expect("PNG header");
    w.write_image_data(&checker_rows()).expect("PNG data");
    w.finish().expect("PNG end");
    out
}

/// OBJ text of a quad with the given corners (counter-clockwise seen from where `normal`
/// points, fixed here if given the other way), texture coordinates and normal.
struct ObjWriter {
    text: String,
    vertices: usize,
}

impl ObjWriter {
    fn new() -> Self {
        Self {
            text: "mtllib box.mtl\n".into(),
            vertices: 0,
        }
    }

    fn object(&mut self, name: &str, material: &str) {
        writeln!(self.text, "o {name}\nusemtl {material}").unwrap();
    }

    fn quad(&mut self, corners: [Vec3; 4], uvs: [Vec2; 4], normal: Vec3) {
        let mut order = [0, 1, 2, 3];
        if (corners[1] - corners[0])
            .cross(corners[2] - corners[0])
            .dot(normal)
            < 0.0
        {
            order.reverse();
        }
        let first = self.vertices + 1;
        for &k in &order {
            let (p, uv) = (corners[k], uvs[k]);
            writeln!(self.text, "v {} {} {}\nvt {} {}", p.x, p.y, p.z, uv.x, uv.y).unwrap();
        }
        writeln!(self.text, "vn {} {} {}", normal.x, normal.y, normal.z).unwrap();
        let n = self.text.matches("\nvn ").count();
        let f: Vec<String> = (0..4).map(|k| format!("{0}/{0}/{n}", first + k)).collect();
        writeln!(self.text, "f {}", f.join(" ")).unwrap();
        self.vertices += 4;
    }

    /// The five emitting walls of the box `[-1, 1]² × [0, 2]` around the floor.
    fn sky(&mut self) {
        self.object("sky", "light");
        let z = Vec2::ZERO;
        let c = |x: f32, y: f32, z: f32| Vec3::new(x, y, z);
        self.quad(
            [
                c(-1., -1., 2.),
                c(1., -1., 2.),
                c(1., 1., 2.),
                c(-1., 1., 2.),
            ],
            [z; 4],
            -Vec3::Z,
        );
        for (axis, s) in [(0, -1.0f32), (0, 1.0), (1, -1.0), (1, 1.0)] {
            let p = |a: f32, h: f32| {
                if axis == 0 {
                    c(s, a, h)
                } else {
                    c(a, s, h)
                }
            };
            let mut inward = Vec3::ZERO;
            inward[axis] = -s;
            self.quad(
                [p(-1., 0.), p(1., 0.), p(1., 2.), p(-1., 2.)],
                [z; 4],
                inward,
            );
        }
    }
}

const MTL: &str = "newmtl floor\nKd 0.5 0.5 0.5\nillum 7\nmap_Kd checker.TEX\nnewmtl light\nKd 0 0 0\nKe 2 2 2\nillum 7\n";

/// Writes the box scene with the checker as `checker.<ext>` (`ppm` or `png`) and a floor made
/// by `floor`; returns the TOML's path.
fn write_scene(dir: &TempDir, ext: &str, floor: impl FnOnce(&mut ObjWriter)) -> PathBuf {
    let mut obj = ObjWriter::new();
    obj.object("floor", "floor");
    floor(&mut obj);
    obj.sky();
    dir.write("box.obj", &obj.text);
    dir.write("box.mtl", &MTL.replace("TEX", ext));
    let texture = if ext == "png" {
        checker_png()
    } else {
        checker_ppm()
    };
    std::fs::write(dir.path().join(format!("checker.{ext}")), texture).unwrap();
    dir.write(
        "box.toml",
        &format!(
            "[input]\nobjfile = \"box.obj\"\n\n[camera]\neye = [0.0, 0.0, 1.5]\nat = [0.0, 0.0, 0.0]\nup = [0.0, 1.0, 0.0]\nfov = 40.0\n\n[film]\nwidth = {SIDE}\nheight = {SIDE}\n\n[renderer]\nrealtime = false\ntype = \"path\"\nisExplicit = true\nmaxDepth = 1\nspp = 256\n"
        ),
    )
}

/// The floor as one quad, `uv = ((x + 1)/2, (y + 1)/2)`.
fn one_quad(obj: &mut ObjWriter) {
    let c = |x: f32, y: f32| Vec3::new(x, y, 0.0);
    let uv = |x: f32, y: f32| Vec2::new((x + 1.0) / 2.0, (y + 1.0) / 2.0);
    obj.quad(
        [c(-1., -1.), c(1., -1.), c(1., 1.), c(-1., 1.)],
        [uv(-1., -1.), uv(1., -1.), uv(1., 1.), uv(-1., 1.)],
        Vec3::Z,
    );
}

/// The texel every sample of pixel `(x, y)` sees, or `None` when the pixel (grown by a small
/// margin) straddles a texel boundary.
fn pixel_texel(camera: &Camera, x: u32, y: u32) -> Option<(u32, u32)> {
    let mut found = None;
    for u in [
        Vec2::new(-0.02, -0.02),
        Vec2::new(1.02, -0.02),
        Vec2::new(-0.02, 1.02),
        Vec2::new(1.02, 1.02),
    ] {
        let r = camera.generate_ray(x, y, u);
        let p = r.o + r.d * (-r.o.z / r.d.z);
        assert!(
            p.x.abs() < 1.0 && p.y.abs() < 1.0,
            "pixel ({x}, {y}) sees beyond the floor"
        );
        let texel = (
            ((p.x + 1.0) / 2.0 * 4.0).floor() as u32,
            ((p.y + 1.0) / 2.0 * 4.0).floor() as u32,
        );
        if *found.get_or_insert(texel) != texel {
            return None;
        }
    }
    found
}

#[test]
fn textured_floor_renders_to_its_closed_form() {
    let dir = TempDir::new("textured-floor");
    let toml = write_scene(&dir, "ppm", one_quad);
    let scene = LoadedScene::load(&toml).unwrap_or_else(|e| panic!("{e}"));
    assert!(scene.data.warnings.is_empty(), "{:?}", scene.data.warnings);
    assert_eq!(scene.data.textures.len(), 1);
    let camera = scene.camera(SIDE, SIDE);
    let mut cells = Vec::new();
    let mut expected = Vec::new();
    for y in 0..SIDE {
        for x in 0..SIDE {
            if let Some((i, j)) = pixel_texel(&camera, x, y) {
                cells.push((x, y));
                expected.push(linear(checker(i, j)) * L);
            }
        }
    }
    // 24 pixels span 1.09 floor units across the texel boundaries at -0.5, 0 and 0.5, each
    // costing up to 2 columns (and rows) of pixels: at least 18 × 18 pixels remain.
    assert!(
        cells.len() >= 18 * 18,
        "only {} pixels inside one texel",
        cells.len()
    );
    let zero = vec![Rgb::ZERO; cells.len()];
    for integrator in [Integrator::PathExplicit, Integrator::PathMis] {
        // 1024 spp: the explicit estimator is skewed (rare large samples), enough samples make
        // its mean normal enough for the z-test.
        let r = render_scene_full(&toml, Some(integrator), SIDE, SIDE, 1024, 7, 8, 0);
        assert_eq!(r.invalid_samples, 0);
        let at = |img: &ember_cli::image::Image| -> Vec<Rgb> {
            cells.iter().map(|&(x, y)| img.at(x, y)).collect()
        };
        let (mean, var) = (at(&r.image), at(&r.variance));
        let rep = z_scores(&format!("{integrator:?}"), &mean, &var, &expected, &zero);
        let limit = critical_z(1e-3, rep.tests);
        println!(
            "{integrator:?}: {} pixels, max |z| {:.2} (limit {limit:.2}); worst {}",
            cells.len(),
            rep.max_abs_z,
            rep.worst
        );
        assert!(rep.max_abs_z < limit, "{}", rep.worst);
        // The channels a colour lacks are exactly 0: no sample read the other colour.
        for (m, e) in mean.iter().zip(&expected) {
            for c in 0..3 {
                assert_eq!(m[c] == 0.0, e[c] == 0.0, "{m} vs {e}");
            }
        }
    }
}

#[test]
fn png_and_ppm_of_one_picture_render_the_same_image() {
    let (a, b) = (TempDir::new("tex-ppm"), TempDir::new("tex-png"));
    let (ta, tb) = (
        write_scene(&a, "ppm", one_quad),
        write_scene(&b, "png", one_quad),
    );
    let sa = LoadedScene::load(&ta).unwrap();
    let sb = LoadedScene::load(&tb).unwrap();
    assert_eq!(sa.data.texels, sb.data.texels);
    let ra = render_scene_full(&ta, None, 16, 16, 8, 3, 8, 0);
    let rb = render_scene_full(&tb, None, 16, 16, 8, 3, 8, 0);
    let bits = |img: &ember_cli::image::Image| -> Vec<u32> {
        img.pixels
            .iter()
            .flat_map(|p| p.to_array().map(f32::to_bits))
            .collect()
    };
    assert_eq!(bits(&ra.image), bits(&rb.image));
    assert!(ra.image.mean().max_element() > 0.1);
}

/// The floor as two quads meeting at `x = 0` whose texture coordinates differ there: the left
/// quad's lie inside texel (0, 0) (colour A), the right quad's inside texel (1, 0) (colour B).
/// The vertices on the seam share position and normal but not their coordinates.
fn seam_quads(obj: &mut ObjWriter) {
    let c = |x: f32, y: f32| Vec3::new(x, y, 0.0);
    // Texel (i, 0) is u in [i/4, (i+1)/4], v in [0, 1/4].
    let inside = |i: f32| {
        let (lo, hi) = ((i + 0.2) / 4.0, (i + 0.8) / 4.0);
        [
            Vec2::new(lo, 0.05),
            Vec2::new(hi, 0.05),
            Vec2::new(hi, 0.2),
            Vec2::new(lo, 0.2),
        ]
    };
    obj.quad(
        [c(-1., -1.), c(0., -1.), c(0., 1.), c(-1., 1.)],
        inside(0.0),
        Vec3::Z,
    );
    obj.quad(
        [c(0., -1.), c(1., -1.), c(1., 1.), c(0., 1.)],
        inside(1.0),
        Vec3::Z,
    );
}

#[test]
fn bake_reads_each_vertex_texel_and_keeps_seams_apart() {
    let dir = TempDir::new("tex-bake");
    let toml = write_scene(&dir, "ppm", seam_quads);
    let scene = LoadedScene::load(&toml).unwrap();
    let settings = BakeSettings {
        path: PathSettings {
            max_depth: 1,
            ..PathSettings::default()
        },
        samples_per_vertex: 4096,
        seed: 11,
        threads: 0,
        progress: false,
        vertex_inset: ember_cli::bake::BAKE_INSET,
        estimator: BakeEstimator::Mis,
        sampler: ember_kernel::sampler::SamplerKind::ZSobol,
    };
    let (mesh, report) = bake(&scene, &settings).unwrap();
    let floor = &scene.data.objects[0];
    assert_eq!(floor.name, "floor");
    // 8 floor vertices at 6 positions: the two seam positions are baked twice (different
    // texture coordinates). The sky's 20 vertices are not textured.
    assert_eq!(floor.vertices.len(), 8);
    assert_eq!(report.unique_keys, 8 + 20);
    for v in floor.vertices.clone() {
        let uv = scene.data.uvs[v as usize];
        let colour = if uv.x < 0.25 { A } else { B };
        let expected = linear(colour) * L;
        let got = Rgb::from_array(mesh.colors[v as usize]);
        for c in 0..3 {
            if expected[c] == 0.0 {
                assert_eq!(got[c], 0.0, "vertex {v} (uv {uv}): {got} vs {expected}");
            } else {
                // 4096 MIS samples of a smooth integrand: a few percent at most.
                let rel = (got[c] - expected[c]).abs() / expected[c];
                assert!(rel < 0.05, "vertex {v} (uv {uv}): {got} vs {expected}");
            }
        }
    }
}
