//! The first surface a ray meets, found together with a proof that nothing lies beyond it
//! (one traversal instead of two). A transparent shadow ray that leaves a closed mesh
//! otherwise searches the mesh twice: to the crossing, then from the crossing on to show
//! that the way to the light is clear. Keeping the two nearest triangle hits in one
//! traversal answers both: the traversal can prune only beyond the second-nearest hit, so
//! where there is none it visits every node the ray passes through once, where the two
//! searches visited the nodes around the crossing twice.

use super::{Best, BlockLane, SceneGeometry};
use crate::geometry::triangle::{ShearedRay, TriangleHit};
use crate::geometry::Hit;
use crate::math::Ray;

impl SceneGeometry {
    /// [`Self::intersect`] over `(0, t_max)`, and `true` when the ray provably meets no
    /// other surface on that interval (no triangle hit besides the returned one, counting a
    /// second hit at the same distance). `false` whenever that is not proven: a second hit
    /// exists, no hit at all, or the scene has analytic shapes or level sets (tested outside
    /// the triangle hierarchy; the answer is then [`Self::intersect`]'s alone). The returned
    /// hit is exactly [`Self::intersect`]'s, ties between equally near triangles included.
    #[must_use]
    #[inline]
    pub fn intersect_and_beyond(&self, ray: &Ray, t_max: f32) -> (Option<Hit>, bool) {
        let (hit, clear) = self.closest_and_beyond(ray, t_max);
        #[cfg(feature = "ray-log")]
        crate::geometry::ray_log::beyond(ray, t_max, hit.as_ref(), clear);
        (hit, clear)
    }

    /// [`Self::intersect_and_beyond`]'s search (the ray log's hook is in
    /// `intersect_and_beyond`).
    fn closest_and_beyond(&self, ray: &Ray, t_max: f32) -> (Option<Hit>, bool) {
        if !self.analytic.is_empty()
            || self.prims.is_empty()
            || !ray.o.is_finite()
            || !ray.d.is_finite()
            || ray.d == crate::math::Vec3::ZERO
            || t_max.is_nan()
            || t_max <= 0.0
            || self.segment_misses_triangles(ray, t_max)
        {
            return (self.closest(ray, t_max), false);
        }
        let sr = ShearedRay::new(ray);
        let mut first: Option<(usize, TriangleHit)> = None;
        // The distance of the second-nearest hit (∞ while there is none): hits beyond it
        // change neither answer, so the traversal prunes there.
        let mut second = f32::INFINITY;
        self.bvh.traverse(ray, t_max, |slot, bound| {
            if let Some(h) = sr.intersect(&self.triangle(slot as usize), bound) {
                match first {
                    // Not nearer than the first (a tie keeps the first found, as
                    // `intersect` does).
                    Some((_, f)) if !(h.t < f.t) => second = second.min(h.t),
                    Some((_, f)) => {
                        second = f.t;
                        first = Some((slot as usize, h));
                    }
                    None => first = Some((slot as usize, h)),
                }
            }
            second.min(t_max)
        });
        let clear = first.is_some() && second.is_infinite();
        (
            first.map(|(slot, h)| self.make_hit(ray, Best::Tri(slot, BlockLane::NONE, h))),
            clear,
        )
    }
}
