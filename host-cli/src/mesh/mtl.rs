//! MTL libraries (FORMAT.md §4): keys, values, texture map options and the scattering model
//! each material selects.

use super::files::FileSource;
use super::quote::{escape, quote};
use crate::error::{Error, Result};
use ember_kernel::bsdf::Phong;
use ember_kernel::material::{PhongParams, Reflectance, Surface};
use ember_kernel::Rgb;
use glam::Vec2;
use std::path::{Path, PathBuf};

/// The surface for an MTL `illum` value with constant `Kd`, `Ks`, `Ns` and the other keys at
/// their defaults (`Pr 0`, `Ni 1`, `Tf 1 1 1`): 7 diffuse, 8 diffuse+Phong mixture,
/// 5 conductor (a perfect mirror of reflectance `Ks`), 6 dielectric, anything else Phong
/// (README.md, "Materials (MTL)").
#[must_use]
pub fn bsdf_for(illum: u8, kd: Rgb, ks: Rgb, ns: f32) -> Surface {
    let mut m = MtlMaterial::new(String::new());
    (m.illum, m.kd, m.ks, m.ns) = (illum, kd, ks, ns);
    m.surface(Param::constant(kd), Param::constant(ks))
}

/// The scattering model an `illum` value selects.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Model {
    Diffuse,
    Phong,
    Mixture,
    Conductor,
    Dielectric,
}

impl Model {
    /// 7 diffuse, 8 mixture, 5 conductor, 6 dielectric, anything else Phong (3 included, as
    /// the official `sphere_phong.mtl` needs).
    #[must_use]
    pub fn of_illum(illum: u8) -> Self {
        match illum {
            7 => Self::Diffuse,
            8 => Self::Mixture,
            5 => Self::Conductor,
            6 => Self::Dielectric,
            _ => Self::Phong,
        }
    }

    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Diffuse => "diffuse",
            Self::Phong => "Phong",
            Self::Mixture => "mixture",
            Self::Conductor => "conductor",
            Self::Dielectric => "dielectric",
        }
    }

    /// Whether the model reads the reflectance `Kd` (and so `map_Kd`).
    #[must_use]
    pub fn uses_kd(self) -> bool {
        matches!(self, Self::Diffuse | Self::Phong | Self::Mixture)
    }

    /// Whether the model reads the reflectance `Ks` (and so `map_Ks`).
    #[must_use]
    pub fn uses_ks(self) -> bool {
        matches!(self, Self::Phong | Self::Mixture | Self::Conductor)
    }
}

/// A reflectance parameter as the assembly resolved it: a constant or a texture, with the
/// per-channel maximum and average that Phong's energy clamp and lobe weight are derived from
/// (for a constant, the colour itself).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Param {
    pub(crate) reflectance: Reflectance,
    pub(crate) max: Rgb,
    pub(crate) avg: Rgb,
}

impl Param {
    pub(crate) fn constant(value: Rgb) -> Self {
        Self {
            reflectance: Reflectance::constant(value),
            max: value,
            avg: value,
        }
    }
}

/// A texture map line (`map_Kd`/`map_Ks`): the file found for it and its options.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct TextureMap {
    /// The line of the MTL file, for errors.
    pub(crate) line: usize,
    /// The file read: the name as written, resolved against the OBJ's directory, or the same
    /// with the extension `.ppm` (TinyRender's rule) when only that exists.
    pub(crate) file: PathBuf,
    pub(crate) options: MapOptions,
}

/// The options of a texture map line that ember applies (`-s`, `-o`), and the names of those
/// it accepts and ignores.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct MapOptions {
    /// `-s u v w`: texture coordinates are multiplied by (u, v) (default 1 1).
    pub(crate) scale: Vec2,
    /// `-o u v w`: then (u, v) is added (default 0 0).
    pub(crate) offset: Vec2,
    /// Options given that ember does not apply, in order, each once.
    pub(crate) ignored: Vec<&'static str>,
}

impl Default for MapOptions {
    fn default() -> Self {
        Self {
            scale: Vec2::ONE,
            offset: Vec2::ZERO,
            ignored: Vec::new(),
        }
    }
}

/// How many arguments an MTL map option takes.
#[derive(Clone, Copy)]
enum OptionArgs {
    /// Between `min` and `max` numbers (`-s u [v [w]]`).
    Numbers {
        min: usize,
        max: usize,
        what: &'static str,
    },
    /// `on` or `off`.
    OnOff,
    /// One of the given words.
    OneOf(&'static [&'static str]),
    /// Any one word.
    Word,
}

/// The options of the MTL specification's texture maps (`map_*`, `bump`, `refl`).
fn map_option(word: &str) -> Option<(&'static str, OptionArgs)> {
    use OptionArgs::{Numbers, OnOff, OneOf, Word};
    let uvw = Numbers {
        min: 1,
        max: 3,
        what: "1 to 3 numbers (u [v [w]])",
    };
    let one = Numbers {
        min: 1,
        max: 1,
        what: "a number",
    };
    Some(match word {
        "-s" => ("-s", uvw),
        "-o" => ("-o", uvw),
        "-t" => ("-t", uvw),
        "-bm" => ("-bm", one),
        "-boost" => ("-boost", one),
        "-texres" => ("-texres", one),
        "-mm" => (
            "-mm",
            Numbers {
                min: 2,
                max: 2,
                what: "2 numbers (base gain)",
            },
        ),
        "-blendu" => ("-blendu", OnOff),
        "-blendv" => ("-blendv", OnOff),
        "-cc" => ("-cc", OnOff),
        "-clamp" => ("-clamp", OnOff),
        "-imfchan" => ("-imfchan", OneOf(&["r", "g", "b", "m", "l", "z"])),
        "-type" => ("-type", Word),
        _ => return None,
    })
}

/// The next word of `s`, consumed (`s` starts with a word or is empty).
fn next_word<'a>(s: &mut &'a str) -> Option<&'a str> {
    let w = s.split_whitespace().next()?;
    *s = s[w.len()..].trim_start();
    Some(w)
}

/// Splits the text after `map_Kd`/`map_Ks` into its options and the file name, which is what
/// remains (it may contain spaces). A word that starts with `-` but is no MTL option begins
/// the file name. Errors are the message after the key, e.g. `option -s needs ...`.
pub(crate) fn parse_map(rest: &str) -> std::result::Result<(&str, MapOptions), String> {
    let mut options = MapOptions::default();
    let mut s = rest.trim_start();
    while let Some((word, (name, args))) = s
        .split_whitespace()
        .next()
        .and_then(|w| Some((w, map_option(w)?)))
    {
        s = s[word.len()..].trim_start();
        match args {
            OptionArgs::Numbers { min, max, what } => {
                let mut values = [0.0f32; 3];
                let mut count = 0;
                while count < max {
                    let Some(w) = s.split_whitespace().next() else {
                        break;
                    };
                    let Ok(v) = w.parse::<f32>() else { break };
                    if !v.is_finite() {
                        return Err(format!(
                            "option {name}: '{}' is not a finite number",
                            quote(w)
                        ));
                    }
                    next_word(&mut s);
                    values[count] = v;
                    count += 1;
                }
                if count < min {
                    let found = s.split_whitespace().next().unwrap_or("");
                    return Err(format!(
                        "option {name} needs {what}, found '{}'",
                        quote(found)
                    ));
                }
                match name {
                    // v and w default to u's defaults: 1 for a scale, 0 for an offset.
                    "-s" => {
                        options.scale =
                            Vec2::new(values[0], if count > 1 { values[1] } else { 1.0 });
                    }
                    "-o" => options.offset = Vec2::new(values[0], values[1]),
                    _ => {}
                }
            }
            OptionArgs::OnOff => match next_word(&mut s) {
                Some("on" | "off") => {}
                w => {
                    return Err(format!(
                        "option {name} must be on or off, found '{}'",
                        quote(w.unwrap_or(""))
                    ))
                }
            },
            OptionArgs::OneOf(allowed) => match next_word(&mut s) {
                Some(w) if allowed.contains(&w) => {}
                w => {
                    return Err(format!(
                        "option {name} must be one of {}, found '{}'",
                        allowed.join(" "),
                        quote(w.unwrap_or(""))
                    ))
                }
            },
            OptionArgs::Word => {
                if next_word(&mut s).is_none() {
                    return Err(format!("option {name} needs a value, found ''"));
                }
            }
        }
        if !matches!(name, "-s" | "-o") && !options.ignored.contains(&name) {
            options.ignored.push(name);
        }
    }
    let file = s.trim();
    if file.is_empty() {
        return Err("without a file name".into());
    }
    Ok((file, options))
}

/// One material of an MTL file, checked.
#[derive(Clone, Debug)]
pub(crate) struct MtlMaterial {
    pub(crate) name: String,
    pub(crate) kd: Rgb,
    pub(crate) ks: Rgb,
    pub(crate) ke: Rgb,
    pub(crate) ns: f32,
    /// `Ni`, the index of refraction relative to air (`None`: not given, tinyobj's 1).
    pub(crate) ni: Option<f32>,
    /// `Pr`, the roughness in [0, 1] (0: smooth).
    pub(crate) pr: f32,
    /// `Tf`, the transmission filter.
    pub(crate) tf: Rgb,
    pub(crate) illum: u8,
    pub(crate) map_kd: Option<TextureMap>,
    pub(crate) map_ks: Option<TextureMap>,
}

impl MtlMaterial {
    /// tinyobj's defaults for keys the MTL does not give: Kd = Ks = Ke = 0, Ns = 1, Ni = 1,
    /// Pr = 0, Tf = 1 1 1, illum 0, no maps.
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
            map_kd: None,
            map_ks: None,
        }
    }

    #[must_use]
    pub(crate) fn model(&self) -> Model {
        Model::of_illum(self.illum)
    }

    /// The microfacet roughness of conductors and dielectrics: `alpha = Pr²` (`Pr` is the
    /// perceptual roughness of the MTL PBR extension; 0 is smooth).
    fn alpha(&self) -> f32 {
        self.pr * self.pr
    }

    /// The texture maps the model applies: `map_Kd` where it reads `Kd`, `map_Ks` where it
    /// reads `Ks` (`None` for a map not given or not applied).
    pub(crate) fn applied_maps(&self) -> [Option<&TextureMap>; 2] {
        let model = self.model();
        [
            self.map_kd.as_ref().filter(|_| model.uses_kd()),
            self.map_ks.as_ref().filter(|_| model.uses_ks()),
        ]
    }

    /// The scattering model `illum` selects, with the keys that model uses (the others are
    /// accepted and not applied): 7 diffuse (`Kd`), 8 mixture and anything else but 5 and 6
    /// Phong (`Kd`, `Ks`, `Ns`), 5 conductor (`Ks`, `Pr`), 6 dielectric (`Ni`, `Tf`, `Pr`).
    /// `kd` and `ks` are the reflectances as resolved (constants or textures). Phong's energy
    /// clamp and lobe weight come from their maxima and averages, as TinyRender derives them
    /// ([`Phong::weights`]); for constants this is [`PhongParams::constant`].
    pub(crate) fn surface(&self, kd: Param, ks: Param) -> Surface {
        let phong = || {
            let (scale, specular_weight) = Phong::weights(kd.max, ks.max, kd.avg, ks.avg);
            PhongParams {
                kd: kd.reflectance,
                ks: ks.reflectance,
                exponent: self.ns.max(0.0),
                scale,
                specular_weight,
            }
        };
        match self.model() {
            Model::Diffuse => Surface::Diffuse { kd: kd.reflectance },
            Model::Mixture => Surface::Mixture(phong()),
            Model::Phong => Surface::Phong(phong()),
            Model::Conductor => Surface::Conductor {
                ks: ks.reflectance,
                alpha: self.alpha(),
            },
            Model::Dielectric => Surface::Dielectric {
                eta: self.ni.unwrap_or(1.0),
                tf: self.tf,
                alpha: self.alpha(),
            },
        }
    }

    /// Remarks about a material that loads but may not render as meant: glass whose index
    /// of refraction is the air's does not bend or reflect light; a texture map the model
    /// does not read is not loaded.
    pub(crate) fn warnings(&self) -> Vec<String> {
        let name = quote(&self.name);
        let model = self.model();
        let mut out = Vec::new();
        if model == Model::Dielectric {
            match self.ni {
                None => out.push(format!(
                    "material '{name}': illum 6 (dielectric) without Ni: its index of refraction is tinyobj's default 1, the air's, so the glass is invisible"
                )),
                Some(1.0) => out.push(format!(
                    "material '{name}': illum 6 (dielectric) with Ni 1, the air's index of refraction: the glass is invisible"
                )),
                Some(_) => {}
            }
        }
        for (key, map, used) in [
            ("map_Kd", &self.map_kd, model.uses_kd()),
            ("map_Ks", &self.map_ks, model.uses_ks()),
        ] {
            if map.is_some() && !used {
                out.push(format!(
                    "material '{name}': {key} does not apply to illum {} ({}); not loaded",
                    self.illum,
                    model.name()
                ));
            }
        }
        out
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
pub(crate) fn parse_mtl(
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
                // map_Kd / map_Ks: options, then the file name (the rest of the line).
                let (name, options) = parse_map(rest).map_err(|e| err(format!("{key} {e}")))?;
                let written = obj_dir.join(name);
                let ppm = written.with_extension("ppm");
                let file = if files.is_file(&written) {
                    written
                } else if files.is_file(&ppm) {
                    ppm
                } else {
                    return Err(err(format!(
                        "{key} texture {} not found",
                        escape(&written.display().to_string())
                    )));
                };
                let map = Some(TextureMap {
                    line: n,
                    file,
                    options,
                });
                if key == "map_Kd" {
                    m.map_kd = map;
                } else {
                    m.map_ks = map;
                }
            }
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{parse_for_test, SceneData, TEST_QUAD};
    use ember_kernel::scene::Material;

    fn parse(obj: &str, mtl: &str) -> crate::Result<SceneData> {
        parse_for_test(obj, mtl, |_| None)
    }

    #[test]
    fn mtl_values_defaults_and_comments() {
        let mtl = "# c\nnewmtl light\nKe 1 2 3 # warm\nNs 4\nKa 9 9\nillum 8 # mixture\n";
        let s = parse(TEST_QUAD, mtl).unwrap();
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
        let surface = |illum: &str| {
            parse(TEST_QUAD, &format!("{mtl}{illum}\n"))
                .unwrap()
                .materials[0]
                .surface
        };
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
        let s = parse(TEST_QUAD, "newmtl light\nKs 1 1 1\nillum 5\n").unwrap();
        assert_eq!(
            s.materials[0].surface,
            Material::conductor(Rgb::ONE, 0.0).surface
        );
        assert!(s.warnings.is_empty(), "{:?}", s.warnings);
        let s = parse(TEST_QUAD, "newmtl light\nillum 6\n").unwrap();
        assert_eq!(
            s.materials[0].surface,
            Material::dielectric(1.0, Rgb::ONE, 0.0).surface
        );
        assert_eq!(
            s.warnings,
            ["material 'light': illum 6 (dielectric) without Ni: its index of refraction is tinyobj's default 1, the air's, so the glass is invisible"]
        );
        let s = parse(TEST_QUAD, "newmtl light\nNi 1\nillum 6\n").unwrap();
        assert_eq!(s.warnings.len(), 1, "{:?}", s.warnings);
        assert!(s.warnings[0].contains("with Ni 1"), "{:?}", s.warnings);
        // Ni on a material that is not glass is accepted and not applied, without a warning.
        let s = parse(TEST_QUAD, "newmtl light\nNi 1.45\nillum 7\n").unwrap();
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
        let e = |mtl: &str| parse(TEST_QUAD, mtl).unwrap_err().to_string();
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
    fn names_in_messages_stay_on_one_line() {
        let mtl = "newmtl a\u{1b}b\rc\nKd -1 0 0\n";
        let obj = TEST_QUAD.replace("usemtl light", "usemtl a\u{1b}b\rc");
        let e = parse(&obj, mtl).unwrap_err().to_string();
        assert_eq!(
            e,
            "m/quad.mtl: line 2: material 'a\\u{1b}b\\rc': Kd = [-1, 0, 0] must be finite and non-negative"
        );
    }

    #[test]
    fn map_options_are_not_file_names() {
        let (file, o) = parse_map("-s 2 2 1 -o 0.5 0 0 my tex.ppm").unwrap();
        assert_eq!(file, "my tex.ppm");
        assert_eq!(o.scale, Vec2::new(2.0, 2.0));
        assert_eq!(o.offset, Vec2::new(0.5, 0.0));
        assert!(o.ignored.is_empty());
        // v and w are optional: a scale's default 1, an offset's 0.
        let (file, o) = parse_map("-s 3 -o 0.25   wood floor.png ").unwrap();
        assert_eq!(file, "wood floor.png");
        assert_eq!(
            (o.scale, o.offset),
            (Vec2::new(3.0, 1.0), Vec2::new(0.25, 0.0))
        );
        // No options: the identity.
        let (file, o) = parse_map("tex.ppm").unwrap();
        assert_eq!((file, o), ("tex.ppm", MapOptions::default()));
        // Every other option of the MTL specification, with its arguments, is skipped and
        // named once.
        let (file, o) = parse_map(
            "-bm 1 -blendu off -blendv on -boost 2.5 -cc on -clamp off -mm 0 1 -t 1 1 1 -texres 512 -imfchan r -type sphere -bm 2 f.ppm",
        )
        .unwrap();
        assert_eq!(file, "f.ppm");
        assert_eq!(
            o.ignored,
            [
                "-bm", "-blendu", "-blendv", "-boost", "-cc", "-clamp", "-mm", "-t", "-texres",
                "-imfchan", "-type"
            ]
        );
        assert_eq!((o.scale, o.offset), (Vec2::ONE, Vec2::ZERO));
        // A word starting with '-' that is no option begins the file name.
        assert_eq!(parse_map("-s 2 -dash.ppm").unwrap().0, "-dash.ppm");
    }

    #[test]
    fn bad_map_options_are_refused() {
        let e = |rest: &str| parse_map(rest).unwrap_err();
        assert_eq!(
            e("-s tex.ppm"),
            "option -s needs 1 to 3 numbers (u [v [w]]), found 'tex.ppm'"
        );
        assert_eq!(
            e("-o inf 0 tex.ppm"),
            "option -o: 'inf' is not a finite number"
        );
        assert_eq!(
            e("-mm 1 tex.ppm"),
            "option -mm needs 2 numbers (base gain), found 'tex.ppm'"
        );
        assert_eq!(
            e("-clamp yes tex.ppm"),
            "option -clamp must be on or off, found 'yes'"
        );
        assert_eq!(
            e("-imfchan q tex.ppm"),
            "option -imfchan must be one of r g b m l z, found 'q'"
        );
        assert_eq!(e("-type"), "option -type needs a value, found ''");
        assert_eq!(e("-s 1 1 1"), "without a file name");
        assert_eq!(e(""), "without a file name");
        // Through the MTL: line, material and key.
        let err = parse(TEST_QUAD, "newmtl light\nmap_Kd -bm\n").unwrap_err();
        assert_eq!(
            err.to_string(),
            "m/quad.mtl: line 2: material 'light': map_Kd option -bm needs a number, found ''"
        );
        let err = parse(TEST_QUAD, "newmtl light\nmap_Ks -s 1\n").unwrap_err();
        assert_eq!(
            err.to_string(),
            "m/quad.mtl: line 2: material 'light': map_Ks without a file name"
        );
    }
}
