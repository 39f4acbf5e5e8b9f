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

/// The table of glibc's single-precision `exp` (`__exp2f_data.tab`, glibc 2.27 and later):
/// entry `i` is the bit pattern of 2^(i/32) with `i << 47` subtracted, so that adding
/// `k << 47` to entry `k mod 32` gives 2^(k/32) for any integer `k`.
#[cfg(target_feature = "fma")]
const EXPF_TABLE: [u64; 32] = [
    0x3ff0000000000000,
    0x3fefd9b0d3158574,
    0x3fefb5586cf9890f,
    0x3fef9301d0125b51,
    0x3fef72b83c7d517b,
    0x3fef54873168b9aa,
    0x3fef387a6e756238,
    0x3fef1e9df51fdee1,
    0x3fef06fe0a31b715,
    0x3feef1a7373aa9cb,
    0x3feedea64c123422,
    0x3feece086061892d,
    0x3feebfdad5362a27,
    0x3feeb42b569d4f82,
    0x3feeab07dd485429,
    0x3feea47eb03a5585,
    0x3feea09e667f3bcd,
    0x3fee9f75e8ec5f74,
    0x3feea11473eb0187,
    0x3feea589994cce13,
    0x3feeace5422aa0db,
    0x3feeb737b0cdc5e5,
    0x3feec49182a3f090,
    0x3feed503b23e255d,
    0x3feee89f995ad3ad,
    0x3feeff76f2fb5e47,
    0x3fef199bdd85529c,
    0x3fef3720dcef9069,
    0x3fef5818dcfba487,
    0x3fef7c97337b9b5f,
    0x3fefa4afa2a490da,
    0x3fefd0765b6e4540,
];
/// 32/ln 2 (`__exp2f_data.invln2_scaled`).
#[cfg(target_feature = "fma")]
const EXPF_INV_LN2_N: u64 = 0x40471547652b82fe;
/// 1.5 · 2^52: adding it rounds to an integer (`__exp2f_data.shift`).
#[cfg(target_feature = "fma")]
const EXPF_SHIFT: u64 = 0x4338000000000000;
/// The polynomial for 2^(r/32) − 1 ≈ (C0 r + C1) r² + C2 r (`__exp2f_data.poly_scaled`).
#[cfg(target_feature = "fma")]
const EXPF_POLY: [u64; 3] = [0x3ebc6af84b912394, 0x3f2ebfce50fac4f3, 0x3f962e42ff0c52d6];
/// Arguments whose biased exponent field (bits 20–30 of the `f32`) is above this (|x| ≥ 88,
/// infinities, NaN) take glibc's special-case path.
#[cfg(target_feature = "fma")]
const EXPF_LARGE_TOP: u32 = 0x42a;

/// `x.exp()` with the bits that glibc's `expf` gives on a CPU with FMA (its `__expf_fma`,
/// the variant the dynamic loader picks on every CPU velour runs on; glibc 2.27 and later,
/// after Szabolcs Nagy's implementation), computed inline: the same double-precision
/// operations in the same order with the same fused multiply–adds, the same table and
/// constants. For |x| ≥ 88 and non-finite `x` (glibc's special cases: overflow, underflow,
/// NaN) it calls `x.exp()` itself. Saves the call's and the caller's spills and lets
/// [`exp3`] compute three channels at once. Without FMA in the build it is `x.exp()`.
/// Checked bit for bit against the C library on every `f32` by the exhaustive test
/// (`cargo test --release --lib -- math::tests::exp_f32_has_the_c_librarys_bits_everywhere --ignored`).
#[must_use]
#[inline]
pub fn exp_f32(x: f32) -> f32 {
    #[cfg(target_feature = "fma")]
    {
        if (x.to_bits() >> 20) & 0x7ff > EXPF_LARGE_TOP {
            return x.exp();
        }
        let inv = f64::from_bits(EXPF_INV_LN2_N);
        let shift = f64::from_bits(EXPF_SHIFT);
        let xd = f64::from(x);
        // x·32/ln 2 = k + r with k an integer (rounded to nearest by the shift) and |r| ≤ 1/2.
        let z = inv.mul_add(xd, shift);
        let ki = z.to_bits();
        let kd = z - shift;
        let r = inv.mul_add(xd, -kd);
        let s = f64::from_bits(EXPF_TABLE[(ki % 32) as usize].wrapping_add(ki << 47));
        let [c0, c1, c2] = EXPF_POLY.map(f64::from_bits);
        let p = c0.mul_add(r, c1);
        let y = r.mul_add(c2, 1.0);
        let y = p.mul_add(r * r, y);
        (y * s) as f32
    }
    #[cfg(not(target_feature = "fma"))]
    {
        x.exp()
    }
}

/// [`exp_f32`] of three values (the same bits as three calls), in the four lanes of AVX2
/// registers when the build has AVX2 and FMA and no value is one of glibc's special cases.
#[must_use]
#[inline]
pub fn exp3(x: [f32; 3]) -> [f32; 3] {
    #[cfg(all(
        target_arch = "x86_64",
        target_feature = "avx2",
        target_feature = "fma"
    ))]
    {
        use std::arch::x86_64::{
            _mm256_add_epi64, _mm256_and_si256, _mm256_castpd_si256, _mm256_castsi256_pd,
            _mm256_cvtpd_ps, _mm256_cvtps_pd, _mm256_fmadd_pd, _mm256_fmsub_pd,
            _mm256_i64gather_epi64, _mm256_mul_pd, _mm256_set1_epi64x, _mm256_set1_pd,
            _mm256_slli_epi64, _mm256_sub_pd, _mm_and_si128, _mm_castps_si128, _mm_castsi128_ps,
            _mm_cmpgt_epi32, _mm_movemask_ps, _mm_set1_epi32, _mm_setr_ps, _mm_srli_epi32,
        };
        // SAFETY: the build enables AVX2 and FMA (the `cfg` above), the intrinsics' only
        // requirement but for the gather, whose indices are masked to 0..32, inside the
        // 32-entry table; `__m128` and `[f32; 4]` are both four `f32`s.
        unsafe {
            let xf = _mm_setr_ps(x[0], x[1], x[2], 0.0);
            let top = _mm_and_si128(
                _mm_srli_epi32::<20>(_mm_castps_si128(xf)),
                _mm_set1_epi32(0x7ff),
            );
            let large = _mm_cmpgt_epi32(top, _mm_set1_epi32(EXPF_LARGE_TOP as i32));
            if _mm_movemask_ps(_mm_castsi128_ps(large)) != 0 {
                return x.map(exp_f32);
            }
            let inv = _mm256_set1_pd(f64::from_bits(EXPF_INV_LN2_N));
            let shift = _mm256_set1_pd(f64::from_bits(EXPF_SHIFT));
            let xd = _mm256_cvtps_pd(xf);
            let z = _mm256_fmadd_pd(inv, xd, shift);
            let ki = _mm256_castpd_si256(z);
            let kd = _mm256_sub_pd(z, shift);
            let r = _mm256_fmsub_pd(inv, xd, kd);
            let index = _mm256_and_si256(ki, _mm256_set1_epi64x(31));
            // The gather reads EXPF_TABLE at indices masked to 0..32, inside the table.
            let entry = _mm256_i64gather_epi64::<8>(EXPF_TABLE.as_ptr().cast(), index);
            let s = _mm256_castsi256_pd(_mm256_add_epi64(entry, _mm256_slli_epi64::<47>(ki)));
            let [c0, c1, c2] = EXPF_POLY.map(|c| _mm256_set1_pd(f64::from_bits(c)));
            let p = _mm256_fmadd_pd(c0, r, c1);
            let y = _mm256_fmadd_pd(r, c2, _mm256_set1_pd(1.0));
            let y = _mm256_fmadd_pd(p, _mm256_mul_pd(r, r), y);
            let out: [f32; 4] = std::mem::transmute(_mm256_cvtpd_ps(_mm256_mul_pd(y, s)));
            [out[0], out[1], out[2]]
        }
    }
    #[cfg(not(all(
        target_arch = "x86_64",
        target_feature = "avx2",
        target_feature = "fma"
    )))]
    {
        x.map(exp_f32)
    }
}

/// The table of glibc's single-precision `log` (`__logf_data.tab`, glibc 2.27 and later):
/// `(1/c, ln c)` for the 16 subintervals c of [0x1.66p-1, 0x1.66p0) that the argument's
/// mantissa is reduced to.
#[cfg(target_feature = "fma")]
const LOGF_TABLE: [(u64, u64); 16] = [
    (0x3ff661ec79f8f3be, 0xbfd57bf7808caade),
    (0x3ff571ed4aaf883d, 0xbfd2bef0a7c06ddb),
    (0x3ff49539f0f010b0, 0xbfd01eae7f513a67),
    (0x3ff3c995b0b80385, 0xbfcb31d8a68224e9),
    (0x3ff30d190c8864a5, 0xbfc6574f0ac07758),
    (0x3ff25e227b0b8ea0, 0xbfc1aa2bc79c8100),
    (0x3ff1bb4a4a1a343f, 0xbfba4e76ce8c0e5e),
    (0x3ff12358f08ae5ba, 0xbfb1973c5a611ccc),
    (0x3ff0953f419900a7, 0xbfa252f438e10c1e),
    (0x3ff0000000000000, 0x0000000000000000),
    (0x3fee608cfd9a47ac, 0x3faaa5aa5df25984),
    (0x3feca4b31f026aa0, 0x3fbc5e53aa362eb4),
    (0x3feb2036576afce6, 0x3fc526e57720db08),
    (0x3fe9c2d163a1aa2d, 0x3fcbc2860d224770),
    (0x3fe886e6037841ed, 0x3fd1058bc8a07ee1),
    (0x3fe767dcf5534862, 0x3fd4043057b6ee09),
];
/// ln 2 (`__logf_data.ln2`).
#[cfg(target_feature = "fma")]
const LOGF_LN2: u64 = 0x3fe62e42fefa39ef;
/// The polynomial for ln(1 + r) − r ≈ A0 r⁴ + A1 r³ + A2 r² (`__logf_data.poly`).
#[cfg(target_feature = "fma")]
const LOGF_POLY: [u64; 3] = [0xbfd00ea348b88334, 0x3fd5575b0be00b6a, 0xbfdffffef20a4123];

/// `x.ln()` with the bits that glibc's `logf` gives on a CPU with FMA (its `__logf_fma`;
/// glibc 2.27 and later), computed inline as [`exp_f32`] is for `expf`: the same
/// operations, fused multiply–adds, table and constants. Zero, subnormal, negative and
/// non-finite `x` (glibc's special cases) call `x.ln()` itself. Without FMA in the build it
/// is `x.ln()`. Checked against the C library on every `f32` by the exhaustive test
/// (`cargo test --release --lib -- math::tests::ln_f32_has_the_c_librarys_bits_everywhere --ignored`).
#[must_use]
#[inline]
pub fn ln_f32(x: f32) -> f32 {
    #[cfg(target_feature = "fma")]
    {
        let ix = x.to_bits();
        if ix == 0x3f80_0000 {
            return 0.0;
        }
        if ix.wrapping_sub(0x0080_0000) >= 0x7f80_0000 - 0x0080_0000 {
            return x.ln();
        }
        // x = 2^k z with z in [0x1.66p-1, 0x1.66p0); c near z from the table, r = z/c − 1.
        let tmp = ix.wrapping_sub(0x3f33_0000);
        let (invc, logc) = LOGF_TABLE[((tmp >> 19) % 16) as usize];
        let (invc, logc) = (f64::from_bits(invc), f64::from_bits(logc));
        let k = (tmp as i32) >> 23;
        let z = f64::from(f32::from_bits(ix.wrapping_sub(tmp & 0xff80_0000)));
        let r = z.mul_add(invc, -1.0);
        let y0 = f64::from(k).mul_add(f64::from_bits(LOGF_LN2), logc);
        let [a0, a1, a2] = LOGF_POLY.map(f64::from_bits);
        let r2 = r * r;
        let y = r.mul_add(a1, a2);
        let y = r2.mul_add(a0, y);
        r2.mul_add(y, r + y0) as f32
    }
    #[cfg(not(target_feature = "fma"))]
    {
        x.ln()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Calls `check` on the bit patterns `start`, `start + step`, … up to `last` (stopping
    /// before the pattern would pass `u32::MAX`); returns how many it checked.
    fn for_patterns(start: u32, last: u32, step: u32, mut check: impl FnMut(u32)) -> u64 {
        let mut n = 0u64;
        let mut bits = start;
        loop {
            check(bits);
            n += 1;
            match bits.checked_add(step) {
                Some(b) if b <= last => bits = b,
                _ => return n,
            }
        }
    }

    /// `exp_f32` and `exp3` against the C library's `expf` for the bit patterns `start`,
    /// `start + step`, … up to `last`; returns how many were compared.
    fn compare_exp(start: u32, last: u32, step: u32) -> u64 {
        for_patterns(start, last, step, |bits| {
            let x = f32::from_bits(bits);
            let want = x.exp().to_bits();
            assert_eq!(exp_f32(x).to_bits(), want, "exp_f32({x:e}) ({bits:#010x})");
            let y = f32::from_bits(bits ^ 0x8000_0000);
            let w = f32::from_bits(bits.wrapping_add(1));
            let got = exp3([x, y, w]);
            assert_eq!(
                got.map(f32::to_bits),
                [x, y, w].map(|v| v.exp().to_bits()),
                "exp3 at {bits:#010x}"
            );
        })
    }

    #[test]
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    fn exp_f32_has_the_c_librarys_bits() {
        // A stride through every bit pattern (both signs, subnormals, the special cases).
        assert!(compare_exp(0, u32::MAX, 9_973) > 400_000);
        // Every pattern from |x| = 80 to 104 (glibc's special cases begin at 88), and every
        // third from −0.5 to −80 (the arguments −σ_t·d of the renderer's transmittances).
        compare_exp(0x42a0_0000, 0x42d0_0000, 1);
        compare_exp(0xc2a0_0000, 0xc2d0_0000, 1);
        // Around 32.56 (0x4202422e), where a multiply and subtract in place of the fused
        // multiply–subtract for r changes exp3's third lane (found by the exhaustive test).
        compare_exp(0x4202_4000, 0x4202_4400, 1);
        let mut n = 0;
        for bits in (0xbf00_0000u32..0xc2a0_0000).step_by(3) {
            let x = f32::from_bits(bits);
            assert_eq!(exp_f32(x).to_bits(), x.exp().to_bits(), "{bits:#010x}");
            n += 1;
        }
        assert!(n > 20_000_000);
        // exp3 falls back lane by lane when one value is special.
        let mixed = [-1.5f32, -200.0, f32::NAN];
        let got = exp3(mixed);
        assert_eq!(got[0].to_bits(), (-1.5f32).exp().to_bits());
        assert_eq!(got[1].to_bits(), (-200.0f32).exp().to_bits());
        assert!(got[2].is_nan());
    }

    #[test]
    #[ignore = "every f32: two to ten minutes in release"]
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    fn exp_f32_has_the_c_librarys_bits_everywhere() {
        assert_eq!(compare_exp(0, u32::MAX, 1), 1 << 32);
    }

    /// `ln_f32` against the C library's `logf` for the bit patterns `start`, `start + step`,
    /// … up to `last`; returns how many were compared.
    fn compare_ln(start: u32, last: u32, step: u32) -> u64 {
        for_patterns(start, last, step, |bits| {
            let x = f32::from_bits(bits);
            assert_eq!(
                ln_f32(x).to_bits(),
                x.ln().to_bits(),
                "ln_f32({x:e}) ({bits:#010x})"
            );
        })
    }

    #[test]
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    fn ln_f32_has_the_c_librarys_bits() {
        // A stride through every bit pattern (zeros, subnormals, negatives, ∞, NaN), then
        // every third pattern of [2^-24, 1]: the arguments 1 − u of the free flights.
        assert!(compare_ln(0, u32::MAX, 9_973) > 400_000);
        assert!(compare_ln(0x3380_0000, 0x3f80_0000, 3) > 60_000_000);
        for x in [
            0.0f32,
            -0.0,
            1.0,
            f32::MIN_POSITIVE,
            1e-40,
            f32::INFINITY,
            -1.0,
        ] {
            assert_eq!(ln_f32(x).to_bits(), x.ln().to_bits(), "{x:e}");
        }
        assert!(ln_f32(f32::NAN).is_nan());
    }

    #[test]
    #[ignore = "every f32: two to ten minutes in release"]
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    fn ln_f32_has_the_c_librarys_bits_everywhere() {
        assert_eq!(compare_ln(0, u32::MAX, 1), 1 << 32);
    }
}
