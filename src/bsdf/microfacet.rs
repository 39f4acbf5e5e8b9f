//! Isotropic microfacet normal distributions (GGX / Trowbridge–Reitz and Beckmann), Smith
//! masking, and visible-normal sampling.
//!
//! All vectors are in the local shading frame (+z = macro normal). Microfacet normals always
//! have `m.z > 0`. Directions below the surface are handled by the mirror symmetry of the
//! distributions: the visible normals seen from `w` with `w.z < 0` are those seen from `-w`.

use crate::math::{Vec2, Vec3, PI};

use super::special::{beckmann_two_lambda, erf, erf_inv, INV_SQRT_PI};
use super::MicrofacetDistribution;

/// Below this `alpha` a microfacet lobe is treated as perfectly smooth (a delta lobe), as in
/// pbrt-v4's "effectively smooth" test (docs/references.md §3.8, §8).
pub const SMOOTH_ALPHA: f32 = 1e-3;

/// An isotropic microfacet distribution with width `alpha` (GGX: α of Walter et al. 2007;
/// Beckmann: RMS slope).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Microfacet {
    /// Which distribution.
    pub distribution: MicrofacetDistribution,
    /// Width parameter α (dimensionless slope scale), `alpha = roughness²`.
    pub alpha: f32,
}

impl Microfacet {
    /// A distribution of width `alpha` (expected in `[SMOOTH_ALPHA, 1]`; smaller values are
    /// clamped to `SMOOTH_ALPHA` so no evaluation overflows).
    #[must_use]
    pub fn new(distribution: MicrofacetDistribution, alpha: f32) -> Self {
        let alpha = if alpha.is_finite() {
            alpha.clamp(SMOOTH_ALPHA, 1.0)
        } else {
            1.0
        };
        Microfacet {
            distribution,
            alpha,
        }
    }

    /// True when a surface with this α should be treated as a delta lobe.
    #[must_use]
    pub fn is_smooth_alpha(alpha: f32) -> bool {
        alpha < SMOOTH_ALPHA
    }

    /// Normal distribution function D(m) (1/sr, projected: ∫ D(m) m.z dm = 1). Zero for
    /// `m.z <= 0`. GGX in the overflow-free `x, y, z` form (docs/references.md §3.2); Beckmann §3.3.
    #[must_use]
    pub fn d(&self, m: Vec3) -> f32 {
        if !(m.z > 0.0) {
            return 0.0;
        }
        let a2 = self.alpha * self.alpha;
        let xy2 = m.x * m.x + m.y * m.y;
        match self.distribution {
            MicrofacetDistribution::Ggx => {
                let s = xy2 / a2 + m.z * m.z;
                let v = 1.0 / (PI * a2 * s * s);
                if v.is_finite() {
                    v
                } else {
                    0.0
                }
            }
            MicrofacetDistribution::Beckmann => {
                let tan2 = xy2 / (m.z * m.z);
                let e = tan2 / a2;
                if !(e < 80.0) {
                    return 0.0;
                }
                // 1/cos⁴θ = (1 + tan²θ)² for a unit m.
                let c = 1.0 + tan2;
                (-e).exp() * c * c / (PI * a2)
            }
        }
    }

    /// Smith Λ(w) (docs/references.md §3.2/§3.3); `+∞` at grazing `w.z = 0`. Symmetric in `w.z`.
    #[must_use]
    pub fn lambda(&self, w: Vec3) -> f32 {
        let z2 = w.z * w.z;
        let xy2 = w.x * w.x + w.y * w.y;
        if z2 == 0.0 {
            return if xy2 > 0.0 { f32::INFINITY } else { 0.0 };
        }
        let t = self.alpha * self.alpha * xy2 / z2;
        if !t.is_finite() {
            return f32::INFINITY;
        }
        match self.distribution {
            // Cancellation-free form t / (2 (sqrt(1+t) + 1)).
            MicrofacetDistribution::Ggx => t / (2.0 * ((1.0 + t).sqrt() + 1.0)),
            MicrofacetDistribution::Beckmann => {
                if t == 0.0 {
                    return 0.0;
                }
                // a = 1/(α tanθ) = 1/sqrt(t).
                let a = 1.0 / t.sqrt();
                0.5 * beckmann_two_lambda(a)
            }
        }
    }

    /// Smith masking G1(w) = 1 / (1 + Λ(w)).
    #[must_use]
    pub fn g1(&self, w: Vec3) -> f32 {
        1.0 / (1.0 + self.lambda(w))
    }

    /// Height-correlated Smith masking–shadowing G2 = 1 / (1 + Λ(wo) + Λ(wi)) (Heitz 2014),
    /// used for reflection and transmission alike (as pbrt-v4 does).
    #[must_use]
    pub fn g2(&self, wo: Vec3, wi: Vec3) -> f32 {
        1.0 / (1.0 + self.lambda(wo) + self.lambda(wi))
    }

    /// Density of visible normals D_w(m) = G1(w) max(0, w·m) D(m) / w.z (1/sr), with `w`
    /// first flipped to the upper hemisphere. Integrates to 1 over `m`. Zero at `w.z = 0`.
    #[must_use]
    pub fn visible_pdf(&self, w: Vec3, m: Vec3) -> f32 {
        self.visible_pdf_with(w, m, |w| self.lambda(w), || self.d(m))
    }

    /// [`Microfacet::visible_pdf`] with Λ(w) and D(m) supplied by the caller when they are
    /// needed (a caller that has them already passes closures returning them: the same bits,
    /// as Λ is even in `w.z` and is computed here for the flipped `w`).
    #[inline]
    pub(crate) fn visible_pdf_with(
        &self,
        w: Vec3,
        m: Vec3,
        lambda: impl FnOnce(Vec3) -> f32,
        d: impl FnOnce() -> f32,
    ) -> f32 {
        let w = if w.z < 0.0 { -w } else { w };
        if !(w.z > 0.0) {
            return 0.0;
        }
        let wm = w.dot(m);
        if !(wm > 0.0) {
            return 0.0;
        }
        let v = 1.0 / (1.0 + lambda(w)) * wm * d() / w.z;
        if v.is_finite() {
            v
        } else {
            0.0
        }
    }

    /// Samples a microfacet normal from the visible-normal distribution seen from `w`
    /// (flipped to the upper hemisphere if needed); `u` uniform in [0,1)². The result has
    /// `m.z > 0` and pdf [`Microfacet::visible_pdf`].
    ///
    /// GGX: spherical-cap sampling of the stretched configuration (Dupuy & Benyoub 2023,
    /// "Sampling Visible GGX Normals with Spherical Caps"; same distribution as Heitz 2018).
    /// Beckmann: Heitz & d'Eon 2014 in slope space, with the marginal CDF inverted by a
    /// bracketed Newton iteration in `erf` space (docs/references.md §3.7).
    #[must_use]
    pub fn sample_visible(&self, w: Vec3, u: Vec2) -> Vec3 {
        let w = if w.z < 0.0 { -w } else { w };
        let a = self.alpha;
        // Stretch to the α = 1 configuration.
        let wh = Vec3::new(a * w.x, a * w.y, w.z)
            .try_normalize()
            .unwrap_or(Vec3::Z);
        let m = match self.distribution {
            MicrofacetDistribution::Ggx => {
                let phi = 2.0 * PI * u.x;
                let z = (1.0 - u.y) * (1.0 + wh.z) - wh.z;
                let s = (1.0 - z * z).max(0.0).sqrt();
                let h = Vec3::new(s * phi.cos(), s * phi.sin(), z) + wh;
                Vec3::new(a * h.x, a * h.y, h.z.max(1e-7))
            }
            MicrofacetDistribution::Beckmann => {
                let (sx, sy) = sample_beckmann_slopes_11(wh, u);
                Vec3::new(-a * sx, -a * sy, 1.0)
            }
        };
        let m = m.try_normalize().unwrap_or(Vec3::Z);
        if m.z > 0.0 {
            m
        } else {
            Vec3::new(m.x, m.y, 1e-7).normalize_or(Vec3::Z)
        }
    }
}

/// Visible slopes of the standard (α = 1) Beckmann surface seen from the unit direction `wh`
/// (`wh.z >= 0`), rotated to `wh`'s azimuth (Heitz & d'Eon 2014, "Importance Sampling
/// Microfacet-Based BSDFs using the Distribution of Visible Normals", §4/§5).
fn sample_beckmann_slopes_11(wh: Vec3, u: Vec2) -> (f32, f32) {
    let sin_t = (wh.x * wh.x + wh.y * wh.y).sqrt();
    let cos_t = wh.z.max(0.0);
    let (cos_phi, sin_phi) = if sin_t > 0.0 {
        (wh.x / sin_t, wh.y / sin_t)
    } else {
        (1.0, 0.0)
    };
    let xi1 = u.x.clamp(1e-6, 1.0 - 1e-6);
    let xi2 = u.y.clamp(1e-6, 1.0 - 1e-6);

    // Marginal of the slope x̃ along the incidence plane (density ∝ (1 - x̃ tanθ) e^{-x̃²}
    // on x̃ < cotθ). In u = erf(x̃) its CDF is linear up to the exp term, so Newton converges
    // fast; a bracket [lo, hi] keeps every iterate valid.
    let tan_t = if cos_t > 0.0 {
        sin_t / cos_t
    } else {
        f32::INFINITY
    };
    let x_slope = if !(tan_t < 1e7) {
        // Grazing: the density ∝ -x̃ e^{-x̃²} on x̃ < 0 has CDF e^{-x̃²}.
        -(-xi1.ln()).sqrt()
    } else {
        let cot_t = if sin_t > 0.0 {
            cos_t / sin_t
        } else {
            f32::INFINITY
        };
        let erf_cot = erf(cot_t);
        let exp_term = |x: f32| {
            if tan_t > 0.0 {
                tan_t * INV_SQRT_PI * (-x * x).exp()
            } else {
                0.0
            }
        };
        let norm = 1.0 + erf_cot + exp_term(cot_t);
        let cdf = |b: f32, x: f32| (1.0 + b + exp_term(x)) / norm;
        let mut lo = -1.0f32;
        let mut hi = erf_cot;
        // Initial guess (Mitsuba's fit of the inverse's shape in θ).
        let theta = cos_t.clamp(-1.0, 1.0).acos();
        let fit = 1.0 + theta * (-0.876 + theta * (0.4265 - 0.0594 * theta));
        let mut b = erf_cot - (1.0 + erf_cot) * (1.0 - xi1).powf(fit);
        // The last evaluated (u, x̃) pair: the converged iterate is reused, not recomputed.
        let mut last = (f32::NAN, 0.0f32);
        for _ in 0..10 {
            if !(b >= lo && b <= hi) {
                b = 0.5 * (lo + hi);
            }
            let x = erf_inv(b);
            last = (b, x);
            let value = cdf(b, x) - xi1;
            if value.abs() < 2e-6 || hi - lo < 1e-6 {
                break;
            }
            if value > 0.0 {
                hi = b;
            } else {
                lo = b;
            }
            let deriv = (1.0 - x * tan_t) / norm;
            if deriv > 0.0 {
                b -= value / deriv;
            } else {
                b = 0.5 * (lo + hi);
            }
        }
        let b_c = b.clamp(-1.0 + 6e-8, erf_cot.min(1.0 - 6e-8));
        if b_c == last.0 {
            last.1
        } else {
            erf_inv(b_c)
        }
    };
    let y_slope = erf_inv(2.0 * xi2 - 1.0);
    let x = if x_slope.is_finite() { x_slope } else { 0.0 };
    let y = if y_slope.is_finite() { y_slope } else { 0.0 };
    // Rotate from the incidence plane to wh's azimuth.
    (cos_phi * x - sin_phi * y, sin_phi * x + cos_phi * y)
}
