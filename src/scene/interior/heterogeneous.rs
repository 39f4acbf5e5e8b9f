//! What `voxel` and `fbm` interiors share besides their density field: the coefficients per
//! unit density, the optional homogeneous base medium of a combined interior, the phase
//! function and the estimator choices.

use std::sync::Arc;

use super::scattering::Scattering;
use super::tracking::build_tracking;
use super::{textured_extinction_and_nee, BuiltInterior, Site};
use crate::majorant::MajorantPyramid;
use crate::math::Vec2;
use crate::medium::{
    AlbedoGrid, AlbedoMode, Coefficients, ComponentDensity, DensityField, EmissionGrid,
    FieldInterior, HeterogeneousMedium, Medium, MixtureComponent, MixtureMedium, NeeStrategy,
    ScaledField, WalkInterior,
};
use crate::phase::PhaseFunction;
use crate::scene::desc::{ColorInput, ColorValue, PhaseDesc, ScalarInput, TrackingDesc};
use crate::scene::validate::color;
use crate::scene::SceneError;
use crate::spectrum::Rgb;
use crate::texture::{ColorParam, ScalarParam};
use crate::tracking::DensityCoefficients;
use crate::tracking::TrackingConfig;

/// The keys of a density-field interior other than its field.
pub(super) struct DensityKeys<'a> {
    /// Artist albedo.
    pub albedo: Option<ColorValue>,
    /// "multiple" or "single".
    pub albedo_mode: Option<&'a str>,
    /// Phase function.
    pub phase: Option<&'a PhaseDesc>,
    /// Albedo of the combined interior's homogeneous base medium.
    pub base_albedo: Option<ColorValue>,
    /// Attenuation distance of that base medium.
    pub base_attenuation: Option<ColorValue>,
    /// Estimator choices.
    pub tracking: Option<&'a TrackingDesc>,
}

/// Everything of a density-field medium but the field and its majorants.
pub(super) struct DensityLook {
    coefficients: DensityCoefficients,
    phase: PhaseFunction,
    tracking: TrackingConfig,
    /// How the artist albedo was read (for albedo grids, inverted per vertex the same way).
    pub mode: AlbedoMode,
}

impl DensityLook {
    /// Reads the keys: coefficients per unit density from the albedo, `attenuation` and
    /// `density`; with `base_albedo` or `base_attenuation`, a homogeneous medium added
    /// everywhere inside (the combined interior of course notes §2.4.1, e.g. ocean water
    /// with voxel foam), read with the same albedo mode and phase function.
    pub fn read(
        at: &Site,
        keys: &DensityKeys<'_>,
        density: f32,
        attenuation: Rgb,
    ) -> Result<DensityLook, SceneError> {
        let scattering = Scattering::read(at, keys.albedo, keys.albedo_mode, keys.phase)?;
        let per_unit = scattering.coefficients(attenuation, density);
        let mut coefficients = DensityCoefficients::new(per_unit.sigma_t(), per_unit.sigma_s);
        if keys.base_albedo.is_some() || keys.base_attenuation.is_some() {
            let base_albedo = at.unit_colour("base_albedo", keys.base_albedo, Rgb::splat(0.8))?;
            let base_attenuation = crate::scene::validate::color(keys.base_attenuation, Rgb::ONE);
            if base_attenuation.0.iter().any(|v| !(*v > 0.0)) {
                return Err(at.invalid(format!(
                    "{}.base_attenuation = {:?}: every channel must be a distance > 0",
                    at.owner, base_attenuation.0
                )));
            }
            let base = scattering.coefficients_of(base_albedo, base_attenuation, 1.0);
            coefficients.base_t = base.sigma_t();
            coefficients.base_s = base.sigma_s;
        }
        let tracking = build_tracking(at, keys.tracking)?;
        Ok(DensityLook {
            coefficients,
            phase: scattering.phase,
            tracking,
            mode: scattering.mode,
        })
    }

    /// The medium of `field` with its majorant `pyramid` (and the pyramid's local bounds when
    /// the tracking configuration uses them).
    pub fn into_medium(
        self,
        at: &Site,
        field: DensityField,
        pyramid: MajorantPyramid,
    ) -> Result<Medium, SceneError> {
        let mut medium = HeterogeneousMedium {
            field,
            pyramid,
            coefficients: self.coefficients,
            phase: self.phase,
            tracking: self.tracking,
            fabric: None,
        };
        medium
            .attach_local_bounds()
            .map_err(|e| at.invalid(format!("{}: local bounds: {e}", at.owner)))?;
        Ok(Medium::Heterogeneous(Box::new(medium)))
    }
}

impl DensityLook {
    /// The phase function's mean cosine (for albedo-grid inversions).
    pub fn mean_cosine(&self) -> f32 {
        self.phase.mean_cosine()
    }

    /// The medium of `field` as a mixture (docs/references.md §15): the field with its albedo
    /// and emission grids as one component, and the homogeneous base medium of
    /// `base_albedo`/`base_attenuation` (sharing the phase function) as a second. Used when
    /// the interior has albedo or emission grids; the mixture's free flights are delta
    /// tracked (`tracking` chooses the majorants and the shadow-ray estimator).
    pub fn into_mixture(
        self,
        at: &Site,
        field: DensityField,
        pyramid: MajorantPyramid,
        albedo: Option<AlbedoGrid>,
        emission: Option<EmissionGrid>,
        tracking_desc: Option<&TrackingDesc>,
    ) -> Result<Medium, SceneError> {
        let tracking = super::mixture::check_mixture_tracking(at, tracking_desc)?;
        let c = self.coefficients;
        let mut components = vec![MixtureComponent {
            density: ComponentDensity::Field(Box::new(HeterogeneousMedium {
                field,
                pyramid,
                coefficients: DensityCoefficients::new(c.sigma_t, c.sigma_s),
                phase: self.phase,
                tracking: super::mixture::component_tracking(tracking),
                fabric: None,
            })),
            phase: self.phase,
            albedo: albedo.map(Box::new),
            emission: emission.map(Box::new),
        }];
        if !c.base_t.is_black() {
            components.push(MixtureComponent {
                density: ComponentDensity::Constant(Coefficients {
                    sigma_a: (c.base_t - c.base_s).clamp_zero(),
                    sigma_s: c.base_s,
                }),
                phase: self.phase,
                albedo: None,
                emission: None,
            });
        }
        Ok(Medium::Mixture(Box::new(MixtureMedium { components })))
    }
}

/// The texturable keys of a `voxel` or `fbm` interior (`albedo`, `attenuation`, `density`),
/// read at the entry point when textured (docs/textures.md): the constants (or the textures'
/// means, for the stand-in medium) and the parameters.
pub(super) struct FieldParams {
    /// Artist albedo.
    pub albedo: ColorParam,
    /// Attenuation distance at density 1.
    pub attenuation: ColorParam,
    /// Density multiplier.
    pub density: ScalarParam,
    /// Where NEE happens.
    pub nee: NeeStrategy,
}

impl FieldParams {
    /// Reads the keys; `projection` must be "entry" (or absent): `"surface"` is refused for
    /// density fields, naming the object and key.
    pub fn read(
        at: &Site,
        albedo: Option<&ColorInput>,
        attenuation: Option<&ColorInput>,
        density: Option<&ScalarInput>,
        nee: Option<&str>,
        projection: Option<&str>,
    ) -> Result<FieldParams, SceneError> {
        let (density, attenuation, nee) =
            textured_extinction_and_nee(at, density, attenuation, nee)?;
        if projection == Some("surface") {
            return Err(at.invalid(format!(
                "{}.projection = \"surface\" is not supported on voxel and fbm interiors (their textured parameters are read at the entry point: use \"entry\")",
                at.owner
            )));
        }
        at.projection(projection)?;
        let albedo = match albedo {
            Some(ColorInput::Texture(_)) => {
                at.params()
                    .colour("albedo", albedo, Rgb::splat(0.8), 0.0, 1.0)?
            }
            // Checked by `DensityLook::read`.
            Some(ColorInput::Value(v)) => ColorParam::Constant(color(Some(*v), Rgb::splat(0.8))),
            None => ColorParam::Constant(Rgb::splat(0.8)),
        };
        Ok(FieldParams {
            albedo,
            attenuation,
            density,
            nee,
        })
    }

    /// True when a parameter is a texture.
    pub fn is_textured(&self) -> bool {
        self.albedo.is_textured() || self.attenuation.is_textured() || self.density.is_textured()
    }

    /// The albedo for [`DensityLook::read`]: the constant as written, or the texture's mean.
    pub fn look_albedo(&self, written: Option<&ColorInput>) -> Option<ColorValue> {
        match (&self.albedo, written) {
            (ColorParam::Texture(_), _) => Some(ColorValue::Rgb(mean(&self.albedo).0)),
            (_, Some(ColorInput::Value(v))) => Some(*v),
            _ => None,
        }
    }

    /// The density and attenuation for [`DensityLook::read`]: the constants, or the textures'
    /// means.
    pub fn look_extinction(&self) -> (f32, Rgb) {
        (
            self.density.eval(Vec2::ZERO, f32::INFINITY),
            mean(&self.attenuation),
        )
    }

    /// The interior of `medium` (built with [`Self::look_albedo`] and
    /// [`Self::look_extinction`]): fixed when nothing is textured, else resolved per walk,
    /// its stand-in the field at the textures' means.
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
