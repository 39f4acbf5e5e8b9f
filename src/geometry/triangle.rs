//! Watertight ray–triangle intersection (Woop, Benthin & Wald 2013, "Watertight Ray/Triangle
//! Intersection", JCGT 2(1)) with exact tie-breaking on shared edges and vertices.

use crate::math::{Ray, Vec3};

/// Barycentric hit on one triangle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriangleHit {
    /// Distance along the ray (> 0).
    pub t: f32,
    /// Barycentric weight of the first vertex.
    pub b0: f32,
    /// Barycentric weight of the second vertex.
    pub b1: f32,
    /// Barycentric weight of the third vertex.
    pub b2: f32,
}

/// Per-ray constants of the watertight test: the dominant axis `kz`, the two others in an
/// order that keeps the winding, and the shear that maps the ray to `+z` from the origin.
#[derive(Clone, Copy, Debug)]
pub(crate) struct ShearedRay {
    o: Vec3,
    kx: usize,
    ky: usize,
    kz: usize,
    sx: f32,
    sy: f32,
    sz: f32,
}

impl ShearedRay {
    pub(crate) fn new(ray: &Ray) -> Self {
        let d = ray.d;
        let a = d.abs();
        let kz = if a.x >= a.y && a.x >= a.z {
            0
        } else if a.y >= a.z {
            1
        } else {
            2
        };
        let mut kx = (kz + 1) % 3;
        let mut ky = (kx + 1) % 3;
        if d[kz] < 0.0 {
            std::mem::swap(&mut kx, &mut ky);
        }
        ShearedRay {
            o: ray.o,
            kx,
            ky,
            kz,
            sx: d[kx] / d[kz],
            sy: d[ky] / d[kz],
            sz: 1.0 / d[kz],
        }
    }

    /// The watertight test. Edge functions are evaluated as `E(P,Q) = Qx·Py − Qy·Px` on
    /// sheared vertex coordinates that depend only on the vertex and the ray, so the two
    /// triangles sharing an edge see exactly negated values; exact zeros are re-evaluated in
    /// f64 (exact for products of f32) and then resolved by a symbolic perturbation of the
    /// ray origin by `(ε, ε²)`, which assigns a point on a shared edge or vertex to exactly
    /// one of the triangles around it.
    #[inline]
    pub(crate) fn intersect(
        &self,
        p0: Vec3,
        p1: Vec3,
        p2: Vec3,
        t_max: f32,
    ) -> Option<TriangleHit> {
        let (kx, ky, kz) = (self.kx, self.ky, self.kz);
        let a = p0 - self.o;
        let b = p1 - self.o;
        let c = p2 - self.o;
        let ax = a[kx] - self.sx * a[kz];
        let ay = a[ky] - self.sy * a[kz];
        let bx = b[kx] - self.sx * b[kz];
        let by = b[ky] - self.sy * b[kz];
        let cx = c[kx] - self.sx * c[kz];
        let cy = c[ky] - self.sy * c[kz];

        let mut u = cx * by - cy * bx; // E(B, C): weight of vertex 0
        let mut v = ax * cy - ay * cx; // E(C, A): weight of vertex 1
        let mut w = bx * ay - by * ax; // E(A, B): weight of vertex 2

        if u == 0.0 || v == 0.0 || w == 0.0 {
            let ud = f64::from(cx) * f64::from(by) - f64::from(cy) * f64::from(bx);
            let vd = f64::from(ax) * f64::from(cy) - f64::from(ay) * f64::from(cx);
            let wd = f64::from(bx) * f64::from(ay) - f64::from(by) * f64::from(ax);
            let s = if ud > 0.0 || vd > 0.0 || wd > 0.0 {
                1.0
            } else if ud < 0.0 || vd < 0.0 || wd < 0.0 {
                -1.0
            } else {
                return None; // the ray lies in the triangle's plane
            };
            if ud * s < 0.0 || vd * s < 0.0 || wd * s < 0.0 {
                return None;
            }
            // A zero edge function: the ray passes exactly through the edge's line. Decide by
            // the sign the edge function takes when the origin moves by (ε, ε²).
            let inside = |e: f64, px: f32, py: f32, qx: f32, qy: f32| -> bool {
                if e != 0.0 {
                    return true;
                }
                let dy = qy - py;
                let pert = if dy != 0.0 { dy } else { px - qx };
                pert != 0.0 && (f64::from(pert) * s) > 0.0
            };
            if !inside(ud, bx, by, cx, cy)
                || !inside(vd, cx, cy, ax, ay)
                || !inside(wd, ax, ay, bx, by)
            {
                return None;
            }
            u = ud as f32;
            v = vd as f32;
            w = wd as f32;
        } else if (u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0) {
            return None;
        }

        let det = u + v + w;
        if det == 0.0 || !det.is_finite() {
            return None;
        }
        let az = self.sz * a[kz];
        let bz = self.sz * b[kz];
        let cz = self.sz * c[kz];
        let tn = u * az + v * bz + w * cz;
        let inv = 1.0 / det;
        let t = tn * inv;
        if !(t > 0.0 && t < t_max) {
            return None;
        }
        Some(TriangleHit {
            t,
            b0: u * inv,
            b1: v * inv,
            b2: w * inv,
        })
    }
}

/// Intersects `ray` (unit direction) with the triangle `(p0, p1, p2)`, accepting hits with
/// `0 < t < t_max`, either facing. Watertight (Woop, Benthin & Wald 2013): a ray through an
/// edge or vertex shared by triangles of a mesh (bit-identical vertex positions) hits
/// exactly one of them where the surface is not folded over in the ray's view.
#[must_use]
pub fn intersect_triangle(
    ray: &Ray,
    p0: Vec3,
    p1: Vec3,
    p2: Vec3,
    t_max: f32,
) -> Option<TriangleHit> {
    if !ray.o.is_finite() || !ray.d.is_finite() || ray.d == Vec3::ZERO {
        return None;
    }
    ShearedRay::new(ray).intersect(p0, p1, p2, t_max)
}
