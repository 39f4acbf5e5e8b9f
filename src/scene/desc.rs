//! The TOML scene file as written by users: plain serde structures with every key optional
//! where a default exists, and `deny_unknown_fields` everywhere so that a misspelt key is an
//! error. Validation and defaults live in [`super::build`]. Keys are documented in
//! `docs/scene-format.md`.

use serde::Deserialize;

/// A colour given either as one number (grey) or as `[r, g, b]`.
#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(untagged)]
pub enum ColorValue {
    /// The same value in every channel.
    Scalar(f32),
    /// Per channel.
    Rgb([f32; 3]),
}

/// A scale given either as one number (uniform) or per axis.
#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(untagged)]
pub enum ScaleValue {
    /// Uniform scale.
    Uniform(f32),
    /// Per-axis scale.
    PerAxis([f32; 3]),
}

/// Tiles given either as one number (both axes) or as `[u, v]`.
#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(untagged)]
pub enum TilesValue {
    /// The same count along `u` and `v`.
    Uniform(f32),
    /// Per axis.
    PerAxis([f32; 2]),
}

/// A fabric mip level: a number, or `"auto"` (chosen from the camera's pixel footprint).
#[derive(Clone, Debug, Deserialize)]
#[serde(untagged)]
pub enum MipValue {
    /// A fixed level (0 = full resolution; negative values are rejected with the range).
    Level(i64),
    /// A named choice: `"auto"`.
    Named(String),
}

/// The whole file.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneFile {
    /// `[camera]`.
    pub camera: Option<CameraDesc>,
    /// `[film]`.
    pub film: Option<FilmDesc>,
    /// `[[light]]` tables.
    #[serde(default)]
    pub light: Vec<toml::Spanned<LightDesc>>,
    /// `[[object]]` tables.
    #[serde(default)]
    pub object: Vec<toml::Spanned<ObjectDesc>>,
}

/// `[camera]`.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraDesc {
    /// "pinhole" (default) or "thin_lens".
    #[serde(rename = "type")]
    pub kind: Option<String>,
    /// Eye position.
    pub eye: Option<[f32; 3]>,
    /// Point looked at.
    pub look_at: Option<[f32; 3]>,
    /// Up vector.
    pub up: Option<[f32; 3]>,
    /// Vertical field of view, degrees.
    pub fov: Option<f32>,
    /// Lens radius (thin lens), world units.
    pub aperture_radius: Option<f32>,
    /// Focus distance (thin lens), world units.
    pub focus_distance: Option<f32>,
}

/// `[film]`.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FilmDesc {
    /// Image width, pixels.
    pub width: Option<u32>,
    /// Image height, pixels.
    pub height: Option<u32>,
    /// Samples per pixel.
    pub spp: Option<u32>,
    /// Random seed.
    pub seed: Option<u64>,
    /// Maximum number of scattering events per path.
    pub max_depth: Option<u32>,
    /// Output EXR path (relative to the scene file's folder).
    pub output: Option<String>,
    /// Exposure of the PNG preview, stops.
    pub exposure: Option<f32>,
}

/// `[[light]]`.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LightDesc {
    /// "environment", "envmap", "distant" or "sphere".
    #[serde(rename = "type")]
    pub kind: String,
    /// Radiance (environment, sphere).
    pub radiance: Option<ColorValue>,
    /// Lat-long EXR file (envmap).
    pub file: Option<String>,
    /// Multiplier (envmap).
    pub scale: Option<f32>,
    /// Rotation about +y, degrees (envmap).
    pub rotation: Option<f32>,
    /// Direction towards the light (distant).
    pub direction: Option<[f32; 3]>,
    /// Irradiance at normal incidence (distant).
    pub irradiance: Option<ColorValue>,
    /// Angular radius, degrees (distant).
    pub angular_radius: Option<f32>,
    /// Centre (sphere).
    pub center: Option<[f32; 3]>,
    /// Radius (sphere).
    pub radius: Option<f32>,
}

/// `[[object]]`.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObjectDesc {
    /// A name used in messages.
    pub name: Option<String>,
    /// "mesh", "sphere" or "bounds" (the box around a voxel interior's grid).
    pub shape: String,
    /// PLY file (mesh), relative to the scene file's folder.
    pub file: Option<String>,
    /// Centre (sphere), object space.
    pub center: Option<[f32; 3]>,
    /// Radius (sphere), object space.
    pub radius: Option<f32>,
    /// Translation.
    pub translate: Option<[f32; 3]>,
    /// Rotation: Euler angles in degrees about x, then y, then z.
    pub rotate: Option<[f32; 3]>,
    /// Scale.
    pub scale: Option<ScaleValue>,
    /// Priority for nested or overlapping interiors (higher wins).
    pub priority: Option<i32>,
    /// The boundary's scattering model.
    pub surface: Option<SurfaceDesc>,
    /// What fills the object.
    pub interior: Option<InteriorDesc>,
}

/// `surface = { ... }`.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SurfaceDesc {
    /// "dielectric", "diffuse_transmission", "lambertian" or "conductor".
    #[serde(rename = "type")]
    pub kind: String,
    /// Index of refraction of the interior (dielectric; default 1.4).
    pub ior: Option<f32>,
    /// Roughness in [0, 1] (α = roughness²).
    pub roughness: Option<f32>,
    /// "ggx" (default) or "beckmann".
    pub distribution: Option<String>,
    /// Multiplier on transmission (dielectric).
    pub tint: Option<ColorValue>,
    /// Reflectance (lambertian albedo, conductor colour, diffuse_transmission reflectance).
    pub reflectance: Option<ColorValue>,
    /// Transmittance (diffuse_transmission).
    pub transmittance: Option<ColorValue>,
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
    /// Coat weight in [0, 1] (default 1).
    pub weight: Option<f32>,
}

/// `interior = { ... }`.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InteriorDesc {
    /// "absorption", "homogeneous", "voxel" or "fbm".
    #[serde(rename = "type")]
    pub kind: String,
    /// Artist albedo in [0, 1] (homogeneous).
    pub albedo: Option<ColorValue>,
    /// Attenuation distance per channel (world units), > 0.
    pub attenuation: Option<ColorValue>,
    /// Density multiplier ≥ 0 (default 1).
    pub density: Option<f32>,
    /// "multiple" (default) or "single".
    pub albedo_mode: Option<String>,
    /// Phase function.
    pub phase: Option<PhaseDesc>,
    /// "exit" or "interior".
    pub nee: Option<String>,
    /// OpenVDB file (voxel), relative to the scene file.
    pub file: Option<String>,
    /// Grid name in the file (voxel; default "density").
    pub grid: Option<String>,
    /// Estimator choices (voxel, fbm).
    pub tracking: Option<TrackingDesc>,
    /// Noise parameters (fbm).
    pub noise: Option<NoiseDesc>,
    /// "baked" (default) or "exact" (fbm).
    pub evaluation: Option<String>,
    /// Voxel size of the baked/bounding lattice in the object's rest space (fbm).
    pub voxel_size: Option<f32>,
    /// "analytic", "artist" or "estimated" (fbm, exact evaluation).
    pub bound: Option<String>,
    /// Artist minimum density (bound = "artist").
    pub bound_min: Option<f32>,
    /// Artist maximum density (bound = "artist").
    pub bound_max: Option<f32>,
    /// Trial samples per brick (bound = "estimated").
    pub trial_samples: Option<u32>,
    /// Safety factor ≥ 1 on estimated bounds.
    pub safety: Option<f32>,
    /// Albedo of a homogeneous medium added to the density field (combined interiors).
    pub base_albedo: Option<ColorValue>,
    /// Attenuation distance of that homogeneous medium.
    pub base_attenuation: Option<ColorValue>,
    /// Weave pattern (fabric): "plain", "twill", "basket", "satin" or "velvet".
    pub pattern: Option<String>,
    /// Yarn preset (fabric), e.g. "cotton1", "silk", "polyester".
    pub yarn: Option<String>,
    /// Voxels across the patch's largest side (fabric).
    pub resolution: Option<u32>,
    /// Pattern repeats per side of the patch (fabric).
    pub repeats: Option<u32>,
    /// Generator seed (fabric).
    pub seed: Option<u64>,
    /// Flyaway fraction (fabric): 0 = none, 1 = as fitted.
    pub flyaways: Option<f32>,
    /// Warp yarn colour (fabric).
    pub warp_albedo: Option<ColorValue>,
    /// Weft yarn colour (fabric).
    pub weft_albedo: Option<ColorValue>,
    /// Patch tiles across the unit UV square (fabric shell on a mesh).
    pub tiles: Option<TilesValue>,
    /// Mip level of the voxelised patch (fabric): 0–6 or "auto".
    pub mip: Option<MipValue>,
    /// "fibre" (default: projected fibre width) or "isotropic" extinction (fabric).
    pub extinction: Option<String>,
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
}

/// `noise = { ... }`: procedural fBm density.
#[derive(Clone, Debug, Deserialize)]
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
