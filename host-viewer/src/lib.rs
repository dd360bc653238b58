//! ember's viewer as a library: draws a mesh whose per-vertex colours hold baked global
//! illumination (TinyRender's `gi` pass, FORMAT.md §6) with Gouraud shading, through wgpu, and
//! shows a progressive path-traced view of a scene converging.
//!
//! * [`render_headless`] renders one frame offscreen and returns it as a linear image, the way
//!   TinyRender saves the first real-time frame (FORMAT.md §8): linear → sRGB by the hardware
//!   into an 8-bit sRGB target, read back, and decoded with the exact sRGB EOTF, so the values
//!   are clamped to [0, 1].
//! * [`window::run`] opens a window with an orbit/fly camera: the baked view, and the
//!   progressive path-traced view ([`trace::TraceWorker`] renders passes with host-cli's
//!   `Progressive` on worker threads; [`display::TraceDisplay`] shows them with exposure and
//!   the sRGB transfer in WGSL).
//!
//! The `ember-view` binary is a thin layer over this crate.

pub mod camera;
pub mod display;
pub mod gpu;
pub mod headless;
pub mod trace;
pub mod window;

pub use camera::ViewCamera;
pub use gpu::{MeshRenderer, COLOR_FORMAT, DEPTH_FORMAT};
pub use headless::{render_headless, Frame, FrameInfo, HeadlessGpu};

use std::fmt;

/// What went wrong; [`ViewerError::exit_code`] gives the binary's exit status.
#[derive(Debug)]
pub enum ViewerError {
    /// No Vulkan or GL adapter: the message names what to install. Exit status 1.
    NoAdapter(String),
    /// The device could not be created, or it reported an error while rendering. Exit status 1.
    Gpu(String),
    /// No window could be opened (no display). Exit status 1.
    Display(String),
    /// Bad input: scene, bake, mesh, film size or output path. Exit status 2.
    Input(ember_cli::Error),
}

impl ViewerError {
    /// 2 for bad input (as the `ember` binary), 1 for anything the machine lacks or failed at.
    #[must_use]
    pub fn exit_code(&self) -> u8 {
        match self {
            Self::Input(_) => 2,
            Self::NoAdapter(_) | Self::Gpu(_) | Self::Display(_) => 1,
        }
    }
}

impl fmt::Display for ViewerError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::NoAdapter(m) | Self::Gpu(m) | Self::Display(m) => f.write_str(m),
            Self::Input(e) => e.fmt(f),
        }
    }
}

impl std::error::Error for ViewerError {}

impl From<ember_cli::Error> for ViewerError {
    fn from(e: ember_cli::Error) -> Self {
        Self::Input(e)
    }
}

/// The sRGB EOTF (8-bit sRGB code → linear), exact to f32, as a table of the 256 codes.
#[must_use]
pub fn srgb8_to_linear_table() -> [f32; 256] {
    let mut t = [0.0f32; 256];
    for (i, v) in t.iter_mut().enumerate() {
        let c = i as f64 / 255.0;
        let l = if c <= 0.040_45 {
            c / 12.92
        } else {
            ((c + 0.055) / 1.055).powf(2.4)
        };
        *v = l as f32;
    }
    t
}

/// The 8-bit sRGB code a linear value is stored as in an sRGB target (clamped, rounded to
/// nearest): the reference the tests compare the hardware's encoding with.
#[must_use]
pub fn linear_to_srgb8(v: f32) -> u8 {
    let v = f64::from(if v.is_finite() {
        v.clamp(0.0, 1.0)
    } else {
        0.0
    });
    let s = if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    };
    (s * 255.0).round().clamp(0.0, 255.0) as u8
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eotf_table_ends_and_round_trip() {
        let t = srgb8_to_linear_table();
        assert_eq!(t[0], 0.0);
        assert_eq!(t[255], 1.0);
        assert!(t.windows(2).all(|w| w[0] < w[1]));
        for (code, &l) in t.iter().enumerate() {
            assert_eq!(usize::from(linear_to_srgb8(l)), code);
        }
        // Mid grey: sRGB 0.5 is about 0.214 linear.
        assert!((t[128] - 0.2158605).abs() < 1e-6);
    }

    #[test]
    fn encoding_clamps() {
        assert_eq!(linear_to_srgb8(2.0), 255);
        assert_eq!(linear_to_srgb8(-1.0), 0);
        assert_eq!(linear_to_srgb8(f32::NAN), 0);
        assert_eq!(linear_to_srgb8(0.25), 137);
    }

    #[test]
    fn exit_codes() {
        assert_eq!(ViewerError::NoAdapter(String::new()).exit_code(), 1);
        assert_eq!(
            ViewerError::Input(ember_cli::Error::new("x")).exit_code(),
            2
        );
    }
}
