//! What the scene was built into, for the image metadata and the render summary: the kind of
//! each interior, the estimators chosen for it, the grids loaded, the bricks baked and the
//! memory used.

use std::collections::BTreeMap;

use crate::medium::{DensityField, Medium};
use crate::scene::{Object, Scene};

/// The objects that have an interior, with it.
fn interiors(scene: &Scene) -> impl Iterator<Item = (&Object, &Medium)> {
    scene.objects.iter().filter_map(|o| {
        o.medium
            .and_then(|m| scene.media.get(m as usize))
            .map(|m| (o, m))
    })
}

/// One `velour:interior.<object>` attribute per object with an interior: the interior's kind
/// and the estimators chosen for it (free flights, shadow-ray transmittance, majorants, NEE).
#[must_use]
pub fn estimator_attributes(scene: &Scene) -> BTreeMap<String, String> {
    let mut out = BTreeMap::new();
    for (object, medium) in interiors(scene) {
        let what = match medium {
            Medium::Absorbing { .. } => "absorbing".to_string(),
            Medium::Homogeneous(_) => "homogeneous".to_string(),
            Medium::Projected(_) => {
                "surface-projected textures; free_flight spectral delta; transmittance ratio"
                    .to_string()
            }
            Medium::Heterogeneous(h) => format!(
                "heterogeneous; free_flight {:?}; transmittance {:?}; majorant {:?}",
                h.tracking.free_flight, h.tracking.transmittance, h.tracking.majorant
            ),
            Medium::Scaled(f) => format!(
                "heterogeneous, textured per walk; free_flight {:?}; transmittance {:?}; majorant {:?}",
                f.medium.tracking.free_flight, f.medium.tracking.transmittance, f.medium.tracking.majorant
            ),
            Medium::Dyed(f) => format!(
                "fabric, yarn colours textured per walk; free_flight {:?}; transmittance {:?}; majorant {:?}",
                f.medium.tracking.free_flight, f.medium.tracking.transmittance, f.medium.tracking.majorant
            ),
            Medium::Mixture(m) => format!(
                "mixture of {}; free_flight delta (mixture); transmittance {} per component",
                m.components.len(),
                mixture_transmittance(m)
            ),
            Medium::ScaledMixture(m) => format!(
                "mixture of {}, textured per walk; free_flight delta (mixture); transmittance {} per component",
                m.medium.components.len(),
                mixture_transmittance(&m.medium)
            ),
        };
        let name: String = object
            .name
            .chars()
            .map(|c| if c.is_ascii_graphic() { c } else { '_' })
            .collect();
        out.insert(
            format!("velour:interior.{name}"),
            format!("{what}; nee {:?}", object.nee),
        );
    }
    out
}

/// One line per object with an interior, saying what velour built for it: the kind
/// (homogeneous, voxel grid, fBm baked / lazily baked / exact, fabric shell), the grid's bricks
/// and memory, lazily baked bricks so far, and the estimators. Call it after the render to see
/// how many lazy bricks the render needed.
#[must_use]
pub fn interior_summary(scene: &Scene) -> Vec<String> {
    let mut lines = Vec::new();
    let mb = |bytes: usize| bytes as f64 / (1024.0 * 1024.0);
    for (object, medium) in interiors(scene) {
        let built = match medium {
            Medium::Absorbing { .. } => "absorbing only (no grid)".to_string(),
            Medium::Homogeneous(_) => "no grid".to_string(),
            Medium::Projected(p) => format!(
                "textures projected to the closest boundary point ({} triangles){}, majorant {:.4}",
                p.boundary.triangle_count(),
                if p.field.is_some() {
                    " over a density field (its majorant segments times the textures' bound)"
                } else {
                    ""
                },
                p.majorant()
            ),
            Medium::Heterogeneous(h) => {
                let field = match &h.field {
                    DensityField::Grid { grid, .. } => {
                        let m = grid.memory_report();
                        format!(
                            "grid of {} bricks, {:.1} MB",
                            grid.brick_count(),
                            mb(m.total_bytes)
                        )
                    }
                    DensityField::Procedural(_) => "fBm evaluated exactly (no grid)".to_string(),
                    DensityField::LazyBaked(g) => format!(
                        "fBm baked lazily: {} of {} bricks baked",
                        g.baked_bricks(),
                        g.total_bricks()
                    ),
                    DensityField::Shell(_) => {
                        "fabric shell over a voxelised weave patch".to_string()
                    }
                };
                format!(
                    "{field}; free flights {:?}, transmittance {:?}, majorants {:?}",
                    h.tracking.free_flight, h.tracking.transmittance, h.tracking.majorant
                )
            }
            Medium::Scaled(f) => format!(
                "density field with albedo/attenuation/density textures read per walk; free flights {:?}, transmittance {:?}, majorants {:?}",
                f.medium.tracking.free_flight, f.medium.tracking.transmittance, f.medium.tracking.majorant
            ),
            Medium::ScaledMixture(m) => format!(
                "mixture of {} with components textured per walk (read at the entry point)",
                m.medium.components.len()
            ),
            Medium::Dyed(f) => format!(
                "fabric shell over a voxelised weave patch, yarn colours textured per walk; free flights {:?}, transmittance {:?}, majorants {:?}",
                f.medium.tracking.free_flight, f.medium.tracking.transmittance, f.medium.tracking.majorant
            ),
            Medium::Mixture(m) => {
                let parts: Vec<String> = m
                    .components
                    .iter()
                    .map(|c| {
                        let mut s = match &c.density {
                            crate::medium::ComponentDensity::Constant(_) => {
                                "homogeneous".to_string()
                            }
                            crate::medium::ComponentDensity::Field(h) => match &h.field {
                                DensityField::Grid { grid, .. } => {
                                    format!("grid of {} bricks", grid.brick_count())
                                }
                                _ => "fBm".to_string(),
                            },
                        };
                        if c.albedo.is_some() {
                            s.push_str(" with an albedo grid");
                        }
                        if c.emission.is_some() {
                            s.push_str(" with emission");
                        }
                        s
                    })
                    .collect();
                format!(
                    "{}; free flights by delta tracking of the sum, transmittance {} per field",
                    parts.join(" + "),
                    mixture_transmittance(m)
                )
            }
        };
        lines.push(format!(
            "interior {}: {}, {built}; NEE {:?}",
            object.name, object.interior_kind, object.nee
        ));
    }
    lines
}

/// The shadow-ray estimator of a mixture's fields (the homogeneous parts are closed form).
fn mixture_transmittance(m: &crate::medium::MixtureMedium) -> String {
    m.components
        .iter()
        .find_map(|c| match &c.density {
            crate::medium::ComponentDensity::Field(h) => {
                Some(format!("{:?}", h.tracking.transmittance))
            }
            crate::medium::ComponentDensity::Constant(_) => None,
        })
        .unwrap_or_else(|| "closed form".to_string())
}
