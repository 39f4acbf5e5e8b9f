//! Scenes: the only module that reads scene files and calls loaders. It turns a TOML file
//! (documented key by key in `docs/scene-format.md`) into an immutable [`Scene`] of index
//! handles: objects, media, lights and one [`SceneGeometry`].
//!
//! One file per job: `read` turns the text into the descriptions of [`desc`]; `validate`
//! holds the shared checks; `camera` builds the film and camera, `lights` the lights,
//! `objects` the shapes, transforms and object list, `surface` the boundaries and `interior`
//! the media (a file per kind of interior); `nee` resolves the default next event estimation
//! of each interior from its boundary and the lights; `place` places the objects (and builds
//! the geometry beside their interiors where it can); `build` puts them together in named
//! steps. The fabric level-of-detail policy the interiors apply is [`crate::fabric::lod`].

mod build;
mod camera;
mod context;
pub mod desc;
mod interior;
mod lights;
mod nee;
mod objects;
mod place;
mod read;
mod surface;
mod textures;
mod validate;

use std::path::{Path, PathBuf};

use crate::bsdf::{Coat, MicrofacetDistribution, Surface};
use crate::camera::Camera;
use crate::geometry::SceneGeometry;
use crate::light::{Light, LightSampler};
use crate::medium::{Medium, NeeStrategy, WalkInterior};
use crate::texture::{ColorParam, ScalarParam};

pub use build::{load_scene, load_scene_str, DEFAULT_SCENE_NAME, DEFAULT_SCENE_TEXT};
pub use nee::guided_boundary;

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
    /// When and how Russian roulette ends paths.
    pub roulette: Roulette,
    /// Output EXR path; the PNG preview goes next to it.
    pub output: PathBuf,
    /// PNG exposure, stops.
    pub exposure: f32,
}

/// Russian roulette on path throughput: after [`Roulette::start_depth`] scattering events, a
/// path whose largest throughput component β (times the η-scale of its refractions) is below
/// [`Roulette::threshold`] survives with probability β / threshold and then carries
/// throughput `threshold`. A threshold of 1 is pbrt-v4's and Mitsuba 3's rule (survival
/// probability β); a lower threshold lets paths keep going at lower weight, which pays where
/// high scattering orders carry much of the image (dense, bright media; docs/scene-format.md,
/// `[film]`). Unbiased for any setting: it only trades variance against cost.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Roulette {
    /// Scattering events (surface and volume) before roulette may play.
    pub start_depth: u32,
    /// Throughput below which roulette plays, in (0, 1].
    pub threshold: f32,
}

impl Roulette {
    /// The default: from depth 5, threshold 0.5 (measured in docs/BENCHMARKS.md, "Russian
    /// roulette's threshold").
    pub const DEFAULT: Roulette = Roulette {
        start_depth: 5,
        threshold: 0.5,
    };
}

/// Parameters of a dielectric boundary, turned into a [`Surface`] at each hit once the media
/// on both sides (and so the relative IOR) are known, and the textured parameters read at
/// the hit's texture coordinates; an untextured boundary seen from air (the common case)
/// uses the surface built once at load ([`DielectricParams::in_air`]) instead.
#[derive(Clone, Debug)]
pub struct DielectricParams {
    /// IOR of the object's interior.
    pub ior: f32,
    /// Roughness in [0, 1].
    pub roughness: ScalarParam,
    /// Microfacet distribution.
    pub distribution: MicrofacetDistribution,
    /// Transmission tint.
    pub tint: ColorParam,
    /// The least probability of sampling reflection from outside
    /// ([`crate::bsdf::Surface::with_reflect_floor`]; 0: by Fresnel alone).
    pub min_reflect_probability: f32,
    /// Optional coat.
    pub coat: Option<CoatParams>,
    /// The surface against an outside of IOR exactly 1 (relative IOR `ior`), built once when
    /// the scene is loaded if no parameter is textured (`None` otherwise): the surface every
    /// hit from air builds, so hits can borrow it instead of building and checking it again.
    pub in_air: Option<Surface>,
}

/// A coat over a boundary whose [`Surface`] is built at each hit: the coat itself, with its
/// albedo table tabulated once when the scene is loaded, and its weight, which may be a
/// texture.
#[derive(Clone, Debug)]
pub struct CoatParams {
    /// The coat at weight 1 (relative index and roughness fixed for the object).
    pub coat: Coat,
    /// The coat weight in [0, 1].
    pub weight: ScalarParam,
}

impl CoatParams {
    /// `surface` under this coat at the weight read at texture coordinates `uv` (footprint
    /// `width_uv`); `None` where the weight read is out of range.
    #[must_use]
    pub fn over(&self, surface: Surface, uv: crate::math::Vec2, width_uv: f32) -> Option<Surface> {
        surface
            .with_prepared_coat(&self.coat, self.weight.eval(uv, width_uv))
            .ok()
    }
}

impl DielectricParams {
    /// True when a parameter is a texture.
    #[must_use]
    pub fn is_textured(&self) -> bool {
        self.roughness.is_textured()
            || self.tint.is_textured()
            || self.coat.as_ref().is_some_and(|c| c.weight.is_textured())
    }
}

/// A boundary that does not depend on the neighbouring media but has textured parameters:
/// its [`Surface`] is built at each hit from the parameters read at the hit's texture
/// coordinates.
#[derive(Clone, Debug)]
pub struct TexturedSurface {
    /// The scattering model and its parameters.
    pub kind: TexturedKind,
    /// Optional coat.
    pub coat: Option<CoatParams>,
}

/// The scattering models of a [`TexturedSurface`].
#[derive(Clone, Debug)]
pub enum TexturedKind {
    /// Diffuse reflection and transmission.
    DiffuseTransmission {
        /// Diffuse reflectance.
        reflectance: ColorParam,
        /// Diffuse transmittance.
        transmittance: ColorParam,
    },
    /// An opaque diffuse reflector.
    Lambertian {
        /// Albedo.
        reflectance: ColorParam,
    },
    /// An opaque metal-like reflector.
    Conductor {
        /// Colour at normal incidence.
        reflectance: ColorParam,
        /// Roughness in [0, 1].
        roughness: ScalarParam,
        /// Microfacet distribution.
        distribution: MicrofacetDistribution,
    },
}

impl TexturedSurface {
    /// The surface at texture coordinates `uv` for a footprint `width_uv` wide (texture
    /// units); `None` if the parameters there do not make a valid surface.
    #[must_use]
    pub fn at(&self, uv: crate::math::Vec2, width_uv: f32) -> Option<Surface> {
        let s = match &self.kind {
            TexturedKind::DiffuseTransmission {
                reflectance,
                transmittance,
            } => Surface::diffuse_transmission(
                reflectance.eval(uv, width_uv),
                transmittance.eval(uv, width_uv),
            )
            .ok()?,
            TexturedKind::Lambertian { reflectance } => {
                Surface::lambertian(reflectance.eval(uv, width_uv)).ok()?
            }
            TexturedKind::Conductor {
                reflectance,
                roughness,
                distribution,
            } => Surface::conductor_from_reflectance_with(
                reflectance.eval(uv, width_uv),
                roughness.eval(uv, width_uv),
                *distribution,
            )
            .ok()?,
        };
        match &self.coat {
            Some(c) => c.over(s, uv, width_uv),
            None => Some(s),
        }
    }

    /// True when light can cross the boundary somewhere.
    #[must_use]
    pub fn transmits(&self) -> bool {
        match &self.kind {
            TexturedKind::DiffuseTransmission { transmittance, .. } => {
                !transmittance.max().is_black()
            }
            TexturedKind::Lambertian { .. } | TexturedKind::Conductor { .. } => false,
        }
    }
}

/// Two boundaries mixed per hit by a mask (`surface = { type = "blend", ... }`).
#[derive(Clone, Debug)]
pub struct SurfaceBlend {
    /// The probability of `a`, in [0, 1].
    pub mask: ScalarParam,
    /// The first surface.
    pub a: ObjectSurface,
    /// The second surface.
    pub b: ObjectSurface,
}

/// The scattering model of an object's boundary.
// One per object (or two for a blend), read at every hit: a dielectric's surface built at load
// (`DielectricParams::in_air`) is kept inline rather than behind a pointer.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug)]
pub enum ObjectSurface {
    /// A dielectric whose relative IOR depends on the neighbouring interiors.
    Dielectric(DielectricParams),
    /// A surface that does not depend on the neighbouring media.
    Fixed(Surface),
    /// A surface that does not depend on the neighbouring media, with textured parameters.
    Textured(Box<TexturedSurface>),
    /// At each hit, surface `a` with probability mask(uv), else `b` (both dielectrics of the
    /// same IOR, or neither, and both transmitting or neither).
    Blend(Box<SurfaceBlend>),
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
            ObjectSurface::Textured(s) => s.transmits(),
            ObjectSurface::Blend(b) => b.a.transmits() || b.b.transmits(),
        }
    }

    /// The surface used at a hit at texture coordinates `uv` with a footprint `width_uv`
    /// wide: itself, or a blend's `a` when `u < mask(uv)`, else its `b`.
    #[inline]
    #[must_use]
    pub fn pick(&self, uv: crate::math::Vec2, width_uv: f32, u: f32) -> &ObjectSurface {
        match self {
            ObjectSurface::Blend(b) => {
                if u < b.mask.eval(uv, width_uv) {
                    &b.a
                } else {
                    &b.b
                }
            }
            other => other,
        }
    }

    /// True when a parameter is read from a texture.
    #[must_use]
    pub fn is_textured(&self) -> bool {
        match self {
            ObjectSurface::Dielectric(d) => d.is_textured(),
            ObjectSurface::Textured(_) | ObjectSurface::Blend(_) => true,
            ObjectSurface::Fixed(_) | ObjectSurface::Null => false,
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
    /// The interior as the scene file describes it (`fbm (baked)`, `voxel`, …), for the render
    /// summary; empty without an interior.
    pub interior_kind: String,
    /// An interior resolved per walk (entry-projected textures, a blend), `medium` being its
    /// stand-in where no entry point is known.
    pub walk: Option<Box<WalkInterior>>,
    /// Texture units per world unit on the surface (for texture footprints; 0 when nothing
    /// of the object is textured).
    pub uv_scale: f32,
    /// The same per triangle of a textured mesh (empty otherwise: `uv_scale` applies).
    pub uv_scales: Vec<f32>,
}

impl Object {
    /// Texture units per world unit at triangle `prim` (the whole object's figure for spheres
    /// and untextured objects).
    #[inline]
    #[must_use]
    pub fn uv_scale_at(&self, prim: u32) -> f32 {
        self.uv_scales
            .get(prim as usize)
            .copied()
            .unwrap_or(self.uv_scale)
    }
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
    /// Light selection by power (the guided and manifold connections' choice).
    pub light_sampler: LightSampler,
    /// Light selection for next event estimation from path vertices
    /// ([`LightSampler::for_nee`]: a constant sky beside other lights at a tenth of its share).
    pub nee_light_sampler: LightSampler,
    /// The delta sun a medium's `sun_lean` estimate leans towards
    /// ([`crate::light::brightest_delta_sun`]), found once at load.
    pub brightest_delta_sun: Option<usize>,
    /// The distant light, delta or disc, the fibre vertices' sun lean leans towards
    /// ([`crate::light::brightest_distant`]), found once at load.
    pub brightest_sun: Option<usize>,
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
    /// Per light of [`Scene::lights`]: its beauty layer's slot, for named lights.
    pub light_layers: Vec<Option<u8>>,
    /// The names of the light layers, by slot.
    pub light_layer_names: Vec<String>,
    /// The radiance a ray escaping the scene sees from every direction
    /// ([`crate::light::direction_free_escape`]), where it is the same for every direction
    /// and no light has a layer of its own; `None` otherwise. Found once at load: a path
    /// that escapes without NEE at its last vertex adds it without visiting the lights.
    pub escape_radiance: Option<crate::spectrum::Rgb>,
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
