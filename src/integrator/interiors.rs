//! The interior stack (Schmidt & Budge 2002, "Simple Nested Dielectrics in Ray Traced
//! Images"): which objects a point is inside of, which one governs, and which boundary
//! crossings are false intersections that only update the stack.

use std::borrow::Cow;

use crate::bsdf::Surface;
use crate::math::Vec2;
use crate::medium::{Coefficients, Medium, WalkMedium};
use crate::scene::{DielectricParams, Object, ObjectSurface, Scene};
use crate::spectrum::Rgb;

/// The deepest nesting of interiors tracked; deeper entries are ignored.
pub const MAX_NESTING: usize = 16;

/// How many entered objects with per-walk interiors (textured, blended) keep their resolved
/// medium on the stack at once; a deeper one falls back to its stand-in medium.
pub const WALK_SLOTS: usize = 2;

/// The objects (by index) that a point is inside of, with their priorities, and the media
/// resolved at the entry points of the entered objects whose interiors are resolved per walk
/// (docs/textures.md). Packed to 124 bytes: it is copied for every shadow ray, and stays
/// within what the compiler copies inline.
#[derive(Clone, Copy, Debug)]
pub struct InteriorStack {
    entries: [u32; MAX_NESTING],
    len: u8,
    walk_len: u8,
    /// Per walk slot: 0 a scene medium (index in the first value's bits), 1 homogeneous look
    /// `a` (or an entry interior), 2 homogeneous look `b`, 3 absorbing, 4 field look `a` (or a
    /// textured voxel/fbm interior), 5 field look `b`, 6 textured mixture look `a` (or a
    /// textured mixture), 7 textured mixture look `b`, 8 fabric look `a` (or a textured
    /// fabric), 9 fabric look `b`.
    walk_kind: [u8; WALK_SLOTS],
    walk_obj: [u32; WALK_SLOTS],
    /// σ_a then σ_s (homogeneous), σ_a (absorbing), σ_t then σ_s per unit density (field),
    /// the entry point's u, v and footprint width (textured mixture, fabric).
    walk_data: [[f32; 6]; WALK_SLOTS],
}

impl Default for InteriorStack {
    fn default() -> Self {
        InteriorStack {
            entries: [0; MAX_NESTING],
            len: 0,
            walk_len: 0,
            walk_kind: [0; WALK_SLOTS],
            walk_obj: [u32::MAX; WALK_SLOTS],
            walk_data: [[0.0; 6]; WALK_SLOTS],
        }
    }
}

/// A walk medium as (kind, values) for the stack.
fn pack(m: WalkMedium) -> (u8, [f32; 6]) {
    match m {
        WalkMedium::Scene(i) => (0, [f32::from_bits(i), 0.0, 0.0, 0.0, 0.0, 0.0]),
        WalkMedium::Homogeneous { coefficients, look } => {
            let (a, s) = (coefficients.sigma_a.0, coefficients.sigma_s.0);
            (1 + look.min(1), [a[0], a[1], a[2], s[0], s[1], s[2]])
        }
        WalkMedium::Absorbing(sigma_a) => {
            let a = sigma_a.0;
            (3, [a[0], a[1], a[2], 0.0, 0.0, 0.0])
        }
        WalkMedium::Field {
            sigma_t,
            sigma_s,
            look,
        } => {
            let (t, s) = (sigma_t.0, sigma_s.0);
            (4 + look.min(1), [t[0], t[1], t[2], s[0], s[1], s[2]])
        }
        WalkMedium::EntryPoint { uv, width_uv, look } => {
            (6 + look.min(1), [uv.x, uv.y, width_uv, 0.0, 0.0, 0.0])
        }
        WalkMedium::Fabric { uv, width_uv, look } => {
            (8 + look.min(1), [uv.x, uv.y, width_uv, 0.0, 0.0, 0.0])
        }
    }
}

/// The inverse of [`pack`].
fn unpack(kind: u8, d: [f32; 6]) -> WalkMedium {
    match kind {
        0 => WalkMedium::Scene(d[0].to_bits()),
        1 | 2 => WalkMedium::Homogeneous {
            coefficients: Coefficients {
                sigma_a: Rgb([d[0], d[1], d[2]]),
                sigma_s: Rgb([d[3], d[4], d[5]]),
            },
            look: kind - 1,
        },
        4 | 5 => WalkMedium::Field {
            sigma_t: Rgb([d[0], d[1], d[2]]),
            sigma_s: Rgb([d[3], d[4], d[5]]),
            look: kind - 4,
        },
        6 | 7 => WalkMedium::EntryPoint {
            uv: Vec2::new(d[0], d[1]),
            width_uv: d[2],
            look: kind - 6,
        },
        8 | 9 => WalkMedium::Fabric {
            uv: Vec2::new(d[0], d[1]),
            width_uv: d[2],
            look: kind - 8,
        },
        _ => WalkMedium::Absorbing(Rgb([d[0], d[1], d[2]])),
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
        &self.entries[..usize::from(self.len)]
    }

    /// True if `obj` is on the stack.
    #[inline]
    #[must_use]
    pub fn contains(&self, obj: u32) -> bool {
        self.entries().contains(&obj)
    }

    /// Enters `obj`.
    #[inline]
    pub fn push(&mut self, obj: u32) {
        let len = usize::from(self.len);
        if len < MAX_NESTING && !self.contains(obj) {
            self.entries[len] = obj;
            self.len += 1;
        }
    }

    /// Enters `obj` with the medium resolved at its entry point for this walk.
    pub fn push_walk(&mut self, obj: u32, medium: WalkMedium) {
        if self.contains(obj) {
            return;
        }
        self.push(obj);
        let slot = usize::from(self.walk_len);
        if slot < WALK_SLOTS && self.contains(obj) {
            let (kind, data) = pack(medium);
            self.walk_kind[slot] = kind;
            self.walk_obj[slot] = obj;
            self.walk_data[slot] = data;
            self.walk_len += 1;
        }
    }

    /// The medium resolved for `obj` when it was entered, if any.
    #[inline]
    #[must_use]
    pub fn walk_medium(&self, obj: u32) -> Option<WalkMedium> {
        let n = usize::from(self.walk_len);
        let i = self.walk_obj[..n].iter().position(|&o| o == obj)?;
        Some(unpack(self.walk_kind[i], self.walk_data[i]))
    }

    /// Leaves `obj` (no-op if not entered).
    #[inline]
    pub fn remove(&mut self, obj: u32) {
        // The most recently entered object, with no walk medium riding on the stack: the
        // last entry goes (entries are distinct, `push` skips an object already entered, so
        // the search below would find this one and move nothing after it).
        if self.walk_len == 0 && self.entries().last() == Some(&obj) {
            self.len -= 1;
            return;
        }
        self.remove_searched(obj);
    }

    /// [`InteriorStack::remove`] by a search of the entries and the walk slots.
    #[inline(never)]
    fn remove_searched(&mut self, obj: u32) {
        if let Some(i) = self.entries().iter().position(|&o| o == obj) {
            self.entries.copy_within(i + 1..usize::from(self.len), i);
            self.len -= 1;
        }
        if self.walk_len > 0 {
            let n = usize::from(self.walk_len);
            if let Some(i) = self.walk_obj[..n].iter().position(|&o| o == obj) {
                self.walk_obj.copy_within(i + 1..n, i);
                self.walk_kind.copy_within(i + 1..n, i);
                self.walk_data.copy_within(i + 1..n, i);
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
/// when the path entered it (a medium of the scene, or one made for this walk in `scratch`).
#[inline]
pub(super) fn current_medium<'a>(
    scene: &'a Scene,
    stack: &InteriorStack,
    scratch: &'a mut Option<Medium>,
) -> Option<(&'a Medium, &'a Object)> {
    let top = stack.top(&scene.objects, None)?;
    let obj = &scene.objects[top as usize];
    if obj.walk.is_some() {
        return walk_medium(scene, stack, top, obj, scratch);
    }
    obj.medium.map(|m| (&scene.media[m as usize], obj))
}

/// [`current_medium`] where the medium is one of the scene's own (an object whose interior is
/// not resolved per walk): borrowed for the scene's lifetime. `None` in vacuum and for
/// interiors resolved per walk (ask [`current_medium`]).
#[inline]
pub(super) fn scene_medium<'a>(
    scene: &'a Scene,
    stack: &InteriorStack,
) -> Option<(&'a Medium, &'a Object)> {
    let top = stack.top(&scene.objects, None)?;
    let obj = &scene.objects[top as usize];
    if obj.walk.is_some() {
        return None;
    }
    obj.medium.map(|m| (&scene.media[m as usize], obj))
}

/// [`current_medium`] for an object whose interior is resolved per walk (kept out of line:
/// untextured scenes never get here).
#[cold]
#[inline(never)]
fn walk_medium<'a>(
    scene: &'a Scene,
    stack: &InteriorStack,
    top: u32,
    obj: &'a Object,
    scratch: &'a mut Option<Medium>,
) -> Option<(&'a Medium, &'a Object)> {
    let (Some(walk), Some(w)) = (obj.walk.as_deref(), stack.walk_medium(top)) else {
        return obj.medium.map(|m| (&scene.media[m as usize], obj));
    };
    let m = match w {
        WalkMedium::Scene(i) => scene.media.get(i as usize)?,
        own => &*scratch.insert(walk.medium_of(own)?),
    };
    Some((m, obj))
}

/// Enters object `oi` at texture coordinates `uv` (footprint `width_uv` wide): an object
/// whose interior is resolved per walk resolves it here (`u()` gives a blend's random number,
/// drawn only for blends).
#[inline]
pub(super) fn enter(
    scene: &Scene,
    stack: &mut InteriorStack,
    oi: u32,
    uv: Vec2,
    width_uv: f32,
    u: impl FnMut() -> f32,
) {
    match scene.objects.get(oi as usize) {
        Some(o) if o.walk.is_some() => enter_walk(o, stack, oi, uv, width_uv, u),
        _ => stack.push(oi),
    }
}

/// [`enter`] for an object whose interior is resolved per walk.
#[cold]
#[inline(never)]
fn enter_walk(
    obj: &Object,
    stack: &mut InteriorStack,
    oi: u32,
    uv: Vec2,
    width_uv: f32,
    mut u: impl FnMut() -> f32,
) {
    match obj.walk.as_deref() {
        Some(w) => {
            let r = if w.is_random() { u() } else { 0.0 };
            stack.push_walk(oi, w.resolve(uv, width_uv, r));
        }
        None => stack.push(oi),
    }
}

/// The boundary BSDF of `obj` for the media meeting there, its textured parameters read at
/// texture coordinates `uv` with a footprint `width_uv` wide; `u_mask` picks a blend's surface
/// ([`ObjectSurface::pick`]). Borrowed where the surface is fixed for the object (a fixed
/// surface, or an untextured dielectric seen from air, built when the scene was loaded),
/// built here otherwise.
#[inline]
pub(super) fn boundary_surface_at(
    obj: &Object,
    outside_ior: f32,
    uv: Vec2,
    width_uv: f32,
    u_mask: f32,
) -> Option<Cow<'_, Surface>> {
    match obj.surface.pick(uv, width_uv, u_mask) {
        ObjectSurface::Dielectric(d) => match &d.in_air {
            Some(s) if outside_ior == 1.0 => Some(Cow::Borrowed(s)),
            _ => built_dielectric(d, outside_ior, uv, width_uv).map(Cow::Owned),
        },
        ObjectSurface::Fixed(s) => Some(Cow::Borrowed(s)),
        ObjectSurface::Textured(t) => t.at(uv, width_uv).map(Cow::Owned),
        ObjectSurface::Blend(_) | ObjectSurface::Null => None,
    }
}

/// The dielectric boundary `d` built for an outside of IOR `outside_ior`, its textured
/// parameters read at `uv` (footprint `width_uv`).
fn built_dielectric(
    d: &DielectricParams,
    outside_ior: f32,
    uv: Vec2,
    width_uv: f32,
) -> Option<Surface> {
    let eta = d.ior / outside_ior.max(1e-6);
    let s = Surface::dielectric(
        eta,
        d.roughness.eval(uv, width_uv),
        d.distribution,
        d.tint.eval(uv, width_uv),
    )
    .and_then(|s| s.with_reflect_floor(d.min_reflect_probability))
    .ok()?;
    match &d.coat {
        Some(c) => c.over(s, uv, width_uv),
        None => Some(s),
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

/// Untextured dielectrics of every kind the loader builds: smooth, rough, index-matched, tinted,
/// with a reflection floor, Beckmann, coated (rough and smooth coats over smooth and rough
/// bases), a blend of two, and a diffuse boundary beside them.
#[cfg(test)]
pub(super) const DIELECTRICS: &str = r#"
[camera]
eye = [0.0, 0.0, 5.0]
look_at = [0.0, 0.0, 0.0]
fov = 40
[film]
width = 8
height = 8
spp = 1
[[light]]
type = "environment"
radiance = 0.5
[[object]]
name = "smooth"
shape = "sphere"
center = [-2.0, 0.0, 0.0]
radius = 0.3
surface = { type = "dielectric", ior = 1.5 }
[[object]]
name = "skin"
shape = "sphere"
center = [-1.0, 0.0, 0.0]
radius = 0.3
surface = { type = "dielectric", ior = 1.4, roughness = 0.5477225575051661 }
interior = { type = "homogeneous", albedo = 0.9, attenuation = 2.0 }
[[object]]
name = "matched"
shape = "sphere"
center = [0.0, 0.0, 0.0]
radius = 0.3
surface = { type = "dielectric", ior = 1.0, roughness = 0.4 }
[[object]]
name = "tinted"
shape = "sphere"
center = [1.0, 0.0, 0.0]
radius = 0.3
surface = { type = "dielectric", ior = 1.33, roughness = 0.2, tint = [0.9, 0.5, 0.25], min_reflect_probability = 0.4, distribution = "beckmann" }
[[object]]
name = "coated"
shape = "sphere"
center = [2.0, 0.0, 0.0]
radius = 0.3
surface = { type = "dielectric", ior = 1.6, roughness = 0.3, coat = { ior = 1.5, roughness = 0.2, weight = 0.7 } }
[[object]]
name = "clear coat"
shape = "sphere"
center = [0.0, 1.0, 0.0]
radius = 0.3
surface = { type = "dielectric", ior = 1.45, coat = { ior = 1.3, roughness = 0.25 } }
[[object]]
name = "blend"
shape = "sphere"
center = [0.0, -1.0, 0.0]
radius = 0.3
surface = { type = "blend", mask = 0.3, a = { type = "dielectric", ior = 1.5, roughness = 0.3 }, b = { type = "dielectric", ior = 1.5 } }
[[object]]
name = "diffuse"
shape = "sphere"
center = [0.0, 2.0, 0.0]
radius = 0.3
surface = { type = "lambertian", reflectance = 0.5 }
"#;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_surface_seen_from_air_is_the_one_a_hit_would_build() {
        let scene = crate::scene::load_scene_str(DIELECTRICS, std::path::Path::new("d.toml"))
            .expect("scene");
        let (mut borrowed, mut built) = (0, 0);
        for obj in &scene.objects {
            for u_mask in [0.0, 0.5, 0.99] {
                let ObjectSurface::Dielectric(d) = obj.surface.pick(Vec2::ZERO, 0.0, u_mask) else {
                    continue;
                };
                assert!(d.in_air.is_some(), "{}: untextured", obj.name);
                for outside_ior in [1.0, 1.33, 1.5, 0.999_999_9, 1.000_000_1] {
                    for uv in [Vec2::ZERO, Vec2::new(0.25, 0.75)] {
                        let got = boundary_surface_at(obj, outside_ior, uv, 0.0, u_mask);
                        let want = built_dielectric(d, outside_ior, uv, 0.0);
                        assert!(want.is_some(), "{}: builds", obj.name);
                        assert_eq!(
                            got.as_deref(),
                            want.as_ref(),
                            "{} from outside IOR {outside_ior}",
                            obj.name
                        );
                        match got {
                            Some(Cow::Borrowed(_)) => borrowed += 1,
                            _ => built += 1,
                        }
                        // Only a hit from air borrows the surface built at load.
                        assert_eq!(
                            matches!(
                                boundary_surface_at(obj, outside_ior, uv, 0.0, u_mask),
                                Some(Cow::Borrowed(_))
                            ),
                            outside_ior == 1.0
                        );
                    }
                }
            }
        }
        assert!(
            borrowed >= 20 && built >= 80,
            "{borrowed} borrowed, {built} built"
        );
    }

    #[test]
    fn the_stack_stays_small_enough_to_copy_inline() {
        assert!(std::mem::size_of::<InteriorStack>() <= 128);
    }

    #[test]
    fn walk_media_ride_on_the_stack_until_their_object_is_left() {
        let h = WalkMedium::Homogeneous {
            coefficients: Coefficients {
                sigma_a: Rgb([0.1, 0.2, 0.3]),
                sigma_s: Rgb([4.0, 5.0, 6.0]),
            },
            look: 1,
        };
        let mut s = InteriorStack::new();
        s.push(3);
        s.push_walk(7, h);
        s.push_walk(9, WalkMedium::Scene(12));
        s.push_walk(11, WalkMedium::Absorbing(Rgb([1.0, 2.0, 3.0])));
        assert_eq!(s.walk_medium(7), Some(h));
        assert_eq!(s.walk_medium(9), Some(WalkMedium::Scene(12)));
        // A third per-walk object finds no slot: it falls back to its stand-in medium.
        assert_eq!(s.walk_medium(11), None);
        assert!(s.contains(11));
        s.remove(7);
        assert_eq!(s.walk_medium(7), None);
        assert_eq!(s.walk_medium(9), Some(WalkMedium::Scene(12)));
        assert_eq!(s.entries(), &[3, 9, 11]);
        s.push_walk(7, WalkMedium::Absorbing(Rgb([1.0, 2.0, 3.0])));
        assert_eq!(
            s.walk_medium(7),
            Some(WalkMedium::Absorbing(Rgb([1.0, 2.0, 3.0])))
        );
    }

    #[test]
    fn removing_an_object_matches_the_searched_removal() {
        let mut rng = crate::sampling::Rng::new(17, 3);
        let mut fast_taken = 0;
        for _ in 0..20_000 {
            let mut s = InteriorStack::new();
            for _ in 0..(rng.next_u32() % 6) {
                let o = rng.next_u32() % 8;
                if rng.next_u32().is_multiple_of(4) {
                    s.push_walk(o, WalkMedium::Scene(o + 100));
                } else {
                    s.push(o);
                }
            }
            let obj = rng.next_u32() % 8;
            let (mut fast, mut searched) = (s, s);
            fast.remove(obj);
            searched.remove_searched(obj);
            assert_eq!(
                fast.entries(),
                searched.entries(),
                "{:?} less {obj}",
                s.entries()
            );
            for o in 0..8 {
                assert_eq!(fast.walk_medium(o), searched.walk_medium(o));
            }
            if s.walk_len == 0 && s.entries().last() == Some(&obj) {
                fast_taken += 1;
            }
        }
        assert!(fast_taken > 1000, "{fast_taken}");
    }

    #[test]
    fn field_walk_media_keep_their_coefficients_and_look() {
        let mut s = InteriorStack::new();
        for look in [0, 1] {
            let f = WalkMedium::Field {
                sigma_t: Rgb([1.5, 2.5, 3.5]),
                sigma_s: Rgb([1.0, 2.0, 3.0]),
                look,
            };
            s.push_walk(5, f);
            assert_eq!(s.walk_medium(5), Some(f));
            s.remove(5);
        }
    }

    #[test]
    fn textured_mixture_entry_points_ride_on_the_stack() {
        let mut s = InteriorStack::new();
        for look in [0, 1] {
            let e = WalkMedium::EntryPoint {
                uv: Vec2::new(0.25, 0.75),
                width_uv: 0.01,
                look,
            };
            s.push_walk(4, e);
            assert_eq!(s.walk_medium(4), Some(e));
            s.remove(4);
        }
    }
}
