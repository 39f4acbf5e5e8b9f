//! `fbm` interiors: procedural fBm noise density in the object's rest space (it deforms with
//! the object), bounded by the shape's rest-space box.

use glam::DAffine3;

use super::heterogeneous::{field_keys, FieldLook};
use super::{BuiltInterior, Placement, Site};
use crate::majorant::MajorantPyramid;
use crate::math::Aabb;
use crate::medium::DensityField;
use crate::procedural::{
    bake_fbm, procedural_pyramid, FbmField, FbmParams, LazyFbmGrid, ProceduralBound,
    ProceduralLattice,
};
use crate::scene::desc::FbmDesc;
use crate::scene::validate::reject_unused;
use crate::scene::SceneError;

/// The medium of an `fbm` interior.
pub(super) fn build(
    at: &Site,
    d: &FbmDesc,
    placement: &Placement<'_>,
) -> Result<BuiltInterior, SceneError> {
    let look = FieldLook::read(at, &field_keys!(d))?;
    let xf = DAffine3::from_mat4(placement.xf.as_dmat4());
    let rest_bounds = placement.rest_bounds.ok_or_else(|| {
        at.invalid(format!(
            "{}: an fbm interior needs a mesh or sphere shape to bound it",
            at.owner
        ))
    })?;
    let (field, pyramid) = fbm_field(at, d, xf, rest_bounds)?;
    look.build(at, field, pyramid, None, d.tracking.as_ref())
}

/// The noise field over the lattice of `voxel_size` spanning `rest_bounds`, baked, baked
/// lazily or exact (`evaluation`), with its majorant pyramid.
fn fbm_field(
    at: &Site,
    d: &FbmDesc,
    xf: DAffine3,
    rest_bounds: Aabb,
) -> Result<(DensityField, MajorantPyramid), SceneError> {
    let owner = &at.owner;
    let bad = |e: &dyn std::fmt::Display| at.failed(e);
    let defaults = FbmParams::default();
    let n = d.noise.clone().unwrap_or_default();
    let params = FbmParams {
        frequency: n.frequency.unwrap_or(defaults.frequency),
        octaves: n.octaves.unwrap_or(defaults.octaves),
        lacunarity: n.lacunarity.unwrap_or(defaults.lacunarity),
        gain: n.gain.unwrap_or(defaults.gain),
        amplitude: n.amplitude.unwrap_or(defaults.amplitude),
        offset: n.offset.unwrap_or(defaults.offset),
        min: n.min.unwrap_or(defaults.min),
        max: n.max.unwrap_or(defaults.max),
        seed: n.seed.unwrap_or(defaults.seed),
    };
    let field = FbmField::new(params, xf).map_err(|e| bad(&e))?;
    let reach = f64::from(
        rest_bounds
            .min
            .abs()
            .max(rest_bounds.max.abs())
            .max_element(),
    );
    field.params().check_extent(reach).map_err(|e| bad(&e))?;
    let extent = rest_bounds.extent().max_element().max(1e-9);
    let voxel_size = at.range(
        "voxel_size",
        d.voxel_size.unwrap_or(extent / 128.0),
        extent * 1e-4,
        extent,
    )?;
    let lattice = ProceduralLattice::new(rest_bounds, voxel_size, xf).map_err(|e| bad(&e))?;
    match d.evaluation.as_deref().unwrap_or("baked") {
        "baked" => {
            // Baked bricks have exact majorants: the bound keys would do nothing.
            reject_unused(
                at.ctx,
                at.line,
                owner,
                "fbm (baked)",
                &[
                    ("bound", d.bound.is_some()),
                    ("bound_min", d.bound_min.is_some()),
                    ("bound_max", d.bound_max.is_some()),
                    ("trial_samples", d.trial_samples.is_some()),
                    ("safety", d.safety.is_some()),
                ],
            )?;
            let grid = bake_fbm(&field, &lattice).map_err(|e| bad(&e))?;
            let pyramid = MajorantPyramid::from_grid(&grid, 0).map_err(|e| bad(&e))?;
            grid.prepare_padded(0);
            Ok((DensityField::Grid { grid, channel: 0 }, pyramid))
        }
        evaluation @ ("lazy" | "exact") => {
            let bound = match d.bound.as_deref().unwrap_or("estimated") {
                "analytic" => ProceduralBound::Analytic,
                "artist" => {
                    let min = d.bound_min.unwrap_or(0.0);
                    let max = d.bound_max.ok_or_else(|| at.invalid(format!("{owner}: bound = \"artist\" needs `bound_max` (and optionally `bound_min`)")))?;
                    ProceduralBound::Artist { min, max }
                }
                "estimated" => ProceduralBound::Estimated {
                    samples: d.trial_samples.unwrap_or(32),
                    safety: d.safety.unwrap_or(1.25),
                },
                other => return Err(at.invalid(format!("{owner}.bound = \"{other}\" is unknown (expected \"analytic\", \"artist\" or \"estimated\")"))),
            };
            let pyramid =
                procedural_pyramid(&field, &lattice, bound, 0x5eed).map_err(|e| bad(&e))?;
            if evaluation == "lazy" {
                let lazy = LazyFbmGrid::new(field, &lattice).map_err(|e| bad(&e))?;
                Ok((DensityField::LazyBaked(Box::new(lazy)), pyramid))
            } else {
                Ok((DensityField::Procedural(Box::new(field)), pyramid))
            }
        }
        other => Err(at.invalid(format!("{owner}.evaluation = \"{other}\" is unknown (expected \"baked\", \"lazy\" or \"exact\")"))),
    }
}
