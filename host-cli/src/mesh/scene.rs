//! Scene assembly: the objects, materials and textures of an OBJ in the flat, host-owned
//! buffers the kernel reads, with the emitter table and the BVH.

use super::files::{Disk, FileSource};
use super::mtl::{MtlMaterial, Param, TextureMap};
use super::obj::read_obj;
use super::quote::{escape, quote};
use super::texture::TextureTable;
use crate::error::{Error, Result};
use ember_kernel::bvh::{self, BvhNode, WideBvh, WideNode};
use ember_kernel::emitter::{build_emitter_table, EmitterPolicy, EmitterTableError};
use ember_kernel::geometry::{Aabb, TriangleGroup, GROUP_WIDTH};
use ember_kernel::material::Reflectance;
use ember_kernel::scene::{Material, SceneView};
use ember_kernel::texture::{Texture, Textures};
use ember_kernel::Rgb;
use glam::{Vec2, Vec3};
use std::path::{Path, PathBuf};

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
    /// The wide BVH (8 lanes on x86-64, 4 elsewhere) the renderer traces (the binary build is
    /// collapsed and dropped).
    pub bvh_nodes: Vec<WideNode>,
    /// The wide tree's primitive order, each leaf starting at a multiple of four
    /// ([`bvh::align_leaves`]; padded with repeats of the leaf's last triangle).
    pub bvh_prim_order: Vec<u32>,
    /// The triangles of `bvh_prim_order` four at a time ([`WideBvh::leaf_groups`]).
    pub bvh_leaf_groups: Vec<TriangleGroup>,
    /// Non-fatal remarks about the input (unsupported MTL features and the like).
    pub warnings: Vec<String>,
    /// Wall time of the last BVH build.
    pub bvh_build_seconds: f64,
    /// The MTL files the OBJ loaded.
    pub mtl_files: Vec<PathBuf>,
    /// Texture coordinates per vertex, indexed like `positions`; empty unless a material is
    /// textured.
    pub uvs: Vec<Vec2>,
    /// The texture table and its texels (bottom row first), empty without textures.
    pub textures: Vec<Texture>,
    pub texels: Vec<Rgb>,
    /// The texture files decoded (each once).
    pub texture_files: Vec<PathBuf>,
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
    /// Memory and time are linear in the size of the OBJ, its MTLs and its textures (each
    /// distinct `mtllib` and texture file is read once; at most [`super::MAX_MATERIALS`]
    /// materials, textures of at most [`super::texture::MAX_TEXTURE_SIDE`]² texels).
    ///
    /// # Errors
    /// Malformed OBJ or MTL (with the line), face indices out of range, faces without normals,
    /// non-finite coordinates, missing MTL or texture files, invalid material values, texture
    /// files that are not valid images (with the MTL line), textured objects without texture
    /// coordinates, a scene without triangles. Every error names the file it is about.
    pub fn parse_obj(path: &Path, obj: &[u8], files: &dyn FileSource) -> Result<Self> {
        let obj_file = read_obj(path, obj, files)?;
        let models = obj_file.models;
        let libraries = obj_file.libraries;
        let mut scene = Self {
            mtl_files: libraries.iter().map(|(p, _)| p.clone()).collect(),
            ..Self::default()
        };
        scene.add_materials(&libraries, files)?;
        // Texture coordinates are kept only when a material is textured; the scenes without
        // textures (all of TinyRender's but one) keep `uvs` empty and never look at them.
        let textured_scene = scene.materials.iter().any(Material::is_textured);
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
            if textured_scene {
                scene.add_uvs(path, model, material)?;
            }
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

    /// The kernel materials of the MTL libraries, in tobj's id order (library by library),
    /// with the texture maps their models apply decoded into the texture table.
    ///
    /// # Errors
    /// A texture file that cannot be read or decoded, named with its MTL line.
    fn add_materials(
        &mut self,
        libraries: &[(PathBuf, Vec<MtlMaterial>)],
        files: &dyn FileSource,
    ) -> Result<()> {
        let mut table = TextureTable::default();
        // Each map option ember ignores, with where it was first given.
        let mut ignored: Vec<(&'static str, String)> = Vec::new();
        for (library, materials) in libraries {
            let lib_name = library.file_name().map_or_else(
                || library.display().to_string(),
                |n| n.to_string_lossy().into_owned(),
            );
            for m in materials {
                self.warnings.extend(m.warnings());
                // Only maps the model applies reach the table: a material without them (and so
                // a scene without textures) reads and decodes no file.
                let mut param = |map: Option<&TextureMap>, key: &str, constant: Rgb| {
                    let Some(map) = map else {
                        return Ok(Param::constant(constant));
                    };
                    let t = table
                        .get(&map.file, map.options.scale, map.options.offset, files)
                        .map_err(|e| {
                            Error::in_file(
                                library,
                                format!(
                                    "line {}: material '{}': {key} texture {}: {e}",
                                    map.line,
                                    quote(&m.name),
                                    escape(&map.file.display().to_string())
                                ),
                            )
                        })?;
                    for &o in &map.options.ignored {
                        if !ignored.iter().any(|(seen, _)| *seen == o) {
                            ignored.push((o, format!("{} line {}", escape(&lib_name), map.line)));
                        }
                    }
                    Ok::<_, Error>(Param {
                        reflectance: Reflectance::texture(t.id),
                        max: t.max,
                        avg: t.avg,
                    })
                };
                let [kd_map, ks_map] = m.applied_maps();
                let kd = param(kd_map, "map_Kd", m.kd)?;
                let ks = param(ks_map, "map_Ks", m.ks)?;
                self.materials.push(Material {
                    surface: m.surface(kd, ks),
                    emission: m.ke,
                });
                self.material_info.push(MaterialInfo {
                    name: m.name.clone(),
                    illum: m.illum,
                });
            }
        }
        if !ignored.is_empty() {
            let list: Vec<String> = ignored
                .iter()
                .map(|(o, at)| format!("{o} ({at})"))
                .collect();
            self.warnings.push(format!(
                "texture map options not supported, ignored (ember applies -s and -o): {}",
                list.join(", ")
            ));
        }
        self.textures = table.textures;
        self.texels = table.texels;
        self.texture_files = table.files;
        Ok(())
    }

    /// Appends the texture coordinates of an object's vertices (zeros for an object whose
    /// material is not textured: they are never read).
    ///
    /// # Errors
    /// A textured object whose vertices lack texture coordinates, or with non-finite ones.
    fn add_uvs(&mut self, path: &Path, model: &tobj::Model, material: u32) -> Result<()> {
        let mesh = &model.mesh;
        let nv = mesh.positions.len() / 3;
        if !self.materials[material as usize].is_textured() {
            self.uvs.resize(self.uvs.len() + nv, Vec2::ZERO);
            return Ok(());
        }
        let name = quote(&model.name);
        if mesh.texcoords.len() != 2 * nv {
            return Err(Error::in_file(
                path,
                format!(
                    "object '{name}' uses the textured material '{}' but has faces without texture coordinates (write faces as f v/vt/vn)",
                    quote(&self.material_info[material as usize].name)
                ),
            ));
        }
        for (i, uv) in mesh.texcoords.chunks_exact(2).enumerate() {
            let uv = Vec2::new(uv[0], uv[1]);
            if !uv.is_finite() {
                return Err(Error::in_file(
                    path,
                    format!("object '{name}': vertex {i} has non-finite texture coordinates"),
                ));
            }
            self.uvs.push(uv);
        }
        Ok(())
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

    /// Builds the BVH over all triangles, collapses it to the wide tree the renderer
    /// traces, trims that to the nodes used, and lays its leaves out in groups of
    /// `GROUP_WIDTH` triangles (8 on x86-64, 4 elsewhere) for the lane-wise triangle test.
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
        let mut aligned = vec![0u32; bvh::aligned_order_len(&wide)];
        bvh::align_leaves(&mut wide, &order, &mut aligned).map_err(|e| e.to_string())?;
        let mut groups = vec![TriangleGroup::default(); aligned.len().div_ceil(GROUP_WIDTH)];
        bvh::gather_leaf_groups(&self.positions, &self.triangles, &aligned, &mut groups)
            .map_err(|e| e.to_string())?;
        self.bvh_nodes = wide;
        self.bvh_prim_order = aligned;
        self.bvh_leaf_groups = groups;
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
                leaf_groups: &self.bvh_leaf_groups,
            }
            .into(),
            textures: Textures {
                uvs: &self.uvs,
                textures: &self.textures,
                texels: &self.texels,
            },
        }
    }

    /// Bytes of kernel scene data (geometry, materials, textures, emitters, BVH).
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
            + size_of_val(self.bvh_leaf_groups.as_slice())
            + size_of_val(self.uvs.as_slice())
            + size_of_val(self.textures.as_slice())
            + size_of_val(self.texels.as_slice())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The lane-wise triangle groups change no hit: the Cornell box traced with them and
    /// triangle by triangle through the index buffer gives the same closest hits (bit for
    /// bit) and occlusion answers on rays from inside the room in every direction; and
    /// `validate` refuses groups that are too few or differ from the triangles.
    #[test]
    fn leaf_groups_give_the_same_hits_and_are_validated() {
        use ember_kernel::geometry::Ray;
        use ember_kernel::scene::SceneError;
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../data/cornell-box/mesh");
        let data = SceneData::load_obj(&dir.join("cornell_box.obj")).unwrap();
        // Every leaf starts a group, and every triangle is in one.
        assert_eq!(data.bvh_prim_order.len() % GROUP_WIDTH, 0);
        assert_eq!(
            data.bvh_leaf_groups.len() * GROUP_WIDTH,
            data.bvh_prim_order.len()
        );
        let mut seen = data.bvh_prim_order.clone();
        seen.sort_unstable();
        seen.dedup();
        assert_eq!(seen, (0..32).collect::<Vec<u32>>());
        let with = data.view();
        with.validate().unwrap();
        let view = |groups| SceneView {
            bvh: WideBvh {
                nodes: &data.bvh_nodes,
                prim_order: &data.bvh_prim_order,
                leaf_groups: groups,
            }
            .into(),
            ..with
        };
        let leaf = data.bvh_leaf_groups.clone();
        let without = view(&[]);
        let (lo, hi) = data
            .positions
            .iter()
            .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(l, h), p| {
                (l.min(*p), h.max(*p))
            });
        let mut hits = 0;
        for i in 0..4000u32 {
            let u = |k: u32| ember_kernel::sampler::IndependentSampler::new(9, u64::from(i), k);
            let (mut a, mut b) = (u(0), u(1));
            use ember_kernel::sampler::Sampler;
            let o = lo + (hi - lo) * Vec3::new(a.next_1d(), a.next_1d(), a.next_1d());
            let d = ember_kernel::math::warp::sample_uniform_sphere(b.next_2d());
            let mut ray = Ray::new(o, d);
            let h = with.intersect(&ray);
            let key = |h: Option<ember_kernel::scene::Hit>| {
                h.map(|h| (h.t.to_bits(), h.triangle, h.b1.to_bits(), h.b2.to_bits()))
            };
            assert_eq!(key(h), key(without.intersect(&ray)), "ray {i}");
            hits += usize::from(h.is_some());
            ray.t_max = 0.5;
            assert_eq!(with.occluded(&ray), without.occluded(&ray), "ray {i}");
        }
        assert!(hits > 3000, "{hits} hits");
        let mut wrong = leaf.clone();
        wrong[1].v[2][0][3] += 1e-3;
        assert_eq!(
            view(&wrong).validate(),
            Err(SceneError::BvhLeafTriangle {
                entry: GROUP_WIDTH + 3
            })
        );
        let short = &leaf[..leaf.len() - 1];
        assert_eq!(
            view(short).validate(),
            Err(SceneError::BvhLeafTriangle {
                entry: data.bvh_prim_order.len()
            })
        );
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

    use crate::mesh::{parse_for_test, TEST_QUAD};
    use ember_kernel::bsdf::Phong;
    use ember_kernel::material::{PhongParams, Surface};
    use ember_kernel::texture::{texel_stats, NO_TEXTURE};
    use std::cell::RefCell;

    /// [`TEST_QUAD`] with texture coordinates (0,0) (1,0) (1,1) (0,1) at its corners.
    const UV_QUAD: &str = "mtllib quad.mtl\no light\nv -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\nusemtl light\nf 1/1/1 2/2/1 3/3/1 4/4/1\n";

    /// A 2×1 PPM: a red and a green pixel.
    const PPM: &[u8] = b"P6\n2 1\n255\n\xff\x00\x00\x00\xff\x00";

    /// Loads with `files` serving `PPM` for every texture, recording the textures read.
    fn load(obj: &str, mtl: &str) -> (Result<SceneData>, Vec<std::path::PathBuf>) {
        let reads = RefCell::new(Vec::new());
        let r = parse_for_test(obj, mtl, |p| {
            reads.borrow_mut().push(p.to_path_buf());
            Some(PPM.to_vec())
        });
        (r, reads.into_inner())
    }

    #[test]
    fn textured_diffuse_quad() {
        let (s, _) = load(
            UV_QUAD,
            "newmtl light\nKd 0.5 0.5 0.5\nillum 7\nmap_Kd -s 2 1 1 t.ppm\n",
        );
        let s = s.unwrap();
        assert_eq!(
            s.materials[0].surface,
            Surface::Diffuse {
                kd: Reflectance::texture(0)
            }
        );
        assert_eq!(s.uvs.len(), s.positions.len());
        let mut uvs: Vec<[f32; 2]> = s.uvs.iter().map(|u| u.to_array()).collect();
        uvs.sort_by(|a, b| a.partial_cmp(b).unwrap());
        assert_eq!(uvs, [[0.0, 0.0], [0.0, 1.0], [1.0, 0.0], [1.0, 1.0]]);
        assert_eq!(s.texels, [Rgb::X, Rgb::Y]);
        assert_eq!(s.textures.len(), 1);
        assert_eq!(s.textures[0].uv_scale, Vec2::new(2.0, 1.0));
        assert_eq!(s.texture_files, [Path::new("m/t.ppm")]);
        assert!(s.warnings.is_empty(), "{:?}", s.warnings);
        // The kernel reads the texel at the hit's interpolated coordinates.
        let view = s.view();
        let bsdf = s.materials[0].bsdf(&view.textures, || Vec2::new(0.3, 0.5));
        assert_eq!(
            bsdf,
            Material::diffuse(Rgb::Y).constant_bsdf(),
            "u·2 = 0.6: the green texel"
        );
    }

    #[test]
    fn textured_phong_weights_come_from_the_texels() {
        let mtl = "newmtl light\nKd 0.1 0.1 0.1\nKs 0.4 0.4 0.4\nNs 12\nillum 8\nmap_Kd t.ppm\n";
        let s = load(UV_QUAD, mtl).0.unwrap();
        let (max, avg) = texel_stats(&[Rgb::X, Rgb::Y]).unwrap();
        let ks = Rgb::splat(0.4);
        let (scale, specular_weight) = Phong::weights(max, ks, avg, ks);
        assert_eq!(
            s.materials[0].surface,
            Surface::Mixture(PhongParams {
                kd: Reflectance::texture(0),
                ks: Reflectance::constant(ks),
                exponent: 12.0,
                scale,
                specular_weight,
            })
        );
        // Both maps of one file: one decode, one texture; a conductor's map_Ks applies too.
        // `./t.ppm` is the same path (paths compare by components).
        let mtl = "newmtl light\nillum 2\nmap_Kd t.ppm\nmap_Ks t.ppm\nnewmtl metal\nillum 5\nPr 0.5\nmap_Ks ./t.ppm\n";
        let (s, calls) = load(UV_QUAD, mtl);
        let s = s.unwrap();
        assert_eq!(s.materials[0].texture_ids(), [0, 0]);
        assert_eq!(
            s.materials[1].surface,
            Surface::Conductor {
                ks: Reflectance::texture(0),
                alpha: 0.25
            }
        );
        assert_eq!(s.textures.len(), 1);
        assert_eq!(s.texture_files, [Path::new("m/t.ppm")]);
        // Three existence checks while parsing the MTL, then one read.
        assert_eq!(calls.len(), 4, "{calls:?}");
    }

    #[test]
    fn maps_a_model_does_not_read_are_not_loaded() {
        let mtl = "newmtl light\nNi 1.5\nillum 6\nmap_Kd t.ppm\nmap_Ks t.ppm\n";
        let (s, reads) = load(TEST_QUAD, mtl);
        let s = s.unwrap();
        assert_eq!(s.materials[0].texture_ids(), [NO_TEXTURE; 2]);
        assert!(s.uvs.is_empty() && s.textures.is_empty() && s.texels.is_empty());
        // Found (is_file), never read.
        assert_eq!(reads.len(), 2, "{reads:?}");
        assert_eq!(
            s.warnings,
            [
                "material 'light': map_Kd does not apply to illum 6 (dielectric); not loaded",
                "material 'light': map_Ks does not apply to illum 6 (dielectric); not loaded"
            ]
        );
        let s = load(TEST_QUAD, "newmtl light\nillum 7\nmap_Ks t.ppm\n")
            .0
            .unwrap();
        assert_eq!(
            s.warnings,
            ["material 'light': map_Ks does not apply to illum 7 (diffuse); not loaded"]
        );
    }

    #[test]
    fn scenes_without_textures_keep_no_coordinates() {
        // The OBJ has vt lines, no material is textured: nothing is kept, no file is read.
        let (s, reads) = load(UV_QUAD, "newmtl light\nKd 1 1 1\nillum 7\n");
        let s = s.unwrap();
        assert!(reads.is_empty());
        assert!(s.uvs.is_empty() && s.textures.is_empty() && s.texture_files.is_empty());
        // A textured material in the scene: every vertex has coordinates, zeros for objects
        // whose material is not textured.
        let obj = format!(
            "{UV_QUAD}o plain\nv 0 0 1\nv 1 0 1\nv 0 1 1\nusemtl plain\nf 5//1 6//1 7//1\n"
        );
        let mtl = "newmtl light\nillum 7\nmap_Kd t.ppm\nnewmtl plain\nKd 1 1 1\nillum 7\n";
        let s = load(&obj, mtl).0.unwrap();
        assert_eq!(s.uvs.len(), 7);
        assert_eq!(&s.uvs[4..], [Vec2::ZERO; 3]);
    }

    #[test]
    fn texture_errors_name_the_mtl_line() {
        let e = |obj: &str, mtl: &str, texture: &'static [u8]| {
            parse_for_test(obj, mtl, |_| Some(texture.to_vec()))
                .unwrap_err()
                .to_string()
        };
        let mtl = "newmtl light\nillum 7\nmap_Kd -o 0.5 0 0 t.png\n";
        assert_eq!(
            e(UV_QUAD, mtl, b"P6\n2 2\n255\n\x01\x02\x03"),
            "m/quad.mtl: line 3: material 'light': map_Kd texture m/t.png: truncated PPM: expected 12 bytes of pixels, found 3"
        );
        assert_eq!(
            e(UV_QUAD, mtl, b"<html>"),
            "m/quad.mtl: line 3: material 'light': map_Kd texture m/t.png: not an image (expected binary PPM (P6), PNG or JPEG)"
        );
        // A textured object without texture coordinates.
        assert_eq!(
            e(TEST_QUAD, mtl, PPM),
            "m/quad.obj: object 'light' uses the textured material 'light' but has faces without texture coordinates (write faces as f v/vt/vn)"
        );
        let nan = UV_QUAD.replace("vt 1 1", "vt nan 1");
        assert_eq!(
            e(&nan, mtl, PPM),
            "m/quad.obj: object 'light': vertex 2 has non-finite texture coordinates"
        );
    }

    #[test]
    fn ignored_map_options_are_named_in_one_warning() {
        let mtl = "newmtl light\nillum 8\nmap_Kd -bm 0.5 -clamp on t.ppm\nmap_Ks -clamp off -texres 64 t.ppm\n";
        let s = load(UV_QUAD, mtl).0.unwrap();
        assert_eq!(
            s.warnings,
            ["texture map options not supported, ignored (ember applies -s and -o): -bm (quad.mtl line 3), -clamp (quad.mtl line 3), -texres (quad.mtl line 4)"]
        );
    }
}
