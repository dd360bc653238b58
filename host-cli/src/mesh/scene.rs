//! Scene assembly: the objects and materials of an OBJ in the flat, host-owned buffers the
//! kernel reads, with the emitter table and the BVH.

use super::files::{Disk, FileSource};
use super::obj::read_obj;
use super::quote::quote;
use crate::error::{Error, Result};
use ember_kernel::bvh::{self, BvhNode, WideBvh, WideNode};
use ember_kernel::emitter::{build_emitter_table, EmitterPolicy, EmitterTableError};
use ember_kernel::geometry::Aabb;
use ember_kernel::scene::{Material, SceneView};
use ember_kernel::Rgb;
use glam::Vec3;
use std::path::Path;

/// Most vertices or triangles a scene may have: the kernel indexes them with `u32`.
pub const MAX_ELEMENTS: usize = u32::MAX as usize;

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
        let obj_file = read_obj(path, obj, files)?;
        let models = obj_file.models;
        let libraries = obj_file.libraries;
        let mut scene = Self {
            mtl_files: libraries.iter().map(|(p, _)| p.clone()).collect(),
            ..Self::default()
        };
        for (_, library) in &libraries {
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
                        surface: super::mtl::bsdf_for(0, Rgb::ZERO, Rgb::ZERO, 1.0),
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
}
