//! MTL libraries (FORMAT.md §4): keys, values and the scattering model each material selects.

use super::files::FileSource;
use super::quote::{escape, quote};
use crate::error::{Error, Result};
use ember_kernel::material::Surface;
use ember_kernel::scene::Material;
use ember_kernel::Rgb;
use std::path::Path;

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
    /// `map_Kd`/`map_Ks` were given (and found); ember does not use textures yet.
    pub(crate) has_texture: bool,
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
    pub(crate) fn surface(&self) -> Surface {
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
    pub(crate) fn warning(&self) -> Option<String> {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{parse_for_test, SceneData, TEST_QUAD};

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
}
