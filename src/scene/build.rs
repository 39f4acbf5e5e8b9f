//! Building a [`Scene`] from a scene file: read the descriptions, then build the film and
//! camera, the objects with their interiors, the lights and the geometry.

use std::path::{Path, PathBuf};

use super::context::Ctx;
use super::{camera, lights, objects, place, read, Scene, SceneError};
use crate::geometry::SceneGeometry;
use crate::light::{Light, LightSampler};
use crate::medium::NeeStrategy;

/// Name shown for the built-in default scene.
pub const DEFAULT_SCENE_NAME: &str = "<built-in default scene>";

/// Reads and builds a scene file.
pub fn load_scene(path: &Path) -> Result<Scene, SceneError> {
    let text = std::fs::read_to_string(path).map_err(|source| SceneError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    load_scene_str(&text, path)
}

/// Builds a scene from TOML text; `path` names it in messages and anchors relative file paths.
pub fn load_scene_str(text: &str, path: &Path) -> Result<Scene, SceneError> {
    load_scene_placing(text, path, true)
}

/// [`load_scene_str`]; with `overlap` false, the geometry is never built beside the interiors
/// (the object-by-object build, which the overlapped one must equal).
///
/// The steps, in this order (which fixes the order of the input files, warnings and notes, and
/// which error is reported first): the film and camera; the objects ([`place::place_objects`],
/// whose geometry may be building meanwhile); the lights ([`lights::build_lights`]) and the
/// sphere lights' shapes; the interiors' default NEE ([`super::nee::resolve_defaults`]) and
/// the checks of manifold NEE ([`check_manifold`]); the geometry; the light selection
/// ([`LightSelection::new`]) and the interiors' sun maps ([`prepare_sun_maps`]).
fn load_scene_placing(text: &str, path: &Path, overlap: bool) -> Result<Scene, SceneError> {
    let ctx = Ctx {
        path,
        text,
        inputs: Default::default(),
        textures: Default::default(),
    };
    let file = read::read_scene_file(&ctx)?;
    let mut warnings = Vec::new();
    let mut notes = Vec::new();
    let film = camera::build_film(&ctx, file.film.as_ref())?;
    let (camera, camera_params) = camera::build_camera(&ctx, file.camera.as_ref(), &film)?;
    let overlap = overlap && place::can_overlap(&file.object, &file.light);
    std::thread::scope(|scope| {
        let mut placed = place::place_objects(
            scope,
            &ctx,
            &file.object,
            overlap,
            &mut warnings,
            &mut notes,
        )?;
        let lights = lights::build_lights(&ctx, &file.light)?;
        placed.add_light_shapes(&lights.lights);
        super::nee::resolve_defaults(
            &mut placed.built.objects,
            &placed.built.auto_guided,
            &lights.lights,
        );
        check_manifold(&ctx, &placed.built, &lights.lights)?;
        if lights.lights.is_empty() {
            warnings.push(format!(
                "{}: the scene has no lights; the image will be black",
                ctx.path.display()
            ));
        }
        let geometry = placed.geometry(&ctx)?;
        let selection = LightSelection::new(&lights.lights, &geometry);
        prepare_sun_maps(&placed.built, &lights.lights, selection.brightest_delta_sun);
        let escape_radiance =
            if lights.layers.iter().all(Option::is_none) && lights.layer_names.is_empty() {
                crate::light::direction_free_escape(&lights.lights)
            } else {
                None
            };
        Ok(Scene {
            camera,
            camera_params,
            film,
            lights: lights.lights,
            light_sampler: selection.light_sampler,
            nee_light_sampler: selection.nee_light_sampler,
            brightest_delta_sun: selection.brightest_delta_sun,
            brightest_sun: selection.brightest_sun,
            geometry,
            objects: placed.built.objects,
            media: placed.built.media,
            shape_owner: placed.shape_owner,
            warnings,
            notes,
            source: ctx.path.to_path_buf(),
            inputs: ctx.inputs.take(),
            light_layers: lights.layers,
            light_layer_names: lights.layer_names,
            escape_radiance,
        })
    })
}

/// Checks the objects with `nee = "manifold"` against the scene: the first of them (in file
/// order) needs a sphere or distant light to connect to, and one without a surface of its own
/// needs an object of the scene with a smooth refractive boundary to enclose it. Each error
/// names the object and its interior table's line.
fn check_manifold(
    ctx: &Ctx,
    built: &objects::ObjectList,
    lights: &[Light],
) -> Result<(), SceneError> {
    if !lights
        .iter()
        .any(|l| matches!(l, Light::Sphere { .. } | Light::Distant { .. }))
    {
        if let Some((name, line, _)) = built.manifold.first() {
            return Err(ctx.invalid(
                *line,
                format!("{name}: interior.nee = \"manifold\" connects to sphere and distant lights, but the scene has none (only environments, or no light)"),
            ));
        }
    }
    let any_interface = built
        .objects
        .iter()
        .any(|o| objects::is_smooth_refractor(&o.surface));
    if let Some((name, line, _)) = built.manifold.iter().find(|m| m.2 && !any_interface) {
        return Err(ctx.invalid(
            *line,
            format!("{name}: interior.nee = \"manifold\" needs a smooth refractive boundary (surface type = \"dielectric\", roughness = 0), but it has no surface and no object of the scene has such a boundary to enclose it"),
        ));
    }
    Ok(())
}

/// How the renderer picks among the scene's lights, found once at load.
struct LightSelection {
    /// [`LightSampler::new`].
    light_sampler: LightSampler,
    /// [`LightSampler::for_nee`].
    nee_light_sampler: LightSampler,
    /// [`crate::light::brightest_delta_sun`].
    brightest_delta_sun: Option<usize>,
    /// [`crate::light::brightest_distant`], discs included.
    brightest_sun: Option<usize>,
}

impl LightSelection {
    /// The selection among `lights` in a scene of `geometry`: the samplers see the scene as
    /// a ball of half the diagonal of its bounds (at least 10⁻³; 1 when it has no bounds).
    fn new(lights: &[Light], geometry: &SceneGeometry) -> Self {
        let b = geometry.bounds();
        let radius = if b.is_valid() {
            (b.extent().length() * 0.5).max(1e-3)
        } else {
            1.0
        };
        LightSelection {
            light_sampler: LightSampler::new(lights, radius),
            nee_light_sampler: LightSampler::for_nee(lights, radius),
            brightest_delta_sun: crate::light::brightest_delta_sun(lights),
            brightest_sun: crate::light::brightest_distant(lights, true),
        }
    }
}

/// Makes now (in parallel) the sun map of every interior whose sun lean will ask for it
/// (interior NEE, [`crate::medium::Medium::sun_lean`]) towards the delta sun
/// `brightest_delta_sun` of `lights`, rather than by the first render thread to need it.
fn prepare_sun_maps(
    built: &objects::ObjectList,
    lights: &[Light],
    brightest_delta_sun: Option<usize>,
) {
    let Some(Light::Distant { to_light, .. }) = brightest_delta_sun.and_then(|l| lights.get(l))
    else {
        return;
    };
    for obj in built
        .objects
        .iter()
        .filter(|o| o.nee == NeeStrategy::Interior)
    {
        if let Some(m) = obj.medium.and_then(|m| built.media.get(m as usize)) {
            if m.sun_lean() {
                m.prepare_sun_map(*to_light);
            }
        }
    }
}

/// The text of the built-in default scene (`scenes/creature.toml`).
pub const DEFAULT_SCENE_TEXT: &str = include_str!("../../scenes/creature.toml");

/// The built-in default scene: `scenes/creature.toml` and its meshes, compiled into the binary
/// and unpacked into a temporary folder so that it renders from anywhere.
pub(super) fn default_scene() -> Result<Scene, SceneError> {
    const FILES: [(&str, &[u8]); 3] = [
        (
            "creature_skin.ply",
            include_bytes!("../../scenes/meshes/creature_skin.ply"),
        ),
        (
            "creature_skeleton.ply",
            include_bytes!("../../scenes/meshes/creature_skeleton.ply"),
        ),
        (
            "backdrop.ply",
            include_bytes!("../../scenes/meshes/backdrop.ply"),
        ),
    ];
    let text = DEFAULT_SCENE_TEXT;
    let dir = std::env::temp_dir().join(format!("velour-default-scene-{}", std::process::id()));
    let meshes = dir.join("meshes");
    let io = |path: &Path, source: std::io::Error| SceneError::Io {
        path: path.to_path_buf(),
        source,
    };
    std::fs::create_dir_all(&meshes).map_err(|e| io(&meshes, e))?;
    for (name, bytes) in FILES {
        let p = meshes.join(name);
        std::fs::write(&p, bytes).map_err(|e| io(&p, e))?;
    }
    let scene_path = dir.join("creature.toml");
    let result = load_scene_str(text, &scene_path);
    let _ = std::fs::remove_dir_all(&dir);
    let mut scene = result?;
    // The unpacked files are gone; they are part of the binary, which the version names.
    scene.inputs.clear();
    scene.source = PathBuf::from(DEFAULT_SCENE_NAME);
    Ok(scene)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::ShapeOwner;

    /// Loads `scenes/NAME` both ways.
    fn both(name: &str) -> (Scene, Scene) {
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("scenes")
            .join(name);
        let text = std::fs::read_to_string(&path).expect("a shipped scene");
        let overlapped = load_scene_placing(&text, &path, true).expect("loads");
        let serial = load_scene_placing(&text, &path, false).expect("loads");
        (overlapped, serial)
    }

    #[test]
    fn overlapped_geometry_builds_the_serial_scene() {
        // Meshes with voxel interiors (VDB files), textured surfaces and a sphere.
        for name in ["vdb_character.toml", "creature_textured.toml"] {
            let (a, b) = both(name);
            assert!(a.geometry.shape_count() > 1, "{name}");
            assert_eq!(
                format!("{:?}", a.geometry),
                format!("{:?}", b.geometry),
                "{name}: geometry"
            );
            assert_eq!(
                format!("{:?}", a.objects),
                format!("{:?}", b.objects),
                "{name}: objects"
            );
            assert_eq!(format!("{:?}", a.media), format!("{:?}", b.media), "{name}");
            assert_eq!(
                a.inputs, b.inputs,
                "{name}: the input files in reading order"
            );
            assert!(a.inputs.len() > 1, "{name}");
            assert_eq!(a.warnings, b.warnings, "{name}");
            assert_eq!(a.notes, b.notes, "{name}");
        }
    }

    #[test]
    fn an_object_staged_before_a_failing_one_reports_its_own_error_first() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/inline.toml");
        // The first object's interior is invalid (albedo out of range) and the second
        // object's mesh file is missing: the object-by-object build meets the first.
        let text = r#"
[camera]
eye = [0.0, 0.0, 5.0]
look_at = [0.0, 0.0, 0.0]

[[light]]
type = "environment"

[[object]]
name = "first"
shape = "sphere"
surface = { type = "dielectric", ior = 1.3 }
interior = { type = "homogeneous", albedo = 2.0 }

[[object]]
name = "second"
shape = "mesh"
file = "meshes/does_not_exist.ply"
"#;
        let a = load_scene_placing(text, &path, true).expect_err("invalid");
        let b = load_scene_placing(text, &path, false).expect_err("invalid");
        assert_eq!(a.to_string(), b.to_string());
        assert!(a.to_string().contains("first"), "{a}");
    }

    /// A scene of a camera, `lights` and `objects` (TOML tables).
    fn scene_text(lights: &str, objects: &str) -> String {
        format!("[camera]\neye = [0.0, 0.0, 5.0]\nlook_at = [0.0, 0.0, 0.0]\n{lights}\n{objects}")
    }

    /// Loads `text` both ways (as `bad.toml`); both give the same error, which is returned.
    fn error_both_ways(text: &str) -> String {
        let path = Path::new("bad.toml");
        let a = load_scene_placing(text, path, true).expect_err("invalid");
        let b = load_scene_placing(text, path, false).expect_err("invalid");
        assert_eq!(a.to_string(), b.to_string());
        a.to_string()
    }

    const ENVIRONMENT: &str = "[[light]]\ntype = \"environment\"";
    const SUN: &str = "[[light]]\ntype = \"distant\"\ndirection = [0.0, -1.0, 0.0]";

    /// An object `name` with `surface` (a TOML value, or none) and a manifold-NEE interior.
    fn manifold_object(name: &str, surface: Option<&str>) -> String {
        let surface = surface.map_or(String::new(), |s| format!("surface = {s}\n"));
        format!(
            "[[object]]\nname = \"{name}\"\nshape = \"sphere\"\n{surface}interior = {{ type = \"homogeneous\", albedo = 0.8, nee = \"manifold\" }}\n"
        )
    }

    const SMOOTH: &str = "{ type = \"dielectric\", ior = 1.4 }";

    #[test]
    fn manifold_nee_without_a_sphere_or_distant_light_names_the_first_such_object() {
        let objects = format!(
            "{}{}",
            manifold_object("first", Some(SMOOTH)),
            manifold_object("second", Some(SMOOTH))
        );
        for lights in [ENVIRONMENT, ""] {
            let e = error_both_ways(&scene_text(lights, &objects));
            // The first object's interior table is on its fifth line (after the camera's
            // three lines and the lights').
            let line = 3 + lights.lines().count().max(1) + 1 + 4;
            assert_eq!(
                e,
                format!("bad.toml:{line}: first: interior.nee = \"manifold\" connects to sphere and distant lights, but the scene has none (only environments, or no light)"),
            );
        }
        // With a distant light the scene loads.
        load_scene_placing(&scene_text(SUN, &objects), Path::new("ok.toml"), true).expect("loads");
    }

    #[test]
    fn manifold_nee_without_a_surface_needs_an_enclosing_smooth_boundary() {
        let inside = manifold_object("iris", None);
        let e = error_both_ways(&scene_text(SUN, &inside));
        assert_eq!(
            e,
            "bad.toml:10: iris: interior.nee = \"manifold\" needs a smooth refractive boundary (surface type = \"dielectric\", roughness = 0), but it has no surface and no object of the scene has such a boundary to enclose it",
        );
        // The light check comes first.
        let e = error_both_ways(&scene_text(ENVIRONMENT, &inside));
        assert!(e.contains("connects to sphere and distant lights"), "{e}");
        // An enclosing smooth dielectric object (here, a second manifold object) is enough.
        let objects = format!("{inside}{}", manifold_object("globe", Some(SMOOTH)));
        load_scene_placing(&scene_text(SUN, &objects), Path::new("ok.toml"), true).expect("loads");
    }

    #[test]
    fn sphere_lights_own_shapes_after_the_objects_and_a_scene_without_lights_warns() {
        let sphere_light =
            "[[light]]\ntype = \"sphere\"\ncenter = [0.0, 3.0, 0.0]\nradius = 0.5\nradiance = 2.0";
        let lights = format!("{ENVIRONMENT}\n{sphere_light}\n{sphere_light}");
        let object = "[[object]]\nname = \"ball\"\nshape = \"sphere\"\nsurface = { type = \"lambertian\" }\n";
        let scene =
            load_scene_str(&scene_text(&lights, object), Path::new("ok.toml")).expect("loads");
        assert_eq!(
            scene.shape_owner,
            [
                ShapeOwner::Object(0),
                ShapeOwner::Light(1),
                ShapeOwner::Light(2)
            ]
        );
        assert_eq!(scene.geometry.shape_count(), 3);
        assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
        for overlap in [true, false] {
            let dark = load_scene_placing(&scene_text("", object), Path::new("dark.toml"), overlap)
                .expect("loads");
            assert_eq!(
                dark.warnings,
                ["dark.toml: the scene has no lights; the image will be black"]
            );
            assert_eq!(dark.shape_owner, [ShapeOwner::Object(0)]);
        }
    }
}
