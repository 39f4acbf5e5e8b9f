//! `surface = { ... }`: one description per surface `type`.

use serde::Deserialize;
use toml::Spanned;

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
    /// `type = "blend"`.
    Blend(SurfaceBlendDesc),
}

/// `type = "blend"`: at each hit, surface `a` with probability mask(uv), else `b`.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SurfaceBlendDesc {
    /// The probability of `a`: a number in [0, 1] or a texture table (required).
    pub mask: Option<ScalarInput>,
    /// The first surface (a surface table; read by the scene reader, as its `type` picks it).
    #[serde(skip)]
    pub a: Option<Box<Spanned<SurfaceDesc>>>,
    /// The second surface.
    #[serde(skip)]
    pub b: Option<Box<Spanned<SurfaceDesc>>>,
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
    /// The least probability with which sampling picks reflection from outside, in
    /// [0, 0.95] (default 0: by Fresnel alone).
    pub min_reflect_probability: Option<f32>,
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
            SurfaceDesc::Blend(_) => None,
        }
    }

    /// The roughness of the surface types that have one.
    #[must_use]
    pub fn roughness(&self) -> Option<&ScalarInput> {
        match self {
            SurfaceDesc::Dielectric(d) => d.roughness.as_ref(),
            SurfaceDesc::Conductor(d) => d.roughness.as_ref(),
            SurfaceDesc::DiffuseTransmission(_)
            | SurfaceDesc::Lambertian(_)
            | SurfaceDesc::Blend(_) => None,
        }
    }
}

impl TypedTable for SurfaceDesc {
    const TYPES: &'static [&'static str] = &[
        "dielectric",
        "diffuse_transmission",
        "lambertian",
        "conductor",
        "blend",
    ];

    fn nested_keys(kind: &str) -> &'static [&'static str] {
        if kind == "blend" {
            &["a", "b"]
        } else {
            &[]
        }
    }

    fn set_nested(&mut self, key: &str, value: Spanned<Self>) {
        if let SurfaceDesc::Blend(d) = self {
            match key {
                "a" => d.a = Some(Box::new(value)),
                "b" => d.b = Some(Box::new(value)),
                _ => {}
            }
        }
    }

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
            "blend" => SurfaceDesc::Blend(SurfaceBlendDesc::deserialize(keys)?),
            _ => return Ok(None),
        }))
    }
}
