//! Small geometric helpers shared by every layer: rays, orthonormal frames,
//! robust ray-origin offsets and numerically careful scalar functions.

pub use glam::{Mat3, Mat4, Vec2, Vec3};

/// π as `f32`.
pub const PI: f32 = std::f32::consts::PI;
/// 1/π.
pub const INV_PI: f32 = std::f32::consts::FRAC_1_PI;
/// 1/(4π).
pub const INV_4PI: f32 = 0.25 * std::f32::consts::FRAC_1_PI;

/// True when the CPU runs AVX2 and the environment variable `VELOUR_NO_AVX2` is not set. The
/// code paths that use AVX2 (the BVH's 8-wide node test, the fibre phase function's batched
/// azimuthal sums) give the same results as their baseline forms; the variable forces the
/// baseline, for A/B measurements in one binary. Reads the environment: call it once per
/// structure built, not per evaluation.
#[must_use]
pub fn avx2_enabled() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::is_x86_feature_detected!("avx2") && std::env::var_os("VELOUR_NO_AVX2").is_none()
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// A ray `o + t d`. `d` is always unit length so that `t` is a world distance
/// (media coefficients are per unit world length; docs/references.md §0).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    /// Origin (world space).
    pub o: Vec3,
    /// Unit direction.
    pub d: Vec3,
}

impl Ray {
    /// Builds a ray; `d` must already be normalised.
    #[must_use]
    pub fn new(o: Vec3, d: Vec3) -> Self {
        Ray { o, d }
    }
    /// The point at distance `t`.
    #[must_use]
    pub fn at(&self, t: f32) -> Vec3 {
        self.o + self.d * t
    }
}

/// An orthonormal frame `(s, t, n)`; local `z` is `n`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    /// First tangent.
    pub s: Vec3,
    /// Second tangent.
    pub t: Vec3,
    /// Normal (local +z).
    pub n: Vec3,
}

impl Frame {
    /// Builds a frame around unit `n` with the branchless construction of
    /// Duff et al. 2017, "Building an Orthonormal Basis, Revisited" (JCGT 6(1)).
    #[must_use]
    pub fn from_normal(n: Vec3) -> Self {
        let sign = 1.0f32.copysign(n.z);
        let a = -1.0 / (sign + n.z);
        let b = n.x * n.y * a;
        let s = Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
        let t = Vec3::new(b, sign + n.y * n.y * a, -n.y);
        Frame { s, t, n }
    }
    /// World to local coordinates.
    #[must_use]
    pub fn to_local(&self, v: Vec3) -> Vec3 {
        Vec3::new(v.dot(self.s), v.dot(self.t), v.dot(self.n))
    }
    /// Local to world coordinates.
    #[must_use]
    pub fn to_world(&self, v: Vec3) -> Vec3 {
        self.s * v.x + self.t * v.y + self.n * v.z
    }
}

/// Moves a surface point off the surface along the geometric normal `ng`, to the side
/// `dir` points to, by a few ULPs of the coordinates (Wächter & Binder 2019, "A Fast and
/// Robust Method for Avoiding Self-Intersection", Ray Tracing Gems ch. 6). Spawned rays then
/// start with `t_min = 0` and can neither re-hit the surface they left nor skip a nearby one.
#[must_use]
pub fn offset_ray_origin(p: Vec3, ng: Vec3, dir: Vec3) -> Vec3 {
    // Below |p| = 2^-14 the integer offset (256 ULPs) becomes too small to matter, so a fixed
    // offset takes over; both are scaled down from Wächter & Binder's (1/32, 1/65536) so that
    // millimetre-scale scenes are not biased (a fixed 1.5e-5 offset shortens media chords).
    const ORIGIN: f32 = 1.0 / 16384.0;
    const FLOAT_SCALE: f32 = 1.0 / 16_777_216.0;
    const INT_SCALE: f32 = 256.0;
    let n = if ng.dot(dir) < 0.0 { -ng } else { ng };
    let of_i = [
        (INT_SCALE * n.x) as i32,
        (INT_SCALE * n.y) as i32,
        (INT_SCALE * n.z) as i32,
    ];
    let pa = p.to_array();
    let na = n.to_array();
    let mut out = [0.0f32; 3];
    for k in 0..3 {
        let bits = pa[k].to_bits() as i32;
        let shifted = if pa[k] < 0.0 {
            bits.wrapping_sub(of_i[k])
        } else {
            bits.wrapping_add(of_i[k])
        };
        let p_i = f32::from_bits(shifted as u32);
        out[k] = if pa[k].abs() < ORIGIN {
            pa[k] + FLOAT_SCALE * na[k]
        } else {
            p_i
        };
    }
    Vec3::from_array(out)
}

/// `sqrt(max(x, 0))`.
#[must_use]
pub fn safe_sqrt(x: f32) -> f32 {
    x.max(0.0).sqrt()
}

/// `acos` of a clamped argument.
#[must_use]
pub fn safe_acos(x: f32) -> f32 {
    x.clamp(-1.0, 1.0).acos()
}

/// `asin` of a clamped argument.
#[must_use]
pub fn safe_asin(x: f32) -> f32 {
    x.clamp(-1.0, 1.0).asin()
}

/// Mirror reflection of `wo` (pointing away) about `n`.
#[must_use]
pub fn reflect(wo: Vec3, n: Vec3) -> Vec3 {
    -wo + n * (2.0 * wo.dot(n))
}

/// Refraction of `wi` (pointing away from the surface on the side `n` points to) through a
/// boundary with relative index `eta = η_transmitted / η_incident`. Returns `None` on total
/// internal reflection.
#[must_use]
pub fn refract(wi: Vec3, n: Vec3, eta: f32) -> Option<Vec3> {
    let cos_i = wi.dot(n);
    let sin2_i = (1.0 - cos_i * cos_i).max(0.0);
    let sin2_t = sin2_i / (eta * eta);
    if sin2_t >= 1.0 {
        return None;
    }
    let cos_t = safe_sqrt(1.0 - sin2_t);
    Some(-wi / eta + n * (cos_i / eta - cos_t))
}

/// An axis-aligned bounding box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    /// Smallest corner.
    pub min: Vec3,
    /// Largest corner.
    pub max: Vec3,
}

impl Aabb {
    /// The world box around the box `[lo, hi]` mapped by the affine `m` (its eight corners).
    #[must_use]
    pub fn around_transformed(lo: glam::DVec3, hi: glam::DVec3, m: &glam::DAffine3) -> Aabb {
        let mut out = Aabb::EMPTY;
        for i in 0..8 {
            let p = glam::DVec3::new(
                if i & 1 != 0 { hi.x } else { lo.x },
                if i & 2 != 0 { hi.y } else { lo.y },
                if i & 4 != 0 { hi.z } else { lo.z },
            );
            out = out.union_point(m.transform_point3(p).as_vec3());
        }
        out
    }

    /// The empty box (min = +∞, max = −∞).
    pub const EMPTY: Aabb = Aabb {
        min: Vec3::splat(f32::INFINITY),
        max: Vec3::splat(f32::NEG_INFINITY),
    };
    /// Grows the box to contain `p`.
    #[must_use]
    pub fn union_point(self, p: Vec3) -> Aabb {
        Aabb {
            min: self.min.min(p),
            max: self.max.max(p),
        }
    }
    /// Smallest box containing both.
    #[must_use]
    pub fn union(self, o: Aabb) -> Aabb {
        Aabb {
            min: self.min.min(o.min),
            max: self.max.max(o.max),
        }
    }
    /// True when `min <= max` on every axis.
    #[must_use]
    pub fn is_valid(&self) -> bool {
        self.min.cmple(self.max).all()
    }
    /// Centre point.
    #[must_use]
    pub fn center(&self) -> Vec3 {
        (self.min + self.max) * 0.5
    }
    /// Diagonal vector.
    #[must_use]
    pub fn extent(&self) -> Vec3 {
        self.max - self.min
    }
    /// Slab test: the parametric interval `[t0, t1]` of `ray` inside the box, clipped to
    /// `[t_min, t_max]`, or `None` when the ray misses.
    #[must_use]
    pub fn intersect(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<(f32, f32)> {
        let mut t0 = t_min;
        let mut t1 = t_max;
        for k in 0..3 {
            let inv = 1.0 / ray.d[k];
            let mut a = (self.min[k] - ray.o[k]) * inv;
            let mut b = (self.max[k] - ray.o[k]) * inv;
            if a > b {
                std::mem::swap(&mut a, &mut b);
            }
            // NaN from 0 * inf (origin on a slab plane, axis-parallel ray) keeps the old bound.
            if a > t0 {
                t0 = a;
            }
            if b < t1 {
                t1 = b * (1.0 + 2.0 * gamma(3));
            }
            if t0 > t1 {
                return None;
            }
        }
        Some((t0, t1))
    }
}

/// Conservative rounding-error bound γ_n = nε/(1 − nε) (pbrt-v4 §6.8).
#[must_use]
pub fn gamma(n: i32) -> f32 {
    let e = f32::EPSILON * 0.5;
    (n as f32 * e) / (1.0 - n as f32 * e)
}
