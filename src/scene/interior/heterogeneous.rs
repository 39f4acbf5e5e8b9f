//! What `voxel` and `fbm` interiors share besides their density field: the coefficients per
//! unit density, the optional homogeneous base medium of a combined interior, the phase
//! function and the estimator choices.

use super::scattering::Scattering;
use super::tracking::build_tracking;
use super::Site;
use crate::majorant::MajorantPyramid;
use crate::medium::{
    AlbedoGrid, AlbedoMode, Coefficients, ComponentDensity, DensityField, EmissionGrid,
    HeterogeneousMedium, Medium, MixtureComponent, MixtureMedium,
};
use crate::phase::PhaseFunction;
use crate::scene::desc::{ColorValue, PhaseDesc, TrackingDesc};
use crate::scene::SceneError;
use crate::spectrum::Rgb;
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
