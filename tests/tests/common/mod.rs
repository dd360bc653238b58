//! Shared helpers of the cross-crate tests: where the TinyRender data is, rendering a scene
//! file at a chosen size, and variance-aware image comparisons.
#![allow(dead_code)]

pub mod replicates;
pub mod scenes;

use ember_cli::image::Image;
use ember_cli::render::{render, RenderSettings, Rendered};
use ember_cli::LoadedScene;
use ember_kernel::integrator::Integrator;
use ember_kernel::sampler::DEFAULT_SEED;
use ember_kernel::Rgb;
use std::path::{Path, PathBuf};

/// The TinyRender data: `$EMBER_TINYRENDER` or `../shared/tinyrender` beside the checkout.
/// Missing data is a failure, never a skip.
pub fn tinyrender_dir() -> PathBuf {
    let dir = std::env::var_os("EMBER_TINYRENDER").map_or_else(
        || Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/tinyrender"),
        PathBuf::from,
    );
    assert!(
        dir.join("data/a5/cbox/tinyrender").is_dir(),
        "TinyRender data not found at {} (set EMBER_TINYRENDER to the folder holding data/a5)",
        dir.display()
    );
    dir
}

pub fn cbox_scene(name: &str) -> PathBuf {
    tinyrender_dir().join("data/a5/cbox/tinyrender").join(name)
}

pub fn project_data(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../data")
        .join(rel)
}

/// Renders a path-traced scene file at `width × height` with `spp` samples.
pub fn render_scene(toml: &Path, width: u32, height: u32, spp: u32) -> Rendered {
    render_scene_with(toml, width, height, spp, DEFAULT_SEED, 16, 0)
}

pub fn render_scene_with(
    toml: &Path,
    width: u32,
    height: u32,
    spp: u32,
    seed: u64,
    tile: u32,
    threads: usize,
) -> Rendered {
    render_scene_full(toml, None, width, height, spp, seed, tile, threads)
}

/// Renders with an integrator other than the scene's (`None`: the scene's).
pub fn render_scene_full(
    toml: &Path,
    integrator: Option<Integrator>,
    width: u32,
    height: u32,
    spp: u32,
    seed: u64,
    tile: u32,
    threads: usize,
) -> Rendered {
    let scene = LoadedScene::load(toml).unwrap_or_else(|e| panic!("{e}"));
    let (scene_integrator, path, _) = scene.path_settings().unwrap();
    let integrator = integrator.unwrap_or(scene_integrator);
    let camera = scene.camera(width, height);
    render(
        &scene.data.view(),
        &camera,
        &RenderSettings {
            integrator,
            path,
            spp,
            seed,
            sampler: ember_kernel::sampler::SamplerKind::Independent,
            tile,
            threads,
            progress: false,
            shard: ember_cli::render::Shard::WHOLE,
            strategies: None,
        },
    )
}

/// Sum of per-pixel variances of the mean inside each block, divided by the pixel count²:
/// the variance of each block mean.
pub fn block_mean_variances(var: &Image, bx: u32, by: u32) -> Vec<Rgb> {
    let n = f64::from(var.width / bx * (var.height / by));
    var.block_means(bx, by)
        .into_iter()
        .map(|v| (v.as_dvec3() / n).as_vec3())
        .collect()
}

/// Two-sided critical |z| for significance `alpha` shared (Šidák) among `tests` tests.
pub fn critical_z(alpha: f64, tests: usize) -> f64 {
    let a = 1.0 - (1.0 - alpha).powf(1.0 / tests as f64);
    // Inverse of the two-sided normal tail by bisection on erfc.
    let (mut lo, mut hi) = (0.0f64, 40.0f64);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if erfc(mid / std::f64::consts::SQRT_2) > a {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// Complementary error function (W. J. Cody's rational approximations are overkill here; this
/// is Numerical Recipes' erfcc, relative error < 1.2e-7).
pub fn erfc(x: f64) -> f64 {
    let z = x.abs();
    let t = 1.0 / (1.0 + 0.5 * z);
    // Horner's rule from the innermost coefficient out (a loop rather than nine nested
    // parentheses, which rustfmt takes seconds to lay out).
    const C: [f64; 10] = [
        -1.265_512_23,
        1.000_023_68,
        0.374_091_96,
        0.096_784_18,
        -0.186_288_06,
        0.278_868_07,
        -1.135_203_98,
        1.488_515_87,
        -0.822_152_23,
        0.170_872_77,
    ];
    let inner = C[1..9].iter().rev().fold(C[9], |acc, &c| c + t * acc);
    let r = t * ((-z * z + C[0]) + t * inner).exp();
    if x >= 0.0 {
        r
    } else {
        2.0 - r
    }
}

/// Result of comparing an estimate with a reference, channel by channel.
#[derive(Debug)]
pub struct ZReport {
    pub max_abs_z: f64,
    pub worst: String,
    pub tests: usize,
}

/// z-scores of `a − b` where both have known variances of their means.
pub fn z_scores(label: &str, a: &[Rgb], va: &[Rgb], b: &[Rgb], vb: &[Rgb]) -> ZReport {
    let mut rep = ZReport {
        max_abs_z: 0.0,
        worst: String::new(),
        tests: 0,
    };
    for i in 0..a.len() {
        for c in 0..3 {
            let d = f64::from(a[i][c]) - f64::from(b[i][c]);
            let v = f64::from(va[i][c]) + f64::from(vb[i][c]);
            let z = if v > 0.0 {
                d / v.sqrt()
            } else if d == 0.0 {
                0.0
            } else {
                f64::INFINITY
            };
            rep.tests += 1;
            if z.abs() > rep.max_abs_z {
                rep.max_abs_z = z.abs();
                rep.worst = format!(
                    "{label} #{i} ch{c}: {:.5} vs {:.5}, sd {:.5}, z {z:.2}",
                    a[i][c],
                    b[i][c],
                    v.sqrt()
                );
            }
        }
    }
    rep
}

/// Per-pixel agreement: the ratio Σ(a−b)² / Σ(va+vb) over pixels and channels, and the z of
/// its numerator minus denominator, normalised by the empirical spread Σ((a−b)² − v)² so that
/// heavy-tailed (fireflying) estimators do not make it overconfident.
pub fn pixel_mse_z(a: &Image, b: &Image, var_sum: impl Fn(usize) -> glam::DVec3) -> (f64, f64) {
    let (mut sq, mut sv, mut spread) = (0.0f64, 0.0f64, 0.0f64);
    for i in 0..a.pixels.len() {
        let d = (a.pixels[i] - b.pixels[i]).as_dvec3();
        let v = var_sum(i);
        let e = d * d - v;
        sq += (d * d).element_sum();
        sv += v.element_sum();
        spread += (e * e).element_sum();
    }
    (sq / sv, (sq - sv) / spread.sqrt())
}

/// ln Γ(x) for x > 0 (Lanczos, g = 7, 9 terms; relative error below 1e-13).
pub fn ln_gamma(x: f64) -> f64 {
    const G: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    if x < 0.5 {
        // Reflection: Γ(x) Γ(1 − x) = π / sin(πx).
        let pi = std::f64::consts::PI;
        return (pi / (pi * x).sin()).ln() - ln_gamma(1.0 - x);
    }
    let x = x - 1.0;
    let t = x + 7.5;
    let a = G[1..]
        .iter()
        .enumerate()
        .fold(G[0], |acc, (i, &g)| acc + g / (x + i as f64 + 1.0));
    0.5 * (2.0 * std::f64::consts::PI).ln() + (x + 0.5) * t.ln() - t + a.ln()
}

/// The regularised incomplete beta function I_x(a, b) (Numerical Recipes' continued fraction,
/// modified Lentz; accurate to ~1e-14 relative, also far in the tails).
pub fn incomplete_beta(a: f64, b: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 0.0;
    }
    if x >= 1.0 {
        return 1.0;
    }
    let front =
        (ln_gamma(a + b) - ln_gamma(a) - ln_gamma(b) + a * x.ln() + b * (1.0 - x).ln()).exp();
    // The continued fraction converges fast for x < (a + 1) / (a + b + 2); use the symmetry
    // I_x(a, b) = 1 − I_{1−x}(b, a) otherwise.
    if x > (a + 1.0) / (a + b + 2.0) {
        return 1.0 - incomplete_beta(b, a, 1.0 - x);
    }
    let tiny = 1e-300;
    let (mut c, mut d) = (1.0f64, 1.0 - (a + b) * x / (a + 1.0));
    if d.abs() < tiny {
        d = tiny;
    }
    d = 1.0 / d;
    let mut f = d;
    for m in 1..=10_000 {
        let m = f64::from(m);
        for k in 0..2 {
            let num = if k == 0 {
                m * (b - m) * x / ((a + 2.0 * m - 1.0) * (a + 2.0 * m))
            } else {
                -(a + m) * (a + b + m) * x / ((a + 2.0 * m) * (a + 2.0 * m + 1.0))
            };
            d = 1.0 + num * d;
            if d.abs() < tiny {
                d = tiny;
            }
            c = 1.0 + num / c;
            if c.abs() < tiny {
                c = tiny;
            }
            d = 1.0 / d;
            f *= c * d;
        }
        if (c * d - 1.0).abs() < 1e-15 {
            break;
        }
    }
    front * f / a
}

/// Two-sided tail probability P(|T| ≥ |t|) of Student's t with `dof` degrees of freedom (the
/// normal tail for infinite `dof`). 0 for an infinite `t`.
pub fn student_t_two_sided(t: f64, dof: f64) -> f64 {
    if !t.is_finite() {
        return 0.0;
    }
    if !dof.is_finite() || dof > 1e7 {
        return erfc(t.abs() / std::f64::consts::SQRT_2);
    }
    incomplete_beta(0.5 * dof, 0.5, dof / (dof + t * t))
}

/// The |z| whose two-sided normal tail is `p`: a p-value expressed on the z scale, so that
/// tests with different degrees of freedom can be reported together. Saturates at 37 (where
/// the tail underflows).
pub fn z_of_p(p: f64) -> f64 {
    if p >= 1.0 {
        return 0.0;
    }
    let (mut lo, mut hi) = (0.0f64, 37.0f64);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if erfc(mid / std::f64::consts::SQRT_2) > p {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// The per-test significance that gives `alpha` for a family of `tests` independent tests
/// (Šidák).
pub fn sidak(alpha: f64, tests: usize) -> f64 {
    1.0 - (1.0 - alpha).powf(1.0 / tests as f64)
}
