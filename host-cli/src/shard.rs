//! Renders split across processes: partial EXRs of shards and their merge.
//!
//! A partial EXR has the channels `R`, `G`, `B` (f32 **sums** of each pixel's own samples,
//! exactly as the render accumulated them; 0 outside the shard) and `ember.spp` (u32 samples
//! per pixel, 0 outside the shard). Light tracing and BDPT splat onto every pixel of the film,
//! so their partials also carry the shard's fixed-point splat sums for the whole film, each
//! `i64` channel as two u32 halves (`ember.splat.R.hi`, `ember.splat.R.lo`, … for G and B).
//! The merge takes each pixel's own sums from the shard that owns it, adds the splat sums of
//! all shards as integers, and resolves the pixels with the one rule every render uses
//! ([`crate::splats::resolve`]): the merged image is bit-identical to one render. The layer
//! name records the shard (`i/n`) and a key of everything that determines the image (scene
//! file, size, spp, seed, integrator, path settings, tile size), so that parts of different
//! renders are never merged.

use crate::error::{Error, Result};
use crate::image::{write_atomically, Image};
use crate::render::{shard_coverage, RenderSettings, Rendered, Shard};
use crate::splats::resolve;
use ember_kernel::sampler::SamplerKind;
use ember_kernel::Rgb;
use std::path::Path;

/// What a partial render is a part of.
#[must_use]
pub fn render_key(scene: &Path, width: u32, height: u32, s: &RenderSettings) -> String {
    format!(
        "sums {} {width}x{height} spp={} seed={} {:?} maxDepth={} rrDepth={} rrProb={} tile={}",
        scene.display(),
        s.spp,
        s.seed,
        s.integrator,
        s.path.max_depth,
        s.path.rr_depth,
        s.path.rr_prob,
        s.tile
    ) + match s.sampler {
        // Keys of independent renders stay as they were before samplers could be chosen.
        SamplerKind::Independent => "",
        SamplerKind::ZSobol => " sampler=zsobol",
    }
}

/// A shard as read back: the own-sample sums of its pixels, per-pixel sample counts, its
/// splat sums (light tracing, BDPT) and identity.
#[derive(Clone, Debug, PartialEq)]
pub struct Partial {
    pub sums: Image,
    pub spp: Vec<u32>,
    pub splats: Option<Vec<[i64; 3]>>,
    pub shard: Shard,
    pub key: String,
}

/// The six u32 channels of the splat sums, in the order they are written.
const SPLAT_CHANNELS: [&str; 6] = [
    "ember.splat.B.hi",
    "ember.splat.B.lo",
    "ember.splat.G.hi",
    "ember.splat.G.lo",
    "ember.splat.R.hi",
    "ember.splat.R.lo",
];

const LAYER_PREFIX: &str = "ember-shard ";

/// Writes the shard's own-sample sums with their sample counts, and its splat sums.
///
/// # Errors
/// When the file cannot be written.
pub fn write_partial(path: &Path, r: &Rendered, s: &RenderSettings, key: &str) -> Result<()> {
    use exr::prelude::{
        AnyChannel, AnyChannels, Encoding, FlatSamples, Image as ExrImage, Layer, LayerAttributes,
        WritableImage,
    };
    let (w, h) = (r.sums.width, r.sums.height);
    let covered = shard_coverage(w, h, s.tile, s.shard);
    let n = w as usize * h as usize;
    let mut channels = vec![
        AnyChannel::new(
            "B",
            FlatSamples::F32(r.sums.pixels.iter().map(|p| p.z).collect()),
        ),
        AnyChannel::new(
            "G",
            FlatSamples::F32(r.sums.pixels.iter().map(|p| p.y).collect()),
        ),
        AnyChannel::new(
            "R",
            FlatSamples::F32(r.sums.pixels.iter().map(|p| p.x).collect()),
        ),
        AnyChannel::new(
            "ember.spp",
            FlatSamples::U32((0..n).map(|i| if covered[i] { r.spp } else { 0 }).collect()),
        ),
    ];
    if let Some(splats) = &r.splats {
        for (k, name) in SPLAT_CHANNELS.iter().enumerate() {
            let c = 2 - k / 2;
            let hi = k % 2 == 0;
            let half = |v: i64| {
                let u = v as u64;
                if hi {
                    (u >> 32) as u32
                } else {
                    u as u32
                }
            };
            channels.push(AnyChannel::new(
                *name,
                FlatSamples::U32(splats.iter().map(|p| half(p[c])).collect()),
            ));
        }
    }
    write_atomically(path, |tmp| {
        let name = format!("{LAYER_PREFIX}{}/{} {key}", s.shard.index, s.shard.count);
        let layer = Layer::new(
            (w as usize, h as usize),
            LayerAttributes::named(name.as_str()),
            Encoding::SMALL_LOSSLESS,
            AnyChannels::sort(channels.into()),
        );
        ExrImage::from_layer(layer)
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
    let u32s = |n: &str| -> Result<Vec<u32>> {
        match &channel(n)?.sample_data {
            FlatSamples::U32(v) => Ok(v.clone()),
            _ => Err(bad(format!("channel {n} is not u32"))),
        }
    };
    let (r, g, b) = (f32s("R")?, f32s("G")?, f32s("B")?);
    let spp = u32s("ember.spp")?;
    let mut sums = Image::new(size.width() as u32, size.height() as u32);
    for (i, p) in sums.pixels.iter_mut().enumerate() {
        *p = Rgb::new(r[i], g[i], b[i]);
    }
    let splats = if channel(SPLAT_CHANNELS[0]).is_ok() {
        let halves: Vec<Vec<u32>> = SPLAT_CHANNELS
            .iter()
            .map(|n| u32s(n))
            .collect::<Result<_>>()?;
        let whole = |k: usize, i: usize| {
            ((u64::from(halves[k][i]) << 32) | u64::from(halves[k + 1][i])) as i64
        };
        Some(
            (0..sums.pixels.len())
                .map(|i| [whole(4, i), whole(2, i), whole(0, i)])
                .collect(),
        )
    } else {
        None
    };
    Ok(Partial {
        sums,
        spp,
        splats,
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
    let (w, h, n) = (first.sums.width, first.sums.height, first.shard.count);
    let mut seen = vec![false; n as usize];
    let mut sums = Image::new(w, h);
    let mut spp = vec![0u32; sums.pixels.len()];
    let mut splats: Option<Vec<[i64; 3]>> = None;
    let mut from = vec![u32::MAX; sums.pixels.len()];
    for (path, p) in parts {
        if (p.sums.width, p.sums.height) != (w, h)
            || p.shard.count != n
            || p.key != first.key
            || p.splats.is_some() != first.splats.is_some()
        {
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
        for (k, &n) in p.spp.iter().enumerate() {
            if n > 0 {
                if from[k] != u32::MAX {
                    return Err(Error::in_file(path, format!("pixel {k} is in two shards")));
                }
                from[k] = p.shard.index;
                sums.pixels[k] = p.sums.pixels[k];
                spp[k] = n;
            }
        }
        if let Some(part) = &p.splats {
            let total = splats.get_or_insert_with(|| vec![[0; 3]; part.len()]);
            for (t, v) in total.iter_mut().zip(part) {
                for c in 0..3 {
                    t[c] = t[c].saturating_add(v[c]);
                }
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
    let mut out = Image::new(w, h);
    for (i, p) in out.pixels.iter_mut().enumerate() {
        let s = splats.as_ref().map_or([0; 3], |s| s[i]);
        *p = resolve(sums.pixels[i], s, spp[i]);
    }
    Ok(out)
}
