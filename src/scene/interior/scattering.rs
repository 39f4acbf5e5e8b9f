//! The scattering keys of `homogeneous`, `voxel` and `fbm` interiors: the artist albedo, how
//! it is read (`albedo_mode`) and the phase function.

use super::Site;
use crate::medium::{AlbedoMode, Coefficients};
use crate::phase::PhaseFunction;
use crate::scene::desc::{ColorValue, PhaseDesc};
use crate::scene::validate::reject_unused;
use crate::scene::SceneError;
use crate::spectrum::Rgb;

/// How an interior scatters, as written.
pub(super) struct Scattering {
    /// Artist albedo in [0, 1].
    pub albedo: Rgb,
    /// Whether `albedo` is the multiple- or single-scattering albedo.
    pub mode: AlbedoMode,
    /// The phase function.
    pub phase: PhaseFunction,
}

impl Scattering {
    /// Reads `albedo` (default 0.8), `albedo_mode` (default "multiple") and `phase` (default
    /// isotropic).
    pub fn read(
        at: &Site,
        albedo: Option<ColorValue>,
        albedo_mode: Option<&str>,
        phase: Option<&PhaseDesc>,
    ) -> Result<Scattering, SceneError> {
        let albedo = at.unit_colour("albedo", albedo, Rgb::splat(0.8))?;
        let mode = match albedo_mode.unwrap_or("multiple") {
            "multiple" => AlbedoMode::MultipleScattering,
            "single" => AlbedoMode::SingleScattering,
            other => {
                return Err(at.invalid(format!(
                    "{}.albedo_mode = \"{other}\" is unknown (expected \"multiple\" or \"single\")",
                    at.owner
                )))
            }
        };
        let phase = build_phase(at, phase)?;
        Ok(Scattering {
            albedo,
            mode,
            phase,
        })
    }

    /// The coefficients of this albedo with `attenuation` distances at `density`.
    pub fn coefficients(&self, attenuation: Rgb, density: f32) -> Coefficients {
        self.coefficients_of(self.albedo, attenuation, density)
    }

    /// The coefficients of another albedo read the same way (mode, phase asymmetry).
    pub fn coefficients_of(&self, albedo: Rgb, attenuation: Rgb, density: f32) -> Coefficients {
        Coefficients::from_artist(
            albedo,
            attenuation,
            density,
            self.mode,
            self.phase.mean_cosine(),
        )
    }
}

/// The phase function of `phase = { ... }`: "hg" (default, g = 0) or "double_hg".
fn build_phase(at: &Site, p: Option<&PhaseDesc>) -> Result<PhaseFunction, SceneError> {
    let owner = format!("{}.phase", at.owner);
    let bad = |e: &dyn std::fmt::Display| at.invalid(format!("{owner}: {e}"));
    let Some(p) = p else {
        return PhaseFunction::henyey_greenstein(0.0).map_err(|e| bad(&e));
    };
    let lobe = |key: &str, v: Option<f32>, default: f32, min: f32| {
        at.range(&format!("phase.{key}"), v.unwrap_or(default), min, 1.0)
    };
    match p.kind.as_deref().unwrap_or("hg") {
        "hg" => {
            reject_unused(
                at.ctx,
                at.line,
                &owner,
                "hg",
                &[
                    ("g1", p.g1.is_some()),
                    ("g2", p.g2.is_some()),
                    ("w", p.w.is_some()),
                ],
            )?;
            let g = lobe("g", p.g, 0.0, -1.0)?;
            PhaseFunction::henyey_greenstein(g).map_err(|e| bad(&e))
        }
        "double_hg" => {
            reject_unused(
                at.ctx,
                at.line,
                &owner,
                "double_hg",
                &[("g", p.g.is_some())],
            )?;
            let g1 = lobe("g1", p.g1, 0.8, -1.0)?;
            let g2 = lobe("g2", p.g2, -0.3, -1.0)?;
            let w = lobe("w", p.w, 0.7, 0.0)?;
            PhaseFunction::double_henyey_greenstein(g1, g2, w).map_err(|e| bad(&e))
        }
        other => Err(at.invalid(format!(
            "{owner}.type = \"{other}\" is unknown (expected \"hg\" or \"double_hg\")"
        ))),
    }
}
