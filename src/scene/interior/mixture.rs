//! `mixture` interiors: two to four `homogeneous`, `voxel` or `fbm` media in one object
//! (clear water plus foam), each with its own albedo, attenuation, density source and phase
//! function; `tracking` and `nee` belong to the mixture (docs/references.md §15.1).
//! Components with textured parameters are read at each walk's entry point
//! (docs/textures.md, "Mixtures read at the entry point").

use std::sync::Arc;

use super::tracking::build_tracking;
use super::{build_medium, BuiltInterior, Placement, Site};
use crate::medium::{
    Coefficients, ComponentDensity, ComponentTextures, FieldTextures, Medium, MixtureComponent,
    MixtureMedium, NeeStrategy, ScaledMixture, TexturedMixture, WalkInterior,
};
use crate::phase::PhaseFunction;
use crate::scene::desc::{InteriorDesc, MixtureDesc, TrackingDesc};
use crate::scene::SceneError;
use crate::tracking::{FreeFlightMethod, TrackingConfig, MAX_COMPONENTS};

/// Refuses estimator choices a mixture does not have: its free flights are delta tracked (the
/// summed majorants, §15.1); shadow rays multiply the components' transmittances, each
/// estimated with `tracking.transmittance` (and `control`, `step`) over the `majorant` walk.
pub(super) fn check_mixture_tracking(
    at: &Site,
    t: Option<&TrackingDesc>,
) -> Result<TrackingConfig, SceneError> {
    let cfg = build_tracking(at, t)?;
    let owner = format!("{}.tracking", at.owner);
    if let Some(t) = t {
        if cfg.free_flight != FreeFlightMethod::DeltaTracking {
            return Err(at.invalid(format!(
                "{owner}.free_flight = \"{}\": media with several components or with albedo or emission grids are delta tracked only (expected \"delta\")",
                t.free_flight.as_deref().unwrap_or("delta")
            )));
        }
        if t.behind.is_some() {
            return Err(at.invalid(format!(
                "{owner}.behind does not apply to media with several components or with albedo or emission grids (their escaped paths survive or die)"
            )));
        }
        if t.local_bounds == Some(true) {
            return Err(at.invalid(format!(
                "{owner}.local_bounds does not apply to media with several components or with albedo or emission grids"
            )));
        }
    }
    Ok(cfg)
}

/// A component's own tracking configuration: the mixture's majorants and shadow-ray
/// estimator, no point bounds.
pub(super) fn component_tracking(mixture: TrackingConfig) -> TrackingConfig {
    TrackingConfig {
        majorant: mixture.majorant,
        transmittance: mixture.transmittance,
        local_bounds: false,
        ..TrackingConfig::default()
    }
}

/// The medium of a `mixture` interior.
pub(super) fn build(
    at: &Site,
    d: &MixtureDesc,
    placement: &Placement<'_>,
    media: &mut Vec<Medium>,
) -> Result<BuiltInterior, SceneError> {
    let owner = &at.owner;
    let n = d.media.len();
    if !(2..=MAX_COMPONENTS).contains(&n) {
        return Err(at.invalid(format!(
            "{owner}: a mixture needs 2 to {MAX_COMPONENTS} media (`media = [{{ type = \"homogeneous\", ... }}, {{ type = \"voxel\", ... }}]`); it has {n}"
        )));
    }
    let (_, _, nee) = super::extinction_and_nee(at, None, None, d.nee.as_deref())?;
    let cfg = check_mixture_tracking(at, d.tracking.as_ref())?;
    let mut components = Vec::with_capacity(n);
    let mut textures = Vec::with_capacity(n);
    for (i, entry) in d.media.iter().enumerate() {
        let line = at.ctx.line_of(entry.span().start);
        let inner = entry.get_ref();
        let inner_owner = format!("{owner}.media[{i}]");
        let bad = |m: String| at.ctx.invalid(line, format!("{inner_owner}: {m}"));
        let (tracking, base) = match inner {
            InteriorDesc::Homogeneous(_) => (false, false),
            InteriorDesc::Voxel(v) => (
                v.tracking.is_some(),
                v.base_albedo.is_some() || v.base_attenuation.is_some(),
            ),
            InteriorDesc::Fbm(f) => (
                f.tracking.is_some(),
                f.base_albedo.is_some() || f.base_attenuation.is_some(),
            ),
            other => {
                return Err(bad(format!(
                    "type \"{}\" cannot be a mixture component (expected \"homogeneous\", \"voxel\" or \"fbm\")",
                    other.kind()
                )))
            }
        };
        if inner.nee().is_some() {
            return Err(bad(
                "`nee` goes on the mixture itself (its media share it)".into()
            ));
        }
        if tracking {
            return Err(bad(
                "`tracking` goes on the mixture itself (its media are tracked together)".into(),
            ));
        }
        if base {
            return Err(bad("`base_albedo`/`base_attenuation` inside a mixture: write the homogeneous medium as another entry of `media`".into()));
        }
        let built = build_medium(
            at.ctx,
            line,
            at.name,
            inner_owner.clone(),
            inner,
            placement,
            media,
        )?;
        // A textured component keeps its textures; its stand-in (the textures' means) is
        // its constant part.
        let texture = match built.walk {
            None => ComponentTextures::Fixed,
            Some(WalkInterior::Entry(e)) => ComponentTextures::Entry(e),
            Some(WalkInterior::Field(f)) => ComponentTextures::Field(FieldTextures {
                albedo: f.albedo,
                attenuation: f.attenuation,
                density: f.density,
                mode: f.mode,
                mean_cosine: f.medium.phase.mean_cosine(),
            }),
            Some(WalkInterior::Mixture(_) | WalkInterior::Blend { .. } | WalkInterior::Fabric(_)) => {
                return Err(bad(
                    "a blend, a fabric, or a combined interior with a textured base, cannot be a mixture component"
                        .into(),
                ))
            }
        };
        let before = components.len();
        match built.medium {
            Medium::Homogeneous(h) => components.push(MixtureComponent {
                density: ComponentDensity::Constant(h.coefficients),
                phase: h.phase,
                albedo: None,
                emission: None,
            }),
            Medium::Absorbing { sigma_a } => components.push(MixtureComponent {
                density: ComponentDensity::Constant(Coefficients {
                    sigma_a,
                    sigma_s: crate::spectrum::Rgb::ZERO,
                }),
                phase: PhaseFunction::henyey_greenstein(0.0).map_err(|e| bad(e.to_string()))?,
                albedo: None,
                emission: None,
            }),
            Medium::Heterogeneous(mut h) => {
                h.tracking = component_tracking(cfg);
                let phase = h.phase;
                components.push(MixtureComponent {
                    density: ComponentDensity::Field(h),
                    phase,
                    albedo: None,
                    emission: None,
                });
            }
            Medium::Scaled(f) => {
                // The walk's copy of the field was dropped with `built.walk`: the field is
                // usually this stand-in's alone.
                let mut h = Arc::try_unwrap(f.medium).unwrap_or_else(|shared| (*shared).clone());
                h.coefficients.sigma_t = f.sigma_t;
                h.coefficients.sigma_s = f.sigma_s;
                h.tracking = component_tracking(cfg);
                let phase = h.phase;
                components.push(MixtureComponent {
                    density: ComponentDensity::Field(Box::new(h)),
                    phase,
                    albedo: None,
                    emission: None,
                });
            }
            Medium::Dyed(_) => {
                return Err(bad("a fabric cannot be a mixture component (entries of `media` are homogeneous, voxel or fbm)".into()));
            }
            Medium::Mixture(m) => {
                for mut c in m.components {
                    if let ComponentDensity::Field(h) = &mut c.density {
                        h.tracking = component_tracking(cfg);
                    }
                    components.push(c);
                }
            }
            Medium::Projected(_) => {
                return Err(bad(
                    "a surface-projected interior (projection = \"surface\") cannot be a mixture component; use projection = \"entry\" or constant values".into(),
                ))
            }
            Medium::ScaledMixture(_) => {
                return Err(bad(
                    "a combined interior with a textured base cannot be a mixture component; write the base as another entry of `media`".into(),
                ))
            }
        }
        if components.len() == before + 1 {
            textures.push(texture);
        } else {
            textures.extend((before..components.len()).map(|_| ComponentTextures::Fixed));
        }
    }
    if components.len() > MAX_COMPONENTS {
        return Err(at.invalid(format!(
            "{owner}: the mixture has {} media in all; at most {MAX_COMPONENTS}",
            components.len()
        )));
    }
    Ok(with_textures(MixtureMedium { components }, textures, nee))
}

/// The interior of a `voxel` or `fbm` interior with a textured base medium: `medium` is the
/// field and its base as a mixture ([`super::heterogeneous::DensityLook::into_mixture`]),
/// `textures` how each of the two reads its coefficients per walk.
pub(super) fn with_base_textures(
    at: &Site,
    medium: Medium,
    textures: Vec<ComponentTextures>,
    nee: NeeStrategy,
) -> Result<BuiltInterior, SceneError> {
    match medium {
        Medium::Mixture(m) if m.components.len() == textures.len() => {
            Ok(with_textures(*m, textures, nee))
        }
        _ => Err(at.invalid(format!(
            "{}: the textured base medium has no extinction (base_attenuation is infinite)",
            at.owner
        ))),
    }
}

/// The interior of mixture `medium` whose components get their coefficients per walk as
/// `textures` says (one entry per component): fixed when none is textured, else resolved at
/// each entry point, its stand-in the mixture at the textures' means.
pub(super) fn with_textures(
    medium: MixtureMedium,
    textures: Vec<ComponentTextures>,
    nee: NeeStrategy,
) -> BuiltInterior {
    if textures
        .iter()
        .all(|t| matches!(t, ComponentTextures::Fixed))
    {
        return BuiltInterior {
            medium: Medium::Mixture(Box::new(medium)),
            nee,
            walk: None,
        };
    }
    let shared = Arc::new(medium);
    BuiltInterior {
        medium: Medium::ScaledMixture(ScaledMixture {
            medium: Arc::clone(&shared),
            coefficients: shared.own_coefficients(),
        }),
        nee,
        walk: Some(WalkInterior::Mixture(TexturedMixture {
            medium: shared,
            textures,
        })),
    }
}
