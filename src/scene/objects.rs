//! `[[object]]`: shapes, transforms and the object list, each object with its surface
//! ([`super::surface`]) and interior ([`super::interior`]).

use toml::Spanned;

use super::context::Ctx;
use super::desc::{ColorInput, InteriorDesc, ObjectDesc, ScaleValue};
use super::interior::{build_medium, fabric_note, Placement};
use super::surface::build_surface;
use super::validate::{check_range, reject_unused, vec3};
use super::{Object, ObjectSurface, SceneError};
use crate::bsdf::microfacet::SMOOTH_ALPHA;
use crate::geometry::{load_ply, LevelSet, Shape, TriangleMesh};
use crate::math::{Aabb, Mat4, Vec3};
use crate::medium::{DensityField, Medium, NeeStrategy};
use crate::spectrum::Rgb;

/// The objects built so far and the interiors they own.
#[derive(Default)]
pub(super) struct ObjectList {
    /// Objects, in file order.
    pub objects: Vec<Object>,
    /// Interiors, indexed by [`Object::medium`].
    pub media: Vec<Medium>,
    /// Objects with `nee = "manifold"`: name, the interior table's line, and whether the
    /// object has no surface (its interface is an enclosing object's): the scene checks that a
    /// light they can connect to, and such an enclosing interface, exist.
    pub manifold: Vec<(String, usize, bool)>,
    /// Objects (indices into [`Self::objects`]) whose interiors leave `nee` to the default
    /// behind a rough dielectric boundary ([`super::nee::guided_boundary`]): built with
    /// `"exit"`, turned to `"exit_guided"` by [`super::nee::resolve_defaults`] once the
    /// scene's lights are known.
    pub auto_guided: Vec<usize>,
}

/// An object's parts made before its interior: its place, rest shape and surface
/// ([`stage`]).
pub(super) struct Staged {
    line: usize,
    name: String,
    xf: Mat4,
    uniform: Option<f32>,
    rest: RestShape,
    has_uvs: bool,
    surface: ObjectSurface,
    ior: f32,
}

/// An object's world shape made before its interior ([`place_early`]) and handed to the
/// geometry's build: what [`ObjectList::finish`] still needs to know of it.
pub(super) struct Placed {
    /// The mesh is open (not every edge shared by exactly two triangles).
    open_mesh: bool,
    /// [`uv_per_world`] of the world shape.
    uv: (f32, Vec<f32>),
}

/// Builds the `index`-th `[[object]]`'s transform, rest shape (meshes and level sets are
/// loaded here) and surface: everything [`ObjectList::finish`] does not.
pub(super) fn stage(
    ctx: &Ctx,
    index: usize,
    spanned: &Spanned<ObjectDesc>,
) -> Result<Staged, SceneError> {
    let line = ctx.line_of(spanned.span().start);
    let desc = spanned.get_ref();
    let name = desc
        .name
        .clone()
        .unwrap_or_else(|| format!("object {}", index + 1));
    let (xf, uniform) = object_transform(ctx, line, &name, desc)?;
    let rest = build_rest_shape(ctx, line, &name, desc, uniform)?;
    let has_uvs = match &rest {
        RestShape::Mesh(m) => m.uvs.is_some(),
        RestShape::Sphere { .. } => true,
        RestShape::Bounds | RestShape::LevelSet(_) => false,
    };
    let (surface, ior) = match &desc.surface {
        Some(s) => build_surface(
            ctx,
            ctx.line_of(s.span().start),
            &name,
            Some(s.get_ref()),
            has_uvs,
        )?,
        None => build_surface(ctx, line, &name, None, has_uvs)?,
    };
    Ok(Staged {
        line,
        name,
        xf,
        uniform,
        rest,
        has_uvs,
        surface,
        ior,
    })
}

/// Whether every object's world shape can be made before its interior ([`place_early`]): its
/// `shape` is a mesh or a sphere and its interior, if any, holds no fabric (whose shell may be
/// the object's shape, also as a look of a blend). Level sets, `shape = "bounds"` and fabrics
/// are placed after their interiors, as [`ObjectList::add`] does.
pub(super) fn all_placeable_early(objects: &[Spanned<ObjectDesc>]) -> bool {
    objects.iter().all(|o| {
        let d = o.get_ref();
        matches!(d.shape.as_str(), "mesh" | "sphere")
            && !d
                .interior
                .as_ref()
                .is_some_and(|i| holds_fabric(i.get_ref()))
    })
}

/// Whether interior `d` is a fabric or has one among its blend looks or mixture media.
fn holds_fabric(d: &InteriorDesc) -> bool {
    match d {
        InteriorDesc::Fabric(_) => true,
        InteriorDesc::Blend(b) => [&b.a, &b.b]
            .into_iter()
            .flatten()
            .any(|look| holds_fabric(look.get_ref())),
        InteriorDesc::Mixture(m) => m.media.iter().any(|c| holds_fabric(c.get_ref())),
        InteriorDesc::Absorption(_)
        | InteriorDesc::Homogeneous(_)
        | InteriorDesc::Voxel(_)
        | InteriorDesc::Fbm(_) => false,
    }
}

/// The world shape of a staged mesh or sphere object, made as [`ObjectList::add`] makes it
/// (a copy of the rest mesh placed by the object transform and, when closed, oriented
/// outward; a sphere's centre and radius placed), with what [`ObjectList::finish`] needs of
/// it. `None` for shapes placed after their interiors (level sets, bounds).
pub(super) fn place_early(staged: &Staged) -> Option<(Shape, Placed)> {
    let (shape, open_mesh) = match &staged.rest {
        RestShape::Mesh(rest) => {
            let mut mesh = rest.transformed(staged.xf);
            let closed = mesh.is_closed();
            if closed {
                mesh.make_outward();
            }
            (Shape::Mesh(mesh), !closed)
        }
        RestShape::Sphere { center, radius } => (
            sphere_shape(staged.xf, staged.uniform, *center, *radius),
            false,
        ),
        RestShape::Bounds | RestShape::LevelSet(_) => return None,
    };
    let uv = uv_per_world(&shape);
    Some((shape, Placed { open_mesh, uv }))
}

/// A sphere placed by object transform `xf` (uniform scale `uniform`).
fn sphere_shape(xf: Mat4, uniform: Option<f32>, center: Vec3, radius: f32) -> Shape {
    let scale = uniform.unwrap_or(1.0).abs();
    Shape::Sphere {
        center: xf.transform_point3(center),
        radius: radius * scale,
    }
}

impl ObjectList {
    /// Builds the `index`-th `[[object]]` of the file, adds it
    /// and returns its world shape. Warnings and notes go to the scene's lists.
    pub fn add(
        &mut self,
        ctx: &Ctx,
        index: usize,
        spanned: &Spanned<ObjectDesc>,
        warnings: &mut Vec<String>,
        notes: &mut Vec<String>,
    ) -> Result<Shape, SceneError> {
        let staged = stage(ctx, index, spanned)?;
        self.finish(ctx, spanned, staged, None, warnings, notes)?
            .ok_or_else(|| ctx.invalid(1, "an object's shape was lost".to_string()))
    }

    /// Builds a staged object's interior and adds the object. With `placed` (its world shape
    /// made by [`place_early`] and given to the geometry), returns `None`; otherwise makes and
    /// returns the world shape, as [`Self::add`].
    pub fn finish(
        &mut self,
        ctx: &Ctx,
        spanned: &Spanned<ObjectDesc>,
        staged: Staged,
        placed: Option<Placed>,
        warnings: &mut Vec<String>,
        notes: &mut Vec<String>,
    ) -> Result<Option<Shape>, SceneError> {
        let desc = spanned.get_ref();
        let Staged {
            line,
            name,
            xf,
            uniform,
            rest,
            has_uvs,
            surface,
            ior,
        } = staged;
        let mut walk = None;
        let (medium, nee) = match &desc.interior {
            Some(interior) => {
                let placement = Placement {
                    xf,
                    rest_bounds: rest.bounds(),
                    rest_mesh: match &rest {
                        RestShape::Mesh(m) => Some(m),
                        _ => None,
                    },
                    has_uvs,
                };
                let interior_line = ctx.line_of(interior.span().start);
                let built = build_medium(
                    ctx,
                    interior_line,
                    &name,
                    format!("{name}: interior"),
                    interior.get_ref(),
                    &placement,
                    &mut self.media,
                )?;
                walk = built.walk.map(Box::new);
                self.media.push(built.medium);
                (Some((self.media.len() - 1) as u32), built.nee)
            }
            None => (None, NeeStrategy::ExitPoint),
        };
        if nee == NeeStrategy::Manifold {
            let interior_line = desc
                .interior
                .as_ref()
                .map_or(line, |i| ctx.line_of(i.span().start));
            check_manifold_boundary(ctx, interior_line, &name, &surface)?;
            let enclosed = matches!(surface, ObjectSurface::Null);
            self.manifold.push((name.clone(), interior_line, enclosed));
        }
        let media = &self.media;
        if let Some(note) = medium.and_then(|m| fabric_note(&media[m as usize])) {
            notes.push(format!("{name}: {note}"));
        }
        let shell_boundary = medium.and_then(|m| match &media[m as usize] {
            Medium::Heterogeneous(h) => match &h.field {
                DensityField::Shell(shell) => Some(shell.boundary_mesh().clone()),
                _ => None,
            },
            // A fabric with textured yarn colours.
            Medium::Dyed(f) => match &f.medium.field {
                DensityField::Shell(shell) => Some(shell.boundary_mesh().clone()),
                _ => None,
            },
            _ => None,
        });
        let (shape, open_mesh, early_uv) = match placed {
            Some(p) => {
                if shell_boundary.is_some() {
                    return Err(ctx.invalid(
                        line,
                        format!("{name}: a fabric shell cannot be placed before its interior"),
                    ));
                }
                (None, p.open_mesh, Some(p.uv))
            }
            None => {
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
                        (sphere_shape(xf, uniform, center, radius), false)
                    }
                    (RestShape::LevelSet(mut ls), _) => {
                        ls.transform(xf).map_err(|e| {
                            ctx.invalid(line, format!("{name}: placing the level set: {e}"))
                        })?;
                        (Shape::LevelSet(std::sync::Arc::new(*ls)), false)
                    }
                    (RestShape::Bounds, _) => {
                        let bounds = match medium.map(|m| &media[m as usize]) {
                        Some(Medium::Heterogeneous(h)) => Ok(h.world_bounds()),
                        Some(Medium::Mixture(m)) => Ok(m.world_bounds()),
                        _ => Err(ctx.invalid(
                            line,
                            format!(
                                "{name}: shape \"bounds\" needs a \"voxel\", \"fabric\" or \"mixture\" interior"
                            ),
                        )),
                    }?;
                        let b = bounds.ok_or_else(|| {
                            ctx.invalid(line, format!("{name}: the interior's grid is empty"))
                        })?;
                        (
                            Shape::Box {
                                min: b.min,
                                max: b.max,
                            },
                            false,
                        )
                    }
                };
                (Some(shape), open_mesh, None)
            }
        };
        // Exit-point NEE needs a scattering boundary: behind an index-matched one (no surface,
        // or a dielectric of IOR 1) it would never happen, so NEE moves to the interior
        // vertices, where transparent shadows through such a boundary are exact. (Manifold NEE
        // behind no surface refracts at the enclosing boundary instead.)
        let index_matched = match &surface {
            ObjectSurface::Null => true,
            ObjectSurface::Dielectric(d) => d.ior == 1.0,
            // Both looks are dielectrics of one IOR, or neither (checked by the blend).
            ObjectSurface::Blend(b) => matches!(&b.a, ObjectSurface::Dielectric(d) if d.ior == 1.0),
            ObjectSurface::Fixed(_) | ObjectSurface::Textured(_) => false,
        };
        let auto_nee = desc
            .interior
            .as_ref()
            .is_some_and(|i| super::nee::is_auto(i.get_ref().nee()));
        let nee = if medium.is_some()
            && index_matched
            && !matches!(nee, NeeStrategy::Interior | NeeStrategy::Manifold)
        {
            if !auto_nee {
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
        let (uv_scale, uv_scales) = if surface.is_textured() || walk.is_some() {
            match (&shape, early_uv) {
                (Some(shape), _) => uv_per_world(shape),
                (None, Some(uv)) => uv,
                (None, None) => (0.0, Vec::new()),
            }
        } else {
            (0.0, Vec::new())
        };
        if medium.is_some()
            && auto_nee
            && nee == NeeStrategy::ExitPoint
            && super::nee::guided_boundary(&surface)
        {
            self.auto_guided.push(self.objects.len());
        }
        self.objects.push(Object {
            name,
            surface,
            medium,
            priority: desc.priority.unwrap_or(0),
            ior,
            nee,
            aov_albedo: desc.interior.as_ref().and_then(|i| aov_albedo(i.get_ref())),
            interior_kind: desc
                .interior
                .as_ref()
                .map_or_else(String::new, |i| interior_kind(i.get_ref())),
            walk,
            uv_scale,
            uv_scales,
        });
        Ok(shape)
    }
}

/// `nee = "manifold"` needs the object's own boundary to be a smooth refracting dielectric
/// (the interface the manifold walk solves on): a `dielectric` surface whose roughness the
/// BSDF treats as smooth (roughness² below [`SMOOTH_ALPHA`], i.e. roughness < 0.0316), an IOR
/// other than 1 and no coat, or a `blend` of two such dielectrics (of one IOR; the connection
/// then transmits the mask-weighted tint); or no surface at all (an index-matched region
/// inside such an object, e.g. an iris inside an eye: the walk then refracts at the enclosing
/// boundary, which [`super::build`] checks exists).
fn check_manifold_boundary(
    ctx: &Ctx,
    line: usize,
    name: &str,
    surface: &ObjectSurface,
) -> Result<(), SceneError> {
    let why = match surface {
        ObjectSurface::Null => None,
        ObjectSurface::Blend(b) => not_smooth_refractor(&b.a, "surface.a")
            .or_else(|| not_smooth_refractor(&b.b, "surface.b")),
        s => not_smooth_refractor(s, "surface"),
    };
    let Some(why) = why else {
        return Ok(());
    };
    Err(ctx.invalid(
        line,
        format!(
            "{name}: interior.nee = \"manifold\" needs a smooth refractive boundary (surface type = \"dielectric\", roughness = 0, or a blend of two such, or no surface inside such an object), but {why}"
        ),
    ))
}

/// Why surface `s` (the table `key` of its object) is not a smooth refracting dielectric
/// without a coat; `None` when it is one.
fn not_smooth_refractor(s: &ObjectSurface, key: &str) -> Option<String> {
    match s {
        ObjectSurface::Dielectric(d) if d.roughness.max() * d.roughness.max() >= SMOOTH_ALPHA => {
            Some(format!(
                "its {key}.roughness = {} is rough (must be 0, below {:.4} at most)",
                d.roughness.max(),
                SMOOTH_ALPHA.sqrt()
            ))
        }
        ObjectSurface::Dielectric(d) if d.ior == 1.0 => {
            Some(format!("its {key}.ior = 1 does not refract"))
        }
        ObjectSurface::Dielectric(d) if d.coat.is_some() => Some(format!(
            "its {key} has a coat (not supported by the manifold walk)"
        )),
        ObjectSurface::Dielectric(_) => None,
        ObjectSurface::Fixed(_) | ObjectSurface::Textured(_) | ObjectSurface::Null => {
            Some(format!("its {key} is not a dielectric"))
        }
        ObjectSurface::Blend(_) => Some(format!("its {key} is a blend inside a blend")),
    }
}

/// True when `surface` can be the manifold walk's interface (seen from vacuum): a smooth
/// refracting dielectric without a coat, or a blend of two ([`check_manifold_boundary`]).
pub(super) fn is_smooth_refractor(surface: &ObjectSurface) -> bool {
    match surface {
        ObjectSurface::Blend(b) => {
            not_smooth_refractor(&b.a, "").is_none() && not_smooth_refractor(&b.b, "").is_none()
        }
        ObjectSurface::Null => false,
        s => not_smooth_refractor(s, "").is_none(),
    }
}

/// Texture units per world unit of a shape's surface: sqrt(UV area / world area) over the
/// whole shape (a sphere's (φ/2π, θ/π) parameterisation covers the unit square over 4πr²),
/// and for a mesh the same per triangle (Akenine-Möller et al.'s Δ, docs/references.md §14.2;
/// degenerate triangles take the whole mesh's figure). They turn a ray cone's width into a
/// footprint in texture units (docs/textures.md).
fn uv_per_world(shape: &Shape) -> (f32, Vec<f32>) {
    match shape {
        Shape::Sphere { radius, .. } => (
            1.0 / (2.0 * radius * std::f32::consts::PI.sqrt()),
            Vec::new(),
        ),
        Shape::Mesh(m) => {
            let Some(uvs) = &m.uvs else {
                return (0.0, Vec::new());
            };
            let (mut uv_total, mut total) = (0.0f64, 0.0f64);
            let per_triangle: Vec<(f64, f64)> = m
                .indices
                .iter()
                .map(|tri| {
                    let [a, b, c] = tri.map(|i| i as usize);
                    match (
                        m.positions.get(a),
                        m.positions.get(b),
                        m.positions.get(c),
                        uvs.get(a),
                        uvs.get(b),
                        uvs.get(c),
                    ) {
                        (Some(pa), Some(pb), Some(pc), Some(ta), Some(tb), Some(tc)) => {
                            let area = f64::from((*pb - *pa).cross(*pc - *pa).length());
                            let uv_area = f64::from(((*tb - *ta).perp_dot(*tc - *ta)).abs());
                            total += area;
                            uv_total += uv_area;
                            (uv_area, area)
                        }
                        _ => (0.0, 0.0),
                    }
                })
                .collect();
            let whole = if total > 0.0 {
                (uv_total / total).sqrt() as f32
            } else {
                0.0
            };
            let per = per_triangle
                .iter()
                .map(|&(uv, area)| {
                    let r = (uv / area).sqrt() as f32;
                    if area > 0.0 && uv > 0.0 && r.is_finite() {
                        r
                    } else {
                        whole
                    }
                })
                .collect();
            (whole, per)
        }
        _ => (0.0, Vec::new()),
    }
}

/// The object transform `translate · rotate · scale`, and the scale when it is uniform.
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
    /// A triangle mesh.
    Mesh(TriangleMesh),
    /// A sphere.
    Sphere {
        /// Centre.
        center: Vec3,
        /// Radius.
        radius: f32,
    },
    /// The world box of the interior's grid.
    Bounds,
    /// A level set (placed by its file's transform; the object transform comes on top;
    /// boxed: it is much larger than the other shapes).
    LevelSet(Box<LevelSet>),
}

impl RestShape {
    /// The rest-space box (none for [`RestShape::Bounds`], which is already in world space).
    fn bounds(&self) -> Option<Aabb> {
        match self {
            RestShape::Mesh(m) => Some(m.bounds()),
            RestShape::Sphere { center, radius } => Some(Aabb {
                min: *center - Vec3::splat(*radius),
                max: *center + Vec3::splat(*radius),
            }),
            RestShape::LevelSet(ls) => Some(ls.bounds()),
            RestShape::Bounds => None,
        }
    }
}

/// The object's `shape` in its rest space (meshes are loaded here).
fn build_rest_shape(
    ctx: &Ctx,
    line: usize,
    name: &str,
    d: &ObjectDesc,
    uniform: Option<f32>,
) -> Result<RestShape, SceneError> {
    match d.shape.as_str() {
        "mesh" => {
            reject_unused(
                ctx,
                line,
                name,
                "mesh",
                &[
                    ("center", d.center.is_some()),
                    ("radius", d.radius.is_some()),
                    ("grid", d.grid.is_some()),
                ],
            )?;
            let file = d.file.as_ref().ok_or_else(|| {
                ctx.invalid(line, format!("{name}: shape \"mesh\" needs `file`"))
            })?;
            let path = ctx.resolve(file);
            let mesh = load_ply(&path).map_err(|e| ctx.invalid(line, format!("{name}: {e}")))?;
            Ok(RestShape::Mesh(mesh))
        }
        "sphere" => {
            reject_unused(
                ctx,
                line,
                name,
                "sphere",
                &[("file", d.file.is_some()), ("grid", d.grid.is_some())],
            )?;
            let center = vec3(
                ctx,
                line,
                &format!("{name}: center"),
                d.center.unwrap_or([0.0; 3]),
            )?;
            let radius = check_range(
                ctx,
                line,
                &format!("{name}: radius"),
                d.radius.unwrap_or(1.0),
                1e-9,
                1e9,
            )?;
            if uniform.is_none() {
                return Err(ctx.invalid(line, format!("{name}: a sphere needs a uniform scale")));
            }
            Ok(RestShape::Sphere { center, radius })
        }
        "bounds" => {
            reject_unused(
                ctx,
                line,
                name,
                "bounds",
                &[
                    ("file", d.file.is_some()),
                    ("center", d.center.is_some()),
                    ("radius", d.radius.is_some()),
                    ("grid", d.grid.is_some()),
                ],
            )?;
            Ok(RestShape::Bounds)
        }
        "levelset" => {
            reject_unused(
                ctx,
                line,
                name,
                "levelset",
                &[("center", d.center.is_some()), ("radius", d.radius.is_some())],
            )?;
            let file = d.file.as_ref().ok_or_else(|| {
                ctx.invalid(
                    line,
                    format!("{name}: shape \"levelset\" needs `file` (an OpenVDB level set)"),
                )
            })?;
            let path = ctx.resolve(file);
            let grid = d.grid.as_deref().unwrap_or("surface");
            Ok(RestShape::LevelSet(Box::new(load_level_set(
                ctx, line, name, &path, grid,
            )?)))
        }
        other => Err(ctx.invalid(
            line,
            format!(
                "{name}: shape = \"{other}\" is unknown (expected \"mesh\", \"sphere\", \"bounds\" or \"levelset\")"
            ),
        )),
    }
}

/// Reads grid `grid` of the VDB file at `path` as a level-set boundary. Refused, naming the
/// file and grid: a missing grid (the message lists the file's grids), a grid of class
/// `fog volume` or `staggered`, and any grid that [`LevelSet::new`] refuses (vectors, no
/// negative values, a background that is not positive, non-finite values). Class `unknown`
/// is accepted when the values are those of a level set.
fn load_level_set(
    ctx: &Ctx,
    line: usize,
    name: &str,
    path: &std::path::Path,
    grid: &str,
) -> Result<LevelSet, SceneError> {
    let file =
        crate::vdb::VdbFile::open(path).map_err(|e| ctx.invalid(line, format!("{name}: {e}")))?;
    let vg = file
        .read_grid(grid)
        .map_err(|e| ctx.invalid(line, format!("{name}: {e}")))?;
    let where_ = format!("{name}: {}: grid `{grid}`", path.display());
    if vg.class == "fog volume" || vg.class == "staggered" {
        return Err(ctx.invalid(
            line,
            format!(
                "{where_} has class `{}`, not a level set: shape = \"levelset\" needs a signed distance grid (class `level set`, negative inside; `velour voxelize --levelset`); a fog volume belongs in `interior = {{ type = \"voxel\" }}`",
                vg.class
            ),
        ));
    }
    LevelSet::new(vg.grid).map_err(|e| {
        ctx.invalid(
            line,
            format!(
                "{where_} (class `{}`) is not a usable level set: {e}",
                vg.class
            ),
        )
    })
}

/// The albedo an interior shows in the albedo AOV: its artist albedo (default 0.8) when it has
/// one constant colour.
fn aov_albedo(desc: &InteriorDesc) -> Option<Rgb> {
    let value = match desc {
        InteriorDesc::Homogeneous(d) => match &d.albedo {
            None => None,
            Some(ColorInput::Value(v)) => Some(*v),
            // A textured albedo varies per entry: the first event inside shows it.
            Some(ColorInput::Texture(_)) => return None,
        },
        // An albedo grid varies per vertex: the first event inside shows it.
        InteriorDesc::Voxel(d) if d.albedo_grid.is_some() => return None,
        InteriorDesc::Voxel(d) => constant_colour(d.albedo.as_ref())?,
        InteriorDesc::Fbm(d) => constant_colour(d.albedo.as_ref())?,
        InteriorDesc::Absorption(_)
        | InteriorDesc::Fabric(_)
        | InteriorDesc::Blend(_)
        | InteriorDesc::Mixture(_) => return None,
    };
    Some(super::validate::color(value, Rgb::splat(0.8)))
}

/// A colour key's constant (`Some(None)` when absent), or `None` for a texture (it varies per
/// entry: the first event inside shows it).
fn constant_colour(v: Option<&ColorInput>) -> Option<Option<crate::scene::desc::ColorValue>> {
    match v {
        None => Some(None),
        Some(ColorInput::Value(c)) => Some(Some(*c)),
        Some(ColorInput::Texture(_)) => None,
    }
}

/// How the render summary names an interior: its `type`, and for fBm its evaluation.
fn interior_kind(desc: &InteriorDesc) -> String {
    match desc {
        InteriorDesc::Fbm(d) => format!("fbm ({})", d.evaluation.as_deref().unwrap_or("baked")),
        other => other.kind().to_string(),
    }
}
