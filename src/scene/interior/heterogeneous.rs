//! What `voxel` and `fbm` interiors share besides their density field: the coefficients per
//! unit density, the optional homogeneous base medium of a combined interior, the phase
//! function and the estimator choices.

use super::field_params::FieldParams;
use super::scattering::Scattering;
use super::tracking::{build_tracking, default_local_bounds};
use super::{BuiltInterior, Site};
use crate::majorant::MajorantPyramid;
use crate::math::Vec2;
use crate::medium::{
    AlbedoGrid, AlbedoMode, Coefficients, ComponentDensity, ComponentTextures, DensityField,
    EmissionGrid, EntryInterior, FieldTextures, HeterogeneousMedium, Medium, MixtureComponent,
    MixtureMedium,
};
use crate::phase::PhaseFunction;
use crate::scene::desc::{ColorInput, ColorValue, PhaseDesc, ScalarInput, TrackingDesc};
use crate::scene::validate::color;
use crate::scene::SceneError;
use crate::spectrum::Rgb;
use crate::texture::{ColorParam, ScalarParam};
use crate::tracking::DensityCoefficients;
use crate::tracking::TrackingConfig;

/// `base_albedo` and `base_attenuation` of a `voxel` or `fbm` interior: constants, or
/// textures read at the entry point (docs/textures.md). With a texture the combined interior
/// is built as a two-component mixture (the field, and the base medium with per-walk
/// coefficients).
pub(super) struct BaseParams {
    albedo: Option<ColorValue>,
    attenuation: Option<ColorValue>,
    /// The textures, when either key is one (the other then a constant parameter).
    textures: Option<(ColorParam, ColorParam)>,
}

impl BaseParams {
    /// Reads the keys: textured base albedos must lie in [0, 1], attenuations be > 0
    /// (errors name the object, key and pixel).
    pub fn read(
        at: &Site,
        albedo: Option<&ColorInput>,
        attenuation: Option<&ColorInput>,
    ) -> Result<BaseParams, SceneError> {
        let constant = |v: Option<&ColorInput>| match v {
            Some(ColorInput::Value(c)) => Some(*c),
            _ => None,
        };
        let textured = |v: Option<&ColorInput>| matches!(v, Some(ColorInput::Texture(_)));
        if !textured(albedo) && !textured(attenuation) {
            return Ok(BaseParams {
                albedo: constant(albedo),
                attenuation: constant(attenuation),
                textures: None,
            });
        }
        let p = at.params();
        let a = match albedo {
            Some(ColorInput::Texture(_)) => {
                p.colour("base_albedo", albedo, Rgb::splat(0.8), 0.0, 1.0)?
            }
            _ => ColorParam::Constant(at.unit_colour(
                "base_albedo",
                constant(albedo),
                Rgb::splat(0.8),
            )?),
        };
        let d = match attenuation {
            Some(ColorInput::Texture(_)) => p.colour(
                "base_attenuation",
                attenuation,
                Rgb::ONE,
                1e-9,
                f32::INFINITY,
            )?,
            // Checked by `DensityLook::read`.
            _ => ColorParam::Constant(color(constant(attenuation), Rgb::ONE)),
        };
        let mean = |c: &ColorParam| Some(ColorValue::Rgb(c.eval(Vec2::ZERO, f32::INFINITY).0));
        Ok(BaseParams {
            albedo: mean(&a),
            attenuation: mean(&d),
            textures: Some((a, d)),
        })
    }

    /// True when a key is a texture.
    pub fn is_textured(&self) -> bool {
        self.textures.is_some()
    }

    /// The base albedo for [`DensityKeys`]: the constant as written, or the texture's mean.
    pub fn albedo(&self) -> Option<ColorValue> {
        self.albedo
    }

    /// The base attenuation for [`DensityKeys`]: the constant as written, or the texture's
    /// mean.
    pub fn attenuation(&self) -> Option<ColorValue> {
        self.attenuation
    }

    /// How a walk reads the base medium: its textures, inverted with `look`'s albedo mode
    /// and phase function (density 1), or fixed.
    pub fn textures(self, look: &DensityLook) -> ComponentTextures {
        match self.textures {
            Some((albedo, attenuation)) => ComponentTextures::Entry(EntryInterior {
                albedo,
                attenuation,
                density: ScalarParam::Constant(1.0),
                mode: look.mode,
                phase: look.phase,
                absorbing: false,
            }),
            None => ComponentTextures::Fixed,
        }
    }
}

/// The keys `voxel` and `fbm` interiors share besides their field (built from either
/// description by [`field_keys`]).
pub(super) struct FieldKeys<'a> {
    pub albedo: Option<&'a ColorInput>,
    pub albedo_mode: Option<&'a str>,
    pub attenuation: Option<&'a ColorInput>,
    pub density: Option<&'a ScalarInput>,
    pub nee: Option<&'a str>,
    pub projection: Option<&'a str>,
    pub phase: Option<&'a PhaseDesc>,
    pub base_albedo: Option<&'a ColorInput>,
    pub base_attenuation: Option<&'a ColorInput>,
    pub tracking: Option<&'a TrackingDesc>,
}

/// The [`FieldKeys`] of a `VoxelDesc` or `FbmDesc` (the same field names in both).
macro_rules! field_keys {
    ($d:expr) => {
        super::heterogeneous::FieldKeys {
            albedo: $d.albedo.as_ref(),
            albedo_mode: $d.albedo_mode.as_deref(),
            attenuation: $d.attenuation.as_ref(),
            density: $d.density.as_ref(),
            nee: $d.nee.as_deref(),
            projection: $d.projection.as_deref(),
            phase: $d.phase.as_ref(),
            base_albedo: $d.base_albedo.as_ref(),
            base_attenuation: $d.base_attenuation.as_ref(),
            tracking: $d.tracking.as_ref(),
        }
    };
}
pub(super) use field_keys;

/// A `voxel` or `fbm` interior's parameters read from its [`FieldKeys`]: the (possibly
/// textured) field parameters, the base medium and the density look.
pub(super) struct FieldLook {
    pub params: FieldParams,
    pub base: BaseParams,
    pub look: DensityLook,
}

impl FieldLook {
    /// Reads `keys` (errors name the object and key). A look whose parameters are projected
    /// onto a surface keeps no local bounds (the coefficients vary per walk).
    pub fn read(at: &Site, keys: &FieldKeys<'_>) -> Result<FieldLook, SceneError> {
        let params = FieldParams::read(
            at,
            keys.albedo,
            keys.attenuation,
            keys.density,
            keys.nee,
            keys.projection,
        )?;
        params.refuse_unused_tracking(at, keys.tracking)?;
        let base = BaseParams::read(at, keys.base_albedo, keys.base_attenuation)?;
        let (density, attenuation) = params.look_extinction();
        let density_keys = DensityKeys {
            albedo: params.look_albedo(keys.albedo),
            albedo_mode: keys.albedo_mode,
            phase: keys.phase,
            base_albedo: base.albedo(),
            base_attenuation: base.attenuation(),
            tracking: keys.tracking,
        };
        let mut look = DensityLook::read(at, &density_keys, density, attenuation)?;
        if params.surface.is_some() {
            look = look.without_local_bounds();
        }
        Ok(FieldLook { params, base, look })
    }

    /// The interior of `field` with its majorant `pyramid`: with a textured base medium, the
    /// field and the base as a two-component mixture, the base (and the field's own textured
    /// parameters) read per walk; with `grids` (a voxel interior's albedo and emission
    /// grids), a mixture of the field alone; otherwise the heterogeneous medium.
    pub fn build(
        self,
        at: &Site,
        field: DensityField,
        pyramid: MajorantPyramid,
        grids: Option<(Option<AlbedoGrid>, Option<EmissionGrid>)>,
        tracking: Option<&TrackingDesc>,
    ) -> Result<BuiltInterior, SceneError> {
        let FieldLook { params, base, look } = self;
        let mode = look.mode;
        if base.is_textured() {
            let textures = vec![field_textures(&params, &look), base.textures(&look)];
            let (albedo, emission) = grids.unwrap_or((None, None));
            let medium = look.into_mixture(at, field, pyramid, albedo, emission, tracking)?;
            return super::mixture::with_base_textures(at, medium, textures, params.nee);
        }
        let medium = match grids {
            Some((albedo, emission)) => {
                look.into_mixture(at, field, pyramid, albedo, emission, tracking)?
            }
            None => look.into_medium(at, field, pyramid)?,
        };
        Ok(params.finish(medium, mode))
    }
}

/// How a walk reads a field's own coefficients per unit density: the textured `albedo`,
/// `attenuation` and `density` of `params`, or fixed when none is a texture.
fn field_textures(params: &FieldParams, look: &DensityLook) -> ComponentTextures {
    if !params.is_textured() {
        return ComponentTextures::Fixed;
    }
    ComponentTextures::Field(FieldTextures {
        albedo: params.albedo.clone(),
        attenuation: params.attenuation.clone(),
        density: params.density.clone(),
        mode: look.mode,
        mean_cosine: look.mean_cosine(),
    })
}

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
            if base_attenuation.0.iter().any(|v| v.is_nan() || *v <= 0.0) {
                return Err(at.invalid(format!(
                    "{}.base_attenuation = {:?}: every channel must be a distance > 0",
                    at.owner, base_attenuation.0
                )));
            }
            let base = scattering.coefficients_of(base_albedo, base_attenuation, 1.0);
            coefficients.base_t = base.sigma_t();
            coefficients.base_s = base.sigma_s;
        }
        let mut tracking = build_tracking(at, keys.tracking)?;
        default_local_bounds(&mut tracking, keys.tracking, &coefficients);
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
            mips: None,
        };
        medium
            .attach_local_bounds()
            .map_err(|e| at.invalid(format!("{}: local bounds: {e}", at.owner)))?;
        Ok(Medium::Heterogeneous(Box::new(medium)))
    }
}

impl DensityLook {
    /// The look without local bounds: for surface-projected fields, whose per-channel
    /// trackers do not read them (no table is built).
    pub fn without_local_bounds(mut self) -> Self {
        self.tracking.local_bounds = false;
        self
    }

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
                mips: None,
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
