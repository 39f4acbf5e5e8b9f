//! Building a [`Scene`] from a scene file: read the descriptions, then build the film and
//! camera, the objects with their interiors, the lights and the geometry.

use std::path::{Path, PathBuf};

use super::context::Ctx;
use super::desc::{LightDesc, ObjectDesc};
use super::{camera, lights, objects, read, Scene, SceneError, ShapeOwner};
use crate::geometry::{SceneGeometry, Shape};
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

    // The BVH over the objects' triangles is the largest serial step of loading a scene with a
    // large mesh: when every shape is known before the interiors (and no sphere light adds
    // one), it is built on its own thread while the interiors are.
    let sphere_lights = file
        .light
        .iter()
        .any(|l| matches!(l.get_ref(), LightDesc::Sphere(_)));
    let early = overlap && !sphere_lights && objects::all_placeable_early(&file.object);
    std::thread::scope(|scope| {
        let mut shapes: Vec<Shape> = Vec::new();
        let mut shape_owner = Vec::new();
        let mut built = objects::ObjectList::default();
        let mut pending = None;
        if early {
            let staged = stage_all(&ctx, &file.object, &mut built, &mut warnings, &mut notes)?;
            let mut placed = Vec::with_capacity(staged.len());
            for (s, _) in &staged {
                let (shape, p) = objects::place_early(s)
                    .ok_or_else(|| ctx.invalid(1, "an object's shape cannot be placed early"))?;
                shapes.push(shape);
                placed.push(p);
            }
            let early_shapes = std::mem::take(&mut shapes);
            pending = Some(scope.spawn(move || SceneGeometry::build(early_shapes)));
            let mut own_inputs = Vec::with_capacity(staged.len());
            for (((s, stage_inputs), p), desc) in staged.into_iter().zip(placed).zip(&file.object) {
                let from = ctx.inputs.borrow().len();
                built.finish(&ctx, desc, s, Some(p), &mut warnings, &mut notes)?;
                let interior_inputs = ctx.inputs.borrow_mut().split_off(from);
                own_inputs.push((stage_inputs, interior_inputs));
                shape_owner.push(ShapeOwner::Object((built.objects.len() - 1) as u32));
            }
            // The files in the order the serial build reads them: each object's own, its
            // interior's after its shape's and surface's.
            let mut inputs = ctx.inputs.borrow_mut();
            for (stage_inputs, interior_inputs) in own_inputs {
                inputs.extend(stage_inputs);
                inputs.extend(interior_inputs);
            }
        } else {
            for (index, desc) in file.object.iter().enumerate() {
                let shape = built.add(&ctx, index, desc, &mut warnings, &mut notes)?;
                shapes.push(shape);
                shape_owner.push(ShapeOwner::Object((built.objects.len() - 1) as u32));
            }
        }

        let mut lights = Vec::new();
        let mut light_layers = Vec::new();
        let mut layer_names: Vec<String> = Vec::new();
        for spanned in &file.light {
            let line = ctx.line_of(spanned.span().start);
            let light = lights::build_light(&ctx, line, spanned.get_ref())?;
            light_layers.push(match spanned.get_ref().name() {
                None => None,
                Some(name) => Some(lights::layer_slot(&ctx, line, name, &mut layer_names)?),
            });
            if let Light::Sphere { center, radius, .. } = &light {
                shapes.push(Shape::Sphere {
                    center: *center,
                    radius: *radius,
                });
                shape_owner.push(ShapeOwner::Light(lights.len() as u32));
            }
            lights.push(light);
        }
        super::nee::resolve_defaults(&mut built.objects, &built.auto_guided, &lights);
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
            .any(|o| super::objects::is_smooth_refractor(&o.surface));
        if let Some((name, line, _)) = built.manifold.iter().find(|m| m.2 && !any_interface) {
            return Err(ctx.invalid(
            *line,
            format!("{name}: interior.nee = \"manifold\" needs a smooth refractive boundary (surface type = \"dielectric\", roughness = 0), but it has no surface and no object of the scene has such a boundary to enclose it"),
        ));
        }
        if lights.is_empty() {
            warnings.push(format!(
                "{}: the scene has no lights; the image will be black",
                ctx.path.display()
            ));
        }

        let geometry = match pending {
            Some(handle) => {
                debug_assert!(shapes.is_empty(), "sphere lights are placed serially");
                handle
                    .join()
                    .unwrap_or_else(|panic| std::panic::resume_unwind(panic))
            }
            None => SceneGeometry::build(shapes),
        }
        .map_err(|e| ctx.invalid(1, format!("building the geometry: {e}")))?;
        let b = geometry.bounds();
        let radius = if b.is_valid() {
            (b.extent().length() * 0.5).max(1e-3)
        } else {
            1.0
        };
        let light_sampler = LightSampler::new(&lights, radius);
        let nee_light_sampler = LightSampler::for_nee(&lights, radius);
        let brightest_delta_sun = crate::light::brightest_delta_sun(&lights);
        let brightest_sun = crate::light::brightest_distant(&lights, true);
        // The sun map of every interior whose sun lean will ask for it, made now (in parallel)
        // rather than by the first render thread to need it.
        if let Some(Light::Distant { to_light, .. }) =
            brightest_delta_sun.and_then(|l| lights.get(l))
        {
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
        Ok(Scene {
            camera,
            camera_params,
            film,
            lights,
            light_sampler,
            nee_light_sampler,
            brightest_delta_sun,
            brightest_sun,
            geometry,
            objects: built.objects,
            media: built.media,
            shape_owner,
            warnings,
            notes,
            source: ctx.path.to_path_buf(),
            inputs: ctx.inputs.take(),
            light_layers,
            light_layer_names: layer_names,
        })
    })
}

/// Stages every object ([`objects::stage`]) with the input files each one reads. When one
/// fails, the objects before it are built in full first ([`objects::ObjectList::finish`]), so
/// that the error reported is the one the object-by-object build meets first.
fn stage_all(
    ctx: &Ctx,
    descs: &[toml::Spanned<ObjectDesc>],
    built: &mut objects::ObjectList,
    warnings: &mut Vec<String>,
    notes: &mut Vec<String>,
) -> Result<Vec<(objects::Staged, Vec<PathBuf>)>, SceneError> {
    let mut staged = Vec::with_capacity(descs.len());
    for (index, desc) in descs.iter().enumerate() {
        let from = ctx.inputs.borrow().len();
        match objects::stage(ctx, index, desc) {
            Ok(s) => {
                let own = ctx.inputs.borrow_mut().split_off(from);
                staged.push((s, own));
            }
            Err(e) => {
                for ((s, _), desc) in staged.into_iter().zip(descs) {
                    built.finish(ctx, desc, s, None, warnings, notes)?;
                }
                return Err(e);
            }
        }
    }
    Ok(staged)
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
}
