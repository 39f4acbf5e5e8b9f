//! One trilinear cell: corner values, the interpolant and its gradient, and the first zero
//! crossing of the interpolant along a ray segment (Marmitt, Kleer, Wald, Friedrich and
//! Slusallek 2004, "Fast and Accurate Ray-Voxel Intersection Techniques for Iso-Surface Ray
//! Tracing": the cubic along the ray, split at its extrema, then a bracketed refinement;
//! docs/references.md §12.5).

use glam::{IVec3, Vec3, Vec4};

use crate::grid::Accessor;

/// The values at the cell's corners, `c[(dx << 2) | (dy << 1) | dz]` at voxel `ijk + (dx, dy, dz)`.
#[inline]
pub(super) fn corner_values(acc: &mut Accessor<'_>, ijk: IVec3) -> [f32; 8] {
    acc.corners(ijk)
}

/// Whether any of the corner values is `<= 0` and whether any is `>= 0`: the cell's range
/// `[min, max]` straddles zero exactly when both hold, and lies below zero when the second
/// does not (NaN corners count in neither, as `f32::min`/`max` skip them). Four 4-wide
/// compares instead of a sixteen-step min/max fold.
#[inline]
pub(super) fn corner_signs(c: &[f32; 8]) -> (bool, bool) {
    let a = Vec4::new(c[0], c[1], c[2], c[3]);
    let b = Vec4::new(c[4], c[5], c[6], c[7]);
    let le = (a.cmple(Vec4::ZERO) | b.cmple(Vec4::ZERO)).any();
    let ge = (a.cmpge(Vec4::ZERO) | b.cmpge(Vec4::ZERO)).any();
    (le, ge)
}

/// The trilinear interpolant at local point `u` (`[0, 1]³` inside the cell; extrapolates
/// outside).
#[cfg(test)]
fn eval(c: &[f32; 8], u: Vec3) -> f32 {
    let lerp = |a: f32, b: f32, s: f32| a + (b - a) * s;
    let x00 = lerp(c[0], c[4], u.x);
    let x01 = lerp(c[1], c[5], u.x);
    let x10 = lerp(c[2], c[6], u.x);
    let x11 = lerp(c[3], c[7], u.x);
    lerp(lerp(x00, x10, u.y), lerp(x01, x11, u.y), u.z)
}

/// The gradient of the trilinear interpolant at local point `u` (index units).
#[inline]
pub(super) fn trilinear_gradient(c: &[f32; 8], u: Vec3) -> Vec3 {
    let w = |b: usize, s: f32| if b == 1 { s } else { 1.0 - s };
    let mut g = Vec3::ZERO;
    for j in 0..2usize {
        for k in 0..2usize {
            // Differences along x, weighted in y and z; likewise for y and z.
            g.x += (c[4 | (j << 1) | k] - c[(j << 1) | k]) * w(j, u.y) * w(k, u.z);
            g.y += (c[(j << 2) | 2 | k] - c[(j << 2) | k]) * w(j, u.x) * w(k, u.z);
            g.z += (c[(j << 2) | (k << 1) | 1] - c[(j << 2) | (k << 1)]) * w(j, u.x) * w(k, u.y);
        }
    }
    g
}

/// A continuous gradient: central differences at the 8 corners, blended trilinearly at `u`.
/// The 4³ voxels around the cell are read as eight 2³ blocks.
pub(super) fn smooth_gradient(acc: &mut Accessor<'_>, ijk: IVec3, u: Vec3) -> Vec3 {
    let mut v = [[[0.0f32; 4]; 4]; 4];
    for block in 0..8usize {
        let (bx, by, bz) = (block >> 2, (block >> 1) & 1, block & 1);
        let base = ijk - IVec3::ONE + 2 * IVec3::new(bx as i32, by as i32, bz as i32);
        let c = acc.corners(base);
        for (k, value) in c.iter().enumerate() {
            let (dx, dy, dz) = (k >> 2, (k >> 1) & 1, k & 1);
            v[2 * bx + dx][2 * by + dy][2 * bz + dz] = *value;
        }
    }
    let mut g = Vec3::ZERO;
    for k in 0..8usize {
        let (x, y, z) = (1 + (k >> 2), 1 + ((k >> 1) & 1), 1 + (k & 1));
        let central = Vec3::new(
            v[x + 1][y][z] - v[x - 1][y][z],
            v[x][y + 1][z] - v[x][y - 1][z],
            v[x][y][z + 1] - v[x][y][z - 1],
        ) * 0.5;
        let wx = if x == 2 { u.x } else { 1.0 - u.x };
        let wy = if y == 2 { u.y } else { 1.0 - u.y };
        let wz = if z == 2 { u.z } else { 1.0 - u.z };
        g += central * (wx * wy * wz);
    }
    g
}

/// The cubic `k0 + k1 s + k2 s² + k3 s³` of the interpolant along `a + d s` (local coords).
fn cubic(c: &[f32; 8], a: Vec3, d: Vec3) -> [f32; 4] {
    // Each corner weight is a product of linear factors α + β s per axis.
    let ax = [1.0 - a.x, a.x];
    let bx = [-d.x, d.x];
    let ay = [1.0 - a.y, a.y];
    let by = [-d.y, d.y];
    let az = [1.0 - a.z, a.z];
    let bz = [-d.z, d.z];
    let mut k = [0.0f32; 4];
    for i in 0..2 {
        // Quadratic in s after combining y and z for this x slab.
        let mut q = [0.0f32; 3];
        for j in 0..2 {
            let c0 = c[(i << 2) | (j << 1)];
            let c1 = c[(i << 2) | (j << 1) | 1];
            let p0 = c0 * az[0] + c1 * az[1];
            let p1 = c0 * bz[0] + c1 * bz[1];
            q[0] += p0 * ay[j];
            q[1] += p0 * by[j] + p1 * ay[j];
            q[2] += p1 * by[j];
        }
        k[0] += q[0] * ax[i];
        k[1] += q[0] * bx[i] + q[1] * ax[i];
        k[2] += q[1] * bx[i] + q[2] * ax[i];
        k[3] += q[2] * bx[i];
    }
    k
}

#[inline]
fn horner(k: &[f32; 4], s: f32) -> f32 {
    ((k[3] * s + k[2]) * s + k[1]) * s + k[0]
}

/// Roots of `a s² + b s + c` strictly inside `(0, len)`, ascending (at most two).
fn quadratic_roots_in(a: f32, b: f32, c: f32, len: f32) -> ([f32; 2], usize) {
    let mut out = [0.0f32; 2];
    let mut n = 0;
    let mut push = |s: f32| {
        if s > 0.0 && s < len && s.is_finite() {
            out[n] = s;
            n += 1;
        }
    };
    let scale = a.abs().max(b.abs()).max(c.abs());
    if scale == 0.0 || !scale.is_finite() {
        return (out, 0);
    }
    if a.abs() <= 1e-7 * scale {
        if b != 0.0 {
            push(-c / b);
        }
    } else {
        let disc = b * b - 4.0 * a * c;
        if disc >= 0.0 {
            let q = -0.5 * (b + disc.sqrt().copysign(b));
            let (r0, r1) = (q / a, if q != 0.0 { c / q } else { q / a });
            let (r0, r1) = if r0 <= r1 { (r0, r1) } else { (r1, r0) };
            push(r0);
            if r1 != r0 {
                push(r1);
            }
        }
    }
    if n == 2 && out[0] > out[1] {
        out.swap(0, 1);
    }
    (out, n)
}

/// The first zero crossing of the interpolant of `c` along `a + d t` (`a` the ray origin in
/// cell-local coordinates) with `t` in `[ta, tb]`, or `None`. `inside` carries whether the ray
/// was inside (negative) where the previous cell ended (`None` before the first evaluated
/// point) and is left at this cell's end: a sign change across a cell face that rounding puts
/// on either side is still a crossing, found at the face.
pub(super) fn first_root(
    c: &[f32; 8],
    a: Vec3,
    d: Vec3,
    ta: f32,
    tb: f32,
    inside: &mut Option<bool>,
) -> Option<f32> {
    let start = a + d * ta;
    let k = cubic(c, start, d);
    let len = tb - ta;
    let f0 = horner(&k, 0.0);
    let neg0 = f0 < 0.0;
    if let Some(prev) = *inside {
        if prev != neg0 {
            *inside = Some(neg0);
            return Some(ta);
        }
    }
    // Split [0, len] at the cubic's extrema: each piece is monotone, one crossing at most.
    let (ext, n) = quadratic_roots_in(3.0 * k[3], 2.0 * k[2], k[1], len);
    let mut s0 = 0.0f32;
    let mut fa = f0;
    let tol = 1e-5 / d.abs().max_element().max(1e-30);
    // `i == n` is the interval's end, not a root: the indexed form keeps this hot loop plain.
    #[allow(clippy::needless_range_loop)]
    for i in 0..=n {
        let s1 = if i < n { ext[i] } else { len };
        let fb = horner(&k, s1);
        if (fa < 0.0) != (fb < 0.0) {
            *inside = Some(fb < 0.0);
            return Some(ta + refine(&k, s0, fa, s1, fb, tol));
        }
        s0 = s1;
        fa = fb;
    }
    *inside = Some(fa < 0.0);
    None
}

/// A root of the cubic in `[s0, s1]` where `f(s0)` and `f(s1)` differ in sign (negative or
/// not): regula falsi with the Illinois modification, to a bracket of `tol`.
fn refine(k: &[f32; 4], mut s0: f32, mut f0: f32, mut s1: f32, mut f1: f32, tol: f32) -> f32 {
    let neg0 = f0 < 0.0;
    let mut side = 0i8;
    for _ in 0..60 {
        if s1 - s0 <= tol {
            break;
        }
        let mut s = if f1 != f0 {
            (s0 * f1 - s1 * f0) / (f1 - f0)
        } else {
            0.5 * (s0 + s1)
        };
        if !(s > s0 && s < s1) {
            s = 0.5 * (s0 + s1);
        }
        let fs = horner(k, s);
        if (fs < 0.0) == neg0 {
            s0 = s;
            f0 = fs;
            if side == -1 {
                f1 *= 0.5;
            }
            side = -1;
        } else {
            s1 = s;
            f1 = fs;
            if side == 1 {
                f0 *= 0.5;
            }
            side = 1;
        }
    }
    // The bracket's end past the crossing: a ray restarted there is on the far side.
    if s1 - s0 <= tol {
        0.5 * (s0 + s1)
    } else if f0.abs() < f1.abs() {
        s0
    } else {
        s1
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `corner_signs` decides as the min/max fold it replaced (`straddles` = min <= 0 <= max,
    /// `below` = max < 0) on corners drawn from a set with ±0, infinities, NaN and values
    /// of both signs.
    #[test]
    fn corner_signs_equal_the_range_fold() {
        let pool = [
            -2.5f32,
            -1e-30,
            -0.0,
            0.0,
            1e-30,
            0.75,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
        ];
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let (mut straddling, mut below, mut above) = (0, 0, 0);
        for _ in 0..50_000 {
            let mut c = [0.0f32; 8];
            for v in &mut c {
                state = state
                    .wrapping_mul(6_364_136_223_846_793_005)
                    .wrapping_add(1_442_695_040_888_963_407);
                // Mostly one sign per cell, so both outcomes are common.
                let i = (state >> 33) as usize % pool.len();
                *v = pool[i];
            }
            if (state >> 40) & 1 == 0 {
                for v in &mut c {
                    *v = v.abs();
                }
            }
            let (min, max) = c
                .iter()
                .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), &v| {
                    (a.min(v), b.max(v))
                });
            let (le, ge) = corner_signs(&c);
            assert_eq!(le && ge, min <= 0.0 && max >= 0.0, "{c:?}");
            if !(le && ge) {
                assert_eq!(!ge, max < 0.0, "{c:?}");
                if max < 0.0 {
                    below += 1;
                } else {
                    above += 1;
                }
            } else {
                straddling += 1;
            }
        }
        assert!(straddling > 1000 && below > 0 && above > 1000);
    }

    /// A plane φ = x − 0.3 (corners 0 − 0.3 and 1 − 0.3): a ray along +x crosses at x = 0.3.
    #[test]
    fn plane_crossing() {
        let mut c = [0.0f32; 8];
        for (k, v) in c.iter_mut().enumerate() {
            *v = (k >> 2) as f32 - 0.3;
        }
        let mut inside = None;
        let t = first_root(
            &c,
            Vec3::new(-1.0, 0.5, 0.5),
            Vec3::X,
            1.0,
            2.0,
            &mut inside,
        );
        let t = t.unwrap_or(f32::NAN);
        assert!((t - 1.3).abs() < 1e-5, "{t}");
        assert_eq!(inside, Some(false));
    }

    /// Two crossings inside one cell (a saddle dipping below zero between two positive
    /// ends): the first is found though both ends are positive.
    #[test]
    fn two_crossings_in_one_cell() {
        // Positive at the diagonal's two ends, negative at the six other corners: along the
        // diagonal the interpolant is 0.2 at both ends and (0.4 − 6)/8 in the middle.
        let c = [0.2, -1.0, -1.0, -1.0, -1.0, -1.0, -1.0, 0.2];
        let k = cubic(&c, Vec3::ZERO, Vec3::ONE);
        assert!(horner(&k, 0.0) > 0.0 && horner(&k, 1.0) > 0.0);
        let mid = horner(&k, 0.5);
        assert!(mid < 0.0, "{mid}");
        let mut inside = None;
        let t = first_root(&c, Vec3::ZERO, Vec3::ONE, 0.0, 1.0, &mut inside);
        let t = t.unwrap_or(f32::NAN);
        assert!(t > 0.0 && t < 0.5 && horner(&k, t).abs() < 1e-4, "{t}");
        // The cubic matches the trilinear interpolant.
        for s in [0.1f32, 0.37, 0.8] {
            assert!((horner(&k, s) - eval(&c, Vec3::splat(s))).abs() < 1e-5);
        }
    }
}
