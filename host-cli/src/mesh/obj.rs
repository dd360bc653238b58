//! Reading OBJ files: a pass that checks what tobj does not (with line numbers), then tobj
//! (triangulated, one index per vertex), with every `mtllib` parsed by [`super::mtl`].

use super::files::FileSource;
use super::mtl::{parse_mtl, MtlMaterial};
use super::quote::quote;
use crate::error::{Error, Result};
use std::path::{Path, PathBuf};

/// Most materials an OBJ may load from all its MTL libraries together. Real scenes have tens;
/// the cap bounds the memory of an OBJ that names the same large MTL under many spellings.
pub const MAX_MATERIALS: usize = 65_536;

/// An OBJ as tobj read it, with the MTL libraries it loaded.
pub(crate) struct ObjFile {
    /// The objects (`o`/`g` groups split by material), triangulated.
    pub(crate) models: Vec<tobj::Model>,
    /// Every MTL library loaded, in `mtllib` order, with its materials; tobj's material ids
    /// index them in that order.
    pub(crate) libraries: Vec<(PathBuf, Vec<MtlMaterial>)>,
}

/// Reads OBJ bytes: checks the lines, then parses them with tobj, the `mtllib` files
/// resolved against `path`'s directory and read from `files`. `path` names the OBJ in
/// errors.
///
/// # Errors
/// Malformed OBJ (with the line), face indices out of range, non-finite coordinates, missing
/// or unreadable MTL files, invalid MTL values, more than [`MAX_MATERIALS`] materials.
pub(crate) fn read_obj(path: &Path, obj: &[u8], files: &dyn FileSource) -> Result<ObjFile> {
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
    Ok(ObjFile {
        models,
        libraries: loads.libraries,
    })
}

/// The MTL libraries parsed while tobj reads the OBJ, and the first failure (tobj itself only
/// keeps a `LoadError`).
#[derive(Default)]
struct MtlLoads {
    /// Every library loaded, in `mtllib` order, with its materials.
    libraries: Vec<(PathBuf, Vec<MtlMaterial>)>,
    /// The paths of `libraries`.
    seen: std::collections::HashSet<PathBuf>,
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

#[cfg(test)]
mod tests {
    use crate::mesh::{parse_for_test, SceneData, TEST_QUAD};
    use std::cell::Cell;
    use std::path::Path;

    fn parse(obj: &str, mtl: &str) -> crate::Result<SceneData> {
        parse_for_test(obj, mtl, |_| None)
    }

    #[test]
    fn mtllib_named_twice_is_read_once() {
        let reads = Cell::new(0);
        let files = |p: &Path| {
            reads.set(reads.get() + 1);
            (p.extension()? == "mtl").then(|| b"newmtl light\nKe 1 1 1\n".to_vec())
        };
        let obj = TEST_QUAD.replace(
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
}
