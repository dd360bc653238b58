//! Wavefront OBJ/MTL loading (FORMAT.md §3–5) into the flat arrays the kernel reads.
//!
//! [`SceneData::parse_obj`] works on bytes in memory, with MTL and texture files from a
//! [`FileSource`], so tests and fuzzers (`host-cli/fuzz`) drive the same code as
//! [`SceneData::load_obj`]. OBJ syntax is tobj's, after a pass that checks face indices and
//! coordinates with line numbers; MTL files are parsed here, so that every value TinyRender
//! uses is checked and its errors name the line, the material and the key.

use crate::error::{Error, Result};
use ember_kernel::bvh::{self, BvhNode, WideBvh, WideNode};
use ember_kernel::emitter::{build_emitter_table, EmitterPolicy, EmitterTableError};
use ember_kernel::geometry::Aabb;
use ember_kernel::material::Surface;
use ember_kernel::scene::{Material, SceneView};
use ember_kernel::Rgb;
use glam::Vec3;
use std::path::Path;

/// One OBJ object (`o`/`g` group with one material), as a range of triangles and vertices.
#[derive(Clone, Debug, PartialEq)]
pub struct Object {
    pub name: String,
    pub triangles: std::ops::Range<u32>,
    pub vertices: std::ops::Range<u32>,
    pub material: u32,
}

/// Material as read from the MTL, kept for reports and for the real-time pass.
#[derive(Clone, Debug, PartialEq)]
pub struct MaterialInfo {
    pub name: String,
    pub illum: u8,
}

/// The scene's geometry and materials in host-owned buffers; [`SceneData::view`] lends them to
/// the kernel.
#[derive(Clone, Debug, Default)]
pub struct SceneData {
    pub positions: Vec<Vec3>,
    pub normals: Vec<Vec3>,
    pub triangles: Vec<[u32; 3]>,
    pub triangle_materials: Vec<u32>,
    pub materials: Vec<Material>,
    pub material_info: Vec<MaterialInfo>,
    pub objects: Vec<Object>,
    pub emitter_triangles: Vec<u32>,
    pub emitter_cdf: Vec<f32>,
    /// Number of emitters (objects whose first face is emissive).
    pub emitter_count: usize,
    /// The four-wide BVH the renderer traces (the binary build is collapsed and dropped).
    pub bvh_nodes: Vec<WideNode>,
    pub bvh_prim_order: Vec<u32>,
    /// Non-fatal remarks about the input (unsupported MTL features and the like).
    pub warnings: Vec<String>,
    /// Wall time of the last BVH build.
    pub bvh_build_seconds: f64,
    /// The MTL files the OBJ loaded.
    pub mtl_files: Vec<std::path::PathBuf>,
}

/// The surface for an MTL `illum` value with constant `Kd`, `Ks`, `Ns` and the other keys at
/// their defaults (`Pr 0`, `Ni 1`, `Tf 1 1 1`): 7 diffuse, 8 diffuse+Phong mixture,
/// 5 conductor (a perfect mirror of reflectance `Ks`), 6 dielectric, anything else Phong
/// (README.md, "Materials (MTL)").
#[must_use]
pub fn bsdf_for(illum: u8, kd: Rgb, ks: Rgb, ns: f32) -> Surface {
    let mut m = MtlMaterial::new(String::new());
    (m.illum, m.kd, m.ks, m.ns) = (illum, kd, ks, ns);
    m.surface()
}

/// Where an OBJ's companion files (its MTL libraries and the texture maps they name) come
/// from: the disk ([`Disk`]), or memory for tests and fuzzers (any
/// `Fn(&Path) -> Option<Vec<u8>>`, `None` meaning "no such file").
pub trait FileSource {
    /// The bytes of the file at `path`.
    ///
    /// # Errors
    /// When the file does not exist (kind `NotFound`) or cannot be read.
    fn read(&self, path: &Path) -> std::io::Result<Vec<u8>>;
    /// Whether `path` is an existing regular file.
    fn is_file(&self, path: &Path) -> bool;
}

/// Companion files read from the file system.
#[derive(Clone, Copy, Debug, Default)]
pub struct Disk;

impl FileSource for Disk {
    fn read(&self, path: &Path) -> std::io::Result<Vec<u8>> {
        std::fs::read(path)
    }
    fn is_file(&self, path: &Path) -> bool {
        path.is_file()
    }
}

impl<F: Fn(&Path) -> Option<Vec<u8>>> FileSource for F {
    fn read(&self, path: &Path) -> std::io::Result<Vec<u8>> {
        self(path).ok_or_else(|| std::io::Error::from(std::io::ErrorKind::NotFound))
    }
    fn is_file(&self, path: &Path) -> bool {
        self(path).is_some()
    }
}

/// Most materials an OBJ may load from all its MTL libraries together. Real scenes have tens;
/// the cap bounds the memory of an OBJ that names the same large MTL under many spellings.
pub const MAX_MATERIALS: usize = 65_536;

/// Most vertices or triangles a scene may have: the kernel indexes them with `u32`.
pub const MAX_ELEMENTS: usize = u32::MAX as usize;

/// Longest name or value quoted in an error message; longer ones are cut with `…`.
const QUOTE_MAX: usize = 60;

/// `s` for an error message: control characters escaped (a message stays one line) and cut
/// after [`QUOTE_MAX`] characters.
pub(crate) fn quote(s: &str) -> String {
    let mut out = escape(&s.chars().take(QUOTE_MAX).collect::<String>());
    if s.chars().nth(QUOTE_MAX).is_some() {
        out.push('…');
    }
    out
}

/// `s` with control characters escaped, so that an error message stays one line.
pub(crate) fn escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        if c.is_control() {
            out.extend(c.escape_default());
        } else {
            out.push(c);
        }
    }
    out
}

/// One material of an MTL file, checked.
#[derive(Clone, Debug)]
struct MtlMaterial {
    name: String,
    kd: Rgb,
    ks: Rgb,
    ke: Rgb,
    ns: f32,
    /// `Ni`, the index of refraction relative to air (`None`: not given, tinyobj's 1).
    ni: Option<f32>,
    /// `Pr`, the roughness in [0, 1] (0: smooth).
    pr: f32,
    /// `Tf`, the transmission filter.
    tf: Rgb,
    illum: u8,
    /// `map_Kd`/`map_Ks` were given (and found); ember does not use textures yet.
    has_texture: bool,
}

impl MtlMaterial {
    /// tinyobj's defaults for keys the MTL does not give: Kd = Ks = Ke = 0, Ns = 1, Ni = 1,
    /// Pr = 0, Tf = 1 1 1, illum 0.
    fn new(name: String) -> Self {
        Self {
            name,
            kd: Rgb::ZERO,
            ks: Rgb::ZERO,
            ke: Rgb::ZERO,
            ns: 1.0,
            ni: None,
            pr: 0.0,
            tf: Rgb::ONE,
            illum: 0,
            has_texture: false,
        }
    }

    /// The microfacet roughness of conductors and dielectrics: `alpha = Pr²` (`Pr` is the
    /// perceptual roughness of the MTL PBR extension; 0 is smooth).
    fn alpha(&self) -> f32 {
        self.pr * self.pr
    }

    /// The scattering model `illum` selects, with the keys that model uses (the others are
    /// accepted and not applied): 7 diffuse (`Kd`), 8 mixture and anything else but 5 and 6
    /// Phong (`Kd`, `Ks`, `Ns`), 5 conductor (`Ks`, `Pr`), 6 dielectric (`Ni`, `Tf`, `Pr`).
    fn surface(&self) -> Surface {
        match self.illum {
            7 => Material::diffuse(self.kd).surface,
            8 => Material::mixture(self.kd, self.ks, self.ns).surface,
            5 => Material::conductor(self.ks, self.alpha()).surface,
            6 => Material::dielectric(self.ni.unwrap_or(1.0), self.tf, self.alpha()).surface,
            _ => Material::phong(self.kd, self.ks, self.ns).surface,
        }
    }

    /// A remark about a material that loads but may not render as meant: glass whose index
    /// of refraction is the air's does not bend or reflect light.
    fn warning(&self) -> Option<String> {
        if self.illum != 6 {
            return None;
        }
        let name = quote(&self.name);
        match self.ni {
            None => Some(format!(
                "material '{name}': illum 6 (dielectric) without Ni: its index of refraction is tinyobj's default 1, the air's, so the glass is invisible"
            )),
            Some(1.0) => Some(format!(
                "material '{name}': illum 6 (dielectric) with Ni 1, the air's index of refraction: the glass is invisible"
            )),
            Some(_) => None,
        }
    }
}

/// Highest MTL illumination model (the MTL specification defines 0 to 10).
const MAX_ILLUM: i64 = 10;

/// Parses an MTL library (FORMAT.md §4; README.md, "Materials (MTL)"). The keys ember uses
/// are checked and errors name the line, the material and the key: `Kd`, `Ks`, `Ke`, `Tf`
/// (3 finite non-negative numbers), `Ns` (a finite number >= 0), `Ni` (a finite number > 0),
/// `Pr` (a finite number in [0, 1]), `illum` (an integer 0..=10), `map_Kd`/`map_Ks` (a file
/// that exists, resolved against the OBJ's directory as TinyRender does, which also accepts it
/// with the extension `.ppm`). They are checked whichever model `illum` selects, and applied
/// only where that model uses them. Other keys (`Ka`, `d`, `Tr`, other maps) and unknown keys
/// are skipped.
fn parse_mtl(
    path: &Path,
    bytes: &[u8],
    obj_dir: &Path,
    files: &dyn FileSource,
) -> Result<Vec<MtlMaterial>> {
    let mut out: Vec<MtlMaterial> = Vec::new();
    for (i, raw) in bytes.split(|&b| b == b'\n').enumerate() {
        let n = i + 1;
        let err = |msg: String| Error::in_file(path, format!("line {n}: {msg}"));
        let line = std::str::from_utf8(raw)
            .map_err(|_| err("is not UTF-8 text".into()))?
            .trim();
        let mut words = line.split_whitespace();
        let Some(key) = words.next() else { continue };
        if key.starts_with('#') {
            continue;
        }
        let rest = line[key.len()..].trim();
        if key == "newmtl" {
            if rest.is_empty() {
                return Err(err("newmtl without a material name".into()));
            }
            out.push(MtlMaterial::new(rest.to_string()));
            continue;
        }
        if !matches!(
            key,
            "Kd" | "Ks" | "Ke" | "Tf" | "Ns" | "Ni" | "Pr" | "illum" | "map_Kd" | "map_Ks"
        ) {
            continue;
        }
        let Some(m) = out.last_mut() else {
            return Err(err(format!("{key} before the first newmtl")));
        };
        let err = |msg: String| err(format!("material '{}': {msg}", quote(&m.name)));
        // The values, up to a trailing `# comment` (tinyobj ignores words after the values).
        let values: Vec<&str> = words.take_while(|w| !w.starts_with('#')).collect();
        match key {
            "Tf" if matches!(values.first(), Some(&("spectral" | "xyz"))) => {
                let what = if values[0] == "xyz" {
                    "CIE XYZ"
                } else {
                    "a spectral curve file"
                };
                return Err(err(format!(
                    "Tf {} ({what}) is not supported; give the transmission filter as Tf r g b",
                    values[0]
                )));
            }
            "Kd" | "Ks" | "Ke" | "Tf" => {
                if values.len() != 3 {
                    return Err(err(format!(
                        "{key} must have 3 numbers (r g b), found {}",
                        values.len()
                    )));
                }
                let mut c = [0.0f32; 3];
                for (c, w) in c.iter_mut().zip(&values) {
                    *c = w
                        .parse()
                        .map_err(|_| err(format!("{key} value '{}' is not a number", quote(w))))?;
                }
                let c = Rgb::from_array(c);
                if !c.is_finite() || c.min_element() < 0.0 {
                    return Err(err(format!("{key} = {c} must be finite and non-negative")));
                }
                match key {
                    "Kd" => m.kd = c,
                    "Ks" => m.ks = c,
                    "Tf" => m.tf = c,
                    _ => m.ke = c,
                }
            }
            "Ns" | "Ni" | "Pr" => {
                let v: f32 = match values[..] {
                    [w] => w
                        .parse()
                        .map_err(|_| err(format!("{key} value '{}' is not a number", quote(w))))?,
                    _ => {
                        return Err(err(format!(
                            "{key} must be one number, found '{}'",
                            quote(rest)
                        )))
                    }
                };
                match key {
                    "Ns" if !v.is_finite() || v < 0.0 => {
                        return Err(err(format!("Ns = {v} must be finite and >= 0")));
                    }
                    "Ni" if !v.is_finite() || v <= 0.0 => {
                        return Err(err(format!(
                            "Ni = {v} must be finite and > 0 (the index of refraction relative to air)"
                        )));
                    }
                    "Pr" if !(0.0..=1.0).contains(&v) => {
                        return Err(err(format!("Pr = {v} must be a roughness in [0, 1]")));
                    }
                    "Ns" => m.ns = v,
                    "Ni" => m.ni = Some(v),
                    _ => m.pr = v,
                }
            }
            "illum" => {
                let illum = match values[..] {
                    [w] => w.parse::<i64>().map_err(|_| {
                        err(format!("illum value '{}' is not an integer", quote(w)))
                    })?,
                    _ => {
                        return Err(err(format!(
                            "illum must be one integer, found '{}'",
                            quote(rest)
                        )))
                    }
                };
                if !(0..=MAX_ILLUM).contains(&illum) {
                    return Err(err(format!(
                        "illum {illum} is not an MTL illumination model (0 to {MAX_ILLUM}; ember uses 5 conductor, 6 dielectric, 7 diffuse, 8 mixture, others Phong)"
                    )));
                }
                m.illum = illum as u8;
            }
            _ => {
                // map_Kd / map_Ks
                if rest.is_empty() {
                    return Err(err(format!("{key} without a file name")));
                }
                let file = obj_dir.join(rest);
                let ppm = file.with_extension("ppm");
                if !files.is_file(&file) && !files.is_file(&ppm) {
                    return Err(err(format!(
                        "{key} texture {} not found",
                        escape(&file.display().to_string())
                    )));
                }
                m.has_texture = true;
            }
        }
    }
    Ok(out)
}

/// The MTL libraries parsed while tobj reads the OBJ, and the first failure (tobj itself only
/// keeps a `LoadError`).
#[derive(Default)]
struct MtlLoads {
    /// Every library loaded, in `mtllib` order, with its materials.
    libraries: Vec<(std::path::PathBuf, Vec<MtlMaterial>)>,
    /// The paths of `libraries`.
    seen: std::collections::HashSet<std::path::PathBuf>,
    materials: usize,
    error: Option<Error>,
}

/// The OBJ bytes as a [`std::io::BufRead`] that counts the lines tobj has consumed, so that
/// its errors (which carry no position) can name the line.
struct LineCounter<'a> {
    data: &'a [u8],
    pos: usize,
}

impl LineCounter<'_> {
    /// The line tobj was reading: the last one it consumed, in full or in part.
    fn line(&self) -> usize {
        let done = &self.data[..self.pos];
        let newlines = done.iter().filter(|&&b| b == b'\n').count();
        if done.last() == Some(&b'\n') {
            newlines
        } else {
            newlines + 1
        }
    }
}

impl std::io::Read for LineCounter<'_> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let rest = &self.data[self.pos..];
        let n = rest.len().min(buf.len());
        buf[..n].copy_from_slice(&rest[..n]);
        self.pos += n;
        Ok(n)
    }
}

impl std::io::BufRead for LineCounter<'_> {
    fn fill_buf(&mut self) -> std::io::Result<&[u8]> {
        Ok(&self.data[self.pos..])
    }
    fn consume(&mut self, amt: usize) {
        self.pos = (self.pos + amt).min(self.data.len());
    }
}

/// Checks what tobj does not: face indices in range (tobj computes `vt * 2 + 1` and
/// `vn * 3 + 2` unchecked, which overflows for indices near `usize::MAX`, such as a relative
/// index before the first line), index 0, and finite `v`/`vn` numbers. Tokenises lines exactly as tobj does (`BufRead::lines`,
/// whitespace-separated words), so it sees the same vertex counts. Positive indices are checked
/// against the file's totals (tobj and tinyobj accept a face naming a vertex defined later in
/// the same object), relative ones against the vertices before the line, as tobj resolves them.
fn check_obj_lines(path: &Path, bytes: &[u8]) -> Result<()> {
    let lines = || {
        bytes.split(|&b| b == b'\n').enumerate().map(|(i, l)| {
            let l = l.strip_suffix(b"\r").unwrap_or(l);
            (i + 1, std::str::from_utf8(l))
        })
    };
    let mut total = [0usize; 3];
    for (_, line) in lines() {
        match line.ok().and_then(|l| l.split_whitespace().next()) {
            Some("v") => total[0] += 1,
            Some("vt") => total[1] += 1,
            Some("vn") => total[2] += 1,
            _ => {}
        }
    }
    let mut seen = [0usize; 3];
    // The last `o`/`g` name, to say where a bad line is (tobj names objects the same way).
    let mut object: Option<&str> = None;
    for (n, line) in lines() {
        let err = |msg: String| {
            let at = object.map_or_else(String::new, |o| format!("object '{}': ", quote(o)));
            Error::in_file(path, format!("line {n}: {at}{msg}"))
        };
        let line = line.map_err(|_| err("is not UTF-8 text".into()))?;
        let mut words = line.split_whitespace();
        let key = words.next();
        match key {
            Some(key @ ("o" | "g")) => {
                let name = line.trim_start()[key.len()..].trim();
                object = Some(if name.is_empty() {
                    "unnamed_object"
                } else {
                    name
                });
            }
            Some(key @ ("v" | "vn")) => {
                for axis in ["x", "y", "z"] {
                    let Some(v) = words.next().and_then(|w| w.parse::<f32>().ok()) else {
                        return Err(err(format!("{key} must start with 3 numbers (x y z)")));
                    };
                    if !v.is_finite() {
                        let what = if key == "v" { "position" } else { "normal" };
                        return Err(err(format!(
                            "{what} has a non-finite {axis} coordinate: '{}'",
                            quote(line.trim())
                        )));
                    }
                }
                seen[usize::from(key == "vn") * 2] += 1;
            }
            Some("vt") => seen[1] += 1,
            Some("f" | "l") => {
                let mut corners = 0;
                for word in words {
                    corners += 1;
                    let parts: Vec<&str> = word.split('/').collect();
                    if parts.len() > 3 || parts[0].is_empty() {
                        return Err(err(format!(
                            "face vertex '{}' is not v, v/vt, v//vn or v/vt/vn",
                            quote(word)
                        )));
                    }
                    for (k, part) in parts.iter().enumerate() {
                        if part.is_empty() {
                            continue;
                        }
                        let Ok(index) = part.parse::<isize>() else {
                            return Err(err(format!(
                                "face vertex '{}' is not v, v/vt, v//vn or v/vt/vn",
                                quote(word)
                            )));
                        };
                        let ok = if index > 0 {
                            index.unsigned_abs() <= total[k]
                        } else {
                            index != 0 && index.unsigned_abs() <= seen[k]
                        };
                        if !ok {
                            let kind = ["v", "vt", "vn"][k];
                            let why = match (index.signum(), total[k], seen[k]) {
                                (0, ..) => "OBJ indices start at 1".to_string(),
                                (1, 0, _) => format!("the file has no {kind} lines"),
                                (1, n, _) => format!("the file's {kind} lines are 1..={n}"),
                                (_, _, 0) => format!("no {kind} lines precede it"),
                                (_, _, n) => {
                                    format!("the {kind} lines before it are -{n}..=-1")
                                }
                            };
                            return Err(err(format!(
                                "face index {index} in '{}' is out of range: {why}",
                                quote(word)
                            )));
                        }
                    }
                }
                if corners == 0 {
                    return Err(err(format!("{} without vertices", key.unwrap_or("f"))));
                }
            }
            _ => {}
        }
    }
    Ok(())
}

impl SceneData {
    /// Loads an OBJ with its MTL, triangulating polygons. Vertex normals are required.
    ///
    /// # Errors
    /// Missing or unreadable OBJ, and everything [`SceneData::parse_obj`] refuses.
    pub fn load_obj(path: &Path) -> Result<Self> {
        let bytes = std::fs::read(path).map_err(|e| {
            if e.kind() == std::io::ErrorKind::NotFound {
                Error::in_file(path, "OBJ file not found")
            } else {
                Error::in_file(path, format!("cannot read OBJ: {e}"))
            }
        })?;
        Self::parse_obj(path, &bytes, &Disk)
    }

    /// Parses OBJ bytes into kernel buffers and checks them: the MTL libraries and texture maps
    /// it names are resolved against `path`'s directory and read from `files`; then the
    /// emitter table and the BVH are built and the kernel view is validated. `path` names the
    /// OBJ in errors. [`SceneData::load_obj`] is this with the file read from disk.
    ///
    /// Memory and time are linear in the size of the OBJ and its MTLs (each distinct `mtllib`
    /// is read once; at most [`MAX_MATERIALS`] materials).
    ///
    /// # Errors
    /// Malformed OBJ or MTL (with the line), face indices out of range, faces without normals,
    /// non-finite coordinates, missing MTL or texture files, invalid material values, a scene
    /// without triangles. Every error names the file it is about.
    pub fn parse_obj(path: &Path, obj: &[u8], files: &dyn FileSource) -> Result<Self> {
        check_obj_lines(path, obj)?;
        let options = tobj::LoadOptions {
            triangulate: true,
            single_index: true,
            ignore_points: true,
            ignore_lines: true,
        };
        let obj_name = quote(
            &path
                .file_name()
                .unwrap_or(path.as_os_str())
                .to_string_lossy(),
        );
        // Each `mtllib` is resolved against the OBJ's directory (as tobj::load_obj does) and
        // parsed by `parse_mtl`; tobj only gets the names, to map `usemtl` to indices. A
        // library named twice is read once (its second load adds no materials, so `usemtl`
        // keeps the first load's indices, which hold the same materials).
        let dir = path.parent().unwrap_or(Path::new(""));
        let loads = std::cell::RefCell::new(MtlLoads::default());
        let mut reader = LineCounter { data: obj, pos: 0 };
        let loaded = tobj::load_obj_buf(&mut reader, &options, |name| {
            let mut loads = loads.borrow_mut();
            let mtl = dir.join(name);
            if loads.error.is_some() {
                return Err(tobj::LoadError::GenericFailure);
            }
            if loads.seen.contains(&mtl) {
                return Ok((Vec::new(), Default::default()));
            }
            let parsed = files
                .read(&mtl)
                .map_err(|e| {
                    let what = if e.kind() == std::io::ErrorKind::NotFound {
                        "MTL file not found".to_string()
                    } else {
                        format!("cannot read MTL: {e}")
                    };
                    Error::in_file(&mtl, format!("{what} (mtllib of {obj_name})"))
                })
                .and_then(|bytes| parse_mtl(&mtl, &bytes, dir, files))
                .and_then(|m| {
                    if loads.materials + m.len() > MAX_MATERIALS {
                        Err(Error::in_file(
                            &mtl,
                            format!(
                                "more than {MAX_MATERIALS} materials in the MTL libraries of {obj_name}"
                            ),
                        ))
                    } else {
                        Ok(m)
                    }
                });
            match parsed {
                Ok(materials) => {
                    let names: Vec<tobj::Material> = materials
                        .iter()
                        .map(|m| tobj::Material {
                            name: m.name.clone(),
                            ..Default::default()
                        })
                        .collect();
                    // Indices are local to this library; tobj offsets them. A name defined
                    // twice maps to its last definition, as in tobj.
                    let map = names
                        .iter()
                        .enumerate()
                        .map(|(i, m)| (m.name.clone(), i))
                        .collect();
                    loads.materials += materials.len();
                    loads.seen.insert(mtl.clone());
                    loads.libraries.push((mtl, materials));
                    Ok((names, map))
                }
                Err(e) => {
                    loads.error = Some(e);
                    Err(tobj::LoadError::GenericFailure)
                }
            }
        });
        let line = reader.line();
        let loads = loads.into_inner();
        if let Some(e) = loads.error {
            return Err(e);
        }
        let (models, _) = loaded.map_err(|e| {
            use tobj::LoadError as L;
            match e {
                // Raised when an object is finished, not on the line being read.
                L::FaceVertexOutOfBounds
                | L::FaceTexCoordOutOfBounds
                | L::FaceNormalOutOfBounds
                | L::FaceColorOutOfBounds
                | L::InvalidPolygon => Error::in_file(path, format!("cannot load OBJ: {e}")),
                _ => Error::in_file(path, format!("line {line}: cannot load OBJ: {e}")),
            }
        })?;
        let mut scene = Self {
            mtl_files: loads.libraries.iter().map(|(p, _)| p.clone()).collect(),
            ..Self::default()
        };
        for (_, library) in &loads.libraries {
            for m in library {
                if m.has_texture {
                    scene.warnings.push(format!(
                        "material '{}': texture maps are not supported yet; using Kd/Ks",
                        quote(&m.name)
                    ));
                }
                scene.warnings.extend(m.warning());
                scene.materials.push(Material {
                    surface: m.surface(),
                    emission: m.ke,
                });
                scene.material_info.push(MaterialInfo {
                    name: m.name.clone(),
                    illum: m.illum,
                });
            }
        }
        // Faces without a material get tinyobj's defaults: Kd = Ks = Ke = 0, Ns = 1, illum 0.
        let mut default_material = None;

        for model in &models {
            let mesh = &model.mesh;
            if mesh.indices.is_empty() {
                continue;
            }
            let name = quote(&model.name);
            let nv = mesh.positions.len() / 3;
            if mesh.normals.len() != mesh.positions.len() {
                return Err(Error::in_file(
                    path,
                    format!(
                        "object '{name}' has faces without vertex normals (write faces as f v//vn); TinyRender requires normals"
                    ),
                ));
            }
            if scene.positions.len() + nv > MAX_ELEMENTS
                || scene.triangles.len() + mesh.indices.len() / 3 > MAX_ELEMENTS
            {
                return Err(Error::in_file(
                    path,
                    format!("more than {MAX_ELEMENTS} vertices or triangles"),
                ));
            }
            let material = match mesh.material_id {
                Some(id) if id < scene.materials.len() => id as u32,
                Some(id) => {
                    return Err(Error::in_file(
                        path,
                        format!(
                            "object '{name}' uses material #{id}, which the MTL does not define"
                        ),
                    ))
                }
                None => *default_material.get_or_insert_with(|| {
                    scene.materials.push(Material {
                        surface: bsdf_for(0, Rgb::ZERO, Rgb::ZERO, 1.0),
                        emission: Rgb::ZERO,
                    });
                    scene.material_info.push(MaterialInfo {
                        name: "(default)".into(),
                        illum: 0,
                    });
                    scene.warnings.push(format!(
                        "object '{name}' has no material; using a black default"
                    ));
                    (scene.materials.len() - 1) as u32
                }),
            };
            let base = scene.positions.len() as u32;
            let first_tri = scene.triangles.len() as u32;
            for (i, (p, n)) in mesh
                .positions
                .chunks_exact(3)
                .zip(mesh.normals.chunks_exact(3))
                .enumerate()
            {
                let p = Vec3::new(p[0], p[1], p[2]);
                let n = Vec3::new(n[0], n[1], n[2]);
                if !p.is_finite() || !n.is_finite() {
                    return Err(Error::in_file(
                        path,
                        format!("object '{name}': vertex {i} has a non-finite position or normal"),
                    ));
                }
                scene.positions.push(p);
                scene.normals.push(n);
            }
            for f in mesh.indices.chunks_exact(3) {
                if f.iter().any(|&v| v as usize >= nv) {
                    return Err(Error::in_file(
                        path,
                        format!("object '{name}': face index out of range"),
                    ));
                }
                scene
                    .triangles
                    .push([base + f[0], base + f[1], base + f[2]]);
                scene.triangle_materials.push(material);
            }
            scene.objects.push(Object {
                name: model.name.clone(),
                triangles: first_tri..scene.triangles.len() as u32,
                vertices: base..scene.positions.len() as u32,
                material,
            });
        }
        if scene.triangles.is_empty() {
            return Err(Error::in_file(path, "OBJ has no faces"));
        }
        scene
            .build_emitters()
            .map_err(|e| Error::in_file(path, e))?;
        scene.build_bvh().map_err(|e| Error::in_file(path, e))?;
        scene
            .view()
            .validate()
            .map_err(|e| Error::in_file(path, e.to_string()))?;
        Ok(scene)
    }

    #[must_use]
    pub fn triangle_area(&self, t: u32) -> f32 {
        let [a, b, c] = self.triangles[t as usize];
        let (p0, p1, p2) = (
            self.positions[a as usize],
            self.positions[b as usize],
            self.positions[c as usize],
        );
        0.5 * (p1 - p0).cross(p2 - p0).length()
    }

    /// TinyRender's emitter rule: an object is an area light when its material has non-zero
    /// `Ke`; an emitter is chosen uniformly, then a triangle of it by area (the kernel's
    /// [`EmitterPolicy::UniformPerObject`]).
    ///
    /// # Errors
    /// When an emitter's area is not finite (coordinates near the `f32` limit).
    fn build_emitters(&mut self) -> std::result::Result<(), String> {
        let mut objects = vec![0u32; self.triangles.len()];
        for (i, o) in self.objects.iter().enumerate() {
            for t in o.triangles.clone() {
                objects[t as usize] = i as u32;
            }
        }
        let emission = |m: u32| self.materials[m as usize].emission;
        let policy = EmitterPolicy::UniformPerObject { objects: &objects };
        let (p, t, m) = (&self.positions, &self.triangles, &self.triangle_materials);
        let needed = match build_emitter_table(p, t, m, emission, policy, &mut [], &mut []) {
            Ok(n) => n,
            Err(EmitterTableError::Capacity { needed, .. }) => needed,
            Err(e) => return Err(e.to_string()),
        };
        let mut tris = vec![0u32; needed];
        let mut cdf = vec![0f32; needed];
        build_emitter_table(p, t, m, emission, policy, &mut tris, &mut cdf)
            .map_err(|e| e.to_string())?;
        self.emitter_count = self
            .objects
            .iter()
            .filter(|o| o.triangles.clone().any(|t| tris.binary_search(&t).is_ok()))
            .count();
        self.emitter_triangles = tris;
        self.emitter_cdf = cdf;
        Ok(())
    }

    /// Builds the BVH over all triangles, collapses it to the four-wide tree the renderer
    /// traces and trims that to the nodes used.
    ///
    /// # Errors
    /// When the kernel's build refuses the input.
    pub fn build_bvh(&mut self) -> std::result::Result<(), String> {
        let bounds: Vec<Aabb> = (0..self.triangles.len() as u32)
            .map(|t| {
                let [a, b, c] = self.triangles[t as usize];
                Aabb::from_points(
                    self.positions[a as usize],
                    self.positions[b as usize],
                    self.positions[c as usize],
                )
            })
            .collect();
        let start = std::time::Instant::now();
        let mut nodes = vec![BvhNode::default(); bvh::max_nodes(bounds.len())];
        let mut order = vec![0u32; bounds.len()];
        let used = bvh::build(&bounds, &mut nodes, &mut order).map_err(|e| e.to_string())?;
        let mut wide = vec![WideNode::default(); bvh::max_wide_nodes(used)];
        let used = bvh::collapse(&nodes[..used], &mut wide).map_err(|e| e.to_string())?;
        wide.truncate(used);
        wide.shrink_to_fit();
        self.bvh_nodes = wide;
        self.bvh_prim_order = order;
        self.bvh_build_seconds = start.elapsed().as_secs_f64();
        Ok(())
    }

    /// The kernel's view of this scene.
    #[must_use]
    pub fn view(&self) -> SceneView<'_> {
        SceneView {
            positions: &self.positions,
            normals: &self.normals,
            triangles: &self.triangles,
            triangle_materials: &self.triangle_materials,
            materials: &self.materials,
            emitter_triangles: &self.emitter_triangles,
            emitter_cdf: &self.emitter_cdf,
            bvh: WideBvh {
                nodes: &self.bvh_nodes,
                prim_order: &self.bvh_prim_order,
            }
            .into(),
            textures: ember_kernel::texture::Textures::NONE,
        }
    }

    /// Bytes of kernel scene data per triangle (geometry, materials, emitters, BVH).
    #[must_use]
    pub fn kernel_bytes(&self) -> usize {
        use std::mem::size_of_val;
        size_of_val(self.positions.as_slice())
            + size_of_val(self.normals.as_slice())
            + size_of_val(self.triangles.as_slice())
            + size_of_val(self.triangle_materials.as_slice())
            + size_of_val(self.materials.as_slice())
            + size_of_val(self.emitter_triangles.as_slice())
            + size_of_val(self.emitter_cdf.as_slice())
            + size_of_val(self.bvh_nodes.as_slice())
            + size_of_val(self.bvh_prim_order.as_slice())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::cell::Cell;

    const QUAD: &str = "mtllib quad.mtl\no light\nv -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nvn 0 0 1\nusemtl light\nf 1//1 2//1 3//1 4//1\n";

    fn parse(obj: &str, mtl: &str) -> Result<SceneData> {
        let mtl = mtl.as_bytes().to_vec();
        let files = move |p: &Path| (p.extension()? == "mtl").then(|| mtl.clone());
        SceneData::parse_obj(Path::new("m/quad.obj"), obj.as_bytes(), &files)
    }

    #[test]
    fn memory_and_disk_give_the_same_scene() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../data/cornell-box/mesh");
        let path = dir.join("cornell_box.obj");
        let disk = SceneData::load_obj(&path).unwrap();
        let obj = std::fs::read(&path).unwrap();
        let files = |p: &Path| std::fs::read(p).ok();
        let memory = SceneData::parse_obj(&path, &obj, &files).unwrap();
        assert_eq!(disk.positions, memory.positions);
        assert_eq!(disk.triangles, memory.triangles);
        assert_eq!(disk.materials, memory.materials);
        assert_eq!(disk.bvh_prim_order, memory.bvh_prim_order);
        assert_eq!(disk.triangles.len(), 32);
    }

    #[test]
    fn mtl_values_defaults_and_comments() {
        let mtl = "# c\nnewmtl light\nKe 1 2 3 # warm\nNs 4\nKa 9 9\nillum 8 # mixture\n";
        let s = parse(QUAD, mtl).unwrap();
        assert_eq!(s.materials.len(), 1);
        assert_eq!(s.materials[0].emission, Rgb::new(1.0, 2.0, 3.0));
        assert_eq!(s.material_info[0].illum, 8);
        assert_eq!(
            s.materials[0].surface,
            bsdf_for(8, Rgb::ZERO, Rgb::ZERO, 4.0),
            "Kd and Ks default to 0, the ignored Ka is not checked"
        );
    }

    #[test]
    fn illum_selects_the_model_and_its_keys() {
        let mtl = "newmtl light\nKd 0.5 0.5 0.5\nKs 0.9 0.8 0.7\nNs 20\nNi 1.5\nPr 0.5\nTf 0.9 1 1\nillum ";
        let surface =
            |illum: &str| parse(QUAD, &format!("{mtl}{illum}\n")).unwrap().materials[0].surface;
        let (kd, ks) = (Rgb::splat(0.5), Rgb::new(0.9, 0.8, 0.7));
        assert_eq!(surface("7"), Material::diffuse(kd).surface);
        assert_eq!(surface("8"), Material::mixture(kd, ks, 20.0).surface);
        assert_eq!(
            surface("3"),
            Material::phong(kd, ks, 20.0).surface,
            "3 is Phong"
        );
        assert_eq!(surface("0"), Material::phong(kd, ks, 20.0).surface);
        // Conductor: Ks and alpha = Pr²; Kd, Ns, Ni and Tf are not applied.
        assert_eq!(surface("5"), Material::conductor(ks, 0.25).surface);
        // Dielectric: Ni, Tf and alpha = Pr²; Kd, Ks, Ns are not applied.
        assert_eq!(
            surface("6"),
            Material::dielectric(1.5, Rgb::new(0.9, 1.0, 1.0), 0.25).surface
        );
    }

    #[test]
    fn conductor_and_dielectric_defaults() {
        // No Pr: a perfect mirror; no Ni: IOR 1 with a warning; no Tf: 1 1 1.
        let s = parse(QUAD, "newmtl light\nKs 1 1 1\nillum 5\n").unwrap();
        assert_eq!(
            s.materials[0].surface,
            Material::conductor(Rgb::ONE, 0.0).surface
        );
        assert!(s.warnings.is_empty(), "{:?}", s.warnings);
        let s = parse(QUAD, "newmtl light\nillum 6\n").unwrap();
        assert_eq!(
            s.materials[0].surface,
            Material::dielectric(1.0, Rgb::ONE, 0.0).surface
        );
        assert_eq!(
            s.warnings,
            ["material 'light': illum 6 (dielectric) without Ni: its index of refraction is tinyobj's default 1, the air's, so the glass is invisible"]
        );
        let s = parse(QUAD, "newmtl light\nNi 1\nillum 6\n").unwrap();
        assert_eq!(s.warnings.len(), 1, "{:?}", s.warnings);
        assert!(s.warnings[0].contains("with Ni 1"), "{:?}", s.warnings);
        // Ni on a material that is not glass is accepted and not applied, without a warning.
        let s = parse(QUAD, "newmtl light\nNi 1.45\nillum 7\n").unwrap();
        assert!(s.warnings.is_empty(), "{:?}", s.warnings);
        assert_eq!(
            bsdf_for(5, Rgb::ONE, Rgb::splat(0.5), 3.0),
            Material::conductor(Rgb::splat(0.5), 0.0).surface
        );
        assert_eq!(
            bsdf_for(6, Rgb::ONE, Rgb::ONE, 3.0),
            Material::dielectric(1.0, Rgb::ONE, 0.0).surface
        );
    }

    #[test]
    fn ni_pr_tf_are_checked() {
        let e = |mtl: &str| parse(QUAD, mtl).unwrap_err().to_string();
        let at = "m/quad.mtl: line 2: material 'light': ";
        for (line, msg) in [
            ("Ni 0", "Ni = 0 must be finite and > 0 (the index of refraction relative to air)"),
            ("Ni -1.5", "Ni = -1.5 must be finite and > 0 (the index of refraction relative to air)"),
            ("Ni inf", "Ni = inf must be finite and > 0 (the index of refraction relative to air)"),
            ("Ni glass", "Ni value 'glass' is not a number"),
            ("Ni 1.5 1.5", "Ni must be one number, found '1.5 1.5'"),
            ("Pr 1.5", "Pr = 1.5 must be a roughness in [0, 1]"),
            ("Pr -0.1", "Pr = -0.1 must be a roughness in [0, 1]"),
            ("Pr nan", "Pr = NaN must be a roughness in [0, 1]"),
            ("Pr", "Pr must be one number, found ''"),
            ("Tf 1 1", "Tf must have 3 numbers (r g b), found 2"),
            ("Tf 1 -1 1", "Tf = [1, -1, 1] must be finite and non-negative"),
            ("Tf 1 x 1", "Tf value 'x' is not a number"),
            ("Tf spectral glass.rfl 1.0", "Tf spectral (a spectral curve file) is not supported; give the transmission filter as Tf r g b"),
            ("Tf xyz 1 1 1", "Tf xyz (CIE XYZ) is not supported; give the transmission filter as Tf r g b"),
        ] {
            assert_eq!(e(&format!("newmtl light\n{line}\nillum 6\n")), format!("{at}{msg}"), "{line}");
        }
        assert_eq!(
            e("newmtl light\nillum 11\n"),
            "m/quad.mtl: line 2: material 'light': illum 11 is not an MTL illumination model (0 to 10; ember uses 5 conductor, 6 dielectric, 7 diffuse, 8 mixture, others Phong)"
        );
    }

    #[test]
    fn mtllib_named_twice_is_read_once() {
        let reads = Cell::new(0);
        let files = |p: &Path| {
            reads.set(reads.get() + 1);
            (p.extension()? == "mtl").then(|| b"newmtl light\nKe 1 1 1\n".to_vec())
        };
        let obj = QUAD.replace(
            "o light",
            "mtllib ./quad.mtl\nmtllib ../m/quad.mtl\no light",
        );
        let s = SceneData::parse_obj(Path::new("m/quad.obj"), obj.as_bytes(), &files).unwrap();
        // quad.mtl and ./quad.mtl are one path (read once); ../m/quad.mtl is another spelling
        // of the same file, read again (it adds a second material named light).
        assert_eq!(reads.get(), 2);
        assert_eq!(s.materials.len(), 2);
        assert_eq!(s.mtl_files.len(), 2);
    }

    #[test]
    fn tobj_errors_name_the_line() {
        let e = parse("v 0 0 0\nusemtl\n", "").unwrap_err().to_string();
        assert_eq!(
            e,
            "m/quad.obj: line 2: cannot load OBJ: material parse error"
        );
        let e = parse("v 0 0 0 0\n", "").unwrap_err().to_string();
        assert_eq!(
            e,
            "m/quad.obj: line 1: cannot load OBJ: scaling (w) by zero"
        );
    }

    #[test]
    fn names_in_messages_stay_on_one_line() {
        let mtl = "newmtl a\u{1b}b\rc\nKd -1 0 0\n";
        let obj = QUAD.replace("usemtl light", "usemtl a\u{1b}b\rc");
        let e = parse(&obj, mtl).unwrap_err().to_string();
        assert_eq!(
            e,
            "m/quad.mtl: line 2: material 'a\\u{1b}b\\rc': Kd = [-1, 0, 0] must be finite and non-negative"
        );
        assert_eq!(
            quote(&"x".repeat(100)),
            format!("{}…", "x".repeat(QUOTE_MAX))
        );
    }
}
