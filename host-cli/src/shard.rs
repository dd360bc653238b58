//! Renders split across processes: partial EXRs of shards and their merge.
//!
//! A partial EXR has the channels `R`, `G`, `B` (f32 means, 0 outside the shard) and
//! `ember.spp` (u32 samples per pixel, 0 outside the shard). Its layer name records the shard
//! (`i/n`) and a key of everything that determines the image (scene file, size, spp, seed,
//! integrator, path settings, tile size), so that parts of different renders are never merged.

use crate::error::{Error, Result};
use crate::image::{write_atomically, Image};
use crate::render::{shard_coverage, RenderSettings, Rendered, Shard};
use ember_kernel::Rgb;
use std::path::Path;

/// What a partial render is a part of.
#[must_use]
pub fn render_key(scene: &Path, width: u32, height: u32, s: &RenderSettings) -> String {
    format!(
        "{} {width}x{height} spp={} seed={} {:?} maxDepth={} rrDepth={} rrProb={} tile={}",
        scene.display(),
        s.spp,
        s.seed,
        s.integrator,
        s.path.max_depth,
        s.path.rr_depth,
        s.path.rr_prob,
        s.tile
    )
}

/// A shard as read back: its image, per-pixel sample counts and identity.
#[derive(Clone, Debug, PartialEq)]
pub struct Partial {
    pub image: Image,
    pub spp: Vec<u32>,
    pub shard: Shard,
    pub key: String,
}

const LAYER_PREFIX: &str = "ember-shard ";

/// Writes the shard's pixels with their sample counts.
///
/// # Errors
/// When the file cannot be written.
pub fn write_partial(path: &Path, r: &Rendered, s: &RenderSettings, key: &str) -> Result<()> {
    use exr::prelude::{Encoding, Layer, LayerAttributes, SpecificChannels, Vec2, WritableImage};
    let (w, h) = (r.image.width, r.image.height);
    let covered = shard_coverage(w, h, s.tile, s.shard);
    write_atomically(path, |tmp| {
        let channels = SpecificChannels::build()
            .with_channel("B")
            .with_channel("G")
            .with_channel("R")
            .with_channel("ember.spp")
            .with_pixel_fn(|p: Vec2<usize>| {
                let i = p.y() * w as usize + p.x();
                let c = r.image.pixels[i];
                let n = if covered[i] { r.spp } else { 0 };
                (c.z, c.y, c.x, n)
            });
        let name = format!("{LAYER_PREFIX}{}/{} {key}", s.shard.index, s.shard.count);
        let layer = Layer::new(
            (w as usize, h as usize),
            LayerAttributes::named(name.as_str()),
            Encoding::SMALL_LOSSLESS,
            channels,
        );
        exr::image::Image::from_layer(layer)
            .write()
            .to_file(tmp)
            .map_err(|e| Error::in_file(path, format!("cannot write partial EXR: {e}")))
    })
}

/// Reads a partial EXR written by [`write_partial`].
///
/// # Errors
/// When the file is not such a partial.
pub fn read_partial(path: &Path) -> Result<Partial> {
    use exr::prelude::{read_all_flat_layers_from_file, FlatSamples};
    let bad = |m: String| Error::in_file(path, format!("not an ember partial render: {m}"));
    let img = read_all_flat_layers_from_file(path).map_err(|e| bad(e.to_string()))?;
    let layer = img
        .layer_data
        .first()
        .ok_or_else(|| bad("no layer".into()))?;
    let name = layer
        .attributes
        .layer_name
        .as_ref()
        .map(ToString::to_string)
        .unwrap_or_default();
    let rest = name
        .strip_prefix(LAYER_PREFIX)
        .ok_or_else(|| bad(format!("layer name {name:?}")))?;
    let (ij, key) = rest.split_once(' ').ok_or_else(|| bad("no key".into()))?;
    let (i, n) = ij.split_once('/').ok_or_else(|| bad("no shard".into()))?;
    let shard = Shard {
        index: i.parse().map_err(|_| bad("shard index".into()))?,
        count: n.parse().map_err(|_| bad("shard count".into()))?,
    };
    let size = layer.size;
    let channel = |n: &str| {
        layer
            .channel_data
            .list
            .iter()
            .find(|c| c.name.to_string() == n)
            .ok_or_else(|| bad(format!("no channel {n}")))
    };
    let f32s = |n: &str| -> Result<Vec<f32>> {
        match &channel(n)?.sample_data {
            FlatSamples::F32(v) => Ok(v.clone()),
            _ => Err(bad(format!("channel {n} is not f32"))),
        }
    };
    let (r, g, b) = (f32s("R")?, f32s("G")?, f32s("B")?);
    let spp = match &channel("ember.spp")?.sample_data {
        FlatSamples::U32(v) => v.clone(),
        _ => return Err(bad("channel ember.spp is not u32".into())),
    };
    let mut image = Image::new(size.width() as u32, size.height() as u32);
    for (i, p) in image.pixels.iter_mut().enumerate() {
        *p = Rgb::new(r[i], g[i], b[i]);
    }
    Ok(Partial {
        image,
        spp,
        shard,
        key: key.to_string(),
    })
}

/// Combines the shards of one render: every pixel must come from exactly one part, and all
/// parts must share size, shard count and key.
///
/// # Errors
/// Parts of different renders, missing or duplicated shards, pixels covered twice or never.
pub fn merge(parts: &[(std::path::PathBuf, Partial)]) -> Result<Image> {
    let Some((first_path, first)) = parts.first() else {
        return Err(Error::new("merge needs at least one partial render"));
    };
    let (w, h, n) = (first.image.width, first.image.height, first.shard.count);
    let mut seen = vec![false; n as usize];
    let mut out = Image::new(w, h);
    let mut from = vec![u32::MAX; out.pixels.len()];
    for (path, p) in parts {
        if (p.image.width, p.image.height) != (w, h) || p.shard.count != n || p.key != first.key {
            return Err(Error::in_file(
                path,
                format!(
                    "is a part of a different render than {} ({}x{}, {} shards, {:?})",
                    first_path.display(),
                    w,
                    h,
                    n,
                    first.key
                ),
            ));
        }
        let i = p.shard.index as usize;
        if i >= seen.len() || seen[i] {
            return Err(Error::in_file(
                path,
                format!("shard {i}/{n} given twice or out of range"),
            ));
        }
        seen[i] = true;
        for (k, &spp) in p.spp.iter().enumerate() {
            if spp > 0 {
                if from[k] != u32::MAX {
                    return Err(Error::in_file(path, format!("pixel {k} is in two shards")));
                }
                from[k] = p.shard.index;
                out.pixels[k] = p.image.pixels[k];
            }
        }
    }
    if let Some(missing) = seen.iter().position(|s| !s) {
        return Err(Error::new(format!("shard {missing}/{n} is missing")));
    }
    if let Some(k) = from.iter().position(|&f| f == u32::MAX) {
        return Err(Error::new(format!(
            "pixel ({}, {}) is in no shard (a partial was interrupted?)",
            k as u32 % w,
            k as u32 / w
        )));
    }
    Ok(out)
}
