//! Wavefront OBJ/MTL loading (FORMAT.md §3–5) into the flat arrays the kernel reads.
//!
//! [`SceneData::parse_obj`] works on bytes in memory, with MTL and texture files from a
//! [`FileSource`], so tests and fuzzers (`host-cli/fuzz`) drive the same code as
//! [`SceneData::load_obj`]. One concept per module:
//!
//! - [`obj`]: OBJ syntax is tobj's, after a pass that checks face indices and coordinates with
//!   line numbers;
//! - [`mtl`]: MTL files are parsed here, so that every value ember uses is checked and its
//!   errors name the line, the material and the key; `illum` selects the scattering model;
//! - [`texture`]: texture files (PPM, PNG, JPEG) decoded to linear texels as TinyRender
//!   reads them, each file once;
//! - [`scene`]: the objects, materials and textures assembled into [`SceneData`], its kernel
//!   view, the emitter table and the BVH;
//! - [`files`]: where companion files come from; `quote`: names in messages.

pub mod files;
pub mod mtl;
pub mod obj;
mod quote;
pub mod scene;
pub mod texture;

pub use files::{Disk, FileSource};
pub use mtl::{bsdf_for, Model};
pub use obj::MAX_MATERIALS;
pub(crate) use quote::quote;
pub use scene::{MaterialInfo, Object, SceneData, MAX_ELEMENTS};

/// Loads an OBJ and its MTL from memory for unit tests: every `*.mtl` reads as `mtl`, and
/// `other` serves the remaining files (textures).
#[cfg(test)]
pub(crate) fn parse_for_test(
    obj: &str,
    mtl: &str,
    other: impl Fn(&std::path::Path) -> Option<Vec<u8>>,
) -> crate::Result<SceneData> {
    let mtl = mtl.as_bytes().to_vec();
    let files = move |p: &std::path::Path| {
        if p.extension()? == "mtl" {
            Some(mtl.clone())
        } else {
            other(p)
        }
    };
    SceneData::parse_obj(std::path::Path::new("m/quad.obj"), obj.as_bytes(), &files)
}

/// A unit quad in z = 0 facing +z with the material `light`, for unit tests.
#[cfg(test)]
pub(crate) const TEST_QUAD: &str = "mtllib quad.mtl\no light\nv -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nvn 0 0 1\nusemtl light\nf 1//1 2//1 3//1 4//1\n";
