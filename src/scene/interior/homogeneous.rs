//! `absorption` and `homogeneous` interiors: constant coefficients everywhere inside.

use super::scattering::Scattering;
use super::{extinction_and_nee, Site};
use crate::medium::{HomogeneousMedium, Medium, NeeStrategy};
use crate::scene::desc::{AbsorptionDesc, HomogeneousDesc};
use crate::scene::SceneError;

/// Coloured glass: σ_a = density / attenuation per channel (0 for an infinite distance).
pub(super) fn absorption(
    at: &Site,
    d: &AbsorptionDesc,
) -> Result<(Medium, NeeStrategy), SceneError> {
    let (density, attenuation, nee) =
        extinction_and_nee(at, d.density, d.attenuation, d.nee.as_deref())?;
    let sigma_a = attenuation.map(|d| if d.is_infinite() { 0.0 } else { density / d });
    Ok((Medium::Absorbing { sigma_a }, nee))
}

/// A scattering medium of constant density: σ_t = density / attenuation, the albedo inverted
/// into σ_s (course notes eq. 1–3).
pub(super) fn homogeneous(
    at: &Site,
    d: &HomogeneousDesc,
) -> Result<(Medium, NeeStrategy), SceneError> {
    let (density, attenuation, nee) =
        extinction_and_nee(at, d.density, d.attenuation, d.nee.as_deref())?;
    let scattering = Scattering::read(at, d.albedo, d.albedo_mode.as_deref(), d.phase.as_ref())?;
    let coefficients = scattering.coefficients(attenuation, density);
    if !coefficients.sigma_t().is_finite() {
        return Err(at.invalid(format!(
            "{}: density/attenuation gives a non-finite extinction",
            at.owner
        )));
    }
    Ok((
        Medium::Homogeneous(HomogeneousMedium {
            coefficients,
            phase: scattering.phase,
        }),
        nee,
    ))
}
