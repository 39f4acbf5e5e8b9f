//! A 3D DDA (Amanatides & Woo 1987) over a uniform lattice of cells of edge `2^shift` in
//! index space, restricted to the cell keys `[lo, hi]` and the ray interval `[t0, t1]`. It
//! yields each cell with the interval the ray spends in it; the intervals are contiguous and
//! cover `[t0, t1]`, so a rounding error in the first cell's key (clamped into `[lo, hi]`)
//! only shifts which polynomial evaluates a stretch of the ray, never drops a stretch.

use glam::{IVec3, Vec3};

pub(super) struct Dda {
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

impl Dda {
    /// The walk of `o + t d` over `[t0, t1]` through cells of edge `2^shift`, keys in
    /// `[lo, hi]`.
    pub(super) fn new(o: Vec3, d: Vec3, t0: f32, t1: f32, shift: i32, lo: IVec3, hi: IVec3) -> Dda {
        let size = (1i32 << shift) as f32;
        let p = o + d * t0;
        let cell = (p / size).floor().as_ivec3().clamp(lo, hi);
        let inv = Vec3::ONE / d;
        let step = IVec3::new(sign(d.x), sign(d.y), sign(d.z));
        let mut dda = Dda {
            cell,
            step,
            t_next: Vec3::INFINITY,
            o,
            inv,
            size,
            t: t0,
            t_end: t1,
            lo,
            hi,
            done: !(t0 <= t1) || lo.cmpgt(hi).any(),
        };
        for k in 0..3 {
            dda.update(k);
        }
        dda
    }

    /// The exit distance of the current cell across axis `k`.
    #[inline]
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

fn sign(x: f32) -> i32 {
    if x > 0.0 {
        1
    } else if x < 0.0 {
        -1
    } else {
        0
    }
}
