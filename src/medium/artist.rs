//! The artist's parameterisation of an interior (course notes §2.4.2, eq. 1–3):
//! `attenuation` is a distance per RGB channel (σ_t = density / attenuation) and `albedo` is
//! the colour the artist wants the medium to be. By default the albedo is read as the
//! *multiple-scattering* albedo and inverted to the single-scattering albedo with the van de
//! Hulst relation as used by Chiang, Kutz and Burley 2016 and Wrenninge et al. 2017
//! (docs/references.md §1.3–1.4), which contains the similarity relation for anisotropic
//! phase functions. `albedo_mode = "single"` uses the albedo as σ_s/σ_t.

use crate::spectrum::Rgb;

/// How the artist's albedo maps to the single-scattering albedo σ_s/σ_t.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AlbedoMode {
    /// The albedo is the multiple-scattering (diffuse-illumination) albedo of a semi-infinite
    /// medium: inverted with van de Hulst's relation (docs/references.md §1.3).
    MultipleScattering,
    /// The albedo is the single-scattering albedo σ_s/σ_t itself.
    SingleScattering,
}

/// The largest single-scattering albedo velour uses (docs/references.md §8: albedo → 1 makes walks of
/// ~1/(1−α) events; the clamp keeps them finite).
pub const MAX_SINGLE_SCATTERING_ALBEDO: f32 = 0.999_999;

/// van de Hulst's inversion: the single-scattering albedo of a semi-infinite index-matched
/// medium whose diffuse-illumination albedo is `a`, for mean cosine `g`
/// (docs/references.md §1.3: s(A) = 4.09712 + 4.20863 A − sqrt(9.59217 + 41.6808 A + 17.7126 A²),
/// α = (1 − s²)/(1 − g s²)).
#[must_use]
pub fn single_scattering_albedo_from_multiple(a: f32, g: f32) -> f32 {
    let a = a.clamp(0.0, 1.0) as f64;
    let g = g.clamp(-0.999, 0.999) as f64;
    let s = 4.09712 + 4.20863 * a - (9.59217 + 41.6808 * a + 17.7126 * a * a).sqrt();
    let s2 = s * s;
    let alpha = (1.0 - s2) / (1.0 - g * s2);
    (alpha as f32).clamp(0.0, MAX_SINGLE_SCATTERING_ALBEDO)
}

/// van de Hulst's forward relation A(α, g) = (1 − s)(1 − 0.139 s)/(1 + 1.17 s),
/// s = sqrt((1 − α)/(1 − g α)): the multiple-scattering albedo of a medium.
#[must_use]
pub fn multiple_scattering_albedo(alpha: f32, g: f32) -> f32 {
    let alpha = alpha.clamp(0.0, 1.0) as f64;
    let g = g.clamp(-0.999, 0.999) as f64;
    let s = ((1.0 - alpha) / (1.0 - g * alpha)).max(0.0).sqrt();
    ((1.0 - s) * (1.0 - 0.139 * s) / (1.0 + 1.17 * s)) as f32
}

/// Optical coefficients of a homogeneous region, per unit world length.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Coefficients {
    /// Absorption coefficient σ_a (1/length).
    pub sigma_a: Rgb,
    /// Scattering coefficient σ_s (1/length).
    pub sigma_s: Rgb,
}

impl Coefficients {
    /// Extinction σ_t = σ_a + σ_s.
    #[must_use]
    pub fn sigma_t(&self) -> Rgb {
        self.sigma_a + self.sigma_s
    }

    /// Coefficients from the artist's parameters (notes eq. 1–3 with a density multiplier):
    /// σ_t = density / attenuation, σ_s = α σ_t, σ_a = σ_t − σ_s, where α is `albedo` itself or
    /// its van de Hulst inversion (see [`AlbedoMode`]).
    #[must_use]
    pub fn from_artist(
        albedo: Rgb,
        attenuation: Rgb,
        density: f32,
        mode: AlbedoMode,
        g: f32,
    ) -> Self {
        let sigma_t = attenuation.map(|d| if d.is_infinite() { 0.0 } else { density / d });
        let alpha = match mode {
            AlbedoMode::MultipleScattering => {
                albedo.map(|a| single_scattering_albedo_from_multiple(a, g))
            }
            AlbedoMode::SingleScattering => {
                albedo.map(|a| a.clamp(0.0, MAX_SINGLE_SCATTERING_ALBEDO))
            }
        };
        let sigma_s = sigma_t * alpha;
        Coefficients {
            sigma_a: (sigma_t - sigma_s).clamp_zero(),
            sigma_s,
        }
    }
}
