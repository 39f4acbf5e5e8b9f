//! The interior stack (Schmidt & Budge 2002, "Simple Nested Dielectrics in Ray Traced
//! Images"): which objects a point is inside of, which one governs, and which boundary
//! crossings are false intersections that only update the stack.

use std::borrow::Cow;

use crate::bsdf::Surface;
use crate::math::Vec2;
use crate::medium::{Medium, WalkMedium};
use crate::scene::{Object, ObjectSurface, Scene};

/// The deepest nesting of interiors tracked; deeper entries are ignored.
pub const MAX_NESTING: usize = 16;

/// How many entered objects with per-walk interiors (textured, blended) keep their resolved
/// medium on the stack at once; a deeper one falls back to its stand-in medium.
pub const WALK_SLOTS: usize = 2;

/// The objects (by index) that a point is inside of, with their priorities, and the media
/// resolved at the entry points of the entered objects whose interiors are resolved per walk
/// (docs/textures.md).
#[derive(Clone, Copy, Debug)]
pub struct InteriorStack {
    entries: [u32; MAX_NESTING],
    len: usize,
    walk: [(u32, WalkMedium); WALK_SLOTS],
    walk_len: usize,
}

impl Default for InteriorStack {
    fn default() -> Self {
        InteriorStack {
            entries: [0; MAX_NESTING],
            len: 0,
            walk: [(u32::MAX, WalkMedium::Scene(0)); WALK_SLOTS],
            walk_len: 0,
        }
    }
}

impl InteriorStack {
    /// The stack with nothing entered.
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }

    /// Entered objects, oldest first.
    #[must_use]
    pub fn entries(&self) -> &[u32] {
        &self.entries[..self.len]
    }

    /// True if `obj` is on the stack.
    #[must_use]
    pub fn contains(&self, obj: u32) -> bool {
        self.entries().contains(&obj)
    }

    /// Enters `obj`.
    pub fn push(&mut self, obj: u32) {
        if self.len < MAX_NESTING && !self.contains(obj) {
            self.entries[self.len] = obj;
            self.len += 1;
        }
    }

    /// Enters `obj` with the medium resolved at its entry point for this walk.
    pub fn push_walk(&mut self, obj: u32, medium: WalkMedium) {
        if self.contains(obj) {
            return;
        }
        self.push(obj);
        if self.walk_len < WALK_SLOTS && self.contains(obj) {
            self.walk[self.walk_len] = (obj, medium);
            self.walk_len += 1;
        }
    }

    /// The medium resolved for `obj` when it was entered, if any.
    #[inline]
    #[must_use]
    pub fn walk_medium(&self, obj: u32) -> Option<WalkMedium> {
        self.walk[..self.walk_len]
            .iter()
            .find(|(o, _)| *o == obj)
            .map(|(_, m)| *m)
    }

    /// Leaves `obj` (no-op if not entered).
    pub fn remove(&mut self, obj: u32) {
        if let Some(i) = self.entries().iter().position(|&o| o == obj) {
            self.entries.copy_within(i + 1..self.len, i);
            self.len -= 1;
        }
        if self.walk_len > 0 {
            if let Some(i) = self.walk[..self.walk_len]
                .iter()
                .position(|(o, _)| *o == obj)
            {
                self.walk.copy_within(i + 1..self.walk_len, i);
                self.walk_len -= 1;
            }
        }
    }

    /// The governing object: highest priority, the most recently entered on ties;
    /// `exclude` is ignored.
    #[must_use]
    pub fn top(&self, objects: &[Object], exclude: Option<u32>) -> Option<u32> {
        let mut best: Option<u32> = None;
        for &o in self.entries() {
            if Some(o) == exclude {
                continue;
            }
            match best {
                Some(b) if objects[b as usize].priority > objects[o as usize].priority => {}
                _ => best = Some(o),
            }
        }
        best
    }

    /// IOR of the medium around, ignoring `exclude` (1 for vacuum).
    #[must_use]
    pub fn ior(&self, objects: &[Object], exclude: Option<u32>) -> f32 {
        self.top(objects, exclude)
            .map_or(1.0, |o| objects[o as usize].ior)
    }
}

/// The medium governing a point with the given stack, and the object it belongs to: the
/// object's medium, or for an object whose interior is resolved per walk the medium resolved
/// when the path entered it (a homogeneous one made for this walk, or a medium of the scene).
#[inline]
pub(super) fn current_medium<'a>(
    scene: &'a Scene,
    stack: &InteriorStack,
) -> Option<(Cow<'a, Medium>, &'a Object)> {
    let top = stack.top(&scene.objects, None)?;
    let obj = &scene.objects[top as usize];
    if obj.walk.is_some() {
        if let Some(w) = stack.walk_medium(top) {
            let m = match w {
                WalkMedium::Scene(i) => Cow::Borrowed(scene.media.get(i as usize)?),
                WalkMedium::Homogeneous(h) => Cow::Owned(Medium::Homogeneous(h)),
                WalkMedium::Absorbing(sigma_a) => Cow::Owned(Medium::Absorbing { sigma_a }),
            };
            return Some((m, obj));
        }
    }
    obj.medium
        .map(|m| (Cow::Borrowed(&scene.media[m as usize]), obj))
}

/// Enters object `oi` at texture coordinates `uv` (footprint `width_uv` wide): an object
/// whose interior is resolved per walk resolves it here (`u()` gives a blend's random number,
/// drawn only for blends).
pub(super) fn enter(
    scene: &Scene,
    stack: &mut InteriorStack,
    oi: u32,
    uv: Vec2,
    width_uv: f32,
    mut u: impl FnMut() -> f32,
) {
    match scene
        .objects
        .get(oi as usize)
        .and_then(|o| o.walk.as_deref())
    {
        Some(w) => {
            let r = if w.is_random() { u() } else { 0.0 };
            stack.push_walk(oi, w.resolve(uv, width_uv, r));
        }
        None => stack.push(oi),
    }
}

/// Builds the boundary BSDF of `obj` for the media meeting there, with textured parameters
/// at their means (callers that know the hit use [`boundary_surface_at`]).
pub(super) fn boundary_surface(obj: &Object, outside_ior: f32) -> Option<Surface> {
    boundary_surface_at(obj, outside_ior, Vec2::ZERO, f32::INFINITY)
}

/// Builds the boundary BSDF of `obj` for the media meeting there, its textured parameters
/// read at texture coordinates `uv` with a footprint `width_uv` wide.
pub(super) fn boundary_surface_at(
    obj: &Object,
    outside_ior: f32,
    uv: Vec2,
    width_uv: f32,
) -> Option<Surface> {
    match &obj.surface {
        ObjectSurface::Fixed(s) => Some(s.clone()),
        ObjectSurface::Null => None,
        ObjectSurface::Textured(t) => t.at(uv, width_uv),
        ObjectSurface::Dielectric(d) => {
            let eta = d.ior / outside_ior.max(1e-6);
            let s = Surface::dielectric(
                eta,
                d.roughness.eval(uv, width_uv),
                d.distribution,
                d.tint.eval(uv, width_uv),
            )
            .ok()?;
            match &d.coat {
                Some((ior, r, w)) => s.with_coat(*ior, *r, w.eval(uv, width_uv)).ok(),
                None => Some(s),
            }
        }
    }
}

/// True when a boundary of transmissive object `oi` does not interact: entering an object
/// under a higher-priority interior, leaving an object while a higher-priority one governs,
/// and the inconsistent cases that rounding can produce at silhouettes (entering an object
/// already entered, leaving one never entered), which pass straight through.
pub(super) fn is_false_intersection(
    scene: &Scene,
    stack: &InteriorStack,
    oi: u32,
    entering: bool,
) -> bool {
    let governing = stack.top(&scene.objects, None);
    if entering {
        stack.contains(oi)
            || governing.is_some_and(|g| {
                scene.objects[g as usize].priority > scene.objects[oi as usize].priority
            })
    } else {
        !stack.contains(oi) || governing != Some(oi)
    }
}
