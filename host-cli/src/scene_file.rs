//! The TinyRender TOML scene file (FORMAT.md §2): four mandatory tables, defaults for every key.
//!
//! Type rules: a number key accepts a TOML integer or float (as cpptoml does); an integer or
//! boolean key must have exactly that type. TinyRender silently falls back to the default on a
//! wrong type (so `maxDepth = 4.0` meant −1); ember rejects it with an error naming the key,
//! because a silently ignored setting is worse than a refused file. Unknown keys are ignored.

use crate::error::{Error, Result};
use crate::mesh::quote;
use ember_kernel::integrator::bdpt::check_depth;
use ember_kernel::integrator::{Integrator, MisHeuristic};
use std::path::{Path, PathBuf};
use toml::{Table, Value};

#[derive(Clone, Debug, PartialEq)]
pub struct CameraDesc {
    pub eye: [f32; 3],
    pub at: [f32; 3],
    pub up: [f32; 3],
    /// Full vertical field of view in degrees.
    pub fov: f32,
}

/// Settings of the `path` integrator and of the `gi` bake.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PathDesc {
    pub max_depth: i32,
    pub rr_depth: i32,
    pub rr_prob: f32,
}

#[derive(Clone, Debug, PartialEq)]
pub enum RendererDesc {
    /// An offline integrator (`realtime = false`): `type = "path"` (TinyRender's; `isExplicit`
    /// chooses next-event estimation or not), `"mis"`, `"lighttracer"` or `"bdpt"`
    /// (`misHeuristic = "power"` or `"balance"`).
    Path {
        integrator: Integrator,
        path: PathDesc,
        spp: u32,
    },
    /// `realtime = true, type = "gi"`: bake per-vertex radiance, draw it rasterised.
    Gi {
        path: PathDesc,
        samples_by_vertex: u32,
    },
}

#[derive(Clone, Debug, PartialEq)]
pub struct SceneFile {
    /// The TOML file itself.
    pub path: PathBuf,
    /// The OBJ, resolved against the TOML's directory.
    pub objfile: PathBuf,
    pub camera: CameraDesc,
    pub width: u32,
    pub height: u32,
    pub renderer: RendererDesc,
}

/// The renderer types ember reads, for error messages.
const SUPPORTED_TYPES: &str =
    "\"path\", \"mis\", \"lighttracer\" and \"bdpt\" (realtime = false), \"gi\" (realtime = true)";

/// Largest film side accepted, so that a typo cannot ask for terabytes of image.
pub const MAX_FILM_SIDE: u32 = 32_768;

impl SceneFile {
    /// Reads and checks a scene file.
    ///
    /// # Errors
    /// Unreadable file, TOML syntax error (with line and column), missing table or key, wrong
    /// type or out-of-range value, unknown or unsupported renderer type.
    pub fn load(path: &Path) -> Result<Self> {
        let bytes = std::fs::read(path)
            .map_err(|e| Error::in_file(path, format!("cannot read scene file: {e}")))?;
        Self::parse_bytes(path, &bytes)
    }

    /// Parses the bytes of a scene file (what [`SceneFile::load`] reads), refusing text that
    /// is not UTF-8 with the line of the first bad byte.
    ///
    /// # Errors
    /// As [`SceneFile::load`].
    pub fn parse_bytes(path: &Path, bytes: &[u8]) -> Result<Self> {
        let text = std::str::from_utf8(bytes).map_err(|e| {
            let (line, col) = line_col(bytes, e.valid_up_to());
            Error::in_file(
                path,
                format!("not UTF-8 text (invalid byte at line {line}, column {col})"),
            )
        })?;
        Self::parse(path, text)
    }

    /// Parses scene text; `path` names the file in errors and anchors the relative `objfile`.
    ///
    /// # Errors
    /// As [`SceneFile::load`].
    pub fn parse(path: &Path, text: &str) -> Result<Self> {
        let root: Table = text.parse().map_err(|e: toml::de::Error| {
            let at = e
                .span()
                .map(|s| {
                    let (line, col) = line_col(text.as_bytes(), s.start);
                    format!(" at line {line}, column {col}")
                })
                .unwrap_or_default();
            // One line, whatever the parser's message holds.
            let message = e.message().trim_end().replace('\n', "; ");
            Error::in_file(path, format!("TOML syntax error{at}: {message}"))
        })?;
        let keys = Keys { path, root: &root };
        let input = keys.table("input")?;
        let camera_table = keys.table("camera")?;
        let film = keys.table("film")?;
        let renderer = keys.table("renderer")?;

        let objfile = match input.get("objfile") {
            Some(Value::String(s)) => s.clone(),
            Some(v) => return Err(keys.wrong_type("input", "objfile", "a string", v)),
            None => return Err(Error::in_file(path, "missing key [input].objfile")),
        };
        let dir = path.parent().unwrap_or(Path::new("."));
        let objfile = dir.join(objfile);

        let eye = keys.vec3(camera_table, "camera", "eye", [1.0, 1.0, 0.0])?;
        let at = keys.vec3(camera_table, "camera", "at", [0.0, 0.0, 0.0])?;
        let up = keys.vec3(camera_table, "camera", "up", [0.0, 1.0, 0.0])?;
        // Kept as written for messages (the f32 may round it to 0 or 180).
        let fov = keys.number(camera_table, "camera", "fov", 30.0)?;
        let camera = CameraDesc {
            eye,
            at,
            up,
            fov: fov as f32,
        };
        if !(camera.fov > 0.0 && camera.fov < 180.0) {
            return Err(Error::in_file(
                path,
                format!(
                    "[camera].fov = {} is out of range (0, 180) degrees",
                    num(fov)
                ),
            ));
        }
        // The camera's tan(fov/2) must not underflow (found by tests/tests/fuzz_loaders.rs:
        // fov = 1e-40 gave a camera whose every ray had the same direction).
        if !(camera.fov.to_radians() * 0.5).is_normal() {
            return Err(Error::in_file(
                path,
                format!(
                    "[camera].fov = {} degrees is too small for f32 (the view would be a point)",
                    num(fov)
                ),
            ));
        }
        let eye = glam::Vec3::from_array(camera.eye);
        let at = glam::Vec3::from_array(camera.at);
        let up = glam::Vec3::from_array(camera.up);
        // As Camera::look_at computes its frame: both directions must normalise to finite
        // vectors (this also refuses points so far apart that at - eye overflows f32).
        let frame = (at - eye)
            .try_normalize()
            .and_then(|forward| forward.cross(up).try_normalize());
        if frame.is_none() {
            return Err(Error::in_file(
                path,
                "[camera]: eye, at and up do not define a view (eye == at, up parallel to the view direction, or coordinates too large)",
            ));
        }

        let width = keys.film_side(film, "width", 768)?;
        let height = keys.film_side(film, "height", 576)?;

        let realtime = keys.boolean(renderer, "renderer", "realtime", false)?;
        let kind = match renderer.get("type") {
            Some(Value::String(s)) => s.clone(),
            Some(v) => return Err(keys.wrong_type("renderer", "type", "a string", v)),
            None => "normal".to_string(),
        };
        let renderer = match (realtime, kind.as_str()) {
            (false, kind @ ("path" | "mis" | "lighttracer" | "bdpt")) => {
                let integrator = match kind {
                    "path" => {
                        if keys.boolean(renderer, "renderer", "isExplicit", true)? {
                            Integrator::PathExplicit
                        } else {
                            Integrator::PathImplicit
                        }
                    }
                    "mis" => Integrator::PathMis,
                    "lighttracer" => Integrator::LightTracing,
                    _ => Integrator::Bdpt(keys.heuristic(renderer)?),
                };
                let path_desc = keys.path_desc(renderer, -1, 0.95)?;
                if let Integrator::Bdpt(_) = integrator {
                    check_depth(path_desc.max_depth).map_err(|e| {
                        Error::in_file(path, format!("[renderer].maxDepth: {e}"))
                    })?;
                }
                RendererDesc::Path {
                    integrator,
                    path: path_desc,
                    spp: keys.positive(renderer, "spp", 1)?,
                }
            }
            (true, "gi") => RendererDesc::Gi {
                // TinyRender's default rrProb for gi is written 9.95f, a typo for 0.95.
                path: keys.path_desc(renderer, 5, 0.95)?,
                samples_by_vertex: keys.positive(renderer, "samplesByVertex", 100)?,
            },
            (false, "normal" | "simple" | "ao" | "ro" | "direct" | "polygonal")
            | (true, "normal" | "direct" | "ssao" | "polygonal") => {
                return Err(Error::in_file(
                    path,
                    format!(
                        "[renderer].type = \"{}\" (realtime = {realtime}) is a TinyRender pass that ember does not implement; supported: {SUPPORTED_TYPES}",
                        quote(&kind)
                    ),
                ))
            }
            _ => {
                return Err(Error::in_file(
                    path,
                    format!(
                        "[renderer].type = \"{}\" is not a renderer type (realtime = {realtime}); valid types: {SUPPORTED_TYPES}",
                        quote(&kind)
                    ),
                ))
            }
        };
        Ok(Self {
            path: path.to_path_buf(),
            objfile,
            camera,
            width,
            height,
            renderer,
        })
    }
}

/// 1-based line and column (in characters) of byte `offset`; any offset is accepted, even
/// one inside a character or past the end.
fn line_col(text: &[u8], offset: usize) -> (usize, usize) {
    let before = &text[..offset.min(text.len())];
    let line = before.iter().filter(|&&b| b == b'\n').count() + 1;
    let start = before
        .iter()
        .rposition(|&b| b == b'\n')
        .map_or(0, |i| i + 1);
    // Characters are the bytes that do not continue a UTF-8 sequence.
    let col = before[start..]
        .iter()
        .filter(|&&b| b & 0xC0 != 0x80)
        .count()
        + 1;
    (line, col)
}

/// A number for an error message: as Rust prints it, but in exponent form when that would
/// be very long (1e-40 rather than 0.000…0001).
fn num(v: f64) -> String {
    if v != 0.0 && v.is_finite() && !(1e-4..1e15).contains(&v.abs()) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}

/// A TOML value for an error message: on one line and cut after a few dozen characters.
fn show(v: &Value) -> String {
    quote(&v.to_string())
}

fn type_name(v: &Value) -> &'static str {
    match v {
        Value::String(_) => "a string",
        Value::Integer(_) => "an integer",
        Value::Float(_) => "a float",
        Value::Boolean(_) => "a boolean",
        Value::Datetime(_) => "a date",
        Value::Array(_) => "an array",
        Value::Table(_) => "a table",
    }
}

struct Keys<'a> {
    path: &'a Path,
    root: &'a Table,
}

impl<'a> Keys<'a> {
    fn table(&self, name: &str) -> Result<&'a Table> {
        match self.root.get(name) {
            Some(Value::Table(t)) => Ok(t),
            Some(v) => Err(Error::in_file(
                self.path,
                format!("[{name}] must be a table, found {}", type_name(v)),
            )),
            None => Err(Error::in_file(
                self.path,
                format!("missing table [{name}] (TinyRender requires [input], [camera], [film] and [renderer])"),
            )),
        }
    }

    fn wrong_type(&self, table: &str, key: &str, want: &str, v: &Value) -> Error {
        Error::in_file(
            self.path,
            format!(
                "[{table}].{key} must be {want}, found {} ({})",
                type_name(v),
                show(v)
            ),
        )
    }

    fn number(&self, t: &Table, table: &str, key: &str, default: f64) -> Result<f64> {
        let v = match t.get(key) {
            None => return Ok(default),
            Some(Value::Float(f)) => *f,
            Some(Value::Integer(i)) => *i as f64,
            Some(v) => return Err(self.wrong_type(table, key, "a number", v)),
        };
        if !v.is_finite() {
            return Err(Error::in_file(
                self.path,
                format!("[{table}].{key} = {v} is not a finite number"),
            ));
        }
        Ok(v)
    }

    fn integer(&self, t: &Table, table: &str, key: &str, default: i64) -> Result<i64> {
        match t.get(key) {
            None => Ok(default),
            Some(Value::Integer(i)) => Ok(*i),
            Some(v) => Err(self.wrong_type(table, key, "an integer", v)),
        }
    }

    fn boolean(&self, t: &Table, table: &str, key: &str, default: bool) -> Result<bool> {
        match t.get(key) {
            None => Ok(default),
            Some(Value::Boolean(b)) => Ok(*b),
            Some(v) => Err(self.wrong_type(table, key, "a boolean", v)),
        }
    }

    /// `[renderer].misHeuristic` of BDPT: `"power"` (the default) or `"balance"`.
    fn heuristic(&self, t: &Table) -> Result<MisHeuristic> {
        match t.get("misHeuristic") {
            None => Ok(MisHeuristic::Power),
            Some(Value::String(s)) if s == "power" => Ok(MisHeuristic::Power),
            Some(Value::String(s)) if s == "balance" => Ok(MisHeuristic::Balance),
            Some(Value::String(s)) => Err(Error::in_file(
                self.path,
                format!(
                    "[renderer].misHeuristic = \"{}\" is not a heuristic; valid: \"power\" and \"balance\"",
                    quote(s)
                ),
            )),
            Some(v) => Err(self.wrong_type("renderer", "misHeuristic", "a string", v)),
        }
    }

    fn vec3(&self, t: &Table, table: &str, key: &str, default: [f32; 3]) -> Result<[f32; 3]> {
        let Some(v) = t.get(key) else {
            return Ok(default);
        };
        let Value::Array(a) = v else {
            return Err(self.wrong_type(table, key, "an array of 3 numbers", v));
        };
        if a.len() != 3 {
            return Err(Error::in_file(
                self.path,
                format!("[{table}].{key} must have 3 numbers, found {}", a.len()),
            ));
        }
        let mut out = [0.0f32; 3];
        for (o, x) in out.iter_mut().zip(a) {
            *o = match x {
                Value::Float(f) if f.is_finite() => *f as f32,
                Value::Integer(i) => *i as f32,
                _ => {
                    return Err(Error::in_file(
                        self.path,
                        format!(
                            "[{table}].{key} must hold 3 finite numbers, found {}",
                            show(v)
                        ),
                    ))
                }
            };
        }
        Ok(out)
    }

    fn film_side(&self, t: &Table, key: &str, default: i64) -> Result<u32> {
        let v = self.integer(t, "film", key, default)?;
        if v < 1 || v > i64::from(MAX_FILM_SIDE) {
            return Err(Error::in_file(
                self.path,
                format!("[film].{key} = {v} is out of range 1..={MAX_FILM_SIDE}"),
            ));
        }
        Ok(v as u32)
    }

    fn positive(&self, t: &Table, key: &str, default: i64) -> Result<u32> {
        let v = self.integer(t, "renderer", key, default)?;
        if v < 1 || v > i64::from(u32::MAX) {
            return Err(Error::in_file(
                self.path,
                format!("[renderer].{key} = {v} must be a positive integer"),
            ));
        }
        Ok(v as u32)
    }

    fn path_desc(&self, t: &Table, default_depth: i64, default_rr_prob: f64) -> Result<PathDesc> {
        let max_depth = self.integer(t, "renderer", "maxDepth", default_depth)?;
        let rr_depth = self.integer(t, "renderer", "rrDepth", 5)?;
        let rr_prob = self.number(t, "renderer", "rrProb", default_rr_prob)?;
        if max_depth < -1 || max_depth > i64::from(i32::MAX) {
            return Err(Error::in_file(
                self.path,
                format!("[renderer].maxDepth = {max_depth} must be -1 (unbounded) or a bounce count >= 0"),
            ));
        }
        if rr_depth < 0 || rr_depth > i64::from(i32::MAX) {
            return Err(Error::in_file(
                self.path,
                format!("[renderer].rrDepth = {rr_depth} must be >= 0"),
            ));
        }
        if !(rr_prob > 0.0 && rr_prob <= 1.0) {
            return Err(Error::in_file(
                self.path,
                format!(
                    "[renderer].rrProb = {} must be a probability in (0, 1]",
                    num(rr_prob)
                ),
            ));
        }
        Ok(PathDesc {
            max_depth: max_depth as i32,
            rr_depth: rr_depth as i32,
            rr_prob: rr_prob as f32,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn line_col_accepts_any_offset() {
        let text = "ab\né😀x".as_bytes();
        assert_eq!(line_col(text, 0), (1, 1));
        assert_eq!(line_col(text, 3), (2, 1));
        // Inside the 4-byte emoji (bytes 5..9): still its column.
        assert_eq!(line_col(text, 6), (2, 3));
        assert_eq!(line_col(text, 9), (2, 3));
        assert_eq!(line_col(text, 1000), (2, 4));
    }

    #[test]
    fn values_in_messages_stay_on_one_line() {
        let toml = "[input]\nobjfile = \"a.obj\"\n[camera]\n[film]\n[renderer]\ntype = \"\"\"x\ny\"\"\"\nspp = { a = 1, b = \"\\n\" }\n";
        let e = SceneFile::parse(Path::new("s.toml"), toml).unwrap_err();
        assert_eq!(
            e.to_string(),
            "s.toml: [renderer].type = \"x\\ny\" is not a renderer type (realtime = false); valid types: \"path\", \"mis\", \"lighttracer\" and \"bdpt\" (realtime = false), \"gi\" (realtime = true)"
        );
        let toml = toml.replace("type = \"\"\"x\ny\"\"\"", "type = \"path\"");
        let e = SceneFile::parse(Path::new("s.toml"), &toml).unwrap_err();
        assert!(!e.message.contains('\n'), "{e}");
        assert!(
            e.message
                .starts_with("[renderer].spp must be an integer, found a table ("),
            "{e}"
        );
    }
}
