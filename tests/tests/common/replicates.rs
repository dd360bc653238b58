//! Randomised replicates: K renders with independent seeds, the per-pixel (per-block, per-image)
//! mean over them and the variance of that mean from their spread, compared by Welch t-tests
//! with Student's t tails. Valid for any estimator whose pixels are not independent or whose
//! samples are not (light tracing and BDPT splat; quasi-random samplers stratify), since the
//! replicates themselves are independent and identically distributed. See `bdpt.rs` for the
//! statistics' notes.
#![allow(dead_code)]

use super::*;
use ember_cli::image::Image;
use ember_cli::render::{render, RenderSettings, Rendered, Shard};
use ember_kernel::camera::Camera;
use ember_kernel::glam::DVec3;
use ember_kernel::integrator::{Integrator, PathSettings};
use ember_kernel::sampler::mix64;
use ember_kernel::scene::SceneView;

// ---------------------------------------------------------------------------------------------
// Rendering and replicates
// ---------------------------------------------------------------------------------------------

pub fn settings(integrator: Integrator, path: PathSettings, spp: u32, seed: u64) -> RenderSettings {
    RenderSettings {
        integrator,
        path,
        spp,
        seed,
        sampler: ember_kernel::sampler::SamplerKind::Independent,
        tile: 8,
        threads: 0,
        progress: false,
        shard: Shard::WHOLE,
        strategies: None,
    }
}

/// No NaN/Inf pixel and no invalid sample or refused splat.
#[track_caller]
pub fn assert_clean(r: &Rendered, ctx: &str) {
    assert_eq!(r.image.non_finite_count(), 0, "{ctx}: non-finite pixels");
    assert_eq!(r.invalid_samples, 0, "{ctx}: invalid samples");
}

pub fn bits(img: &Image) -> Vec<u32> {
    img.pixels
        .iter()
        .flat_map(|p| p.to_array().map(f32::to_bits))
        .collect()
}

/// A seed for replicate `i` of the estimate called `label`: distinct labels give independent
/// renders.
pub fn seed_of(label: &str, i: usize) -> u64 {
    let h = label.bytes().fold(0xcbf2_9ce4_8422_2325u64, |h, b| {
        (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
    });
    mix64(h ^ mix64(i as u64 + 1))
}

/// K images of one estimator with independent seeds (or any per-replicate derived images:
/// block means, image means), as f64 RGB, row-major.
#[derive(Clone, Debug)]
pub struct Replicates {
    pub width: u32,
    pub height: u32,
    pub images: Vec<Vec<DVec3>>,
}

impl Replicates {
    /// `k` renders of `spp` samples each, with seeds from `label`; each must be clean.
    #[allow(clippy::too_many_arguments)]
    pub fn render(
        view: &SceneView<'_>,
        camera: &Camera,
        integrator: Integrator,
        path: PathSettings,
        spp: u32,
        k: usize,
        label: &str,
    ) -> Self {
        Self::render_with(view, camera, &settings(integrator, path, spp, 0), k, label)
    }

    /// `k` renders with `template`'s settings and seeds from `label`; each must be clean.
    pub fn render_with(
        view: &SceneView<'_>,
        camera: &Camera,
        template: &RenderSettings,
        k: usize,
        label: &str,
    ) -> Self {
        let images = (0..k)
            .map(|i| {
                let r = render(
                    view,
                    camera,
                    &RenderSettings {
                        seed: seed_of(label, i),
                        ..*template
                    },
                );
                assert_clean(&r, label);
                r.image.pixels.iter().map(|p| p.as_dvec3()).collect()
            })
            .collect();
        Self {
            width: camera.width,
            height: camera.height,
            images,
        }
    }

    pub fn map(&self, f: impl Fn(usize, DVec3) -> DVec3) -> Self {
        Self {
            images: self
                .images
                .iter()
                .map(|img| img.iter().enumerate().map(|(i, &p)| f(i, p)).collect())
                .collect(),
            ..*self
        }
    }

    /// Per-replicate means over a `bx × by` grid of blocks (a pixel belongs to the block
    /// containing its centre, as `Image::block_means`).
    pub fn blocks(&self, bx: u32, by: u32) -> Self {
        let (w, h) = (self.width, self.height);
        let images = self
            .images
            .iter()
            .map(|img| {
                let mut sums = vec![DVec3::ZERO; (bx * by) as usize];
                let mut counts = vec![0u32; (bx * by) as usize];
                for y in 0..h {
                    for x in 0..w {
                        let b = ((y * by / h) * bx + x * bx / w) as usize;
                        sums[b] += img[(y * w + x) as usize];
                        counts[b] += 1;
                    }
                }
                sums.iter()
                    .zip(&counts)
                    .map(|(s, &c)| *s / f64::from(c.max(1)))
                    .collect()
            })
            .collect();
        Self {
            width: bx,
            height: by,
            images,
        }
    }

    /// Per-replicate image means.
    pub fn image_mean(&self) -> Self {
        self.blocks(1, 1)
    }

    /// The mean over the replicates and its estimated variance s²/K, with K − 1 degrees of
    /// freedom.
    pub fn estimate(&self) -> Estimate {
        let k = self.images.len() as f64;
        assert!(k >= 2.0, "need at least two replicates");
        let n = self.images[0].len();
        let mut mean = vec![DVec3::ZERO; n];
        for img in &self.images {
            for (m, p) in mean.iter_mut().zip(img) {
                *m += *p / k;
            }
        }
        let mut var = vec![DVec3::ZERO; n];
        for img in &self.images {
            for ((v, p), m) in var.iter_mut().zip(img).zip(&mean) {
                let d = *p - *m;
                *v += d * d / ((k - 1.0) * k);
            }
        }
        Estimate {
            width: self.width,
            height: self.height,
            mean,
            var,
            dof: k - 1.0,
        }
    }
}

/// Means with estimated variances of the means and the degrees of freedom of those variances.
#[derive(Clone, Debug)]
pub struct Estimate {
    pub width: u32,
    pub height: u32,
    pub mean: Vec<DVec3>,
    pub var: Vec<DVec3>,
    pub dof: f64,
}

impl Estimate {
    /// A known value (no variance).
    pub fn exact(width: u32, height: u32, value: DVec3) -> Self {
        let n = (width * height) as usize;
        Self {
            width,
            height,
            mean: vec![value; n],
            var: vec![DVec3::ZERO; n],
            dof: f64::INFINITY,
        }
    }

    /// Each variance replaced by the largest in its 3×3 neighbourhood (see the module notes).
    pub fn neighbourhood_max(&self) -> Self {
        let (w, h) = (i64::from(self.width), i64::from(self.height));
        let var = (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .map(|(x, y)| {
                let mut m = DVec3::ZERO;
                for dy in -1..=1 {
                    for dx in -1..=1 {
                        let (nx, ny) = (x + dx, y + dy);
                        if (0..w).contains(&nx) && (0..h).contains(&ny) {
                            m = m.max(self.var[(ny * w + nx) as usize]);
                        }
                    }
                }
                m
            })
            .collect();
        Self {
            var,
            ..self.clone()
        }
    }
}

/// The smallest p-value of a family of tests and where it was.
#[derive(Clone, Debug)]
pub struct Report {
    pub tests: usize,
    pub min_p: f64,
    pub worst: String,
}

impl Report {
    /// The smallest p-value on the z scale.
    pub fn z(&self) -> f64 {
        z_of_p(self.min_p)
    }
}

/// Welch t-tests of `a − b`, element by element and channel by channel.
pub fn welch(label: &str, a: &Estimate, b: &Estimate) -> Report {
    assert_eq!(a.mean.len(), b.mean.len());
    let mut rep = Report {
        tests: 0,
        min_p: 1.0,
        worst: String::new(),
    };
    for i in 0..a.mean.len() {
        for c in 0..3 {
            let d = a.mean[i][c] - b.mean[i][c];
            let (va, vb) = (a.var[i][c], b.var[i][c]);
            let v = va + vb;
            // Welch–Satterthwaite; a side without variance adds nothing.
            let part = |v: f64, dof: f64| if v > 0.0 { v * v / dof } else { 0.0 };
            let dof = v * v / (part(va, a.dof) + part(vb, b.dof));
            let (t, p) = if v > 0.0 {
                let t = d / v.sqrt();
                (t, student_t_two_sided(t, dof))
            } else if d == 0.0 {
                (0.0, 1.0)
            } else {
                (f64::INFINITY, 0.0)
            };
            rep.tests += 1;
            if p < rep.min_p || rep.worst.is_empty() {
                rep.min_p = p;
                rep.worst = format!(
                    "{label} #{i} ({}, {}) ch{c}: {:.5} vs {:.5}, sd {:.5}, t {t:.2} ({dof:.0} dof)",
                    i as u32 % a.width,
                    i as u32 / a.width,
                    a.mean[i][c],
                    b.mean[i][c],
                    v.sqrt()
                );
            }
        }
    }
    rep
}

/// The image-wide statistic of `reference.rs`: Σ(a−b)² against Σ(va+vb) over pixels and
/// channels, and the z of the excess normalised by its empirical spread (robust to
/// fireflies); one-sided: excess squared error means bias somewhere.
pub fn mse_z(a: &Estimate, b: &Estimate) -> (f64, f64) {
    let (mut sq, mut sv, mut spread) = (0.0f64, 0.0f64, 0.0f64);
    for i in 0..a.mean.len() {
        let d = a.mean[i] - b.mean[i];
        let v = a.var[i] + b.var[i];
        let e = d * d - v;
        sq += (d * d).element_sum();
        sv += v.element_sum();
        spread += (e * e).element_sum();
    }
    if spread == 0.0 {
        return (1.0, 0.0);
    }
    (sq / sv, (sq - sv) / spread.sqrt())
}

/// One comparison of two replicated images: pixels (neighbourhood variances), blocks, the
/// image mean and the image-wide squared error.
pub struct Comparison {
    pub label: String,
    pub pixels: Report,
    pub blocks: Report,
    pub mean: Report,
    pub mse: (f64, f64),
    pub means: (DVec3, DVec3),
}

/// Tests one [`compare_blocks`] makes on a `w × h` film with `bx × by` blocks.
pub const fn tests_per_block_comparison(w: u32, h: u32, bx: u32, by: u32) -> usize {
    3 * (w * h + bx * by + 1) as usize + 1
}

/// Compares two replicated images with `bx × by` blocks.
pub fn compare_blocks(label: &str, a: &Replicates, b: &Replicates, bx: u32, by: u32) -> Comparison {
    let (ea, eb) = (a.estimate(), b.estimate());
    let (ma, mb) = (a.image_mean().estimate(), b.image_mean().estimate());
    Comparison {
        label: label.to_string(),
        pixels: welch(
            &format!("{label} pixel"),
            &ea.neighbourhood_max(),
            &eb.neighbourhood_max(),
        ),
        blocks: welch(
            &format!("{label} block"),
            &a.blocks(bx, by).estimate(),
            &b.blocks(bx, by).estimate(),
        ),
        mean: welch(&format!("{label} mean"), &ma, &mb),
        mse: mse_z(&ea, &eb),
        means: (ma.mean[0], mb.mean[0]),
    }
}

impl Comparison {
    pub fn print(&self) {
        println!(
            "{}: mean {:.4} (reference {:.4}) | max|z| pixels {:.2}, blocks {:.2}, mean {:.2} | mse/var {:.3} (z {:.2})\n    worst pixel: {}\n    worst block: {}",
            self.label,
            self.means.0,
            self.means.1,
            self.pixels.z(),
            self.blocks.z(),
            self.mean.z(),
            self.mse.0,
            self.mse.1,
            self.pixels.worst,
            self.blocks.worst
        );
    }

    /// What exceeds the per-test significance `a`.
    pub fn failures(&self, a: f64, z_crit: f64) -> Vec<String> {
        let mut f: Vec<String> = [&self.pixels, &self.blocks, &self.mean]
            .iter()
            .filter(|r| r.min_p < a)
            .map(|r| r.worst.clone())
            .collect();
        if self.mse.1 > z_crit {
            f.push(format!(
                "{}: image mse/var {:.3}, z {:.2}",
                self.label, self.mse.0, self.mse.1
            ));
        }
        f
    }

    /// Whether any of its tests rejects at `a`.
    pub fn rejects(&self, a: f64, z_crit: f64) -> bool {
        !self.failures(a, z_crit).is_empty()
    }
}

/// The per-replicate mean over the pixels of `mask` (all if `None`).
pub fn masked_mean(reps: &Replicates, mask: Option<&[bool]>) -> Estimate {
    let inside = |i: usize| mask.is_none_or(|m| m[i]);
    Replicates {
        width: 1,
        height: 1,
        images: reps
            .images
            .iter()
            .map(|img| {
                let (s, n) = (0..img.len())
                    .filter(|&i| inside(i))
                    .fold((DVec3::ZERO, 0.0), |(s, n), i| (s + img[i], n + 1.0));
                vec![s / n]
            })
            .collect(),
    }
    .estimate()
}

/// One estimate against a known value: the image mean (over the pixels of `mask`, all if
/// `None`) within `tolerance` (relative) of `value`, with noise small enough to test it (4
/// standard errors inside the band); and per-pixel and mean t-tests against `value`, or
/// against `reference` replicates when the expectation is not exactly `value` (the glass
/// furnace truncated at BDPT's depth cap). Per-pixel tests use neighbourhood variances (see
/// the module notes: in the a = 0.8 furnace BDPT's per-pixel estimates are right-skewed, and
/// with each pixel's own variance a dark pixel reached t = −5.6 with 31 dof at 256 spp).
/// Pixels outside the mask are not tested (they count as passed tests). Returns the
/// per-pixel report and the mean's.
pub fn against_value(
    label: &str,
    reps: &Replicates,
    value: f64,
    tolerance: f64,
    mask: Option<&[bool]>,
    reference: Option<&Replicates>,
) -> [Report; 2] {
    let inside = |i: usize| mask.is_none_or(|m| m[i]);
    let (w, h) = (reps.width, reps.height);
    let masked = |e: Estimate| Estimate {
        mean: (0..e.mean.len())
            .map(|i| if inside(i) { e.mean[i] } else { DVec3::ZERO })
            .collect(),
        var: (0..e.var.len())
            .map(|i| if inside(i) { e.var[i] } else { DVec3::ZERO })
            .collect(),
        ..e
    };
    let est = masked(reps.estimate().neighbourhood_max());
    let m = masked_mean(reps, mask);
    let (mean, se) = (m.mean[0], m.var[0].map(f64::sqrt));
    let median_se = {
        let own = reps.estimate();
        let mut s: Vec<f64> = (0..own.var.len())
            .filter(|&i| inside(i))
            .map(|i| own.var[i].x.sqrt())
            .collect();
        s.sort_by(f64::total_cmp);
        s[s.len() / 2]
    };
    let pixels = (0..(w * h) as usize).filter(|&i| inside(i)).count();
    println!(
        "{label}: mean {mean:.5} expected {value} (standard error {:.5}) over {pixels} pixels; per pixel median standard error {:.2}%",
        se.max_element(),
        100.0 * median_se / value
    );
    for c in 0..3 {
        assert!(
            4.0 * se[c] < tolerance * value,
            "{label}: too noisy to test {}% ({})",
            100.0 * tolerance,
            se[c]
        );
        assert!(
            (mean[c] - value).abs() < tolerance * value,
            "{label}: channel {c} mean {} vs {value}",
            mean[c]
        );
    }
    let (ref_pixels, ref_mean) = match reference {
        Some(r) => (
            masked(r.estimate().neighbourhood_max()),
            masked_mean(r, mask),
        ),
        None => {
            let exact = Estimate::exact(w, h, DVec3::splat(value));
            (masked(exact), Estimate::exact(1, 1, DVec3::splat(value)))
        }
    };
    if let Some(r) = reference {
        println!("    reference mean {:.5}", masked_mean(r, mask).mean[0].x);
    }
    [
        welch(&format!("{label} pixel"), &est, &ref_pixels),
        welch(&format!("{label} mean"), &m, &ref_mean),
    ]
}

/// TinyRender's `cbox_path_explicit_rr_REF.exr` (800×600, 128 spp of its explicit path tracer,
/// unknown seed) as an estimate at `1/factor` of its resolution in each direction: its pixels
/// box-filtered, with variances from ember's explicit path tracer on the same scene (the same
/// estimator, independent samples, so its pixels' own variances are valid and its pixels are
/// independent: a block's variance is the sum of its pixels' over the count²). Comparisons:
/// the image mean and `bx × by` block means by Welch t-tests and the one-sided per-pixel
/// squared-error statistic ([`Self::check`]).
pub struct TinyRenderReference {
    pub scene: ember_cli::LoadedScene,
    pub path: PathSettings,
    pub width: u32,
    pub height: u32,
    pub bx: u32,
    pub by: u32,
    mean: Estimate,
    blocks: Estimate,
    pixels: Estimate,
}

impl TinyRenderReference {
    /// Tests one [`Self::check`] makes.
    pub const fn tests(&self) -> usize {
        3 * (1 + self.bx * self.by) as usize + 1
    }

    pub fn load(factor: u32, bx: u32, by: u32) -> Self {
        const EXPLICIT_SPP: u32 = 16;
        let (w, h) = (800 / factor, 600 / factor);
        let ref_samples = 128.0 * f64::from(factor * factor);
        let scene =
            ember_cli::LoadedScene::load(&cbox_scene("cbox_path_explicit_rr.toml")).unwrap();
        let (_, path, _) = scene.path_settings().unwrap();
        let reference = ember_cli::image::read_exr(&cbox_scene("cbox_path_explicit_rr_REF.exr"))
            .unwrap()
            .downsample(factor, factor);
        assert_eq!((reference.width, reference.height), (w, h));
        let explicit = render(
            &scene.data.view(),
            &scene.camera(w, h),
            &settings(Integrator::PathExplicit, path, EXPLICIT_SPP, 0x7E_F001),
        );
        assert_clean(&explicit, "explicit");
        // Variance of a reference pixel's mean: the per-sample variance over its samples.
        let var: Vec<DVec3> = explicit
            .variance
            .pixels
            .iter()
            .map(|v| v.as_dvec3() * f64::from(EXPLICIT_SPP) / ref_samples)
            .collect();
        let pixels: Vec<DVec3> = reference.pixels.iter().map(|p| p.as_dvec3()).collect();
        let blocks = |bx: u32, by: u32| {
            let one = Replicates {
                width: w,
                height: h,
                images: vec![pixels.clone()],
            }
            .blocks(bx, by);
            let vars = Replicates {
                width: w,
                height: h,
                images: vec![var.clone()],
            }
            .blocks(bx, by);
            let n = f64::from(w * h / (bx * by));
            Estimate {
                width: bx,
                height: by,
                mean: one.images[0].clone(),
                var: vars.images[0].iter().map(|v| *v / n).collect(),
                dof: f64::INFINITY,
            }
        };
        Self {
            mean: blocks(1, 1),
            blocks: blocks(bx, by),
            pixels: Estimate {
                width: w,
                height: h,
                mean: pixels,
                var,
                dof: f64::from(EXPLICIT_SPP - 1),
            },
            scene,
            path,
            width: w,
            height: h,
            bx,
            by,
        }
    }

    /// The camera of the reference's film.
    pub fn camera(&self) -> Camera {
        self.scene.camera(self.width, self.height)
    }

    /// Compares replicates with the reference (significance `a` per test, `z_crit` for the
    /// one-sided squared-error statistic); prints the figures and returns what failed.
    pub fn check(&self, label: &str, reps: &Replicates, a: f64, z_crit: f64) -> Vec<String> {
        let m = welch(
            &format!("{label} mean"),
            &reps.image_mean().estimate(),
            &self.mean,
        );
        let b = welch(
            &format!("{label} block"),
            &reps.blocks(self.bx, self.by).estimate(),
            &self.blocks,
        );
        let (ratio, pz) = mse_z(&reps.estimate(), &self.pixels);
        println!(
            "{label}: mean {:.4} (reference {:.4}) | max|z| mean {:.2}, blocks {:.2} | pixel mse/var {ratio:.3} (z {pz:.2})\n    worst block: {}",
            reps.image_mean().estimate().mean[0],
            self.mean.mean[0],
            m.z(),
            b.z(),
            b.worst
        );
        let mut f: Vec<String> = [m, b]
            .into_iter()
            .filter(|r| r.min_p < a)
            .map(|r| r.worst)
            .collect();
        if pz > z_crit {
            f.push(format!("{label}: pixel mse/var {ratio:.3}, z {pz:.2}"));
        }
        f
    }
}
