//! Inside or outside: exact ray parity along the three index axes, decided by a vote of the six
//! axis half-rays from a voxel centre (docs/voxelize.md, "Sign").
//!
//! For each axis `a`, every lattice line parallel to `a` through voxel centres is intersected
//! with every triangle by a 2-D point-in-triangle test in the plane of the two other axes. The
//! test is exact: vertices are rounded once to a fixed-point lattice of 2⁻¹⁶ voxel, edge
//! functions are evaluated in 128-bit integers, each edge is always evaluated in one canonical
//! direction (so the two triangles sharing it see the same value with opposite signs), and a
//! point lying exactly on an edge or a vertex is decided as if it were moved by the same
//! infinitesimal offset `(ε, ε²)` for every edge (simulation of simplicity). A line through a
//! shared edge or vertex of a closed mesh therefore crosses it exactly once, and the crossing
//! count along any line is exact. A voxel is inside when at least four of its six half-rays
//! (±x, ±y, ±z) cross the surface an odd number of times: for a closed mesh all six agree; for an
//! open mesh the majority decides (a 3–3 tie counts as outside).

use glam::{DVec3, IVec3};
use rayon::prelude::*;

/// Fixed-point scale of the vertex lattice: 2¹⁶ steps per voxel.
const FIXED_SCALE: f64 = 65536.0;
const FIXED_SHIFT: u32 = 16;

/// A triangle in index space: exact fixed-point vertices and the f64 vertices they came from.
#[derive(Clone, Copy, Debug)]
pub(crate) struct FixedTriangle {
    q: [[i64; 3]; 3],
    p: [DVec3; 3],
}

impl FixedTriangle {
    /// Rounds the index-space vertices `p` to the fixed-point lattice. The caller guarantees
    /// |coordinates| < 2³⁰ (so fixed-point values stay below 2⁴⁶ and products below 2⁹⁴).
    pub(crate) fn new(p: [DVec3; 3]) -> Self {
        let q = p.map(|v| v.to_array().map(|x| (x * FIXED_SCALE).round() as i64));
        FixedTriangle { q, p }
    }
}

/// The sorted crossings of every lattice line parallel to one axis (a compressed table:
/// line `l` owns `xs[offsets[l]..offsets[l + 1]]`, positions along the axis in index units).
#[derive(Debug)]
struct LineTable {
    axis: usize,
    /// Lowest (u, v) lattice coordinate of the domain (u = axis + 1, v = axis + 2, mod 3).
    lo: [i32; 2],
    /// Lines along u and v.
    dims: [usize; 2],
    offsets: Vec<u32>,
    xs: Vec<f64>,
}

/// Sign of the canonical edge function of the 2-D edge `lo → hi` (`lo < hi`
/// lexicographically) at the lattice point `p`, with ties broken by the offset `(ε, ε²)`.
fn canonical_side(lo: [i64; 2], hi: [i64; 2], p: [i64; 2]) -> (i128, i32) {
    let d = [i128::from(hi[0] - lo[0]), i128::from(hi[1] - lo[1])];
    let r = [i128::from(p[0] - lo[0]), i128::from(p[1] - lo[1])];
    let e = d[0] * r[1] - d[1] * r[0];
    let s = if e != 0 {
        e.signum() as i32
    } else if d[1] != 0 {
        // cross(d, (ε, ε²)) = d_u ε² − d_v ε: the ε term decides.
        -(d[1].signum() as i32)
    } else {
        d[0].signum() as i32
    };
    (e, s)
}

/// The edge function of the directed edge `a → b` at `p` (exact value and tie-broken sign),
/// evaluated in the canonical direction.
fn edge(a: [i64; 2], b: [i64; 2], p: [i64; 2]) -> (i128, i32) {
    if a <= b {
        canonical_side(a, b, p)
    } else {
        let (e, s) = canonical_side(b, a, p);
        (-e, -s)
    }
}

impl LineTable {
    fn build(axis: usize, tris: &[FixedTriangle], lo: IVec3, hi: IVec3) -> Self {
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        let lo2 = [lo[u], lo[v]];
        let dims = [(hi[u] - lo[u] + 1) as usize, (hi[v] - lo[v] + 1) as usize];
        let mut hits: Vec<(u32, f64)> = tris
            .par_chunks(256)
            .flat_map_iter(|chunk| {
                let mut out = Vec::new();
                for t in chunk {
                    crossings_of(t, axis, lo2, dims, &mut out);
                }
                out
            })
            .collect();
        hits.par_sort_unstable_by(|a, b| a.0.cmp(&b.0).then(a.1.total_cmp(&b.1)));
        let lines = dims[0] * dims[1];
        let mut offsets = vec![0u32; lines + 1];
        for &(l, _) in &hits {
            if let Some(o) = offsets.get_mut(l as usize + 1) {
                *o += 1;
            }
        }
        for i in 0..lines {
            offsets[i + 1] += offsets[i];
        }
        LineTable {
            axis,
            lo: lo2,
            dims,
            offsets,
            xs: hits.into_iter().map(|h| h.1).collect(),
        }
    }

    /// Inside votes (0, 1 or 2) of the two half-rays along this axis from voxel `ijk`.
    fn votes(&self, ijk: IVec3) -> u32 {
        let (u, v) = ((self.axis + 1) % 3, (self.axis + 2) % 3);
        let (a, b) = (ijk[u] - self.lo[0], ijk[v] - self.lo[1]);
        if a < 0 || b < 0 || a as usize >= self.dims[0] || b as usize >= self.dims[1] {
            return 0;
        }
        let l = a as usize * self.dims[1] + b as usize;
        let (s, e) = match (self.offsets.get(l), self.offsets.get(l + 1)) {
            (Some(&s), Some(&e)) => (s as usize, e as usize),
            _ => return 0,
        };
        let xs = self.xs.get(s..e).unwrap_or(&[]);
        let x = f64::from(ijk[self.axis]);
        let below = xs.partition_point(|&c| c < x);
        let above = xs.len() - below;
        (below % 2) as u32 + (above % 2) as u32
    }
}

/// Appends `(line, position)` for every lattice line parallel to `axis` that crosses `t`.
fn crossings_of(
    t: &FixedTriangle,
    axis: usize,
    lo: [i32; 2],
    dims: [usize; 2],
    out: &mut Vec<(u32, f64)>,
) {
    let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
    let q2 = t.q.map(|q| [q[u], q[v]]);
    let (a, b, c) = (q2[0], q2[1], q2[2]);
    let area = i128::from(b[0] - a[0]) * i128::from(c[1] - a[1])
        - i128::from(b[1] - a[1]) * i128::from(c[0] - a[0]);
    if area == 0 {
        // Parallel to the lines (or degenerate): crossed by none of them.
        return;
    }
    let orient = area.signum() as i32;
    let min_u = a[0].min(b[0]).min(c[0]);
    let max_u = a[0].max(b[0]).max(c[0]);
    let min_v = a[1].min(b[1]).min(c[1]);
    let max_v = a[1].max(b[1]).max(c[1]);
    // Lattice points (multiples of 2^16) inside the bounding box, clamped to the domain.
    let first = |m: i64| (m + (1 << FIXED_SHIFT) - 1).div_euclid(1 << FIXED_SHIFT);
    let last = |m: i64| m.div_euclid(1 << FIXED_SHIFT);
    let u0 = first(min_u).max(i64::from(lo[0]));
    let u1 = last(max_u).min(i64::from(lo[0]) + dims[0] as i64 - 1);
    let v0 = first(min_v).max(i64::from(lo[1]));
    let v1 = last(max_v).min(i64::from(lo[1]) + dims[1] as i64 - 1);
    let areaf = area as f64;
    for pu in u0..=u1 {
        for pv in v0..=v1 {
            let p = [pu << FIXED_SHIFT, pv << FIXED_SHIFT];
            let (e_bc, s_bc) = edge(b, c, p);
            if s_bc != orient {
                continue;
            }
            let (e_ca, s_ca) = edge(c, a, p);
            if s_ca != orient {
                continue;
            }
            let (e_ab, s_ab) = edge(a, b, p);
            if s_ab != orient {
                continue;
            }
            // Barycentric weights from the exact edge functions.
            let (w0, w1, w2) = (
                e_bc as f64 / areaf,
                e_ca as f64 / areaf,
                e_ab as f64 / areaf,
            );
            let x = w0 * t.p[0][axis] + w1 * t.p[1][axis] + w2 * t.p[2][axis];
            let line =
                (pu - i64::from(lo[0])) as usize * dims[1] + (pv - i64::from(lo[1])) as usize;
            out.push((line as u32, x));
        }
    }
}

/// Crossing tables along x, y and z over a voxel domain.
#[derive(Debug)]
pub(crate) struct ParityTables {
    tables: [LineTable; 3],
}

impl ParityTables {
    /// Builds the tables for the voxel range `lo..=hi` (inclusive).
    pub(crate) fn build(tris: &[FixedTriangle], lo: IVec3, hi: IVec3) -> Self {
        ParityTables {
            tables: [0, 1, 2].map(|a| LineTable::build(a, tris, lo, hi)),
        }
    }

    /// How many of the six axis half-rays from voxel `ijk` cross the surface an odd number of
    /// times (0..=6).
    pub(crate) fn votes(&self, ijk: IVec3) -> u32 {
        self.tables.iter().map(|t| t.votes(ijk)).sum()
    }

    /// Inside when at least four of six half-rays vote inside.
    pub(crate) fn inside(&self, ijk: IVec3) -> bool {
        self.votes(ijk) >= 4
    }

    /// Crossings stored in the three tables (a measure of the work done).
    pub(crate) fn crossing_count(&self) -> usize {
        self.tables.iter().map(|t| t.xs.len()).sum()
    }
}
