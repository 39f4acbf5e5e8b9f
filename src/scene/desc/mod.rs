//! The TOML scene file as written by users: plain serde structures with every key optional
//! where a default exists, and `deny_unknown_fields` everywhere so that a misspelt key is an
//! error. Keys are documented in `docs/scene-format.md`.
//!
//! Tables with a `type` key (lights, surfaces, interiors) have one description per type, so a
//! key that the chosen type does not use is an unknown key of that description: [`LightDesc`],
//! [`SurfaceDesc`] and [`InteriorDesc`] hold one struct per type. They are read by the scene
//! reader in two steps (the `type`, then the rest of the table into that type's struct) so
//! that every error keeps the line of its key. Validation and defaults live in the builder.

mod interior;
mod light;
mod surface;
mod texture;

use serde::Deserialize;
use toml::Spanned;

pub use texture::{ColorInput, MaskDesc, ScalarInput, TextureDesc};

pub use interior::{
    AbsorptionDesc, BlendDesc, FabricDesc, FbmDesc, FibrePhaseDesc, HomogeneousDesc, InteriorDesc,
    MixtureDesc, NoiseDesc, PhaseDesc, TrackingDesc, VoxelDesc,
};
pub use light::{
    DistantLightDesc, EnvironmentLightDesc, EnvmapLightDesc, LightDesc, SphereLightDesc,
};
pub use surface::{
    CoatDesc, ConductorDesc, DielectricDesc, DiffuseTransmissionDesc, LambertianDesc,
    SurfaceBlendDesc, SurfaceDesc,
};

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
#[derive(Clone, Debug, Default)]
pub struct SceneFile {
    /// `[camera]`.
    pub camera: Option<CameraDesc>,
    /// `[film]`.
    pub film: Option<FilmDesc>,
    /// `[[light]]` tables, with their place in the file.
    pub light: Vec<Spanned<LightDesc>>,
    /// `[[object]]` tables, with their place in the file.
    pub object: Vec<Spanned<ObjectDesc>>,
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
#[derive(Clone, Debug, Default, Deserialize)]
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
    /// Scattering events before Russian roulette may end a path.
    pub roulette_depth: Option<u32>,
    /// Path throughput below which Russian roulette plays (survivors carry this throughput).
    pub roulette_threshold: Option<f32>,
    /// Output EXR path (relative to the working directory).
    pub output: Option<String>,
    /// Exposure of the PNG preview, stops.
    pub exposure: Option<f32>,
}

/// `[[object]]`.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObjectDesc {
    /// A name used in messages.
    pub name: Option<String>,
    /// "mesh", "sphere", "bounds" (the box around a voxel or fabric interior's grid) or
    /// "levelset" (the zero crossing of a VDB level set).
    pub shape: String,
    /// PLY file (mesh) or OpenVDB file (levelset), relative to the scene file's folder.
    pub file: Option<String>,
    /// The level-set grid's name in `file` (levelset; default "surface").
    pub grid: Option<String>,
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
    /// The boundary's scattering model (`surface = { type = ... }`), with its place in the
    /// file. Its `type` picks the description, so the reader fills it in a second step.
    #[serde(skip)]
    pub surface: Option<Spanned<SurfaceDesc>>,
    /// What fills the object (`interior = { type = ... }`), with its place in the file; read
    /// like `surface`.
    #[serde(skip)]
    pub interior: Option<Spanned<InteriorDesc>>,
}

impl ObjectDesc {
    /// The keys of an `[[object]]` table that are not read with serde (their `type` picks the
    /// description).
    pub const TYPED_KEYS: [&'static str; 2] = ["surface", "interior"];
}

/// A table whose `type` key picks one of several descriptions (a light, surface or interior).
pub(in crate::scene) trait TypedTable: Sized {
    /// Every accepted `type`, in the order messages list them.
    const TYPES: &'static [&'static str];

    /// Reads the keys of a table of type `kind` (its `type` key removed) into that type's
    /// description; `Ok(None)` when `kind` is not one of [`Self::TYPES`].
    fn read<'de, D: serde::Deserializer<'de>>(
        kind: &str,
        keys: D,
    ) -> Result<Option<Self>, D::Error>;

    /// The keys of a table of type `kind` that hold nested tables of the same kind (a
    /// blend's `a` and `b` interiors), read by the reader like the table itself.
    fn nested_keys(_kind: &str) -> &'static [&'static str] {
        &[]
    }

    /// The keys of [`Self::nested_keys`] that hold an *array* of nested tables (a mixture's
    /// `media`): each element is read and stored with [`Self::set_nested`], in order.
    fn nested_list_keys(_kind: &str) -> &'static [&'static str] {
        &[]
    }

    /// Stores a nested table read for one of [`Self::nested_keys`].
    fn set_nested(&mut self, _key: &str, _value: Spanned<Self>) {}
}
