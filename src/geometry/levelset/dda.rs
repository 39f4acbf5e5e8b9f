//! A 3D DDA (Amanatides & Woo 1987) over a uniform lattice of cells of edge `2^shift` in
//! index space, restricted to the cell keys `[lo, hi]` and the ray interval `[t0, t1]`. It
//! yields each cell with the interval the ray spends in it; the intervals are contiguous and
//! cover `[t0, t1]`, so a rounding error in the first cell's key (clamped into `[lo, hi]`)
//! only shifts which polynomial evaluates a stretch of the ray, never drops a stretch.
//!
//! A level set's intersection nests four of these walks per ray (coarse cells, bricks,
//! quarters, voxels): the ray's reciprocal direction and steps are computed once
//! ([`DdaRay`]), and the per-axis state is kept in arrays (a glam vector indexed by a run-time
//! axis compiles to a branch per access).

use glam::{IVec3, Vec3};

/// The quantities every walk of one ray shares.
#[derive(Clone, Copy, Debug)]
pub(super) struct DdaRay {
    o: Vec3,
    d: Vec3,
    inv: [f32; 3],
    step: [i32; 3],
}

impl DdaRay {
    /// The ray `o + t d` (index space).
    pub(super) fn new(o: Vec3, d: Vec3) -> Self {
        let inv = Vec3::ONE / d;
        DdaRay {
            o,
            d,
            inv: inv.to_array(),
            step: [sign(d.x), sign(d.y), sign(d.z)],
        }
    }

    /// The walk over `[t0, t1]` through cells of edge `2^shift`, keys in `[lo, hi]`.
    #[inline]
    pub(super) fn walk(&self, t0: f32, t1: f32, shift: i32, lo: IVec3, hi: IVec3) -> Dda {
        let size = (1i32 << shift) as f32;
        // Division by a power of two is the multiplication by its (exact) reciprocal.
        let p = (self.o + self.d * t0) * (1.0 / size);
        let cell = IVec3::new(floor_i32(p.x), floor_i32(p.y), floor_i32(p.z)).clamp(lo, hi);
        let t_next = first_exits(cell, self.step, size, self.o, self.inv);
        Dda {
            cell: cell.to_array(),
            step: self.step,
            t_next,
            o: self.o.to_array(),
            inv: self.inv,
            size,
            t: t0,
            t_end: t1,
            lo: lo.to_array(),
            hi: hi.to_array(),
            // `!(t0 <= t1)`: an empty or NaN interval is done at once (the crate's idiom).
            done: !(t0 <= t1) || lo.cmpgt(hi).any(),
        }
    }
}

/// The exit distances of cell `cell` (edge `size`) across each axis, as [`Dda::update`]
/// computes them one axis at a time (the same operations lane by lane, so the same bits),
/// without its per-axis branch: `INFINITY` where the step is 0.
#[inline(always)]
fn first_exits(cell: IVec3, step: [i32; 3], size: f32, o: Vec3, inv: [f32; 3]) -> [f32; 3] {
    let step = IVec3::from_array(step);
    let up = IVec3::select(step.cmpgt(IVec3::ZERO), IVec3::ONE, IVec3::ZERO);
    let plane = (cell + up).as_vec3() * size;
    let t = (plane - o) * Vec3::from_array(inv);
    Vec3::select(step.cmpeq(IVec3::ZERO), Vec3::INFINITY, t).to_array()
}

/// `x.floor() as i32` (saturating, NaN to 0) without a library call: truncation, one lower
/// where it rounded up.
///
/// Not `grid::floor_frac`'s (or `fabric::floor_ivec3`'s) integers, which wrap below −2³¹ to
/// `i32::MAX`: the cell key is clamped into `[lo, hi]` next, so a point far below the grid
/// must give the lowest key. Not the texture lookups' `floor_exact` either, which returns the
/// float floor (`floor_exact(x) as i32` is this function, with more work per call).
#[inline(always)]
fn floor_i32(x: f32) -> i32 {
    let i = x as i32;
    if i as f32 > x {
        i.saturating_sub(1)
    } else {
        i
    }
}

/// One walk of a [`DdaRay`].
pub(super) struct Dda {
    cell: [i32; 3],
    step: [i32; 3],
    t_next: [f32; 3],
    o: [f32; 3],
    inv: [f32; 3],
    size: f32,
    t: f32,
    t_end: f32,
    lo: [i32; 3],
    hi: [i32; 3],
    done: bool,
}

impl Dda {
    /// The exit distance of the current cell across axis `k`.
    #[inline(always)]
    fn update(&mut self, k: usize) {
        self.t_next[k] = match self.step[k] {
            0 => f32::INFINITY,
            s => {
                let plane = (self.cell[k] + i32::from(s > 0)) as f32 * self.size;
                (plane - self.o[k]) * self.inv[k]
            }
        };
    }

    /// The next cell and the ray interval `[ta, tb]` inside it.
    #[inline]
    pub(super) fn next(&mut self) -> Option<(IVec3, f32, f32)> {
        if self.done {
            return None;
        }
        let [x, y, z] = self.t_next;
        let k = if x <= y && x <= z {
            0
        } else if y <= z {
            1
        } else {
            2
        };
        let ta = self.t;
        let tb = self.t_next[k].min(self.t_end).max(ta);
        let out = (IVec3::from_array(self.cell), ta, tb);
        self.t = tb;
        if tb >= self.t_end {
            self.done = true;
        } else {
            self.cell[k] += self.step[k];
            if self.cell[k] < self.lo[k] || self.cell[k] > self.hi[k] {
                self.done = true;
            } else {
                self.update(k);
            }
        }
        Some(out)
    }
}

fn sign(x: f32) -> i32 {
    if x > 0.0 {
        1
    } else if x < 0.0 {
        -1
    } else {
        0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `first_exits` gives `Dda::update`'s distances bit for bit (zero, tiny and large
    /// direction components, cells on both sides of the origin, all four cell sizes).
    #[test]
    fn first_exits_equal_the_per_axis_update() {
        let comps = [0.0f32, -0.0, 1e-30, -1e-30, 0.37, -0.81, 3.5, -1e6];
        let mut n = 0;
        for &dx in &comps {
            for &dy in &comps {
                for &dz in &comps {
                    for shift in [0, 2, 3, 6] {
                        for cell in [IVec3::new(-3, 0, 7), IVec3::new(12, -40, 1)] {
                            let o = Vec3::new(0.3, -17.25, 5.5);
                            let ray = DdaRay::new(o, Vec3::new(dx, dy, dz));
                            let size = (1i32 << shift) as f32;
                            let mut dda = Dda {
                                cell: cell.to_array(),
                                step: ray.step,
                                t_next: [0.0; 3],
                                o: o.to_array(),
                                inv: ray.inv,
                                size,
                                t: 0.0,
                                t_end: 1.0,
                                lo: [i32::MIN; 3],
                                hi: [i32::MAX; 3],
                                done: false,
                            };
                            for k in 0..3 {
                                dda.update(k);
                            }
                            let got = first_exits(cell, ray.step, size, o, ray.inv);
                            for (g, want) in got.iter().zip(dda.t_next) {
                                assert_eq!(g.to_bits(), want.to_bits());
                            }
                            n += 1;
                        }
                    }
                }
            }
        }
        assert_eq!(n, 8 * 8 * 8 * 4 * 2);
    }

    /// The walk as it was written before (per-walk reciprocal and steps, `Vec3` state,
    /// `floor` by the library): the reference the shared-ray walk must reproduce bit for bit.
    struct Reference {
        cell: IVec3,
        step: IVec3,
        t_next: Vec3,
        o: Vec3,
        inv: Vec3,
        size: f32,
        t: f32,
        t_end: f32,
        lo: IVec3,
        hi: IVec3,
        done: bool,
    }

    impl Reference {
        fn new(o: Vec3, d: Vec3, t0: f32, t1: f32, shift: i32, lo: IVec3, hi: IVec3) -> Self {
            let size = (1i32 << shift) as f32;
            let p = o + d * t0;
            let cell = (p / size).floor().as_ivec3().clamp(lo, hi);
            let mut r = Reference {
                cell,
                step: IVec3::new(sign(d.x), sign(d.y), sign(d.z)),
                t_next: Vec3::INFINITY,
                o,
                inv: Vec3::ONE / d,
                size,
                t: t0,
                t_end: t1,
                lo,
                hi,
                done: t0.partial_cmp(&t1).is_none_or(|o| o.is_gt()) || lo.cmpgt(hi).any(),
            };
            for k in 0..3 {
                r.update(k);
            }
            r
        }

        fn update(&mut self, k: usize) {
            self.t_next[k] = match self.step[k] {
                0 => f32::INFINITY,
                s => {
                    let plane = (self.cell[k] + i32::from(s > 0)) as f32 * self.size;
                    (plane - self.o[k]) * self.inv[k]
                }
            };
        }

        fn next(&mut self) -> Option<(IVec3, f32, f32)> {
            if self.done {
                return None;
            }
            let k = if self.t_next.x <= self.t_next.y && self.t_next.x <= self.t_next.z {
                0
            } else if self.t_next.y <= self.t_next.z {
                1
            } else {
                2
            };
            let ta = self.t;
            let tb = self.t_next[k].min(self.t_end).max(ta);
            let out = (self.cell, ta, tb);
            self.t = tb;
            if tb >= self.t_end {
                self.done = true;
            } else {
                self.cell[k] += self.step[k];
                if self.cell[k] < self.lo[k] || self.cell[k] > self.hi[k] {
                    self.done = true;
                } else {
                    self.update(k);
                }
            }
            Some(out)
        }
    }

    /// The truncating floor equals the library's floor cast, at the edges included.
    #[test]
    fn floor_i32_is_the_floor_cast() {
        let cases = [
            0.0f32,
            -0.0,
            0.5,
            -0.5,
            1.0,
            -1.0,
            -1.0e-30,
            2.999_999_8,
            -2.999_999_8,
            8_388_607.5,
            -8_388_607.5,
            3.0e9,
            -3.0e9,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            2_147_483_520.0,
            -2_147_483_648.0,
            -2_147_483_904.0,
        ];
        for x in cases {
            assert_eq!(floor_i32(x), x.floor() as i32, "{x}");
        }
    }

    /// Random rays (axis-parallel components, zero-length intervals, origins inside and
    /// outside, all four cell sizes of the level set's walks): the same cells and intervals,
    /// bit for bit, as the reference walk.
    #[test]
    fn shared_ray_walks_equal_the_reference() {
        let mut x = 0x853C_49E6_748F_EA9Bu64;
        let mut next = move || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (x >> 40) as f32 / (1u64 << 24) as f32
        };
        let mut cells = 0;
        for i in 0..20_000 {
            let o = Vec3::new(next(), next(), next()) * 300.0 - Vec3::splat(120.0);
            let mut d = Vec3::new(next(), next(), next()) * 2.0 - Vec3::ONE;
            if i % 5 == 0 {
                d.x = 0.0;
            }
            if i % 7 == 0 {
                d.y = 0.0;
            }
            let shift = (i % 4) * 2 - i32::from(i % 4 == 3);
            let lo = IVec3::new(-3, -2, -4) << 1;
            let hi = IVec3::new(5, 6, 4) << 1;
            let t0 = next() * 100.0;
            let t1 = if i % 11 == 0 { t0 } else { t0 + next() * 400.0 };
            let mut a = DdaRay::new(o, d).walk(t0, t1, shift, lo, hi);
            let mut b = Reference::new(o, d, t0, t1, shift, lo, hi);
            loop {
                let (p, q) = (a.next(), b.next());
                let bits =
                    |c: Option<(IVec3, f32, f32)>| c.map(|(k, s, t)| (k, s.to_bits(), t.to_bits()));
                assert_eq!(bits(p), bits(q), "ray {i}");
                if p.is_none() {
                    break;
                }
                cells += 1;
            }
        }
        assert!(cells > 50_000, "{cells}");
    }
}
