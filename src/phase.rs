//! Phase functions of participating media: single and double Henyey–Greenstein.
//!
//! Convention (docs/references.md §0, §2): `wo` and `wi` both point AWAY from the scattering point
//! (pbrt convention). The photon propagates along `-wo` before the event and along `wi` after
//! it, so the scattering cosine is `μ = (-wo)·wi` and forward scattering (g > 0) means
//! `wi ≈ -wo`. All evaluation and sampling use the cancellation-free forms of
//! docs/references.md §2.2–§2.3, accurate to a few ulp for |g| up to 1 − 1e-6.

use crate::math::{Frame, Vec2, Vec3, INV_4PI, PI};

/// Largest |g| used: anisotropy is clamped to ±0.99 (pbrt's choice, docs/references.md §2.5). Beyond
/// it the lobe is so narrow that NEE with MIS fireflies; the clamped value is used for `eval`,
/// `pdf`, `sample` and `mean_cosine` alike.
pub const MAX_ABS_G: f32 = 0.99;

/// Invalid phase-function parameter.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PhaseError {
    /// A parameter is NaN or outside its valid range.
    #[error("invalid phase-function parameter `{param}` = {value}: {problem}")]
    InvalidParameter {
        /// Parameter name.
        param: &'static str,
        /// The offending value.
        value: f32,
        /// What is wrong with it.
        problem: &'static str,
    },
}

/// A phase function (1/sr, normalised over the sphere).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PhaseFunction {
    /// Henyey & Greenstein 1941 with mean cosine `g` (|g| ≤ 0.99 after clamping).
    HenyeyGreenstein {
        /// Mean cosine (anisotropy).
        g: f32,
    },
    /// Mixture `w·HG(g1) + (1−w)·HG(g2)` (docs/references.md §2.4).
    DoubleHenyeyGreenstein {
        /// Anisotropy of the first lobe.
        g1: f32,
        /// Anisotropy of the second lobe.
        g2: f32,
        /// Weight of the first lobe in [0, 1].
        w: f32,
    },
}

/// A sampled phase-function direction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PhaseSample {
    /// New direction (pointing away from the scattering point = new propagation direction).
    pub wi: Vec3,
    /// Solid-angle pdf of `wi` (the full mixture pdf for double HG).
    pub pdf: f32,
    /// Phase-function value `p(wo, wi)`; equals `pdf`, so the MC weight `value/pdf` is 1.
    pub value: f32,
}

fn validate_g(param: &'static str, g: f32) -> Result<f32, PhaseError> {
    if g.is_nan() {
        return Err(PhaseError::InvalidParameter {
            param,
            value: g,
            problem: "is NaN",
        });
    }
    if !(-1.0..=1.0).contains(&g) {
        return Err(PhaseError::InvalidParameter {
            param,
            value: g,
            problem: "must be in [-1, 1]",
        });
    }
    Ok(g.clamp(-MAX_ABS_G, MAX_ABS_G))
}

/// HG value from `a = 1 − μ` and `b = 1 + μ` (docs/references.md §2.2).
#[inline]
fn hg_from_ab(g: f32, a: f32, b: f32) -> f32 {
    let delta = if g >= 0.0 {
        (1.0 - g) * (1.0 - g) + 2.0 * g * a
    } else {
        (1.0 + g) * (1.0 + g) - 2.0 * g * b
    };
    hg_from_delta(g, delta)
}

/// HG value from the denominator's base `delta` = 1 + g² − 2gμ in its cancellation-free form.
#[inline]
fn hg_from_delta(g: f32, delta: f32) -> f32 {
    let v = (1.0 - g) * (1.0 + g) * INV_4PI / (delta * delta.sqrt());
    if v.is_finite() {
        v
    } else {
        0.0
    }
}

/// Single-lobe HG value for directions `wo`, `wi` (both pointing away): [`hg_from_ab`] with
/// only the one of `1 − μ`, `1 + μ` that the sign of `g` uses computed (the same bits).
#[inline]
fn hg_eval(g: f32, wo: Vec3, wi: Vec3) -> f32 {
    hg_eval_with::<true>(g, wo, wi)
}

/// [`hg_eval`], with the isotropic shortcut when `ISOTROPIC_SHORTCUT` (the tests compare the
/// two instances bit for bit).
#[inline(always)]
fn hg_eval_with<const ISOTROPIC_SHORTCUT: bool>(g: f32, wo: Vec3, wi: Vec3) -> f32 {
    if ISOTROPIC_SHORTCUT && g == 0.0 {
        // Isotropic (g = ±0): δ = 1 + 2g·a is exactly 1 for every a in [0, 2], and the value
        // (1 − g)(1 + g)/(4π)/(1·√1) is exactly 1/(4π); only a NaN `a` (a NaN direction)
        // makes it NaN, which [`hg_from_delta`] turns into 0.
        let a = (0.5 * (wo + wi).length_squared()).clamp(0.0, 2.0);
        return if a.is_nan() { 0.0 } else { INV_4PI };
    }
    let delta = if g >= 0.0 {
        let a = (0.5 * (wo + wi).length_squared()).clamp(0.0, 2.0);
        (1.0 - g) * (1.0 - g) + 2.0 * g * a
    } else {
        let b = (0.5 * (wo - wi).length_squared()).clamp(0.0, 2.0);
        (1.0 + g) * (1.0 + g) - 2.0 * g * b
    };
    hg_from_delta(g, delta)
}

/// `(1 − μ, 1 + μ)` for the propagation cosine μ = (−wo)·wi, without cancellation.
#[inline]
fn one_minus_plus_mu(wo: Vec3, wi: Vec3) -> (f32, f32) {
    // u = -wo (propagation before), v = wi: 1 - μ = |u - v|²/2 = |wo + wi|²/2.
    let a = 0.5 * (wo + wi).length_squared();
    let b = 0.5 * (wo - wi).length_squared();
    (a.clamp(0.0, 2.0), b.clamp(0.0, 2.0))
}

/// Henyey–Greenstein value as a function of the scattering cosine μ (1/sr); `g` is used as
/// given (not clamped). Useful as a test oracle.
#[must_use]
pub fn henyey_greenstein_mu(g: f32, mu: f32) -> f32 {
    let mu = mu.clamp(-1.0, 1.0);
    hg_from_ab(g, 1.0 - mu, 1.0 + mu)
}

/// Samples HG by exact inversion in the cancellation-free form of docs/references.md §2.3; returns
/// the propagation direction after scattering, given the direction before (`w_in`).
fn sample_hg(g: f32, w_in: Vec3, u: Vec2) -> Vec3 {
    sample_hg_with::<true>(g, w_in, u)
}

/// [`sample_hg`], with the isotropic shortcut when `ISOTROPIC_SHORTCUT` (the tests compare the
/// two instances bit for bit).
#[inline(always)]
fn sample_hg_with<const ISOTROPIC_SHORTCUT: bool>(g: f32, w_in: Vec3, u: Vec2) -> Vec3 {
    let xi = u.x.clamp(0.0, 1.0);
    let xi_c = 1.0 - xi;
    let (a, b) = if ISOTROPIC_SHORTCUT && g == 0.0 {
        // Isotropic (g = ±0): below, d = p = q = 1 exactly for every ξ in [0, 1] and the
        // factors (1 ∓ g)² are 1, so a = 2(1 − ξ) and b = 2ξ (doubling is exact, and both lie
        // in [0, 2]; a NaN ξ stays NaN): the same bits without the division.
        (2.0 * xi_c, 2.0 * xi)
    } else {
        let (d, p, q) = if g >= 0.0 {
            ((1.0 - g) + 2.0 * g * xi, 1.0 + g * xi, (1.0 - g) + g * xi)
        } else {
            (
                (1.0 + g) - 2.0 * g * xi_c,
                (1.0 + g) - g * xi_c,
                1.0 - g * xi_c,
            )
        };
        let d2 = d * d;
        (
            (2.0 * (1.0 - g) * (1.0 - g) * xi_c * p / d2).clamp(0.0, 2.0),
            (2.0 * (1.0 + g) * (1.0 + g) * xi * q / d2).clamp(0.0, 2.0),
        )
    };
    let mu = if a < b { 1.0 - a } else { b - 1.0 };
    let sin_t = (a * b).max(0.0).sqrt().min(1.0);
    let phi = 2.0 * PI * u.y;
    let f = Frame::from_normal(w_in);
    let w = f.to_world(Vec3::new(sin_t * phi.cos(), sin_t * phi.sin(), mu));
    w.try_normalize().unwrap_or(w_in)
}

impl PhaseFunction {
    /// Henyey–Greenstein with mean cosine `g` ∈ [−1, 1]; NaN or |g| > 1 is an error, and |g|
    /// is clamped to [`MAX_ABS_G`] = 0.99 (docs/references.md §2.5).
    pub fn henyey_greenstein(g: f32) -> Result<Self, PhaseError> {
        Ok(PhaseFunction::HenyeyGreenstein {
            g: validate_g("g", g)?,
        })
    }

    /// Two-lobe HG `w·HG(g1) + (1−w)·HG(g2)`; `g1`, `g2` validated and clamped as in
    /// [`PhaseFunction::henyey_greenstein`], `w` ∈ [0, 1].
    pub fn double_henyey_greenstein(g1: f32, g2: f32, w: f32) -> Result<Self, PhaseError> {
        let g1 = validate_g("g1", g1)?;
        let g2 = validate_g("g2", g2)?;
        if w.is_nan() {
            return Err(PhaseError::InvalidParameter {
                param: "w",
                value: w,
                problem: "is NaN",
            });
        }
        if !(0.0..=1.0).contains(&w) {
            return Err(PhaseError::InvalidParameter {
                param: "w",
                value: w,
                problem: "must be in [0, 1]",
            });
        }
        Ok(PhaseFunction::DoubleHenyeyGreenstein { g1, g2, w })
    }

    /// Phase function value `p(wo, wi)` (1/sr); both directions point away from the
    /// scattering point. Never NaN for finite unit inputs.
    #[must_use]
    #[inline]
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> f32 {
        match *self {
            PhaseFunction::HenyeyGreenstein { g } => hg_eval(g, wo, wi),
            PhaseFunction::DoubleHenyeyGreenstein { g1, g2, w } => {
                let (a, b) = one_minus_plus_mu(wo, wi);
                w * hg_from_ab(g1, a, b) + (1.0 - w) * hg_from_ab(g2, a, b)
            }
        }
    }

    /// Solid-angle pdf of [`PhaseFunction::sample`] (equal to [`PhaseFunction::eval`]).
    #[must_use]
    #[inline]
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.eval(wo, wi)
    }

    /// Samples a new direction; `u` uniform in [0, 1)². For double HG, `u.x` first picks the
    /// lobe and is rescaled. The returned pdf is the full mixture pdf, so `value/pdf = 1`.
    #[must_use]
    pub fn sample(&self, wo: Vec3, u: Vec2) -> PhaseSample {
        let (wi, w_in) = self.sample_with_incident(wo, u);
        let pdf = match *self {
            // Isotropic (the pattern matches g = −0 too: float patterns compare with `==`):
            // `w_in` and `wi` are finite (normalised or fallen back to a unit axis), so the pdf
            // below is exactly 1/(4π) ([`hg_eval`]).
            PhaseFunction::HenyeyGreenstein { g: 0.0 } => INV_4PI,
            _ => self.pdf(-w_in, wi),
        };
        PhaseSample {
            wi,
            pdf,
            value: pdf,
        }
    }

    /// The direction [`PhaseFunction::sample`] returns for the same `wo` and `u` (the same
    /// bits), without its pdf: for callers that evaluate the pdf they need themselves.
    #[must_use]
    pub fn sample_direction(&self, wo: Vec3, u: Vec2) -> Vec3 {
        self.sample_with_incident(wo, u).0
    }

    /// The sampled direction and the normalised propagation direction before scattering.
    #[inline]
    fn sample_with_incident(&self, wo: Vec3, u: Vec2) -> (Vec3, Vec3) {
        let w_in = (-wo).try_normalize().unwrap_or(Vec3::Z);
        let wi = match *self {
            PhaseFunction::HenyeyGreenstein { g } => sample_hg(g, w_in, u),
            PhaseFunction::DoubleHenyeyGreenstein { g1, g2, w } => {
                if u.x < w {
                    let x = (u.x / w).min(crate::sampling::ONE_MINUS_EPSILON);
                    sample_hg(g1, w_in, Vec2::new(x, u.y))
                } else {
                    let x = ((u.x - w) / (1.0 - w)).clamp(0.0, crate::sampling::ONE_MINUS_EPSILON);
                    sample_hg(g2, w_in, Vec2::new(x, u.y))
                }
            }
        };
        (wi, w_in)
    }

    /// Mean cosine `E[μ]` of the scattering angle (after clamping): `g`, or `w g1 + (1−w) g2`.
    #[must_use]
    pub fn mean_cosine(&self) -> f32 {
        match *self {
            PhaseFunction::HenyeyGreenstein { g } => g,
            PhaseFunction::DoubleHenyeyGreenstein { g1, g2, w } => w * g1 + (1.0 - w) * g2,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `sample_hg`'s inversion for every g, without the isotropic shortcut.
    fn sample_hg_general(g: f32, w_in: Vec3, u: Vec2) -> Vec3 {
        sample_hg_with::<false>(g, w_in, u)
    }

    /// `hg_eval` for every g, without the isotropic shortcut.
    fn hg_eval_general(g: f32, wo: Vec3, wi: Vec3) -> f32 {
        hg_eval_with::<false>(g, wo, wi)
    }

    /// A small deterministic generator of uniform `f32`s in [0, 1) (24-bit, as the sampler's).
    struct Uniform(u64);
    impl Uniform {
        fn next(&mut self) -> f32 {
            self.0 = self
                .0
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            ((self.0 >> 40) as f32) * (1.0 / 16_777_216.0)
        }
        fn direction(&mut self) -> Vec3 {
            let v = Vec3::new(self.next() - 0.5, self.next() - 0.5, self.next() - 0.5);
            v.try_normalize().unwrap_or(Vec3::Z)
        }
    }

    #[test]
    fn isotropic_sampling_and_values_have_the_general_formulas_bits() {
        let mut rng = Uniform(7);
        let edges = [0.0, 0.5, 1.0 - f32::EPSILON / 2.0, f32::EPSILON, f32::NAN];
        for i in 0..200_000 {
            let u = if i < edges.len() * edges.len() {
                Vec2::new(edges[i % edges.len()], edges[i / edges.len()])
            } else {
                Vec2::new(rng.next(), rng.next())
            };
            let (wo, wi) = (rng.direction(), rng.direction());
            for g in [0.0f32, -0.0] {
                let w_in = (-wo).try_normalize().unwrap_or(Vec3::Z);
                let got = sample_hg(g, w_in, u);
                let want = sample_hg_general(g, w_in, u);
                assert_eq!(
                    got.to_array().map(f32::to_bits),
                    want.to_array().map(f32::to_bits)
                );
                assert_eq!(
                    hg_eval(g, wo, wi).to_bits(),
                    hg_eval_general(g, wo, wi).to_bits()
                );
                let phase = PhaseFunction::HenyeyGreenstein { g };
                let s = phase.sample(wo, u);
                let pdf = hg_eval_general(g, -w_in, want);
                assert_eq!(
                    (s.pdf.to_bits(), s.value.to_bits()),
                    (pdf.to_bits(), pdf.to_bits())
                );
            }
        }
        // A NaN direction: the value is 0, as the general formula's.
        let nan = Vec3::new(f32::NAN, 0.0, 1.0);
        assert_eq!(hg_eval(0.0, nan, Vec3::Z), 0.0);
        assert_eq!(hg_eval_general(0.0, nan, Vec3::Z), 0.0);
    }

    #[test]
    fn a_samples_value_over_its_pdf_is_exactly_one() {
        // What `VertexPhase::sample`'s weight of 1 relies on, for single and double HG.
        let mut rng = Uniform(11);
        let phases = [
            PhaseFunction::HenyeyGreenstein { g: 0.0 },
            PhaseFunction::HenyeyGreenstein { g: 0.99 },
            PhaseFunction::HenyeyGreenstein { g: -0.99 },
            PhaseFunction::HenyeyGreenstein { g: 0.3 },
            PhaseFunction::DoubleHenyeyGreenstein {
                g1: 0.95,
                g2: -0.6,
                w: 0.8,
            },
        ];
        let mut positive = 0;
        for _ in 0..50_000 {
            let u = Vec2::new(rng.next(), rng.next());
            let wo = rng.direction();
            for p in &phases {
                let s = p.sample(wo, u);
                assert!(s.pdf.is_finite() && s.value.to_bits() == s.pdf.to_bits());
                if s.pdf > 0.0 {
                    assert_eq!(s.value / s.pdf, 1.0);
                    positive += 1;
                }
            }
        }
        assert!(positive > 200_000);
    }
}
