//! Compatibility with the TinyRender Cornell box references (`cbox_path_*_REF.exr`, 800×600,
//! 128 spp, unknown seed): every path scene is rendered at a quarter of the resolution in each
//! direction and compared with the reference box-filtered to the same size by
//! - mean RGB and 8×6 block means: z-tests of the difference;
//! - per pixel: the summed squared differences against the summed variances (a bias anywhere
//!   in the image adds to the squared differences and shows up as a positive z).
//!
//! Variance model: our render has `S` samples per (quarter-resolution) pixel, with per-pixel
//! sample variances measured. A reference quarter-pixel averages 16 pixels × 128 samples =
//! 2048 samples of the same distribution, so its variance is ours × S / 2048.
//! Every z-test in a test function shares α = 0.01 (Šidák correction), so the tolerance is
//! derived from the measured noise, never a hand-picked number.
//! Set `EMBER_SPP_SCALE` to multiply the sample counts for a more powerful local run.

mod common;

use common::*;
use ember_cli::image::{read_exr, Image};
use ember_cli::render::Rendered;
use ember_kernel::Rgb;
use std::collections::HashMap;
use std::sync::{Mutex, OnceLock};

const FACTOR: u32 = 4;
const W: u32 = 800 / FACTOR;
const H: u32 = 600 / FACTOR;
const BX: u32 = 8;
const BY: u32 = 6;
const REF_SAMPLES: f32 = 128.0 * (FACTOR * FACTOR) as f32;

/// (scene, reference, spp): implicit paths are noisier, so they get more samples.
const CASES: &[(&str, &str, u32)] = &[
    (
        "cbox_path_explicit_0_bounce.toml",
        "cbox_path_explicit_0_bounce_REF.exr",
        16,
    ),
    (
        "cbox_path_implicit_0_bounce.toml",
        "cbox_path_implicit_0_bounce_REF.exr",
        16,
    ),
    (
        "cbox_path_explicit_1_bounce.toml",
        "cbox_path_explicit_1_bounce_REF.exr",
        32,
    ),
    (
        "cbox_path_implicit_1_bounce.toml",
        "cbox_path_implicit_1_bounce_REF.exr",
        128,
    ),
    (
        "cbox_path_explicit_2_bounces.toml",
        "cbox_path_explicit_2_bounces_REF.exr",
        32,
    ),
    (
        "cbox_path_implicit_2_bounces.toml",
        "cbox_path_implicit_2_bounces_REF.exr",
        128,
    ),
    (
        "cbox_path_explicit_4_bounces.toml",
        "cbox_path_explicit_4_bounces_REF.exr",
        32,
    ),
    (
        "cbox_path_implicit.toml",
        "cbox_path_implicit_4_bounces_REF.exr",
        128,
    ),
    (
        "cbox_path_explicit_rr.toml",
        "cbox_path_explicit_rr_REF.exr",
        32,
    ),
    // ember's MIS path tracer (not a TinyRender integrator) on the same scene and reference.
    (MIS_RR, "cbox_path_explicit_rr_REF.exr", 32),
];

/// Pseudo-name: the `_rr` scene rendered with `Integrator::PathMis`.
const MIS_RR: &str = "cbox_path_explicit_rr.toml#mis";

/// Same-depth pairs (explicit, implicit).
const PAIRS: &[(&str, &str)] = &[
    (
        "cbox_path_explicit_0_bounce.toml",
        "cbox_path_implicit_0_bounce.toml",
    ),
    (
        "cbox_path_explicit_1_bounce.toml",
        "cbox_path_implicit_1_bounce.toml",
    ),
    (
        "cbox_path_explicit_2_bounces.toml",
        "cbox_path_implicit_2_bounces.toml",
    ),
    (
        "cbox_path_explicit_4_bounces.toml",
        "cbox_path_implicit.toml",
    ),
];

fn spp_scale() -> u32 {
    std::env::var("EMBER_SPP_SCALE")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(1)
}

/// Each scene is rendered once per test process and shared by the tests.
fn rendered(toml: &'static str) -> std::sync::Arc<Rendered> {
    static CACHE: OnceLock<Mutex<HashMap<&'static str, std::sync::Arc<Rendered>>>> =
        OnceLock::new();
    let cache = CACHE.get_or_init(Default::default);
    if let Some(r) = cache.lock().unwrap().get(toml) {
        return r.clone();
    }
    let spp = CASES.iter().find(|c| c.0 == toml).unwrap().2 * spp_scale();
    // A seed per scene keeps the implicit and explicit renders independent (the same seed
    // would correlate their camera samples and shrink their differences below the noise).
    let seed = ember_kernel::sampler::mix64(
        toml.bytes()
            .fold(0u64, |h, b| h.wrapping_mul(31).wrapping_add(u64::from(b))),
    );
    let (file, integrator) = match toml.split_once('#') {
        Some((file, "mis")) => (file, Some(ember_kernel::integrator::Integrator::PathMis)),
        _ => (toml, None),
    };
    let r = std::sync::Arc::new(render_scene_full(
        &cbox_scene(file),
        integrator,
        W,
        H,
        spp,
        seed,
        16,
        0,
    ));
    assert_eq!(r.image.non_finite_count(), 0, "{toml}: non-finite pixels");
    assert_eq!(r.invalid_samples, 0, "{toml}: invalid samples");
    cache.lock().unwrap().insert(toml, r.clone());
    r
}

fn spp_of(toml: &str) -> f32 {
    (CASES.iter().find(|c| c.0 == toml).unwrap().2 * spp_scale()) as f32
}

fn scaled(v: &[Rgb], k: f32) -> Vec<Rgb> {
    v.iter().map(|x| *x * k).collect()
}

/// Variance of the image mean from per-pixel variances of the means.
fn mean_variance(var: &Image) -> Rgb {
    (var.mean().as_dvec3() / var.pixels.len() as f64).as_vec3()
}

#[test]
#[cfg_attr(debug_assertions, ignore = "slow statistical test: run with --release")]
fn path_scenes_match_the_tinyrender_references() {
    let tests_per_case = 3 * (1 + BX * BY) as usize + 1;
    let z_crit = critical_z(0.01, tests_per_case * CASES.len());
    let mut failures = Vec::new();
    for &(toml, reference, _) in CASES {
        let r = rendered(toml);
        let reference = read_exr(&cbox_scene(reference))
            .unwrap()
            .downsample(FACTOR, FACTOR);
        assert_eq!((reference.width, reference.height), (W, H));
        let k = spp_of(toml) / REF_SAMPLES;
        let vm = mean_variance(&r.variance);
        let m = z_scores(
            "mean",
            &[r.image.mean()],
            &[vm],
            &[reference.mean()],
            &[vm * k],
        );
        let vb = block_mean_variances(&r.variance, BX, BY);
        let b = z_scores(
            "block",
            &r.image.block_means(BX, BY),
            &vb,
            &reference.block_means(BX, BY),
            &scaled(&vb, k),
        );
        let (ratio, pz) = pixel_mse_z(&r.image, &reference, |i| {
            r.variance.pixels[i].as_dvec3() * (1.0 + f64::from(k))
        });
        let (ours, theirs) = (r.image.mean(), reference.mean());
        println!(
            "{toml:36} mean {:.4} {:.4} {:.4} ref {:.4} {:.4} {:.4} | max|z| mean {:.2} blocks {:.2} | pixel mse/var {ratio:.3} (z {pz:.2})",
            ours.x, ours.y, ours.z, theirs.x, theirs.y, theirs.z, m.max_abs_z, b.max_abs_z
        );
        for rep in [m, b] {
            if rep.max_abs_z > z_crit {
                failures.push(format!("{toml}: {}", rep.worst));
            }
        }
        // One-sided: only excess error means bias. (Fewer squared differences than the
        // variances predict is expected where our quarter-resolution pixels straddle edges:
        // their variance includes the signal variation inside the pixel.)
        if pz > z_crit {
            failures.push(format!(
                "{toml}: per-pixel mse/variance {ratio:.3}, z {pz:.2}"
            ));
        }
    }
    println!("critical |z| = {z_crit:.2}");
    assert!(
        failures.is_empty(),
        "differences beyond noise:\n{}",
        failures.join("\n")
    );
}

#[test]
#[cfg_attr(debug_assertions, ignore = "slow statistical test: run with --release")]
fn implicit_and_explicit_agree_at_each_depth() {
    let tests_per_pair = 3 * (1 + BX * BY) as usize + 1;
    let z_crit = critical_z(0.01, tests_per_pair * PAIRS.len());
    let mut failures = Vec::new();
    for &(explicit, implicit) in PAIRS {
        let (e, i) = (rendered(explicit), rendered(implicit));
        let m = z_scores(
            "mean",
            &[e.image.mean()],
            &[mean_variance(&e.variance)],
            &[i.image.mean()],
            &[mean_variance(&i.variance)],
        );
        let b = z_scores(
            "block",
            &e.image.block_means(BX, BY),
            &block_mean_variances(&e.variance, BX, BY),
            &i.image.block_means(BX, BY),
            &block_mean_variances(&i.variance, BX, BY),
        );
        let (ratio, pz) = pixel_mse_z(&e.image, &i.image, |p| {
            (e.variance.pixels[p] + i.variance.pixels[p]).as_dvec3()
        });
        println!(
            "{explicit:36} vs implicit: max|z| mean {:.2} blocks {:.2} | pixel mse/var {ratio:.3} (z {pz:.2})",
            m.max_abs_z, b.max_abs_z
        );
        for rep in [m, b] {
            if rep.max_abs_z > z_crit {
                failures.push(format!("{explicit} vs {implicit}: {}", rep.worst));
            }
        }
        if pz > z_crit {
            failures.push(format!(
                "{explicit} vs {implicit}: per-pixel mse/variance {ratio:.3}"
            ));
        }
    }
    println!("critical |z| = {z_crit:.2}");
    assert!(
        failures.is_empty(),
        "differences beyond noise:\n{}",
        failures.join("\n")
    );
}
