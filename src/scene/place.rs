//! Placing a scene's objects: each object's shape, surface and interior
//! ([`objects::ObjectList`]) and the shapes the scene's geometry is built from.
//!
//! The BVH over the objects' triangles is the largest serial step of loading a scene with a
//! large mesh: when every shape is known before the interiors (and no sphere light adds
//! one, [`can_overlap`]), it is built on its own thread while the interiors are
//! ([`place_objects`] with `overlap`). Either way the objects, shapes, warnings, notes and
//! input files come out as the object-by-object build makes them, and the first error
//! reported is the one it meets first.

use std::path::PathBuf;
use std::thread::{Scope, ScopedJoinHandle};

use toml::Spanned;

use super::context::Ctx;
use super::desc::{LightDesc, ObjectDesc};
use super::{objects, SceneError, ShapeOwner};
use crate::geometry::{GeometryError, SceneGeometry, Shape};
use crate::light::Light;

/// The placed objects and the shapes of the scene's geometry, built or being built.
pub(super) struct Placement<'scope> {
    /// The objects and their interiors, in file order.
    pub built: objects::ObjectList,
    /// The owner of each shape of the geometry, in the geometry's order.
    pub shape_owner: Vec<ShapeOwner>,
    /// The shapes not handed to a build yet (none when the build runs beside the interiors).
    shapes: Vec<Shape>,
    /// The geometry's build started beside the interiors.
    pending: Option<ScopedJoinHandle<'scope, Result<SceneGeometry, GeometryError>>>,
}

/// Whether the geometry can be built beside the interiors: every object's shape can be
/// placed before its interior ([`objects::all_placeable_early`]) and no sphere light adds a
/// shape after them.
pub(super) fn can_overlap(objects: &[Spanned<ObjectDesc>], lights: &[Spanned<LightDesc>]) -> bool {
    let sphere_lights = lights
        .iter()
        .any(|l| matches!(l.get_ref(), LightDesc::Sphere(_)));
    !sphere_lights && objects::all_placeable_early(objects)
}

/// Builds every `[[object]]` of `descs` in file order. With `overlap` (which only
/// [`can_overlap`] scenes may ask for), the shapes are made first and the geometry's build
/// starts on a thread of `scope` while the interiors are built; otherwise objects are built
/// one by one and the geometry is built by [`Placement::geometry`]. Warnings and notes go to
/// the scene's lists.
pub(super) fn place_objects<'scope>(
    scope: &'scope Scope<'scope, '_>,
    ctx: &Ctx,
    descs: &[Spanned<ObjectDesc>],
    overlap: bool,
    warnings: &mut Vec<String>,
    notes: &mut Vec<String>,
) -> Result<Placement<'scope>, SceneError> {
    if overlap {
        place_overlapped(scope, ctx, descs, warnings, notes)
    } else {
        place_serially(ctx, descs, warnings, notes)
    }
}

/// The object-by-object build ([`objects::ObjectList::add`]), which the overlapped one must
/// equal.
fn place_serially<'scope>(
    ctx: &Ctx,
    descs: &[Spanned<ObjectDesc>],
    warnings: &mut Vec<String>,
    notes: &mut Vec<String>,
) -> Result<Placement<'scope>, SceneError> {
    let mut built = objects::ObjectList::default();
    let mut shapes = Vec::with_capacity(descs.len());
    let mut shape_owner = Vec::with_capacity(descs.len());
    for (index, desc) in descs.iter().enumerate() {
        shapes.push(built.add(ctx, index, desc, warnings, notes)?);
        shape_owner.push(object_owner(&built));
    }
    Ok(Placement {
        built,
        shape_owner,
        shapes,
        pending: None,
    })
}

/// Stages every object ([`stage_all`]), places their shapes ([`objects::place_early`]),
/// starts the geometry's build on a thread of `scope`, then builds the interiors
/// ([`objects::ObjectList::finish`]) and puts the input files in the serial build's order.
fn place_overlapped<'scope>(
    scope: &'scope Scope<'scope, '_>,
    ctx: &Ctx,
    descs: &[Spanned<ObjectDesc>],
    warnings: &mut Vec<String>,
    notes: &mut Vec<String>,
) -> Result<Placement<'scope>, SceneError> {
    let mut built = objects::ObjectList::default();
    let staged = stage_all(ctx, descs, &mut built, warnings, notes)?;
    let mut shapes = Vec::with_capacity(staged.len());
    let mut placed = Vec::with_capacity(staged.len());
    for (s, _) in &staged {
        let (shape, p) = objects::place_early(s)
            .ok_or_else(|| ctx.invalid(1, "an object's shape cannot be placed early"))?;
        shapes.push(shape);
        placed.push(p);
    }
    let pending = Some(scope.spawn(move || SceneGeometry::build(shapes)));
    let mut shape_owner = Vec::with_capacity(staged.len());
    let mut own_inputs = Vec::with_capacity(staged.len());
    for (((s, stage_inputs), p), desc) in staged.into_iter().zip(placed).zip(descs) {
        let from = ctx.inputs.borrow().len();
        built.finish(ctx, desc, s, Some(p), warnings, notes)?;
        let interior_inputs = ctx.inputs.borrow_mut().split_off(from);
        own_inputs.push((stage_inputs, interior_inputs));
        shape_owner.push(object_owner(&built));
    }
    // The files in the order the serial build reads them: each object's own, its
    // interior's after its shape's and surface's.
    let mut inputs = ctx.inputs.borrow_mut();
    for (stage_inputs, interior_inputs) in own_inputs {
        inputs.extend(stage_inputs);
        inputs.extend(interior_inputs);
    }
    Ok(Placement {
        built,
        shape_owner,
        shapes: Vec::new(),
        pending,
    })
}

/// The owner of the shape of the object `built` added last.
fn object_owner(built: &objects::ObjectList) -> ShapeOwner {
    ShapeOwner::Object((built.objects.len() - 1) as u32)
}

/// Stages every object ([`objects::stage`]) with the input files each one reads. When one
/// fails, the objects before it are built in full first ([`objects::ObjectList::finish`]), so
/// that the error reported is the one the object-by-object build meets first.
fn stage_all(
    ctx: &Ctx,
    descs: &[Spanned<ObjectDesc>],
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

impl Placement<'_> {
    /// Adds the shape of every sphere light of `lights` (the scene's lights, in order) after
    /// the objects' shapes. Only a serial placement has room for them ([`can_overlap`]).
    pub fn add_light_shapes(&mut self, lights: &[Light]) {
        for (index, light) in lights.iter().enumerate() {
            if let Light::Sphere { center, radius, .. } = light {
                self.shapes.push(Shape::Sphere {
                    center: *center,
                    radius: *radius,
                });
                self.shape_owner.push(ShapeOwner::Light(index as u32));
            }
        }
    }

    /// The scene's geometry: the build started beside the interiors, joined (a panic there
    /// resumes here), or the shapes built now.
    pub fn geometry(&mut self, ctx: &Ctx) -> Result<SceneGeometry, SceneError> {
        let shapes = std::mem::take(&mut self.shapes);
        match self.pending.take() {
            Some(handle) => {
                debug_assert!(shapes.is_empty(), "sphere lights are placed serially");
                handle
                    .join()
                    .unwrap_or_else(|panic| std::panic::resume_unwind(panic))
            }
            None => SceneGeometry::build(shapes),
        }
        .map_err(|e| ctx.invalid(1, format!("building the geometry: {e}")))
    }
}
