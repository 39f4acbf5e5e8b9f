//! Surface scattering: smooth and rough dielectrics (GGX / Beckmann, Walter et al. 2007),
//! diffuse transmission, Lambertian, rough conductors, and an optional specular coat.
//!
//! Conventions (docs/references.md §0, §3): every direction is a unit vector in the LOCAL shading
//! frame, +z is the shading normal and points to the OUTSIDE of the object, and `wo`, `wi`
//! both point away from the surface (`wo` towards the camera-side vertex, `wi` towards the
//! light side). `wo.z < 0` means the camera-side vertex is inside the object. [`Surface::eval`]
//! returns `f` in 1/sr without the cosine, in RADIANCE transport mode: rough and smooth
//! transmission carry the `1/η'²` radiance scaling (docs/references.md §3.5, §3.8), where
//! `η' = η_{wi side}/η_{wo side}`.
//!
//! Using a [`Surface`] from an integrator: build a [`crate::math::Frame`] around the shading
//! normal (outward), convert `wo` to local, call [`Surface::sample`]; multiply the throughput
//! by `weight`, and by `eta²` the eta-scale used for Russian roulette. Samples with
//! `is_delta` carry a discrete probability in `pdf` and must skip MIS; for light samples use
//! [`Surface::eval`] × `|cos θ_i|` and [`Surface::pdf`] (which matches the `pdf` of non-delta
//! samples exactly, mixture of coat and base included). Surfaces with [`Surface::is_delta`]
//! need no light sampling at all.
//!
//! Numerical guards (docs/references.md §8): directions with `|cos θ| < 1e-7` and Jacobian
//! denominators below `1e-7` give zero `f`, zero pdf and no sample; microfacet lobes with
//! `α < 1e-3` become delta lobes; no function returns NaN or infinity.

pub mod fresnel;
pub mod microfacet;
pub mod special;

use crate::math::{refract, Vec2, Vec3, INV_PI};
use crate::sampling::{sample_cosine_hemisphere, ONE_MINUS_EPSILON};
use crate::spectrum::Rgb;

use fresnel::{fresnel_conductor, fresnel_dielectric, gulbrandsen_eta_k};
use microfacet::{Microfacet, SMOOTH_ALPHA};

/// Cosines (and Jacobian denominators) below this are treated as grazing: zero BSDF, no sample.
pub const COS_EPSILON: f32 = 1e-7;

/// Number of nodes of the tabulated coat albedo `E(μ)`.
const COAT_TABLE_SIZE: usize = 32;

/// The largest reflection floor a dielectric accepts ([`Surface::with_reflect_floor`]): the
/// transmission keeps at least this much less than all of the samples.
pub const MAX_REFLECT_FLOOR: f32 = 0.95;
/// Stratified quadrature resolution (per axis) used to tabulate the coat albedo.
const COAT_TABLE_STRATA: usize = 24;

/// Microfacet normal distribution of a rough lobe.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MicrofacetDistribution {
    /// GGX / Trowbridge–Reitz (Walter et al. 2007), visible normals by Heitz 2018 /
    /// Dupuy & Benyoub 2023.
    Ggx,
    /// Beckmann–Spizzichino, visible normals by Heitz & d'Eon 2014.
    Beckmann,
}

/// Invalid BSDF construction parameter.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum BsdfError {
    /// A parameter is NaN, infinite, or outside its valid range.
    #[error("invalid BSDF parameter `{param}` = {value}: {problem}")]
    InvalidParameter {
        /// Parameter name (with the RGB channel where relevant).
        param: String,
        /// The offending value.
        value: f32,
        /// What is wrong with it.
        problem: &'static str,
    },
}

/// One sampled scattering direction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BsdfSample {
    /// Sampled incident direction (local frame, pointing away from the surface).
    pub wi: Vec3,
    /// Monte-Carlo weight `f |cos θ_i| / pdf` (radiance mode).
    pub weight: Rgb,
    /// Solid-angle pdf of `wi` (for delta samples: the discrete probability of the choice).
    pub pdf: f32,
    /// True when `wi` came from a delta (specular) lobe; such samples must not take part in MIS.
    pub is_delta: bool,
    /// True when `wi` is on the other side of the surface from `wo`.
    pub is_transmission: bool,
    /// Relative IOR crossed, `η_{wi side}/η_{wo side}` (1 for reflection); the integrator
    /// multiplies its eta-scale by `eta²` for Russian roulette (pbrt-v4 convention).
    pub eta: f32,
}

/// The base scattering lobe of a [`Surface`]. Construct through the validating constructors
/// of [`Surface`]; the fields are exposed read-only through [`Surface::base`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum BaseLobe {
    /// Dielectric interface (Walter et al. 2007): smooth (delta) below α = 1e-3, index-matched
    /// pass-through at `eta == 1`.
    Dielectric {
        /// `n_inside / n_outside`.
        eta: f32,
        /// Microfacet width α = roughness².
        alpha: f32,
        /// Microfacet distribution.
        distribution: MicrofacetDistribution,
        /// Transmission tint in [0, 1] per channel (reflection is untinted).
        tint: Rgb,
        /// The least probability with which sampling picks reflection for a direction
        /// arriving from outside (`wo.z > 0`), in [0, [`MAX_REFLECT_FLOOR`]]: reflection is
        /// picked with probability max(F, floor), transmission with the rest (0: by F alone,
        /// the usual choice). Only the sampling changes, not the BSDF.
        reflect_floor: f32,
    },
    /// Lambertian transmission `T/π` to the opposite side plus Lambertian reflection `R/π`
    /// (docs/references.md §3.9); reciprocal, no η² scaling.
    DiffuseTransmission {
        /// Diffuse reflectance R.
        reflectance: Rgb,
        /// Diffuse transmittance T (R + T ≤ 1).
        transmittance: Rgb,
    },
    /// Two-sided Lambertian reflector `albedo/π`.
    Lambertian {
        /// Hemispherical albedo in [0, 1].
        albedo: Rgb,
    },
    /// Two-sided rough (or smooth below α = 1e-3) conductor with complex Fresnel.
    Conductor {
        /// Real part of the relative complex IOR.
        eta: Rgb,
        /// Imaginary part (extinction coefficient).
        k: Rgb,
        /// Microfacet width α = roughness².
        alpha: f32,
        /// Microfacet distribution.
        distribution: MicrofacetDistribution,
    },
}

/// A secondary specular reflection lobe (GGX, dielectric Fresnel) layered on top of the base.
///
/// Approximation (documented in [`Surface::with_coat`]): the base is attenuated by
/// `a(μ) = 1 - weight·E_c(μ)` for each of `wo`, `wi` that lies on the outside, where `E_c(μ)`
/// is the coat's own directional albedo (tabulated at construction); no inter-reflection
/// between coat and base is modelled. This is reciprocal and energy conserving.
#[derive(Clone, Debug, PartialEq)]
pub struct Coat {
    /// Coat IOR relative to the outside medium (≥ 1).
    pub ior: f32,
    /// GGX width α = roughness².
    pub alpha: f32,
    /// Coat weight in [0, 1].
    pub weight: f32,
    /// Coat directional albedo E_c at μ = j/(N-1).
    albedo_table: [f32; COAT_TABLE_SIZE],
}

/// A surface BSDF: a base lobe plus an optional specular coat.
#[derive(Clone, Debug, PartialEq)]
pub struct Surface {
    base: BaseLobe,
    coat: Option<Coat>,
}

fn invalid(param: impl Into<String>, value: f32, problem: &'static str) -> BsdfError {
    BsdfError::InvalidParameter {
        param: param.into(),
        value,
        problem,
    }
}

fn check_unit(param: &str, v: f32) -> Result<(), BsdfError> {
    if v.is_nan() {
        return Err(invalid(param, v, "is NaN"));
    }
    if !(0.0..=1.0).contains(&v) {
        return Err(invalid(param, v, "must be in [0, 1]"));
    }
    Ok(())
}

/// True when `v` lies in [0, 1] (false for NaN).
#[inline]
fn in_unit(v: f32) -> bool {
    (0.0..=1.0).contains(&v)
}

/// True when every channel of `c` lies in [0, 1] (false for NaN), without branches.
#[inline]
fn rgb_in_unit(c: Rgb) -> bool {
    in_unit(c[0]) & in_unit(c[1]) & in_unit(c[2])
}

/// Checks each channel of `c` lies in [0, 1]; the channel's name (`param.r`, ...) is formatted
/// only for an error, so a valid colour costs no allocation (BSDFs are built per hit). The
/// all-in-range test is inlined and the error's construction is out of line
/// ([`rgb_unit_error`]).
#[inline]
fn check_rgb_unit(param: &str, c: Rgb) -> Result<(), BsdfError> {
    if rgb_in_unit(c) {
        Ok(())
    } else {
        rgb_unit_error(param, c)
    }
}

/// The error of [`check_rgb_unit`] for the first channel out of [0, 1] (or NaN).
#[cold]
#[inline(never)]
fn rgb_unit_error(param: &str, c: Rgb) -> Result<(), BsdfError> {
    for (i, ch) in ["r", "g", "b"].iter().enumerate() {
        let v = c[i];
        if v.is_nan() || !(0.0..=1.0).contains(&v) {
            return check_unit(&format!("{param}.{ch}"), v);
        }
    }
    Ok(())
}

/// The checks of [`Surface::dielectric`] in their order, for parameters that failed its
/// inlined all-valid test: returns the first error.
#[cold]
#[inline(never)]
fn dielectric_error(eta: f32, roughness: f32, tint: Rgb) -> Result<(), BsdfError> {
    check_positive("eta", eta)?;
    check_unit("roughness", roughness)?;
    rgb_unit_error("tint", tint)
}

fn check_positive(param: &str, v: f32) -> Result<(), BsdfError> {
    if v.is_nan() {
        return Err(invalid(param, v, "is NaN"));
    }
    if !(v > 0.0) || !v.is_finite() {
        return Err(invalid(param, v, "must be finite and > 0"));
    }
    Ok(())
}

/// Mirror reflection about +z (pointing-away convention).
fn mirror_z(w: Vec3) -> Vec3 {
    Vec3::new(-w.x, -w.y, w.z)
}

fn flip_z(w: Vec3) -> Vec3 {
    Vec3::new(w.x, w.y, -w.z)
}

fn finite_or_zero(v: f32) -> f32 {
    if v.is_finite() {
        v
    } else {
        0.0
    }
}

fn finite_rgb(c: Rgb) -> Rgb {
    c.map(finite_or_zero)
}

/// Geometry of a (generalised) half vector for a dielectric pair (wo, wi) (docs/references.md §3.4).
struct HalfGeometry {
    wm: Vec3,
    reflect: bool,
    /// η_{wi side}/η_{wo side} (1 for reflection).
    etap: f32,
    wo_m: f32,
    wi_m: f32,
    /// (wi·m + wo·m/η')², the transmission Jacobian denominator.
    denom: f32,
}

/// Half vector of (wo, wi) for a dielectric with `eta = n_in/n_out`, or `None` when the pair
/// is grazing, degenerate or back-facing (Walter 2007 §5.1: reject back-facing microfacets).
fn dielectric_half(wo: Vec3, wi: Vec3, eta: f32) -> Option<HalfGeometry> {
    let co = wo.z;
    let ci = wi.z;
    if !(co.abs() >= COS_EPSILON) || !(ci.abs() >= COS_EPSILON) {
        return None;
    }
    let reflect = co * ci > 0.0;
    let etap = if reflect {
        1.0
    } else if co > 0.0 {
        eta
    } else {
        1.0 / eta
    };
    let wm = (wi * etap + wo).try_normalize()?;
    let wm = if wm.z < 0.0 { -wm } else { wm };
    if !(wm.z > 0.0) {
        return None;
    }
    let wo_m = wo.dot(wm);
    let wi_m = wi.dot(wm);
    if !(wo_m * co > 0.0) || !(wi_m * ci > 0.0) {
        return None;
    }
    let mut denom = 1.0;
    if !reflect {
        let s = wi_m + wo_m / etap;
        if !(s.abs() >= COS_EPSILON) {
            return None;
        }
        denom = s * s;
    }
    Some(HalfGeometry {
        wm,
        reflect,
        etap,
        wo_m,
        wi_m,
        denom,
    })
}

/// Shared geometry of a rough microfacet reflection lobe for (wo, wi), both above the
/// surface: the half vector `wm`, `wo·wm`, the Fresnel-free BRDF `D G2 / (4 cos_o cos_i)` and
/// the visible-normal pdf `D_wo(wm) / (4 wo·wm)`. `None` when grazing or degenerate.
struct ReflectionTerms {
    wo_m: f32,
    brdf: f32,
    pdf: f32,
}

fn rough_reflection(mf: &Microfacet, wo: Vec3, wi: Vec3) -> Option<ReflectionTerms> {
    if !(wo.z >= COS_EPSILON) || !(wi.z >= COS_EPSILON) {
        return None;
    }
    let wm = (wo + wi).try_normalize()?;
    let wo_m = wo.dot(wm);
    if !(wo_m > 0.0) {
        return None;
    }
    let brdf = finite_or_zero(mf.d(wm) * mf.g2(wo, wi) / (4.0 * wo.z * wi.z));
    let pdf = finite_or_zero(mf.visible_pdf(wo, wm) / (4.0 * wo_m));
    Some(ReflectionTerms { wo_m, brdf, pdf })
}

/// Mirrors both directions below the surface into the upper hemisphere when `wo` is below
/// (two-sided opaque lobes).
fn upper_pair(wo: Vec3, wi: Vec3) -> (Vec3, Vec3) {
    if wo.z < 0.0 {
        (flip_z(wo), flip_z(wi))
    } else {
        (wo, wi)
    }
}

/// Rough dielectric `f` (radiance mode) for a valid half-vector geometry.
fn dielectric_f(mf: &Microfacet, tint: Rgb, eta: f32, wo: Vec3, wi: Vec3, h: &HalfGeometry) -> Rgb {
    let f = fresnel_dielectric(h.wo_m, eta);
    let d = mf.d(h.wm);
    let g = mf.g2(wo, wi);
    if h.reflect {
        Rgb::splat(finite_or_zero(d * g * f / (4.0 * (wo.z * wi.z).abs())))
    } else {
        let v = d * (1.0 - f) * g * (h.wi_m * h.wo_m / (h.denom * wi.z * wo.z)).abs()
            / (h.etap * h.etap);
        finite_rgb(tint * v)
    }
}

/// The probability with which a dielectric's sampling picks reflection: the Fresnel
/// reflectance `f`, raised to `floor` for a direction arriving from outside (`wo_z > 0`).
/// Any choice in (0, 1) keeps the estimate unbiased (the sample's weight divides by it); a
/// floor spends more samples on the reflection where it is bright and cheap beside what
/// the transmission reaches (sky over water).
#[inline]
fn reflect_probability(f: f32, floor: f32, wo_z: f32) -> f32 {
    if wo_z > 0.0 {
        f.max(floor)
    } else {
        f
    }
}

/// Rough dielectric pdf for a valid half-vector geometry (docs/references.md §3.8), with
/// reflection picked with [`reflect_probability`].
fn dielectric_pdf(mf: &Microfacet, eta: f32, floor: f32, wo: Vec3, h: &HalfGeometry) -> f32 {
    let f = reflect_probability(fresnel_dielectric(h.wo_m, eta), floor, wo.z);
    let dv = mf.visible_pdf(wo, h.wm);
    let v = if h.reflect {
        f * dv / (4.0 * h.wo_m.abs())
    } else {
        (1.0 - f) * dv * h.wi_m.abs() / h.denom
    };
    finite_or_zero(v)
}

/// [`dielectric_f`] and [`dielectric_pdf`] together, for a sample: the Fresnel term, `D(wm)`
/// and `Λ(wo)` are computed once for both (the same values, so the same bits as the two
/// separate calls).
fn dielectric_f_pdf(
    mf: &Microfacet,
    tint: Rgb,
    eta: f32,
    floor: f32,
    wo: Vec3,
    wi: Vec3,
    h: &HalfGeometry,
) -> (Rgb, f32) {
    let f = fresnel_dielectric(h.wo_m, eta);
    let d = mf.d(h.wm);
    let lambda_o = mf.lambda(wo);
    let g = 1.0 / (1.0 + lambda_o + mf.lambda(wi));
    let fv = if h.reflect {
        Rgb::splat(finite_or_zero(d * g * f / (4.0 * (wo.z * wi.z).abs())))
    } else {
        let v = d * (1.0 - f) * g * (h.wi_m * h.wo_m / (h.denom * wi.z * wo.z)).abs()
            / (h.etap * h.etap);
        finite_rgb(tint * v)
    };
    let q = reflect_probability(f, floor, wo.z);
    let dv = mf.visible_pdf_with(wo, h.wm, |_| lambda_o, || d);
    let pdf = if h.reflect {
        q * dv / (4.0 * h.wo_m.abs())
    } else {
        (1.0 - q) * dv * h.wi_m.abs() / h.denom
    };
    (fv, finite_or_zero(pdf))
}

/// Attempts to build the BSDF sample record for a continuous lobe from `f` and `pdf`.
fn continuous_sample(wo: Vec3, wi: Vec3, f: Rgb, pdf: f32, eta: f32) -> Option<BsdfSample> {
    if !(pdf > 0.0) || !pdf.is_finite() {
        return None;
    }
    let weight = finite_rgb(f * (wi.z.abs() / pdf));
    Some(BsdfSample {
        wi,
        weight,
        pdf,
        is_delta: false,
        is_transmission: wo.z * wi.z < 0.0,
        eta,
    })
}

impl BaseLobe {
    fn is_delta(&self) -> bool {
        match *self {
            BaseLobe::Dielectric { eta, alpha, .. } => eta == 1.0 || alpha < SMOOTH_ALPHA,
            BaseLobe::Conductor { alpha, .. } => alpha < SMOOTH_ALPHA,
            BaseLobe::DiffuseTransmission { .. } | BaseLobe::Lambertian { .. } => false,
        }
    }

    /// Rough weight used to split samples between coat and base.
    fn sampling_weight(&self) -> f32 {
        let w = match *self {
            BaseLobe::Dielectric { .. } => 1.0,
            BaseLobe::DiffuseTransmission {
                reflectance,
                transmittance,
            } => (reflectance + transmittance).average(),
            BaseLobe::Lambertian { albedo } => albedo.average(),
            BaseLobe::Conductor { eta, k, .. } => fresnel_conductor(1.0, eta, k).average(),
        };
        w.clamp(0.0, 1.0)
    }

    fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        match *self {
            BaseLobe::Dielectric {
                eta,
                alpha,
                distribution,
                tint,
                ..
            } => {
                if eta == 1.0 || alpha < SMOOTH_ALPHA {
                    return Rgb::ZERO;
                }
                let mf = Microfacet::new(distribution, alpha);
                match dielectric_half(wo, wi, eta) {
                    Some(h) => dielectric_f(&mf, tint, eta, wo, wi, &h),
                    None => Rgb::ZERO,
                }
            }
            BaseLobe::DiffuseTransmission {
                reflectance,
                transmittance,
            } => {
                if !(wo.z.abs() >= COS_EPSILON) || !(wi.z.abs() >= COS_EPSILON) {
                    return Rgb::ZERO;
                }
                if wo.z * wi.z > 0.0 {
                    reflectance * INV_PI
                } else {
                    transmittance * INV_PI
                }
            }
            BaseLobe::Lambertian { albedo } => {
                if !(wo.z.abs() >= COS_EPSILON) || !(wi.z.abs() >= COS_EPSILON) || wo.z * wi.z < 0.0
                {
                    return Rgb::ZERO;
                }
                albedo * INV_PI
            }
            BaseLobe::Conductor {
                eta,
                k,
                alpha,
                distribution,
            } => {
                if alpha < SMOOTH_ALPHA {
                    return Rgb::ZERO;
                }
                let (wo, wi) = upper_pair(wo, wi);
                let mf = Microfacet::new(distribution, alpha);
                match rough_reflection(&mf, wo, wi) {
                    Some(r) => finite_rgb(fresnel_conductor(r.wo_m, eta, k) * r.brdf),
                    None => Rgb::ZERO,
                }
            }
        }
    }

    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        match *self {
            BaseLobe::Dielectric {
                eta,
                alpha,
                distribution,
                reflect_floor,
                ..
            } => {
                if eta == 1.0 || alpha < SMOOTH_ALPHA {
                    return 0.0;
                }
                let mf = Microfacet::new(distribution, alpha);
                match dielectric_half(wo, wi, eta) {
                    Some(h) => dielectric_pdf(&mf, eta, reflect_floor, wo, &h),
                    None => 0.0,
                }
            }
            BaseLobe::DiffuseTransmission {
                reflectance,
                transmittance,
            } => {
                if !(wo.z.abs() >= COS_EPSILON) || !(wi.z.abs() >= COS_EPSILON) {
                    return 0.0;
                }
                let pr = diffuse_reflect_prob(reflectance, transmittance);
                let p = if wo.z * wi.z > 0.0 { pr } else { 1.0 - pr };
                p * wi.z.abs() * INV_PI
            }
            BaseLobe::Lambertian { .. } => {
                if !(wo.z.abs() >= COS_EPSILON) || !(wi.z.abs() >= COS_EPSILON) || wo.z * wi.z < 0.0
                {
                    return 0.0;
                }
                wi.z.abs() * INV_PI
            }
            BaseLobe::Conductor {
                alpha,
                distribution,
                ..
            } => {
                if alpha < SMOOTH_ALPHA {
                    return 0.0;
                }
                let (wo, wi) = upper_pair(wo, wi);
                let mf = Microfacet::new(distribution, alpha);
                rough_reflection(&mf, wo, wi).map_or(0.0, |r| r.pdf)
            }
        }
    }

    fn sample(&self, wo: Vec3, uc: f32, u: Vec2) -> Option<BsdfSample> {
        if !(wo.z.abs() >= COS_EPSILON) || !wo.is_finite() {
            return None;
        }
        match *self {
            BaseLobe::Dielectric {
                eta,
                alpha,
                distribution,
                tint,
                reflect_floor,
            } => {
                if eta == 1.0 {
                    // Index-matched boundary: straight pass-through.
                    return Some(BsdfSample {
                        wi: -wo,
                        weight: tint,
                        pdf: 1.0,
                        is_delta: true,
                        is_transmission: true,
                        eta: 1.0,
                    });
                }
                if alpha < SMOOTH_ALPHA {
                    return sample_smooth_dielectric(eta, tint, reflect_floor, wo, uc);
                }
                let mf = Microfacet::new(distribution, alpha);
                let wm = mf.sample_visible(wo, u);
                let wo_m = wo.dot(wm);
                if !(wo_m * wo.z > 0.0) {
                    return None;
                }
                let f = fresnel_dielectric(wo_m, eta);
                let wi = if uc < reflect_probability(f, reflect_floor, wo.z) {
                    let wi = crate::math::reflect(wo, wm);
                    if !(wi.z * wo.z > 0.0) {
                        return None;
                    }
                    wi
                } else {
                    let (n, etap) = if wo_m > 0.0 {
                        (wm, eta)
                    } else {
                        (-wm, 1.0 / eta)
                    };
                    let wi = refract(wo, n, etap)?;
                    if !(wi.z * wo.z < 0.0) {
                        return None;
                    }
                    wi
                };
                let wi = wi.try_normalize()?;
                // Recompute f and pdf from (wo, wi) exactly as eval/pdf do (MIS consistency).
                let h = dielectric_half(wo, wi, eta)?;
                let (fv, pdf) = dielectric_f_pdf(&mf, tint, eta, reflect_floor, wo, wi, &h);
                continuous_sample(wo, wi, fv, pdf, h.etap)
            }
            BaseLobe::DiffuseTransmission {
                reflectance,
                transmittance,
            } => {
                let pr = diffuse_reflect_prob(reflectance, transmittance);
                if reflectance.is_black() && transmittance.is_black() {
                    return None;
                }
                let local = sample_cosine_hemisphere(u);
                let same_side = uc < pr;
                let up = (wo.z > 0.0) == same_side;
                let wi = if up { local } else { flip_z(local) };
                if !(wi.z.abs() >= COS_EPSILON) {
                    return None;
                }
                let (value, prob) = if same_side {
                    (reflectance, pr)
                } else {
                    (transmittance, 1.0 - pr)
                };
                if !(prob > 0.0) {
                    return None;
                }
                Some(BsdfSample {
                    wi,
                    weight: finite_rgb(value / prob),
                    pdf: prob * wi.z.abs() * INV_PI,
                    is_delta: false,
                    is_transmission: !same_side,
                    eta: 1.0,
                })
            }
            BaseLobe::Lambertian { albedo } => {
                let local = sample_cosine_hemisphere(u);
                let wi = if wo.z > 0.0 { local } else { flip_z(local) };
                if !(wi.z.abs() >= COS_EPSILON) {
                    return None;
                }
                Some(BsdfSample {
                    wi,
                    weight: albedo,
                    pdf: wi.z.abs() * INV_PI,
                    is_delta: false,
                    is_transmission: false,
                    eta: 1.0,
                })
            }
            BaseLobe::Conductor {
                eta,
                k,
                alpha,
                distribution,
            } => {
                let below = wo.z < 0.0;
                let wo_up = if below { flip_z(wo) } else { wo };
                let unflip = |w: Vec3| if below { flip_z(w) } else { w };
                if alpha < SMOOTH_ALPHA {
                    return Some(BsdfSample {
                        wi: unflip(mirror_z(wo_up)),
                        weight: fresnel_conductor(wo_up.z, eta, k),
                        pdf: 1.0,
                        is_delta: true,
                        is_transmission: false,
                        eta: 1.0,
                    });
                }
                let mf = Microfacet::new(distribution, alpha);
                let wm = mf.sample_visible(wo_up, u);
                let wo_m = wo_up.dot(wm);
                if !(wo_m > 0.0) {
                    return None;
                }
                let wi = crate::math::reflect(wo_up, wm).try_normalize()?;
                if !(wi.z >= COS_EPSILON) {
                    return None;
                }
                let pdf = self.pdf(wo_up, wi);
                if !(pdf > 0.0) {
                    return None;
                }
                // f cos/pdf = F G2/G1 (D and the Jacobian cancel).
                let weight = fresnel_conductor(wo_m, eta, k)
                    * finite_or_zero(mf.g2(wo_up, wi) / mf.g1(wo_up));
                Some(BsdfSample {
                    wi: unflip(wi),
                    weight: finite_rgb(weight),
                    pdf,
                    is_delta: false,
                    is_transmission: false,
                    eta: 1.0,
                })
            }
        }
    }

    fn albedo_hint(&self) -> Rgb {
        match *self {
            BaseLobe::Dielectric { tint, .. } => tint,
            BaseLobe::DiffuseTransmission {
                reflectance,
                transmittance,
            } => reflectance + transmittance,
            BaseLobe::Lambertian { albedo } => albedo,
            BaseLobe::Conductor { eta, k, .. } => fresnel_conductor(1.0, eta, k),
        }
    }
}

/// Probability of choosing the reflection side of diffuse transmission: R̄/(R̄ + T̄).
fn diffuse_reflect_prob(r: Rgb, t: Rgb) -> f32 {
    let (ra, ta) = (r.average(), t.average());
    if ra + ta > 0.0 {
        ra / (ra + ta)
    } else {
        0.5
    }
}

/// Smooth (delta) dielectric: reflect with probability q = [`reflect_probability`] (F when
/// `floor` is 0), refract otherwise; weights F/q and (1 − F)/(1 − q) (the latter × tint/η'²,
/// radiance mode): f/pdf = 1 at `floor` 0.
fn sample_smooth_dielectric(
    eta: f32,
    tint: Rgb,
    floor: f32,
    wo: Vec3,
    uc: f32,
) -> Option<BsdfSample> {
    let f = fresnel_dielectric(wo.z, eta);
    let q = reflect_probability(f, floor, wo.z);
    if uc < q {
        return Some(BsdfSample {
            wi: mirror_z(wo),
            weight: if q == f {
                Rgb::ONE
            } else {
                Rgb::splat(finite_or_zero(f / q))
            },
            pdf: q,
            is_delta: true,
            is_transmission: false,
            eta: 1.0,
        });
    }
    let (n, etap) = if wo.z > 0.0 {
        (Vec3::Z, eta)
    } else {
        (-Vec3::Z, 1.0 / eta)
    };
    match refract(wo, n, etap).and_then(|w| w.try_normalize()) {
        Some(wi) if wi.z * wo.z < 0.0 => Some(BsdfSample {
            wi,
            weight: if q == f {
                finite_rgb(tint / (etap * etap))
            } else {
                finite_rgb(tint * ((1.0 - f) / ((1.0 - q) * etap * etap)))
            },
            pdf: 1.0 - q,
            is_delta: true,
            is_transmission: true,
            eta: etap,
        }),
        _ => Some(BsdfSample {
            wi: mirror_z(wo),
            weight: Rgb::ONE,
            pdf: 1.0,
            is_delta: true,
            is_transmission: false,
            eta: 1.0,
        }),
    }
}

impl Coat {
    /// A coat of relative index `ior` (≥ 1) and `roughness` in [0, 1] (α = roughness², smooth
    /// below α = 1e-3) at weight 1, its directional albedo `E_c(μ)` tabulated here by
    /// quadrature (32 cosines, 24² visible-normal samples each). Errors on parameters out of
    /// range.
    pub fn new(ior: f32, roughness: f32) -> Result<Coat, BsdfError> {
        if ior.is_nan() {
            return Err(invalid("coat ior", ior, "is NaN"));
        }
        if !(ior >= 1.0) || !ior.is_finite() {
            return Err(invalid("coat ior", ior, "must be finite and >= 1"));
        }
        check_unit("coat roughness", roughness)?;
        let mut coat = Coat {
            ior,
            alpha: roughness * roughness,
            weight: 1.0,
            albedo_table: [0.0; COAT_TABLE_SIZE],
        };
        if !coat.is_smooth() {
            coat.tabulate();
        }
        Ok(coat)
    }

    fn is_smooth(&self) -> bool {
        self.alpha < SMOOTH_ALPHA
    }

    fn mf(&self) -> Microfacet {
        Microfacet::new(MicrofacetDistribution::Ggx, self.alpha)
    }

    /// Coat BRDF (without weight); zero unless both directions are outside; zero if smooth.
    fn eval(&self, wo: Vec3, wi: Vec3) -> f32 {
        if self.is_smooth() {
            return 0.0;
        }
        rough_reflection(&self.mf(), wo, wi).map_or(0.0, |r| {
            finite_or_zero(fresnel_dielectric(r.wo_m, self.ior) * r.brdf)
        })
    }

    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if self.is_smooth() {
            return 0.0;
        }
        rough_reflection(&self.mf(), wo, wi).map_or(0.0, |r| r.pdf)
    }

    /// Directional albedo E_c(μ) of the unweighted coat, interpolated from the table.
    fn albedo(&self, mu: f32) -> f32 {
        if self.is_smooth() {
            return fresnel_dielectric(mu.clamp(0.0, 1.0), self.ior);
        }
        let x = mu.clamp(0.0, 1.0) * (COAT_TABLE_SIZE - 1) as f32;
        let i = (x as usize).min(COAT_TABLE_SIZE - 2);
        let t = x - i as f32;
        self.albedo_table[i] * (1.0 - t) + self.albedo_table[i + 1] * t
    }

    /// Base attenuation for one direction: 1 - weight·E_c(μ) outside, 1 inside.
    fn attenuation(&self, w: Vec3) -> f32 {
        if w.z > 0.0 {
            (1.0 - self.weight * self.albedo(w.z)).clamp(0.0, 1.0)
        } else {
            1.0
        }
    }

    /// Tabulates E_c(μ) = ∫ f_c cos θ_i dω_i by stratified visible-normal quadrature:
    /// E_c = E_{m ~ D_wo}[F(wo·m) G2/G1 · 1(wi above)].
    fn tabulate(&mut self) {
        let mf = self.mf();
        for j in 0..COAT_TABLE_SIZE {
            let mu = (j as f32 / (COAT_TABLE_SIZE - 1) as f32).max(1e-3);
            let wo = Vec3::new((1.0 - mu * mu).max(0.0).sqrt(), 0.0, mu);
            let mut sum = 0.0f64;
            let n = COAT_TABLE_STRATA;
            for a in 0..n {
                for b in 0..n {
                    let u = Vec2::new((a as f32 + 0.5) / n as f32, (b as f32 + 0.5) / n as f32);
                    let wm = mf.sample_visible(wo, u);
                    let wi = crate::math::reflect(wo, wm);
                    if wi.z > 0.0 {
                        let v =
                            fresnel_dielectric(wo.dot(wm), self.ior) * mf.g2(wo, wi) / mf.g1(wo);
                        sum += finite_or_zero(v) as f64;
                    }
                }
            }
            self.albedo_table[j] = ((sum / (n * n) as f64) as f32).clamp(0.0, 1.0);
        }
    }
}

impl Surface {
    /// A dielectric interface (docs/references.md §3.1–§3.8).
    ///
    /// * `eta = n_inside / n_outside` for the two media meeting at this boundary (may be < 1
    ///   for nested media); must be finite and > 0. `eta == 1` exactly is an index-matched
    ///   pass-through (delta transmission with weight `tint`).
    /// * `roughness` in [0, 1]; `α = roughness²`; below α = 1e-3 the interface is smooth
    ///   (delta lobes, reflect with probability F, refract with 1 − F).
    /// * `tint` in [0, 1] per channel multiplies transmission only.
    pub fn dielectric(
        eta: f32,
        roughness: f32,
        distribution: MicrofacetDistribution,
        tint: Rgb,
    ) -> Result<Surface, BsdfError> {
        // Built at every boundary hit: one branch-free test of all five parameters (NaN fails
        // every comparison), the error found out of line.
        let valid = (eta > 0.0) & (eta < f32::INFINITY) & in_unit(roughness) & rgb_in_unit(tint);
        if !valid {
            dielectric_error(eta, roughness, tint)?;
        }
        let alpha = roughness * roughness;
        Ok(Surface {
            base: BaseLobe::Dielectric {
                eta,
                alpha,
                distribution,
                tint,
                reflect_floor: 0.0,
            },
            coat: None,
        })
    }

    /// Diffuse transmission `T/π` (opposite side) plus diffuse reflection `R/π` (same side)
    /// (docs/references.md §3.9). Each channel of R and T in [0, 1] with R + T ≤ 1.
    pub fn diffuse_transmission(
        reflectance: Rgb,
        transmittance: Rgb,
    ) -> Result<Surface, BsdfError> {
        check_rgb_unit("reflectance", reflectance)?;
        check_rgb_unit("transmittance", transmittance)?;
        for i in 0..3 {
            let s = reflectance[i] + transmittance[i];
            if s > 1.0 + 1e-6 {
                return Err(invalid(
                    format!("reflectance + transmittance (channel {i})"),
                    s,
                    "must be <= 1 (energy conservation)",
                ));
            }
        }
        Ok(Surface {
            base: BaseLobe::DiffuseTransmission {
                reflectance,
                transmittance,
            },
            coat: None,
        })
    }

    /// Two-sided Lambertian reflector; `albedo` in [0, 1] per channel.
    pub fn lambertian(albedo: Rgb) -> Result<Surface, BsdfError> {
        check_rgb_unit("albedo", albedo)?;
        Ok(Surface {
            base: BaseLobe::Lambertian { albedo },
            coat: None,
        })
    }

    /// Two-sided rough conductor with complex relative IOR `eta + i k` per channel (complex
    /// Fresnel, Born & Wolf §14.2). `eta > 0`, `k >= 0`, finite; `roughness` in [0, 1],
    /// `α = roughness²`, smooth (delta mirror) below α = 1e-3.
    pub fn conductor(
        eta: Rgb,
        k: Rgb,
        roughness: f32,
        distribution: MicrofacetDistribution,
    ) -> Result<Surface, BsdfError> {
        for (i, ch) in ["r", "g", "b"].iter().enumerate() {
            if !(eta[i] > 0.0) || !eta[i].is_finite() {
                check_positive(&format!("eta.{ch}"), eta[i])?;
            }
            let kv = k[i];
            if kv.is_nan() {
                return Err(invalid(format!("k.{ch}"), kv, "is NaN"));
            }
            if !(kv >= 0.0) || !kv.is_finite() {
                return Err(invalid(format!("k.{ch}"), kv, "must be finite and >= 0"));
            }
        }
        check_unit("roughness", roughness)?;
        let alpha = roughness * roughness;
        Ok(Surface {
            base: BaseLobe::Conductor {
                eta,
                k,
                alpha,
                distribution,
            },
            coat: None,
        })
    }

    /// A rough GGX conductor whose normal-incidence reflectance is `reflectance` (in [0, 1]
    /// per channel; values above 0.999 are treated as 0.999). The complex IOR comes from
    /// Gulbrandsen 2014 with the edge tint set equal to the reflectance.
    pub fn conductor_from_reflectance(
        reflectance: Rgb,
        roughness: f32,
    ) -> Result<Surface, BsdfError> {
        Surface::conductor_from_reflectance_with(
            reflectance,
            roughness,
            MicrofacetDistribution::Ggx,
        )
    }

    /// [`Surface::conductor_from_reflectance`] with a chosen microfacet distribution.
    pub fn conductor_from_reflectance_with(
        reflectance: Rgb,
        roughness: f32,
        distribution: MicrofacetDistribution,
    ) -> Result<Surface, BsdfError> {
        check_rgb_unit("reflectance", reflectance)?;
        let mut eta = Rgb::ZERO;
        let mut k = Rgb::ZERO;
        for i in 0..3 {
            let (n, kk) = gulbrandsen_eta_k(reflectance[i], reflectance[i]);
            eta[i] = n.max(1e-4);
            k[i] = kk;
        }
        Surface::conductor(eta, k, roughness, distribution)
    }

    /// Sets a dielectric's reflection floor: its sampling picks reflection with probability
    /// max(F, `floor`) for a direction arriving from outside instead of F (from inside, F as
    /// before), and weights the two branches by F/q and (1 − F)/(1 − q). The BSDF (`eval`)
    /// is unchanged and `pdf` follows the sampling, so estimates stay unbiased and MIS stays
    /// consistent. `floor` in [0, [`MAX_REFLECT_FLOOR`]]; other lobes are returned unchanged.
    /// Pays where the reflection is bright and cheap to follow (the sky over water) beside
    /// what a transmitted path costs (docs/choosing-estimators.md, "Reflection floor").
    pub fn with_reflect_floor(mut self, floor: f32) -> Result<Surface, BsdfError> {
        if !(0.0..=MAX_REFLECT_FLOOR).contains(&floor) {
            return Err(invalid(
                "min_reflect_probability",
                floor,
                "must be in [0, 0.95]",
            ));
        }
        if let BaseLobe::Dielectric { reflect_floor, .. } = &mut self.base {
            *reflect_floor = floor;
        }
        Ok(self)
    }

    /// Adds a secondary specular coat: a GGX reflection lobe with dielectric Fresnel of
    /// relative index `ior` (≥ 1), `roughness` in [0, 1] (α = roughness², delta below
    /// α = 1e-3) and `weight` in [0, 1]; replaces any previous coat.
    ///
    /// Layering approximation: `f = w f_c + a(wo) a(wi) f_base` with `a(w) = 1 − w E_c(w.z)`
    /// for a direction outside the object and `a = 1` inside, where `E_c(μ)` is the coat's
    /// directional albedo (tabulated here by quadrature, exact Fresnel for a smooth coat).
    /// Reciprocal, and the albedo from outside is at most `w E_c + (1 − w E_c)·1 ≤ 1`; light
    /// bouncing between coat and base is ignored (slight darkening). Sampling picks the coat
    /// with probability `w E_c(μ_o) / (w E_c(μ_o) + a(wo) · base albedo estimate)`.
    pub fn with_coat(self, ior: f32, roughness: f32, weight: f32) -> Result<Surface, BsdfError> {
        let coat = Coat::new(ior, roughness)?;
        self.with_prepared_coat(&coat, weight)
    }

    /// [`Surface::with_coat`] with a coat built beforehand by [`Coat::new`] (its albedo table is
    /// tabulated once there), at `weight` in [0, 1]. Surfaces built at every hit (textured
    /// parameters, dielectrics whose relative index depends on the neighbouring media) use
    /// this so that the quadrature is not repeated per hit.
    pub fn with_prepared_coat(self, coat: &Coat, weight: f32) -> Result<Surface, BsdfError> {
        check_unit("coat weight", weight)?;
        let mut coat = coat.clone();
        coat.weight = weight;
        Ok(Surface {
            base: self.base,
            coat: Some(coat),
        })
    }

    /// The base lobe (read-only).
    #[must_use]
    pub fn base(&self) -> &BaseLobe {
        &self.base
    }

    /// The coat, if any (read-only).
    #[must_use]
    pub fn coat(&self) -> Option<&Coat> {
        self.coat.as_ref()
    }

    /// Probability of sampling the coat for this `wo`.
    fn coat_probability(&self, wo: Vec3) -> f32 {
        match &self.coat {
            Some(c) if wo.z > 0.0 && c.weight > 0.0 => {
                let pc = c.weight * c.albedo(wo.z);
                let pb = c.attenuation(wo) * self.base.sampling_weight();
                if pc + pb > 0.0 {
                    finite_or_zero(pc / (pc + pb))
                } else {
                    0.0
                }
            }
            _ => 0.0,
        }
    }

    /// BSDF value `f(wo, wi)` in 1/sr, without the cosine, radiance transport mode; zero for
    /// delta lobes. Never NaN or infinite.
    #[must_use]
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        if !wo.is_finite() || !wi.is_finite() {
            return Rgb::ZERO;
        }
        let base = self.base.eval(wo, wi);
        match &self.coat {
            None => base,
            Some(c) => {
                let att = c.attenuation(wo) * c.attenuation(wi);
                finite_rgb(base * att + Rgb::splat(c.weight * c.eval(wo, wi)))
            }
        }
    }

    /// Solid-angle pdf with which [`Surface::sample`] produces `wi` from `wo` through its
    /// non-delta lobes (matches the `pdf` of non-delta samples, for MIS). Zero for delta lobes.
    #[must_use]
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if !wo.is_finite() || !wi.is_finite() {
            return 0.0;
        }
        let pb = self.base.pdf(wo, wi);
        match &self.coat {
            None => pb,
            Some(c) => {
                let pc = self.coat_probability(wo);
                finite_or_zero(pc * c.pdf(wo, wi) + (1.0 - pc) * pb)
            }
        }
    }

    /// Samples `wi` given `wo`; `uc` (lobe choice) and `u` uniform in [0, 1). Returns `None`
    /// when the sample is absorbed, grazing or invalid. Non-delta samples carry the full
    /// mixture pdf and `weight = eval·|cos θ_i|/pdf`.
    #[must_use]
    pub fn sample(&self, wo: Vec3, uc: f32, u: Vec2) -> Option<BsdfSample> {
        if !wo.is_finite() || !uc.is_finite() || !u.is_finite() {
            return None;
        }
        let uc = uc.clamp(0.0, ONE_MINUS_EPSILON);
        let u = u.clamp(Vec2::ZERO, Vec2::splat(ONE_MINUS_EPSILON));
        let Some(coat) = &self.coat else {
            return self.base.sample(wo, uc, u);
        };
        let pc = self.coat_probability(wo);
        if uc < pc {
            if !(wo.z >= COS_EPSILON) {
                return None;
            }
            if coat.is_smooth() {
                let f = coat.weight * fresnel_dielectric(wo.z, coat.ior);
                return Some(BsdfSample {
                    wi: mirror_z(wo),
                    weight: Rgb::splat(finite_or_zero(f / pc)),
                    pdf: pc,
                    is_delta: true,
                    is_transmission: false,
                    eta: 1.0,
                });
            }
            let mf = coat.mf();
            let wm = mf.sample_visible(wo, u);
            let wi = crate::math::reflect(wo, wm).try_normalize()?;
            if !(wi.z >= COS_EPSILON) {
                return None;
            }
            return continuous_sample(wo, wi, self.eval(wo, wi), self.pdf(wo, wi), 1.0);
        }
        let ucb = if pc > 0.0 {
            ((uc - pc) / (1.0 - pc)).clamp(0.0, ONE_MINUS_EPSILON)
        } else {
            uc
        };
        let s = self.base.sample(wo, ucb, u)?;
        if s.is_delta {
            let att = coat.attenuation(wo) * coat.attenuation(s.wi);
            return Some(BsdfSample {
                weight: finite_rgb(s.weight * (att / (1.0 - pc))),
                pdf: s.pdf * (1.0 - pc),
                ..s
            });
        }
        continuous_sample(wo, s.wi, self.eval(wo, s.wi), self.pdf(wo, s.wi), s.eta)
    }

    /// True when every lobe is a delta lobe (smooth dielectric, index-matched pass-through,
    /// smooth conductor, with no rough coat): such a surface needs no light sampling or MIS.
    #[must_use]
    pub fn is_delta(&self) -> bool {
        self.base.is_delta()
            && self
                .coat
                .as_ref()
                .is_none_or(|c| c.is_smooth() || c.weight == 0.0)
    }

    /// True when light can pass through the surface (dielectrics, diffuse transmission with
    /// non-zero T).
    #[must_use]
    pub fn has_transmission(&self) -> bool {
        match self.base {
            BaseLobe::Dielectric { .. } => true,
            BaseLobe::DiffuseTransmission { transmittance, .. } => !transmittance.is_black(),
            BaseLobe::Lambertian { .. } | BaseLobe::Conductor { .. } => false,
        }
    }

    /// A representative colour for the film's albedo AOV: the dielectric tint, R + T of
    /// diffuse transmission, the Lambertian albedo, or the conductor's normal-incidence
    /// reflectance (the coat is ignored).
    #[must_use]
    pub fn albedo_hint(&self) -> Rgb {
        self.base.albedo_hint()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const GGX: MicrofacetDistribution = MicrofacetDistribution::Ggx;

    fn error_of(eta: f32, roughness: f32, tint: Rgb) -> Option<(String, u32, &'static str)> {
        match Surface::dielectric(eta, roughness, GGX, tint) {
            Ok(_) => None,
            Err(BsdfError::InvalidParameter {
                param,
                value,
                problem,
            }) => Some((param, value.to_bits(), problem)),
        }
    }

    #[test]
    fn dielectric_accepts_the_edges_of_its_ranges() {
        for (eta, r, tint) in [
            (1.5, 0.0, Rgb::ZERO),
            (1.5, 1.0, Rgb::ONE),
            (f32::MAX, -0.0, Rgb::new(-0.0, 0.5, 1.0)),
            (f32::from_bits(1), 0.5, Rgb::new(1.0, 0.0, -0.0)),
        ] {
            assert_eq!(error_of(eta, r, tint), None, "{eta} {r} {tint:?}");
        }
    }

    #[test]
    fn dielectric_errors_name_the_first_bad_parameter() {
        let nan = f32::NAN;
        let e = |p: &str, v: f32, m: &'static str| Some((p.to_string(), v.to_bits(), m));
        let pos = "must be finite and > 0";
        let unit = "must be in [0, 1]";
        assert_eq!(error_of(nan, 0.5, Rgb::ONE), e("eta", nan, "is NaN"));
        assert_eq!(error_of(0.0, 0.5, Rgb::ONE), e("eta", 0.0, pos));
        assert_eq!(error_of(-0.0, 0.5, Rgb::ONE), e("eta", -0.0, pos));
        assert_eq!(
            error_of(f32::INFINITY, 0.5, Rgb::ONE),
            e("eta", f32::INFINITY, pos)
        );
        // The first failing check wins, in the order eta, roughness, tint.
        assert_eq!(error_of(-1.0, 2.0, Rgb::splat(nan)), e("eta", -1.0, pos));
        assert_eq!(
            error_of(1.5, nan, Rgb::splat(2.0)),
            e("roughness", nan, "is NaN")
        );
        assert_eq!(
            error_of(1.5, 1.0001, Rgb::ONE),
            e("roughness", 1.0001, unit)
        );
        assert_eq!(
            error_of(1.5, -1e-30, Rgb::ONE),
            e("roughness", -1e-30, unit)
        );
        let tint = Rgb::new(0.5, 1.5, nan);
        assert_eq!(error_of(1.5, 0.5, tint), e("tint.g", 1.5, unit));
        let tint = Rgb::new(0.5, 1.0, nan);
        assert_eq!(error_of(1.5, 0.5, tint), e("tint.b", nan, "is NaN"));
        let tint = Rgb::new(-0.5, 1.0, 0.0);
        assert_eq!(error_of(1.5, 0.5, tint), e("tint.r", -0.5, unit));
    }

    /// A small deterministic generator of uniform numbers in [0, 1).
    struct Lcg(u64);
    impl Lcg {
        fn next(&mut self) -> f32 {
            self.0 = self
                .0
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (self.0 >> 40) as f32 / (1u64 << 24) as f32
        }
        fn dir(&mut self) -> Vec3 {
            let z = 2.0 * self.next() - 1.0;
            let phi = 2.0 * std::f32::consts::PI * self.next();
            let s = (1.0 - z * z).max(0.0).sqrt();
            Vec3::new(s * phi.cos(), s * phi.sin(), z)
        }
    }

    #[test]
    fn dielectric_f_pdf_has_the_bits_of_f_and_pdf_apart() {
        let mut rng = Lcg(27);
        let tint = Rgb::new(0.9, 0.6, 0.3);
        let mut checked = 0;
        for distribution in [GGX, MicrofacetDistribution::Beckmann] {
            for alpha in [0.002, 0.05, 0.3, 0.8, 1.0] {
                let mf = Microfacet::new(distribution, alpha);
                for (eta, floor) in [(1.33, 0.0), (1.0 / 1.33, 0.0), (1.5, 0.4), (2.4, 0.95)] {
                    for _ in 0..400 {
                        let (wo, wi) = (rng.dir(), rng.dir());
                        let Some(h) = dielectric_half(wo, wi, eta) else {
                            continue;
                        };
                        let (f, pdf) = dielectric_f_pdf(&mf, tint, eta, floor, wo, wi, &h);
                        let f_apart = dielectric_f(&mf, tint, eta, wo, wi, &h);
                        let pdf_apart = dielectric_pdf(&mf, eta, floor, wo, &h);
                        for c in 0..3 {
                            assert_eq!(f[c].to_bits(), f_apart[c].to_bits(), "{wo:?} {wi:?}");
                        }
                        assert_eq!(pdf.to_bits(), pdf_apart.to_bits(), "{wo:?} {wi:?}");
                        checked += usize::from(pdf > 0.0);
                    }
                }
            }
        }
        assert!(checked > 5000, "only {checked} pairs with a positive pdf");
    }
}
