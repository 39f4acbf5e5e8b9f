//! `absorption` and `homogeneous` interiors: constant coefficients everywhere inside, or,
//! with textured parameters, constant along each walk and read at its entry point
//! (`projection = "entry"`, docs/textures.md), or read at the boundary point closest to
//! every lookup (`projection = "surface"`: a tracked [`ProjectedMedium`]).

use super::scattering::Scattering;
use super::{textured_extinction_and_nee, BuiltInterior, Placement, Projection, Site};
use crate::math::Vec2;
use crate::medium::{EntryInterior, HomogeneousMedium, Medium, ProjectedMedium, WalkInterior};
use crate::phase::PhaseFunction;
use crate::scene::desc::{AbsorptionDesc, HomogeneousDesc};
use crate::scene::SceneError;
use crate::spectrum::Rgb;
use crate::texture::ColorParam;

/// An interior with a textured parameter: resolved at each entry point; its stand-in is the
/// medium of the textures' means.
fn entry(e: EntryInterior, nee: crate::medium::NeeStrategy) -> BuiltInterior {
    let mean = e.at(Vec2::ZERO, f32::INFINITY);
    let walk = WalkInterior::Entry(e);
    BuiltInterior {
        // An entry interior always resolves to a medium of its own.
        medium: walk
            .medium_of(mean)
            .unwrap_or(Medium::Absorbing { sigma_a: Rgb::ZERO }),
        nee,
        walk: Some(walk),
    }
}

/// A textured interior read at the closest point of the object's mesh (`projection =
/// "surface"`): the rest mesh placed in the world, prepared for closest-point queries.
fn projected(
    at: &Site,
    e: EntryInterior,
    nee: crate::medium::NeeStrategy,
    placement: &Placement<'_>,
) -> Result<BuiltInterior, SceneError> {
    let boundary = at.surface_boundary(placement)?;
    let medium = ProjectedMedium::new(e, boundary);
    if !medium.majorant().is_finite() {
        return Err(at.invalid(format!(
            "{}: density/attenuation gives a non-finite extinction",
            at.owner
        )));
    }
    Ok(BuiltInterior {
        medium: Medium::Projected(Box::new(medium)),
        nee,
        walk: None,
    })
}

/// The built interior of textured parameters `e`: per walk (`"entry"`) or projected
/// (`"surface"`).
fn textured(
    at: &Site,
    e: EntryInterior,
    nee: crate::medium::NeeStrategy,
    projection: Projection,
    placement: &Placement<'_>,
) -> Result<BuiltInterior, SceneError> {
    match projection {
        Projection::Entry => Ok(entry(e, nee)),
        Projection::Surface => projected(at, e, nee, placement),
    }
}

/// Coloured glass: σ_a = density / attenuation per channel (0 for an infinite distance).
pub(super) fn absorption(
    at: &Site,
    d: &AbsorptionDesc,
    placement: &Placement<'_>,
) -> Result<BuiltInterior, SceneError> {
    let projection = at.projection(d.projection.as_deref(), placement)?;
    let (density, attenuation, nee) = textured_extinction_and_nee(
        at,
        d.density.as_ref(),
        d.attenuation.as_ref(),
        d.nee.as_deref(),
    )?;
    if density.is_textured() || attenuation.is_textured() {
        let e = EntryInterior {
            albedo: ColorParam::Constant(Rgb::ZERO),
            attenuation,
            density,
            mode: crate::medium::AlbedoMode::SingleScattering,
            phase: PhaseFunction::henyey_greenstein(0.0).map_err(|e| at.failed(&e))?,
            absorbing: true,
        };
        return textured(at, e, nee, projection, placement);
    }
    let (density, attenuation) = (density.max(), attenuation.max());
    let sigma_a = attenuation.map(|d| if d.is_infinite() { 0.0 } else { density / d });
    Ok(BuiltInterior {
        medium: Medium::Absorbing { sigma_a },
        nee,
        walk: None,
    })
}

/// A scattering medium of constant density: σ_t = density / attenuation, the albedo inverted
/// into σ_s (course notes eq. 1–3).
pub(super) fn homogeneous(
    at: &Site,
    d: &HomogeneousDesc,
    placement: &Placement<'_>,
) -> Result<BuiltInterior, SceneError> {
    let projection = at.projection(d.projection.as_deref(), placement)?;
    let (density, attenuation, nee) = textured_extinction_and_nee(
        at,
        d.density.as_ref(),
        d.attenuation.as_ref(),
        d.nee.as_deref(),
    )?;
    let scattering = Scattering::read(at, None, d.albedo_mode.as_deref(), d.phase.as_ref())?;
    let albedo = at
        .params()
        .colour("albedo", d.albedo.as_ref(), Rgb::splat(0.8), 0.0, 1.0)?;
    if density.is_textured() || attenuation.is_textured() || albedo.is_textured() {
        let e = EntryInterior {
            albedo,
            attenuation,
            density,
            mode: scattering.mode,
            phase: scattering.phase,
            absorbing: false,
        };
        return textured(at, e, nee, projection, placement);
    }
    let coefficients = scattering.coefficients_of(albedo.max(), attenuation.max(), density.max());
    if !coefficients.sigma_t().is_finite() {
        return Err(at.invalid(format!(
            "{}: density/attenuation gives a non-finite extinction",
            at.owner
        )));
    }
    Ok(BuiltInterior {
        medium: Medium::Homogeneous(HomogeneousMedium {
            coefficients,
            phase: scattering.phase,
        }),
        nee,
        walk: None,
    })
}
