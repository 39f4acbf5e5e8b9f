//! `interior = { ... }`: one description per interior `type`, and the tables they nest
//! (`phase`, `tracking`, `noise`).

use serde::Deserialize;

use toml::Spanned;

use super::{ColorInput, ColorValue, MipValue, ScalarInput, TilesValue, TypedTable};

/// An object's `interior` table, by its `type`.
#[derive(Clone, Debug)]
pub enum InteriorDesc {
    /// `type = "absorption"`.
    Absorption(AbsorptionDesc),
    /// `type = "homogeneous"`.
    Homogeneous(HomogeneousDesc),
    /// `type = "voxel"`.
    Voxel(VoxelDesc),
    /// `type = "fbm"`.
    Fbm(FbmDesc),
    /// `type = "fabric"`.
    Fabric(FabricDesc),
    /// `type = "blend"`.
    Blend(BlendDesc),
    /// `type = "mixture"`.
    Mixture(MixtureDesc),
}

/// `type = "absorption"`: absorbing only (coloured glass), σ_a = density / attenuation.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AbsorptionDesc {
    /// Attenuation distance per channel (world units), > 0 (default 1); may be a texture.
    pub attenuation: Option<ColorInput>,
    /// Density multiplier ≥ 0 (default 1); may be a texture.
    pub density: Option<ScalarInput>,
    /// "exit" or "interior".
    pub nee: Option<String>,
    /// How textured parameters are read: "entry" (the default: at the entry point) or
    /// "surface" (at the boundary point closest to every lookup; needs a mesh with UVs).
    pub projection: Option<String>,
}

/// `type = "homogeneous"`: a scattering medium of constant density.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HomogeneousDesc {
    /// Artist albedo in [0, 1] (default 0.8); may be a texture.
    pub albedo: Option<ColorInput>,
    /// "multiple" (default) or "single".
    pub albedo_mode: Option<String>,
    /// Attenuation distance per channel (world units), > 0 (default 1); may be a texture.
    pub attenuation: Option<ColorInput>,
    /// Density multiplier ≥ 0 (default 1); may be a texture.
    pub density: Option<ScalarInput>,
    /// Phase function (default isotropic).
    pub phase: Option<PhaseDesc>,
    /// "exit" or "interior".
    pub nee: Option<String>,
    /// How textured parameters are read: "entry" (the default: at the entry point) or
    /// "surface" (at the boundary point closest to every lookup; needs a mesh with UVs).
    pub projection: Option<String>,
}

/// `type = "blend"`: each path entering the object picks interior `a` with probability
/// mask(uv) at its entry point, else `b`, and keeps it for its walk.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BlendDesc {
    /// The probability of `a`: a number in [0, 1] or a texture table with values in [0, 1]
    /// (required).
    pub mask: Option<ScalarInput>,
    /// "exit" or "interior" (for both looks).
    pub nee: Option<String>,
    /// The first look (an interior table; read by the scene reader, as its `type` picks it).
    #[serde(skip)]
    pub a: Option<Box<Spanned<InteriorDesc>>>,
    /// The second look.
    #[serde(skip)]
    pub b: Option<Box<Spanned<InteriorDesc>>>,
}

/// `type = "voxel"`: a density grid from an OpenVDB file, optionally added to a homogeneous
/// medium (a combined interior, `base_albedo`/`base_attenuation`).
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VoxelDesc {
    /// OpenVDB file, relative to the scene file (required).
    pub file: Option<String>,
    /// Grid name in the file (default "density").
    pub grid: Option<String>,
    /// Artist albedo in [0, 1] (default 0.8); may be a texture (read at the entry point).
    pub albedo: Option<ColorInput>,
    /// "multiple" (default) or "single".
    pub albedo_mode: Option<String>,
    /// Attenuation distance per channel at density 1 (world units), > 0 (default 1); may be a
    /// texture (read at the entry point).
    pub attenuation: Option<ColorInput>,
    /// Density multiplier ≥ 0 (default 1); may be a texture (read at the entry point).
    pub density: Option<ScalarInput>,
    /// How textured parameters are read: "entry" (the default; the only mode for density
    /// fields).
    pub projection: Option<String>,
    /// Phase function (default isotropic).
    pub phase: Option<PhaseDesc>,
    /// "exit" or "interior".
    pub nee: Option<String>,
    /// Albedo of a homogeneous medium added to the density field (combined interior); may be
    /// a texture (read at the entry point).
    pub base_albedo: Option<ColorInput>,
    /// Attenuation distance of that homogeneous medium; may be a texture (read at the entry
    /// point).
    pub base_attenuation: Option<ColorInput>,
    /// Estimator choices.
    pub tracking: Option<TrackingDesc>,
    /// Name of a grid giving the artist albedo per voxel: a Vec3 grid, or a scalar grid
    /// through `albedo_ramp` (same transform as the density grid).
    pub albedo_grid: Option<String>,
    /// `[[value, colour], ...]` stops (sorted by value) mapping a scalar albedo grid to colours.
    pub albedo_ramp: Option<Vec<(f32, ColorValue)>>,
    /// OpenVDB file of the albedo grid, relative to the scene file (default: `file`).
    pub albedo_file: Option<String>,
    /// Name of a grid of emitted radiance: Vec3, or scalar times `emission_color`.
    pub emission_grid: Option<String>,
    /// Colour a scalar emission grid is multiplied by (default 1).
    pub emission_color: Option<ColorValue>,
    /// OpenVDB file of the emission or temperature grid (default: `file`).
    pub emission_file: Option<String>,
    /// Name of a scalar temperature grid emitting blackbody radiance.
    pub temperature_grid: Option<String>,
    /// Kelvin per unit of the temperature grid (default 1), ≥ 0.
    pub temperature_scale: Option<f32>,
    /// Multiplier of the emitted radiance (default 1), ≥ 0.
    pub emission_scale: Option<f32>,
}

/// `type = "mixture"`: two to four media filling the same object, each with its own albedo,
/// attenuation, density source and phase function.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MixtureDesc {
    /// Estimator choices of the mixture.
    pub tracking: Option<TrackingDesc>,
    /// "exit", "interior", "exit_guided" or "manifold".
    pub nee: Option<String>,
    /// The components (`homogeneous`, `voxel` or `fbm` interior tables; read by the scene
    /// reader, as their `type` picks them).
    #[serde(skip)]
    pub media: Vec<Spanned<InteriorDesc>>,
}

/// `type = "fbm"`: procedural fBm noise density in the object's rest space, optionally added
/// to a homogeneous medium like [`VoxelDesc`].
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FbmDesc {
    /// Noise parameters.
    pub noise: Option<NoiseDesc>,
    /// "baked" (default), "lazy" or "exact".
    pub evaluation: Option<String>,
    /// Voxel size of the baked/bounding lattice in the object's rest space.
    pub voxel_size: Option<f32>,
    /// "analytic", "artist" or "estimated" (lazy and exact evaluation).
    pub bound: Option<String>,
    /// Artist minimum density (bound = "artist").
    pub bound_min: Option<f32>,
    /// Artist maximum density (bound = "artist").
    pub bound_max: Option<f32>,
    /// Trial samples per brick (bound = "estimated").
    pub trial_samples: Option<u32>,
    /// Safety factor ≥ 1 on estimated bounds.
    pub safety: Option<f32>,
    /// Artist albedo in [0, 1] (default 0.8); may be a texture (read at the entry point).
    pub albedo: Option<ColorInput>,
    /// "multiple" (default) or "single".
    pub albedo_mode: Option<String>,
    /// Attenuation distance per channel at density 1 (world units), > 0 (default 1); may be a
    /// texture (read at the entry point).
    pub attenuation: Option<ColorInput>,
    /// Density multiplier ≥ 0 (default 1); may be a texture (read at the entry point).
    pub density: Option<ScalarInput>,
    /// How textured parameters are read: "entry" (the default; the only mode for density
    /// fields).
    pub projection: Option<String>,
    /// Phase function (default isotropic).
    pub phase: Option<PhaseDesc>,
    /// "exit" or "interior".
    pub nee: Option<String>,
    /// Albedo of a homogeneous medium added to the density field (combined interior); may be
    /// a texture (read at the entry point).
    pub base_albedo: Option<ColorInput>,
    /// Attenuation distance of that homogeneous medium; may be a texture (read at the entry
    /// point).
    pub base_attenuation: Option<ColorInput>,
    /// Estimator choices.
    pub tracking: Option<TrackingDesc>,
}

/// `type = "fabric"`: a procedurally woven, voxelised patch, free-standing or as a shell over
/// a mesh.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FabricDesc {
    /// A patch written by `velour weave` (OpenVDB with grids density, tangent, id and the
    /// generator parameters as metadata), relative to the scene file. The generator keys
    /// below must then agree with the file's metadata when given.
    pub file: Option<String>,
    /// Weave pattern: "plain" (default), "twill", "basket", "satin" or "velvet".
    pub pattern: Option<String>,
    /// Yarn preset of warp and weft, e.g. "cotton1" (default), "silk1", "polyester1".
    pub yarn: Option<String>,
    /// Yarn preset of the warps (overrides `yarn` for the warps).
    pub warp_yarn: Option<String>,
    /// Yarn preset of the wefts (overrides `yarn` for the wefts).
    pub weft_yarn: Option<String>,
    /// Voxels across the patch's largest side (default 128).
    pub resolution: Option<u32>,
    /// Pattern repeats per side of the patch (default 1).
    pub repeats: Option<u32>,
    /// Generator seed (default 1).
    pub seed: Option<u64>,
    /// Flyaway fraction: 0 = none, 1 = as fitted (default).
    pub flyaways: Option<f32>,
    /// Warp yarn colour: a constant or a texture read at the entry point.
    pub warp_albedo: Option<ColorInput>,
    /// Weft yarn colour: a constant or a texture read at the entry point.
    pub weft_albedo: Option<ColorInput>,
    /// Pile (velvet) fibre colour: a constant or a texture read at the entry point.
    pub pile_albedo: Option<ColorInput>,
    /// Fibre scattering parameters shared by the yarn families.
    pub fibre_phase: Option<FibrePhaseDesc>,
    /// Patch tiles across the unit UV square (shell on a mesh only).
    pub tiles: Option<TilesValue>,
    /// Mip level of the voxelised patch: 0–6 or "auto".
    pub mip: Option<MipValue>,
    /// "fibre" (default: projected fibre width) or "isotropic" extinction.
    pub extinction: Option<String>,
    /// Attenuation distance per unit fibre fraction (world units), > 0 (default 1).
    pub attenuation: Option<ColorValue>,
    /// Density multiplier ≥ 0 (default 1).
    pub density: Option<f32>,
    /// "exit" or "interior".
    pub nee: Option<String>,
    /// With `nee = "interior"`: the sun-leaned estimate of the next vertex's sun light at
    /// every fibre vertex (default true; docs/fabric.md, "The sun lean at fibre vertices").
    pub sun_lean: Option<bool>,
}

/// `fibre_phase = { ... }`: the fibre scattering parameters of a fabric interior (Chiang et
/// al. 2016 plus a diffuse lobe); the absorption and diffuse albedo come from each yarn's
/// colour.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FibrePhaseDesc {
    /// Fibre index of refraction, [1, 3] (default 1.55).
    pub eta: Option<f32>,
    /// Longitudinal roughness β_m, [0.01, 1] (default 0.3).
    pub beta_m: Option<f32>,
    /// Azimuthal roughness β_n, [0.01, 1] (default 0.3).
    pub beta_n: Option<f32>,
    /// Cuticle tilt α in radians, [−0.2, 0.2] (default 0).
    pub alpha: Option<f32>,
    /// Weight of the diffuse lobe, [0, 1] (default 0.3).
    pub diffuse_weight: Option<f32>,
}

/// `tracking = { ... }`: estimator choices of a heterogeneous interior.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrackingDesc {
    /// "delta" (default) or "ray_march".
    pub free_flight: Option<String>,
    /// "residual" (default), "ratio" or "ray_march".
    pub transmittance: Option<String>,
    /// Control variate of residual ratio tracking: "novak" (default), "mean" or "minorant".
    pub control: Option<String>,
    /// "pyramid" (default) or "global".
    pub majorant: Option<String>,
    /// Finest pyramid level used (0 = bricks; default 0).
    pub level: Option<u8>,
    /// Ray-marching step, world units.
    pub step: Option<f32>,
    /// Decide tentative collisions from per-point local bounds before looking the density up.
    pub local_bounds: Option<bool>,
    /// The light behind the medium: "survive" (default) or "transmittance".
    pub behind: Option<String>,
    /// The sun-leaned estimate of light scattered at the next vertex (default true).
    pub sun_lean: Option<bool>,
}

/// `noise = { ... }`: procedural fBm density.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NoiseDesc {
    /// Base frequency, 1/length in rest space.
    pub frequency: Option<f32>,
    /// Octaves.
    pub octaves: Option<u32>,
    /// Frequency multiplier per octave.
    pub lacunarity: Option<f32>,
    /// Amplitude multiplier per octave.
    pub gain: Option<f32>,
    /// Noise scale.
    pub amplitude: Option<f32>,
    /// Offset added to the scaled noise.
    pub offset: Option<f32>,
    /// Lower clamp.
    pub min: Option<f32>,
    /// Upper clamp.
    pub max: Option<f32>,
    /// Seed.
    pub seed: Option<u32>,
}

/// `phase = { ... }`.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PhaseDesc {
    /// "hg" (default) or "double_hg".
    #[serde(rename = "type")]
    pub kind: Option<String>,
    /// Mean cosine (hg).
    pub g: Option<f32>,
    /// First lobe (double_hg).
    pub g1: Option<f32>,
    /// Second lobe (double_hg).
    pub g2: Option<f32>,
    /// Weight of the first lobe (double_hg).
    pub w: Option<f32>,
}

impl InteriorDesc {
    /// The `type` of the interior, as written in the file.
    #[must_use]
    pub fn kind(&self) -> &'static str {
        match self {
            InteriorDesc::Absorption(_) => "absorption",
            InteriorDesc::Homogeneous(_) => "homogeneous",
            InteriorDesc::Voxel(_) => "voxel",
            InteriorDesc::Fbm(_) => "fbm",
            InteriorDesc::Fabric(_) => "fabric",
            InteriorDesc::Blend(_) => "blend",
            InteriorDesc::Mixture(_) => "mixture",
        }
    }

    /// The `nee` key, which every interior type has.
    #[must_use]
    pub fn nee(&self) -> Option<&str> {
        match self {
            InteriorDesc::Absorption(d) => d.nee.as_deref(),
            InteriorDesc::Homogeneous(d) => d.nee.as_deref(),
            InteriorDesc::Voxel(d) => d.nee.as_deref(),
            InteriorDesc::Fbm(d) => d.nee.as_deref(),
            InteriorDesc::Fabric(d) => d.nee.as_deref(),
            InteriorDesc::Blend(d) => d.nee.as_deref(),
            InteriorDesc::Mixture(d) => d.nee.as_deref(),
        }
    }
}

impl TypedTable for InteriorDesc {
    const TYPES: &'static [&'static str] = &[
        "absorption",
        "homogeneous",
        "voxel",
        "fbm",
        "fabric",
        "blend",
        "mixture",
    ];

    fn nested_keys(kind: &str) -> &'static [&'static str] {
        match kind {
            "blend" => &["a", "b"],
            "mixture" => &["media"],
            _ => &[],
        }
    }

    fn nested_list_keys(kind: &str) -> &'static [&'static str] {
        if kind == "mixture" {
            &["media"]
        } else {
            &[]
        }
    }

    fn set_nested(&mut self, key: &str, value: Spanned<Self>) {
        match self {
            InteriorDesc::Blend(d) => match key {
                "a" => d.a = Some(Box::new(value)),
                "b" => d.b = Some(Box::new(value)),
                _ => {}
            },
            InteriorDesc::Mixture(d) if key == "media" => d.media.push(value),
            _ => {}
        }
    }

    fn read<'de, D: serde::Deserializer<'de>>(
        kind: &str,
        keys: D,
    ) -> Result<Option<Self>, D::Error> {
        Ok(Some(match kind {
            "absorption" => InteriorDesc::Absorption(AbsorptionDesc::deserialize(keys)?),
            "homogeneous" => InteriorDesc::Homogeneous(HomogeneousDesc::deserialize(keys)?),
            "voxel" => InteriorDesc::Voxel(VoxelDesc::deserialize(keys)?),
            "fbm" => InteriorDesc::Fbm(FbmDesc::deserialize(keys)?),
            "fabric" => InteriorDesc::Fabric(FabricDesc::deserialize(keys)?),
            "blend" => InteriorDesc::Blend(BlendDesc::deserialize(keys)?),
            "mixture" => InteriorDesc::Mixture(MixtureDesc::deserialize(keys)?),
            _ => return Ok(None),
        }))
    }
}
