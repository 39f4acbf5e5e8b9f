//! `surface = { ... }`: one description per surface `type`.

use serde::Deserialize;

use super::{ColorInput, ScalarInput, TypedTable};

/// An object's `surface` table, by its `type`.
#[derive(Clone, Debug)]
pub enum SurfaceDesc {
    /// `type = "dielectric"`.
    Dielectric(DielectricDesc),
    /// `type = "diffuse_transmission"`.
    DiffuseTransmission(DiffuseTransmissionDesc),
    /// `type = "lambertian"`.
    Lambertian(LambertianDesc),
    /// `type = "conductor"`.
    Conductor(ConductorDesc),
}

/// `type = "dielectric"`: a smooth or rough refracting boundary.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DielectricDesc {
    /// Index of refraction of the interior (default 1.4).
    pub ior: Option<f32>,
    /// Roughness in [0, 1] (α = roughness²; default 0).
    pub roughness: Option<ScalarInput>,
    /// "ggx" (default) or "beckmann".
    pub distribution: Option<String>,
    /// Multiplier on transmission (default 1).
    pub tint: Option<ColorInput>,
    /// Optional secondary specular coat.
    pub coat: Option<CoatDesc>,
}

/// `type = "diffuse_transmission"`: diffuse reflection and transmission.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DiffuseTransmissionDesc {
    /// Diffuse reflectance (default 0).
    pub reflectance: Option<ColorInput>,
    /// Diffuse transmittance (default 1).
    pub transmittance: Option<ColorInput>,
    /// Optional secondary specular coat.
    pub coat: Option<CoatDesc>,
}

/// `type = "lambertian"`: an opaque diffuse reflector.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LambertianDesc {
    /// Albedo (default 0.8).
    pub reflectance: Option<ColorInput>,
    /// Optional secondary specular coat.
    pub coat: Option<CoatDesc>,
}

/// `type = "conductor"`: an opaque metal-like reflector.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ConductorDesc {
    /// Colour at normal incidence (default 0.9).
    pub reflectance: Option<ColorInput>,
    /// Roughness in [0, 1] (α = roughness²; default 0).
    pub roughness: Option<ScalarInput>,
    /// "ggx" (default) or "beckmann".
    pub distribution: Option<String>,
    /// Optional secondary specular coat.
    pub coat: Option<CoatDesc>,
}

/// `coat = { ... }`.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CoatDesc {
    /// Coat IOR (default 1.5).
    pub ior: Option<f32>,
    /// Coat roughness (default 0.1).
    pub roughness: Option<f32>,
    /// Coat weight in [0, 1] (default 1); may be a texture.
    pub weight: Option<ScalarInput>,
}

impl SurfaceDesc {
    /// The coat of any surface type.
    #[must_use]
    pub fn coat(&self) -> Option<&CoatDesc> {
        match self {
            SurfaceDesc::Dielectric(d) => d.coat.as_ref(),
            SurfaceDesc::DiffuseTransmission(d) => d.coat.as_ref(),
            SurfaceDesc::Lambertian(d) => d.coat.as_ref(),
            SurfaceDesc::Conductor(d) => d.coat.as_ref(),
        }
    }

    /// The roughness of the surface types that have one.
    #[must_use]
    pub fn roughness(&self) -> Option<&ScalarInput> {
        match self {
            SurfaceDesc::Dielectric(d) => d.roughness.as_ref(),
            SurfaceDesc::Conductor(d) => d.roughness.as_ref(),
            SurfaceDesc::DiffuseTransmission(_) | SurfaceDesc::Lambertian(_) => None,
        }
    }
}

impl TypedTable for SurfaceDesc {
    const TYPES: &'static [&'static str] = &[
        "dielectric",
        "diffuse_transmission",
        "lambertian",
        "conductor",
    ];

    fn read<'de, D: serde::Deserializer<'de>>(
        kind: &str,
        keys: D,
    ) -> Result<Option<Self>, D::Error> {
        Ok(Some(match kind {
            "dielectric" => SurfaceDesc::Dielectric(DielectricDesc::deserialize(keys)?),
            "diffuse_transmission" => {
                SurfaceDesc::DiffuseTransmission(DiffuseTransmissionDesc::deserialize(keys)?)
            }
            "lambertian" => SurfaceDesc::Lambertian(LambertianDesc::deserialize(keys)?),
            "conductor" => SurfaceDesc::Conductor(ConductorDesc::deserialize(keys)?),
            _ => return Ok(None),
        }))
    }
}
