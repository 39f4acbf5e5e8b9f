//! Validation of a parsed scene file and construction of the [`Scene`].

use std::path::{Path, PathBuf};

use super::desc::{
    ColorValue, InteriorDesc, LightDesc, ObjectDesc, ScaleValue, SceneFile, SurfaceDesc,
};
use super::{
    CameraParams, DielectricParams, FilmSettings, Object, ObjectSurface, Scene, SceneError,
    ShapeOwner,
};
use crate::bsdf::{MicrofacetDistribution, Surface};
use crate::camera::Camera;
use crate::geometry::{load_ply, SceneGeometry, Shape};
use crate::light::{EnvironmentMap, Light, LightSampler};
use crate::math::{Aabb, Mat4, Vec3};
use crate::medium::{
    AlbedoMode, Coefficients, DensityField, HeterogeneousMedium, HomogeneousMedium, Medium,
    NeeStrategy,
};
use crate::phase::PhaseFunction;
use crate::spectrum::Rgb;
use crate::tracking::{FreeFlightMethod, TrackingConfig};

/// Name shown for the built-in default scene.
pub const DEFAULT_SCENE_NAME: &str = "<built-in default scene>";

/// Largest accepted image side, pixels.
const MAX_IMAGE_SIDE: u32 = 32_768;

struct Ctx<'a> {
    path: &'a Path,
    text: &'a str,
}

impl Ctx<'_> {
    fn line_of(&self, offset: usize) -> usize {
        self.text[..offset.min(self.text.len())]
            .bytes()
            .filter(|&b| b == b'\n')
            .count()
            + 1
    }
    fn invalid(&self, line: usize, message: impl Into<String>) -> SceneError {
        SceneError::Invalid {
            path: self.path.to_path_buf(),
            line,
            message: message.into(),
        }
    }
    fn resolve(&self, file: &str) -> PathBuf {
        let p = Path::new(file);
        if p.is_absolute() {
            p.to_path_buf()
        } else {
            self.path.parent().unwrap_or(Path::new(".")).join(p)
        }
    }
}

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
    let ctx = Ctx { path, text };
    let file: SceneFile = toml::from_str(text).map_err(|e| parse_error(&ctx, &e))?;
    build_scene(&ctx, file)
}

/// Turns a toml/serde error into one naming the line; for an unknown key, the line of the key
/// itself (serde reports the span of the enclosing table).
fn parse_error(ctx: &Ctx, e: &toml::de::Error) -> SceneError {
    let message = e.message().trim().to_string();
    let mut line = e.span().map(|s| ctx.line_of(s.start)).unwrap_or(1);
    if let Some(rest) = message.strip_prefix("unknown field `") {
        if let Some(key) = rest.split('`').next() {
            let start_line = line;
            let end_line = e.span().map(|s| ctx.line_of(s.end)).unwrap_or(usize::MAX);
            for (i, l) in ctx.text.lines().enumerate() {
                let n = i + 1;
                if n < start_line || n > end_line.max(start_line) {
                    continue;
                }
                let t = l.trim_start();
                let inline = l.contains(&format!("{key} =")) || l.contains(&format!("{key}="));
                if t.starts_with(key) && t[key.len()..].trim_start().starts_with('=') || inline {
                    line = n;
                    break;
                }
            }
            return SceneError::Parse {
                path: ctx.path.to_path_buf(),
                line,
                message: format!("unknown key `{key}` ({message})"),
            };
        }
    }
    // serde's untagged enums say only "data did not match any variant": say what fits.
    let message = match message
        .strip_prefix("data did not match any variant of untagged enum ")
        .map(str::trim)
    {
        Some("ColorValue") => "expected a colour: a number or [r, g, b]".to_string(),
        Some("ScaleValue") => "expected a scale: a number or [x, y, z]".to_string(),
        Some("TilesValue") => "`tiles` expects a number or [u, v]".to_string(),
        Some("MipValue") => format!("`mip` expects a level 0–{MAX_FABRIC_MIP} or \"auto\""),
        _ => message,
    };
    SceneError::Parse {
        path: ctx.path.to_path_buf(),
        line,
        message,
    }
}

fn color(v: Option<ColorValue>, default: Rgb) -> Rgb {
    match v {
        None => default,
        Some(ColorValue::Scalar(s)) => Rgb::splat(s),
        Some(ColorValue::Rgb(c)) => Rgb(c),
    }
}

fn check_finite_rgb(
    ctx: &Ctx,
    line: usize,
    what: &str,
    c: Rgb,
    min: f32,
    max: f32,
) -> Result<Rgb, SceneError> {
    for v in c.0 {
        if !v.is_finite() || v < min || v > max {
            return Err(ctx.invalid(
                line,
                format!(
                    "{what} = {:?} is outside [{min}, {max}] (or not finite)",
                    c.0
                ),
            ));
        }
    }
    Ok(c)
}

fn check_range(
    ctx: &Ctx,
    line: usize,
    what: &str,
    v: f32,
    min: f32,
    max: f32,
) -> Result<f32, SceneError> {
    if !v.is_finite() || v < min || v > max {
        return Err(ctx.invalid(
            line,
            format!("{what} = {v} is outside [{min}, {max}] (or not finite)"),
        ));
    }
    Ok(v)
}

fn vec3(ctx: &Ctx, line: usize, what: &str, v: [f32; 3]) -> Result<Vec3, SceneError> {
    if v.iter().any(|x| !x.is_finite()) {
        return Err(ctx.invalid(line, format!("{what} = {v:?} is not finite")));
    }
    Ok(Vec3::from_array(v))
}

/// Rejects keys that the chosen `type` does not use (they are almost always mistakes).
fn reject_unused(
    ctx: &Ctx,
    line: usize,
    owner: &str,
    kind: &str,
    present: &[(&str, bool)],
) -> Result<(), SceneError> {
    for (key, is_set) in present {
        if *is_set {
            return Err(ctx.invalid(
                line,
                format!("{owner}: key `{key}` is not used by type \"{kind}\""),
            ));
        }
    }
    Ok(())
}

fn build_scene(ctx: &Ctx, file: SceneFile) -> Result<Scene, SceneError> {
    let mut warnings = Vec::new();
    let mut notes = Vec::new();
    let film = build_film(ctx, &file)?;
    let (camera, camera_params) = build_camera(ctx, &file, &film)?;

    let mut shapes: Vec<Shape> = Vec::new();
    let mut shape_owner = Vec::new();
    let mut objects = Vec::new();
    let mut media = Vec::new();
    for (index, spanned) in file.object.iter().enumerate() {
        let line = ctx.line_of(spanned.span().start);
        let desc = spanned.get_ref();
        let name = desc
            .name
            .clone()
            .unwrap_or_else(|| format!("object {}", index + 1));
        let (xf, uniform) = object_transform(ctx, line, &name, desc)?;
        let rest = build_rest_shape(ctx, line, &name, desc, uniform)?;
        let (surface, ior) = build_surface(ctx, line, &name, desc.surface.as_ref())?;
        let (medium, nee) = match &desc.interior {
            Some(interior) => {
                let placement = Placement {
                    xf,
                    rest_bounds: rest.bounds(),
                    rest_mesh: match &rest {
                        RestShape::Mesh(m) => Some(m),
                        _ => None,
                    },
                    view: ViewFootprint {
                        eye: camera_params.eye,
                        pixel_angle: camera_params.fov.to_radians() / film.height.max(1) as f32,
                    },
                };
                let (m, nee) = build_medium(ctx, line, &name, interior, &placement)?;
                media.push(m);
                (Some((media.len() - 1) as u32), nee)
            }
            None => (None, NeeStrategy::ExitPoint),
        };
        if let Some(note) = medium.and_then(|m| fabric_note(&media[m as usize])) {
            notes.push(format!("{name}: {note}"));
        }
        let shell_boundary = medium.and_then(|m| match &media[m as usize] {
            Medium::Heterogeneous(h) => match &h.field {
                DensityField::Shell(shell) => Some(shell.boundary_mesh().clone()),
                _ => None,
            },
            _ => None,
        });
        let (shape, open_mesh) = match (rest, shell_boundary) {
            // A fabric shell: the object is the closed shell around the cloth mesh.
            (RestShape::Mesh(_), Some(mesh)) => {
                let closed = mesh.is_closed();
                (Shape::Mesh(mesh), !closed)
            }
            (RestShape::Mesh(mut mesh), None) => {
                mesh.transform(xf);
                let closed = mesh.is_closed();
                if closed {
                    mesh.make_outward();
                }
                (Shape::Mesh(mesh), !closed)
            }
            (RestShape::Sphere { center, radius }, _) => {
                let scale = uniform.unwrap_or(1.0).abs();
                (
                    Shape::Sphere {
                        center: xf.transform_point3(center),
                        radius: radius * scale,
                    },
                    false,
                )
            }
            (RestShape::Bounds, _) => {
                let Some(Medium::Heterogeneous(h)) = medium.map(|m| &media[m as usize]) else {
                    return Err(ctx.invalid(
                        line,
                        format!(
                            "{name}: shape \"bounds\" needs a \"voxel\" or \"fabric\" interior"
                        ),
                    ));
                };
                let b = h.pyramid.world_bounds().ok_or_else(|| {
                    ctx.invalid(line, format!("{name}: the interior's grid is empty"))
                })?;
                (Shape::Mesh(box_mesh(b)), false)
            }
        };
        // Exit-point NEE needs a scattering boundary: behind an index-matched one (no surface,
        // or a dielectric of IOR 1) it would never happen, so NEE moves to the interior
        // vertices, where transparent shadows through such a boundary are exact.
        let index_matched = matches!(&surface, ObjectSurface::Null)
            || matches!(&surface, ObjectSurface::Dielectric(d) if d.ior == 1.0);
        let nee = if medium.is_some() && index_matched && nee == NeeStrategy::ExitPoint {
            if desc.interior.as_ref().is_some_and(|i| i.nee.is_some()) {
                warnings.push(format!(
                    "{}:{line}: {name}: nee = \"exit\" behind an index-matched boundary finds no exit vertices; using \"interior\"",
                    ctx.path.display()
                ));
            }
            NeeStrategy::Interior
        } else {
            nee
        };
        if medium.is_some() && !surface.transmits() {
            warnings.push(format!("{}:{line}: {name}: has an interior but its surface does not transmit light; the interior is never reached", ctx.path.display()));
        }
        if medium.is_none() && matches!(surface, ObjectSurface::Null) {
            return Err(ctx.invalid(
                line,
                format!("{name}: an object needs a surface, an interior, or both"),
            ));
        }
        if open_mesh && surface.transmits() {
            warnings.push(format!(
                "{}:{line}: {name}: mesh is not closed (some edges are not shared by exactly two triangles); as an interior boundary it can leak paths",
                ctx.path.display()
            ));
        }
        objects.push(Object {
            name,
            surface,
            medium,
            priority: desc.priority.unwrap_or(0),
            ior,
            nee,
        });
        shapes.push(shape);
        shape_owner.push(ShapeOwner::Object((objects.len() - 1) as u32));
    }

    let mut lights = Vec::new();
    for spanned in &file.light {
        let line = ctx.line_of(spanned.span().start);
        let light = build_light(ctx, line, spanned.get_ref())?;
        if let Light::Sphere { center, radius, .. } = &light {
            shapes.push(Shape::Sphere {
                center: *center,
                radius: *radius,
            });
            shape_owner.push(ShapeOwner::Light(lights.len() as u32));
        }
        lights.push(light);
    }
    if lights.is_empty() {
        warnings.push(format!(
            "{}: the scene has no lights; the image will be black",
            ctx.path.display()
        ));
    }

    let geometry = SceneGeometry::build(shapes)
        .map_err(|e| ctx.invalid(1, format!("building the geometry: {e}")))?;
    let b = geometry.bounds();
    let radius = if b.is_valid() {
        (b.extent().length() * 0.5).max(1e-3)
    } else {
        1.0
    };
    let light_sampler = LightSampler::new(&lights, radius);
    Ok(Scene {
        camera,
        camera_params,
        film,
        lights,
        light_sampler,
        geometry,
        objects,
        media,
        shape_owner,
        warnings,
        notes,
        source: ctx.path.to_path_buf(),
    })
}

fn build_film(ctx: &Ctx, file: &SceneFile) -> Result<FilmSettings, SceneError> {
    let f = file.film.clone().unwrap_or(super::desc::FilmDesc {
        width: None,
        height: None,
        spp: None,
        seed: None,
        max_depth: None,
        output: None,
        exposure: None,
    });
    let line = ctx
        .text
        .lines()
        .position(|l| l.trim() == "[film]")
        .map(|i| i + 1)
        .unwrap_or(1);
    let width = f.width.unwrap_or(480);
    let height = f.height.unwrap_or(360);
    for (k, v) in [("film.width", width), ("film.height", height)] {
        if v == 0 || v > MAX_IMAGE_SIDE {
            return Err(ctx.invalid(line, format!("{k} = {v} is outside [1, {MAX_IMAGE_SIDE}]")));
        }
    }
    let spp = f.spp.unwrap_or(16);
    if spp == 0 || spp > 1 << 24 {
        return Err(ctx.invalid(line, format!("film.spp = {spp} is outside [1, 16777216]")));
    }
    let max_depth = f.max_depth.unwrap_or(256);
    if max_depth == 0 || max_depth > 1_000_000 {
        return Err(ctx.invalid(
            line,
            format!("film.max_depth = {max_depth} is outside [1, 1000000]"),
        ));
    }
    let exposure = check_range(
        ctx,
        line,
        "film.exposure",
        f.exposure.unwrap_or(0.0),
        -30.0,
        30.0,
    )?;
    let output = match &f.output {
        // Outputs are relative to the working directory (inputs to the scene file).
        Some(o) => PathBuf::from(o),
        None => {
            let stem = ctx
                .path
                .file_stem()
                .and_then(|s| s.to_str())
                .filter(|s| !s.starts_with('<'))
                .unwrap_or("default");
            PathBuf::from("out").join(format!("{stem}.exr"))
        }
    };
    Ok(FilmSettings {
        width,
        height,
        spp,
        seed: f.seed.unwrap_or(0),
        max_depth,
        output,
        exposure,
    })
}

fn build_camera(
    ctx: &Ctx,
    file: &SceneFile,
    film: &FilmSettings,
) -> Result<(Camera, CameraParams), SceneError> {
    let line = ctx
        .text
        .lines()
        .position(|l| l.trim() == "[camera]")
        .map(|i| i + 1)
        .unwrap_or(1);
    let c = file
        .camera
        .clone()
        .ok_or_else(|| ctx.invalid(1, "missing [camera] table"))?;
    let eye = vec3(
        ctx,
        line,
        "camera.eye",
        c.eye
            .ok_or_else(|| ctx.invalid(line, "camera.eye is required"))?,
    )?;
    let look_at = vec3(
        ctx,
        line,
        "camera.look_at",
        c.look_at
            .ok_or_else(|| ctx.invalid(line, "camera.look_at is required"))?,
    )?;
    let up = vec3(ctx, line, "camera.up", c.up.unwrap_or([0.0, 1.0, 0.0]))?;
    let fov = check_range(ctx, line, "camera.fov", c.fov.unwrap_or(40.0), 1e-3, 179.0)?;
    let kind = c.kind.as_deref().unwrap_or("pinhole");
    let lens = match kind {
        "pinhole" => {
            reject_unused(
                ctx,
                line,
                "camera",
                kind,
                &[
                    ("aperture_radius", c.aperture_radius.is_some()),
                    ("focus_distance", c.focus_distance.is_some()),
                ],
            )?;
            None
        }
        "thin_lens" => {
            let aperture = check_range(
                ctx,
                line,
                "camera.aperture_radius",
                c.aperture_radius.unwrap_or(0.0),
                0.0,
                1e6,
            )?;
            let focus = check_range(
                ctx,
                line,
                "camera.focus_distance",
                c.focus_distance.unwrap_or((look_at - eye).length()),
                1e-6,
                1e9,
            )?;
            Some((aperture, focus))
        }
        other => {
            return Err(ctx.invalid(
                line,
                format!(
                    "camera.type = \"{other}\" is unknown (expected \"pinhole\" or \"thin_lens\")"
                ),
            ))
        }
    };
    let params = CameraParams {
        eye,
        look_at,
        up,
        fov,
        lens,
    };
    let cam = params
        .build(film.width, film.height)
        .map_err(|e| ctx.invalid(line, format!("camera: {e}")))?;
    Ok((cam, params))
}

fn object_transform(
    ctx: &Ctx,
    line: usize,
    name: &str,
    d: &ObjectDesc,
) -> Result<(Mat4, Option<f32>), SceneError> {
    let t = vec3(
        ctx,
        line,
        &format!("{name}: translate"),
        d.translate.unwrap_or([0.0; 3]),
    )?;
    let r = vec3(
        ctx,
        line,
        &format!("{name}: rotate"),
        d.rotate.unwrap_or([0.0; 3]),
    )?;
    let (s, uniform) = match d.scale {
        None => (Vec3::ONE, Some(1.0)),
        Some(ScaleValue::Uniform(u)) => (Vec3::splat(u), Some(u)),
        Some(ScaleValue::PerAxis(a)) => {
            let v = vec3(ctx, line, &format!("{name}: scale"), a)?;
            (
                v,
                if v.x == v.y && v.y == v.z {
                    Some(v.x)
                } else {
                    None
                },
            )
        }
    };
    if !s.is_finite() || s.abs().min_element() < 1e-12 || s.abs().max_element() > 1e12 {
        return Err(ctx.invalid(
            line,
            format!(
                "{name}: scale {:?} must be finite and non-zero",
                s.to_array()
            ),
        ));
    }
    let rot = Mat4::from_rotation_z(r.z.to_radians())
        * Mat4::from_rotation_y(r.y.to_radians())
        * Mat4::from_rotation_x(r.x.to_radians());
    Ok((
        Mat4::from_translation(t) * rot * Mat4::from_scale(s),
        uniform,
    ))
}

/// A shape in the object's rest space.
enum RestShape {
    Mesh(crate::geometry::TriangleMesh),
    Sphere {
        center: Vec3,
        radius: f32,
    },
    /// The world box of the interior's grid.
    Bounds,
}

impl RestShape {
    fn bounds(&self) -> Option<Aabb> {
        match self {
            RestShape::Mesh(m) => Some(m.bounds()),
            RestShape::Sphere { center, radius } => Some(Aabb {
                min: *center - Vec3::splat(*radius),
                max: *center + Vec3::splat(*radius),
            }),
            RestShape::Bounds => None,
        }
    }
}

/// A closed, outward-wound box mesh.
fn box_mesh(b: Aabb) -> crate::geometry::TriangleMesh {
    let c = |i: usize| {
        Vec3::new(
            if i & 1 != 0 { b.max.x } else { b.min.x },
            if i & 2 != 0 { b.max.y } else { b.min.y },
            if i & 4 != 0 { b.max.z } else { b.min.z },
        )
    };
    let positions = (0..8).map(c).collect();
    let quads = [
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ];
    let mut indices = Vec::new();
    for q in quads {
        indices.push([q[0], q[1], q[2]]);
        indices.push([q[0], q[2], q[3]]);
    }
    let mut mesh = crate::geometry::TriangleMesh {
        positions,
        normals: None,
        uvs: None,
        indices,
    };
    mesh.make_outward();
    mesh
}

fn build_rest_shape(
    ctx: &Ctx,
    line: usize,
    name: &str,
    d: &ObjectDesc,
    uniform: Option<f32>,
) -> Result<RestShape, SceneError> {
    match d.shape.as_str() {
        "mesh" => {
            reject_unused(ctx, line, name, "mesh", &[("center", d.center.is_some()), ("radius", d.radius.is_some())])?;
            let file = d.file.as_ref().ok_or_else(|| ctx.invalid(line, format!("{name}: shape \"mesh\" needs `file`")))?;
            let path = ctx.resolve(file);
            let mesh = load_ply(&path).map_err(|e| ctx.invalid(line, format!("{name}: {e}")))?;
            Ok(RestShape::Mesh(mesh))
        }
        "sphere" => {
            reject_unused(ctx, line, name, "sphere", &[("file", d.file.is_some())])?;
            let center = vec3(ctx, line, &format!("{name}: center"), d.center.unwrap_or([0.0; 3]))?;
            let radius = check_range(ctx, line, &format!("{name}: radius"), d.radius.unwrap_or(1.0), 1e-9, 1e9)?;
            if uniform.is_none() {
                return Err(ctx.invalid(line, format!("{name}: a sphere needs a uniform scale")));
            }
            Ok(RestShape::Sphere { center, radius })
        }
        "bounds" => {
            reject_unused(ctx, line, name, "bounds", &[("file", d.file.is_some()), ("center", d.center.is_some()), ("radius", d.radius.is_some())])?;
            Ok(RestShape::Bounds)
        }
        other => Err(ctx.invalid(line, format!("{name}: shape = \"{other}\" is unknown (expected \"mesh\", \"sphere\" or \"bounds\")"))),
    }
}

fn distribution(
    ctx: &Ctx,
    line: usize,
    name: &str,
    d: Option<&str>,
) -> Result<MicrofacetDistribution, SceneError> {
    match d.unwrap_or("ggx") {
        "ggx" => Ok(MicrofacetDistribution::Ggx),
        "beckmann" => Ok(MicrofacetDistribution::Beckmann),
        other => Err(ctx.invalid(line, format!("{name}: surface.distribution = \"{other}\" is unknown (expected \"ggx\" or \"beckmann\")"))),
    }
}

fn build_surface(
    ctx: &Ctx,
    line: usize,
    name: &str,
    s: Option<&SurfaceDesc>,
) -> Result<(ObjectSurface, f32), SceneError> {
    let Some(s) = s else {
        return Ok((ObjectSurface::Null, 1.0));
    };
    let owner = format!("{name}: surface");
    let bad = |e: &dyn std::fmt::Display| ctx.invalid(line, format!("{owner}: {e}"));
    let roughness = check_range(
        ctx,
        line,
        &format!("{owner}.roughness"),
        s.roughness.unwrap_or(0.0),
        0.0,
        1.0,
    )?;
    let coat = match &s.coat {
        None => None,
        Some(c) => {
            let ior = check_range(
                ctx,
                line,
                &format!("{owner}.coat.ior"),
                c.ior.unwrap_or(1.5),
                1.0,
                4.0,
            )?;
            let r = check_range(
                ctx,
                line,
                &format!("{owner}.coat.roughness"),
                c.roughness.unwrap_or(0.1),
                0.0,
                1.0,
            )?;
            let w = check_range(
                ctx,
                line,
                &format!("{owner}.coat.weight"),
                c.weight.unwrap_or(1.0),
                0.0,
                1.0,
            )?;
            Some((ior, r, w))
        }
    };
    let with_coat = |surf: Surface| -> Result<Surface, SceneError> {
        match coat {
            Some((ior, r, w)) => surf.with_coat(ior, r, w).map_err(|e| bad(&e)),
            None => Ok(surf),
        }
    };
    match s.kind.as_str() {
        "dielectric" => {
            reject_unused(ctx, line, &owner, "dielectric", &[("reflectance", s.reflectance.is_some()), ("transmittance", s.transmittance.is_some())])?;
            let ior = check_range(ctx, line, &format!("{owner}.ior"), s.ior.unwrap_or(1.4), 1.0, 4.0)?;
            let tint = check_finite_rgb(ctx, line, &format!("{owner}.tint"), color(s.tint, Rgb::ONE), 0.0, 1.0)?;
            let dist = distribution(ctx, line, name, s.distribution.as_deref())?;
            // Check once that the parameters build (the per-hit construction then cannot fail).
            let test = Surface::dielectric(ior, roughness, dist, tint).map_err(|e| bad(&e))?;
            with_coat(test)?;
            Ok((ObjectSurface::Dielectric(DielectricParams { ior, roughness, distribution: dist, tint, coat }), ior))
        }
        "diffuse_transmission" => {
            reject_unused(ctx, line, &owner, "diffuse_transmission", &[("ior", s.ior.is_some()), ("tint", s.tint.is_some()), ("distribution", s.distribution.is_some()), ("roughness", s.roughness.is_some())])?;
            let r = check_finite_rgb(ctx, line, &format!("{owner}.reflectance"), color(s.reflectance, Rgb::splat(0.0)), 0.0, 1.0)?;
            let t = check_finite_rgb(ctx, line, &format!("{owner}.transmittance"), color(s.transmittance, Rgb::ONE), 0.0, 1.0)?;
            let surf = Surface::diffuse_transmission(r, t).map_err(|e| bad(&e))?;
            Ok((ObjectSurface::Fixed(with_coat(surf)?), 1.0))
        }
        "lambertian" => {
            reject_unused(ctx, line, &owner, "lambertian", &[("ior", s.ior.is_some()), ("tint", s.tint.is_some()), ("transmittance", s.transmittance.is_some()), ("distribution", s.distribution.is_some()), ("roughness", s.roughness.is_some())])?;
            let r = check_finite_rgb(ctx, line, &format!("{owner}.reflectance"), color(s.reflectance, Rgb::splat(0.8)), 0.0, 1.0)?;
            let surf = Surface::lambertian(r).map_err(|e| bad(&e))?;
            Ok((ObjectSurface::Fixed(with_coat(surf)?), 1.0))
        }
        "conductor" => {
            reject_unused(ctx, line, &owner, "conductor", &[("ior", s.ior.is_some()), ("tint", s.tint.is_some()), ("transmittance", s.transmittance.is_some())])?;
            let r = check_finite_rgb(ctx, line, &format!("{owner}.reflectance"), color(s.reflectance, Rgb::splat(0.9)), 0.0, 1.0)?;
            let dist = distribution(ctx, line, name, s.distribution.as_deref())?;
            let surf = Surface::conductor_from_reflectance_with(r, roughness, dist).map_err(|e| bad(&e))?;
            Ok((ObjectSurface::Fixed(with_coat(surf)?), 1.0))
        }
        other => Err(ctx.invalid(
            line,
            format!("{owner}.type = \"{other}\" is unknown (expected \"dielectric\", \"diffuse_transmission\", \"lambertian\" or \"conductor\")"),
        )),
    }
}

fn build_phase(
    ctx: &Ctx,
    line: usize,
    owner: &str,
    p: Option<&super::desc::PhaseDesc>,
) -> Result<PhaseFunction, SceneError> {
    let bad = |e: &dyn std::fmt::Display| ctx.invalid(line, format!("{owner}.phase: {e}"));
    let Some(p) = p else {
        return PhaseFunction::henyey_greenstein(0.0).map_err(|e| bad(&e));
    };
    match p.kind.as_deref().unwrap_or("hg") {
        "hg" => {
            reject_unused(
                ctx,
                line,
                &format!("{owner}.phase"),
                "hg",
                &[
                    ("g1", p.g1.is_some()),
                    ("g2", p.g2.is_some()),
                    ("w", p.w.is_some()),
                ],
            )?;
            let g = check_range(
                ctx,
                line,
                &format!("{owner}.phase.g"),
                p.g.unwrap_or(0.0),
                -1.0,
                1.0,
            )?;
            PhaseFunction::henyey_greenstein(g).map_err(|e| bad(&e))
        }
        "double_hg" => {
            reject_unused(
                ctx,
                line,
                &format!("{owner}.phase"),
                "double_hg",
                &[("g", p.g.is_some())],
            )?;
            let g1 = check_range(
                ctx,
                line,
                &format!("{owner}.phase.g1"),
                p.g1.unwrap_or(0.8),
                -1.0,
                1.0,
            )?;
            let g2 = check_range(
                ctx,
                line,
                &format!("{owner}.phase.g2"),
                p.g2.unwrap_or(-0.3),
                -1.0,
                1.0,
            )?;
            let w = check_range(
                ctx,
                line,
                &format!("{owner}.phase.w"),
                p.w.unwrap_or(0.7),
                0.0,
                1.0,
            )?;
            PhaseFunction::double_henyey_greenstein(g1, g2, w).map_err(|e| bad(&e))
        }
        other => Err(ctx.invalid(
            line,
            format!(
                "{owner}.phase.type = \"{other}\" is unknown (expected \"hg\" or \"double_hg\")"
            ),
        )),
    }
}

fn build_medium_nee(
    ctx: &Ctx,
    line: usize,
    name: &str,
    i: &InteriorDesc,
) -> Result<NeeStrategy, SceneError> {
    match i.nee.as_deref().unwrap_or("exit") {
        "exit" => Ok(NeeStrategy::ExitPoint),
        "interior" => Ok(NeeStrategy::Interior),
        other => Err(ctx.invalid(
            line,
            format!(
                "{name}: interior.nee = \"{other}\" is unknown (expected \"exit\" or \"interior\")"
            ),
        )),
    }
}

/// Where an interior sits: the object transform and its rest shape, and the camera's view.
struct Placement<'a> {
    xf: Mat4,
    rest_bounds: Option<Aabb>,
    rest_mesh: Option<&'a crate::geometry::TriangleMesh>,
    view: ViewFootprint,
}

/// The camera's eye and the angle one pixel subtends (radians), for mip selection.
#[derive(Clone, Copy)]
struct ViewFootprint {
    eye: Vec3,
    pixel_angle: f32,
}

impl ViewFootprint {
    /// Width of a pixel's footprint at the point of `bounds` nearest to the eye.
    fn at(&self, bounds: Aabb) -> f32 {
        let nearest = self.eye.clamp(bounds.min, bounds.max);
        self.eye.distance(nearest) * self.pixel_angle
    }
}

fn build_medium(
    ctx: &Ctx,
    line: usize,
    name: &str,
    i: &InteriorDesc,
    placement: &Placement<'_>,
) -> Result<(Medium, NeeStrategy), SceneError> {
    let (xf, rest_bounds, rest_mesh) = (placement.xf, placement.rest_bounds, placement.rest_mesh);
    let owner = format!("{name}: interior");
    let density = check_range(
        ctx,
        line,
        &format!("{owner}.density"),
        i.density.unwrap_or(1.0),
        0.0,
        1e12,
    )?;
    let attenuation = color(i.attenuation, Rgb::ONE);
    for v in attenuation.0 {
        if !(v > 0.0) || v.is_nan() {
            return Err(ctx.invalid(line, format!("{owner}.attenuation = {:?}: every channel must be a distance > 0 (use a large value for no attenuation)", attenuation.0)));
        }
    }
    let nee = build_medium_nee(ctx, line, name, i)?;
    let heterogeneous_keys = [
        ("file", i.file.is_some()),
        ("grid", i.grid.is_some()),
        ("tracking", i.tracking.is_some()),
        ("noise", i.noise.is_some()),
        ("evaluation", i.evaluation.is_some()),
        ("voxel_size", i.voxel_size.is_some()),
        ("bound", i.bound.is_some()),
        ("bound_min", i.bound_min.is_some()),
        ("bound_max", i.bound_max.is_some()),
        ("trial_samples", i.trial_samples.is_some()),
        ("safety", i.safety.is_some()),
        ("base_albedo", i.base_albedo.is_some()),
        ("base_attenuation", i.base_attenuation.is_some()),
    ];
    let fabric_keys = [
        ("pattern", i.pattern.is_some()),
        ("yarn", i.yarn.is_some()),
        ("resolution", i.resolution.is_some()),
        ("repeats", i.repeats.is_some()),
        ("seed", i.seed.is_some()),
        ("flyaways", i.flyaways.is_some()),
        ("warp_albedo", i.warp_albedo.is_some()),
        ("weft_albedo", i.weft_albedo.is_some()),
        ("tiles", i.tiles.is_some()),
        ("mip", i.mip.is_some()),
        ("extinction", i.extinction.is_some()),
    ];
    if i.kind != "fabric" {
        reject_unused(ctx, line, &owner, &i.kind, &fabric_keys)?;
    }
    if matches!(i.kind.as_str(), "absorption" | "homogeneous") {
        reject_unused(ctx, line, &owner, &i.kind, &heterogeneous_keys)?;
    }
    match i.kind.as_str() {
        "fabric" => {
            reject_unused(ctx, line, &owner, "fabric", &heterogeneous_keys[..11])?;
            reject_unused(ctx, line, &owner, "fabric", &[("albedo", i.albedo.is_some()), ("albedo_mode", i.albedo_mode.is_some()), ("phase", i.phase.is_some())])?;
            if rest_mesh.is_none() && rest_bounds.is_some() {
                return Err(ctx.invalid(line, format!("{owner}: a fabric interior needs shape = \"bounds\" (a free-standing patch) or shape = \"mesh\" (a shell tiled over the mesh's texture coordinates)")));
            }
            let medium = build_fabric(ctx, line, &owner, i, placement, attenuation, density)?;
            Ok((Medium::Heterogeneous(Box::new(medium)), nee))
        }
        "voxel" | "fbm" => {
            let albedo = check_finite_rgb(ctx, line, &format!("{owner}.albedo"), color(i.albedo, Rgb::splat(0.8)), 0.0, 1.0)?;
            let mode = albedo_mode(ctx, line, &owner, i)?;
            let phase = build_phase(ctx, line, &owner, i.phase.as_ref())?;
            let per_unit = Coefficients::from_artist(albedo, attenuation, density, mode, phase.mean_cosine());
            let mut coefficients = crate::tracking::DensityCoefficients::new(per_unit.sigma_t(), per_unit.sigma_s);
            if i.base_albedo.is_some() || i.base_attenuation.is_some() {
                // The combined interior: a homogeneous medium plus the density field (notes §2.4.1).
                let ba = check_finite_rgb(ctx, line, &format!("{owner}.base_albedo"), color(i.base_albedo, Rgb::splat(0.8)), 0.0, 1.0)?;
                let bt = color(i.base_attenuation, Rgb::ONE);
                if bt.0.iter().any(|v| !(*v > 0.0)) {
                    return Err(ctx.invalid(line, format!("{owner}.base_attenuation = {:?}: every channel must be a distance > 0", bt.0)));
                }
                let base = Coefficients::from_artist(ba, bt, 1.0, mode, phase.mean_cosine());
                coefficients.base_t = base.sigma_t();
                coefficients.base_s = base.sigma_s;
            }
            let tracking = build_tracking(ctx, line, &owner, i.tracking.as_ref())?;
            let xf = glam::DAffine3::from_mat4(xf.as_dmat4());
            let (field, pyramid) = if i.kind == "voxel" {
                reject_unused(ctx, line, &owner, "voxel", &heterogeneous_keys[3..11])?;
                build_voxel_field(ctx, line, &owner, i, xf)?
            } else {
                reject_unused(ctx, line, &owner, "fbm", &heterogeneous_keys[..2])?;
                let rb = rest_bounds.ok_or_else(|| ctx.invalid(line, format!("{owner}: an fbm interior needs a mesh or sphere shape to bound it")))?;
                build_fbm_field(ctx, line, &owner, i, xf, rb)?
            };
            Ok((Medium::Heterogeneous(Box::new(HeterogeneousMedium { field, pyramid, coefficients, phase, tracking, fabric: None })), nee))
        }
        "absorption" => {
            reject_unused(ctx, line, &owner, "absorption", &[("albedo", i.albedo.is_some()), ("albedo_mode", i.albedo_mode.is_some()), ("phase", i.phase.is_some())])?;
            let sigma_a = attenuation.map(|d| if d.is_infinite() { 0.0 } else { density / d });
            Ok((Medium::Absorbing { sigma_a }, nee))
        }
        "homogeneous" => {
            let albedo = check_finite_rgb(ctx, line, &format!("{owner}.albedo"), color(i.albedo, Rgb::splat(0.8)), 0.0, 1.0)?;
            let mode = albedo_mode(ctx, line, &owner, i)?;
            let phase = build_phase(ctx, line, &owner, i.phase.as_ref())?;
            let coefficients = Coefficients::from_artist(albedo, attenuation, density, mode, phase.mean_cosine());
            if !coefficients.sigma_t().is_finite() {
                return Err(ctx.invalid(line, format!("{owner}: density/attenuation gives a non-finite extinction")));
            }
            Ok((Medium::Homogeneous(HomogeneousMedium { coefficients, phase }), nee))
        }
        other => Err(ctx.invalid(line, format!("{owner}.type = \"{other}\" is unknown (expected \"absorption\", \"homogeneous\", \"voxel\", \"fbm\" or \"fabric\")"))),
    }
}

fn albedo_mode(
    ctx: &Ctx,
    line: usize,
    owner: &str,
    i: &InteriorDesc,
) -> Result<AlbedoMode, SceneError> {
    match i.albedo_mode.as_deref().unwrap_or("multiple") {
        "multiple" => Ok(AlbedoMode::MultipleScattering),
        "single" => Ok(AlbedoMode::SingleScattering),
        other => Err(ctx.invalid(line, format!("{owner}.albedo_mode = \"{other}\" is unknown (expected \"multiple\" or \"single\")"))),
    }
}

fn build_tracking(
    ctx: &Ctx,
    line: usize,
    owner: &str,
    t: Option<&super::desc::TrackingDesc>,
) -> Result<TrackingConfig, SceneError> {
    use crate::majorant::MajorantMode;
    use crate::tracking::{ControlVariate, TransmittanceMode};
    let mut cfg = TrackingConfig::default();
    let Some(t) = t else { return Ok(cfg) };
    let step = match t.step {
        Some(s) => Some(check_range(
            ctx,
            line,
            &format!("{owner}.tracking.step"),
            s,
            1e-9,
            1e9,
        )?),
        None => None,
    };
    let need_step = || {
        step.ok_or_else(|| {
            ctx.invalid(
                line,
                format!("{owner}.tracking: ray marching needs `step` (world units)"),
            )
        })
    };
    cfg.free_flight = match t.free_flight.as_deref().unwrap_or("delta") {
        "delta" => FreeFlightMethod::DeltaTracking,
        "ray_march" => FreeFlightMethod::RayMarch { step: need_step()? },
        other => return Err(ctx.invalid(line, format!("{owner}.tracking.free_flight = \"{other}\" is unknown (expected \"delta\" or \"ray_march\")"))),
    };
    let control = match t.control.as_deref().unwrap_or("novak") {
        "novak" => ControlVariate::Novak,
        "mean" => ControlVariate::Mean,
        "minorant" => ControlVariate::Minorant,
        other => return Err(ctx.invalid(line, format!("{owner}.tracking.control = \"{other}\" is unknown (expected \"novak\", \"mean\" or \"minorant\")"))),
    };
    cfg.transmittance = match t.transmittance.as_deref().unwrap_or("residual") {
        "residual" => TransmittanceMode::ResidualRatio(control),
        "ratio" => TransmittanceMode::Ratio,
        "ray_march" => TransmittanceMode::RayMarch { step: need_step()? },
        other => return Err(ctx.invalid(line, format!("{owner}.tracking.transmittance = \"{other}\" is unknown (expected \"residual\", \"ratio\" or \"ray_march\")"))),
    };
    let level = t.level.unwrap_or(0);
    if level > 20 {
        return Err(ctx.invalid(
            line,
            format!("{owner}.tracking.level = {level} is outside [0, 20]"),
        ));
    }
    cfg.majorant = match t.majorant.as_deref().unwrap_or("pyramid") {
        "pyramid" => MajorantMode::Hierarchical { finest: level },
        "global" => MajorantMode::Global,
        other => return Err(ctx.invalid(line, format!("{owner}.tracking.majorant = \"{other}\" is unknown (expected \"pyramid\" or \"global\")"))),
    };
    Ok(cfg)
}

/// How a fabric interior was built, for the render log.
fn fabric_note(m: &Medium) -> Option<String> {
    let Medium::Heterogeneous(h) = m else {
        return None;
    };
    let look = h.fabric.as_ref()?;
    Some(match &h.field {
        DensityField::Shell(s) => format!(
            "fabric shell of {} tetrahedra, {} × {} tiles, {:.4} thick, patch mip level {}",
            s.tet_count(),
            s.tiles()[0],
            s.tiles()[1],
            s.thickness(),
            look.mip_level
        ),
        _ if look.mip_level > 0 => {
            format!("free-standing fabric patch, mip level {}", look.mip_level)
        }
        _ => return None,
    })
}

/// The coarsest fabric mip level a scene may ask for.
const MAX_FABRIC_MIP: u32 = 6;

/// Patch tiles across the unit UV square of a shell mesh: the scene's `tiles`, or the weave's
/// true size with scene units taken as the yarn preset's (centimetres).
fn shell_tiles(
    ctx: &Ctx,
    line: usize,
    owner: &str,
    i: &InteriorDesc,
    mesh: &crate::geometry::TriangleMesh,
    patch: &crate::fabric::FabricPatch,
) -> Result<[f32; 2], SceneError> {
    Ok(match i.tiles {
        Some(super::desc::TilesValue::Uniform(t)) => [t, t],
        Some(super::desc::TilesValue::PerAxis(t)) => t,
        None => {
            let per_uv = crate::fabric::shell::world_length_per_uv(mesh).ok_or_else(|| {
                ctx.invalid(line, format!("{owner}: a fabric shell needs a mesh with texture coordinates (u, v) spanning a non-zero area"))
            })?;
            [
                ((per_uv / f64::from(patch.tile.x)).round() as f32).max(1.0),
                ((per_uv / f64::from(patch.tile.y)).round() as f32).max(1.0),
            ]
        }
    })
}

/// The world width of one level-0 patch voxel and the world box of the fabric (a shell over
/// `shell_mesh` with `tiles`, or the patch placed by `xf`).
fn fabric_voxel_footprint(
    vp: &crate::fabric::VoxelisedPatch,
    xf: Mat4,
    shell_mesh: Option<&crate::geometry::TriangleMesh>,
    tiles: Option<[f32; 2]>,
) -> (f32, Aabb) {
    if let (Some(mesh), Some(t)) = (shell_mesh, tiles) {
        let (vx, vy) =
            crate::fabric::shell::tiled_voxel_widths(mesh, t, vp.dims).unwrap_or((1.0, 1.0));
        return ((vx * vy).sqrt() as f32, mesh.bounds());
    }
    let placed = glam::DAffine3::from_mat4(xf.as_dmat4()) * vp.grid.index_to_world();
    let voxel = placed.matrix3.determinant().abs().cbrt() as f32;
    let b = vp.grid.active_bbox().map_or(Aabb::EMPTY, |(lo, hi)| {
        Aabb::around_transformed(lo.as_dvec3(), hi.as_dvec3(), &placed)
    });
    (voxel, b)
}

/// Whether mip level `l` halves the voxels across the patch's tile exactly `l` times (so the
/// tile still wraps exactly at that level).
fn halves_exactly(vp: &crate::fabric::VoxelisedPatch, l: u32) -> bool {
    vp.dims[0].is_multiple_of(1 << l) && vp.dims[1].is_multiple_of(1 << l)
}

/// The coarsest mip level whose voxels are no wider than a pixel's footprint at the fabric's
/// nearest point (`footprint_in_voxels` level-0 voxels; course notes §5.3), capped at
/// [`MAX_FABRIC_MIP`] and at the halvings that keep the tile wrap exact.
fn auto_fabric_mip(vp: &crate::fabric::VoxelisedPatch, footprint_in_voxels: f32) -> u32 {
    let wanted = if footprint_in_voxels >= 2.0 {
        footprint_in_voxels.log2().floor() as u32
    } else {
        0
    };
    let mut l = wanted.min(MAX_FABRIC_MIP);
    while l > 0 && !halves_exactly(vp, l) {
        l -= 1;
    }
    l
}

/// A voxelised weave patch (notes §3): generated, voxelised into density/tangent/id channels,
/// placed by the object transform, shaded with one fibre phase function per yarn family.
fn build_fabric(
    ctx: &Ctx,
    line: usize,
    owner: &str,
    i: &InteriorDesc,
    placement: &Placement<'_>,
    attenuation: Rgb,
    density: f32,
) -> Result<HeterogeneousMedium, SceneError> {
    let xf = placement.xf;
    use crate::fabric::{
        generate_patch, voxelise, FabricShading, FibrePhaseParams, VoxeliseOptions, WeaveParams,
        WeavePattern, YarnParams,
    };
    let bad = |e: &dyn std::fmt::Display| ctx.invalid(line, format!("{owner}: {e}"));
    let pattern =
        WeavePattern::from_name(i.pattern.as_deref().unwrap_or("plain")).map_err(|e| bad(&e))?;
    let yarn = YarnParams::preset(i.yarn.as_deref().unwrap_or("cotton1")).map_err(|e| bad(&e))?;
    let resolution = i.resolution.unwrap_or(128);
    if !(8..=1024).contains(&resolution) {
        return Err(ctx.invalid(
            line,
            format!("{owner}.resolution = {resolution} is outside [8, 1024]"),
        ));
    }
    let repeats = i.repeats.unwrap_or(1);
    if !(1..=16).contains(&repeats) {
        return Err(ctx.invalid(
            line,
            format!("{owner}.repeats = {repeats} is outside [1, 16]"),
        ));
    }
    let flyaways = check_range(
        ctx,
        line,
        &format!("{owner}.flyaways"),
        i.flyaways.unwrap_or(1.0),
        0.0,
        100.0,
    )?;
    let mut params = WeaveParams::new(pattern, yarn);
    params.repeats = [repeats, repeats];
    params.flyaway_fraction = flyaways;
    params.warp_albedo = check_finite_rgb(
        ctx,
        line,
        &format!("{owner}.warp_albedo"),
        color(i.warp_albedo, params.warp_albedo),
        0.0,
        1.0,
    )?;
    params.weft_albedo = check_finite_rgb(
        ctx,
        line,
        &format!("{owner}.weft_albedo"),
        color(i.weft_albedo, params.weft_albedo),
        0.0,
        1.0,
    )?;
    let patch = generate_patch(&params, i.seed.unwrap_or(1)).map_err(|e| bad(&e))?;
    let mip = match &i.mip {
        None => None,
        Some(super::desc::MipValue::Level(l)) if (0..=i64::from(MAX_FABRIC_MIP)).contains(l) => {
            Some(*l as u32)
        }
        Some(super::desc::MipValue::Level(l)) => {
            return Err(ctx.invalid(
                line,
                format!("{owner}.mip = {l} is outside [0, {MAX_FABRIC_MIP}] (or \"auto\")"),
            ));
        }
        Some(super::desc::MipValue::Named(n)) if n == "auto" => None,
        Some(super::desc::MipValue::Named(n)) => {
            return Err(ctx.invalid(line, format!("{owner}.mip = \"{n}\" is unknown (expected a level 0–{MAX_FABRIC_MIP} or \"auto\")")));
        }
    };
    let auto_mip = matches!(&i.mip, Some(super::desc::MipValue::Named(_)));
    let opts = VoxeliseOptions {
        // Mip levels are summed from the fine accumulators.
        keep_accumulators: auto_mip || mip.is_some_and(|l| l > 0),
        ..VoxeliseOptions::default()
    };
    let vp = voxelise(&patch, resolution, &opts).map_err(|e| bad(&e))?;
    // The shell's world mesh and tiles, or the free-standing placement.
    let shell_mesh = placement.rest_mesh.map(|m| m.transformed(xf));
    let tiles = match &shell_mesh {
        None => {
            if i.tiles.is_some() {
                return Err(ctx.invalid(
                    line,
                    format!(
                        "{owner}.tiles: only a fabric shell on a mesh is tiled (shape = \"mesh\")"
                    ),
                ));
            }
            None
        }
        Some(mesh) => Some(shell_tiles(ctx, line, owner, i, mesh, &patch)?),
    };
    let level = if auto_mip {
        let (voxel_world, bounds) = fabric_voxel_footprint(&vp, xf, shell_mesh.as_ref(), tiles);
        auto_fabric_mip(&vp, placement.view.at(bounds) / voxel_world.max(1e-30))
    } else {
        let l = mip.unwrap_or(0);
        if !halves_exactly(&vp, l) {
            return Err(ctx.invalid(line, format!("{owner}.mip = {l}: the patch has {} × {} voxels across its tile, which {l} halvings do not divide exactly; use a resolution that is a multiple of {}", vp.dims[0], vp.dims[1], 1u32 << l)));
        }
        l
    };
    let vp = if level > 0 {
        vp.mip(level).map_err(|e| bad(&e))?
    } else {
        vp
    };
    let patch_voxel_size = vp.voxel_size;
    let (field, pyramid) = match (shell_mesh, tiles) {
        (Some(mesh), Some(tiles)) => {
            // A shell over the cloth mesh (notes §3.3), in world space.
            let shell =
                crate::fabric::FabricShell::new(&vp, &mesh, &crate::fabric::ShellParams { tiles })
                    .map_err(|e| bad(&e))?;
            let pyramid = shell.majorant_pyramid().map_err(|e| bad(&e))?;
            (DensityField::Shell(Box::new(shell)), pyramid)
        }
        _ => {
            let mut grid = vp.grid;
            let placed = glam::DAffine3::from_mat4(xf.as_dmat4()) * grid.index_to_world();
            grid.set_index_to_world(placed).map_err(|e| bad(&e))?;
            let pyramid = crate::majorant::MajorantPyramid::from_grid(
                &grid,
                crate::fabric::voxelise::DENSITY,
            )
            .map_err(|e| bad(&e))?;
            let field = DensityField::Grid {
                grid,
                channel: crate::fabric::voxelise::DENSITY,
            };
            (field, pyramid)
        }
    };
    let shading =
        FabricShading::from_patch(&FibrePhaseParams::default(), &patch).map_err(|e| bad(&e))?;
    // The density is the fibre volume fraction; σ_t⁰ = density / attenuation per unit fraction
    // (× 4/π with fibre-projected extinction, whose mean over directions is then the same);
    // the fibre phase functions carry the yarn colours, so σ_s⁰ = σ_t⁰.
    let extinction = match i.extinction.as_deref().unwrap_or("fibre") {
        "fibre" => crate::fabric::FibreExtinction::Projected,
        "isotropic" => crate::fabric::FibreExtinction::Isotropic,
        other => {
            return Err(ctx.invalid(
                line,
                format!(
                "{owner}.extinction = \"{other}\" is unknown (expected \"fibre\" or \"isotropic\")"
            ),
            ))
        }
    };
    let scale = match extinction {
        crate::fabric::FibreExtinction::Projected => 4.0 / std::f32::consts::PI,
        crate::fabric::FibreExtinction::Isotropic => 1.0,
    };
    let sigma_t = attenuation.map(|d| density * scale / d);
    Ok(HeterogeneousMedium {
        field,
        pyramid,
        coefficients: crate::tracking::DensityCoefficients::new(sigma_t, sigma_t),
        phase: PhaseFunction::henyey_greenstein(0.0).map_err(|e| bad(&e))?,
        tracking: TrackingConfig::default(),
        fabric: Some(Box::new(crate::fabric::FabricLook {
            tangent_channel: crate::fabric::voxelise::TANGENT,
            id_channel: crate::fabric::voxelise::ID,
            patch_voxel_size,
            mip_level: level,
            extinction,
            shading,
        })),
    })
}

fn build_voxel_field(
    ctx: &Ctx,
    line: usize,
    owner: &str,
    i: &InteriorDesc,
    xf: glam::DAffine3,
) -> Result<(DensityField, crate::majorant::MajorantPyramid), SceneError> {
    let file = i.file.as_ref().ok_or_else(|| {
        ctx.invalid(
            line,
            format!("{owner}: a voxel interior needs `file` (an OpenVDB file)"),
        )
    })?;
    let path = ctx.resolve(file);
    let name = i.grid.as_deref().unwrap_or("density");
    let mut grids = crate::vdb::read_vdb_grids(&path, &[name])
        .map_err(|e| ctx.invalid(line, format!("{owner}: {e}")))?;
    let vg = grids
        .pop()
        .ok_or_else(|| ctx.invalid(line, format!("{owner}: {}: no grid {name}", path.display())))?;
    vg.check_finite()
        .map_err(|e| ctx.invalid(line, format!("{owner}: {}: {e}", path.display())))?;
    if vg.grid.channel_kind(0) != Some(crate::grid::ChannelKind::Scalar) {
        return Err(ctx.invalid(
            line,
            format!(
                "{owner}: {}: grid `{name}` is not a scalar grid ({})",
                path.display(),
                vg.value_type.name()
            ),
        ));
    }
    let stats = vg.stats();
    if stats.min[0] < 0.0 || vg.grid.background(0) < 0.0 {
        return Err(ctx.invalid(
            line,
            format!(
                "{owner}: {}: grid `{name}` has negative densities (min {})",
                path.display(),
                stats.min[0]
            ),
        ));
    }
    let mut grid = vg.grid;
    let placed = xf * grid.index_to_world();
    grid.set_index_to_world(placed)
        .map_err(|e| ctx.invalid(line, format!("{owner}: placing grid `{name}`: {e}")))?;
    let pyramid = crate::majorant::MajorantPyramid::from_grid(&grid, 0)
        .map_err(|e| ctx.invalid(line, format!("{owner}: grid `{name}`: {e}")))?;
    Ok((DensityField::Grid { grid, channel: 0 }, pyramid))
}

fn build_fbm_field(
    ctx: &Ctx,
    line: usize,
    owner: &str,
    i: &InteriorDesc,
    xf: glam::DAffine3,
    rest_bounds: Aabb,
) -> Result<(DensityField, crate::majorant::MajorantPyramid), SceneError> {
    use crate::procedural::{
        bake_fbm, procedural_pyramid, FbmField, FbmParams, ProceduralBound, ProceduralLattice,
    };
    let d = FbmParams::default();
    let n = i.noise.clone().unwrap_or(super::desc::NoiseDesc {
        frequency: None,
        octaves: None,
        lacunarity: None,
        gain: None,
        amplitude: None,
        offset: None,
        min: None,
        max: None,
        seed: None,
    });
    let params = FbmParams {
        frequency: n.frequency.unwrap_or(d.frequency),
        octaves: n.octaves.unwrap_or(d.octaves),
        lacunarity: n.lacunarity.unwrap_or(d.lacunarity),
        gain: n.gain.unwrap_or(d.gain),
        amplitude: n.amplitude.unwrap_or(d.amplitude),
        offset: n.offset.unwrap_or(d.offset),
        min: n.min.unwrap_or(d.min),
        max: n.max.unwrap_or(d.max),
        seed: n.seed.unwrap_or(d.seed),
    };
    let bad = |e: &dyn std::fmt::Display| ctx.invalid(line, format!("{owner}: {e}"));
    let field = FbmField::new(params, xf).map_err(|e| bad(&e))?;
    let extent = rest_bounds.extent().max_element().max(1e-9);
    let voxel_size = check_range(
        ctx,
        line,
        &format!("{owner}.voxel_size"),
        i.voxel_size.unwrap_or(extent / 128.0),
        extent * 1e-4,
        extent,
    )?;
    let lattice = ProceduralLattice::new(rest_bounds, voxel_size, xf).map_err(|e| bad(&e))?;
    match i.evaluation.as_deref().unwrap_or("baked") {
        "baked" => {
            reject_unused(ctx, line, owner, "fbm (baked)", &[("bound", i.bound.is_some()), ("bound_min", i.bound_min.is_some()), ("bound_max", i.bound_max.is_some()), ("trial_samples", i.trial_samples.is_some()), ("safety", i.safety.is_some())])?;
            let grid = bake_fbm(&field, &lattice).map_err(|e| bad(&e))?;
            let pyramid = crate::majorant::MajorantPyramid::from_grid(&grid, 0).map_err(|e| bad(&e))?;
            Ok((DensityField::Grid { grid, channel: 0 }, pyramid))
        }
        "lazy" | "exact" => {
            let bound = match i.bound.as_deref().unwrap_or("estimated") {
                "analytic" => ProceduralBound::Analytic,
                "artist" => {
                    let min = i.bound_min.unwrap_or(0.0);
                    let max = i.bound_max.ok_or_else(|| ctx.invalid(line, format!("{owner}: bound = \"artist\" needs `bound_max` (and optionally `bound_min`)")))?;
                    ProceduralBound::Artist { min, max }
                }
                "estimated" => ProceduralBound::Estimated { samples: i.trial_samples.unwrap_or(32), safety: i.safety.unwrap_or(1.25) },
                other => return Err(ctx.invalid(line, format!("{owner}.bound = \"{other}\" is unknown (expected \"analytic\", \"artist\" or \"estimated\")"))),
            };
            let pyramid = procedural_pyramid(&field, &lattice, bound, 0x5eed).map_err(|e| bad(&e))?;
            if i.evaluation.as_deref() == Some("lazy") {
                let lazy = crate::procedural::LazyFbmGrid::new(field, &lattice).map_err(|e| bad(&e))?;
                Ok((DensityField::LazyBaked(Box::new(lazy)), pyramid))
            } else {
                Ok((DensityField::Procedural(Box::new(field)), pyramid))
            }
        }
        other => Err(ctx.invalid(line, format!("{owner}.evaluation = \"{other}\" is unknown (expected \"baked\", \"lazy\" or \"exact\")"))),
    }
}

fn build_light(ctx: &Ctx, line: usize, l: &LightDesc) -> Result<Light, SceneError> {
    let owner = format!("light \"{}\"", l.kind);
    match l.kind.as_str() {
        "environment" => {
            reject_unused(ctx, line, &owner, &l.kind, &[("file", l.file.is_some()), ("scale", l.scale.is_some()), ("rotation", l.rotation.is_some()), ("direction", l.direction.is_some()), ("irradiance", l.irradiance.is_some()), ("angular_radius", l.angular_radius.is_some()), ("center", l.center.is_some()), ("radius", l.radius.is_some())])?;
            let radiance = check_finite_rgb(ctx, line, "light.radiance", color(l.radiance, Rgb::ONE), 0.0, 1e12)?;
            Ok(Light::ConstantEnvironment { radiance })
        }
        "envmap" => {
            reject_unused(ctx, line, &owner, &l.kind, &[("radiance", l.radiance.is_some()), ("direction", l.direction.is_some()), ("irradiance", l.irradiance.is_some()), ("angular_radius", l.angular_radius.is_some()), ("center", l.center.is_some()), ("radius", l.radius.is_some())])?;
            let file = l.file.as_ref().ok_or_else(|| ctx.invalid(line, "light \"envmap\" needs `file`"))?;
            let scale = check_range(ctx, line, "light.scale", l.scale.unwrap_or(1.0), 0.0, 1e12)?;
            let rotation = check_range(ctx, line, "light.rotation", l.rotation.unwrap_or(0.0), -36000.0, 36000.0)?;
            let map = crate::image_io::read_latlong_exr(&ctx.resolve(file)).map_err(|e| ctx.invalid(line, format!("light \"envmap\": {e}")))?;
            Ok(Light::EnvironmentMap(Box::new(EnvironmentMap::new(map, scale, rotation))))
        }
        "distant" => {
            reject_unused(ctx, line, &owner, &l.kind, &[("file", l.file.is_some()), ("scale", l.scale.is_some()), ("rotation", l.rotation.is_some()), ("radiance", l.radiance.is_some()), ("center", l.center.is_some()), ("radius", l.radius.is_some())])?;
            let dir = vec3(ctx, line, "light.direction", l.direction.ok_or_else(|| ctx.invalid(line, "light \"distant\" needs `direction` (towards the light)"))?)?;
            if dir.length() < 1e-12 {
                return Err(ctx.invalid(line, "light.direction must not be zero"));
            }
            let e = check_finite_rgb(ctx, line, "light.irradiance", color(l.irradiance, Rgb::splat(3.0)), 0.0, 1e12)?;
            let r = check_range(ctx, line, "light.angular_radius", l.angular_radius.unwrap_or(0.0), 0.0, 90.0)?;
            Ok(Light::distant(dir, e, r))
        }
        "sphere" => {
            reject_unused(ctx, line, &owner, &l.kind, &[("file", l.file.is_some()), ("scale", l.scale.is_some()), ("rotation", l.rotation.is_some()), ("direction", l.direction.is_some()), ("irradiance", l.irradiance.is_some()), ("angular_radius", l.angular_radius.is_some())])?;
            let center = vec3(ctx, line, "light.center", l.center.unwrap_or([0.0; 3]))?;
            let radius = check_range(ctx, line, "light.radius", l.radius.unwrap_or(0.1), 1e-9, 1e9)?;
            let radiance = check_finite_rgb(ctx, line, "light.radiance", color(l.radiance, Rgb::splat(10.0)), 0.0, 1e12)?;
            Ok(Light::Sphere { center, radius, radiance })
        }
        other => Err(ctx.invalid(line, format!("light.type = \"{other}\" is unknown (expected \"environment\", \"envmap\", \"distant\" or \"sphere\")"))),
    }
}

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
    let text = include_str!("../../scenes/creature.toml");
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
    scene.source = PathBuf::from(DEFAULT_SCENE_NAME);
    Ok(scene)
}
