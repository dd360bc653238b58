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

    /// Bake settings of a `gi` scene (path settings and samples per vertex); other scenes get
    /// TinyRender's `gi` defaults (maxDepth 5, rrDepth 5, rrProb 0.95, 100 samples). With the
    /// scene's [`Self::shortcuts`].
    #[must_use]
    pub fn gi_settings(&self) -> (PathSettings, u32) {
        let (path, spv) = self.gi_settings_general();
        (
            PathSettings {
                shortcuts: self.shortcuts(),
                ..path
            },
            spv,
        )
    }

    fn gi_settings_general(&self) -> (PathSettings, u32) {
        match self.file.renderer {
            RendererDesc::Gi {
                path,
                samples_by_vertex,
            } => (path.into(), samples_by_vertex),
            RendererDesc::Path { .. } => (
                PathSettings {
                    max_depth: 5,
                    rr_depth: 5,
                    rr_prob: 0.95,
                    shortcuts: Shortcuts::NONE,
                },
                100,
            ),
        }
    }

    /// The integrator, path settings (with the scene's [`Self::shortcuts`]) and spp of an
    /// offline (`path`) scene.
    ///
    /// # Errors
    /// For a real-time scene, which is not rendered by a path tracer.
    pub fn path_settings(&self) -> Result<(Integrator, PathSettings, u32)> {
        let (integrator, path, spp) = self.path_settings_general()?;
        let path = PathSettings {
            shortcuts: self.shortcuts(),
            ..path
        };
        Ok((integrator, path, spp))
    }

    fn path_settings_general(&self) -> Result<(Integrator, PathSettings, u32)> {
        match self.file.renderer {
            RendererDesc::Path {
                explicit,
                path,
                spp,
            } => Ok((
                if explicit {
                    Integrator::PathExplicit
                } else {
                    Integrator::PathImplicit
                },
                path.into(),
                spp,
            )),
            RendererDesc::Gi { .. } => Err(Error::in_file(
                &self.file.path,
                "this is a real-time \"gi\" scene, not a path-traced one",
            )),
        }
    }
}
