//! ember's command-line host as a library: scene loading, kernel buffers, parallel rendering,
//! image output. The `ember` binary and the viewer are thin layers over it.

pub mod bake;
pub mod bench;
pub mod compare;
pub mod error;
pub mod fuzzing;
pub mod image;
pub mod mesh;
pub mod render;
pub mod scene_file;
pub mod shard;
pub mod simd;
pub mod splats;

pub use error::{Error, Result};

use ember_kernel::camera::Camera;
use ember_kernel::integrator::{Integrator, PathSettings, Shortcuts};
use mesh::SceneData;
use scene_file::{PathDesc, RendererDesc, SceneFile};
use std::path::Path;

impl From<PathDesc> for PathSettings {
    fn from(p: PathDesc) -> Self {
        Self {
            max_depth: p.max_depth,
            rr_depth: p.rr_depth,
            rr_prob: p.rr_prob,
            shortcuts: Shortcuts::NONE,
        }
    }
}

/// A scene file with its geometry loaded and checked.
#[derive(Debug)]
pub struct LoadedScene {
    pub file: SceneFile,
    pub data: SceneData,
}

impl LoadedScene {
    /// Reads the TOML and its OBJ/MTL, builds the BVH and validates the kernel view.
    ///
    /// # Errors
    /// Any bad input, with the file named.
    pub fn load(toml: &Path) -> Result<Self> {
        let file = SceneFile::load(toml)?;
        // load_obj builds the BVH and validates the kernel view.
        let data = SceneData::load_obj(&file.objfile)?;
        Ok(Self { file, data })
    }

    /// The scene camera at the given film size.
    #[must_use]
    pub fn camera(&self, width: u32, height: u32) -> Camera {
        let c = &self.file.camera;
        Camera::look_at(c.eye.into(), c.at.into(), c.up.into(), c.fov, width, height)
    }

    /// The kernel shortcuts this scene allows ([`Shortcuts::analyse`]).
    #[must_use]
    pub fn shortcuts(&self) -> Shortcuts {
        Shortcuts::analyse(&self.data.view())
    }

    /// Kernel path settings from the file's, with the scene's [`Self::shortcuts`].
    fn path_for(&self, desc: PathDesc) -> PathSettings {
        PathSettings {
            shortcuts: self.shortcuts(),
            ..desc.into()
        }
    }

    /// Bake settings of a `gi` scene (path settings and samples per vertex); other scenes get
    /// TinyRender's `gi` defaults (maxDepth 5, rrDepth 5, rrProb 0.95, 100 samples).
    #[must_use]
    pub fn gi_settings(&self) -> (PathSettings, u32) {
        let (desc, spv) = match self.file.renderer {
            RendererDesc::Gi {
                path,
                samples_by_vertex,
            } => (path, samples_by_vertex),
            RendererDesc::Path { .. } => (
                PathDesc {
                    max_depth: 5,
                    rr_depth: 5,
                    rr_prob: 0.95,
                },
                100,
            ),
        };
        (self.path_for(desc), spv)
    }

    /// The integrator, path settings and spp of an offline scene (`path`, `mis`,
    /// `lighttracer`, `bdpt`).
    ///
    /// # Errors
    /// For a real-time scene, which is not rendered by a path tracer.
    pub fn path_settings(&self) -> Result<(Integrator, PathSettings, u32)> {
        match self.file.renderer {
            RendererDesc::Path {
                integrator,
                path,
                spp,
            } => Ok((integrator, self.path_for(path), spp)),
            RendererDesc::Gi { .. } => Err(Error::in_file(
                &self.file.path,
                "this is a real-time \"gi\" scene, not a path-traced one",
            )),
        }
    }
}
