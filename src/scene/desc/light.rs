//! `[[light]]` tables: one description per light `type`.

use serde::Deserialize;

use super::{ColorValue, TypedTable};

/// A `[[light]]` table, by its `type`.
#[derive(Clone, Debug)]
pub enum LightDesc {
    /// `type = "environment"`.
    Environment(EnvironmentLightDesc),
    /// `type = "envmap"`.
    Envmap(EnvmapLightDesc),
    /// `type = "distant"`.
    Distant(DistantLightDesc),
    /// `type = "sphere"`.
    Sphere(SphereLightDesc),
}

/// `type = "environment"`: uniform radiance from every direction.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EnvironmentLightDesc {
    /// Name of the light's own beauty layer (`light.<name>.R/G/B`); unnamed lights have none.
    pub name: Option<String>,
    /// Radiance, W/(m² sr) (default 1).
    pub radiance: Option<ColorValue>,
}

/// `type = "envmap"`: a lat-long EXR environment.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EnvmapLightDesc {
    /// Name of the light's own beauty layer (`light.<name>.R/G/B`); unnamed lights have none.
    pub name: Option<String>,
    /// Lat-long EXR file, relative to the scene file's folder (required).
    pub file: Option<String>,
    /// Multiplier (default 1).
    pub scale: Option<f32>,
    /// Rotation about +y, degrees (default 0).
    pub rotation: Option<f32>,
}

/// `type = "distant"`: a sun-like disc infinitely far away.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DistantLightDesc {
    /// Name of the light's own beauty layer (`light.<name>.R/G/B`); unnamed lights have none.
    pub name: Option<String>,
    /// Direction towards the light (required).
    pub direction: Option<[f32; 3]>,
    /// Irradiance at normal incidence, W/m² (default 3).
    pub irradiance: Option<ColorValue>,
    /// Angular radius, degrees (default 0: a delta light).
    pub angular_radius: Option<f32>,
}

/// `type = "sphere"`: a spherical area light.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SphereLightDesc {
    /// Name of the light's own beauty layer (`light.<name>.R/G/B`); unnamed lights have none.
    pub name: Option<String>,
    /// Centre, world units (default the origin).
    pub center: Option<[f32; 3]>,
    /// Radius, world units (default 0.1).
    pub radius: Option<f32>,
    /// Radiance, W/(m² sr) (default 10).
    pub radiance: Option<ColorValue>,
}

impl LightDesc {
    /// The light's `name`, if it has one.
    #[must_use]
    pub fn name(&self) -> Option<&str> {
        match self {
            LightDesc::Environment(d) => d.name.as_deref(),
            LightDesc::Envmap(d) => d.name.as_deref(),
            LightDesc::Distant(d) => d.name.as_deref(),
            LightDesc::Sphere(d) => d.name.as_deref(),
        }
    }
}

impl TypedTable for LightDesc {
    const TYPES: &'static [&'static str] = &["environment", "envmap", "distant", "sphere"];

    fn read<'de, D: serde::Deserializer<'de>>(
        kind: &str,
        keys: D,
    ) -> Result<Option<Self>, D::Error> {
        Ok(Some(match kind {
            "environment" => LightDesc::Environment(EnvironmentLightDesc::deserialize(keys)?),
            "envmap" => LightDesc::Envmap(EnvmapLightDesc::deserialize(keys)?),
            "distant" => LightDesc::Distant(DistantLightDesc::deserialize(keys)?),
            "sphere" => LightDesc::Sphere(SphereLightDesc::deserialize(keys)?),
            _ => return Ok(None),
        }))
    }
}
