//! ember against Mitsuba 3 on the mirror and glass Cornell boxes of `data/mirror-glass`: a
//! mirror box (`illum 5`, Ks 0.95) and a glass sphere (`illum 6`, Ni 1.5), smooth
//! (`mirror_glass.toml`) and rough (`mirror_glass_rough.toml`, GGX alpha 0.09 on both).
//!
//! The references are committed (`bench/mitsuba/refs/<stem>_mitsuba_{mean,var}.exr`, made by
//! `bench/mitsuba/materials.sh`; see `bench/mitsuba/refs/README.md`): the mean of K
//! independent Mitsuba renders at 160×120 and the per-pixel variance of that mean. CI never
//! runs Mitsuba.
//!
//! ember renders each scene at the same film size, and the image mean and the 8×6 block means
//! are compared per channel by z = (ember − mitsuba) / sqrt(var_ember + var_mitsuba), where
//! the variance of a block mean is the sum of the block's per-pixel variances of the mean
//! over the pixel count² (pixels are independent in both renderers): ember's from its own
//! per-pixel sample variance (`Rendered::variance`), Mitsuba's from the committed variance
//! image. All the tests of the matching renders share α = 0.01 (Šidák), which gives the
//! critical |z|.
//!
//! The test has power: renders of deliberately wrong scenes (the glass's IOR 1.33 instead of
//! 1.5; the mirror's Ks × 0.9) are compared in the same way against the same references and
//! critical value, and must fail.
//!
//! With the Owen-scrambled Sobol' sampler (ember's default for these integrators) a pixel's
//! samples are not independent and its sample variance says nothing about its error: the
//! ZSobol tests render K replicates with independent seeds (`common/replicates.rs`) and
//! compare their mean, with the variance from their spread, by Welch t-tests against the same
//! references, with the same negative controls.
//!
//! `EMBER_SPP_SCALE` multiplies the sample counts (a more powerful local run),
//! `EMBER_SEED_OFFSET` is added to every seed (for measuring how often the test fails on
//! other seeds), and `EMBER_MITSUBA_DUMP=<dir>` writes each ember render's mean and variance
//! EXRs there.

mod common;

use common::replicates::{welch, Estimate, Replicates};
use common::*;
use ember_cli::image::{read_exr, Image};
use ember_cli::render::{render, RenderSettings, Rendered, Shard};
use ember_cli::LoadedScene;
use ember_kernel::integrator::Integrator;
use ember_kernel::material::{Reflectance, Surface};
use ember_kernel::sampler::SamplerKind;
use ember_kernel::Rgb;
use std::path::{Path, PathBuf};
use std::time::Instant;

const W: u32 = 160;
const H: u32 = 120;
const BX: u32 = 8;
const BY: u32 = 6;
/// Tests per comparison: the image mean and every block mean, three channels each.
const TESTS_PER_CASE: usize = 3 * (1 + (BX * BY) as usize);

/// A render compared with a reference: the scene, the integrator, spp and seed.
struct Case {
    stem: &'static str,
    integrator: Integrator,
    spp: u32,
    seed: u64,
}

/// The matching renders: the smooth box with the scene's explicit path tracer, the rough one
/// with MIS (ember's estimator for glossy lobes), so that both integrators meet Mitsuba.
///
/// Why 256 spp: caustics (diffuse → mirror or glass → light, found only by BSDF sampling) give
/// both renderers heavy-tailed samples, and with too few samples per block a block usually
/// misses its rare bright samples, so its mean is low and its sample variance too small: the
/// z-test is then anti-conservative. Measured over seeds (`EMBER_SEED_OFFSET`): at 128 spp 4
/// of 14 comparisons had a block |z| above the critical 4.14 (up to 6.2, mean z² up to 1.6);
/// at 256 spp 10 of 10 passed (max |z| 1.9–3.4), at 384 spp 8 of 8 (≤ 3.7), at 512 and 1024
/// spp the base seeds gave ≤ 3.3 with mean z² 0.8–1.1. The four renders of the two tests
/// take 62 s of CPU, about 30 s on two free cores (39–45 s measured on a shared machine).
const CASES: &[Case] = &[
    Case {
        stem: "mirror_glass",
        integrator: Integrator::PathExplicit,
        spp: 256,
        seed: 0x6d69_7272_6f72,
    },
    Case {
        stem: "mirror_glass_rough",
        integrator: Integrator::PathMis,
        spp: 256,
        seed: 0x0072_6f75_6768,
    },
];

/// The negative controls: a case (index into [`CASES`]) rendered with a wrong material.
const CONTROLS: [(usize, Change); 2] = [(0, Change::GlassIor133), (1, Change::MirrorKsTimes09)];

/// Which material a negative control changes, and how.
#[derive(Clone, Copy, Debug)]
enum Change {
    /// The glass's relative IOR 1.5 → 1.33.
    GlassIor133,
    /// The mirror's Ks 0.95 → 0.855.
    MirrorKsTimes09,
}

fn critical() -> f64 {
    critical_z(0.01, TESTS_PER_CASE * CASES.len())
}

fn refs_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../bench/mitsuba/refs")
}

/// The committed Mitsuba mean image and per-pixel variance of the mean.
fn reference(stem: &str) -> (Image, Image) {
    let read = |kind: &str| {
        let path = refs_dir().join(format!("{stem}_mitsuba_{kind}.exr"));
        let img = read_exr(&path).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!((img.width, img.height), (W, H), "{}", path.display());
        assert_eq!(img.non_finite_count(), 0, "{}", path.display());
        img
    };
    let (mean, var) = (read("mean"), read("var"));
    assert!(
        var.pixels.iter().all(|v| v.min_element() >= 0.0),
        "{stem}: negative variances"
    );
    (mean, var)
}

fn scene(stem: &str) -> LoadedScene {
    let toml = project_data(&format!("mirror-glass/{stem}.toml"));
    LoadedScene::load(&toml).unwrap_or_else(|e| panic!("{e}"))
}

fn material_index(scene: &LoadedScene, name: &str) -> usize {
    scene
        .data
        .material_info
        .iter()
        .position(|m| m.name == name)
        .unwrap_or_else(|| panic!("no material '{name}'"))
}

/// The loader maps the MTL as the references assume (illum 5 conductor with Ks 0.95 and
/// alpha = Pr², illum 6 dielectric with Ni 1.5, clear, alpha = Pr²): otherwise the comparison
/// would test the wrong scene.
fn check_materials(scene: &LoadedScene, rough: bool) {
    let alpha = if rough { 0.09 } else { 0.0 };
    let mirror = scene.data.materials[material_index(scene, "mirror")].surface;
    match mirror {
        Surface::Conductor { ks, alpha: a } => {
            assert_eq!(ks, Reflectance::constant(Rgb::splat(0.95)), "mirror Ks");
            assert!(
                (a - alpha).abs() < 1e-6,
                "mirror alpha {a}, expected {alpha}"
            );
        }
        other => panic!("the mirror (illum 5) is loaded as {other:?}, not a conductor"),
    }
    let glass = scene.data.materials[material_index(scene, "glass")].surface;
    match glass {
        Surface::Dielectric { eta, tf, alpha: a } => {
            assert_eq!(eta, 1.5, "glass IOR");
            assert_eq!(tf, Rgb::ONE, "glass Tf");
            assert!(
                (a - alpha).abs() < 1e-6,
                "glass alpha {a}, expected {alpha}"
            );
        }
        other => panic!("the glass (illum 6) is loaded as {other:?}, not a dielectric"),
    }
}

fn apply(scene: &mut LoadedScene, change: Change) {
    match change {
        Change::GlassIor133 => {
            let i = material_index(scene, "glass");
            match &mut scene.data.materials[i].surface {
                Surface::Dielectric { eta, .. } => *eta = 1.33,
                other => panic!("glass is {other:?}"),
            }
        }
        Change::MirrorKsTimes09 => {
            let i = material_index(scene, "mirror");
            match &mut scene.data.materials[i].surface {
                Surface::Conductor { ks, .. } => {
                    *ks = Reflectance::constant(ks.value * 0.9);
                }
                other => panic!("mirror is {other:?}"),
            }
        }
    }
}

fn spp_scale() -> u32 {
    std::env::var("EMBER_SPP_SCALE")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(1)
}

fn seed_offset() -> u64 {
    std::env::var("EMBER_SEED_OFFSET")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(0)
}

/// The settings of `case`'s renders in `scene` with `sampler` and `spp` samples.
fn case_settings(
    scene: &LoadedScene,
    case: &Case,
    sampler: SamplerKind,
    spp: u32,
) -> RenderSettings {
    let (_, path, _) = scene.path_settings().unwrap();
    RenderSettings {
        integrator: case.integrator,
        path,
        spp,
        seed: case.seed.wrapping_add(seed_offset()),
        sampler,
        tile: 16,
        threads: 0,
        progress: false,
        shard: Shard::WHOLE,
        strategies: None,
    }
}

fn render_case(scene: &LoadedScene, case: &Case, label: &str) -> Rendered {
    let t = Instant::now();
    let settings = case_settings(
        scene,
        case,
        SamplerKind::Independent,
        case.spp * spp_scale(),
    );
    let r = render(&scene.data.view(), &scene.camera(W, H), &settings);
    println!(
        "{label:44} {} spp: {:.1} s",
        r.spp,
        t.elapsed().as_secs_f64()
    );
    if let Some(dir) = std::env::var_os("EMBER_MITSUBA_DUMP") {
        let name: String = label
            .chars()
            .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
            .collect();
        let dir = PathBuf::from(dir);
        std::fs::create_dir_all(&dir).unwrap();
        ember_cli::image::write_exr(&dir.join(format!("{name}_mean.exr")), &r.image).unwrap();
        ember_cli::image::write_exr(&dir.join(format!("{name}_var.exr")), &r.variance).unwrap();
    }
    assert_eq!(
        r.image.non_finite_count(),
        0,
        "{}: non-finite pixels",
        case.stem
    );
    assert_eq!(r.invalid_samples, 0, "{}: invalid samples", case.stem);
    r
}

/// Variance of the image mean from per-pixel variances of the mean.
fn mean_variance(var: &Image) -> Rgb {
    (var.mean().as_dvec3() / var.pixels.len() as f64).as_vec3()
}

/// The z statistics of a render against the committed reference: (image mean, blocks, the
/// mean of z² over the block tests).
fn compare(label: &str, r: &Rendered, stem: &str) -> (ZReport, ZReport, f64) {
    let (mean, var) = reference(stem);
    let m = z_scores(
        &format!("{label} mean"),
        &[r.image.mean()],
        &[mean_variance(&r.variance)],
        &[mean.mean()],
        &[mean_variance(&var)],
    );
    let (ea, ev) = (
        r.image.block_means(BX, BY),
        block_mean_variances(&r.variance, BX, BY),
    );
    let (ma, mv) = (mean.block_means(BX, BY), block_mean_variances(&var, BX, BY));
    let b = z_scores(&format!("{label} block"), &ea, &ev, &ma, &mv);
    let mut z2 = 0.0;
    for i in 0..ea.len() {
        for c in 0..3 {
            let d = f64::from(ea[i][c]) - f64::from(ma[i][c]);
            let v = f64::from(ev[i][c]) + f64::from(mv[i][c]);
            if v > 0.0 {
                z2 += d * d / v;
            }
        }
    }
    let (e, mi) = (r.image.mean(), mean.mean());
    println!(
        "{label:44} mean ember ({:.5}, {:.5}, {:.5}) mitsuba ({:.5}, {:.5}, {:.5}) | max|z| mean {:.2} blocks {:.2} | mean z² (blocks) {:.2}",
        e.x,
        e.y,
        e.z,
        mi.x,
        mi.y,
        mi.z,
        m.max_abs_z,
        b.max_abs_z,
        z2 / ea.len() as f64 / 3.0
    );
    (m, b, z2 / (ea.len() * 3) as f64)
}

#[test]
#[cfg_attr(debug_assertions, ignore = "slow statistical test: run with --release")]
fn ember_matches_mitsuba_on_mirror_and_glass() {
    let z_crit = critical();
    let mut failures = Vec::new();
    for case in CASES {
        let scene = scene(case.stem);
        check_materials(&scene, case.stem.ends_with("rough"));
        let label = format!("{} ({:?})", case.stem, case.integrator);
        let r = render_case(&scene, case, &label);
        let (m, b, _) = compare(&label, &r, case.stem);
        for rep in [m, b] {
            if rep.max_abs_z > z_crit {
                failures.push(rep.worst);
            }
        }
    }
    println!(
        "critical |z| = {z_crit:.2} (alpha 0.01 over {} tests)",
        TESTS_PER_CASE * CASES.len()
    );
    assert!(
        failures.is_empty(),
        "ember and Mitsuba differ beyond noise:\n{}",
        failures.join("\n")
    );
}

/// Negative controls: wrong materials, rendered like the matching cases, must fail the same
/// comparison (some |z| above the same critical value).
#[test]
#[cfg_attr(debug_assertions, ignore = "slow statistical test: run with --release")]
fn wrong_materials_fail_the_comparison() {
    let z_crit = critical();
    let controls = CONTROLS.map(|(case, change)| (&CASES[case], change));
    let mut passed_wrongly = Vec::new();
    for (case, change) in controls {
        let mut scene = scene(case.stem);
        apply(&mut scene, change);
        let wrong = Case {
            seed: case.seed ^ 0x0bad,
            ..*case
        };
        let label = format!("{} with {change:?}", case.stem);
        let r = render_case(&scene, &wrong, &label);
        let (m, b, _) = compare(&label, &r, case.stem);
        let worst = m.max_abs_z.max(b.max_abs_z);
        println!("  -> max |z| {worst:.2} against the critical {z_crit:.2}");
        if worst <= z_crit {
            passed_wrongly.push(label);
        }
    }
    assert!(
        passed_wrongly.is_empty(),
        "the comparison cannot tell these wrong scenes from Mitsuba's: {passed_wrongly:?}"
    );
}

/// Replicates of the ZSobol comparisons: `KR` renders of `spp / KR` samples each (the same
/// samples in all as the independent comparison).
const KR: usize = 16;

/// The committed reference as estimates of the image mean and the `BX × BY` block means
/// (variances from the committed per-pixel variances of the mean; Mitsuba's pixels are
/// independent).
fn reference_estimates(stem: &str) -> (Estimate, Estimate) {
    let (mean, var) = reference(stem);
    let estimate = |w: u32, h: u32, m: Vec<Rgb>, v: Vec<Rgb>| Estimate {
        width: w,
        height: h,
        mean: m.iter().map(|p| p.as_dvec3()).collect(),
        var: v.iter().map(|p| p.as_dvec3()).collect(),
        dof: f64::INFINITY,
    };
    (
        estimate(1, 1, vec![mean.mean()], vec![mean_variance(&var)]),
        estimate(
            BX,
            BY,
            mean.block_means(BX, BY),
            block_mean_variances(&var, BX, BY),
        ),
    )
}

/// `case` with ZSobol in [`KR`] replicates, compared with the reference: the smallest
/// p-value of the image-mean and block tests and where it was.
fn zsobol_case(scene: &LoadedScene, case: &Case, label: &str) -> (f64, String) {
    let t = Instant::now();
    let template = case_settings(
        scene,
        case,
        SamplerKind::ZSobol,
        case.spp * spp_scale() / KR as u32,
    );
    // The replicates' seeds come from the label and the case's seed (EMBER_SEED_OFFSET
    // changes them).
    let seeds = format!("{label} {:x}", template.seed);
    let reps = Replicates::render_with(
        &scene.data.view(),
        &scene.camera(W, H),
        &template,
        KR,
        &seeds,
    );
    let (mean, blocks) = reference_estimates(case.stem);
    let m = welch(
        &format!("{label} mean"),
        &reps.image_mean().estimate(),
        &mean,
    );
    let b = welch(
        &format!("{label} block"),
        &reps.blocks(BX, BY).estimate(),
        &blocks,
    );
    println!(
        "{label:44} {KR} x {} spp: {:.1} s | mean {:.5} (mitsuba {:.5}) | min p mean {:.2e}, blocks {:.2e}\n    worst: {}",
        template.spp,
        t.elapsed().as_secs_f64(),
        reps.image_mean().estimate().mean[0][0],
        mean.mean[0][0],
        m.min_p,
        b.min_p,
        b.worst
    );
    if m.min_p < b.min_p {
        (m.min_p, m.worst)
    } else {
        (b.min_p, b.worst)
    }
}

/// [`ember_matches_mitsuba_on_mirror_and_glass`] with the ZSobol sampler: each case in
/// [`KR`] replicates, Welch t-tests (Student tails with the replicates' K − 1 degrees of
/// freedom) of the image mean and the block means, α = 0.01 shared (Šidák).
#[test]
#[cfg_attr(debug_assertions, ignore = "slow statistical test: run with --release")]
fn ember_with_zsobol_matches_mitsuba_on_mirror_and_glass() {
    let a = sidak(0.01, TESTS_PER_CASE * CASES.len());
    let mut failures = Vec::new();
    for case in CASES {
        let scene = scene(case.stem);
        check_materials(&scene, case.stem.ends_with("rough"));
        let label = format!("{} ({:?}, ZSobol)", case.stem, case.integrator);
        let (p, worst) = zsobol_case(&scene, case, &label);
        if p < a {
            failures.push(worst);
        }
    }
    println!("per-test significance {a:.2e}");
    assert!(
        failures.is_empty(),
        "ember (ZSobol) and Mitsuba differ beyond noise:\n{}",
        failures.join("\n")
    );
}

/// The negative controls of [`wrong_materials_fail_the_comparison`] with ZSobol replicates:
/// the same wrong scenes must fail the Welch tests.
#[test]
#[cfg_attr(debug_assertions, ignore = "slow statistical test: run with --release")]
fn wrong_materials_fail_the_zsobol_comparison() {
    let a = sidak(0.01, TESTS_PER_CASE * CASES.len());
    let controls = CONTROLS.map(|(case, change)| (&CASES[case], change));
    let mut passed_wrongly = Vec::new();
    for (case, change) in controls {
        let mut scene = scene(case.stem);
        apply(&mut scene, change);
        let label = format!("{} with {change:?} (ZSobol)", case.stem);
        let (p, _) = zsobol_case(&scene, case, &label);
        println!("  -> min p {p:.2e} against {a:.2e}");
        if p >= a {
            passed_wrongly.push(label);
        }
    }
    assert!(
        passed_wrongly.is_empty(),
        "the ZSobol comparison cannot tell these wrong scenes from Mitsuba's: {passed_wrongly:?}"
    );
}
