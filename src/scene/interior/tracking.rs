//! `tracking = { ... }`: the estimator choices of a `voxel` or `fbm` interior.

use super::Site;
use crate::majorant::MajorantMode;
use crate::scene::desc::TrackingDesc;
use crate::scene::SceneError;
use crate::tracking::{BehindMode, ControlVariate, DensityCoefficients, TransmittanceMode};
use crate::tracking::{FreeFlightMethod, TrackingConfig};

/// The tracking configuration: the defaults (delta tracking, residual ratio tracking with
/// Novák's control, the majorant pyramid from the bricks up, local bounds) for every absent
/// key; [`default_local_bounds`] then decides an absent `local_bounds` by the extinction.
pub(super) fn build_tracking(
    at: &Site,
    t: Option<&TrackingDesc>,
) -> Result<TrackingConfig, SceneError> {
    let mut cfg = TrackingConfig::default();
    let Some(t) = t else { return Ok(cfg) };
    let owner = format!("{}.tracking", at.owner);
    let step = match t.step {
        Some(s) => Some(at.range("tracking.step", s, 1e-9, 1e9)?),
        None => None,
    };
    let need_step = || {
        step.ok_or_else(|| at.invalid(format!("{owner}: ray marching needs `step` (world units)")))
    };
    cfg.free_flight = match t.free_flight.as_deref().unwrap_or("delta") {
        "delta" => FreeFlightMethod::DeltaTracking,
        "decomposition" => FreeFlightMethod::Decomposition,
        "split" => FreeFlightMethod::Split,
        "ray_march" => FreeFlightMethod::RayMarch { step: need_step()? },
        other => {
            return Err(at.invalid(format!(
            "{owner}.free_flight = \"{other}\" is unknown (expected \"delta\", \"decomposition\", \"split\" or \"ray_march\")"
        )))
        }
    };
    let control = match t.control.as_deref().unwrap_or("novak") {
        "novak" => ControlVariate::Novak,
        "mean" => ControlVariate::Mean,
        "minorant" => ControlVariate::Minorant,
        other => return Err(at.invalid(format!("{owner}.control = \"{other}\" is unknown (expected \"novak\", \"mean\" or \"minorant\")"))),
    };
    cfg.transmittance = match t.transmittance.as_deref().unwrap_or("residual") {
        "residual" => TransmittanceMode::ResidualRatio(control),
        "ratio" => TransmittanceMode::Ratio,
        "unbiased_ray_march" => TransmittanceMode::UnbiasedRayMarch,
        "jackknife" => TransmittanceMode::Jackknife,
        "ray_march" => TransmittanceMode::RayMarch { step: need_step()? },
        other => return Err(at.invalid(format!("{owner}.transmittance = \"{other}\" is unknown (expected \"residual\", \"ratio\", \"unbiased_ray_march\", \"jackknife\" or \"ray_march\")"))),
    };
    let level = t.level.unwrap_or(0);
    if level > 20 {
        return Err(at.invalid(format!("{owner}.level = {level} is outside [0, 20]")));
    }
    cfg.majorant = match t.majorant.as_deref().unwrap_or("pyramid") {
        "pyramid" => MajorantMode::Hierarchical { finest: level },
        "global" => MajorantMode::Global,
        other => {
            return Err(at.invalid(format!(
                "{owner}.majorant = \"{other}\" is unknown (expected \"pyramid\" or \"global\")"
            )))
        }
    };
    cfg.local_bounds = t.local_bounds.unwrap_or(cfg.local_bounds);
    cfg.sun_lean = t.sun_lean.unwrap_or(cfg.sun_lean);
    cfg.behind = match t.behind.as_deref().unwrap_or("survive") {
        "transmittance" => BehindMode::Transmittance,
        "survive" => BehindMode::Survive,
        other => {
            return Err(at.invalid(format!(
            "{owner}.behind = \"{other}\" is unknown (expected \"survive\" or \"transmittance\")"
        )))
        }
    };
    Ok(cfg)
}

/// The interior's `local_bounds` when its `tracking` table leaves the key out: on where the
/// extinction is grey (σ_t per unit density and the constant part the same in every channel),
/// off for chromatic extinction. With grey extinction the free flights' events are those
/// without local bounds, at a third of the lookups; with chromatic extinction the one-sample
/// MIS over channels weighs the null collisions at the tighter local majorant, and the image's
/// variance rose more than the lookups saved (the fbm creature, σ_t ratio 3.75 between
/// channels: docs/BENCHMARKS.md, "Local bounds by default").
pub(super) fn default_local_bounds(
    cfg: &mut TrackingConfig,
    t: Option<&TrackingDesc>,
    c: &DensityCoefficients,
) {
    if t.and_then(|t| t.local_bounds).is_none() {
        cfg.local_bounds = grey_extinction(c);
    }
}

/// True when σ_t per unit density and the constant part are the same in every channel: where
/// local bounds are on by default ([`default_local_bounds`]; fabric interiors, which have no
/// `tracking` table, follow the same rule).
pub(super) fn grey_extinction(c: &DensityCoefficients) -> bool {
    let grey = |v: crate::spectrum::Rgb| v.max_component() == v.min_component();
    grey(c.sigma_t) && grey(c.base_t)
}
