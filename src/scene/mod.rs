//! Scenes: the only module that reads scene files and calls loaders. It turns a TOML file
//! (documented key by key in `docs/scene-format.md`) into an immutable [`Scene`] of index
//! handles: objects, media, lights and one [`SceneGeometry`].
//!
//! One file per job: `read` turns the text into the descriptions of [`desc`]; `validate`
//! holds the shared checks; `camera` builds the film and camera, `lights` the lights,
//! `objects` the shapes, transforms and object list, `surface` the boundaries and `interior`
//! the media (a file per kind of interior); `build` puts them together. The fabric
//! level-of-detail policy the interiors apply is [`crate::fabric::lod`].

mod build;
mod camera;
mod context;
pub mod desc;
mod interior;
mod lights;
mod objects;
mod read;
mod surface;
mod validate;

use std::path::{Path, PathBuf};

use crate::bsdf::{MicrofacetDistribution, Surface};
use crate::camera::Camera;
use crate::geometry::SceneGeometry;
use crate::light::{Light, LightSampler};
use crate::medium::{Medium, NeeStrategy};
use crate::spectrum::Rgb;

pub use build::{load_scene, load_scene_str, DEFAULT_SCENE_NAME, DEFAULT_SCENE_TEXT};

/// Errors while reading or validating a scene.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The scene file could not be read.
    #[error("{path}: cannot read scene file: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// TOML syntax error, a misspelt/unknown key, or a value of the wrong type.
    #[error("{path}:{line}: {message}")]
    Parse {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// A value outside its allowed range, a missing key, or a loader failure.
    #[error("{path}:{line}: {message}")]
    Invalid {
        /// The file.
        path: PathBuf,
        /// 1-based line of the table holding the bad value.
        line: usize,
        /// What is wrong.
        message: String,
    },
}

/// Film and sampling settings.
#[derive(Clone, Debug, PartialEq)]
pub struct FilmSettings {
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
    /// Samples per pixel.
    pub spp: u32,
    /// Random seed.
    pub seed: u64,
    /// Maximum number of scattering events (surface and volume) per path.
    pub max_depth: u32,
    /// Output EXR path; the PNG preview goes next to it.
    pub output: PathBuf,
    /// PNG exposure, stops.
    pub exposure: f32,
}

/// Parameters of a dielectric boundary, turned into a [`Surface`] at each hit once the media
/// on both sides (and so the relative IOR) are known.
#[derive(Clone, Debug)]
pub struct DielectricParams {
    /// IOR of the object's interior.
    pub ior: f32,
    /// Roughness in [0, 1].
    pub roughness: f32,
    /// Microfacet distribution.
    pub distribution: MicrofacetDistribution,
    /// Transmission tint.
    pub tint: Rgb,
    /// Optional coat (ior, roughness, weight).
    pub coat: Option<(f32, f32, f32)>,
}

/// The scattering model of an object's boundary.
#[derive(Clone, Debug)]
pub enum ObjectSurface {
    /// A dielectric whose relative IOR depends on the neighbouring interiors.
    Dielectric(DielectricParams),
    /// A surface that does not depend on the neighbouring media.
    Fixed(Surface),
    /// An index-matched boundary that only delimits an interior (no scattering).
    Null,
}

impl ObjectSurface {
    /// True when light can cross the boundary into the object's interior.
    #[must_use]
    pub fn transmits(&self) -> bool {
        match self {
            ObjectSurface::Dielectric(_) | ObjectSurface::Null => true,
            ObjectSurface::Fixed(s) => s.has_transmission(),
        }
    }
}

/// An object of the scene.
#[derive(Clone, Debug)]
pub struct Object {
    /// Name used in messages.
    pub name: String,
    /// Boundary scattering.
    pub surface: ObjectSurface,
    /// Index into [`Scene::media`] of the interior, if any.
    pub medium: Option<u32>,
    /// Priority for nested/overlapping interiors (higher wins).
    pub priority: i32,
    /// IOR of the interior (1 when the boundary does not refract).
    pub ior: f32,
    /// NEE strategy inside this object.
    pub nee: NeeStrategy,
    /// The albedo AOV of an event in this object's interior: the artist albedo of a
    /// homogeneous, voxel or fBm interior; `None` uses the event's single-scattering albedo.
    pub aov_albedo: Option<crate::spectrum::Rgb>,
}

/// What a shape of the [`SceneGeometry`] belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ShapeOwner {
    /// An object (index into [`Scene::objects`]).
    Object(u32),
    /// A sphere light (index into [`Scene::lights`]).
    Light(u32),
}

/// The camera as described in the scene file (kept so the resolution can be overridden).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraParams {
    /// Eye position.
    pub eye: crate::math::Vec3,
    /// Point looked at.
    pub look_at: crate::math::Vec3,
    /// Up vector.
    pub up: crate::math::Vec3,
    /// Vertical field of view, degrees.
    pub fov: f32,
    /// Thin-lens (aperture radius, focus distance); `None` for a pinhole.
    pub lens: Option<(f32, f32)>,
}

impl CameraParams {
    /// Builds the camera for a film size.
    pub fn build(&self, width: u32, height: u32) -> Result<Camera, crate::camera::CameraError> {
        match self.lens {
            None => Camera::pinhole(self.eye, self.look_at, self.up, self.fov, width, height),
            Some((a, f)) => Camera::thin_lens(
                self.eye,
                self.look_at,
                self.up,
                self.fov,
                width,
                height,
                a,
                f,
            ),
        }
    }
}

/// An immutable, validated scene.
#[derive(Debug)]
pub struct Scene {
    /// Camera.
    pub camera: Camera,
    /// What the camera was built from.
    pub camera_params: CameraParams,
    /// Film settings.
    pub film: FilmSettings,
    /// Lights.
    pub lights: Vec<Light>,
    /// Light selection for NEE.
    pub light_sampler: LightSampler,
    /// All geometry.
    pub geometry: SceneGeometry,
    /// Objects.
    pub objects: Vec<Object>,
    /// Interiors.
    pub media: Vec<Medium>,
    /// Owner of each shape of `geometry`.
    pub shape_owner: Vec<ShapeOwner>,
    /// Warnings found while loading (e.g. open meshes used as interior boundaries).
    pub warnings: Vec<String>,
    /// Facts about how the scene was built (fabric shells: tiles, thickness, mip level),
    /// printed by `velour render`.
    pub notes: Vec<String>,
    /// Where the scene came from.
    pub source: PathBuf,
    /// The files the scene file names (meshes, grids, images), in the order they were resolved:
    /// with the scene file, what its content hash covers.
    pub inputs: Vec<PathBuf>,
}

impl Scene {
    /// Loads a scene file.
    pub fn load(path: &Path) -> Result<Scene, SceneError> {
        load_scene(path)
    }

    /// Changes the film resolution (and the camera's aspect ratio with it).
    pub fn set_resolution(&mut self, width: u32, height: u32) -> Result<(), SceneError> {
        let camera = self
            .camera_params
            .build(width, height)
            .map_err(|e| SceneError::Invalid {
                path: self.source.clone(),
                line: 1,
                message: format!("camera: {e}"),
            })?;
        self.camera = camera;
        self.film.width = width;
        self.film.height = height;
        Ok(())
    }
}

/// The built-in default scene (`velour render` without a scene file): the translucent
/// creature of `scenes/creature.toml`, with its meshes compiled into the binary.
pub fn default_scene() -> Result<Scene, SceneError> {
    build::default_scene()
}
