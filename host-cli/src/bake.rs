//! Baking per-vertex global illumination (TinyRender's `gi` pass, FORMAT.md §6) and storing it
//! as PLY.
//!
//! Vertices that share position, normal and material (and texture coordinates, where the
//! material is textured) have the same expected radiance, so each such key is baked once: TinyRender bakes every face corner (3 per triangle); the count of
//! paths this saves is reported.
//!
//! The bake is written as binary little-endian PLY with float `red green blue` vertex
//! properties: PLY is read by MeshLab, Blender, Open3D and most geometry tools, stores float
//! colours (HDR radiance, not 8-bit), and is simple enough to read back without a dependency.
//! (glTF would need a JSON writer and a buffer layout for the same result.)

use crate::error::{Error, Result};
use crate::LoadedScene;
use ember_kernel::integrator::{bake_vertex, BakeEstimator, BakePoint, BakeSamples, PathSettings};
use ember_kernel::sampler::SamplerKind;
use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;
use std::collections::HashMap;
use std::io::{BufRead, BufReader, BufWriter, Read, Write};
use std::path::{Path, PathBuf};

/// A mesh with one baked linear RGB radiance per vertex, ready to rasterise.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BakedMesh {
    pub positions: Vec<[f32; 3]>,
    pub normals: Vec<[f32; 3]>,
    pub colors: Vec<[f32; 3]>,
    pub triangles: Vec<[u32; 3]>,
    /// What produced the colours (`key value` pairs stored as PLY comments), used to decide
    /// whether a stored bake can be reused.
    pub provenance: Vec<(String, String)>,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BakeSettings {
    pub path: PathSettings,
    pub samples_per_vertex: u32,
    pub seed: u64,
    /// Worker threads; 0 means one per core. Does not change the result.
    pub threads: usize,
    pub progress: bool,
    /// Where a vertex is baked: this fraction of the way toward the centroid of a triangle
    /// using it. [`BAKE_INSET`] (the default) keeps vertices on room edges from losing half
    /// of their hemisphere through the neighbouring wall (dark seams along every corner);
    /// 0 reproduces TinyRender's bake, and its reference images, exactly.
    pub vertex_inset: f32,
    /// MIS (default) or TinyRender's explicit path tracer.
    pub estimator: BakeEstimator,
    /// Owen-scrambled Sobol' points per vertex (default) or independent numbers.
    pub sampler: SamplerKind,
}

/// Parses `--bake-estimator` (`mis` or `explicit`).
///
/// # Errors
/// Any other word.
pub fn parse_estimator(s: &str) -> std::result::Result<BakeEstimator, String> {
    match s {
        "mis" => Ok(BakeEstimator::Mis),
        "explicit" => Ok(BakeEstimator::Explicit),
        _ => Err(format!("{s:?}: expected mis or explicit")),
    }
}

/// Counts of a bake, for reports.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BakeReport {
    /// Face corners (3 per triangle): what TinyRender bakes.
    pub face_corners: usize,
    /// Distinct (position, normal, material, uv of a textured material) keys actually baked.
    pub unique_keys: usize,
    pub paths_traced: u64,
    /// Paths a per-corner bake would have traced in addition.
    pub paths_saved: u64,
    pub seconds: f64,
}

/// Default fraction of the way from a vertex to an adjacent triangle's centroid where it is
/// baked (see [`BakeSettings::vertex_inset`]).
pub const BAKE_INSET: f32 = 1e-3;

/// Bit pattern key of a vertex (position, normal, material, and texture coordinates when the
/// material is textured, else 0): equal keys have equal expected radiance.
type VertexKey = ([u32; 3], [u32; 3], u32, [u32; 2]);

/// Bakes every vertex of the scene.
///
/// # Errors
/// When the thread pool cannot be created.
pub fn bake(scene: &LoadedScene, s: &BakeSettings) -> Result<(BakedMesh, BakeReport)> {
    let start = std::time::Instant::now();
    let data = &scene.data;
    let view = data.view();
    // Material of each vertex: vertices belong to exactly one object.
    let mut vertex_material = vec![0u32; data.positions.len()];
    for o in &data.objects {
        for v in o.vertices.clone() {
            vertex_material[v as usize] = o.material;
        }
    }
    // A triangle using each vertex, to step the bake point into the surface (below).
    let mut vertex_triangle = vec![u32::MAX; data.positions.len()];
    for (t, tri) in data.triangles.iter().enumerate() {
        for &v in tri {
            if vertex_triangle[v as usize] == u32::MAX {
                vertex_triangle[v as usize] = t as u32;
            }
        }
    }
    let mut keys: HashMap<VertexKey, u32> = HashMap::new();
    let mut points: Vec<BakePoint> = Vec::new();
    let vertex_key: Vec<u32> = (0..data.positions.len())
        .map(|v| {
            let (p, n, m) = (data.positions[v], data.normals[v], vertex_material[v]);
            // `uvs` is empty in a scene without textures; an untextured material never reads
            // the coordinates, so they do not split its vertices.
            let uv = data.uvs.get(v).copied().unwrap_or(glam::Vec2::ZERO);
            let textured = data.materials[m as usize].is_textured();
            let key = (
                p.to_array().map(f32::to_bits),
                n.to_array().map(f32::to_bits),
                m,
                if textured {
                    uv.to_array().map(f32::to_bits)
                } else {
                    [0; 2]
                },
            );
            *keys.entry(key).or_insert_with(|| {
                // A vertex on the edge where two surfaces meet (a room corner) lies in both
                // planes, and half of its hemisphere would start exactly on the other surface
                // and leave the room. Gouraud shading shows the limit of the radiance from
                // inside the triangles, so by default bake a point a thousandth of the way
                // toward the centroid of one of them: inside the surface, off the neighbouring
                // plane. `vertex_inset = 0` bakes the vertex itself, as TinyRender does.
                let p = match vertex_triangle[v] {
                    u32::MAX => p,
                    t => {
                        let c = view.triangle_vertices(t).iter().sum::<glam::Vec3>() / 3.0;
                        p + (c - p) * s.vertex_inset
                    }
                };
                points.push(BakePoint {
                    p,
                    n,
                    material: m,
                    uv,
                });
                (points.len() - 1) as u32
            })
        })
        .collect();

    let bar = if s.progress {
        let b = ProgressBar::new(points.len() as u64);
        b.set_style(
            ProgressStyle::with_template(
                "{spinner} [{elapsed_precise}] {wide_bar} {pos}/{len} vertices, ETA {eta}",
            )
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        b
    } else {
        ProgressBar::hidden()
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(s.threads)
        .build()
        .map_err(|e| Error::new(format!("cannot create worker threads: {e}")))?;
    let samples = BakeSamples {
        sampler: s.sampler,
        seed: s.seed,
        per_vertex: s.samples_per_vertex,
    };
    let radiance: Vec<[f32; 3]> = pool.install(|| {
        points
            .par_iter()
            .enumerate()
            .map(|(k, point)| {
                let l = bake_vertex(&view, point, &s.path, s.estimator, &samples, k as u64);
                if k % 64 == 0 {
                    bar.inc(64);
                }
                l.to_array()
            })
            .collect()
    });
    bar.finish_and_clear();

    let spv = u64::from(s.samples_per_vertex);
    let report = BakeReport {
        face_corners: 3 * data.triangles.len(),
        unique_keys: points.len(),
        paths_traced: points.len() as u64 * spv,
        paths_saved: (3 * data.triangles.len() as u64).saturating_sub(points.len() as u64) * spv,
        seconds: start.elapsed().as_secs_f64(),
    };
    let mesh = BakedMesh {
        positions: data.positions.iter().map(|p| p.to_array()).collect(),
        normals: data.normals.iter().map(|n| n.to_array()).collect(),
        colors: vertex_key.iter().map(|&k| radiance[k as usize]).collect(),
        triangles: data.triangles.clone(),
        provenance: provenance(scene, s),
    };
    Ok((mesh, report))
}

/// The settings a bake depends on, as stored in the PLY header.
#[must_use]
pub fn provenance(scene: &LoadedScene, s: &BakeSettings) -> Vec<(String, String)> {
    vec![
        ("scene".into(), scene.file.path.display().to_string()),
        (
            "samples_per_vertex".into(),
            s.samples_per_vertex.to_string(),
        ),
        ("seed".into(), s.seed.to_string()),
        ("max_depth".into(), s.path.max_depth.to_string()),
        ("rr_depth".into(), s.path.rr_depth.to_string()),
        ("rr_prob".into(), s.path.rr_prob.to_string()),
        ("vertex_inset".into(), s.vertex_inset.to_string()),
        ("estimator".into(), format!("{:?}", s.estimator)),
        (
            "sampler".into(),
            crate::bench::sampler_name(s.sampler).into(),
        ),
        // A hash of the kernel's and the baker's sources (build.rs): a bake made by other
        // code is never reused.
        ("code".into(), env!("EMBER_BAKE_CODE_HASH").into()),
        // A hash of the scene data the kernel reads: whatever changed it (an edited OBJ, MTL
        // or texture, a change to how the loader maps MTL keys to materials) bakes again.
        (
            "scene_data".into(),
            format!("{:016x}", scene_data_hash(&scene.data.view())),
        ),
    ]
}

/// FNV-1a (64-bit) over everything in a kernel scene view that a bake can depend on:
/// geometry, texture coordinates, materials (their parameters, written out by `Debug`, which
/// prints every float exactly), emitter table, textures and texels. Not the BVH: the closest
/// hit does not depend on the tree (`bvh::closest`), whose layout differs between builds (4-
/// or 8-wide nodes, `bvh::lanes`), so that a bake's file is the same whatever the build.
#[must_use]
pub fn scene_data_hash(v: &ember_kernel::scene::SceneView<'_>) -> u64 {
    struct Fnv(u64);
    impl Fnv {
        fn bytes(&mut self, b: &[u8]) {
            for &x in b {
                self.0 ^= u64::from(x);
                self.0 = self.0.wrapping_mul(0x0100_0000_01b3);
            }
        }
        fn floats(&mut self, f: impl IntoIterator<Item = f32>) {
            for x in f {
                self.bytes(&x.to_bits().to_le_bytes());
            }
        }
        fn words(&mut self, w: impl IntoIterator<Item = u32>) {
            for x in w {
                self.bytes(&x.to_le_bytes());
            }
        }
        /// A length first, so that adjacent slices cannot trade elements.
        fn len(&mut self, n: usize) {
            self.bytes(&(n as u64).to_le_bytes());
        }
    }
    let mut h = Fnv(0xcbf2_9ce4_8422_2325);
    h.len(v.positions.len());
    h.floats(v.positions.iter().flat_map(|p| p.to_array()));
    h.len(v.normals.len());
    h.floats(v.normals.iter().flat_map(|n| n.to_array()));
    h.len(v.triangles.len());
    h.words(v.triangles.iter().flatten().copied());
    h.len(v.triangle_materials.len());
    h.words(v.triangle_materials.iter().copied());
    h.len(v.materials.len());
    for m in v.materials {
        h.bytes(format!("{m:?}").as_bytes());
    }
    h.len(v.emitter_triangles.len());
    h.words(v.emitter_triangles.iter().copied());
    h.floats(v.emitter_cdf.iter().copied());
    let t = &v.textures;
    h.len(t.uvs.len());
    h.floats(t.uvs.iter().flat_map(|uv| uv.to_array()));
    h.len(t.textures.len());
    for tex in t.textures {
        h.bytes(format!("{tex:?}").as_bytes());
    }
    h.len(t.texels.len());
    h.floats(t.texels.iter().flat_map(|c| c.to_array()));
    h.0
}

/// Where a scene's bake is stored by default: `<toml stem>.bake.ply` beside the TOML.
#[must_use]
pub fn default_bake_path(toml: &Path) -> PathBuf {
    toml.with_extension("bake.ply")
}

/// Reads the bake at `path` when it was made from the same scene data with the same settings
/// and code ([`provenance`]); otherwise bakes and stores it there (a store that fails, e.g.
/// in a read-only folder, is reported as a warning and the bake is still returned). File
/// times play no part: an edited texture, a copied scene or a changed loader are all seen in
/// the data the kernel reads.
///
/// # Errors
/// When baking fails.
pub fn load_or_bake(
    scene: &LoadedScene,
    path: &Path,
    s: &BakeSettings,
) -> Result<(BakedMesh, Option<BakeReport>)> {
    if let Ok(mesh) = read_ply(path) {
        if mesh.provenance == provenance(scene, s)
            && mesh.positions.len() == scene.data.positions.len()
        {
            return Ok((mesh, None));
        }
    }
    let (mesh, report) = bake(scene, s)?;
    if let Err(e) = write_ply(path, &mesh) {
        eprintln!("warning: the bake was not stored: {e}");
    }
    Ok((mesh, Some(report)))
}

/// Writes binary little-endian PLY: vertices with `x y z nx ny nz red green blue` floats, faces
/// as `uchar`-counted `uint` index lists. Written atomically.
///
/// # Errors
/// When the file cannot be written.
pub fn write_ply(path: &Path, m: &BakedMesh) -> Result<()> {
    let io = |e: std::io::Error| Error::in_file(path, format!("cannot write PLY: {e}"));
    crate::image::write_atomically(path, |tmp| {
        let file = std::fs::File::create(tmp).map_err(io)?;
        let mut w = BufWriter::new(&file);
        let mut header = String::from("ply\nformat binary_little_endian 1.0\n");
        header
            .push_str("comment ember baked global illumination: linear RGB radiance per vertex\n");
        for (k, v) in &m.provenance {
            header.push_str(&format!("comment {k} {v}\n"));
        }
        header.push_str(&format!("element vertex {}\n", m.positions.len()));
        for p in ["x", "y", "z", "nx", "ny", "nz", "red", "green", "blue"] {
            header.push_str(&format!("property float {p}\n"));
        }
        header.push_str(&format!("element face {}\n", m.triangles.len()));
        header.push_str("property list uchar uint vertex_indices\nend_header\n");
        w.write_all(header.as_bytes()).map_err(io)?;
        for i in 0..m.positions.len() {
            for v in m.positions[i]
                .iter()
                .chain(&m.normals[i])
                .chain(&m.colors[i])
            {
                w.write_all(&v.to_le_bytes()).map_err(io)?;
            }
        }
        for t in &m.triangles {
            w.write_all(&[3u8]).map_err(io)?;
            for i in t {
                w.write_all(&i.to_le_bytes()).map_err(io)?;
            }
        }
        w.flush().map_err(io)?;
        drop(w);
        file.sync_all().map_err(io)
    })
}

/// Reads a PLY written by [`write_ply`].
///
/// # Errors
/// When the file is missing or not in that layout.
pub fn read_ply(path: &Path) -> Result<BakedMesh> {
    let bad = |msg: &str| Error::in_file(path, format!("not an ember bake PLY: {msg}"));
    let file = std::fs::File::open(path)
        .map_err(|e| Error::in_file(path, format!("cannot read PLY: {e}")))?;
    let mut r = BufReader::new(file);
    let mut line = String::new();
    let mut mesh = BakedMesh::default();
    let (mut nv, mut nf) = (None, None);
    let mut props = Vec::new();
    loop {
        line.clear();
        if r.read_line(&mut line).map_err(|e| bad(&e.to_string()))? == 0 {
            return Err(bad("no end_header"));
        }
        let words: Vec<&str> = line.split_whitespace().collect();
        match words.as_slice() {
            ["end_header"] => break,
            ["comment", k, rest @ ..] if !rest.is_empty() => {
                mesh.provenance.push(((*k).to_string(), rest.join(" ")));
            }
            ["element", "vertex", n] => nv = n.parse::<usize>().ok(),
            ["element", "face", n] => nf = n.parse::<usize>().ok(),
            ["property", "float", name] => props.push((*name).to_string()),
            ["format", f, _] if *f != "binary_little_endian" => return Err(bad("format")),
            _ => {}
        }
    }
    mesh.provenance.retain(|(k, _)| k != "ember");
    let expected = ["x", "y", "z", "nx", "ny", "nz", "red", "green", "blue"];
    if props != expected {
        return Err(bad("vertex properties"));
    }
    let (nv, nf) = (
        nv.ok_or_else(|| bad("vertex count"))?,
        nf.ok_or_else(|| bad("face count"))?,
    );
    let mut buf = [0u8; 4];
    let mut f32s = |r: &mut BufReader<std::fs::File>| -> Result<[f32; 3]> {
        let mut v = [0.0f32; 3];
        for x in &mut v {
            r.read_exact(&mut buf).map_err(|_| bad("truncated"))?;
            *x = f32::from_le_bytes(buf);
        }
        Ok(v)
    };
    for _ in 0..nv {
        mesh.positions.push(f32s(&mut r)?);
        mesh.normals.push(f32s(&mut r)?);
        mesh.colors.push(f32s(&mut r)?);
    }
    for _ in 0..nf {
        let mut n = [0u8; 1];
        r.read_exact(&mut n).map_err(|_| bad("truncated"))?;
        if n[0] != 3 {
            return Err(bad("non-triangle face"));
        }
        let mut t = [0u32; 3];
        for i in &mut t {
            r.read_exact(&mut buf).map_err(|_| bad("truncated"))?;
            *i = u32::from_le_bytes(buf);
            if *i as usize >= nv {
                return Err(bad("face index out of range"));
            }
        }
        mesh.triangles.push(t);
    }
    Ok(mesh)
}

#[cfg(test)]
mod tests {
    use super::*;
    use ember_kernel::material::{Material, Surface};
    use ember_kernel::Rgb;

    fn settings() -> BakeSettings {
        BakeSettings {
            path: PathSettings::default(),
            samples_per_vertex: 4,
            seed: 1,
            threads: 1,
            progress: false,
            vertex_inset: BAKE_INSET,
            estimator: BakeEstimator::Mis,
            sampler: SamplerKind::ZSobol,
        }
    }

    /// A stored bake is keyed by the scene data the kernel reads, so whatever changes that
    /// data invalidates it: a different material (here the same Kd mapped to another BSDF,
    /// as a change to the MTL mapping code would do), a changed reflectance, changed texels.
    #[test]
    fn provenance_changes_with_the_scene_data() {
        let toml = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../data/furnace/furnace_a050_explicit.toml");
        let mut scene = LoadedScene::load(&toml).unwrap();
        let s = settings();
        let base = provenance(&scene, &s);
        assert_eq!(base, provenance(&scene, &s), "deterministic");
        let original = scene.data.materials[0];
        let Surface::Diffuse { kd } = original.surface else {
            panic!("the furnace is diffuse")
        };
        // The loader mapping the same MTL entry to the mixture instead.
        scene.data.materials[0] =
            Material::mixture(kd.value, Rgb::ZERO, 1.0).with_emission(original.emission);
        assert_ne!(
            base,
            provenance(&scene, &s),
            "another BSDF for the same MTL"
        );
        // A changed reflectance in the MTL.
        scene.data.materials[0] =
            Material::diffuse(kd.value * 0.999).with_emission(original.emission);
        assert_ne!(base, provenance(&scene, &s), "another Kd");
        scene.data.materials[0] = original;
        assert_eq!(base, provenance(&scene, &s));
        // Geometry.
        scene.data.positions[0].x += 1e-6;
        assert_ne!(base, provenance(&scene, &s), "a moved vertex");
    }
}
