//! Texture maps: image files decoded to linear RGB texels as TinyRender reads them
//! (FORMAT.md §4), and the scene's texture table.
//!
//! TinyRender loads binary PPM (P6) only, converts each sample `c` to linear with
//! `(c / maxval)^2.2` and flips the rows so that `v = 0` is the bottom of the picture. ember
//! does the same for PPM (maxval 1..=255 with one byte per sample, 256..=65535 with two,
//! big-endian, as Netpbm defines), and decodes PNG and JPEG with the `image` crate: 8-bit
//! samples (sRGB pictures) get the same `(c / 255)^2.2`, so a PNG and a PPM of one picture
//! give the same texels, and 16-bit PNG samples `(c / 65535)^2.2`. Colour profiles and PNG
//! gamma chunks are not applied (TinyRender has none); alpha is dropped.
//!
//! Errors are the message after `<map> texture <file>: `; the assembly adds the MTL line.

use super::files::FileSource;
use ember_kernel::texture::{texel_stats, Texture};
use ember_kernel::Rgb;
use glam::Vec2;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// Largest texture side accepted (16384 × 16384 texels are 3 GiB of linear RGB).
pub const MAX_TEXTURE_SIDE: u32 = 16_384;

/// A decoded picture: `width × height` linear texels, bottom row first.
#[derive(Clone, Debug, PartialEq)]
pub struct TexelImage {
    pub width: u32,
    pub height: u32,
    pub texels: Vec<Rgb>,
}

/// `(c / maxval)^2.2` for every `c` in `0..=maxval`, computed with `f32::powf` exactly as
/// TinyRender's `std::pow(float(c) / e, 2.2f)`.
fn linear_table(maxval: u32) -> Vec<f32> {
    (0..=maxval)
        .map(|c| (c as f32 / maxval as f32).powf(2.2))
        .collect()
}

/// Refuses an empty or absurdly large picture.
fn check_size(width: u64, height: u64) -> Result<(), String> {
    if width == 0 || height == 0 {
        return Err(format!("image size {width}x{height} is empty"));
    }
    let max = u64::from(MAX_TEXTURE_SIDE);
    if width > max || height > max {
        return Err(format!(
            "image size {width}x{height} is larger than {MAX_TEXTURE_SIDE}x{MAX_TEXTURE_SIDE}"
        ));
    }
    Ok(())
}

/// Decodes a texture file by its content (not its name): binary PPM, PNG or JPEG.
///
/// # Errors
/// Anything else, a malformed header, an empty or absurd size, a truncated PPM, samples above
/// the PPM's maxval, or a PNG/JPEG the decoder refuses.
pub fn decode(bytes: &[u8]) -> Result<TexelImage, String> {
    match bytes {
        [b'P', b'6', ..] => decode_ppm(bytes),
        [b'P', kind @ (b'1'..=b'5' | b'7'), ..] => Err(format!(
            "Netpbm images of type P{} are not supported; use binary PPM (P6), PNG or JPEG",
            char::from(*kind)
        )),
        [0x89, b'P', b'N', b'G', ..] => decode_with_image_crate(bytes, image::ImageFormat::Png),
        [0xFF, 0xD8, 0xFF, ..] => decode_with_image_crate(bytes, image::ImageFormat::Jpeg),
        _ => Err("not an image (expected binary PPM (P6), PNG or JPEG)".into()),
    }
}

/// Binary PPM (Netpbm P6): `P6`, width, height and maxval as decimal numbers separated by
/// whitespace (with `#` comments to the end of a line), one whitespace byte, then the rows
/// top to bottom, RGB, one byte per sample when maxval < 256, else two (big-endian).
fn decode_ppm(bytes: &[u8]) -> Result<TexelImage, String> {
    if !bytes.get(2).is_some_and(u8::is_ascii_whitespace) {
        return Err("bad PPM header: P6 is not followed by whitespace".into());
    }
    let mut pos = 2;
    let mut field = |what: &str| -> Result<u64, String> {
        // Whitespace and comments before the number.
        loop {
            match bytes.get(pos) {
                Some(b) if b.is_ascii_whitespace() => pos += 1,
                Some(b'#') => {
                    while bytes.get(pos).is_some_and(|&b| b != b'\n' && b != b'\r') {
                        pos += 1;
                    }
                }
                _ => break,
            }
        }
        let start = pos;
        while bytes.get(pos).is_some_and(u8::is_ascii_digit) {
            pos += 1;
        }
        let digits = &bytes[start..pos];
        if digits.is_empty() {
            return Err(match bytes.get(pos) {
                None => format!("bad PPM header: the file ends before the {what}"),
                Some(&b) => format!(
                    "bad PPM header: the {what} is not a number (found {:?})",
                    char::from(b)
                ),
            });
        }
        // At most 20 digits fit in a u64; longer is absurd anyway.
        std::str::from_utf8(digits)
            .ok()
            .and_then(|d| d.parse::<u64>().ok())
            .ok_or_else(|| format!("bad PPM header: the {what} is too large"))
    };
    let width = field("width")?;
    let height = field("height")?;
    let maxval = field("maxval")?;
    if !(1..=65_535).contains(&maxval) {
        return Err(format!(
            "bad PPM header: maxval {maxval} is not in 1..=65535"
        ));
    }
    match bytes.get(pos) {
        Some(b) if b.is_ascii_whitespace() => pos += 1,
        // No pixels at all: reported as truncated below.
        None => {}
        Some(&b) => {
            return Err(format!(
                "bad PPM header: the maxval is followed by {:?}, not by whitespace",
                char::from(b)
            ))
        }
    }
    check_size(width, height)?;
    let (w, h) = (width as usize, height as usize);
    let bytes_per_sample = if maxval < 256 { 1 } else { 2 };
    let expected = w * h * 3 * bytes_per_sample;
    let pixels = &bytes[pos..];
    if pixels.len() < expected {
        return Err(format!(
            "truncated PPM: expected {expected} bytes of pixels, found {}",
            pixels.len()
        ));
    }
    let maxval = maxval as u32;
    let table = linear_table(maxval);
    let row_bytes = w * 3 * bytes_per_sample;
    let mut texels = Vec::with_capacity(w * h);
    // Bottom row first.
    for (r, row) in pixels[..expected].chunks_exact(row_bytes).enumerate().rev() {
        if bytes_per_sample == 1 {
            // The table has maxval + 1 entries: a sample above the maxval is the only miss.
            for (x, p) in row.chunks_exact(3).enumerate() {
                match (
                    table.get(p[0] as usize),
                    table.get(p[1] as usize),
                    table.get(p[2] as usize),
                ) {
                    (Some(&r), Some(&g), Some(&b)) => texels.push(Rgb::new(r, g, b)),
                    _ => return Err(above_maxval(p.iter().map(|&s| u32::from(s)), maxval, x, r)),
                }
            }
        } else {
            for (x, p) in row.chunks_exact(6).enumerate() {
                let s = [0, 2, 4].map(|k| u32::from(u16::from_be_bytes([p[k], p[k + 1]])));
                match (
                    table.get(s[0] as usize),
                    table.get(s[1] as usize),
                    table.get(s[2] as usize),
                ) {
                    (Some(&r), Some(&g), Some(&b)) => texels.push(Rgb::new(r, g, b)),
                    _ => return Err(above_maxval(s.into_iter(), maxval, x, r)),
                }
            }
        }
    }
    Ok(TexelImage {
        width: width as u32,
        height: height as u32,
        texels,
    })
}

/// The message for pixel `(x, y)` (from the top) with a sample above the maxval.
fn above_maxval(samples: impl Iterator<Item = u32>, maxval: u32, x: usize, y: usize) -> String {
    let s = samples.max().unwrap_or(0);
    format!("PPM sample {s} of pixel ({x}, {y}) is more than the maxval {maxval}")
}

/// PNG or JPEG through the `image` crate, its size checked before the pixels are decoded.
fn decode_with_image_crate(bytes: &[u8], format: image::ImageFormat) -> Result<TexelImage, String> {
    let name = if format == image::ImageFormat::Png {
        "PNG"
    } else {
        "JPEG"
    };
    let reader = || image::ImageReader::with_format(std::io::Cursor::new(bytes), format);
    let (width, height) = reader()
        .into_dimensions()
        .map_err(|e| format!("cannot decode {name}: {}", one_line(&e.to_string())))?;
    check_size(u64::from(width), u64::from(height))?;
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(MAX_TEXTURE_SIDE);
    limits.max_image_height = Some(MAX_TEXTURE_SIDE);
    // RGBA with 16-bit samples at the largest size.
    limits.max_alloc = Some(u64::from(MAX_TEXTURE_SIDE).pow(2) * 8);
    let mut decoder = reader();
    decoder.limits(limits);
    let picture = decoder
        .decode()
        .map_err(|e| format!("cannot decode {name}: {}", one_line(&e.to_string())))?;
    let (w, h) = (picture.width() as usize, picture.height() as usize);
    let sixteen_bit = matches!(
        picture.color(),
        image::ColorType::L16
            | image::ColorType::La16
            | image::ColorType::Rgb16
            | image::ColorType::Rgba16
    );
    let mut texels = Vec::with_capacity(w * h);
    if sixteen_bit {
        let table = linear_table(65_535);
        let rgb = picture.to_rgb16();
        for row in rgb.as_raw().chunks_exact(w * 3).rev() {
            texels.extend(row.chunks_exact(3).map(|p| {
                Rgb::new(
                    table[p[0] as usize],
                    table[p[1] as usize],
                    table[p[2] as usize],
                )
            }));
        }
    } else {
        let table = linear_table(255);
        let rgb = picture.to_rgb8();
        for row in rgb.as_raw().chunks_exact(w * 3).rev() {
            texels.extend(row.chunks_exact(3).map(|p| {
                Rgb::new(
                    table[p[0] as usize],
                    table[p[1] as usize],
                    table[p[2] as usize],
                )
            }));
        }
    }
    debug_assert_eq!(texels.len(), w * h);
    Ok(TexelImage {
        width,
        height,
        texels,
    })
}

/// A decoder's message on one line.
fn one_line(s: &str) -> String {
    s.split_whitespace().collect::<Vec<_>>().join(" ")
}

/// A texture of the table, with the statistics Phong materials derive their weights from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TextureRef {
    /// Index into [`TextureTable::textures`].
    pub id: u32,
    /// Per-channel maximum and average of the texels.
    pub max: Rgb,
    pub avg: Rgb,
}

/// A decoded file's place in the texel array.
#[derive(Clone, Copy, Debug)]
struct FileEntry {
    width: u32,
    height: u32,
    first_texel: u32,
    max: Rgb,
    avg: Rgb,
}

/// The scene's textures as the kernel reads them ([`ember_kernel::texture::Textures`]): each
/// distinct file is decoded once and its texels shared by every map that names it; maps of
/// one file with the same `-s`/`-o` share one texture entry.
#[derive(Clone, Debug, Default)]
pub struct TextureTable {
    pub textures: Vec<Texture>,
    pub texels: Vec<Rgb>,
    /// The files decoded, in the order they were first used.
    pub files: Vec<PathBuf>,
    by_file: HashMap<PathBuf, FileEntry>,
    by_map: HashMap<(u32, [u32; 4]), u32>,
}

impl TextureTable {
    /// The texture of `file` seen through the coordinate transform `uv·scale + offset`,
    /// reading and decoding the file the first time it is named.
    ///
    /// # Errors
    /// When the file cannot be read or decoded ([`decode`]), or the scene's texels would
    /// outgrow the kernel's `u32` texel index.
    pub fn get(
        &mut self,
        file: &Path,
        scale: Vec2,
        offset: Vec2,
        files: &dyn FileSource,
    ) -> Result<TextureRef, String> {
        let entry = match self.by_file.get(file) {
            Some(&e) => e,
            None => {
                let bytes = files.read(file).map_err(|e| format!("cannot read: {e}"))?;
                let picture = decode(&bytes)?;
                let first_texel = u32::try_from(self.texels.len())
                    .ok()
                    .filter(|&f| u64::from(f) + picture.texels.len() as u64 <= u64::from(u32::MAX))
                    .ok_or_else(|| {
                        format!(
                            "the scene's textures would hold more than {} texels",
                            u32::MAX
                        )
                    })?;
                let (max, avg) = texel_stats(&picture.texels)
                    .ok_or_else(|| "the image has no texels".to_string())?;
                self.texels.extend_from_slice(&picture.texels);
                let e = FileEntry {
                    width: picture.width,
                    height: picture.height,
                    first_texel,
                    max,
                    avg,
                };
                self.by_file.insert(file.to_path_buf(), e);
                self.files.push(file.to_path_buf());
                e
            }
        };
        let key = (
            entry.first_texel,
            [scale.x, scale.y, offset.x, offset.y].map(f32::to_bits),
        );
        let id = match self.by_map.get(&key) {
            Some(&id) => id,
            None => {
                let id = self.textures.len() as u32;
                self.textures.push(Texture {
                    uv_scale: scale,
                    uv_offset: offset,
                    ..Texture::new(entry.width, entry.height, entry.first_texel)
                });
                self.by_map.insert(key, id);
                id
            }
        };
        Ok(TextureRef {
            id,
            max: entry.max,
            avg: entry.avg,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::cell::Cell;

    /// TinyRender's conversion of one sample.
    fn lin(c: u32, maxval: u32) -> f32 {
        (c as f32 / maxval as f32).powf(2.2)
    }

    fn rgb(c: [u32; 3], maxval: u32) -> Rgb {
        Rgb::new(lin(c[0], maxval), lin(c[1], maxval), lin(c[2], maxval))
    }

    /// A 3×2 picture, top row then bottom row, 8-bit.
    const TOP: [[u8; 3]; 3] = [[255, 0, 0], [0, 255, 0], [0, 0, 255]];
    const BOTTOM: [[u8; 3]; 3] = [[10, 20, 30], [128, 128, 128], [255, 255, 255]];

    fn ppm_3x2(header: &str) -> Vec<u8> {
        let mut b = header.as_bytes().to_vec();
        b.extend(TOP.iter().chain(&BOTTOM).flatten());
        b
    }

    fn expected_3x2() -> Vec<Rgb> {
        BOTTOM
            .iter()
            .chain(&TOP)
            .map(|p| rgb(p.map(u32::from), 255))
            .collect()
    }

    #[test]
    fn ppm_texels_are_linearised_and_bottom_row_first() {
        let t = decode(&ppm_3x2("P6\n3 2\n255\n")).unwrap();
        assert_eq!((t.width, t.height), (3, 2));
        assert_eq!(t.texels, expected_3x2());
        // Row flip: texel 0 is the picture's bottom-left pixel.
        assert_eq!(t.texels[0], rgb([10, 20, 30], 255));
        assert_eq!(t.texels[3], Rgb::new(1.0, 0.0, 0.0));
        assert_eq!(t.texels[4], Rgb::new(0.0, 1.0, 0.0));
        // Mid grey: (128/255)^2.2, about 0.2195.
        assert!((t.texels[1].x - 0.219_526).abs() < 1e-5, "{}", t.texels[1]);
        // Comments and any whitespace in the header.
        let t2 = decode(&ppm_3x2("P6 # made by hand\n3\t2 # size\r\n255\n")).unwrap();
        assert_eq!(t2, t);
    }

    #[test]
    fn ppm_maxval_below_255_and_16_bit() {
        // maxval 15: one byte per sample.
        let mut b = b"P6\n2 1\n15\n".to_vec();
        b.extend([15, 0, 7, 1, 2, 3]);
        let t = decode(&b).unwrap();
        assert_eq!(t.texels, [rgb([15, 0, 7], 15), rgb([1, 2, 3], 15)]);
        // maxval 1000: two bytes per sample, big-endian.
        let samples: [u16; 6] = [1000, 500, 0, 1, 256, 999];
        let mut b = b"P6\n2 1\n1000\n".to_vec();
        b.extend(samples.iter().flat_map(|s| s.to_be_bytes()));
        let t = decode(&b).unwrap();
        assert_eq!(
            t.texels,
            [rgb([1000, 500, 0], 1000), rgb([1, 256, 999], 1000)]
        );
        assert_eq!(t.texels[0].x, 1.0);
        // maxval 65535 with a sample of 65535: 1.
        let mut b = b"P6\n1 1\n65535\n".to_vec();
        b.extend([0xFF, 0xFF, 0x80, 0x00, 0, 0]);
        let t = decode(&b).unwrap();
        assert_eq!(t.texels, [rgb([65535, 32768, 0], 65535)]);
    }

    #[test]
    fn bad_ppm_and_other_files_are_refused() {
        let e = |b: &[u8]| decode(b).unwrap_err();
        assert_eq!(
            e(b"P6\n2 2\n255\n\x01\x02\x03"),
            "truncated PPM: expected 12 bytes of pixels, found 3"
        );
        assert_eq!(
            e(b"P6\n2 2\n255"),
            "truncated PPM: expected 12 bytes of pixels, found 0"
        );
        assert_eq!(
            e(b"P6\n2 2\n65535\n\0\0\0\0\0\0"),
            "truncated PPM: expected 24 bytes of pixels, found 6"
        );
        assert_eq!(
            e(b"P6\nwide 2\n255\n"),
            "bad PPM header: the width is not a number (found 'w')"
        );
        assert_eq!(
            e(b"P6\n2"),
            "bad PPM header: the file ends before the height"
        );
        assert_eq!(
            e(b"P6\n2 2\n0\n"),
            "bad PPM header: maxval 0 is not in 1..=65535"
        );
        assert_eq!(
            e(b"P6\n2 2\n65536\n"),
            "bad PPM header: maxval 65536 is not in 1..=65535"
        );
        assert_eq!(
            e(b"P6\n2 2\n255x"),
            "bad PPM header: the maxval is followed by 'x', not by whitespace"
        );
        assert_eq!(
            e(b"P62 2 255\n"),
            "bad PPM header: P6 is not followed by whitespace"
        );
        assert_eq!(
            e(b"P6\n99999999999999999999999 2\n255\n"),
            "bad PPM header: the width is too large"
        );
        assert_eq!(e(b"P6\n0 4\n255\n"), "image size 0x4 is empty");
        // Refused from the header alone, before any pixel is read or allocated.
        assert_eq!(
            e(b"P6\n20000 20000\n255\n"),
            "image size 20000x20000 is larger than 16384x16384"
        );
        assert_eq!(
            e(b"P6\n1 1\n100\n\xc8\x00\x00"),
            "PPM sample 200 of pixel (0, 0) is more than the maxval 100"
        );
        assert_eq!(
            e(b"P3\n1 1\n255\n0 0 0\n"),
            "Netpbm images of type P3 are not supported; use binary PPM (P6), PNG or JPEG"
        );
        for not_an_image in [&b""[..], b"hello", b"GIF89a", b"P"] {
            assert_eq!(
                e(not_an_image),
                "not an image (expected binary PPM (P6), PNG or JPEG)"
            );
        }
    }

    /// A PNG of `width × height` RGB samples (8 or 16 bits, big-endian for 16).
    fn png(
        width: u32,
        height: u32,
        depth: png::BitDepth,
        colour: png::ColorType,
        data: &[u8],
    ) -> Vec<u8> {
        let mut out = Vec::new();
        let mut enc = png::Encoder::new(&mut out, width, height);
        enc.set_color(colour);
        enc.set_depth(depth);
        let mut w = enc.write_header().unwrap();
        w.write_image_data(data).unwrap();
        w.finish().unwrap();
        out
    }

    #[test]
    fn png_gives_the_texels_of_the_same_ppm() {
        let pixels: Vec<u8> = TOP.iter().chain(&BOTTOM).flatten().copied().collect();
        let p = decode(&png(
            3,
            2,
            png::BitDepth::Eight,
            png::ColorType::Rgb,
            &pixels,
        ))
        .unwrap();
        assert_eq!(p, decode(&ppm_3x2("P6\n3 2\n255\n")).unwrap());
        assert_eq!(p.texels, expected_3x2());
        // RGBA: alpha is dropped.
        let rgba: Vec<u8> = TOP
            .iter()
            .chain(&BOTTOM)
            .flat_map(|p| [p[0], p[1], p[2], 77])
            .collect();
        let q = decode(&png(
            3,
            2,
            png::BitDepth::Eight,
            png::ColorType::Rgba,
            &rgba,
        ))
        .unwrap();
        assert_eq!(q, p);
        // Grey: the sample in all three channels.
        let g = decode(&png(
            2,
            1,
            png::BitDepth::Eight,
            png::ColorType::Grayscale,
            &[0, 128],
        ))
        .unwrap();
        assert_eq!(g.texels, [Rgb::ZERO, Rgb::splat(lin(128, 255))]);
        // Palette: the palette's colours.
        let mut out = Vec::new();
        let mut enc = png::Encoder::new(&mut out, 2, 1);
        enc.set_color(png::ColorType::Indexed);
        enc.set_depth(png::BitDepth::Eight);
        enc.set_palette(vec![10, 20, 30, 200, 100, 0]);
        let mut w = enc.write_header().unwrap();
        w.write_image_data(&[1, 0]).unwrap();
        w.finish().unwrap();
        let t = decode(&out).unwrap();
        assert_eq!(t.texels, [rgb([200, 100, 0], 255), rgb([10, 20, 30], 255)]);
    }

    #[test]
    fn png_16_bit_is_divided_by_65535() {
        let samples: [u16; 6] = [65535, 32768, 0, 1, 1000, 40000];
        let bytes: Vec<u8> = samples.iter().flat_map(|s| s.to_be_bytes()).collect();
        let p = decode(&png(
            1,
            2,
            png::BitDepth::Sixteen,
            png::ColorType::Rgb,
            &bytes,
        ))
        .unwrap();
        // Bottom row (the second pixel) first.
        assert_eq!(
            p.texels,
            [rgb([1, 1000, 40000], 65535), rgb([65535, 32768, 0], 65535)]
        );
        let mut ppm = b"P6\n1 2\n65535\n".to_vec();
        ppm.extend(&bytes);
        assert_eq!(decode(&ppm).unwrap(), p);
    }

    #[test]
    fn jpeg_loads_with_the_same_conventions() {
        // 16×16: top half one flat colour, bottom half another (whole 8×8 blocks, so the
        // lossy coding keeps each flat up to a few codes).
        let (top, bottom) = ([200u8, 60, 30], [20u8, 90, 220]);
        let picture =
            image::RgbImage::from_fn(16, 16, |_, y| image::Rgb(if y < 8 { top } else { bottom }));
        let mut jpeg = Vec::new();
        image::codecs::jpeg::JpegEncoder::new_with_quality(&mut jpeg, 100)
            .encode_image(&picture)
            .unwrap();
        let t = decode(&jpeg).unwrap();
        assert_eq!((t.width, t.height), (16, 16));
        // Each texel within 3 codes of its colour, linearised by (c/255)^2.2.
        let close = |texel: Rgb, c: [u8; 3]| {
            (0..3).all(|k| {
                let lo = lin(u32::from(c[k]).saturating_sub(3), 255);
                let hi = lin((u32::from(c[k]) + 3).min(255), 255);
                (lo..=hi).contains(&texel[k])
            })
        };
        for (i, texel) in t.texels.iter().enumerate() {
            let row_from_bottom = i / 16;
            let expected = if row_from_bottom < 8 { bottom } else { top };
            assert!(
                close(*texel, expected),
                "texel {i}: {texel} vs {expected:?}"
            );
        }
    }

    #[test]
    fn broken_png_and_jpeg_are_refused_on_one_line() {
        let pixels = [0u8; 12];
        let full = png(2, 2, png::BitDepth::Eight, png::ColorType::Rgb, &pixels);
        let e = decode(&full[..full.len() - 20]).unwrap_err();
        assert!(e.starts_with("cannot decode PNG: "), "{e}");
        assert!(!e.contains('\n'), "{e}");
        let e = decode(&[0xFF, 0xD8, 0xFF, 0xE0, 0, 0]).unwrap_err();
        assert!(e.starts_with("cannot decode JPEG: "), "{e}");
        // A zero-sized PNG header cannot be written with the png crate; an absurd one can be
        // declared: the size is refused before decoding.
        let mut huge = full.clone();
        // IHDR width at bytes 16..20 (big-endian), then its CRC, which the reader checks.
        huge[16..20].copy_from_slice(&20_000u32.to_be_bytes());
        let crc = crc32(&huge[12..29]);
        huge[29..33].copy_from_slice(&crc.to_be_bytes());
        assert_eq!(
            decode(&huge).unwrap_err(),
            "image size 20000x2 is larger than 16384x16384"
        );
    }

    /// CRC-32 (IEEE) of PNG chunks.
    fn crc32(bytes: &[u8]) -> u32 {
        let mut c = !0u32;
        for &b in bytes {
            c ^= u32::from(b);
            for _ in 0..8 {
                c = if c & 1 != 0 {
                    0xEDB8_8320 ^ (c >> 1)
                } else {
                    c >> 1
                };
            }
        }
        !c
    }

    #[test]
    fn each_file_is_decoded_once_and_shared() {
        let reads = Cell::new(0);
        let ppm = ppm_3x2("P6\n3 2\n255\n");
        let files = |_: &Path| {
            reads.set(reads.get() + 1);
            Some(ppm.clone())
        };
        let mut table = TextureTable::default();
        let a = table
            .get(Path::new("t.ppm"), Vec2::ONE, Vec2::ZERO, &files)
            .unwrap();
        let b = table
            .get(Path::new("t.ppm"), Vec2::ONE, Vec2::ZERO, &files)
            .unwrap();
        let c = table
            .get(
                Path::new("t.ppm"),
                Vec2::splat(2.0),
                Vec2::new(0.5, 0.0),
                &files,
            )
            .unwrap();
        assert_eq!(reads.get(), 1);
        assert_eq!(a, b);
        assert_ne!(a.id, c.id);
        assert_eq!(table.texels, expected_3x2());
        assert_eq!(table.files, [PathBuf::from("t.ppm")]);
        assert_eq!(table.textures.len(), 2);
        assert_eq!(table.textures[0].first_texel, table.textures[1].first_texel);
        assert_eq!(table.textures[1].uv_scale, Vec2::splat(2.0));
        assert_eq!(table.textures[1].uv_offset, Vec2::new(0.5, 0.0));
        let (max, avg) = texel_stats(&expected_3x2()).unwrap();
        assert_eq!((a.max, a.avg), (max, avg));
        // A second file goes after the first.
        let d = table
            .get(Path::new("u.ppm"), Vec2::ONE, Vec2::ZERO, &files)
            .unwrap();
        assert_eq!(table.textures[d.id as usize].first_texel, 6);
        assert_eq!(reads.get(), 2);
    }
}
