//! Numerical stress tests of the kernel: what a production renderer meets at the edges of its
//! input domain.
//!
//! - Extreme uniforms: every warp of `math::warp`, every BSDF sampler and emitter sampling fed
//!   `u` in {0, 1e-7, `f32::MIN_POSITIVE`, 0.5, 1 − 2⁻²⁴} in every dimension must return a
//!   finite unit direction with a finite positive pdf, or no sample; emitter points must lie on
//!   their triangle within the error bound the kernel reports for them.
//! - Extreme materials: Phong exponents 0, 1, 1e6, `Kd + Ks` far above 1, `Kd = Ks = 0`;
//!   conductors and dielectrics at alpha 0 and 1e-4 (effectively smooth: the delta path),
//!   1e-3 exactly (the narrowest rough lobe) and 1, dielectrics with eta 1, 1 ± 1e-4, 1/1.5,
//!   1.5 and 10, black Ks and Tf; outgoing directions from normal to exactly on the horizon
//!   and just below it (inside a dielectric), uc and u extreme independently, both transport
//!   modes.
//! - Geometry at extreme scales: unnormalised ray directions from 1e-6 to 1e6 long against
//!   triangles from 1e-6 to 1e6 wide; random walks and shadow rays inside a closed box scaled
//!   by 1e-4 … 1e4 and translated by 1e5 never escape and never see a false shadow.
//! - Property tests (proptest, fixed seed so CI is reproducible; set `PROPTEST_RNG_SEED` to
//!   explore other cases) over random directions and parameters: `eval`/`pdf` finite and
//!   non-negative, `sample` consistent with `pdf` and `eval`, reciprocity (generalised for
//!   dielectric transmission), Monte Carlo albedo at most 1 after the energy clamp (at most Ks
//!   for a conductor, 1 in importance transport for a dielectric), `Frame` round trips, and
//!   the watertight triangle test never missing a ray aimed at an interior point or at a
//!   shared edge.

use ember_kernel::bsdf::{Bsdf, Conductor, Dielectric, Diffuse, Phong, TransportMode};
use ember_kernel::bvh::Bvh;
use ember_kernel::emitter::{emitter_pdf, sample_emitter};
use ember_kernel::geometry::intersect_triangle;
use ember_kernel::glam::{DVec3, Vec2, Vec3};
use ember_kernel::math::{next_float_down, next_float_up, warp, Frame};
use ember_kernel::sampler::{IndependentSampler, Sampler, ONE_MINUS_EPSILON};
use ember_kernel::scene::{Material, SceneView};
use proptest::prelude::*;
use proptest::test_runner::{Config, RngSeed};

const MODE: TransportMode = TransportMode::Radiance;

/// The extreme uniforms of the issue: 0, tiny, the smallest normal float, the middle and the
/// largest value a sampler returns.
const US: [f32; 5] = [0.0, 1e-7, f32::MIN_POSITIVE, 0.5, ONE_MINUS_EPSILON];

/// Every 2D combination of [`US`].
fn extreme_2d() -> impl Iterator<Item = Vec2> {
    US.iter()
        .flat_map(|&x| US.iter().map(move |&y| Vec2::new(x, y)))
}

fn unit(v: Vec3) -> bool {
    v.is_finite() && (v.length() - 1.0).abs() < 1e-5
}

fn outgoing(cos_theta: f32, phi: f32) -> Vec3 {
    let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
    Vec3::new(sin_theta * phi.cos(), sin_theta * phi.sin(), cos_theta)
}

/// BSDFs at the edges of their parameter space.
fn extreme_bsdfs() -> Vec<(String, Bsdf)> {
    let mut v = vec![
        (
            "Diffuse Kd=0".to_string(),
            Bsdf::Diffuse(Diffuse::new(Vec3::ZERO)),
        ),
        (
            "Diffuse Kd=1".to_string(),
            Bsdf::Diffuse(Diffuse::new(Vec3::ONE)),
        ),
    ];
    for ns in [0.0f32, 1.0, 1e6] {
        for (kd, ks) in [
            (Vec3::ZERO, Vec3::ONE),
            (Vec3::splat(0.5), Vec3::splat(0.5)),
            (Vec3::splat(2.0), Vec3::splat(2.0)),
            (Vec3::new(1.0, 0.0, 0.3), Vec3::new(0.0, 1e-30, 0.0)),
        ] {
            v.push((
                format!("Phong Kd={kd} Ks={ks} Ns={ns}"),
                Bsdf::Phong(Phong::new(kd, ks, ns)),
            ));
            v.push((
                format!("Mixture Kd={kd} Ks={ks} Ns={ns}"),
                Bsdf::Mixture(Phong::new(kd, ks, ns)),
            ));
        }
    }
    for ns in [0.0f32, 1e6] {
        v.push((
            format!("Phong Kd=Ks=0 Ns={ns}"),
            Bsdf::Phong(Phong::new(Vec3::ZERO, Vec3::ZERO, ns)),
        ));
    }
    v.extend(extreme_microfacet_bsdfs());
    v
}

/// Roughnesses at the edges: smooth (0), effectively smooth (1e-4 < 1e-3: the delta path), the
/// narrowest rough lobe (1e-3 exactly), a narrow and a very wide one.
const ALPHAS: [f32; 5] = [0.0, 1e-4, 1e-3, 0.05, 1.0];

/// Conductors and dielectrics at the edges of their parameter space.
fn extreme_microfacet_bsdfs() -> Vec<(String, Bsdf)> {
    let mut v = Vec::new();
    for alpha in ALPHAS {
        for ks in [Vec3::ONE, Vec3::ZERO, Vec3::new(1.0, 0.0, 1e-30)] {
            v.push((
                format!("Conductor Ks={ks} alpha={alpha}"),
                Bsdf::Conductor(Conductor::new(ks, alpha)),
            ));
        }
        for eta in [1.0f32, 1.0001, 0.9999, 1.5, 1.0 / 1.5, 10.0] {
            for tf in [Vec3::ONE, Vec3::ZERO] {
                v.push((
                    format!("Dielectric eta={eta} Tf={tf} alpha={alpha}"),
                    Bsdf::Dielectric(Dielectric::new(eta, tf, alpha)),
                ));
            }
        }
    }
    v
}

fn is_opaque(b: &Bsdf) -> bool {
    !matches!(b, Bsdf::Dielectric(_))
}

/// Outgoing directions from normal incidence to the most grazing ones f32 can represent.
fn extreme_wos() -> Vec<Vec3> {
    vec![
        Vec3::Z,
        outgoing(0.7, 1.1),
        outgoing(0.05, -2.0),
        outgoing(1e-4, 0.3),
        Vec3::new(1.0, 0.0, 1e-7).normalize(),
        Vec3::new(0.0, -1.0, f32::MIN_POSITIVE),
        Vec3::new(1.0, 0.0, 1e-20),
        // Exactly on the horizon, then just below it and further (inside a dielectric, behind
        // an opaque surface).
        Vec3::new(0.6, 0.8, 0.0),
        Vec3::new(1.0, 0.0, -1e-7).normalize(),
        Vec3::new(0.0, 1.0, -f32::MIN_POSITIVE),
        outgoing(-1e-4, 0.3),
        outgoing(-0.7, 1.1),
        -Vec3::Z,
    ]
}

// ---------------------------------------------------------------------------------------------
// Extreme uniforms: warps
// ---------------------------------------------------------------------------------------------

#[test]
fn warps_survive_extreme_uniforms() {
    for u in extreme_2d() {
        let d = warp::sample_concentric_disk(u);
        assert!(d.is_finite() && d.length() <= 1.0 + 1e-6, "disk {u}: {d}");
        let back = warp::invert_concentric_disk(d);
        assert!(back.is_finite() && back.min_element() >= 0.0 && back.max_element() <= 1.0);

        // Cosine hemisphere: unit, upper hemisphere. A zero pdf happens only on the horizon,
        // where `Bsdf::sample` rejects the sample (wi.z == 0): "no sample".
        let w = warp::sample_cosine_hemisphere(u);
        let pdf = warp::cosine_hemisphere_pdf(w.z);
        assert!(unit(w) && w.z >= 0.0, "cosine {u}: {w}");
        assert!(pdf.is_finite() && pdf >= 0.0, "cosine {u}: pdf {pdf}");
        assert!(pdf > 0.0 || w.z == 0.0, "cosine {u}: {w} has pdf 0");
        let back = warp::invert_cosine_hemisphere_sample(w);
        assert!(back.is_finite(), "cosine inverse {u}: {back}");

        for n in [0.0f32, 1.0, 30.0, 1e4, 1e6] {
            let w = warp::sample_phong_lobe(u, n);
            let pdf = warp::phong_lobe_pdf(w.z, n);
            assert!(unit(w) && w.z >= 0.0, "phong n={n} {u}: {w}");
            assert!(pdf.is_finite() && pdf >= 0.0, "phong n={n} {u}: {pdf}");
            assert!(pdf > 0.0 || w.z == 0.0, "phong n={n} {u}: {w} has pdf 0");
            let back = warp::invert_phong_lobe_sample(w, n);
            assert!(back.is_finite(), "phong inverse n={n} {u}: {back}");
        }

        // Triangle barycentrics: inside the closed triangle, b0 computed as the kernel does.
        let b = warp::sample_uniform_triangle(u);
        let b0 = 1.0 - b.x - b.y;
        assert!(
            b.is_finite() && b.x >= 0.0 && b.y >= 0.0 && b0 >= 0.0,
            "triangle {u}: {b} (b0 {b0})"
        );
        let back = warp::invert_uniform_triangle_sample(b);
        assert!(back.is_finite(), "triangle inverse {u}: {back}");

        let s = warp::sample_uniform_sphere(u);
        assert!(unit(s), "sphere {u}: {s}");
    }
}

// ---------------------------------------------------------------------------------------------
// Extreme uniforms and materials: BSDF samplers
// ---------------------------------------------------------------------------------------------

#[test]
fn bsdf_samplers_survive_extreme_uniforms_and_materials() {
    let (mut samples, mut outside_support) = (0, 0);
    for (name, bsdf) in extreme_bsdfs() {
        if let Bsdf::Phong(p) | Bsdf::Mixture(p) = bsdf {
            assert!(
                p.scale.is_finite() && p.scale > 0.0 && p.scale <= 1.0,
                "{name}: scale {}",
                p.scale
            );
            assert!(
                (0.0..=1.0).contains(&p.specular_weight),
                "{name}: specular weight {}",
                p.specular_weight
            );
        }
        let phong_family = matches!(bsdf, Bsdf::Diffuse(_) | Bsdf::Phong(_) | Bsdf::Mixture(_));
        for wo in extreme_wos() {
            for mode in [TransportMode::Radiance, TransportMode::Importance] {
                // The lobe number uc and the direction u are independent dimensions: every
                // combination of extremes (uc = 0 and 1 − 2⁻²⁴ pick the first and last lobes).
                for uc in US {
                    for u in extreme_2d() {
                        let Some(s) = bsdf.sample(wo, uc, u, mode) else {
                            continue;
                        };
                        samples += 1;
                        let ctx = format!("{name} {mode:?} wo={wo} uc={uc} u={u}: {s:?}");
                        outside_support += usize::from(check_sample(&bsdf, wo, &s, mode, &ctx));
                        if phong_family {
                            assert_eq!(s.pdf, bsdf.pdf(wo, s.wi, mode), "{ctx}");
                            assert_eq!(s.f, bsdf.eval(wo, s.wi, mode), "{ctx}");
                        }
                    }
                }
                // eval and pdf on the extreme directions themselves (both ways round).
                for wi in extreme_wos() {
                    for (a, b) in [(wo, wi), (wi, wo)] {
                        let f = bsdf.eval(a, b, mode);
                        let p = bsdf.pdf(a, b, mode).0;
                        assert!(
                            f.is_finite() && f.min_element() >= 0.0,
                            "{name} {a} {b}: {f}"
                        );
                        assert!(p.is_finite() && p >= 0.0, "{name} {a} {b}: pdf {p}");
                        if is_opaque(&bsdf) && (a.z <= 0.0 || b.z <= 0.0) {
                            assert_eq!((f, p), (Vec3::ZERO, 0.0), "{name} {a} {b}");
                        }
                        if bsdf.flags().is_specular() || a.z == 0.0 || b.z == 0.0 {
                            assert_eq!((f, p), (Vec3::ZERO, 0.0), "{name} {a} {b}");
                        }
                    }
                }
            }
        }
    }
    assert!(samples > 50_000, "only {samples} samples were produced");
    // Ill-conditioned near-index-matched samples: few. |η′wi + wo| ≥ |η′ − 1|, so only the
    // η = 1 ± 1e-4 dielectrics can have them; u.y = 1 − 2⁻²⁴ picks microfacets grazing wo on
    // purpose, so they are more frequent here (1e-3) than under random uniforms (1e-4).
    assert!(
        outside_support * 100 < samples,
        "{outside_support} of {samples}"
    );
    println!("{samples} samples, {outside_support} just outside the support (see check_sample)");
}

/// What every sample of every BSDF must satisfy, whatever the inputs: a finite unit direction
/// off the horizon, on the side its flags say (opaque BSDFs: above the surface, and only for
/// wo above it), finite positive pdf, finite non-negative f and weight, flags among the BSDF's,
/// eta 1 for reflection and η′ (finite, positive) for transmission; a delta sample has no
/// eval/pdf, a non-delta one has a finite `eval()` and a finite `pdf()`, positive unless the
/// half vector is ill-conditioned.
///
/// Ill-conditioned: `pdf()` rebuilds the microfacet normal from m ∝ η′wi + wo. Through a
/// nearly index-matched boundary (η = 1 ± 1e-4) wi ≈ −wo and |η′wi + wo| ≈ |η′ − 1| ≈ 1e-4, so
/// the f32 rounding of wi alone (6e-8) turns m by ~6e-4 rad, and a sample through a microfacet
/// grazing wo can land just outside the support (~1e-4 of the samples at η 1.0001, alpha 1;
/// 1e-5 at η 1.001; none at η ≥ 1.01 in 200 000 samples). Those (|η′wi + wo| < 1e-2) may have
/// `pdf() = 0`; the function returns whether the sample was such a case.
fn check_sample(
    bsdf: &Bsdf,
    wo: Vec3,
    s: &ember_kernel::bsdf::BsdfSample,
    mode: TransportMode,
    ctx: &str,
) -> bool {
    assert!(unit(s.wi) && s.wi.z != 0.0, "{ctx}");
    assert!(s.pdf.0.is_finite() && s.pdf.0 > 0.0, "{ctx}");
    assert!(s.f.is_finite() && s.f.min_element() >= 0.0, "{ctx}");
    let w = s.weight();
    assert!(w.is_finite() && w.min_element() >= 0.0, "{ctx}: weight {w}");
    assert!(
        bsdf.flags().contains(s.flags),
        "{ctx}: flags {:?}",
        bsdf.flags()
    );
    // Signs, not the product: wo.z·wi.z underflows to −0 for wo.z = MIN_POSITIVE.
    let transmitted = (s.wi.z < 0.0) != (wo.z < 0.0);
    assert_eq!(transmitted, s.flags.is_transmission(), "{ctx}");
    if is_opaque(bsdf) {
        assert!(wo.z > 0.0 && s.wi.z > 0.0, "{ctx}");
    }
    if transmitted {
        assert!(s.eta.is_finite() && s.eta > 0.0, "{ctx}");
    } else {
        assert_eq!(s.eta, 1.0, "{ctx}");
    }
    let (f, p) = (bsdf.eval(wo, s.wi, mode), bsdf.pdf(wo, s.wi, mode).0);
    assert!(f.is_finite() && f.min_element() >= 0.0, "{ctx}: eval {f}");
    assert!(p.is_finite() && p >= 0.0, "{ctx}: pdf {p}");
    if s.flags.is_specular() {
        assert_eq!((f, p), (Vec3::ZERO, 0.0), "{ctx}");
        assert!(s.pdf.0 <= 1.0, "{ctx}: a lobe probability above 1");
        return false;
    }
    let ill_conditioned =
        transmitted && (s.wi.as_dvec3() * f64::from(s.eta) + wo.as_dvec3()).length() < 1e-2;
    assert!(
        p > 0.0 || ill_conditioned,
        "{ctx}: pdf() = 0 at a sampled direction"
    );
    ill_conditioned && p == 0.0
}

/// Black conductors and transmissions: no NaN (0/0) anywhere, nothing scattered where nothing
/// can be.
#[test]
fn black_microfacets_have_no_nan_anywhere() {
    for alpha in ALPHAS {
        let conductor = Bsdf::Conductor(Conductor::new(Vec3::ZERO, alpha));
        let opaque_glass = Bsdf::Dielectric(Dielectric::new(1.5, Vec3::ZERO, alpha));
        for wo in extreme_wos() {
            for mode in [TransportMode::Radiance, TransportMode::Importance] {
                for uc in US {
                    for u in extreme_2d() {
                        let ctx = format!("alpha={alpha} wo={wo} uc={uc} u={u}");
                        assert!(conductor.sample(wo, uc, u, mode).is_none(), "{ctx}");
                        if let Some(s) = opaque_glass.sample(wo, uc, u, mode) {
                            assert!(!s.flags.is_transmission(), "{ctx}: {s:?}");
                            let _ = check_sample(&opaque_glass, wo, &s, mode, &ctx);
                        }
                    }
                }
                for wi in extreme_wos() {
                    assert_eq!(conductor.eval(wo, wi, mode), Vec3::ZERO);
                    assert!(conductor.pdf(wo, wi, mode).0.is_finite());
                    let f = opaque_glass.eval(wo, wi, mode);
                    assert!(f.is_finite(), "alpha={alpha} {wo} {wi}: {f}");
                    if wo.z * wi.z < 0.0 {
                        assert_eq!(f, Vec3::ZERO);
                    }
                }
            }
        }
    }
}

/// `Kd = Ks = 0`: TinyRender's specular weight is 0/0; ember's must not leak a NaN anywhere,
/// and the BSDF must reflect nothing.
#[test]
fn black_phong_has_no_nan_anywhere() {
    for ns in [0.0f32, 1.0, 1e6] {
        let p = Phong::new(Vec3::ZERO, Vec3::ZERO, ns);
        assert!(!p.specular_weight.is_nan() && !p.scale.is_nan(), "{p:?}");
        for bsdf in [Bsdf::Phong(p), Bsdf::Mixture(p)] {
            for wo in extreme_wos() {
                for u in extreme_2d() {
                    assert!(bsdf.sample(wo, u.x, u, MODE).is_none(), "{bsdf:?} {wo} {u}");
                    let wi = warp::sample_cosine_hemisphere(u);
                    assert_eq!(bsdf.eval(wo, wi, MODE), Vec3::ZERO);
                    let pdf = bsdf.pdf(wo, wi, MODE).0;
                    assert!(pdf.is_finite() && pdf >= 0.0, "{bsdf:?}: pdf {pdf}");
                }
            }
        }
    }
}

/// The white GGX reflection D(m)·G₂·F/(4|cosθₒ cosθᵢ|) in f64 (F = 1 for a conductor, the
/// exact Fresnel of η for a dielectric), written independently of the kernel.
fn ggx_reflection_f64(alpha: f64, eta: Option<f64>, wo: DVec3, wi: DVec3) -> f64 {
    let m = (wo + wi).normalize();
    let m = if m.z < 0.0 { -m } else { m };
    let a2 = alpha * alpha;
    let d = {
        let cos2 = m.z * m.z;
        let sin2 = 1.0 - cos2;
        a2 / (std::f64::consts::PI * (sin2 + a2 * cos2).powi(2))
    };
    let lambda = |w: DVec3| {
        let cos2 = w.z * w.z;
        0.5 * (((cos2 + a2 * (1.0 - cos2)) / cos2).sqrt() - 1.0)
    };
    let g = 1.0 / (1.0 + lambda(wo) + lambda(wi));
    let f = eta.map_or(1.0, |eta| {
        let c = wo.dot(m).abs();
        let e = if wo.z > 0.0 { eta } else { 1.0 / eta };
        let g2 = e * e - 1.0 + c * c;
        if g2 <= 0.0 {
            return 1.0;
        }
        let g = g2.sqrt();
        let a = (g - c) / (g + c);
        let b = (c * (g + c) - 1.0) / (c * (g - c) + 1.0);
        0.5 * a * a * (1.0 + b * b)
    });
    d * g * f / (4.0 * (wo.z * wi.z).abs())
}

/// Microfacet BSDFs at grazing pairs keep their value instead of turning into NaN or into the
/// wrong lobe:
/// - the mirror-symmetric pair wo = (1, 0, c), wi = (−1, 0, c) has the half vector +z,
///   G/c² → 1/(αc) (Λ ≈ α tanθ/2) and F → 1, so f·cosθᵢ → D(z)/(4α) = 1/(4πα³), to 1e-3 for
///   c from 1e-8 to 1e-18 (the remaining O(c) terms are far below it). Past that |wo + wi|² =
///   4c² is subnormal and the half vector cannot be normalised accurately (then not at all):
///   the value must still be finite and non-negative (the kernel once returned NaN once c²
///   underflowed, c < 4e-23);
/// - pairs whose cosines are 1e-25 and 1e-21 (their product underflows to 0; a dielectric once
///   classified such a same-side pair as a transmission by the sign of the product) match the
///   f64 formula to 1e-4 (their half vector is far from the horizon-parallel cancellation).
#[test]
fn grazing_pairs_keep_their_value() {
    for alpha in [1e-3f32, 0.05, 0.5, 1.0] {
        let limit = 1.0 / (4.0 * std::f64::consts::PI * f64::from(alpha).powi(3));
        for (eta, bsdf) in [
            (None, Bsdf::Conductor(Conductor::new(Vec3::ONE, alpha))),
            (
                Some(1.5),
                Bsdf::Dielectric(Dielectric::new(1.5, Vec3::ONE, alpha)),
            ),
        ] {
            let sides: &[f32] = if eta.is_some() { &[1.0, -1.0] } else { &[1.0] };
            for mode in [TransportMode::Radiance, TransportMode::Importance] {
                for &side in sides {
                    for k in 8..=38 {
                        let c = 10f32.powi(-k);
                        let wo = Vec3::new(1.0, 0.0, side * c);
                        let wi = Vec3::new(-1.0, 0.0, side * c);
                        let f = bsdf.eval(wo, wi, mode);
                        let ctx = format!("{bsdf:?} side {side} c=1e-{k}: f = {f}");
                        assert!(f.is_finite() && f.min_element() >= 0.0, "{ctx}");
                        if k <= 18 {
                            let value = f64::from(f.x) * f64::from(c);
                            assert!((value - limit).abs() <= 1e-3 * limit, "{ctx}: {limit}");
                        }
                    }
                    let wo = Vec3::new(1.0, 0.0, side * 1e-25);
                    let wi = Vec3::new(0.0, 1.0, side * 1e-21);
                    assert_eq!(wo.z * wi.z, 0.0, "the product must underflow");
                    for (a, b) in [(wo, wi), (wi, wo)] {
                        let f = f64::from(bsdf.eval(a, b, mode).x);
                        let want =
                            ggx_reflection_f64(f64::from(alpha), eta, a.as_dvec3(), b.as_dvec3());
                        assert!(
                            (f - want).abs() <= 1e-4 * want,
                            "{bsdf:?} {a} {b}: {f} vs f64 {want}"
                        );
                    }
                }
            }
        }
    }
}

/// Monte Carlo albedo (mean weight f·cosθᵢ/pdf) with its standard error, per channel.
/// Dielectrics in importance transport (which carries power: radiance is scaled by 1/η′²),
/// everything else in radiance transport.
fn mc_albedo(bsdf: &Bsdf, wo: Vec3, n: u32, seed: u64) -> (DVec3, DVec3) {
    let mode = if is_opaque(bsdf) {
        MODE
    } else {
        TransportMode::Importance
    };
    let (mut sum, mut sum2) = (DVec3::ZERO, DVec3::ZERO);
    for i in 0..n {
        let mut sampler = IndependentSampler::new(seed, u64::from(i), 0);
        let uc = sampler.next_1d();
        let u = sampler.next_2d();
        if let Some(s) = bsdf.sample(wo, uc, u, mode) {
            let w = s.weight().as_dvec3();
            sum += w;
            sum2 += w * w;
        }
    }
    let nf = f64::from(n);
    let mean = sum / nf;
    let var = (sum2 / nf - mean * mean).max(DVec3::ZERO) * (nf / (nf - 1.0));
    (mean, (var / nf).map(f64::sqrt))
}

/// The energy clamp holds at the extremes: `Kd + Ks` up to 4 per channel, exponents 0 to 1e6.
/// 4 standard errors, one-sided: the clamp makes the true albedo at most 0.99 (and exactly 1
/// for the diffuse Kd = 1, whose weight is 1 up to f32 rounding: hence the 1e-6). Conductors
/// (Ks ≤ 1 here) and dielectrics (Tf ≤ 1, importance transport) conserve energy at every
/// roughness and index, from both sides.
#[test]
fn extreme_materials_reflect_at_most_everything() {
    for (name, bsdf) in extreme_bsdfs() {
        let wos = extreme_wos();
        let mut chosen: Vec<Vec3> = wos[..4].to_vec();
        if !is_opaque(&bsdf) {
            chosen.extend([outgoing(-0.7, 1.1), outgoing(-1e-4, 0.3)]);
        }
        for (k, wo) in chosen.into_iter().enumerate() {
            let (mean, se) = mc_albedo(&bsdf, wo, 20_000, 77 + k as u64);
            for c in 0..3 {
                assert!(
                    mean[c] <= 1.0 + 4.0 * se[c] + 1e-6,
                    "{name} wo={wo}: albedo {mean} ± {se}"
                );
            }
        }
    }
    // Normal incidence, Kd = 0, Ks = 1: the lobe is normalised, so everything is reflected
    // (up to the part of a wide lobe below the horizon; none for Ns = 1e6).
    let mirror = Bsdf::Phong(Phong::new(Vec3::ZERO, Vec3::ONE, 1e6));
    let (mean, se) = mc_albedo(&mirror, Vec3::Z, 20_000, 5);
    assert!(
        (mean - DVec3::ONE).abs().max_element() < 4.0 * se.max_element() + 1e-5,
        "Ns=1e6 at normal incidence: {mean} ± {se}"
    );
}

// ---------------------------------------------------------------------------------------------
// Ray/triangle: unnormalised directions of any length
// ---------------------------------------------------------------------------------------------

/// Rays need not be normalised (shadow rays are `target − origin`). A triangle of size `s`
/// seen from a distance of `s`, for `s` from 1e-6 to 1e6, with the direction scaled by `k`
/// from 1e-6 to 1e6 (so the hit is at t = 1/k): every ray hits, at the right t, and a
/// shadow-ray `t_max` just short of the hit sees nothing.
///
/// (A kernel bug this test found: the conservative `t > 0` bound added the ray-parameter
/// scaled |z| to world-space x/y errors, so a direction of length 1e-6 rejected every hit; see
/// `intersect_triangle`.)
#[test]
fn unnormalised_directions_of_any_length_hit() {
    let mut cases = 0;
    for se in -6..=6 {
        let s = 10f32.powi(se);
        let tri = [
            Vec3::new(-1.0, -1.0, 0.3),
            Vec3::new(1.2, -0.8, -0.2),
            Vec3::new(0.1, 1.1, 0.0),
        ]
        .map(|v| v * s);
        for (k, from) in [
            Vec3::new(0.2, 0.3, 1.0),
            Vec3::new(-0.7, 0.1, -0.5),
            Vec3::new(0.05, -1.0, 0.9),
        ]
        .into_iter()
        .enumerate()
        {
            let target = (tri[0] + tri[1] + tri[2]) / 3.0 + Vec3::new(0.01, -0.02, 0.0) * s;
            let o = target + from.normalize() * s;
            for ke in -6..=6 {
                let scale = 10f32.powi(ke);
                let d = (target - o) * scale;
                let ctx = format!("size {s}, from #{k}, |d| = {}", d.length());
                let (t, b, _) = exact_crossing(o, d, tri).unwrap();
                assert!(b.iter().all(|&x| x > 0.1), "{ctx}: {b:?}");
                let h = intersect_triangle(o, d, f32::INFINITY, tri[0], tri[1], tri[2])
                    .unwrap_or_else(|| panic!("{ctx}: missed (exact t = {t})"));
                assert!(
                    (f64::from(h.t) - t).abs() <= 1e-4 * t,
                    "{ctx}: t {} vs {t}",
                    h.t
                );
                let short = (t * (1.0 - 1e-4)) as f32;
                assert!(
                    intersect_triangle(o, d, short, tri[0], tri[1], tri[2]).is_none(),
                    "{ctx}: hit before t_max = {short}"
                );
                // The reverse ray, leaving the hit point away from the triangle, never hits.
                let p = o + d * h.t;
                assert!(
                    intersect_triangle(p, -d, f32::INFINITY, tri[0], tri[1], tri[2]).is_none()
                        || (p - target).length() > 1e-3 * s,
                    "{ctx}"
                );
                cases += 1;
            }
        }
    }
    assert_eq!(cases, 13 * 3 * 13);
}

// ---------------------------------------------------------------------------------------------
// A closed box at every scale and offset: no ray escapes, no false shadow
// ---------------------------------------------------------------------------------------------

/// The cube [-1, 1]³ with `n × n` quads per face, facing inward, mapped by `f`:
/// (positions, normals, triangles, face of each triangle).
fn closed_box(n: usize, f: impl Fn(Vec3) -> Vec3) -> (Vec<Vec3>, Vec<Vec3>, Vec<[u32; 3]>) {
    let (mut pos, mut nrm, mut tris) = (Vec::new(), Vec::new(), Vec::new());
    for axis in 0..3 {
        for sign in [-1.0f32, 1.0] {
            let inward = -Vec3::AXES[axis] * sign;
            let (u, v) = (Vec3::AXES[(axis + 1) % 3], Vec3::AXES[(axis + 2) % 3]);
            // Counter-clockwise seen from inside.
            let (u, v) = if sign > 0.0 { (v, u) } else { (u, v) };
            let base = pos.len() as u32;
            for j in 0..=n {
                for i in 0..=n {
                    let (a, b) = (
                        2.0 * i as f32 / n as f32 - 1.0,
                        2.0 * j as f32 / n as f32 - 1.0,
                    );
                    pos.push(f(-inward + u * a + v * b));
                    nrm.push(inward);
                }
            }
            let at = |i: usize, j: usize| base + (j * (n + 1) + i) as u32;
            for j in 0..n {
                for i in 0..n {
                    tris.push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
                    tris.push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
                }
            }
        }
    }
    (pos, nrm, tris)
}

/// Random walks inside a closed box (4×4 quads per face) scaled by 1e-4 … 1e4 and translated
/// by 1e4 and 1e5: every ray spawned from a hit (cosine-distributed about the inward normal)
/// hits the box again, and every shadow ray to a point on another face is unoccluded. This is
/// the kernel-level twin of the furnace test in `tests/tests/stability.rs`.
///
/// (Kernel bugs this test found: hit points within rounding of a room's edge spawned rays
/// from behind the adjacent wall, or so close to it that the intersection could not prove the
/// hit; and the symmetric barycentric interpolation's error bound made offsets of 0.04 at
/// 1e5. See `inset_barycentrics` and `triangle_point`.)
#[test]
fn closed_box_does_not_leak_at_any_scale_or_offset() {
    use ember_kernel::bvh::{build, max_nodes, BvhNode};
    use ember_kernel::geometry::{spawn_ray_to, triangle_point, Aabb};
    let walks = if cfg!(debug_assertions) { 300 } else { 2000 };
    for (scale, offset) in [
        (1e-4f64, 0.0f64),
        (1e-2, 0.0),
        (1.0, 0.0),
        (1e2, 0.0),
        (1e4, 0.0),
        (1.0, 1e4),
        (1.0, 1e5),
    ] {
        let f = |p: Vec3| (p.as_dvec3() * scale + DVec3::splat(offset)).as_vec3();
        let (positions, normals, triangles) = closed_box(4, f);
        let bounds: Vec<Aabb> = triangles
            .iter()
            .map(|t| {
                Aabb::from_points(
                    positions[t[0] as usize],
                    positions[t[1] as usize],
                    positions[t[2] as usize],
                )
            })
            .collect();
        let mut nodes = vec![BvhNode::default(); max_nodes(bounds.len())];
        let mut order = vec![0u32; bounds.len()];
        let used = build(&bounds, &mut nodes, &mut order).unwrap();
        let materials = [Material::diffuse(Vec3::splat(0.8))];
        let triangle_materials = vec![0u32; triangles.len()];
        let scene = SceneView {
            positions: &positions,
            normals: &normals,
            triangles: &triangles,
            triangle_materials: &triangle_materials,
            materials: &materials,
            emitter_triangles: &[],
            emitter_cdf: &[],
            bvh: Bvh {
                nodes: &nodes[..used],
                prim_order: &order,
            }
            .into(),
            textures: ember_kernel::texture::Textures::NONE,
        };
        scene.validate().unwrap();
        let label = format!("scale {scale:e}, offset {offset:e}");
        let (mut escapes, mut shadowed, mut rays) = (0, 0, 0);
        for w in 0..walks {
            let mut s = IndependentSampler::new(99, w, 0);
            let dir = warp::sample_uniform_sphere(s.next_2d());
            let ray = ember_kernel::geometry::Ray::new(f(Vec3::ZERO), dir);
            let mut hit = scene.intersect(&ray).expect("camera ray escaped");
            let mut d = dir;
            for _ in 0..100 {
                let si = scene.surface_at(hit.triangle, hit.b1, hit.b2, -d);
                // A shadow ray to a random point of a triangle on another face.
                let k = (s.next_1d() * triangles.len() as f32) as usize % triangles.len();
                if k / 32 != hit.triangle as usize / 32 {
                    let [p0, p1, p2] = scene.triangle_vertices(k as u32);
                    let b = warp::sample_uniform_triangle(s.next_2d());
                    let (q, q_err) = triangle_point(b.x, b.y, p0, p1, p2);
                    let n = normals[triangles[k][0] as usize];
                    let shadow = spawn_ray_to(si.p_spawn, si.p_err, si.ng, q, q_err, n);
                    shadowed += usize::from(scene.occluded(&shadow));
                }
                let local = warp::sample_cosine_hemisphere(s.next_2d());
                d = ember_kernel::math::Frame::from_normal(si.ng).to_world(local);
                if local.z <= 0.0 {
                    continue;
                }
                rays += 1;
                match scene.intersect(&si.spawn_ray(d)) {
                    Some(h) => hit = h,
                    None => {
                        escapes += 1;
                        break;
                    }
                }
            }
        }
        println!("{label}: {rays} rays, {escapes} escaped, {shadowed} false shadows");
        assert_eq!(
            (escapes, shadowed),
            (0, 0),
            "{label}: leaks out of {rays} rays"
        );
    }
}

// ---------------------------------------------------------------------------------------------
// Extreme uniforms: emitter sampling
// ---------------------------------------------------------------------------------------------

/// An emitter-only scene over `tris` with selection probabilities given by `cdf`.
struct EmitterScene {
    positions: Vec<Vec3>,
    normals: Vec<Vec3>,
    triangles: Vec<[u32; 3]>,
    triangle_materials: Vec<u32>,
    materials: Vec<Material>,
    emitter_triangles: Vec<u32>,
    emitter_cdf: Vec<f32>,
}

impl EmitterScene {
    fn new(tris: &[[Vec3; 3]], cdf: &[f32]) -> Self {
        let mut s = Self {
            positions: Vec::new(),
            normals: Vec::new(),
            triangles: Vec::new(),
            triangle_materials: Vec::new(),
            materials: vec![Material::diffuse(Vec3::ZERO).with_emission(Vec3::splat(1e6))],
            emitter_triangles: (0..tris.len() as u32).collect(),
            emitter_cdf: cdf.to_vec(),
        };
        for t in tris {
            let n = (t[1] - t[0]).cross(t[2] - t[0]).normalize_or_zero();
            let base = s.positions.len() as u32;
            s.positions.extend_from_slice(t);
            // Unnormalised vertex normals (and zero ones for degenerate triangles).
            s.normals.extend([n * 3.0, n * 0.5, n]);
            s.triangles.push([base, base + 1, base + 2]);
            s.triangle_materials.push(0);
        }
        s
    }

    fn view(&self) -> SceneView<'_> {
        SceneView {
            positions: &self.positions,
            normals: &self.normals,
            triangles: &self.triangles,
            triangle_materials: &self.triangle_materials,
            materials: &self.materials,
            emitter_triangles: &self.emitter_triangles,
            emitter_cdf: &self.emitter_cdf,
            bvh: Bvh {
                nodes: &[],
                prim_order: &[],
            }
            .into(),
            textures: ember_kernel::texture::Textures::NONE,
        }
    }
}

#[test]
fn emitter_sampling_survives_extreme_uniforms() {
    let o = Vec3::splat(1e5);
    let tris = [
        // 0: zero area (one point), selection probability 0, first in the CDF.
        [Vec3::ONE; 3],
        // 1: an ordinary triangle.
        [Vec3::ZERO, Vec3::X, Vec3::Y],
        // 2: collinear, selection probability 0, in the middle of the CDF.
        [Vec3::ZERO, Vec3::X, Vec3::X * 2.0],
        // 3: tiny (area 5e-13), with a quarter of the selection probability.
        [Vec3::ZERO, Vec3::X * 1e-6, Vec3::Z * 1e-6],
        // 4: far from the origin (1e5 along the diagonal), slanted.
        [
            o,
            o + Vec3::new(1.0, 0.5, 0.0),
            o + Vec3::new(0.0, 1.0, 0.25),
        ],
        // 5: huge.
        [Vec3::ZERO, Vec3::Y * 1e4, Vec3::Z * 1e4],
        // 6: zero area again, last in the CDF.
        [Vec3::X, Vec3::X * 2.0, Vec3::X * 3.0],
    ];
    let cdf = [0.0, 0.25, 0.25, 0.5, 0.75, 1.0, 1.0];
    let scene = EmitterScene::new(&tris, &cdf);
    let view = scene.view();
    view.validate().unwrap();
    let mut selects: Vec<f32> = US.to_vec();
    for c in [0.25f32, 0.5, 0.75] {
        selects.extend([next_float_down(c), c, next_float_up(c)]);
    }
    let mut hits = [0usize; 7];
    for &us in &selects {
        for u in extreme_2d() {
            let es = sample_emitter(&view, us, u)
                .unwrap_or_else(|| panic!("no sample for u_select={us} u={u}"));
            let t = es.triangle as usize;
            hits[t] += 1;
            let ctx = format!("u_select={us} u={u}: {es:?}");
            assert!(
                ![0, 2, 6].contains(&t),
                "a zero-area emitter was sampled: {ctx}"
            );
            assert!(es.pdf.0.is_finite() && es.pdf.0 > 0.0, "{ctx}");
            assert_eq!(es.pdf, emitter_pdf(&view, es.triangle), "{ctx}");
            assert!(unit(es.ng) && unit(es.n) && es.n.dot(es.ng) > 0.99, "{ctx}");
            assert!(es.p_err.is_finite() && es.radiance.is_finite(), "{ctx}");
            // The point is where the warp's barycentrics put it, within the reported error
            // bound, so it lies on the triangle.
            let b = warp::sample_uniform_triangle(u);
            let [p0, p1, p2] = tris[t].map(|v| v.as_dvec3());
            let (b1, b2) = (f64::from(b.x), f64::from(b.y));
            let exact = p0 * (1.0 - b1 - b2) + p1 * b1 + p2 * b2;
            // The bound is relative (γ₇ times the magnitudes) and so, like pbrt's, ignores
            // underflow: products that round into subnormals (the tiny triangle at
            // u = MIN_POSITIVE) may err by up to the smallest normal float.
            let err = (es.p.as_dvec3() - exact).abs();
            let bound = es.p_err.as_dvec3() + f64::from(f32::MIN_POSITIVE);
            assert!(
                err.cmple(bound).all(),
                "{ctx}: error {err} above the bound {}",
                es.p_err
            );
            assert!(b1 >= 0.0 && b2 >= 0.0 && 1.0 - b1 - b2 >= 0.0, "{ctx}");
        }
    }
    for t in [1, 3, 4, 5] {
        assert!(hits[t] > 0, "triangle {t} never sampled: {hits:?}");
    }

    // Only zero-area emitters: no sample, never a NaN.
    let flat = EmitterScene::new(&[tris[0], tris[2]], &[0.0, 0.0]);
    for &us in &selects {
        for u in extreme_2d() {
            assert!(sample_emitter(&flat.view(), us, u).is_none());
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Property tests
// ---------------------------------------------------------------------------------------------

/// Seeded so that CI is reproducible; `PROPTEST_RNG_SEED` overrides the seed to explore.
/// Failures are reported with the shrunk case rather than persisted to the source tree.
fn config(cases: u32) -> Config {
    let mut c = Config::with_cases(cases);
    if std::env::var_os("PROPTEST_RNG_SEED").is_none() {
        c.rng_seed = RngSeed::Fixed(ember_kernel::sampler::DEFAULT_SEED);
    }
    c.failure_persistence = None;
    c
}

/// A direction on the unit sphere from two uniforms, or one of the hard ones (poles, horizon).
fn direction() -> impl Strategy<Value = Vec3> {
    prop_oneof![
        8 => (0.0f32..1.0, 0.0f32..1.0)
            .prop_map(|(a, b)| warp::sample_uniform_sphere(Vec2::new(a, b))),
        1 => prop::sample::select(vec![
            Vec3::Z,
            -Vec3::Z,
            Vec3::X,
            Vec3::new(0.6, 0.8, 0.0),
            Vec3::new(1.0, 0.0, 1e-7).normalize(),
            Vec3::new(0.0, 1.0, -1e-7).normalize(),
        ]),
    ]
}

/// A direction in the upper hemisphere (strictly above the horizon).
fn upper() -> impl Strategy<Value = Vec3> {
    direction()
        .prop_map(|d| d.with_z(d.z.abs()))
        .prop_filter("on the horizon", |d| d.z > 0.0)
}

fn reflectance() -> impl Strategy<Value = Vec3> {
    let c = prop_oneof![1 => Just(0.0f32), 6 => 0.0f32..=2.0];
    (c.clone(), c.clone(), c).prop_map(|(r, g, b)| Vec3::new(r, g, b))
}

/// `Ns` in [0, 1e4]: uniform, log-uniform and the integers that matter.
fn exponent() -> impl Strategy<Value = f32> {
    prop_oneof![
        Just(0.0f32),
        Just(1.0f32),
        0.0f32..=1e4,
        (-3.0f32..=4.0).prop_map(|e| 10f32.powf(e)),
    ]
}

fn bsdf() -> impl Strategy<Value = Bsdf> {
    (0..3u8, reflectance(), reflectance(), exponent()).prop_map(|(kind, kd, ks, ns)| match kind {
        0 => Bsdf::Diffuse(Diffuse::new(kd)),
        1 => Bsdf::Phong(Phong::new(kd, ks, ns)),
        _ => Bsdf::Mixture(Phong::new(kd, ks, ns)),
    })
}

/// Roughness: smooth, effectively smooth, the threshold itself, 1, uniform and log-uniform.
fn alpha() -> impl Strategy<Value = f32> {
    prop_oneof![
        Just(0.0f32),
        Just(1e-4f32),
        Just(9.99e-4f32),
        Just(1e-3f32),
        Just(1.0f32),
        1e-3f32..=1.0,
        (-4.0f32..=0.0).prop_map(|e| 10f32.powf(e)),
    ]
}

/// Relative index: index-matched, nearly so, glass from both sides, and uniform on either
/// side of 1 up to 3.
fn eta() -> impl Strategy<Value = f32> {
    prop_oneof![
        Just(1.0f32),
        Just(1.0001f32),
        Just(0.9999f32),
        Just(1.5f32),
        Just(1.0f32 / 1.5),
        1.0f32..=3.0,
        (1.0f32..=3.0).prop_map(|e| 1.0 / e),
    ]
}

/// A transmission tint in [0, 1]³.
fn tint() -> impl Strategy<Value = Vec3> {
    let c = prop_oneof![1 => Just(0.0f32), 1 => Just(1.0f32), 6 => 0.0f32..=1.0];
    (c.clone(), c.clone(), c).prop_map(|(r, g, b)| Vec3::new(r, g, b))
}

/// A conductor (Ks up to 2 per channel) or a dielectric.
fn microfacet_bsdf() -> impl Strategy<Value = Bsdf> {
    (any::<bool>(), reflectance(), tint(), alpha(), eta()).prop_map(
        |(conductor, ks, tf, alpha, eta)| {
            if conductor {
                Bsdf::Conductor(Conductor::new(ks, alpha))
            } else {
                Bsdf::Dielectric(Dielectric::new(eta, tf, alpha))
            }
        },
    )
}

fn mode() -> impl Strategy<Value = TransportMode> {
    prop_oneof![
        Just(TransportMode::Radiance),
        Just(TransportMode::Importance)
    ]
}

/// A lobe number: uniform, or one of the two extremes.
fn lobe_number() -> impl Strategy<Value = f32> {
    prop_oneof![Just(0.0f32), Just(ONE_MINUS_EPSILON), 0.0f32..1.0]
}

/// Twice the largest relative change of `value` when `wi` moves by 4e-6 rad in one of four
/// directions perpendicular to it (as in bsdf.rs: `pdf()`/`eval()` rebuild the half vector
/// from an f32 wi, rounded by a few ulps, so they differ from the sampler's values by their
/// own variation over a neighbourhood of wi). Twice: four probe directions can miss the
/// steepest one (one case in 1.2e5 random ones was 1.03× the single probe at alpha 1e-3).
fn sensitivity(value: impl Fn(Vec3) -> f32, wi: Vec3) -> f32 {
    const DELTA: f32 = 4e-6;
    let frame = Frame::from_normal(wi);
    let v0 = value(wi);
    let mut worst = 0.0f32;
    for d in [frame.s, -frame.s, frame.t, -frame.t] {
        let v = value((wi + d * DELTA).normalize());
        worst = worst.max((v - v0).abs() / v0.max(v).max(f32::MIN_POSITIVE));
    }
    2.0 * worst
}

/// The f32 conditioning of the Fresnel factor of the pair (a, b) at a dielectric of index
/// `eta` (as in bsdf.rs): next to the critical angle of the microfacet, seen from the denser
/// side, cos²θₜ = 1 − (1 − c²)/η² is a cancellation and 1 − F ∝ cosθₜ: its absolute error is
/// ~2ε(1 + 2c/η²) (the arithmetic, and the error of c = w·m amplified by ∂cos²θₜ/∂c = 2c/η²,
/// 15 at η = 0.355), doubled, over |cos²θₜ|, for the worse of the two sides. Near index matching (η = 1 + δ) the amplitude numerators ηcosθᵢ −
/// cosθₜ and cosθᵢ − ηcosθₜ are O(δ) differences of O(1) numbers, so F ≈ (δ/2)² itself has a
/// relative error ~4ε/|δ| (1e-3 at η = 1.0001, an absolute 1e-12): added for reflection pairs.
fn fresnel_conditioning(eta: f32, a: Vec3, b: Vec3) -> f32 {
    let (ad, bd) = (a.as_dvec3(), b.as_dvec3());
    let eta = f64::from(eta);
    let etap = if (a.z > 0.0) == (b.z > 0.0) {
        1.0
    } else if a.z > 0.0 {
        eta
    } else {
        1.0 / eta
    };
    let m = (ad + bd * etap).normalize();
    let m = if m.z < 0.0 { -m } else { m };
    let term = |w: DVec3| {
        let c = w.dot(m);
        let e = if c > 0.0 { eta } else { 1.0 / eta };
        let cos2_t = 1.0 - (1.0 - c * c) / (e * e);
        // δcos²θₜ ≈ 2ε (arithmetic) + (2c/η²)·δc with δc ≈ 2ε (c is an f32 dot product).
        4.0 * f64::from(f32::EPSILON) * (1.0 + 2.0 * c.abs() / (e * e)) / cos2_t.abs().max(1e-12)
    };
    let reflection = if etap == 1.0 {
        4.0 * f64::from(f32::EPSILON) / (eta - 1.0).abs()
    } else {
        0.0
    };
    (term(ad).max(term(bd)) + reflection) as f32
}

fn relative_error(x: f32, y: f32) -> f32 {
    if x == y {
        0.0
    } else {
        (x - y).abs() / x.abs().max(y.abs())
    }
}

fn exponent_of(b: &Bsdf) -> f32 {
    match b {
        Bsdf::Diffuse(_) => 0.0,
        Bsdf::Phong(p) | Bsdf::Mixture(p) => p.exponent,
        Bsdf::Conductor(_) | Bsdf::Dielectric(_) => 0.0,
    }
}

/// Relative closeness, with the slack a Phong exponent `n` needs: a rounding of cos α by one
/// ulp changes cosⁿα by n ulps.
fn close(a: f32, b: f32, n: f32) -> bool {
    let rel = 1e-5 + 4.0 * n * f32::EPSILON;
    (a - b).abs() <= rel * a.abs().max(b.abs()) || a == b
}

proptest! {
    #![proptest_config(config(512))]

    #[test]
    fn prop_eval_and_pdf_are_finite_and_non_negative(
        b in bsdf(), wo in direction(), wi in direction()
    ) {
        let f = b.eval(wo, wi, MODE);
        let p = b.pdf(wo, wi, MODE).0;
        prop_assert!(f.is_finite() && f.min_element() >= 0.0, "{b:?} {wo} {wi}: f {f}");
        prop_assert!(p.is_finite() && p >= 0.0, "{b:?} {wo} {wi}: pdf {p}");
        if wo.z <= 0.0 || wi.z <= 0.0 {
            prop_assert_eq!(f, Vec3::ZERO);
            prop_assert_eq!(p, 0.0);
        }
    }

    #[test]
    fn prop_sample_agrees_with_pdf_and_eval(
        b in bsdf(), wo in direction(), ux in 0.0f32..1.0, uy in 0.0f32..1.0
    ) {
        let u = Vec2::new(ux, uy);
        if let Some(s) = b.sample(wo, ux, u, MODE) {
            prop_assert!(wo.z > 0.0);
            prop_assert!(unit(s.wi) && s.wi.z > 0.0, "{s:?}");
            prop_assert!(s.pdf.0.is_finite() && s.pdf.0 > 0.0, "{s:?}");
            let pdf = b.pdf(wo, s.wi, MODE).0;
            let f = b.eval(wo, s.wi, MODE);
            let n = exponent_of(&b);
            prop_assert!(close(s.pdf.0, pdf, n), "{b:?} {wo} {u}: {s:?} vs pdf {pdf}");
            for c in 0..3 {
                prop_assert!(close(s.f[c], f[c], n), "{b:?} {wo} {u}: {s:?} vs f {f}");
            }
            let w = s.weight();
            prop_assert!(w.is_finite() && w.min_element() >= 0.0, "{s:?}: weight {w}");
            prop_assert!(b.flags().contains(s.flags));
        }
    }

    #[test]
    fn prop_eval_is_reciprocal(b in bsdf(), wo in direction(), wi in direction()) {
        let (f1, f2) = (b.eval(wo, wi, MODE), b.eval(wi, wo, MODE));
        let n = exponent_of(&b);
        for c in 0..3 {
            prop_assert!(close(f1[c], f2[c], n), "{b:?}: f({wo}, {wi}) = {f1}, reversed {f2}");
        }
        prop_assert_eq!(f1, b.eval(wo, wi, TransportMode::Importance));
    }

    /// Albedo after the clamp: for the Phong family the true value is at most 0.99 whenever
    /// the clamp is active and at most Kd + Ks ≤ 1 otherwise; 4 standard errors (one-sided)
    /// allow for the noise. TinyRender's diffuse BSDF has no clamp: its albedo is exactly Kd
    /// (so `illum 7` with Kd > 1 creates energy, as in TinyRender; the loader accepts it).
    #[test]
    fn prop_albedo_is_at_most_one(b in bsdf(), wo in upper(), seed in any::<u64>()) {
        let (mean, se) = mc_albedo(&b, wo, 4096, seed);
        if let Bsdf::Diffuse(d) = b {
            let kd = d.kd.as_dvec3();
            prop_assert!((mean - kd).abs().max_element() <= 1e-6 * kd.max_element().max(1.0),
                "{b:?} wo={wo}: albedo {mean} vs Kd {kd}");
        } else {
            for c in 0..3 {
                prop_assert!(mean[c] <= 1.0 + 4.0 * se[c] + 1e-6,
                    "{b:?} wo={wo}: albedo {mean} ± {se}");
            }
        }
    }
}

proptest! {
    #![proptest_config(config(512))]

    /// Conductors and dielectrics: eval and pdf finite and non-negative for every pair of
    /// directions and either mode; nothing for a delta BSDF, nothing on the horizon, nothing
    /// below the surface for a conductor.
    #[test]
    fn prop_microfacet_eval_and_pdf_are_finite_and_non_negative(
        b in microfacet_bsdf(), wo in direction(), wi in direction(), mode in mode()
    ) {
        let f = b.eval(wo, wi, mode);
        let p = b.pdf(wo, wi, mode).0;
        prop_assert!(f.is_finite() && f.min_element() >= 0.0, "{b:?} {wo} {wi}: f {f}");
        prop_assert!(p.is_finite() && p >= 0.0, "{b:?} {wo} {wi}: pdf {p}");
        let opaque_below = is_opaque(&b) && (wo.z <= 0.0 || wi.z <= 0.0);
        if b.flags().is_specular() || wo.z == 0.0 || wi.z == 0.0 || opaque_below {
            prop_assert_eq!((f, p), (Vec3::ZERO, 0.0));
        }
    }

    /// Every sample is valid ([`check_sample`]) and, off the delta lobes, agrees with `pdf()` and
    /// `eval()` to their sensitivity plus the Fresnel conditioning plus 1e-5 (not checked for
    /// the ill-conditioned near-index-matched samples `check_sample` reports).
    #[test]
    fn prop_microfacet_sample_agrees_with_pdf_and_eval(
        b in microfacet_bsdf(), wo in direction(), uc in lobe_number(),
        ux in 0.0f32..1.0, uy in 0.0f32..1.0, mode in mode()
    ) {
        let u = Vec2::new(ux, uy);
        if let Some(s) = b.sample(wo, uc, u, mode) {
            let ctx = format!("{b:?} {mode:?} wo={wo} uc={uc} u={u}: {s:?}");
            let outside = check_sample(&b, wo, &s, mode, &ctx);
            let ill_conditioned = s.flags.is_transmission()
                && (s.wi.as_dvec3() * f64::from(s.eta) + wo.as_dvec3()).length() < 1e-2;
            if !s.flags.is_specular() && !outside && !ill_conditioned {
                let fresnel = match b {
                    Bsdf::Dielectric(d) => fresnel_conditioning(d.eta, wo, s.wi),
                    _ => 0.0,
                };
                let tol_p = 1e-5 + fresnel + sensitivity(|w| b.pdf(wo, w, mode).0, s.wi);
                let p = b.pdf(wo, s.wi, mode).0;
                prop_assert!(relative_error(p, s.pdf.0) <= tol_p, "{ctx}: pdf() {p}, tol {tol_p}");
                let f = b.eval(wo, s.wi, mode);
                for c in 0..3 {
                    let tol = 1e-5 + fresnel + sensitivity(|w| b.eval(wo, w, mode)[c], s.wi);
                    prop_assert!(relative_error(f[c], s.f[c]) <= tol, "{ctx}: eval() {f}, tol {tol}");
                }
            }
        }
    }

    /// Conductors are reciprocal (the formula is symmetric in its operands: 1e-6) and ignore
    /// the mode; dielectrics satisfy f_rad(wo, wi)/η_o² = f_rad(wi, wo)/η_i² (η_o, η_i the
    /// indices of the media wo and wi are in; see bsdf.rs) and f_imp(wo, wi) = f_rad(wi, wo),
    /// to the sensitivity of both evaluations plus the Fresnel conditioning.
    #[test]
    fn prop_microfacet_reciprocity(b in microfacet_bsdf(), wo in direction(), wi in direction()) {
        let rad = b.eval(wo, wi, TransportMode::Radiance);
        let rad_rev = b.eval(wi, wo, TransportMode::Radiance);
        let imp = b.eval(wo, wi, TransportMode::Importance);
        match b {
            Bsdf::Conductor(_) => {
                for c in 0..3 {
                    prop_assert!(relative_error(rad[c], rad_rev[c]) <= 1e-6, "{b:?} {wo} {wi}: {rad} {rad_rev}");
                }
                prop_assert_eq!(rad, imp);
            }
            Bsdf::Dielectric(d) => {
                let tol = 2e-5
                    + fresnel_conditioning(d.eta, wo, wi)
                    + sensitivity(|w| b.eval(wo, w, MODE).x, wi)
                        .max(sensitivity(|w| b.eval(wi, w, MODE).x, wo));
                // Near index matching the half vector itself is ill-conditioned.
                let etap = if (wo.z > 0.0) == (wi.z > 0.0) { 1.0 } else if wo.z > 0.0 { d.eta } else { 1.0 / d.eta };
                let h = (wi.as_dvec3() * f64::from(etap) + wo.as_dvec3()).length();
                if tol < 0.5 && h >= 1e-2 {
                    let index = |w: Vec3| if w.z > 0.0 { 1.0 } else { d.eta };
                    let (eta_o, eta_i) = (index(wo), index(wi));
                    for c in 0..3 {
                        let lhs = rad[c] / (eta_o * eta_o);
                        let rhs = rad_rev[c] / (eta_i * eta_i);
                        prop_assert!(relative_error(lhs, rhs) <= tol, "{b:?} {wo} {wi}: {lhs} vs {rhs} (tol {tol})");
                        let adjoint = b.eval(wi, wo, TransportMode::Radiance)[c];
                        prop_assert!(relative_error(imp[c], adjoint) <= tol, "{b:?} {wo} {wi}: adjoint");
                    }
                }
            }
            _ => unreachable!(),
        }
    }

    /// Energy: a conductor reflects at most Ks (per channel), a dielectric with Tf ≤ 1 scatters
    /// at most everything in importance transport, from either side; 4 standard errors,
    /// one-sided, plus 1e-6 for the f32 weights (exactly Ks or 1 for delta lobes).
    #[test]
    fn prop_microfacet_albedo_is_at_most_its_reflectance(
        b in microfacet_bsdf(), wo in direction(), seed in any::<u64>()
    ) {
        prop_assume!(wo.z != 0.0);
        let (mean, se) = mc_albedo(&b, wo, 4096, seed);
        let bound = match b {
            Bsdf::Conductor(c) => c.ks.as_dvec3(),
            _ => DVec3::ONE,
        };
        for c in 0..3 {
            prop_assert!(mean[c] <= bound[c] * (1.0 + 1e-6) + 4.0 * se[c] + 1e-6,
                "{b:?} wo={wo}: albedo {mean} ± {se}, bound {bound}");
        }
    }
}

proptest! {
    #![proptest_config(config(2048))]

    /// `Frame::from_normal` is orthonormal and right-handed, and local/world round trips.
    #[test]
    fn prop_frame_round_trips(
        n in prop_oneof![
            4 => direction(),
            // Near the poles, where Duff et al.'s construction switches branches.
            1 => (-1e-3f32..1e-3, -1e-3f32..1e-3, prop::bool::ANY).prop_map(|(x, y, up)| {
                let z = (1.0 - x * x - y * y).sqrt();
                Vec3::new(x, y, if up { z } else { -z }).normalize()
            }),
        ],
        v in direction(),
        len in 1e-3f32..1e3,
    ) {
        let f = Frame::from_normal(n);
        let tol = 4e-6;
        prop_assert!((f.s.length() - 1.0).abs() < tol && (f.t.length() - 1.0).abs() < tol, "{f:?}");
        prop_assert!(f.s.dot(f.t).abs() < tol && f.s.dot(n).abs() < tol && f.t.dot(n).abs() < tol, "{f:?}");
        prop_assert!((f.s.cross(f.t) - n).length() < tol, "left-handed frame {f:?}");
        prop_assert!((f.to_local(n) - Vec3::Z).length() < tol);
        let v = v * len;
        prop_assert!((f.to_world(f.to_local(v)) - v).length() <= tol * len, "{f:?} {v}");
        prop_assert!((f.to_local(f.to_world(v)) - v).length() <= tol * len, "{f:?} {v}");
    }
}

/// Where the ray `(o, d)`, exactly as given in f32, crosses the plane of the triangle, in f64:
/// (t, barycentrics b0, b1, b2, |cos| between the ray and the normal).
fn exact_crossing(o: Vec3, d: Vec3, p: [Vec3; 3]) -> Option<(f64, [f64; 3], f64)> {
    let [p0, p1, p2] = p.map(|v| v.as_dvec3());
    let (o, d) = (o.as_dvec3(), d.as_dvec3());
    let n = (p1 - p0).cross(p2 - p0);
    let denom = n.dot(d);
    if denom == 0.0 {
        return None;
    }
    let t = n.dot(p0 - o) / denom;
    let x = o + d * t;
    let area2 = n.length_squared();
    let b0 = (p1 - x).cross(p2 - x).dot(n) / area2;
    let b1 = (p2 - x).cross(p0 - x).dot(n) / area2;
    let b2 = (p0 - x).cross(p1 - x).dot(n) / area2;
    Some((t, [b0, b1, b2], (denom / (n.length() * d.length())).abs()))
}

/// A triangle that is not a sliver: its area is at least 5% of that of an equilateral
/// triangle with its longest edge (the watertight test is exact for slivers too, but the
/// target point, rounded to f32, would not reliably stay inside one).
fn shapely(p: &[Vec3; 3]) -> bool {
    let [a, b, c] = p.map(|v| v.as_dvec3());
    let area = 0.5 * (b - a).cross(c - a).length();
    let e = (b - a)
        .length_squared()
        .max((c - b).length_squared())
        .max((a - c).length_squared());
    area >= 0.05 * (3f64.sqrt() / 4.0) * e
}

fn scale_exponent() -> impl Strategy<Value = f32> {
    -4.0f32..=4.0
}

fn vec3_in(lo: f32, hi: f32) -> impl Strategy<Value = Vec3> {
    (lo..hi, lo..hi, lo..hi).prop_map(|(x, y, z)| Vec3::new(x, y, z))
}

proptest! {
    #![proptest_config(config(4096))]

    /// A ray aimed at an interior point of a triangle (barycentrics at least 1e-3, checked in
    /// f64 for the ray as rounded to f32) always hits it, at the right distance, whatever the
    /// triangle's size (1e-4 to 1e4) and its distance from the origin (up to 1e5 sizes).
    #[test]
    fn prop_watertight_test_never_misses_an_interior_point(
        scale in scale_exponent(),
        offset in vec3_in(-1e5, 1e5),
        offset_on in prop::bool::ANY,
        verts in (vec3_in(-1.0, 1.0), vec3_in(-1.0, 1.0), vec3_in(-1.0, 1.0)),
        bary in (0.0f32..1.0, 0.0f32..1.0),
        from in direction(),
        dist in 0.01f32..100.0,
    ) {
        let s = 10f32.powf(scale);
        let off = if offset_on { offset * s } else { Vec3::ZERO };
        let p = [verts.0, verts.1, verts.2].map(|v| v * s + off);
        prop_assume!(shapely(&p));
        let b = warp::sample_uniform_triangle(Vec2::new(bary.0, bary.1)).as_dvec2();
        let [p0, p1, p2] = p.map(|v| v.as_dvec3());
        let target = p0 * (1.0 - b.x - b.y) + p1 * b.x + p2 * b.y;
        let o = (target + from.as_dvec3() * f64::from(dist * s)).as_vec3();
        let d = (target - o.as_dvec3()).as_vec3();
        let Some((t, bb, cos)) = exact_crossing(o, d, p) else {
            return Err(TestCaseError::reject("ray parallel to the plane"));
        };
        // Grazing rays see the triangle as a sliver; the property is about the interior.
        prop_assume!(cos > 0.05 && bb.iter().all(|&x| x >= 1e-3) && t > 0.0);
        let hit = intersect_triangle(o, d, f32::INFINITY, p[0], p[1], p[2]);
        prop_assert!(hit.is_some(), "missed: o={o} d={d} tri={p:?} exact t={t} b={bb:?}");
        let h = hit.unwrap();
        prop_assert!((f64::from(h.t) - t).abs() <= 1e-3 * t, "t {} vs {t}", h.t);
        prop_assert!((f64::from(h.b1) - bb[1]).abs() < 1e-3 && (f64::from(h.b2) - bb[2]).abs() < 1e-3,
            "barycentrics {} {} vs {bb:?}", h.b1, h.b2);
        // And a shadow ray stopping just short of the triangle never sees it.
        prop_assert!(intersect_triangle(o, d, (t * (1.0 - 1e-3)) as f32, p[0], p[1], p[2]).is_none());
    }

    /// Two triangles sharing an edge: a ray through a point of the shared edge hits at least
    /// one of them (no crack), from either side, at any scale and offset.
    #[test]
    fn prop_shared_edges_do_not_leak(
        scale in scale_exponent(),
        offset in vec3_in(-1e5, 1e5),
        offset_on in prop::bool::ANY,
        a in vec3_in(-1.0, 1.0),
        b in vec3_in(-1.0, 1.0),
        side in (0.1f32..1.0, -1.0f32..1.0, 0.1f32..1.0, -1.0f32..1.0),
        along in 0.01f32..0.99,
        from in direction(),
        dist in 0.01f32..100.0,
    ) {
        let s = 10f32.powf(scale);
        let off = if offset_on { offset * s } else { Vec3::ZERO };
        let e = b - a;
        prop_assume!(e.length() > 0.1);
        // c and d on opposite sides of the edge, in one plane.
        let normal = e.normalize().any_orthonormal_vector();
        let across = e.normalize().cross(normal);
        let c = a + e * side.1.abs() + across * side.0;
        let d = a + e * side.3.abs() - across * side.2;
        let [a, b, c, d] = [a, b, c, d].map(|v| v * s + off);
        prop_assume!(shapely(&[a, b, c]) && shapely(&[b, a, d]));
        let q = a.as_dvec3() + (b.as_dvec3() - a.as_dvec3()) * f64::from(along);
        let o = (q + from.as_dvec3() * f64::from(dist * s)).as_vec3();
        let dir = (q - o.as_dvec3()).as_vec3();
        let Some((_, _, cos)) = exact_crossing(o, dir, [a, b, c]) else {
            return Err(TestCaseError::reject("ray parallel to the plane"));
        };
        prop_assume!(cos > 0.05);
        let h1 = intersect_triangle(o, dir, f32::INFINITY, a, b, c);
        let h2 = intersect_triangle(o, dir, f32::INFINITY, b, a, d);
        prop_assert!(h1.is_some() || h2.is_some(), "crack: o={o} d={dir} quad {a} {b} {c} {d}");
    }
}
