//! Chi-square goodness-of-fit tests of `Bsdf::sample` against `Bsdf::pdf`, after Mitsuba 3's
//! `chi2.py` (`ChiSquareTest`):
//!
//! 1. Map directions to the unit square by a [`Domain`] and histogram `RES[0] x RES[1]` cells.
//!    Both resolutions are odd, so the horizon (cosθ = 0, the middle of the spherical domain)
//!    is never a cell edge.
//! 2. Draw `SAMPLES` samples with `IndependentSampler` (`uc = next_1d()`, then `u = next_2d()`); a sample for which
//!    `sample()` returns `None` is drawn but lands in no cell: it goes to an extra "nowhere"
//!    category whose expected count is `N·(1 − ∫pdf)`, so the test also sees lost mass.
//! 3. Expected counts: integrate `pdf()` over every cell (adaptive Gauss–Legendre, see
//!    [`integrate_cell`]) and multiply by the number of samples DRAWN.
//! 4. Pool cells with expected count < 5 into one cell; a sample in a cell whose expected
//!    count is exactly zero (even after integrating that cell again on a 64x64 finer grid),
//!    or at a direction where `pdf()` is 0, fails outright.
//! 5. χ² statistic, p-value from the regularised upper incomplete gamma function
//!    ([`gamma_q`], Numerical Recipes' `gammq`), rejection when p < 1 − (1 − α)^(1/N_TESTS)
//!    (Šidák correction over every (configuration, domain) test in this file).
//!
//! Narrow lobes. A (cosθ, φ) grid has no power for Ns = 1000: the lobe is ~2° wide
//! (σ ≈ 1/√n rad) and at normal incidence it falls entirely into the top row of 51 cosθ cells
//! (the lobe spans cosθ ∈ [0.995, 1], the row [0.961, 1]). Every Phong and Mixture
//! configuration is therefore ALSO tested in a [`Domain::Lobe`] centred on `reflect(wo)`, whose
//! radial coordinate `x = ln(1 + k(1 − cos α)) / ln(1 + 2k)` (k = Ns) spreads the lobe's core
//! (1 − cos α ≲ 3/Ns) over ~10 radial cells × 101 azimuthal cells while still covering the
//! whole sphere. The negative control `chi2_rejects_a_slightly_too_wide_narrow_lobe` shows this
//! domain rejects a 10% exponent error at Ns = 1000 that the spherical domain misses.
//!
//! Microfacet BSDFs (rough `Conductor`, rough `Dielectric`, alpha 0.05, 0.2, 0.6, incident
//! angles up to 85°; the dielectric on the whole sphere, reflection and transmission at once,
//! from outside, from inside (wo.z < 0, eta seen as 1/1.5, including grazing cases dominated
//! by total internal reflection) and with eta = 1/1.5 from outside). Their lobes have angular
//! width σ ≈ 2α in reflection and σ ≈ α|1 − 1/η′| in transmission (a tilt θ_m of the
//! microfacet turns the refracted ray by θ_m(1 − 1/η′) to first order), so for alpha ≤ 0.2 they
//! are also tested in lobe domains centred on `reflect(wo)` and on the Snell direction of wo
//! through the macro normal (where it exists), with k = 4/σ²: the lobe's core out to 3σ
//! (1 − cos α ≲ (3σ)²/2, so k·y ≲ 18) spans x ≲ ln 19/ln(1 + 2k) of the radial range, 15 to 40
//! of the 51 radial cells. Negative controls show power at alpha 0.2 (pdf of alpha
//! 0.22; the pdf of sampling all normals D(m)cosθ_m instead of the visible ones; the
//! visible-normal pdf with Beckmann's Smith G1; the transmission pdf without the refraction
//! Jacobian) and at alpha 0.05 in the lobe domains
//! (pdf of alpha 0.055, which the spherical grid sees at normal incidence only through the
//! mass lost below the horizon). At normal incidence the reflection and transmission lobes of
//! a dielectric are antipodal, so both lobe domains are [`Domain::Bipolar`]; lobe axes are
//! also passed to the quadrature as [`Hint`]s, which it refines to [`HINT_DEPTH`].
//!
//! Time: the 130 configuration × domain tests and the controls run in parallel
//! ([`parallel_map`]), longest first; the whole binary took 1 min 48 s wall (57 s of CPU) on
//! the two shared cores under a load average of ~8, i.e. ~30 s on two idle cores.
//!
//! The slow tests run only in release mode (`cargo test --release`).

use ember_kernel::bsdf::{Bsdf, Conductor, Dielectric, Diffuse, Phong, TransportMode};
use ember_kernel::glam::{DVec3, Vec2, Vec3};
use ember_kernel::sampler::{IndependentSampler, Sampler};
use std::f64::consts::PI;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

/// Samples drawn per configuration.
const SAMPLES: u32 = 1_000_000;
const SEED: u64 = 0xC412_5EED;
/// Histogram resolution: (radial coordinate or cosθ, azimuth φ). Both odd.
const RES: [usize; 2] = [51, 101];
/// Cells whose expected count is below this are pooled into one cell.
const MIN_EXPECTED: f64 = 5.0;
/// Family-wise significance level of all the tests in this file.
const ALPHA: f64 = 0.01;
/// Diffuse/Phong/Mixture: 24 configurations in the spherical domain + 20 in the lobe domain.
/// Rough conductor: 12 spherical + 8 reflection-lobe (alpha ≤ 0.2). Rough dielectric eta 1.5
/// from outside: 12 spherical + 8 reflection + 8 transmission; from inside: 15 spherical +
/// 10 reflection + 4 transmission (no Snell direction past 41.8°); eta 1/1.5 from outside at
/// alpha 0.2: 4 spherical + 4 reflection + 1 transmission. Asserted in the test.
const N_TESTS: usize = 44 + 20 + 28 + 29 + 9;
/// Depth limit of the adaptive quadrature (a cell is split into at most 4^MAX_DEPTH pieces).
const MAX_DEPTH: u32 = 6;
/// Depth limit around a lobe axis ([`Hint`]), where the pdf may peak more narrowly than the
/// 4x4 rule can see: a 1° transmission lobe at the pole of the (cosθ, φ) grid lies within
/// 1.5e-4 of cosθ = −1, while the nodes of a depth-6 piece of the polar row are 4e-5 away at
/// best, and the rule "converged" on the tail (3.5e-4 of the mass missed at normal incidence).
/// Pieces of size 1/1024 of a cell get nodes into the lobe's core.
const HINT_DEPTH: u32 = 10;
const MODE: TransportMode = TransportMode::Radiance;

/// cosθ of the outgoing directions; the last one is grazing.
const COS_THETA_O: [f32; 4] = [1.0, 0.7, 0.3, 0.05];
/// cosθ of the outgoing directions of the microfacet BSDFs, up to 85° (cos 85° = 0.087).
const COS_THETA_O_MICROFACET: [f32; 4] = [1.0, 0.7, 0.3, 0.087];
/// From inside a dielectric (η 1.5, critical angle 41.8°, cos 0.745): normal, 36.9° (below
/// the critical angle), then 45.6°, 72.5° and 85°, where the macro surface reflects totally and
/// only microfacets tilted toward wo transmit.
const COS_THETA_O_INSIDE: [f32; 5] = [-1.0, -0.8, -0.7, -0.3, -0.087];
/// The roughnesses of the microfacet configurations.
const ALPHAS: [f32; 3] = [0.05, 0.2, 0.6];
/// Azimuth of the outgoing directions (non-zero so the lobe frame is not axis aligned).
const PHI_O: f32 = 1.1;

fn sidak_threshold() -> f64 {
    1.0 - (1.0 - ALPHA).powf(1.0 / N_TESTS as f64)
}

fn outgoing(cos_theta: f32) -> Vec3 {
    let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
    Vec3::new(sin_theta * PHI_O.cos(), sin_theta * PHI_O.sin(), cos_theta)
}

// ---------------------------------------------------------------------------------------------
// Regularised incomplete gamma function (Numerical Recipes 3rd ed., §6.1–6.2).
// ---------------------------------------------------------------------------------------------

/// ln Γ(x) for x > 0 (Lanczos approximation, NR3 `gammln`, ~1e-15 relative).
// The coefficients are quoted as published.
#[allow(clippy::excessive_precision)]
fn ln_gamma(x: f64) -> f64 {
    const COF: [f64; 14] = [
        57.156_235_665_862_923_5,
        -59.597_960_355_475_491_2,
        14.136_097_974_741_747_1,
        -0.491_913_816_097_620_199,
        0.339_946_499_848_118_887e-4,
        0.465_236_289_270_485_756e-4,
        -0.983_744_753_048_795_646e-4,
        0.158_088_703_224_912_494e-3,
        -0.210_264_441_724_104_883e-3,
        0.217_439_618_115_212_643e-3,
        -0.164_318_106_536_763_890e-3,
        0.844_182_239_838_527_433e-4,
        -0.261_908_384_015_814_087e-4,
        0.368_991_826_595_316_234e-5,
    ];
    assert!(x > 0.0, "ln_gamma({x})");
    let mut y = x;
    let tmp = x + 5.242_187_5;
    let tmp = (x + 0.5) * tmp.ln() - tmp;
    let mut ser = 0.999_999_999_999_997_092;
    for c in COF {
        y += 1.0;
        ser += c / y;
    }
    tmp + (2.506_628_274_631_000_5 * ser / x).ln()
}

/// P(a, x) by its series; converges quickly for x < a + 1.
fn gamma_p_series(a: f64, x: f64) -> f64 {
    let (mut ap, mut del) = (a, 1.0 / a);
    let mut sum = del;
    for _ in 0..100_000 {
        ap += 1.0;
        del *= x / ap;
        sum += del;
        if del.abs() < sum.abs() * 1e-16 {
            break;
        }
    }
    sum * (-x + a * x.ln() - ln_gamma(a)).exp()
}

/// Q(a, x) by its continued fraction (modified Lentz); converges quickly for x > a + 1.
fn gamma_q_continued_fraction(a: f64, x: f64) -> f64 {
    const FPMIN: f64 = f64::MIN_POSITIVE / f64::EPSILON;
    let mut b = x + 1.0 - a;
    let mut c = 1.0 / FPMIN;
    let mut d = 1.0 / b;
    let mut h = d;
    for i in 1..100_000 {
        let an = -f64::from(i) * (f64::from(i) - a);
        b += 2.0;
        d = an * d + b;
        if d.abs() < FPMIN {
            d = FPMIN;
        }
        c = b + an / c;
        if c.abs() < FPMIN {
            c = FPMIN;
        }
        d = 1.0 / d;
        let del = d * c;
        h *= del;
        if (del - 1.0).abs() < 1e-16 {
            break;
        }
    }
    (-x + a * x.ln() - ln_gamma(a)).exp() * h
}

/// Regularised upper incomplete gamma function Q(a, x) = Γ(a, x)/Γ(a) (NR `gammq`).
fn gamma_q(a: f64, x: f64) -> f64 {
    assert!(a > 0.0 && x >= 0.0, "gamma_q({a}, {x})");
    if x == 0.0 {
        1.0
    } else if x < a + 1.0 {
        1.0 - gamma_p_series(a, x)
    } else {
        gamma_q_continued_fraction(a, x)
    }
}

/// Upper tail of the χ² distribution with `dof` degrees of freedom: P(X ≥ chi2).
fn chi2_p_value(chi2: f64, dof: usize) -> f64 {
    gamma_q(dof as f64 / 2.0, chi2 / 2.0)
}

// ---------------------------------------------------------------------------------------------
// Domains: bijections between the unit square and the sphere of directions.
// ---------------------------------------------------------------------------------------------

#[derive(Clone, Copy, Debug)]
enum Domain {
    /// (cosθ ∈ [−1, 1], φ ∈ [0, 2π)) in the shading frame (Mitsuba's `SphericalDomain`).
    Spherical,
    /// Polar coordinates about the unit vector `n`: radial `x = ln(1 + k·y) / ln(1 + 2k)` with
    /// `y = 1 − cos α`, azimuth φ about `n` in the frame (s, t, n).
    Lobe {
        s: DVec3,
        t: DVec3,
        n: DVec3,
        k: f64,
    },
    /// Polar coordinates about `n` resolving a lobe at `n` AND one at the antipode −n (a
    /// dielectric at normal incidence reflects about +z and refracts about −z): the near
    /// hemisphere (y = 1 − cos α ≤ 1) is `x = ½ ln(1 + k·y)/ln(1 + k)`, the far one
    /// `x = 1 − ½ ln(1 + k_far·ȳ)/ln(1 + k_far)` with ȳ = 1 + cos α. The single-ended lobe
    /// domain squeezes everything near −n into its last radial row, where a lobe of 1° is
    /// out of reach of the adaptive quadrature (it missed 11% of the mass). The Jacobian has a
    /// kink at x = ½ (inside a cell, RES[0] being odd); cells across it are refined fully.
    Bipolar {
        s: DVec3,
        t: DVec3,
        n: DVec3,
        k: f64,
        k_far: f64,
    },
}

impl Domain {
    fn lobe(axis: DVec3, k: f64) -> Self {
        let n = axis.normalize();
        // Duff et al. 2017, in f64 (independent of the kernel's f32 `Frame`).
        let sign = 1f64.copysign(n.z);
        let a = -1.0 / (sign + n.z);
        let b = n.x * n.y * a;
        let s = DVec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
        let t = DVec3::new(b, sign + n.y * n.y * a, -n.y);
        Self::Lobe { s, t, n, k }
    }

    fn bipolar(axis: DVec3, k: f64, k_far: f64) -> Self {
        let Self::Lobe { s, t, n, .. } = Self::lobe(axis, k) else {
            unreachable!()
        };
        Self::Bipolar { s, t, n, k, k_far }
    }

    fn name(&self) -> String {
        // k to 3 significant digits.
        let k3 = |k: f64| {
            let scale = 10f64.powi(2 - k.log10().floor() as i32);
            (k * scale).round() / scale
        };
        match self {
            Self::Spherical => "sphere".into(),
            Self::Lobe { k, .. } => format!("lobe k={}", k3(*k)),
            Self::Bipolar { k, k_far, .. } => format!("lobes k={}/{}", k3(*k), k3(*k_far)),
        }
    }

    /// Whether the radial coordinate's Jacobian has a kink inside the rectangle.
    fn kink_inside(&self, r: [f64; 4]) -> bool {
        matches!(self, Self::Bipolar { .. }) && r[0] < 0.5 && 0.5 < r[1]
    }

    /// The direction at unit-square coordinates (a, b) and the Jacobian dω/(da db).
    fn direction(&self, a: f64, b: f64) -> (DVec3, f64) {
        let phi = 2.0 * PI * b;
        match *self {
            Self::Spherical => {
                let cos_theta = 2.0 * a - 1.0;
                let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
                let w = DVec3::new(sin_theta * phi.cos(), sin_theta * phi.sin(), cos_theta);
                (w, 4.0 * PI)
            }
            Self::Lobe { s, t, n, k } => {
                let l = (2.0 * k).ln_1p();
                let y = ((a * l).exp_m1() / k).min(2.0);
                let sin_alpha = (y * (2.0 - y)).max(0.0).sqrt();
                let w = n * (1.0 - y) + (s * phi.cos() + t * phi.sin()) * sin_alpha;
                // dω = dy dφ, dy/da = L·e^{aL}/k, dφ/db = 2π.
                (w, 2.0 * PI * l * (a * l).exp() / k)
            }
            Self::Bipolar { s, t, n, k, k_far } => {
                // (y, ȳ = 2 − y, dy/da), each computed where it is small.
                let (y, y_bar, dy) = if a <= 0.5 {
                    let l = k.ln_1p();
                    let y = ((2.0 * a * l).exp_m1() / k).min(1.0);
                    (y, 2.0 - y, 2.0 * l * (2.0 * a * l).exp() / k)
                } else {
                    let l = k_far.ln_1p();
                    let y_bar = ((2.0 * (1.0 - a) * l).exp_m1() / k_far).min(1.0);
                    (
                        2.0 - y_bar,
                        y_bar,
                        2.0 * l * (2.0 * (1.0 - a) * l).exp() / k_far,
                    )
                };
                let sin_alpha = (y * y_bar).max(0.0).sqrt();
                let cos_alpha = if y <= 1.0 { 1.0 - y } else { y_bar - 1.0 };
                let w = n * cos_alpha + (s * phi.cos() + t * phi.sin()) * sin_alpha;
                (w, 2.0 * PI * dy)
            }
        }
    }

    /// Unit-square coordinates of the unit vector `w` (inverse of [`Domain::direction`]).
    fn coords(&self, w: DVec3) -> (f64, f64) {
        let turn = |phi: f64| {
            let b = phi / (2.0 * PI);
            if b < 0.0 {
                b + 1.0
            } else {
                b
            }
        };
        match *self {
            Self::Spherical => (0.5 * (w.z + 1.0), turn(w.y.atan2(w.x))),
            Self::Lobe { s, t, n, k } => {
                // 1 − cos α = |w − n|²/2 is accurate near the axis, unlike 1 − w·n.
                let y = 0.5 * (w - n).length_squared();
                let a = (k * y).ln_1p() / (2.0 * k).ln_1p();
                (a, turn(w.dot(t).atan2(w.dot(s))))
            }
            Self::Bipolar { s, t, n, k, k_far } => {
                let a = if w.dot(n) >= 0.0 {
                    let y = 0.5 * (w - n).length_squared();
                    0.5 * (k * y).ln_1p() / k.ln_1p()
                } else {
                    let y_bar = 0.5 * (w + n).length_squared();
                    1.0 - 0.5 * (k_far * y_bar).ln_1p() / k_far.ln_1p()
                };
                (a, turn(w.dot(t).atan2(w.dot(s))))
            }
        }
    }

    fn cell(&self, w: DVec3) -> usize {
        let (a, b) = self.coords(w);
        let i = ((a * RES[0] as f64) as usize).min(RES[0] - 1);
        let j = ((b * RES[1] as f64) as usize).min(RES[1] - 1);
        i * RES[1] + j
    }
}

// ---------------------------------------------------------------------------------------------
// Quadrature of the pdf over the cells.
// ---------------------------------------------------------------------------------------------

/// 4-point Gauss–Legendre nodes and weights on [−1, 1].
const GL_NODES: [f64; 4] = [
    -0.861_136_311_594_052_6,
    -0.339_981_043_584_856_3,
    0.339_981_043_584_856_3,
    0.861_136_311_594_052_6,
];
const GL_WEIGHTS: [f64; 4] = [
    0.347_854_845_137_453_9,
    0.652_145_154_862_546_1,
    0.652_145_154_862_546_1,
    0.347_854_845_137_453_9,
];

/// Tensor-product 4x4 Gauss–Legendre rule over [a0, a1] x [b0, b1] of the pdf in the domain's
/// coordinates. An open rule: it never evaluates the pdf on a cell edge.
fn gauss_legendre(dom: &Domain, pdf: &dyn Fn(DVec3) -> f64, r: [f64; 4]) -> f64 {
    let [a0, a1, b0, b1] = r;
    let (ha, hb) = (0.5 * (a1 - a0), 0.5 * (b1 - b0));
    let mut sum = 0.0;
    for (xa, wa) in GL_NODES.iter().zip(GL_WEIGHTS) {
        for (xb, wb) in GL_NODES.iter().zip(GL_WEIGHTS) {
            let (w, jac) = dom.direction(a0 + ha * (xa + 1.0), b0 + hb * (xb + 1.0));
            sum += wa * wb * pdf(w) * jac;
        }
    }
    sum * ha * hb
}

/// Whether the horizon (where every BSDF pdf here is discontinuous) crosses the rectangle,
/// judged on a 5x5 grid that includes the corners.
fn straddles_horizon(dom: &Domain, r: [f64; 4]) -> bool {
    let [a0, a1, b0, b1] = r;
    let (mut below, mut above) = (false, false);
    for i in 0..=4 {
        for j in 0..=4 {
            let a = a0 + (a1 - a0) * f64::from(i) / 4.0;
            let b = b0 + (b1 - b0) * f64::from(j) / 4.0;
            let z = dom.direction(a, b).0.z;
            below |= z < 0.0;
            above |= z > 0.0;
        }
    }
    below && above
}

/// A direction where the pdf peaks (a lobe axis), in a domain's unit-square coordinates.
#[derive(Clone, Copy, Debug)]
struct Hint {
    a: f64,
    b: f64,
    /// At a pole of the domain's coordinates, where every azimuth meets.
    pole: bool,
}

impl Hint {
    fn new(dom: &Domain, w: DVec3) -> Self {
        let w = w.normalize();
        let (a, b) = dom.coords(w);
        let axis_cos = match *dom {
            Domain::Spherical => w.z,
            Domain::Lobe { n, .. } | Domain::Bipolar { n, .. } => w.dot(n),
        };
        Self {
            a,
            b,
            pole: axis_cos.abs() > 1.0 - 1e-12,
        }
    }

    fn inside(&self, r: [f64; 4]) -> bool {
        r[0] <= self.a && self.a <= r[1] && (self.pole || (r[2] <= self.b && self.b <= r[3]))
    }
}

/// Adaptive quadrature of the pdf over a rectangle whose 4x4 Gauss–Legendre estimate is
/// `whole`: compare with the sum over the four quadrants and recurse into them while the
/// difference exceeds 1% of the Poisson standard deviation of the expected count (`n` samples)
/// or while the horizon (or the kink of a [`Domain::Bipolar`]) crosses the rectangle, down to
/// depth [`MAX_DEPTH`]. Narrow lobes
/// (Ns = 1000 in a 51-row cosθ grid) and the horizon discontinuity are what need refinement.
fn integrate_cell(
    dom: &Domain,
    pdf: &dyn Fn(DVec3) -> f64,
    r: [f64; 4],
    whole: f64,
    depth: u32,
    n: f64,
    hints: &[Hint],
) -> f64 {
    let [a0, a1, b0, b1] = r;
    let (am, bm) = (0.5 * (a0 + a1), 0.5 * (b0 + b1));
    // A rectangle touching a hint at a pole of the coordinates is split radially only: every
    // azimuth meets there, so quadrants would double the hinted pieces at every level, and a
    // lobe about the pole varies mostly with the radial coordinate.
    let pole = hints.iter().any(|h| h.pole && h.inside(r));
    let quads = [
        [a0, am, b0, bm],
        [am, a1, b0, bm],
        [a0, am, bm, b1],
        [am, a1, bm, b1],
    ];
    let halves = [[a0, am, b0, b1], [am, a1, b0, b1]];
    let pieces: &[[f64; 4]] = if pole { &halves } else { &quads };
    let parts: Vec<f64> = pieces
        .iter()
        .map(|q| gauss_legendre(dom, pdf, *q))
        .collect();
    let sum: f64 = parts.iter().sum();
    let tolerance = 0.01 * (sum * n).sqrt().max(1.0);
    let hinted = hints.iter().any(|h| h.inside(r));
    let limit = if hinted { HINT_DEPTH } else { MAX_DEPTH };
    let refine_anyway = straddles_horizon(dom, r) || dom.kink_inside(r) || hinted;
    if depth >= limit || ((sum - whole).abs() * n <= tolerance && !refine_anyway) {
        return sum;
    }
    pieces
        .iter()
        .zip(parts)
        .map(|(q, p)| integrate_cell(dom, pdf, *q, p, depth + 1, n, hints))
        .sum()
}

/// The rectangle of cell (i, j) in unit-square coordinates.
fn cell_rect(i: usize, j: usize) -> [f64; 4] {
    [
        i as f64 / RES[0] as f64,
        (i + 1) as f64 / RES[0] as f64,
        j as f64 / RES[1] as f64,
        (j + 1) as f64 / RES[1] as f64,
    ]
}

/// 4x4 Gauss–Legendre on each of 64x64 sub-rectangles (65 536 pdf evaluations).
fn integrate_finely(dom: &Domain, pdf: &dyn Fn(DVec3) -> f64, r: [f64; 4]) -> f64 {
    const SPLIT: u32 = 64;
    let [a0, a1, b0, b1] = r;
    let (da, db) = ((a1 - a0) / f64::from(SPLIT), (b1 - b0) / f64::from(SPLIT));
    let mut sum = 0.0;
    for i in 0..SPLIT {
        for j in 0..SPLIT {
            let a = a0 + da * f64::from(i);
            let b = b0 + db * f64::from(j);
            sum += gauss_legendre(dom, pdf, [a, a + da, b, b + db]);
        }
    }
    sum
}

/// ∫pdf over every cell.
fn tabulate_pdf(dom: &Domain, pdf: &dyn Fn(DVec3) -> f64, n: f64, axes: &[DVec3]) -> Vec<f64> {
    let hints: Vec<Hint> = axes.iter().map(|&w| Hint::new(dom, w)).collect();
    let mut out = Vec::with_capacity(RES[0] * RES[1]);
    for i in 0..RES[0] {
        for j in 0..RES[1] {
            let r = cell_rect(i, j);
            let whole = gauss_legendre(dom, pdf, r);
            out.push(integrate_cell(dom, pdf, r, whole, 0, n, &hints));
        }
    }
    out
}

// ---------------------------------------------------------------------------------------------
// The test itself.
// ---------------------------------------------------------------------------------------------

#[derive(Clone, Debug)]
struct Outcome {
    chi2: f64,
    dof: usize,
    p_value: f64,
    /// Samples that landed in cells whose expected count is exactly zero, or where the pdf
    /// itself is zero (the larger of the two counts).
    zero_hits: u64,
    /// Samples for which `sample()` returned `None`.
    none: u64,
    /// Expected number of `None` samples, N·(1 − ∫pdf).
    none_expected: f64,
}

impl Outcome {
    fn passes(&self, threshold: f64) -> bool {
        self.zero_hits == 0 && self.p_value >= threshold
    }
}

/// Pearson's χ² of observed against expected counts, with Mitsuba's pooling of small cells.
fn chi_square(observed: &[u64], expected: &[f64]) -> (f64, usize, f64, u64) {
    let mut cells: Vec<(f64, f64)> = Vec::new();
    let (mut pool_obs, mut pool_exp) = (0.0, 0.0);
    let mut zero_hits = 0;
    for (&o, &e) in observed.iter().zip(expected) {
        if e <= 0.0 {
            zero_hits += o;
        } else if e < MIN_EXPECTED {
            pool_obs += o as f64;
            pool_exp += e;
        } else {
            cells.push((o as f64, e));
        }
    }
    if pool_exp > 0.0 {
        if pool_exp >= MIN_EXPECTED || cells.is_empty() {
            cells.push((pool_obs, pool_exp));
        } else {
            // Still too small: merge into the cell with the smallest expected count.
            let smallest = cells
                .iter_mut()
                .min_by(|x, y| x.1.total_cmp(&y.1))
                .expect("non-empty");
            smallest.0 += pool_obs;
            smallest.1 += pool_exp;
        }
    }
    let chi2: f64 = cells.iter().map(|(o, e)| (o - e) * (o - e) / e).sum();
    let dof = cells.len().saturating_sub(1).max(1);
    (chi2, dof, chi2_p_value(chi2, dof), zero_hits)
}

/// Draws `samples` directions with `sample` and tests them against `pdf` in every domain.
/// `axes` are the directions where the pdf peaks (lobe axes, [`Hint`]).
fn run_chi2(
    sample: &dyn Fn(f32, Vec2) -> Option<Vec3>,
    pdf: &dyn Fn(DVec3) -> f64,
    domains: &[Domain],
    axes: &[DVec3],
    samples: u32,
    seed: u64,
) -> Vec<Outcome> {
    let cells = RES[0] * RES[1];
    let mut hist = vec![vec![0u64; cells]; domains.len()];
    let (mut none, mut pdf_zero) = (0u64, 0u64);
    for i in 0..samples {
        let mut sampler = IndependentSampler::new(seed, u64::from(i), 0);
        let uc = sampler.next_1d();
        let Some(wi) = sample(uc, sampler.next_2d()) else {
            none += 1;
            continue;
        };
        assert!(
            wi.is_finite() && (wi.length() - 1.0).abs() < 1e-3,
            "sample {i}: wi = {wi}"
        );
        let w = wi.as_dvec3().normalize();
        let p = pdf(w);
        if p.is_nan() || p <= 0.0 {
            pdf_zero += 1;
        }
        for (h, d) in hist.iter_mut().zip(domains) {
            h[d.cell(w)] += 1;
        }
    }
    let n = f64::from(samples);
    domains
        .iter()
        .zip(hist)
        .map(|(dom, mut observed)| {
            let mut expected: Vec<f64> = tabulate_pdf(dom, pdf, n, axes)
                .into_iter()
                .map(|p| p * n)
                .collect();
            // A cell whose quadrature nodes all missed a thin sliver of support (e.g. where
            // the lobe's cos α = 0 circle clips a corner) gets 0 although samples may land
            // there legitimately: integrate such cells again on a much finer grid before
            // declaring their expected count zero.
            for (c, e) in expected.iter_mut().enumerate() {
                if *e == 0.0 && observed[c] > 0 {
                    *e = integrate_finely(dom, pdf, cell_rect(c / RES[1], c % RES[1])) * n;
                }
            }
            // The "nowhere" category. Quadrature may overshoot 1 by a hair: keep the cell
            // strictly positive so that lost samples are pooled rather than failing outright.
            let none_expected = (n - expected.iter().sum::<f64>()).max(1e-9);
            expected.push(none_expected);
            observed.push(none);
            let (chi2, dof, p_value, zero_cells) = chi_square(&observed, &expected);
            Outcome {
                chi2,
                dof,
                p_value,
                zero_hits: zero_cells.max(pdf_zero),
                none,
                none_expected,
            }
        })
        .collect()
}

/// What the lobe-centred domains of a configuration are centred on.
#[derive(Clone, Copy, Debug)]
enum Lobes {
    None,
    /// A Phong lobe of exponent Ns about `reflect(wo)`.
    Phong(f32),
    /// A microfacet BSDF of roughness alpha: its reflection lobe about `reflect(wo)` and, for a
    /// dielectric of index `eta`, its transmission lobe about the Snell direction.
    Microfacet {
        alpha: f32,
        eta: Option<f32>,
    },
}

struct Config {
    name: String,
    bsdf: Bsdf,
    lobes: Lobes,
    cos_theta_o: &'static [f32],
}

fn configurations() -> Vec<Config> {
    let mut v = vec![Config {
        name: "Diffuse Kd=0.5".into(),
        bsdf: Bsdf::Diffuse(Diffuse::new(Vec3::splat(0.5))),
        lobes: Lobes::None,
        cos_theta_o: &COS_THETA_O,
    }];
    for ns in [1.0, 30.0, 1000.0] {
        v.push(Config {
            name: format!("Phong Kd=0 Ks=1 Ns={ns}"),
            bsdf: Bsdf::Phong(Phong::new(Vec3::ZERO, Vec3::ONE, ns)),
            lobes: Lobes::Phong(ns),
            cos_theta_o: &COS_THETA_O,
        });
    }
    v.push(Config {
        name: "Mixture Kd=(.725,.71,.68) Ks=.5 Ns=30".into(),
        bsdf: Bsdf::Mixture(Phong::new(
            Vec3::new(0.725, 0.71, 0.68),
            Vec3::splat(0.5),
            30.0,
        )),
        lobes: Lobes::Phong(30.0),
        cos_theta_o: &COS_THETA_O,
    });
    v.push(Config {
        name: "Mixture Kd=.3 Ks=.6 Ns=1000".into(),
        bsdf: Bsdf::Mixture(Phong::new(Vec3::splat(0.3), Vec3::splat(0.6), 1000.0)),
        lobes: Lobes::Phong(1000.0),
        cos_theta_o: &COS_THETA_O,
    });
    for alpha in ALPHAS {
        v.push(Config {
            name: format!("Conductor alpha={alpha}"),
            bsdf: Bsdf::Conductor(Conductor::new(Vec3::new(0.95, 0.64, 0.54), alpha)),
            lobes: Lobes::Microfacet { alpha, eta: None },
            cos_theta_o: &COS_THETA_O_MICROFACET,
        });
    }
    for alpha in ALPHAS {
        for (side, cosines) in [
            ("outside", &COS_THETA_O_MICROFACET[..]),
            ("inside", &COS_THETA_O_INSIDE[..]),
        ] {
            v.push(Config {
                name: format!("Dielectric eta=1.5 alpha={alpha} {side}"),
                bsdf: Bsdf::Dielectric(Dielectric::new(1.5, Vec3::ONE, alpha)),
                lobes: Lobes::Microfacet {
                    alpha,
                    eta: Some(1.5),
                },
                cos_theta_o: cosines,
            });
        }
    }
    v.push(Config {
        name: "Dielectric eta=1/1.5 alpha=0.2".into(),
        bsdf: Bsdf::Dielectric(Dielectric::new(1.0 / 1.5, Vec3::ONE, 0.2)),
        lobes: Lobes::Microfacet {
            alpha: 0.2,
            eta: Some(1.0 / 1.5),
        },
        cos_theta_o: &COS_THETA_O_MICROFACET,
    });
    v
}

/// The Snell direction of `wo` through the macro normal of a boundary of index `eta` (η′ =
/// eta from outside, 1/eta from inside), in f64; `None` under total internal reflection.
fn snell_direction(wo: Vec3, eta: f32) -> Option<DVec3> {
    let w = wo.as_dvec3().normalize();
    let etap = if w.z > 0.0 {
        f64::from(eta)
    } else {
        1.0 / f64::from(eta)
    };
    let cos2_t = 1.0 - (1.0 - w.z * w.z) / (etap * etap);
    (cos2_t > 0.0).then(|| DVec3::new(-w.x / etap, -w.y / etap, -w.z.signum() * cos2_t.sqrt()))
}

/// The directions where the configuration's pdf peaks: `reflect(wo)` for a glossy lobe and
/// the Snell direction of a dielectric (where it exists).
fn lobe_axes(wo: Vec3, lobes: Lobes) -> Vec<DVec3> {
    let r = DVec3::new(-f64::from(wo.x), -f64::from(wo.y), f64::from(wo.z));
    match lobes {
        Lobes::None => vec![],
        Lobes::Phong(_) | Lobes::Microfacet { eta: None, .. } => vec![r],
        Lobes::Microfacet { eta: Some(eta), .. } => {
            let mut v = vec![r];
            v.extend(snell_direction(wo, eta));
            v
        }
    }
}

fn domains_for(wo: Vec3, lobes: Lobes) -> Vec<Domain> {
    let mut d = vec![Domain::Spherical];
    let r = DVec3::new(-f64::from(wo.x), -f64::from(wo.y), f64::from(wo.z));
    match lobes {
        Lobes::None => {}
        Lobes::Phong(ns) => d.push(Domain::lobe(r, f64::from(ns).max(1.0))),
        Lobes::Microfacet { alpha, eta } => {
            if alpha > 0.2 {
                // Wide lobes: the spherical grid resolves them.
                return d;
            }
            let alpha = f64::from(alpha);
            // k = 4/σ² with σ = 2α for reflection.
            let k_r = 1.0 / (alpha * alpha);
            let transmission = eta.and_then(|eta| {
                let t = snell_direction(wo, eta)?;
                let etap = if wo.z > 0.0 {
                    f64::from(eta)
                } else {
                    1.0 / f64::from(eta)
                };
                let sigma = alpha * (1.0 - 1.0 / etap).abs();
                Some((t, 4.0 / (sigma * sigma)))
            });
            match transmission {
                // Antipodal lobes (normal incidence): each domain resolves both ends.
                Some((t, k_t)) if t.dot(r.normalize()) < -1.0 + 1e-9 => {
                    d.push(Domain::bipolar(r, k_r, k_t));
                    d.push(Domain::bipolar(t, k_t, k_r));
                }
                Some((t, k_t)) => {
                    d.push(Domain::lobe(r, k_r));
                    d.push(Domain::lobe(t, k_t));
                }
                None => d.push(Domain::lobe(r, k_r)),
            }
        }
    }
    d
}

struct Row {
    config: String,
    cos_theta_o: f32,
    domain: String,
    outcome: Outcome,
}

fn print_table(title: &str, rows: &[Row], threshold: f64) {
    println!(
        "\n{title} (N = {SAMPLES}, {}x{} cells, reject if p < {threshold:.3e})",
        RES[0], RES[1]
    );
    println!(
        "{:<40} {:>6} {:<12} {:>10} {:>5} {:>10} {:>8} {:>10}  verdict",
        "configuration", "cosθo", "domain", "chi2", "dof", "p-value", "None", "E[None]"
    );
    for r in rows {
        let o = &r.outcome;
        println!(
            "{:<40} {:>6.2} {:<12} {:>10.1} {:>5} {:>10.3e} {:>8} {:>10.1}  {}",
            r.config,
            r.cos_theta_o,
            r.domain,
            o.chi2,
            o.dof,
            o.p_value,
            o.none,
            o.none_expected,
            if o.zero_hits > 0 {
                format!("FAIL ({} samples where pdf = 0)", o.zero_hits)
            } else if o.p_value < threshold {
                "FAIL".into()
            } else {
                "ok".into()
            }
        );
    }
}

/// The smallest p-value of every configuration over its angles and domains.
fn print_minimum_p_values(rows: &[Row]) {
    println!("\nminimum p-value per configuration (over incident angles and domains)");
    let mut names: Vec<&str> = Vec::new();
    for r in rows {
        if !names.contains(&r.config.as_str()) {
            names.push(&r.config);
        }
    }
    for name in names {
        let (min, at) = rows
            .iter()
            .filter(|r| r.config == name)
            .map(|r| (r.outcome.p_value, r))
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .expect("rows");
        let tests = rows.iter().filter(|r| r.config == name).count();
        println!(
            "{name:<40} {tests:>3} tests  min p {min:.3e} (cosθo {}, {})",
            at.cos_theta_o, at.domain
        );
    }
}

/// Runs `jobs` on all cores; results come back in job order.
fn parallel_map<T: Sync, R: Send>(jobs: &[T], f: impl Fn(usize, &T) -> R + Sync) -> Vec<R> {
    let next = AtomicUsize::new(0);
    let results: Mutex<Vec<Option<R>>> = Mutex::new((0..jobs.len()).map(|_| None).collect());
    let threads = std::thread::available_parallelism().map_or(2, |n| n.get());
    std::thread::scope(|s| {
        for _ in 0..threads.min(jobs.len()) {
            s.spawn(|| loop {
                let i = next.fetch_add(1, Ordering::Relaxed);
                if i >= jobs.len() {
                    break;
                }
                let r = f(i, &jobs[i]);
                results.lock().unwrap()[i] = Some(r);
            });
        }
    });
    results
        .into_inner()
        .unwrap()
        .into_iter()
        .map(|r| r.expect("job ran"))
        .collect()
}

#[test]
#[cfg_attr(debug_assertions, ignore = "slow statistical test: run with --release")]
fn chi2_bsdf_sample_matches_pdf() {
    let configs = configurations();
    let mut jobs: Vec<(usize, f32)> = (0..configs.len())
        .flat_map(|c| configs[c].cos_theta_o.iter().map(move |&ct| (c, ct)))
        .collect();
    // Longest jobs first (the dielectrics, then the conductors) so that the two cores finish
    // together; results are reported in configuration order.
    let cost = |c: usize| match configs[c].bsdf {
        Bsdf::Dielectric(_) => 0,
        Bsdf::Conductor(_) => 1,
        _ => 2,
    };
    jobs.sort_by_key(|&(c, _)| cost(c));
    let mut results = parallel_map(&jobs, |job, &(c, cos_theta_o)| {
        let cfg = &configs[c];
        let wo = outgoing(cos_theta_o);
        let bsdf = cfg.bsdf;
        let domains = domains_for(wo, cfg.lobes);
        let outcomes = run_chi2(
            &|uc, u| bsdf.sample(wo, uc, u, MODE).map(|s| s.wi),
            &|w| f64::from(bsdf.pdf(wo, w.as_vec3(), MODE).0),
            &domains,
            &lobe_axes(wo, cfg.lobes),
            SAMPLES,
            SEED + job as u64,
        );
        domains
            .iter()
            .zip(outcomes)
            .map(|(d, outcome)| Row {
                config: cfg.name.clone(),
                cos_theta_o,
                domain: d.name(),
                outcome,
            })
            .collect::<Vec<_>>()
    });
    let mut order: Vec<usize> = (0..jobs.len()).collect();
    order.sort_by_key(|&i| {
        let (c, ct) = jobs[i];
        let k = configs[c].cos_theta_o.iter().position(|&x| x == ct);
        (c, k)
    });
    let rows: Vec<Row> = order
        .into_iter()
        .flat_map(|i| std::mem::take(&mut results[i]))
        .collect();
    print_minimum_p_values(&rows);
    assert_eq!(rows.len(), N_TESTS, "update N_TESTS (Šidák correction)");
    let threshold = sidak_threshold();
    print_table("chi-square: Bsdf::sample vs Bsdf::pdf", &rows, threshold);
    let failures: Vec<String> = rows
        .iter()
        .filter(|r| !r.outcome.passes(threshold))
        .map(|r| {
            format!(
                "{} cosθo={} {}: {:?}",
                r.config, r.cos_theta_o, r.domain, r.outcome
            )
        })
        .collect();
    assert!(
        failures.is_empty(),
        "chi-square failures:\n{}",
        failures.join("\n")
    );
}

/// Runs one negative control: samples from `bsdf`, tests against `wrong_pdf`, returns the
/// outcome in each domain.
fn negative_control(
    bsdf: Bsdf,
    cos_theta_o: f32,
    lobes: Lobes,
    wrong_pdf: &(dyn Fn(Vec3, Vec3) -> f32 + Sync),
    title: &str,
) -> Vec<Outcome> {
    let wo = outgoing(cos_theta_o);
    let domains = domains_for(wo, lobes);
    let outcomes = run_chi2(
        &|uc, u| bsdf.sample(wo, uc, u, MODE).map(|s| s.wi),
        &|w| f64::from(wrong_pdf(wo, w.as_vec3())),
        &domains,
        &lobe_axes(wo, lobes),
        SAMPLES,
        SEED ^ 0xBAD,
    );
    let rows: Vec<Row> = domains
        .iter()
        .zip(&outcomes)
        .map(|(d, o)| Row {
            config: title.into(),
            cos_theta_o,
            domain: d.name(),
            outcome: o.clone(),
        })
        .collect();
    print_table("negative control (must FAIL)", &rows, sidak_threshold());
    outcomes
}

/// Sampling Ns = 30 but claiming the pdf of Ns = 35 must be rejected, in both domains.
#[test]
#[cfg_attr(debug_assertions, ignore = "slow statistical test: run with --release")]
fn chi2_rejects_wrong_phong_exponent() {
    let bsdf = Bsdf::Phong(Phong::new(Vec3::ZERO, Vec3::ONE, 30.0));
    let wrong = Bsdf::Phong(Phong::new(Vec3::ZERO, Vec3::ONE, 35.0));
    let out = negative_control(
        bsdf,
        0.7,
        Lobes::Phong(30.0),
        &|wo, wi| wrong.pdf(wo, wi, MODE).0,
        "Phong Ns=30 vs pdf Ns=35",
    );
    for o in out {
        assert!(!o.passes(sidak_threshold()), "not rejected: {o:?}");
    }
}

/// The narrow-lobe domain must see a 10% error in a 1000 exponent. (Ns = 1005 instead is not
/// detectable with 10⁶ samples: the lobe width changes by 0.25%.) At normal incidence the
/// spherical (cosθ, φ) grid puts the whole lobe in its top row and cannot tell.
#[test]
#[cfg_attr(debug_assertions, ignore = "slow statistical test: run with --release")]
fn chi2_rejects_a_slightly_too_wide_narrow_lobe() {
    let bsdf = Bsdf::Phong(Phong::new(Vec3::ZERO, Vec3::ONE, 1000.0));
    let wrong = Bsdf::Phong(Phong::new(Vec3::ZERO, Vec3::ONE, 1100.0));
    let out = negative_control(
        bsdf,
        1.0,
        Lobes::Phong(1000.0),
        &|wo, wi| wrong.pdf(wo, wi, MODE).0,
        "Phong Ns=1000 vs pdf Ns=1100",
    );
    // out[0], the spherical domain, is printed for comparison only: at the time of writing it
    // accepts (p ≈ 0.38, 100 dof: the whole lobe sits in the top cosθ row).
    assert!(
        !out[1].passes(sidak_threshold()),
        "lobe domain did not reject: {:?}",
        out[1]
    );
}

/// A mixture whose pdf uses the wrong lobe-selection probability must be rejected.
#[test]
#[cfg_attr(debug_assertions, ignore = "slow statistical test: run with --release")]
fn chi2_rejects_wrong_mixture_weight() {
    let phong = Phong::new(Vec3::new(0.725, 0.71, 0.68), Vec3::splat(0.5), 30.0);
    let mut wrong = phong;
    wrong.specular_weight += 0.05;
    let out = negative_control(
        Bsdf::Mixture(phong),
        0.7,
        Lobes::Phong(30.0),
        &|wo, wi| wrong.pdf(wo, wi, MODE).0,
        "Mixture w_s vs pdf w_s+0.05",
    );
    for o in out {
        assert!(!o.passes(sidak_threshold()), "not rejected: {o:?}");
    }
}

// ---------------------------------------------------------------------------------------------
// Negative controls for the microfacet BSDFs, with pdfs written here in f64.
// ---------------------------------------------------------------------------------------------

/// Trowbridge–Reitz D(m) = 1/(π α² cos⁴θ (1 + tan²θ/α²)²), in f64.
fn ggx_d(alpha: f64, m: DVec3) -> f64 {
    if m.z <= 0.0 {
        return 0.0;
    }
    let cos2 = m.z * m.z;
    let tan2 = (1.0 - cos2).max(0.0) / cos2;
    let k = 1.0 + tan2 / (alpha * alpha);
    1.0 / (PI * alpha * alpha * cos2 * cos2 * k * k)
}

/// Smith G1 of Trowbridge–Reitz, 2/(1 + √(1 + α² tan²θ)), in f64.
fn ggx_g1(alpha: f64, w: DVec3) -> f64 {
    let cos2 = w.z * w.z;
    let tan2 = (1.0 - cos2).max(0.0) / cos2;
    2.0 / (1.0 + (1.0 + alpha * alpha * tan2).sqrt())
}

/// Exact unpolarised Fresnel reflectance (Walter et al. 2007, eq. 22), in f64; `cos_i < 0`
/// is seen from inside (index ratio 1/eta).
fn fresnel(cos_i: f64, eta: f64) -> f64 {
    let (c, e) = if cos_i < 0.0 {
        (-cos_i, 1.0 / eta)
    } else {
        (cos_i, eta)
    };
    let g2 = e * e - 1.0 + c * c;
    if g2 <= 0.0 {
        return 1.0;
    }
    let g = g2.sqrt();
    let a = (g - c) / (g + c);
    let b = (c * (g + c) - 1.0) / (c * (g - c) + 1.0);
    0.5 * a * a * (1.0 + b * b)
}

/// Which microfacet pdf an f64 reference computes.
#[derive(Clone, Copy, PartialEq)]
enum MicrofacetPdf {
    /// The visible-normal pdf the kernel samples, G1(wo)|wo·m|D(m)/|cosθₒ|, with the exact
    /// Jacobians.
    Visible,
    /// The pdf of sampling all normals, D(m)cosθ_m: a sampler/pdf mix-up.
    AllNormals,
    /// The visible-normal pdf with the wrong Smith G1: Beckmann's Λ (Walter et al. 2007's
    /// rational approximation) instead of Trowbridge–Reitz's.
    BeckmannG1,
    /// Transmission with the reflection Jacobian 1/(4|wo·m|) instead of the refraction one
    /// |wi·m|/(wi·m + wo·m/η′)².
    NoRefractionJacobian,
}

/// The pdf of a rough conductor (eta = None) or dielectric of roughness alpha, in f64.
fn microfacet_pdf(alpha: f64, eta: Option<f64>, wo: DVec3, wi: DVec3, kind: MicrofacetPdf) -> f64 {
    let reflect = wo.z * wi.z > 0.0;
    if eta.is_none() && (wo.z <= 0.0 || wi.z <= 0.0) {
        return 0.0;
    }
    let etap = match eta {
        _ if reflect => 1.0,
        Some(e) if wo.z > 0.0 => e,
        Some(e) => 1.0 / e,
        None => return 0.0,
    };
    let m = (wo + wi * etap).normalize();
    let m = if m.z < 0.0 { -m } else { m };
    if m.dot(wo) * wo.z <= 0.0 || m.dot(wi) * wi.z <= 0.0 {
        return 0.0;
    }
    let pdf_m = match kind {
        MicrofacetPdf::AllNormals => ggx_d(alpha, m) * m.z,
        MicrofacetPdf::BeckmannG1 => {
            let cos2 = wo.z * wo.z;
            let a = 1.0 / (alpha * ((1.0 - cos2).max(0.0) / cos2).sqrt());
            let lambda = if a >= 1.6 {
                0.0
            } else {
                (1.0 - 1.259 * a + 0.396 * a * a) / (3.535 * a + 2.181 * a * a)
            };
            wo.dot(m).abs() * ggx_d(alpha, m) / (wo.z.abs() * (1.0 + lambda))
        }
        _ => ggx_g1(alpha, wo) * wo.dot(m).abs() * ggx_d(alpha, m) / wo.z.abs(),
    };
    let Some(eta) = eta else {
        return pdf_m / (4.0 * wo.dot(m).abs());
    };
    let f = fresnel(wo.dot(m), eta);
    if reflect || kind == MicrofacetPdf::NoRefractionJacobian {
        let p = if reflect { f } else { 1.0 - f };
        return pdf_m / (4.0 * wo.dot(m).abs()) * p;
    }
    let denom = wi.dot(m) + wo.dot(m) / etap;
    pdf_m * wi.dot(m).abs() / (denom * denom) * (1.0 - f)
}

/// The f64 reference pdfs above agree with the kernel's `pdf()` (so that each negative
/// control differs from the truth only by its deliberate mistake). Relative 1e-3: the kernel
/// is f32, and its D is as sharp as 2/α per radian of the half vector.
#[test]
fn reference_microfacet_pdfs_match_the_kernel() {
    let mut compared = 0;
    for alpha in [0.05f32, 0.2, 0.6] {
        for (eta, bsdf) in [
            (None, Bsdf::Conductor(Conductor::new(Vec3::ONE, alpha))),
            (
                Some(1.5),
                Bsdf::Dielectric(Dielectric::new(1.5, Vec3::ONE, alpha)),
            ),
        ] {
            for i in 0..20_000u64 {
                let mut s = IndependentSampler::new(SEED, i, 7);
                let (a, b) = (s.next_2d(), s.next_2d());
                let uniform = |u: Vec2| {
                    let z = 1.0 - 2.0 * u.x;
                    let r = (1.0 - z * z).max(0.0).sqrt();
                    let phi = 2.0 * std::f32::consts::PI * u.y;
                    Vec3::new(r * phi.cos(), r * phi.sin(), z)
                };
                let (wo, wi) = (uniform(a), uniform(b));
                let want = microfacet_pdf(
                    f64::from(alpha),
                    eta,
                    wo.as_dvec3(),
                    wi.as_dvec3(),
                    MicrofacetPdf::Visible,
                );
                let got = f64::from(bsdf.pdf(wo, wi, MODE).0);
                if want < 1e-6 && got < 1e-6 {
                    continue;
                }
                compared += 1;
                // Next to a microfacet's critical angle the kernel's f32 cos²θₜ is a
                // cancellation (absolute error ~2ε) and 1 − F ∝ cosθₜ: 4ε/|cos²θₜ| more.
                let conditioning = eta.map_or(0.0, |e| {
                    let (o, i) = (wo.as_dvec3(), wi.as_dvec3());
                    let etap = if o.z * i.z > 0.0 {
                        1.0
                    } else if o.z > 0.0 {
                        e
                    } else {
                        1.0 / e
                    };
                    let m = (o + i * etap).normalize();
                    let c = o.dot(m).abs();
                    let e = if o.dot(m) * m.z.signum() > 0.0 {
                        e
                    } else {
                        1.0 / e
                    };
                    let cos2_t = 1.0 - (1.0 - c * c) / (e * e);
                    4.0 * f64::from(f32::EPSILON) / cos2_t.abs().max(1e-12)
                });
                assert!(
                    (got - want).abs() <= (1e-3 + conditioning) * want.max(got),
                    "alpha {alpha} eta {eta:?} wo={wo} wi={wi}: kernel {got} vs f64 {want}"
                );
            }
        }
    }
    assert!(compared > 50_000, "{compared}");
}

/// Runs the negative controls `(title, bsdf, cosθo, lobes, wrong pdf)` in parallel.
type WrongPdf = Box<dyn Fn(Vec3, Vec3) -> f32 + Sync>;

fn negative_controls(cases: &[(&str, Bsdf, f32, Lobes, WrongPdf)]) -> Vec<Vec<Outcome>> {
    parallel_map(cases, |_, (title, bsdf, ct, lobes, wrong)| {
        negative_control(*bsdf, *ct, *lobes, wrong.as_ref(), title)
    })
}

/// Sampling alpha = 0.2 but claiming the pdf of alpha = 0.22 (10% off), or the pdf of
/// sampling all normals instead of the visible ones, or the visible-normal pdf with the wrong
/// Smith G1 (Beckmann's: 8% too large a normalisation at cosθo = 0.3, the shape unchanged), or
/// (dielectric) the transmission pdf without the refraction Jacobian, must be rejected in
/// every domain.
#[test]
#[cfg_attr(debug_assertions, ignore = "slow statistical test: run with --release")]
fn chi2_rejects_wrong_microfacet_pdfs() {
    let conductor = Bsdf::Conductor(Conductor::new(Vec3::ONE, 0.2));
    let dielectric = Bsdf::Dielectric(Dielectric::new(1.5, Vec3::ONE, 0.2));
    let wrong_conductor = Conductor::new(Vec3::ONE, 0.22);
    let wrong_dielectric = Dielectric::new(1.5, Vec3::ONE, 0.22);
    let lobes_c = Lobes::Microfacet {
        alpha: 0.2,
        eta: None,
    };
    let lobes_d = Lobes::Microfacet {
        alpha: 0.2,
        eta: Some(1.5),
    };
    let reference = |eta: Option<f64>, kind| -> WrongPdf {
        Box::new(move |wo: Vec3, wi: Vec3| {
            microfacet_pdf(0.2, eta, wo.as_dvec3(), wi.as_dvec3(), kind) as f32
        })
    };
    let cases: Vec<(&str, Bsdf, f32, Lobes, WrongPdf)> = vec![
        (
            "Conductor a=0.2 vs pdf a=0.22",
            conductor,
            0.7,
            lobes_c,
            Box::new(move |wo, wi| wrong_conductor.pdf(wo, wi, MODE).0),
        ),
        (
            "Conductor a=0.2 vs all-normals pdf",
            conductor,
            0.3,
            lobes_c,
            reference(None, MicrofacetPdf::AllNormals),
        ),
        (
            "Conductor a=0.2 vs Beckmann's G1",
            conductor,
            0.3,
            lobes_c,
            reference(None, MicrofacetPdf::BeckmannG1),
        ),
        (
            "Dielectric a=0.2 vs pdf a=0.22",
            dielectric,
            0.7,
            lobes_d,
            Box::new(move |wo, wi| wrong_dielectric.pdf(wo, wi, MODE).0),
        ),
        (
            "Dielectric a=0.2 inside vs pdf a=0.22",
            dielectric,
            -0.8,
            lobes_d,
            Box::new(move |wo, wi| wrong_dielectric.pdf(wo, wi, MODE).0),
        ),
        (
            "Dielectric a=0.2 vs no refraction Jacobian",
            dielectric,
            0.7,
            lobes_d,
            reference(Some(1.5), MicrofacetPdf::NoRefractionJacobian),
        ),
    ];
    for ((title, ..), out) in cases.iter().zip(negative_controls(&cases)) {
        for o in out {
            assert!(!o.passes(sidak_threshold()), "{title}: not rejected: {o:?}");
        }
    }
}

/// The lobe domains must resolve alpha = 0.05: a 10% error in alpha at normal incidence is
/// rejected by the reflection-lobe domain (conductor) and by both bipolar lobe domains
/// (dielectric) with χ² ≈ 3.5–4× the degrees of freedom. The spherical (cosθ, φ) grid has no
/// resolution there (the reflection lobe, 1 − cosθ ≲ 0.01, lies in its top row and the
/// transmission lobe in its bottom row); it notices only through the lost mass (the "None"
/// category: the part of the GGX tail reflected below the horizon grows with α²), clearly for
/// the conductor and barely for the dielectric (p ≈ 5e-5 against a threshold of 7.7e-5 at the
/// time of writing). It is printed for comparison only.
#[test]
#[cfg_attr(debug_assertions, ignore = "slow statistical test: run with --release")]
fn chi2_lobe_domains_resolve_alpha_0_05() {
    let wrong_conductor = Conductor::new(Vec3::ONE, 0.055);
    let wrong_dielectric = Dielectric::new(1.5, Vec3::ONE, 0.055);
    let cases: Vec<(&str, Bsdf, f32, Lobes, WrongPdf)> = vec![
        (
            "Conductor a=0.05 vs pdf a=0.055",
            Bsdf::Conductor(Conductor::new(Vec3::ONE, 0.05)),
            1.0,
            Lobes::Microfacet {
                alpha: 0.05,
                eta: None,
            },
            Box::new(move |wo, wi| wrong_conductor.pdf(wo, wi, MODE).0),
        ),
        (
            "Dielectric a=0.05 vs pdf a=0.055",
            Bsdf::Dielectric(Dielectric::new(1.5, Vec3::ONE, 0.05)),
            1.0,
            Lobes::Microfacet {
                alpha: 0.05,
                eta: Some(1.5),
            },
            Box::new(move |wo, wi| wrong_dielectric.pdf(wo, wi, MODE).0),
        ),
    ];
    let out = negative_controls(&cases);
    // out[k][0], the spherical domain, is printed for comparison only.
    for ((title, ..), o) in cases.iter().zip(&out) {
        for lobe in &o[1..] {
            assert!(
                !lobe.passes(sidak_threshold()),
                "{title}: a lobe domain did not reject: {lobe:?}"
            );
        }
    }
    assert_eq!(
        out[1].len(),
        3,
        "dielectric: sphere, reflection and transmission domains"
    );
}

/// Samples where the claimed pdf is zero fail outright, whatever the p-value.
#[test]
fn chi2_fails_on_samples_where_the_pdf_is_zero() {
    let bsdf = Bsdf::Diffuse(Diffuse::new(Vec3::splat(0.5)));
    let wo = outgoing(0.7);
    let out = run_chi2(
        &|uc, u| bsdf.sample(wo, uc, u, MODE).map(|s| s.wi),
        // Claims nothing is ever sampled with y < 0 (and twice as much elsewhere).
        &|w| {
            if w.y < 0.0 {
                0.0
            } else {
                2.0 * f64::from(bsdf.pdf(wo, w.as_vec3(), MODE).0)
            }
        },
        &[Domain::Spherical],
        &[],
        20_000,
        SEED,
    );
    assert!(out[0].zero_hits > 0, "{:?}", out[0]);
    assert!(!out[0].passes(sidak_threshold()));
}

// ---------------------------------------------------------------------------------------------
// Fast checks of the test machinery itself.
// ---------------------------------------------------------------------------------------------

#[test]
// Reference values are quoted to the digits mpmath printed.
#[allow(clippy::excessive_precision)]
fn incomplete_gamma_matches_reference_values() {
    // ln Γ against exact values.
    assert!(ln_gamma(1.0).abs() < 1e-14);
    assert!((ln_gamma(0.5) - 0.572_364_942_924_700_087).abs() < 1e-13);
    assert!((ln_gamma(10.0) - 362_880f64.ln()).abs() < 1e-12);
    assert!((ln_gamma(100.5) - 361.435_540_467_777_62).abs() < 1e-10);
    assert!((ln_gamma(2500.5) - 17_061.033_949_007_268).abs() < 1e-8);
    // χ² upper tails, reference values from mpmath (30 digits).
    let cases = [
        (1, 3.841_458_820_694_124, 0.05),
        (10, 23.209_251_158_954, 0.01),
        (100, 135.806_723_17, 0.01),
        (1000, 1106.969, 0.009_999_996_853_907_445),
        (2, 1e-3, 0.999_500_124_979_169_27),
        (5000, 5000.0, 0.497_340_378_892_345_12),
        (3, 50.0, 7.989_179_244_951_471_1e-11),
        (50, 200.0, 7.857_610_724_654_743_6e-20),
    ];
    for (dof, x, p) in cases {
        let got = chi2_p_value(x, dof);
        assert!(
            ((got - p) / p).abs() < 1e-7,
            "dof={dof} x={x}: got {got}, want {p}"
        );
    }
}

#[test]
fn domains_round_trip_and_quadrature_integrates_to_one() {
    let domains = [
        Domain::Spherical,
        Domain::lobe(DVec3::new(0.3, -0.2, 0.9), 1.0),
        Domain::lobe(DVec3::new(-0.5, 0.1, 0.2), 1000.0),
        Domain::lobe(DVec3::Z, 30.0),
        Domain::bipolar(DVec3::Z, 400.0, 14_400.0),
        Domain::bipolar(DVec3::new(0.1, 0.7, -0.3), 30.0, 1.0),
    ];
    // A clipped narrow lobe, discontinuous at the horizon, in every domain.
    let axis = DVec3::new(0.0, 0.05f64.sin(), 0.05f64.cos());
    let lobe = |w: DVec3| {
        let c = w.dot(axis);
        if w.z > 0.0 && c > 0.0 {
            31.0 / (2.0 * PI) * c.powi(30)
        } else {
            0.0
        }
    };
    // Reference: for each cos α the azimuths above the horizon form one arc of length
    // 2·acos(−A/B) (z = A + B·cos(φ − φ₀)), so only cos α needs a (fine, midpoint) grid.
    let reference = {
        let Domain::Lobe { s, t, n, .. } = Domain::lobe(axis, 1.0) else {
            unreachable!()
        };
        let steps = 1_000_000;
        let mut sum = 0.0;
        for i in 0..steps {
            let c = 1.0 - (f64::from(i) + 0.5) / f64::from(steps);
            let a = c * n.z;
            let b = (1.0 - c * c).sqrt() * s.z.hypot(t.z);
            let arc = if a >= b {
                2.0 * PI
            } else if a <= -b {
                0.0
            } else {
                2.0 * (-a / b).acos()
            };
            sum += 31.0 / (2.0 * PI) * c.powi(30) * arc;
        }
        sum / f64::from(steps)
    };
    for d in &domains {
        for i in 0..37 {
            for j in 0..41 {
                let (a, b) = ((f64::from(i) + 0.5) / 37.0, (f64::from(j) + 0.5) / 41.0);
                let (w, _) = d.direction(a, b);
                assert!((w.length() - 1.0).abs() < 1e-12);
                let (a2, b2) = d.coords(w);
                assert!(
                    (a - a2).abs() < 1e-9 && (b - b2).abs() < 1e-9,
                    "{d:?}: ({a}, {b}) -> {w} -> ({a2}, {b2})"
                );
            }
        }
        // The uniform density integrates to one in every domain (checks the Jacobians).
        let total: f64 = tabulate_pdf(d, &|_| 0.25 / PI, 1e6, &[]).iter().sum();
        assert!((total - 1.0).abs() < 1e-6, "{d:?}: {total}");
        let total: f64 = tabulate_pdf(d, &lobe, 1e6, &[axis]).iter().sum();
        assert!(
            (total - reference).abs() < 1e-5,
            "{d:?}: clipped lobe {total} vs {reference}"
        );
    }
}
