//! The scene loaders as the fuzzers drive them: on bytes in memory, through the same entry
//! points as the `ember` binary ([`SceneFile::parse_bytes`], [`SceneData::parse_obj`]),
//! followed by what the binary does next (camera, emitter table, BVH, kernel validation).
//!
//! Used by the cargo-fuzz targets in `host-cli/fuzz/` and by the CI harness
//! `tests/tests/fuzz_loaders.rs`. Each function returns normally with the outcome, or panics
//! when the loader broke its contract: a loaded scene that is not usable, or an error that does
//! not name a file or spans more than one line. A panic inside a loader is a failure too.

use crate::error::Error;
use crate::mesh::SceneData;
use crate::scene_file::{SceneFile, MAX_FILM_SIDE};
use ember_kernel::camera::Camera;
use std::path::Path;

/// The path the scene inputs are given in errors.
pub const SCENE_PATH: &str = "fuzz/scene.toml";
/// The path the OBJ inputs are given; MTL libraries resolve against its directory.
pub const OBJ_PATH: &str = "fuzz/mesh.obj";
/// The MTL library of the `obj` target, served for every `mtllib`: the Cornell box's.
pub const CORNELL_MTL: &[u8] = include_bytes!("../../data/cornell-box/mesh/cornell_box.mtl");

/// What a loader made of an input.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Outcome {
    /// A usable scene.
    Loaded,
    /// Refused with an error that names the file.
    Refused,
}

/// Panics unless `e` names a file that `named` accepts and its message is one line.
#[track_caller]
fn check_error(e: &Error, named: impl Fn(&Path) -> bool) {
    let text = e.to_string();
    let Some(path) = &e.path else {
        panic!("error names no file: {text}");
    };
    assert!(
        !path.as_os_str().is_empty() && named(path),
        "error names {} , not an input file: {text}",
        path.display()
    );
    assert!(
        !e.message.is_empty() && !e.message.contains(['\n', '\r']),
        "error message is empty or not one line: {text:?}"
    );
}

/// A scene file: parse, then build the camera as `ember render` does.
///
/// # Panics
/// When the loader breaks its contract (see the module documentation).
#[must_use]
pub fn scene_toml(bytes: &[u8]) -> Outcome {
    let path = Path::new(SCENE_PATH);
    match SceneFile::parse_bytes(path, bytes) {
        Ok(scene) => {
            for side in [scene.width, scene.height] {
                assert!((1..=MAX_FILM_SIDE).contains(&side), "film side {side}");
            }
            let c = &scene.camera;
            let camera = Camera::look_at(
                c.eye.into(),
                c.at.into(),
                c.up.into(),
                c.fov,
                scene.width,
                scene.height,
            );
            assert!(
                camera.forward.is_finite()
                    && camera.right.is_finite()
                    && camera.up.is_finite()
                    && camera.tan_half_fov.is_finite()
                    && camera.tan_half_fov > 0.0,
                "scene accepted with an unusable camera: {camera:?}"
            );
            Outcome::Loaded
        }
        Err(e) => {
            check_error(&e, |p| p == path);
            Outcome::Refused
        }
    }
}

/// The texture served for every texture file the fuzz inputs can find: a 2×2 binary PPM.
pub const TEXTURE_PPM: &[u8] = b"P6\n2 2\n255\n\xff\x00\x00\x00\xff\x00\x00\x00\xff\xff\xff\xff";

/// An OBJ whose `mtllib` files all read as `mtl`. Texture maps exist when their file name
/// starts with `t` (so both a found and a missing `map_Kd` can be reached); they hold
/// [`TEXTURE_PPM`].
///
/// # Panics
/// When the loader breaks its contract (see the module documentation).
#[must_use]
pub fn obj(obj: &[u8], mtl: &[u8]) -> Outcome {
    let path = Path::new(OBJ_PATH);
    let dir = path.parent().unwrap_or(Path::new(""));
    let files = |p: &Path| -> Option<Vec<u8>> {
        let name = p.file_name()?.to_string_lossy();
        if p.extension().is_some_and(|e| e == "mtl") {
            Some(mtl.to_vec())
        } else if name.starts_with('t') {
            Some(TEXTURE_PPM.to_vec())
        } else {
            None
        }
    };
    match SceneData::parse_obj(path, obj, &files) {
        Ok(scene) => {
            let n = scene.triangles.len();
            assert!(n > 0, "scene without triangles accepted");
            assert!(scene.bvh_prim_order.len() >= n);
            assert_eq!(
                scene.bvh_leaf_groups.len() * ember_kernel::geometry::GROUP_WIDTH,
                scene.bvh_prim_order.len()
            );
            assert!(!scene.bvh_nodes.is_empty() && scene.bvh_nodes.len() <= n);
            assert!(scene.positions.iter().all(|p| p.is_finite()));
            assert!(scene.emitter_cdf.iter().all(|c| c.is_finite()));
            assert_eq!(scene.view().validate(), Ok(()));
            let textured = scene.materials.iter().any(|m| m.is_textured());
            assert_eq!(
                scene.uvs.is_empty(),
                !textured,
                "texture coordinates kept without textures, or missing with them"
            );
            assert!(scene.uvs.iter().all(|uv| uv.is_finite()));
            Outcome::Loaded
        }
        Err(e) => {
            // The OBJ itself, or a file the input names (an `mtllib` resolved against the OBJ's
            // directory, which an absolute name replaces, or a texture map of the MTL).
            let contains = |name: &[u8]| {
                [obj, mtl]
                    .iter()
                    .any(|text| text.windows(name.len()).any(|w| w == name))
            };
            let named = |p: &Path| {
                p == path
                    || p.starts_with(dir)
                    || contains(p.as_os_str().as_encoded_bytes())
                    || p.file_name()
                        .is_some_and(|name| contains(name.as_encoded_bytes()))
            };
            check_error(&e, named);
            Outcome::Refused
        }
    }
}

/// Splits a fuzz input of the `obj_mtl` target at its first NUL byte into OBJ and MTL (no
/// NUL: all OBJ, empty MTL).
#[must_use]
pub fn split_obj_mtl(data: &[u8]) -> (&[u8], &[u8]) {
    match data.iter().position(|&b| b == 0) {
        Some(i) => (&data[..i], &data[i + 1..]),
        None => (data, &[]),
    }
}
