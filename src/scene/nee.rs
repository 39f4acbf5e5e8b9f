//! The default next event estimation of an interior: what `nee` absent (or `nee = "auto"`)
//! resolves to once the object's surface and the scene's lights are known
//! (docs/choosing-estimators.md, "Next event estimation"; measurements in docs/BENCHMARKS.md,
//! "The default nee").
//!
//! * Behind an index-matched boundary (no surface, or a dielectric of IOR 1): `"interior"`
//!   (there are no exit vertices; decided by the object builder).
//! * Behind a rough dielectric boundary, coated or not (a constant or textured roughness, or a
//!   blend of two such looks), in a scene with a light the guided
//!   connection samples better than the walk does (a distant light, delta or disc, or a sphere
//!   light): `"exit_guided"`.
//! * Otherwise `"exit"`: behind a smooth boundary `"exit_guided"` is `"exit"`, behind a
//!   diffuse-transmission boundary it mostly adds cost, and behind a blend with a smooth look
//!   and under environments alone it was measured to lose.

use super::{Object, ObjectSurface};
use crate::bsdf::microfacet::SMOOTH_ALPHA;
use crate::light::Light;
use crate::medium::NeeStrategy;

/// The value of `nee` that asks for the default, as a user may write it.
pub(super) const AUTO: &str = "auto";

/// True when an interior's `nee` key (`None` when absent) asks for the default.
pub(super) fn is_auto(nee: Option<&str>) -> bool {
    matches!(nee, None | Some(AUTO))
}

/// True when `surface` is a boundary behind which `"exit_guided"` is the default (given a
/// light it pays for, [`guided_lights`]): a refracting dielectric (IOR ≠ 1) whose largest
/// roughness is not treated as smooth (roughness² ≥ [`SMOOTH_ALPHA`]), with or without a coat
/// (×22–500 measured behind a coat), or a blend of two such looks (behind a blend with a smooth look the smooth parts' fireflies
/// dominate and the connection's cost did not pay).
pub fn guided_boundary(surface: &ObjectSurface) -> bool {
    fn rough(s: &ObjectSurface) -> bool {
        match s {
            ObjectSurface::Dielectric(d) => {
                let r = d.roughness.max();
                d.ior != 1.0 && r * r >= SMOOTH_ALPHA
            }
            _ => false,
        }
    }
    match surface {
        ObjectSurface::Blend(b) => rough(&b.a) && rough(&b.b),
        s => rough(s),
    }
}

/// True when the scene has a light the guided connection samples better than exit-point NEE:
/// a distant light (delta or disc) or a sphere light. Environments alone are not.
pub(super) fn guided_lights(lights: &[Light]) -> bool {
    lights
        .iter()
        .any(|l| matches!(l, Light::Distant { .. } | Light::Sphere { .. }))
}

/// Resolves the default of the objects `auto` (indices into `objects`, whose interiors left
/// `nee` to the default behind a [`guided_boundary`]; the builder set them to `"exit"`):
/// `"exit_guided"` when the scene has [`guided_lights`].
pub(super) fn resolve_defaults(objects: &mut [Object], auto: &[usize], lights: &[Light]) {
    if !guided_lights(lights) {
        return;
    }
    for &i in auto {
        if let Some(o) = objects.get_mut(i) {
            o.nee = NeeStrategy::ExitGuided;
        }
    }
}
