//! Spherical shells about the analytic spheres' centres that no triangle comes near, so that a
//! ray segment lying inside one is known to hit no triangle without traversing the BVH.
//!
//! Nested analytic spheres inside a mesh (the eye: sclera, uvea and anterior chamber inside the
//! globe's mesh) make most closest-hit queries end on a sphere, and the segment up to that hit
//! still paid a traversal from the root that found nothing (the node boxes of a closed mesh
//! overlap its inside). Here, for each centre, the radial intervals the triangles occupy are
//! recorded; the gaps between them, narrowed by a margin, are shells no triangle touches. A
//! segment whose distances from the centre (largest at an end point, smallest at the foot of
//! the perpendicular, clamped to the segment) lie in one gap cannot reach a triangle, so the
//! traversal would report no hit either: the answer is the same and images are bit-identical.
//! The margin (2⁻¹⁰ of the largest distance of a triangle from the centre) and the query's own
//! slack (16 ε of the distances involved) exceed the rounding of these distances and of the
//! triangle test by orders of magnitude.

use crate::math::Vec3;

use super::closest::closest_on_triangle;

/// Centres kept at most (the first distinct sphere centres of the scene).
const MAX_CENTRES: usize = 4;

/// Gaps kept per centre at most (the innermost ones).
const MAX_GAPS: usize = 4;

/// The shells no triangle touches about one centre.
#[derive(Clone, Debug)]
struct Centre {
    c: Vec3,
    /// Open radial intervals `(lo, hi)` free of triangles, margin included; `hi` may be ∞.
    gaps: Vec<(f32, f32)>,
}

/// Triangle-free shells about a few centres ([`FreeShells::clear`]).
#[derive(Clone, Debug)]
pub(super) struct FreeShells {
    centres: Vec<Centre>,
}

impl FreeShells {
    /// The shells about each distinct point of `centres` (the first [`MAX_CENTRES`]) left
    /// free by `triangles` (their three corners). `None` without centres or triangles.
    pub(super) fn build(centres: &[Vec3], triangles: &[[Vec3; 3]]) -> Option<FreeShells> {
        if triangles.is_empty() {
            return None;
        }
        let mut distinct: Vec<Vec3> = Vec::new();
        for c in centres {
            if c.is_finite() && !distinct.contains(c) && distinct.len() < MAX_CENTRES {
                distinct.push(*c);
            }
        }
        let centres: Vec<Centre> = distinct
            .into_iter()
            .filter_map(|c| Centre::build(c, triangles))
            .collect();
        (!centres.is_empty()).then_some(FreeShells { centres })
    }

    /// True when the segment `(0, t_end)` of the ray from `o` along unit `d` lies in a shell
    /// about any centre that no triangle touches: no triangle can be hit along it. False when
    /// unsure (an infinite or non-finite end, a segment crossing occupied radii).
    #[cfg(test)]
    pub(super) fn clear(&self, o: Vec3, d: Vec3, t_end: f32) -> bool {
        self.centres.iter().any(|c| c.clear(o, d, t_end))
    }

    /// [`FreeShells::clear`] about `center` alone (false when it is not one of the centres):
    /// a closest-hit query whose nearest hit so far is on a sphere asks about that sphere's
    /// centre only.
    #[inline]
    pub(super) fn clear_about(&self, center: Vec3, o: Vec3, d: Vec3, t_end: f32) -> bool {
        self.centres
            .iter()
            .find(|c| c.c == center)
            .is_some_and(|c| c.clear(o, d, t_end))
    }
}

impl Centre {
    fn build(c: Vec3, triangles: &[[Vec3; 3]]) -> Option<Centre> {
        let mut spans: Vec<(f32, f32)> = Vec::with_capacity(triangles.len());
        for &[a, b, t] in triangles {
            let far = (a - c).length().max((b - c).length()).max((t - c).length());
            let (p, _) = closest_on_triangle(c, a, b, t);
            // The nearest point, or a corner if the nearest point is not a number (the
            // margin below covers its rounding).
            let near = [
                (p - c).length(),
                (a - c).length(),
                (b - c).length(),
                (t - c).length(),
            ]
            .into_iter()
            .fold(f32::INFINITY, f32::min);
            if !(far.is_finite() && near.is_finite()) {
                return None;
            }
            spans.push((near, far));
        }
        spans.sort_by(|x, y| x.0.total_cmp(&y.0));
        let outer = spans.iter().map(|s| s.1).fold(0.0, f32::max);
        let margin = outer * (1.0 / 1024.0);
        // Gaps between the merged occupied intervals, each narrowed by the margin.
        let mut gaps = Vec::new();
        let mut reach = 0.0f32;
        let mut first = true;
        for &(near, far) in &spans {
            if near > reach || first {
                let lo = if first {
                    f32::NEG_INFINITY
                } else {
                    reach + margin
                };
                let hi = near - margin;
                if lo < hi && hi > 0.0 {
                    gaps.push((lo, hi));
                }
                first = false;
            }
            reach = reach.max(far);
        }
        gaps.push((reach + margin, f32::INFINITY));
        gaps.truncate(MAX_GAPS);
        Some(Centre { c, gaps })
    }

    #[inline]
    fn clear(&self, o: Vec3, d: Vec3, t_end: f32) -> bool {
        if !(t_end.is_finite() && t_end > 0.0) {
            return false;
        }
        let f = o - self.c;
        let s = (-f.dot(d)).clamp(0.0, t_end);
        let start = f.length();
        let end = (f + d * t_end).length();
        let nearest = (f + d * s).length();
        let farthest = start.max(end);
        // The rounding of these distances: a few ulps of the largest coordinates involved.
        let slack = 16.0 * f32::EPSILON * (start + t_end);
        self.gaps
            .iter()
            .any(|&(lo, hi)| nearest - slack > lo && farthest + slack < hi)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{icosphere, intersect_triangle};
    use crate::math::Ray;
    use crate::sampling::{sample_uniform_sphere, Rng};

    /// Two concentric meshed spheres (radii 1 and 0.5) and a small mesh off-centre: the shells
    /// found are (−∞, ~0.5), (~0.5, ~1) less the small mesh's radii, and beyond; every segment
    /// called clear hits no triangle (brute force), and segments inside the gaps are called
    /// clear while segments reaching a mesh are not.
    #[test]
    fn clear_segments_hit_no_triangle_and_gaps_are_found() {
        let mut tris = Vec::new();
        for (r, off) in [
            (1.0, Vec3::ZERO),
            (0.5, Vec3::ZERO),
            (0.05, Vec3::new(0.0, 0.0, 0.75)),
        ] {
            let m = icosphere(3);
            for t in &m.indices {
                tris.push(t.map(|i| m.positions[i as usize] * r + off));
            }
        }
        let shells = FreeShells::build(&[Vec3::ZERO, Vec3::ZERO], &tris).expect("triangles");
        assert_eq!(shells.centres.len(), 1);
        let gaps = &shells.centres[0].gaps;
        // Inside the inner sphere; between the inner sphere and the small mesh; between the
        // small mesh and the outer sphere; outside.
        assert_eq!(gaps.len(), 4, "{gaps:?}");
        assert!(gaps[1].0 > 0.5 && gaps[1].1 < 0.7 && gaps[2].0 > 0.8 && gaps[2].1 < 1.0);
        let mut rng = Rng::new(5, 3);
        let (mut clear, mut blocked) = (0, 0);
        for n in 0..20_000 {
            let r = match n % 3 {
                0 => 0.4 * rng.next_f32(),
                1 => 0.55 + 0.4 * rng.next_f32(),
                _ => 1.5 * rng.next_f32(),
            };
            let o = sample_uniform_sphere(rng.next_2d()) * r;
            let d = sample_uniform_sphere(rng.next_2d());
            let t_end = 0.02 + rng.next_f32() * if n % 2 == 0 { 0.1 } else { 1.0 };
            let ray = Ray::new(o, d);
            let hit = tris
                .iter()
                .any(|&[a, b, c]| intersect_triangle(&ray, a, b, c, t_end).is_some());
            if shells.clear(o, d, t_end) {
                assert!(
                    !hit,
                    "segment {n} called clear hits a triangle: {o} {d} {t_end}"
                );
                clear += 1;
            } else if hit {
                blocked += 1;
            }
            // Short segments well inside a gap are always called clear.
            let radius = o.length();
            let inner =
                (radius < 0.4 && t_end < 0.05) || (radius > 0.6 && radius < 0.64 && t_end < 0.03);
            if inner {
                assert!(shells.clear(o, d, t_end), "segment {n}: {o} {d} {t_end}");
            }
        }
        assert!(clear > 3_000 && blocked > 1_000, "{clear} {blocked}");
        assert!(!shells.clear(Vec3::ZERO, Vec3::X, f32::INFINITY));
    }
}
