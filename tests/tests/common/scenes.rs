//! Scenes for the stress tests (`stability.rs`, `bdpt.rs`): the scale and translation
//! transforms of a loaded scene, and small OBJ/MTL/TOML scenes written to a temporary folder
//! (a room with a floor, a back wall and a light; closed cubes).

use ember_cli::mesh::SceneData;
use ember_cli::LoadedScene;
use ember_kernel::camera::Camera;
use ember_kernel::glam::{DVec3, Vec3};
use ember_kernel::integrator::PathSettings;
use std::fmt::Write as _;
use std::path::PathBuf;

/// `p ↦ p·scale + offset·(1, 1, 1)`, evaluated in f64 and rounded once to f32.
#[derive(Clone, Copy, Debug)]
pub struct Transform {
    pub scale: f64,
    pub offset: f64,
}

impl Transform {
    pub fn apply(self, p: Vec3) -> Vec3 {
        (p.as_dvec3() * self.scale + DVec3::splat(self.offset)).as_vec3()
    }

    /// The inverse translation of a point produced by [`Self::apply`] with scale 1. It is
    /// exact: `q` and the offset are within a factor of 2 of each other (Sterbenz), and the
    /// test asserts it.
    pub fn untranslate(self, q: Vec3) -> Vec3 {
        let r = (q.as_dvec3() - DVec3::splat(self.offset)).as_vec3();
        assert_eq!(
            r.as_dvec3() + DVec3::splat(self.offset),
            q.as_dvec3(),
            "translating back by {} is not exact",
            self.offset
        );
        r
    }

    pub fn label(self) -> String {
        if self.offset != 0.0 {
            format!("translate {:e}", self.offset)
        } else {
            format!("scale {:e}", self.scale)
        }
    }
}

/// The scene's geometry and camera with every point mapped by `f`. Normals are unchanged by a
/// uniform positive scale and a translation. The BVH is rebuilt. The emitter CDF is kept: it
/// holds normalised area fractions, which a uniform scale leaves unchanged (re-checked by
/// [`cdf_deviation`]); the area pdf uses the transformed triangle's own area, so the estimator
/// stays unbiased for the geometry as stored even where rounding changed an area.
pub fn mapped(
    scene: &LoadedScene,
    f: impl Fn(Vec3) -> Vec3,
    w: u32,
    h: u32,
) -> (SceneData, Camera) {
    let mut data = scene.data.clone();
    for p in &mut data.positions {
        *p = f(*p);
    }
    data.build_bvh().unwrap();
    let c = &scene.file.camera;
    let camera = Camera::look_at(f(c.eye.into()), f(c.at.into()), c.up.into(), c.fov, w, h);
    (data, camera)
}

/// Largest difference between the stored emitter CDF and the one the loader's rule (an
/// emitter uniformly, then a triangle by area) gives for the current positions, in f64.
pub fn cdf_deviation(data: &SceneData) -> f64 {
    let emitters: Vec<_> = data
        .objects
        .iter()
        .filter(|o| {
            o.triangles
                .clone()
                .any(|t| data.emitter_triangles.contains(&t))
        })
        .collect();
    let mut acc = 0.0f64;
    let mut worst = 0.0f64;
    let mut i = 0;
    for o in &emitters {
        let area: f64 = o
            .triangles
            .clone()
            .map(|t| f64::from(data.triangle_area(t)))
            .sum();
        for t in o.triangles.clone() {
            acc += f64::from(data.triangle_area(t)) / area / emitters.len() as f64;
            assert_eq!(data.emitter_triangles[i], t);
            worst = worst.max((acc - f64::from(data.emitter_cdf[i])).abs());
            i += 1;
        }
    }
    assert_eq!(i, data.emitter_cdf.len());
    worst
}

pub const SCALES: [f64; 5] = [1e-4, 1e-2, 1.0, 1e2, 1e4];
pub const OFFSETS: [f64; 2] = [1e4, 1e5];

pub fn transforms() -> Vec<Transform> {
    SCALES
        .iter()
        .map(|&scale| Transform { scale, offset: 0.0 })
        .chain(
            OFFSETS
                .iter()
                .map(|&offset| Transform { scale: 1.0, offset }),
        )
        .collect()
}

/// A fresh folder under the system temporary directory, removed when dropped unless the test
/// is failing (then it is kept for inspection).
pub struct TempDir(PathBuf);

impl TempDir {
    pub fn new(name: &str) -> Self {
        static COUNTER: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
        let n = COUNTER.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let slug: String = name
            .chars()
            .map(|c| if c.is_ascii_alphanumeric() { c } else { '-' })
            .collect();
        let path =
            std::env::temp_dir().join(format!("ember-stability-{slug}-{}-{n}", std::process::id()));
        let _ = std::fs::remove_dir_all(&path);
        std::fs::create_dir_all(&path).expect("cannot create a temporary directory");
        Self(path)
    }

    pub fn path(&self) -> &std::path::Path {
        &self.0
    }

    pub fn write(&self, name: &str, contents: &str) -> PathBuf {
        let p = self.0.join(name);
        std::fs::write(&p, contents).expect("cannot write test input");
        p
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        if std::thread::panicking() {
            eprintln!("test inputs kept in {}", self.0.display());
        } else {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }
}

/// A Wavefront OBJ/MTL pair under construction (1-based indices are handled here).
#[derive(Default, Clone)]
pub struct Mesh {
    pub obj: String,
    pub mtl: String,
    pub vertices: usize,
    pub normals: usize,
}

pub fn v3(v: Vec3) -> String {
    format!("{} {} {}", v.x, v.y, v.z)
}

impl Mesh {
    pub fn material(
        mut self,
        name: &str,
        kd: Vec3,
        ks: Vec3,
        ns: f32,
        ke: Vec3,
        illum: u8,
    ) -> Self {
        writeln!(
            self.mtl,
            "newmtl {name}\nKd {}\nKs {}\nNs {ns}\nKe {}\nillum {illum}\n",
            v3(kd),
            v3(ks),
            v3(ke)
        )
        .unwrap();
        self
    }

    /// An object; `faces` index `positions` and `normals` from 0.
    pub fn object(
        mut self,
        name: &str,
        material: &str,
        positions: &[Vec3],
        normals: &[Vec3],
        faces: &[[(usize, usize); 3]],
    ) -> Self {
        writeln!(self.obj, "o {name}").unwrap();
        for p in positions {
            writeln!(self.obj, "v {}", v3(*p)).unwrap();
        }
        for n in normals {
            writeln!(self.obj, "vn {}", v3(*n)).unwrap();
        }
        writeln!(self.obj, "usemtl {material}").unwrap();
        for f in faces {
            let c: Vec<String> = f
                .iter()
                .map(|&(v, n)| format!("{}//{}", self.vertices + v + 1, self.normals + n + 1))
                .collect();
            writeln!(self.obj, "f {}", c.join(" ")).unwrap();
        }
        self.vertices += positions.len();
        self.normals += normals.len();
        self
    }

    /// A quad as two triangles (0, 1, 2) and (0, 2, 3), with one normal per corner.
    pub fn quad(self, name: &str, material: &str, c: [Vec3; 4], n: [Vec3; 4]) -> Self {
        self.object(
            name,
            material,
            &c,
            &n,
            &[[(0, 0), (1, 1), (2, 2)], [(0, 0), (2, 2), (3, 3)]],
        )
    }

    /// Writes `scene.toml`, `mesh.obj` and `mesh.mtl` and loads them.
    pub fn load(&self, dir: &TempDir, camera: &Cam) -> LoadedScene {
        self.write(dir, camera);
        LoadedScene::load(&dir.path().join("scene.toml")).unwrap_or_else(|e| panic!("{e}"))
    }

    pub fn write(&self, dir: &TempDir, camera: &Cam) -> PathBuf {
        dir.write("mesh.obj", &format!("mtllib mesh.mtl\n{}", self.obj));
        dir.write("mesh.mtl", &self.mtl);
        let a = |v: Vec3| format!("[{}, {}, {}]", v.x, v.y, v.z);
        dir.write(
            "scene.toml",
            &format!(
                "[input]\nobjfile = \"mesh.obj\"\n\n[camera]\neye = {}\nat = {}\nup = {}\nfov = {}\n\n\
                 [film]\nwidth = {}\nheight = {}\n\n[renderer]\nrealtime = false\ntype = \"path\"\n\
                 isExplicit = true\nmaxDepth = -1\nrrDepth = 5\nrrProb = 0.95\nspp = 1\n",
                a(camera.eye),
                a(camera.at),
                a(camera.up),
                camera.fov,
                camera.width,
                camera.height
            ),
        )
    }
}

#[derive(Clone, Copy, Debug)]
pub struct Cam {
    pub eye: Vec3,
    pub at: Vec3,
    pub up: Vec3,
    pub fov: f32,
    pub width: u32,
    pub height: u32,
}

/// The camera of the room scenes: it sees the floor, the back wall and the light from below.
pub const ROOM_CAM: Cam = Cam {
    eye: Vec3::new(0.0, 0.6, 2.5),
    at: Vec3::new(0.0, 0.3, 0.0),
    up: Vec3::Y,
    fov: 45.0,
    width: 40,
    height: 30,
};

pub const UP: [Vec3; 4] = [Vec3::Y; 4];
pub const DOWN: [Vec3; 4] = [Vec3::NEG_Y; 4];
pub const FLOOR: [Vec3; 4] = [
    Vec3::new(-1.0, 0.0, 1.0),
    Vec3::new(1.0, 0.0, 1.0),
    Vec3::new(1.0, 0.0, -1.0),
    Vec3::new(-1.0, 0.0, -1.0),
];
/// Facing down (counter-clockwise seen from below).
pub const LIGHT: [Vec3; 4] = [
    Vec3::new(-0.25, 1.0, -0.25),
    Vec3::new(0.25, 1.0, -0.25),
    Vec3::new(0.25, 1.0, 0.25),
    Vec3::new(-0.25, 1.0, 0.25),
];

pub fn room_materials() -> Mesh {
    Mesh::default()
        .material("white", Vec3::splat(0.6), Vec3::ZERO, 1.0, Vec3::ZERO, 7)
        .material("black", Vec3::ZERO, Vec3::ZERO, 1.0, Vec3::ZERO, 7)
        .material(
            "glossy",
            Vec3::new(0.4, 0.5, 0.6),
            Vec3::splat(0.2),
            20.0,
            Vec3::ZERO,
            8,
        )
        .material("light", Vec3::ZERO, Vec3::ZERO, 1.0, Vec3::splat(4.0), 7)
}

pub fn back_wall(m: Mesh) -> Mesh {
    m.quad(
        "wall",
        "glossy",
        [
            Vec3::new(-1.0, 0.0, -1.0),
            Vec3::new(1.0, 0.0, -1.0),
            Vec3::new(1.0, 2.0, -1.0),
            Vec3::new(-1.0, 2.0, -1.0),
        ],
        [Vec3::Z; 4],
    )
}

/// Floor (with the given normals and material), glossy back wall, light (given normals).
pub fn room(floor_normals: [Vec3; 4], floor_material: &str, light_normals: [Vec3; 4]) -> Mesh {
    let m = room_materials().quad("floor", floor_material, FLOOR, floor_normals);
    back_wall(m).quad("light", "light", LIGHT, light_normals)
}

pub fn room_settings() -> PathSettings {
    PathSettings {
        max_depth: 4,
        rr_depth: 5,
        rr_prob: 0.95,
        ..PathSettings::default()
    }
}

/// An axis-aligned closed cube `[c − h, c + h]`, its normals pointing out or in, with the
/// winding to match.
pub fn cube(m: Mesh, name: &str, material: &str, c: Vec3, h: f32, outward: bool) -> Mesh {
    let mut m = m;
    for axis in 0..3 {
        for sign in [-1.0f32, 1.0] {
            let n = Vec3::AXES[axis] * sign;
            let (u, v) = (Vec3::AXES[(axis + 1) % 3], Vec3::AXES[(axis + 2) % 3]);
            // Counter-clockwise about n.
            let (u, v) = if sign > 0.0 { (u, v) } else { (v, u) };
            let corners = [
                c + (n - u - v) * h,
                c + (n + u - v) * h,
                c + (n + u + v) * h,
                c + (n - u + v) * h,
            ];
            let (corners, n) = if outward {
                (corners, n)
            } else {
                ([corners[3], corners[2], corners[1], corners[0]], -n)
            };
            m = m.quad(&format!("{name}_{axis}_{sign}"), material, corners, [n; 4]);
        }
    }
    m
}

/// A square emitter of side 2s = 1e-3 and radiance Le = 1e6 facing down at height 1 over a
/// Lambertian plane (Kd 0.5) at height 0, seen by a pinhole between them looking down (it
/// blocks nothing), with the direct-lighting closed form of each pixel: L(r) = Kd/π · Le·A ·
/// h²/(h² + r²)² (h = 1; the square's finite size changes it by (s/d)² ≤ 1e-6), averaged over
/// 8×8 sub-pixel rays. A second camera looks up at the light from 0.5 below it with a film
/// four times its side, so the light covers 1/16 of it: the mean is Le/16 ([`Self::seen_directly`]).
pub struct TinyEmitter {
    pub scene: LoadedScene,
    /// The camera looking down at the plane.
    pub camera: Camera,
    /// The closed form of each pixel of `camera`, row-major.
    pub exact: Vec<DVec3>,
    /// The camera looking up at the light.
    pub up_camera: Camera,
    /// The closed-form mean of `up_camera`'s image.
    pub seen_directly: f64,
    _dir: TempDir,
}

impl TinyEmitter {
    pub fn new(label: &str) -> Self {
        let s = 5e-4f32;
        let light = [
            Vec3::new(-s, 1.0, -s),
            Vec3::new(s, 1.0, -s),
            Vec3::new(s, 1.0, s),
            Vec3::new(-s, 1.0, s),
        ];
        let big = [
            Vec3::new(-2.0, 0.0, 2.0),
            Vec3::new(2.0, 0.0, 2.0),
            Vec3::new(2.0, 0.0, -2.0),
            Vec3::new(-2.0, 0.0, -2.0),
        ];
        let le = 1e6f32;
        let m = Mesh::default()
            .material("plane", Vec3::splat(0.5), Vec3::ZERO, 1.0, Vec3::ZERO, 7)
            .material("hot", Vec3::ZERO, Vec3::ZERO, 1.0, Vec3::splat(le), 7)
            .quad("plane", "plane", big, UP)
            .quad("hot", "hot", light, DOWN);
        let down = Cam {
            eye: Vec3::new(0.0, 0.5, 0.0),
            at: Vec3::ZERO,
            up: Vec3::NEG_Z,
            fov: 60.0,
            width: 64,
            height: 48,
        };
        let dir = TempDir::new(label);
        let scene = m.load(&dir, &down);
        let camera = scene.camera(down.width, down.height);
        // Area from the stored f32 corners.
        let side = f64::from(light[1].x) - f64::from(light[0].x);
        let area = side * (f64::from(light[2].z) - f64::from(light[0].z));
        let radiance = |p: DVec3| {
            let d2 = p.x * p.x + p.z * p.z + 1.0;
            0.5 / std::f64::consts::PI * f64::from(le) * area / (d2 * d2)
        };
        let mut exact = vec![DVec3::ZERO; (down.width * down.height) as usize];
        for y in 0..down.height {
            for x in 0..down.width {
                let mut sum = 0.0;
                for k in 0..64 {
                    let u = ember_kernel::glam::Vec2::new(
                        ((k % 8) as f32 + 0.5) / 8.0,
                        ((k / 8) as f32 + 0.5) / 8.0,
                    );
                    let ray = camera.generate_ray(x, y, u);
                    let (o, d) = (ray.o.as_dvec3(), ray.d.as_dvec3());
                    sum += radiance(o + d * (-o.y / d.y));
                }
                exact[(y * down.width + x) as usize] = DVec3::splat(sum / 64.0);
            }
        }
        // A square film 8·s wide at the light's distance 0.5, four times the light's side.
        let up_camera = Camera::look_at(
            Vec3::new(0.0, 0.5, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::NEG_Z,
            2.0 * (4.0 * s / 0.5).atan().to_degrees(),
            32,
            32,
        );
        let width = 2.0 * 0.5 * f64::from(up_camera.tan_half_fov);
        Self {
            scene,
            camera,
            exact,
            up_camera,
            seen_directly: f64::from(le) * (side / width).powi(2),
            _dir: dir,
        }
    }
}
