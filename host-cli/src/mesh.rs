//! Wavefront OBJ/MTL loading (FORMAT.md §3–5) into the flat arrays the kernel reads.

use crate::error::{Error, Result};
use ember_kernel::bsdf::{Bsdf, Diffuse, Phong};
use ember_kernel::bvh::{self, Bvh, BvhNode};
use ember_kernel::geometry::Aabb;
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
    pub bvh_nodes: Vec<BvhNode>,
    pub bvh_prim_order: Vec<u32>,
    /// Non-fatal remarks about the input (unsupported MTL features and the like).
    pub warnings: Vec<String>,
    /// Wall time of the last BVH build.
    pub bvh_build_seconds: f64,
    /// The MTL files the OBJ loaded.
    pub mtl_files: Vec<std::path::PathBuf>,
}

/// The BSDF for an MTL `illum` value: 7 diffuse, 8 diffuse+Phong mixture, anything else Phong
/// (FORMAT.md §4; `illum 5` has no BSDF in TinyRender and is treated as Phong here).
#[must_use]
pub fn bsdf_for(illum: u8, kd: Rgb, ks: Rgb, ns: f32) -> Bsdf {
    match illum {
        7 => Bsdf::Diffuse(Diffuse::new(kd)),
        8 => Bsdf::Mixture(Phong::new(kd, ks, ns)),
        _ => Bsdf::Phong(Phong::new(kd, ks, ns)),
    }
}

fn rgb(path: &Path, mat: &str, key: &str, v: Option<[f32; 3]>) -> Result<Rgb> {
    let c = Rgb::from_array(v.unwrap_or([0.0; 3]));
    if !c.is_finite() || c.min_element() < 0.0 {
        return Err(Error::in_file(
            path,
            format!("material '{mat}': {key} = {c} must be finite and non-negative"),
        ));
    }
    Ok(c)
}

impl SceneData {
    /// Loads an OBJ with its MTL, triangulating polygons. Vertex normals are required.
    ///
    /// # Errors
    /// Missing or malformed OBJ or MTL, faces without normals, non-finite coordinates,
    /// negative reflectances, a scene without triangles.
    pub fn load_obj(path: &Path) -> Result<Self> {
        if !path.is_file() {
            return Err(Error::in_file(path, "OBJ file not found"));
        }
        let options = tobj::LoadOptions {
            triangulate: true,
            single_index: true,
            ignore_points: true,
            ignore_lines: true,
        };
        let file = std::fs::File::open(path)
            .map_err(|e| Error::in_file(path, format!("cannot open OBJ: {e}")))?;
        // Each `mtllib` is resolved against the OBJ's directory (as tobj::load_obj does); the
        // loads are recorded so that errors name the MTL file, not the OBJ.
        let dir = path.parent().unwrap_or(Path::new(""));
        let mtls = std::cell::RefCell::new(Vec::new());
        let (models, materials) =
            tobj::load_obj_buf(&mut std::io::BufReader::new(file), &options, |name| {
                let mtl = dir.join(name);
                let r = tobj::load_mtl(&mtl);
                mtls.borrow_mut()
                    .push((mtl, r.as_ref().map(|(m, _)| m.len()).map_err(|e| *e)));
                r
            })
            .map_err(|e| Error::in_file(path, format!("cannot load OBJ: {e}")))?;
        let mtls = mtls.into_inner();
        let obj_name = path
            .file_name()
            .unwrap_or(path.as_os_str())
            .to_string_lossy();
        for (mtl, r) in &mtls {
            if let Err(e) = r {
                let what = if mtl.is_file() {
                    format!("cannot load MTL: {e}")
                } else {
                    "MTL file not found".to_string()
                };
                return Err(Error::in_file(
                    mtl,
                    format!("{what} (mtllib of {obj_name})"),
                ));
            }
        }
        // tobj appends each MTL's materials in load order: material i came from the MTL whose
        // cumulative range holds i.
        let mtl_of = |i: usize| {
            let mut end = 0;
            mtls.iter()
                .filter_map(|(p, r)| r.as_ref().ok().map(|n| (p, *n)))
                .find(|(_, n)| {
                    end += n;
                    i < end
                })
                .map_or(path, |(p, _)| p.as_path())
        };
        let materials = materials
            .map_err(|e| Error::in_file(path, format!("cannot load its MTL (mtllib): {e}")))?;
        let mut scene = Self {
            mtl_files: mtls.iter().map(|(p, _)| p.clone()).collect(),
            ..Self::default()
        };
        for (i, m) in materials.iter().enumerate() {
            let mtl = mtl_of(i);
            let kd = rgb(mtl, &m.name, "Kd", m.diffuse)?;
            let ks = rgb(mtl, &m.name, "Ks", m.specular)?;
            let ke = rgb(mtl, &m.name, "Ke", m.emissive)?;
            let ns = m.shininess.unwrap_or(1.0);
            if !ns.is_finite() || ns < 0.0 {
                return Err(Error::in_file(
                    mtl,
                    format!("material '{}': Ns = {ns} must be finite and >= 0", m.name),
                ));
            }
            let illum = m.illumination_model.unwrap_or(0);
            if m.diffuse_texture.is_some() || m.specular_texture.is_some() {
                scene.warnings.push(format!(
                    "material '{}': texture maps are not supported yet; using Kd/Ks",
                    m.name
                ));
            }
            scene.materials.push(Material {
                bsdf: bsdf_for(illum, kd, ks, ns),
                emission: ke,
            });
            scene.material_info.push(MaterialInfo {
                name: m.name.clone(),
                illum,
            });
        }
        // Faces without a material get tinyobj's defaults: Kd = Ks = Ke = 0, Ns = 1, illum 0.
        let mut default_material = None;

        for model in &models {
            let mesh = &model.mesh;
            if mesh.indices.is_empty() {
                continue;
            }
            let nv = mesh.positions.len() / 3;
            if mesh.normals.len() != mesh.positions.len() {
                return Err(Error::in_file(
                    path,
                    format!(
                        "object '{}' has faces without vertex normals (write faces as f v//vn); TinyRender requires normals",
                        model.name
                    ),
                ));
            }
            let material = match mesh.material_id {
                Some(id) if id < scene.materials.len() => id as u32,
                Some(id) => {
                    return Err(Error::in_file(
                        path,
                        format!(
                            "object '{}' uses material #{id}, which the MTL does not define",
                            model.name
                        ),
                    ))
                }
                None => *default_material.get_or_insert_with(|| {
                    scene.materials.push(Material {
                        bsdf: bsdf_for(0, Rgb::ZERO, Rgb::ZERO, 1.0),
                        emission: Rgb::ZERO,
                    });
                    scene.material_info.push(MaterialInfo {
                        name: "(default)".into(),
                        illum: 0,
                    });
                    scene.warnings.push(format!(
                        "object '{}' has no material; using a black default",
                        model.name
                    ));
                    (scene.materials.len() - 1) as u32
                }),
            };
            let base = scene.positions.len() as u32;
            let first_tri = scene.triangles.len() as u32;
            for i in 0..nv {
                let p = Vec3::new(
                    mesh.positions[3 * i],
                    mesh.positions[3 * i + 1],
                    mesh.positions[3 * i + 2],
                );
                let n = Vec3::new(
                    mesh.normals[3 * i],
                    mesh.normals[3 * i + 1],
                    mesh.normals[3 * i + 2],
                );
                if !p.is_finite() || !n.is_finite() {
                    return Err(Error::in_file(
                        path,
                        format!(
                            "object '{}': vertex {i} has a non-finite position or normal",
                            model.name
                        ),
                    ));
                }
                scene.positions.push(p);
                scene.normals.push(n);
            }
            for f in mesh.indices.chunks_exact(3) {
                if f.iter().any(|&v| v as usize >= nv) {
                    return Err(Error::in_file(
                        path,
                        format!("object '{}': face index out of range", model.name),
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
        scene.build_emitters();
        scene.build_bvh().map_err(|e| Error::in_file(path, e))?;
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

    /// TinyRender's emitter rule: an object is an area light when its (first face's) material
    /// has non-zero `Ke`. An emitter is chosen uniformly, then a triangle of it by area.
    fn build_emitters(&mut self) {
        self.emitter_triangles.clear();
        self.emitter_cdf.clear();
        let emitters: Vec<&Object> = self
            .objects
            .iter()
            .filter(|o| self.materials[o.material as usize].is_emissive())
            .filter(|o| o.triangles.clone().any(|t| self.triangle_area(t) > 0.0))
            .collect();
        self.emitter_count = emitters.len();
        let mut acc = 0.0f64;
        let mut tris = Vec::new();
        let mut cdf = Vec::new();
        for o in &emitters {
            let area: f64 = o
                .triangles
                .clone()
                .map(|t| f64::from(self.triangle_area(t)))
                .sum();
            for t in o.triangles.clone() {
                acc += f64::from(self.triangle_area(t)) / area / emitters.len() as f64;
                tris.push(t);
                cdf.push(acc as f32);
            }
        }
        self.emitter_triangles = tris;
        self.emitter_cdf = cdf;
    }

    /// Builds the BVH over all triangles and trims the node array to what the build used.
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
        nodes.truncate(used);
        nodes.shrink_to_fit();
        self.bvh_nodes = nodes;
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
            bvh: Bvh {
                nodes: &self.bvh_nodes,
                prim_order: &self.bvh_prim_order,
            },
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
