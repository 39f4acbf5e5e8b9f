//! The texturable keys of `voxel` and `fbm` interiors (`albedo`, `attenuation`, `density`):
//! constants, or textures that set the coefficients per unit density over the unchanged
//! density field, read at each walk's entry point (`projection = "entry"`, docs/textures.md,
//! "Density fields read at the entry point") or at the boundary point closest to every lookup
//! (`projection = "surface"`, "Density fields projected to the surface").

use std::sync::Arc;

use super::{textured_extinction_and_nee, BuiltInterior, Projection, Site};
use crate::geometry::ClosestPointMesh;
use crate::math::Vec2;
use crate::medium::{
    AlbedoMode, EntryInterior, FieldInterior, Medium, NeeStrategy, ProjectedMedium, ScaledField,
    WalkInterior,
};
use crate::scene::desc::{ColorInput, ColorValue, ScalarInput, TrackingDesc};
use crate::scene::validate::color;
use crate::scene::SceneError;
use crate::spectrum::Rgb;
use crate::texture::{ColorParam, ScalarParam};

/// The texturable keys of a `voxel` or `fbm` interior (`albedo`, `attenuation`, `density`),
/// read at the entry point or projected to the surface when textured (docs/textures.md): the
/// constants (or the textures' means, for the stand-in medium) and the parameters.
pub(super) struct FieldParams {
    /// Artist albedo.
    pub albedo: ColorParam,
    /// Attenuation distance at density 1.
    pub attenuation: ColorParam,
    /// Density multiplier.
    pub density: ScalarParam,
    /// Where NEE happens.
    pub nee: NeeStrategy,
    /// The mesh textured parameters are projected onto (`projection = "surface"` with a
    /// texture; `None` when they are read at the entry point, or nothing is textured).
    pub surface: Option<ClosestPointMesh>,
}

impl FieldParams {
    /// Reads the keys; `projection` is "entry" (the default) or "surface", which needs a mesh
    /// boundary with texture coordinates (errors name the object and key).
    pub fn read(
        at: &Site,
        albedo: Option<&ColorInput>,
        attenuation: Option<&ColorInput>,
        density: Option<&ScalarInput>,
        nee: Option<&str>,
        projection: Option<&str>,
    ) -> Result<FieldParams, SceneError> {
        let projection = at.projection(projection, at.placement)?;
        let (density, attenuation, nee) =
            textured_extinction_and_nee(at, density, attenuation, nee)?;
        let albedo = match albedo {
            Some(ColorInput::Texture(_)) => {
                at.params()
                    .colour("albedo", albedo, Rgb::splat(0.8), 0.0, 1.0)?
            }
            // Checked by `DensityLook::read`.
            Some(ColorInput::Value(v)) => ColorParam::Constant(color(Some(*v), Rgb::splat(0.8))),
            None => ColorParam::Constant(Rgb::splat(0.8)),
        };
        let mut params = FieldParams {
            albedo,
            attenuation,
            density,
            nee,
            surface: None,
        };
        if projection == Projection::Surface && params.is_textured() {
            let unit = params.density.max() / params.attenuation.min().min_component();
            if !unit.is_finite() {
                return Err(at.invalid(format!(
                    "{}: density/attenuation gives a non-finite extinction per unit density",
                    at.owner
                )));
            }
            params.surface = Some(at.surface_boundary(at.placement)?);
        }
        Ok(params)
    }

    /// True when a parameter is a texture.
    pub fn is_textured(&self) -> bool {
        self.albedo.is_textured() || self.attenuation.is_textured() || self.density.is_textured()
    }

    /// The albedo for `DensityLook::read`: the constant as written, or the texture's mean.
    pub fn look_albedo(&self, written: Option<&ColorInput>) -> Option<ColorValue> {
        match (&self.albedo, written) {
            (ColorParam::Texture(_), _) => Some(ColorValue::Rgb(mean(&self.albedo).0)),
            (_, Some(ColorInput::Value(v))) => Some(*v),
            _ => None,
        }
    }

    /// The density and attenuation for `DensityLook::read`: the constants, or the textures'
    /// means.
    pub fn look_extinction(&self) -> (f32, Rgb) {
        (
            self.density.eval(Vec2::ZERO, f32::INFINITY),
            mean(&self.attenuation),
        )
    }

    /// Refuses the `tracking` keys a surface-projected field does not use (`free_flight`,
    /// `transmittance`, `control`, `step`, `local_bounds`, `behind`: its flights and shadow rays are the
    /// per-channel delta and ratio trackers over the field's majorant segments), naming the
    /// object and key; `majorant` and `level` still shape those segments.
    pub fn refuse_unused_tracking(
        &self,
        at: &Site,
        tracking: Option<&TrackingDesc>,
    ) -> Result<(), SceneError> {
        let (Some(_), Some(t)) = (&self.surface, tracking) else {
            return Ok(());
        };
        let unused = [
            ("free_flight", t.free_flight.is_some()),
            ("transmittance", t.transmittance.is_some()),
            ("control", t.control.is_some()),
            ("step", t.step.is_some()),
            ("local_bounds", t.local_bounds.is_some()),
            ("behind", t.behind.is_some()),
        ];
        match unused.iter().find(|(_, set)| *set) {
            Some((key, _)) => Err(at.invalid(format!(
                "{}.tracking.{key} does not apply with projection = \"surface\" (projected fields are tracked per channel by delta and ratio tracking over the field's majorant segments; only `majorant` and `level` apply)",
                at.owner
            ))),
            None => Ok(()),
        }
    }

    /// The interior of `medium` (built with [`Self::look_albedo`] and
    /// [`Self::look_extinction`]): fixed when nothing is textured; else resolved per walk,
    /// its stand-in the field at the textures' means (`"entry"`), or a [`ProjectedMedium`]
    /// over the field (`"surface"`).
    pub fn finish(self, medium: Medium, mode: AlbedoMode) -> BuiltInterior {
        let h = match medium {
            Medium::Heterogeneous(h) if self.is_textured() => h,
            medium => {
                return BuiltInterior {
                    medium,
                    nee: self.nee,
                    walk: None,
                }
            }
        };
        let c = h.coefficients;
        let shared = Arc::new(*h);
        if let Some(boundary) = self.surface {
            let params = EntryInterior {
                albedo: self.albedo,
                attenuation: self.attenuation,
                density: self.density,
                mode,
                phase: shared.phase,
                absorbing: false,
            };
            return BuiltInterior {
                medium: Medium::Projected(Box::new(ProjectedMedium::over_field(
                    params, boundary, shared,
                ))),
                nee: self.nee,
                walk: None,
            };
        }
        BuiltInterior {
            medium: Medium::Scaled(ScaledField {
                medium: Arc::clone(&shared),
                sigma_t: c.sigma_t,
                sigma_s: c.sigma_s,
            }),
            nee: self.nee,
            walk: Some(WalkInterior::Field(FieldInterior {
                medium: shared,
                albedo: self.albedo,
                attenuation: self.attenuation,
                density: self.density,
                mode,
            })),
        }
    }
}

/// A colour parameter's mean (its pyramid's top level; the constant itself).
fn mean(p: &ColorParam) -> Rgb {
    p.eval(Vec2::ZERO, f32::INFINITY)
}
