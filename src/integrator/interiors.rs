//! The interior stack (Schmidt & Budge 2002, "Simple Nested Dielectrics in Ray Traced
//! Images"): which objects a point is inside of, which one governs, and which boundary
//! crossings are false intersections that only update the stack.

use crate::bsdf::Surface;
use crate::medium::Medium;
use crate::scene::{Object, ObjectSurface, Scene};

/// The deepest nesting of interiors tracked; deeper entries are ignored.
pub const MAX_NESTING: usize = 16;

/// The objects (by index) that a point is inside of, with their priorities.
#[derive(Clone, Copy, Debug)]
pub struct InteriorStack {
    entries: [u32; MAX_NESTING],
    len: usize,
}

impl Default for InteriorStack {
    fn default() -> Self {
        InteriorStack {
            entries: [0; MAX_NESTING],
            len: 0,
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

    /// Leaves `obj` (no-op if not entered).
    pub fn remove(&mut self, obj: u32) {
        if let Some(i) = self.entries().iter().position(|&o| o == obj) {
            self.entries.copy_within(i + 1..self.len, i);
            self.len -= 1;
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

/// The medium governing a point with the given stack, and the object it belongs to.
pub(super) fn current_medium<'a>(
    scene: &'a Scene,
    stack: &InteriorStack,
) -> Option<(&'a Medium, &'a Object)> {
    let top = stack.top(&scene.objects, None)?;
    let obj = &scene.objects[top as usize];
    obj.medium.map(|m| (&scene.media[m as usize], obj))
}

/// Builds the boundary BSDF of `obj` for the media meeting there.
pub(super) fn boundary_surface(obj: &Object, outside_ior: f32) -> Option<Surface> {
    match &obj.surface {
        ObjectSurface::Fixed(s) => Some(s.clone()),
        ObjectSurface::Null => None,
        ObjectSurface::Dielectric(d) => {
            let eta = d.ior / outside_ior.max(1e-6);
            let s = Surface::dielectric(eta, d.roughness, d.distribution, d.tint).ok()?;
            match d.coat {
                Some((ior, r, w)) => s.with_coat(ior, r, w).ok(),
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
