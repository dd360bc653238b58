//! Float RGB images: EXR and PNG output written atomically, EXR input, and the statistics the
//! tests and comparisons use.

use crate::error::{Error, Result};
use ember_kernel::Rgb;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

/// A linear-radiance image, row 0 at the top.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<Rgb>,
}

impl Image {
    #[must_use]
    pub fn new(width: u32, height: u32) -> Self {
        Self {
            width,
            height,
            pixels: vec![Rgb::ZERO; width as usize * height as usize],
        }
    }

    #[must_use]
    pub fn at(&self, x: u32, y: u32) -> Rgb {
        self.pixels[(y * self.width + x) as usize]
    }

    /// Mean RGB over all pixels (accumulated in f64).
    #[must_use]
    pub fn mean(&self) -> Rgb {
        let mut s = glam::DVec3::ZERO;
        for p in &self.pixels {
            s += p.as_dvec3();
        }
        (s / self.pixels.len().max(1) as f64).as_vec3()
    }

    /// Means over a `bx × by` grid of blocks (row-major, block row 0 at the top). Pixels are
    /// assigned to the block containing their centre, so any size works.
    #[must_use]
    pub fn block_means(&self, bx: u32, by: u32) -> Vec<Rgb> {
        let mut sums = vec![glam::DVec3::ZERO; (bx * by) as usize];
        let mut counts = vec![0u64; (bx * by) as usize];
        for y in 0..self.height {
            let j = (u64::from(y) * u64::from(by) / u64::from(self.height)) as u32;
            for x in 0..self.width {
                let i = (u64::from(x) * u64::from(bx) / u64::from(self.width)) as u32;
                let k = (j * bx + i) as usize;
                sums[k] += self.at(x, y).as_dvec3();
                counts[k] += 1;
            }
        }
        sums.iter()
            .zip(&counts)
            .map(|(s, &c)| (*s / c.max(1) as f64).as_vec3())
            .collect()
    }

    /// Box-filters down by an integer factor in each direction.
    #[must_use]
    pub fn downsample(&self, fx: u32, fy: u32) -> Self {
        let (w, h) = (self.width / fx, self.height / fy);
        let mut out = Self::new(w, h);
        for y in 0..h {
            for x in 0..w {
                let mut s = glam::DVec3::ZERO;
                for dy in 0..fy {
                    for dx in 0..fx {
                        s += self.at(x * fx + dx, y * fy + dy).as_dvec3();
                    }
                }
                out.pixels[(y * w + x) as usize] = (s / f64::from(fx * fy)).as_vec3();
            }
        }
        out
    }

    /// Number of pixels with a NaN or infinite component.
    #[must_use]
    pub fn non_finite_count(&self) -> usize {
        self.pixels.iter().filter(|p| !p.is_finite()).count()
    }
}

/// A sibling temporary path for atomic writes: same directory (so rename is atomic), same
/// extension (some writers look at it), hidden, unique per process.
fn temp_path(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    path.with_file_name(format!(".{name}.{}.tmp", std::process::id()))
}

/// Writes through `write` to a temporary file, then renames it over `path`; on any error the
/// temporary is removed and `path` is left as it was.
pub fn write_atomically(path: &Path, write: impl FnOnce(&Path) -> Result<()>) -> Result<()> {
    let tmp = temp_path(path);
    let result = write(&tmp).and_then(|()| {
        std::fs::rename(&tmp, path)
            .map_err(|e| Error::in_file(path, format!("cannot move output into place: {e}")))
    });
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// Writes a 32-bit float linear RGB EXR.
///
/// # Errors
/// When the file cannot be written.
pub fn write_exr(path: &Path, image: &Image) -> Result<()> {
    use exr::prelude::{Encoding, Layer, LayerAttributes, SpecificChannels, Vec2, WritableImage};
    write_atomically(path, |tmp| {
        let channels = SpecificChannels::rgb(|p: Vec2<usize>| {
            let c = image.pixels[p.y() * image.width as usize + p.x()];
            (c.x, c.y, c.z)
        });
        let layer = Layer::new(
            (image.width as usize, image.height as usize),
            LayerAttributes::named("ember"),
            Encoding::SMALL_LOSSLESS,
            channels,
        );
        exr::image::Image::from_layer(layer)
            .write()
            .to_file(tmp)
            .map_err(|e| Error::in_file(path, format!("cannot write EXR: {e}")))
    })
}

/// Reads the first RGB(A) layer of an EXR (any pixel type) as linear f32.
///
/// # Errors
/// When the file is missing or not a readable EXR.
pub fn read_exr(path: &Path) -> Result<Image> {
    use exr::prelude::read_first_rgba_layer_from_file;
    let img = read_first_rgba_layer_from_file(
        path,
        |res, _| Image::new(res.width() as u32, res.height() as u32),
        |img: &mut Image, pos, (r, g, b, _a): (f32, f32, f32, f32)| {
            let w = img.width as usize;
            img.pixels[pos.y() * w + pos.x()] = Rgb::new(r, g, b);
        },
    )
    .map_err(|e| Error::in_file(path, format!("cannot read EXR: {e}")))?;
    Ok(img.layer_data.channel_data.pixels)
}

/// The sRGB transfer function of a linear value, clamped to [0, 1].
#[must_use]
pub fn linear_to_srgb(v: f32) -> f32 {
    let v = if v.is_finite() {
        v.clamp(0.0, 1.0)
    } else {
        0.0
    };
    if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

/// The inverse of [`linear_to_srgb`] (the sRGB EOTF).
#[must_use]
pub fn srgb_to_linear(v: f32) -> f32 {
    if v <= 0.040_45 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

/// The 8-bit sRGB code of a linear value as the PNG previews store it: [`linear_to_srgb`]
/// (clamped to [0, 1]) scaled to 255 and rounded half up.
#[must_use]
pub fn srgb8_code(v: f32) -> u8 {
    (linear_to_srgb(v) * 255.0 + 0.5) as u8
}

/// The RGB bytes of the PNG preview of `image` (row 0 first), [`srgb8_code`] per channel.
#[must_use]
pub fn srgb8(image: &Image) -> Vec<u8> {
    image
        .pixels
        .iter()
        .flat_map(|c| c.to_array())
        .map(srgb8_code)
        .collect()
}

/// Writes `exr` and its PNG preview beside it (same stem, `.png`), each atomically; if the PNG
/// fails the EXR is removed again, so no half of the pair is left behind. Returns the PNG's
/// path.
///
/// # Errors
/// When either file cannot be written, or `exr` ends in `.png`.
pub fn write_exr_and_png(exr: &Path, image: &Image) -> Result<PathBuf> {
    let png = exr.with_extension("png");
    if png == exr {
        return Err(Error::in_file(
            exr,
            "the output must be the EXR (a .png preview is written beside it); use -o NAME.exr",
        ));
    }
    write_exr(exr, image)?;
    if let Err(e) = write_png(&png, image) {
        let _ = std::fs::remove_file(exr);
        return Err(e);
    }
    Ok(png)
}

/// Writes an 8-bit sRGB PNG preview (values clamped to [0, 1], no tone mapping).
///
/// # Errors
/// When the file cannot be written.
pub fn write_png(path: &Path, image: &Image) -> Result<()> {
    let io = |e: std::io::Error| Error::in_file(path, format!("cannot write PNG: {e}"));
    write_atomically(path, |tmp| {
        let file = std::fs::File::create(tmp).map_err(io)?;
        let mut enc = png::Encoder::new(BufWriter::new(&file), image.width, image.height);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        enc.set_source_srgb(png::SrgbRenderingIntent::Perceptual);
        let mut w = enc
            .write_header()
            .map_err(|e| Error::in_file(path, format!("cannot write PNG: {e}")))?;
        let data = srgb8(image);
        let png_err =
            |e: png::EncodingError| Error::in_file(path, format!("cannot write PNG: {e}"));
        w.write_image_data(&data).map_err(png_err)?;
        w.finish().map_err(png_err)?;
        file.sync_all().map_err(io)
    })
}
