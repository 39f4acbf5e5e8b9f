//! Voxelisation of a fabric patch into the sparse brick grid (course notes §3.3 and §5.3),
//! its coarser mip levels, OpenVDB export and a stand-alone single-scattering preview.
//!
//! # Channels
//! [`voxelise`] builds one [`SparseGrid`] with three channels sharing one topology:
//!
//! * `density` ([`DENSITY`]): fibre volume fraction in `[0, 1]` per voxel. Every polyline
//!   segment deposits its cylinder volume `π r² |p_{k+1} − p_k|` into the voxels it crosses, in
//!   proportion to the exact length of the segment inside each voxel (the segment is clipped
//!   against the voxel planes). A fibre thicker than half a voxel is split into parallel
//!   lines over a lattice of its cross-section disc, each carrying an equal share. So
//!   `Σ density × voxel volume` equals [`FabricPatch::fibre_volume`] up to rounding, unless a
//!   voxel would exceed a fraction of 1 (then the excess is clamped and reported in
//!   [`VoxelisedPatch::clamped_volume`]).
//! * `tangent` ([`TANGENT`], Vec3): the principal eigenvector of the volume-weighted
//!   structure tensor `Σ w t tᵀ` of the segments in the voxel. Fibre scattering does not
//!   depend on the sign of the tangent, so directions are averaged as tensors (opposite
//!   tangents would cancel as vectors). The sign is canonical: the largest component is
//!   positive.
//! * `id` ([`ID`]): warp = 0, weft = 1, pile = 2, the yarn family holding most of the
//!   deposited volume (ties go to the lower id), stored as a float.
//!
//! # Index space
//! The tile `[0, tile.x) × [0, tile.y)` is covered by `nx × ny` voxels; `x` and `y` wrap
//! modulo the tile (the patch is periodic; flyaways, fibre ends and pile tufts that leave the
//! tile re-enter it on the other side). Voxel size: `h = max(tile.x, tile.y) / resolution`,
//! `nx = max(1, round(tile.x / h))` and `h_x = tile.x / nx` (likewise for `y`), `h_z = h`, so
//! a square tile has cubic voxels and every tile is covered exactly. Voxel `(i, j, k)` covers
//! `origin + [i, i+1) ⊙ h`, with `origin = (0, 0, bounds.min.z − max fibre radius)`; its
//! centre (the grid's index point `(i, j, k)`, OpenVDB's convention) is at
//! `origin + (i + ½, j + ½, k + ½) ⊙ h`. World units are the patch's units (cm for the
//! presets).
//!
//! # Parallelism and determinism
//! Fibres are cut into fixed chunks of [`CHUNK_FIBRES`]; chunks are voxelised in parallel
//! (rayon) into private brick accumulators, which are added into the patch accumulator in
//! chunk order. The result is bit-identical whatever the number of threads.

use super::fibre_scattering::{extinction_scale, FibrePhaseParams};
use super::{FabricError, FabricPatch, FabricShading, YarnId};
use crate::grid::{
    voxel_offset, ChannelKind, CoordMap, SparseGrid, SparseGridBuilder, Storage, BRICK_VOXELS,
};
use crate::math::{Frame, Mat3, Vec3};
use crate::spectrum::Rgb;
use crate::vdb::{
    write_vdb_with_metadata, Compression, GridStats, GridToWrite, MetaEntry, WriteOptions,
};
use glam::{DAffine3, DVec3, IVec3};
use rayon::prelude::*;
use std::path::Path;

/// Channel index of the fibre volume fraction.
pub const DENSITY: usize = 0;
/// Channel index of the mean fibre tangent (Vec3).
pub const TANGENT: usize = 1;
/// Channel index of the yarn family id (0 warp, 1 weft, 2 pile).
pub const ID: usize = 2;
/// Fibres per parallel work item (fixed, so results do not depend on the thread count).
pub const CHUNK_FIBRES: usize = 64;
/// Largest allowed `resolution` (voxels across the tile's largest side).
pub const MAX_RESOLUTION: u32 = 8192;
/// Largest number of line–voxel deposits a voxelisation may make (memory and time guard).
pub const MAX_DEPOSITS: u64 = 2_000_000_000;
/// Largest number of brick accumulators (each 18 KiB) the bounding box may need.
pub const MAX_BRICKS: u64 = 400_000;

/// Accumulator components per voxel: structure tensor `xx, xy, xz, yy, yz, zz` (volume
/// weighted, so its trace is the deposited volume) and the volume per yarn family.
const ACC: usize = 9;
type BrickAcc = Box<[f32]>;

/// Brick accumulators with a hash index and a one-entry cache (deposits along a fibre hit
/// the same brick many times in a row).
#[derive(Default)]
struct AccMap {
    index: CoordMap<u32>,
    bricks: Vec<(IVec3, BrickAcc)>,
    last: Option<(IVec3, usize)>,
}

impl AccMap {
    fn brick(&mut self, key: IVec3) -> &mut [f32] {
        let i = match self.last {
            Some((k, i)) if k == key => i,
            _ => {
                let bricks = &mut self.bricks;
                let i = *self.index.entry(key).or_insert_with(|| {
                    bricks.push((key, new_brick()));
                    (bricks.len() - 1) as u32
                }) as usize;
                self.last = Some((key, i));
                i
            }
        };
        &mut self.bricks[i].1
    }
    fn into_sorted(self) -> Vec<(IVec3, BrickAcc)> {
        let mut v = self.bricks;
        v.sort_unstable_by_key(|(k, _)| (k.x, k.y, k.z));
        v
    }
}

fn new_brick() -> BrickAcc {
    vec![0.0f32; BRICK_VOXELS * ACC].into_boxed_slice()
}

/// Options of [`voxelise`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VoxeliseOptions {
    /// Storage of the grid's brick values (f32 by default; f16 halves the memory).
    pub storage: Storage,
    /// Wrap `x` and `y` modulo the tile (default true). Without wrapping, index space is
    /// unbounded and voxels outside the tile are kept.
    pub wrap: bool,
    /// Keep the per-voxel accumulators (36 bytes per voxel of every touched brick) so that
    /// [`VoxelisedPatch::mip`] can sum structure tensors exactly (default true). Without
    /// them the patch is smaller and `mip` returns an error.
    pub keep_accumulators: bool,
}

impl Default for VoxeliseOptions {
    fn default() -> Self {
        VoxeliseOptions {
            storage: Storage::F32,
            wrap: true,
            keep_accumulators: true,
        }
    }
}

/// A voxelised fabric patch: the grid and the numbers needed to interpret it.
#[derive(Clone, Debug)]
pub struct VoxelisedPatch {
    /// The grid, channels [`DENSITY`], [`TANGENT`] and [`ID`]; index-to-world as described in
    /// the module docs.
    pub grid: SparseGrid,
    /// Mip level: 0 is the full resolution, level `l` has voxels `2^l` times larger.
    pub level: u32,
    /// Voxel size along `x, y, z` (world units).
    pub voxel_size: DVec3,
    /// World position of the minimum corner of voxel `(0, 0, 0)`.
    pub origin: DVec3,
    /// Voxels across the tile in `x` and `y` at this level (`ceil(n₀ / 2^level)`); with
    /// wrapping on, `x` and `y` indices lie in `[0, dims)`.
    pub dims: [u32; 2],
    /// The periodic tile (world units).
    pub tile: [f64; 2],
    /// Whether `x, y` were wrapped modulo the tile.
    pub wrapped: bool,
    /// Total volume deposited before clamping (world units³).
    pub deposited_volume: f64,
    /// Volume lost by clamping voxels whose fraction exceeded 1 (world units³).
    pub clamped_volume: f64,
    /// Line–voxel deposits made (a measure of the work).
    pub deposits: u64,
    /// Volume-weighted mean fibre radius (world units), used by the preview for extinction.
    pub mean_fibre_radius: f64,
    acc: Vec<(IVec3, BrickAcc)>,
    has_acc: bool,
}

/// Figures of a voxelisation, for `velour weave --stats` and benchmarks.
#[derive(Clone, Debug, PartialEq)]
pub struct VoxelStats {
    /// Active voxels.
    pub active_voxels: u64,
    /// Bricks.
    pub bricks: usize,
    /// `Σ density × voxel volume` over the grid (world units³).
    pub voxel_volume_sum: f64,
    /// Relative difference `voxel_volume_sum / fibre_volume − 1`.
    pub conservation_error: f64,
    /// Bytes of the grid (bricks, masks, topology).
    pub grid_bytes: usize,
    /// Grid bytes per active voxel.
    pub bytes_per_active_voxel: f64,
    /// Bytes of the kept accumulators (needed for [`VoxelisedPatch::mip`]).
    pub accumulator_bytes: usize,
}

/// Index-space layout shared by the deposit code.
#[derive(Clone, Copy, Debug)]
struct Layout {
    origin: Vec3,
    inv_h: Vec3,
    h: Vec3,
    n: IVec3,
    wrap: bool,
}

/// Voxelises `patch` with `resolution` voxels across the tile's largest side (see the module
/// docs for the channels and the index-to-world map).
///
/// # Errors
/// [`FabricError::InvalidParameter`] for `resolution` outside `1..=8192`, a non-positive or
/// non-finite tile, fibre radius or vertex; [`FabricError::TooLarge`] when the voxelisation
/// would need more than [`MAX_DEPOSITS`] deposits or [`MAX_BRICKS`] bricks.
pub fn voxelise(
    patch: &FabricPatch,
    resolution: u32,
    opts: &VoxeliseOptions,
) -> Result<VoxelisedPatch, FabricError> {
    if resolution == 0 || resolution > MAX_RESOLUTION {
        return Err(super::invalid(
            "resolution",
            resolution,
            &format!("1..={MAX_RESOLUTION} voxels across the tile's largest side"),
        ));
    }
    let tile = patch.tile;
    if !(tile.x.is_finite() && tile.y.is_finite() && tile.x > 0.0 && tile.y > 0.0) {
        return Err(super::invalid(
            "patch.tile",
            format!("{tile}"),
            "finite and > 0 in x and y",
        ));
    }
    let h = f64::from(tile.x.max(tile.y)) / f64::from(resolution);
    let nx = ((f64::from(tile.x) / h).round() as i32).max(1);
    let ny = ((f64::from(tile.y) / h).round() as i32).max(1);
    let hv = DVec3::new(
        f64::from(tile.x) / f64::from(nx),
        f64::from(tile.y) / f64::from(ny),
        h,
    );
    // Check the fibres, estimate the work.
    let mut max_r = 0.0f32;
    let mut deposits_est = 0.0f64;
    let mut zmin = f32::INFINITY;
    let mut zmax = f32::NEG_INFINITY;
    let hmin = hv.min_element();
    for (i, f) in patch.fibres.iter().enumerate() {
        let r = f.fibre.radius;
        if !(r.is_finite() && r > 0.0) {
            return Err(super::invalid(
                &format!("fibres[{i}].radius"),
                r,
                "finite and > 0",
            ));
        }
        max_r = max_r.max(r);
        let lines = cross_section_offsets(r, hmin as f32).len() as f64;
        for w in f.fibre.points.windows(2) {
            if !(w[0].is_finite() && w[1].is_finite()) {
                return Err(super::invalid(
                    &format!("fibres[{i}].points"),
                    "a non-finite vertex",
                    "finite coordinates",
                ));
            }
            let d = (w[1] - w[0]).abs().as_dvec3() / hv;
            deposits_est += lines * (1.0 + d.x + d.y + d.z);
        }
        for p in &f.fibre.points {
            zmin = zmin.min(p.z);
            zmax = zmax.max(p.z);
        }
    }
    if deposits_est > MAX_DEPOSITS as f64 {
        return Err(FabricError::TooLarge {
            name: "resolution".into(),
            what: "line-voxel deposits".into(),
            count: deposits_est as u64,
            limit: MAX_DEPOSITS,
        });
    }
    if !zmin.is_finite() {
        zmin = 0.0;
        zmax = 0.0;
    }
    let z0 = f64::from(zmin - max_r);
    let nz = (((f64::from(zmax + max_r) - z0) / h).ceil() as i64).max(1);
    let bricks = if opts.wrap {
        (i64::from(nx) / 8 + 2) * (i64::from(ny) / 8 + 2) * (nz / 8 + 2)
    } else {
        let b = patch.bounds;
        let ex = f64::from(b.max.x - b.min.x) / hv.x;
        let ey = f64::from(b.max.y - b.min.y) / hv.y;
        ((ex / 8.0) as i64 + 2) * ((ey / 8.0) as i64 + 2) * (nz / 8 + 2)
    };
    if bricks as u64 > MAX_BRICKS {
        return Err(FabricError::TooLarge {
            name: "resolution".into(),
            what: "bricks in the patch's bounding box".into(),
            count: bricks as u64,
            limit: MAX_BRICKS,
        });
    }
    let origin = DVec3::new(0.0, 0.0, z0);
    let layout = Layout {
        origin: origin.as_vec3(),
        inv_h: (DVec3::ONE / hv).as_vec3(),
        h: hv.as_vec3(),
        n: IVec3::new(nx, ny, 0),
        wrap: opts.wrap,
    };
    // Deposit, chunk by chunk, merging in chunk order.
    let mut total = AccMap::default();
    let mut deposits = 0u64;
    let group = CHUNK_FIBRES * 2 * rayon::current_num_threads().max(1);
    for fibres in patch.fibres.chunks(group) {
        let parts: Vec<(AccMap, u64)> = fibres
            .par_chunks(CHUNK_FIBRES)
            .map(|chunk| {
                let mut map = AccMap::default();
                let mut n = 0u64;
                let mut buf = Vec::new();
                for f in chunk {
                    n += deposit_fibre(&mut map, &layout, f, &mut buf);
                }
                (map, n)
            })
            .collect();
        for (map, n) in parts {
            deposits += n;
            merge(&mut total, map);
        }
    }
    let acc = total.into_sorted();
    let weighted_r: f64 = patch
        .fibres
        .iter()
        .map(|f| f.fibre.volume() * f64::from(f.fibre.radius))
        .sum();
    let mean_r = if patch.fibre_volume > 0.0 {
        weighted_r / patch.fibre_volume
    } else {
        f64::from(max_r)
    };
    let mut vp = finish(
        acc,
        0,
        hv,
        origin,
        [nx as u32, ny as u32],
        [f64::from(tile.x), f64::from(tile.y)],
        opts.wrap,
        opts.storage,
        deposits,
        mean_r,
    )?;
    if !opts.keep_accumulators {
        vp.acc = Vec::new();
        vp.has_acc = false;
    }
    Ok(vp)
}

/// Offsets (in the fibre's cross-section frame, world units) of the parallel lines that
/// represent a fibre of radius `r` in voxels of smallest edge `h`: one line when `r ≤ h/2`,
/// otherwise a square lattice of spacing `h/2` clipped to the disc.
fn cross_section_offsets(r: f32, h: f32) -> Vec<[f32; 2]> {
    if r <= 0.5 * h || !(h > 0.0) {
        return vec![[0.0, 0.0]];
    }
    let s = 0.5 * h;
    let n = (r / s).floor().min(256.0) as i32;
    let mut out = Vec::new();
    for u in -n..=n {
        for v in -n..=n {
            let (a, b) = (u as f32 * s, v as f32 * s);
            if a * a + b * b <= r * r {
                out.push([a, b]);
            }
        }
    }
    out
}

/// Deposits one fibre; returns the number of line–voxel deposits.
fn deposit_fibre(map: &mut AccMap, l: &Layout, f: &super::PatchFibre, buf: &mut Vec<f32>) -> u64 {
    let class = match f.yarn {
        YarnId::Warp(_) => 6,
        YarnId::Weft(_) => 7,
        YarnId::Pile => 8,
    };
    let r = f.fibre.radius;
    let offsets = cross_section_offsets(r, l.h.min_element());
    let share = 1.0 / offsets.len() as f32;
    let area = std::f32::consts::PI * r * r;
    let mut n = 0u64;
    for w in f.fibre.points.windows(2) {
        let d = w[1] - w[0];
        let len = d.length();
        if !(len > 0.0) {
            continue;
        }
        let t = d / len;
        let tensor = [
            t.x * t.x,
            t.x * t.y,
            t.x * t.z,
            t.y * t.y,
            t.y * t.z,
            t.z * t.z,
        ];
        let vol = area * len * share;
        let frame = (offsets.len() > 1).then(|| Frame::from_normal(t));
        for o in &offsets {
            let off = frame.map_or(Vec3::ZERO, |fr| fr.s * o[0] + fr.t * o[1]);
            let a = (w[0] + off - l.origin) * l.inv_h;
            let b = (w[1] + off - l.origin) * l.inv_h;
            n += deposit_line(map, l, a, b, vol, &tensor, class, buf);
        }
    }
    n
}

/// Deposits `vol` along the index-space segment `a → b`, split by voxel in proportion to the
/// length inside each voxel (voxel `i` covers `[i, i+1)`).
#[allow(clippy::too_many_arguments)]
fn deposit_line(
    map: &mut AccMap,
    l: &Layout,
    a: Vec3,
    b: Vec3,
    vol: f32,
    tensor: &[f32; 6],
    class: usize,
    buf: &mut Vec<f32>,
) -> u64 {
    buf.clear();
    buf.push(0.0);
    buf.push(1.0);
    let d = b - a;
    for c in 0..3 {
        if d[c] == 0.0 {
            continue;
        }
        let (lo, hi) = (a[c].min(b[c]), a[c].max(b[c]));
        let mut m = lo.floor() + 1.0;
        while m < hi {
            let s = (m - a[c]) / d[c];
            if s > 0.0 && s < 1.0 {
                buf.push(s);
            }
            m += 1.0;
        }
    }
    buf.sort_unstable_by(f32::total_cmp);
    let mut n = 0;
    for k in 0..buf.len() - 1 {
        let ds = buf[k + 1] - buf[k];
        if ds <= 0.0 {
            continue;
        }
        let mid = a + d * (0.5 * (buf[k] + buf[k + 1]));
        let mut cell = mid.floor().as_ivec3();
        if l.wrap {
            cell.x = cell.x.rem_euclid(l.n.x);
            cell.y = cell.y.rem_euclid(l.n.y);
        }
        let w = vol * ds;
        let brick = map.brick(cell >> 3);
        let o = voxel_offset(cell & 7) * ACC;
        let v = &mut brick[o..o + ACC];
        for (x, &tt) in v[..6].iter_mut().zip(tensor) {
            *x += w * tt;
        }
        v[class] += w;
        n += 1;
    }
    n
}

fn merge(total: &mut AccMap, part: AccMap) {
    for (k, b) in part.bricks {
        match total.index.get(&k) {
            Some(&i) => {
                for (x, y) in total.bricks[i as usize].1.iter_mut().zip(b.iter()) {
                    *x += *y;
                }
            }
            None => {
                total.index.insert(k, total.bricks.len() as u32);
                total.bricks.push((k, b));
            }
        }
    }
}

/// Principal eigenvector of a symmetric positive semi-definite 3×3 matrix by repeated
/// squaring (`M^(2^6)`, renormalised by the trace): the largest column of a high power of `M`
/// lies along the eigenvector of the largest eigenvalue (the other directions shrink by
/// `(λ₂/λ₁)^64`). Sign: largest component positive. Zero for a zero matrix.
fn principal_axis(s: &[f32]) -> Vec3 {
    let tr = s[0] + s[3] + s[5];
    if !(tr > 0.0) {
        return Vec3::ZERO;
    }
    let mut m = Mat3::from_cols(
        Vec3::new(s[0], s[1], s[2]),
        Vec3::new(s[1], s[3], s[4]),
        Vec3::new(s[2], s[4], s[5]),
    ) * (1.0 / tr);
    for _ in 0..6 {
        m = m * m;
        let t = m.x_axis.x + m.y_axis.y + m.z_axis.z;
        if !(t > 1e-30) {
            break;
        }
        m *= 1.0 / t;
    }
    let cols = [m.x_axis, m.y_axis, m.z_axis];
    let mut best = cols[0];
    for c in &cols[1..] {
        if c.length_squared() > best.length_squared() {
            best = *c;
        }
    }
    let v = best.normalize_or_zero();
    let a = v.abs();
    let big = if a.x >= a.y && a.x >= a.z {
        v.x
    } else if a.y >= a.z {
        v.y
    } else {
        v.z
    };
    if big < 0.0 {
        -v
    } else {
        v
    }
}

/// Builds the grid of a level from its sorted brick accumulators.
#[allow(clippy::too_many_arguments)]
fn finish(
    acc: Vec<(IVec3, BrickAcc)>,
    level: u32,
    hv: DVec3,
    origin: DVec3,
    dims: [u32; 2],
    tile: [f64; 2],
    wrap: bool,
    storage: Storage,
    deposits: u64,
    mean_fibre_radius: f64,
) -> Result<VoxelisedPatch, FabricError> {
    let voxel_volume = hv.x * hv.y * hv.z;
    let inv_vv = 1.0 / voxel_volume;
    // Per brick: density, tangent, id, mask, deposited and clamped volume.
    type Out = (Vec<f32>, Vec<f32>, Vec<f32>, [u64; 8], f64, f64);
    let outs: Vec<Out> = acc
        .par_iter()
        .map(|(_, b)| {
            let mut dens = vec![0.0f32; BRICK_VOXELS];
            let mut tan = vec![0.0f32; BRICK_VOXELS * 3];
            let mut id = vec![0.0f32; BRICK_VOXELS];
            let mut mask = [0u64; 8];
            let (mut dep, mut clamped) = (0.0f64, 0.0f64);
            for v in 0..BRICK_VOXELS {
                let s = &b[v * ACC..(v + 1) * ACC];
                let vol = f64::from(s[6]) + f64::from(s[7]) + f64::from(s[8]);
                if !(vol > 0.0) {
                    continue;
                }
                mask[v >> 6] |= 1 << (v & 63);
                dep += vol;
                let frac = vol * inv_vv;
                if frac > 1.0 {
                    clamped += (frac - 1.0) * voxel_volume;
                }
                dens[v] = frac.min(1.0) as f32;
                let t = principal_axis(&s[..6]);
                tan[v * 3..v * 3 + 3].copy_from_slice(&t.to_array());
                let mut best = 0;
                for c in 1..3 {
                    if s[6 + c] > s[6 + best] {
                        best = c;
                    }
                }
                id[v] = best as f32;
            }
            (dens, tan, id, mask, dep, clamped)
        })
        .collect();
    let grid_err = |e: crate::grid::GridError| FabricError::TooLarge {
        name: "resolution".into(),
        what: format!("grid storage ({e})"),
        count: acc.len() as u64,
        limit: MAX_BRICKS,
    };
    let mut gb = SparseGridBuilder::new(storage);
    gb.add_channel("density", ChannelKind::Scalar, Vec3::ZERO);
    gb.add_channel("tangent", ChannelKind::Vec3, Vec3::ZERO);
    gb.add_channel("id", ChannelKind::Scalar, Vec3::ZERO);
    let m = DAffine3::from_scale_rotation_translation(hv, glam::DQuat::IDENTITY, origin + 0.5 * hv);
    gb.set_index_to_world(m)
        .map_err(|e| super::invalid("voxel size", format!("{hv} ({e})"), "finite and > 0"))?;
    let (mut dep, mut clamped) = (0.0, 0.0);
    for ((key, _), (dens, tan, id, mask, d, c)) in acc.iter().zip(&outs) {
        dep += d;
        clamped += c;
        gb.fill_brick(DENSITY, *key, dens, *mask)
            .map_err(grid_err)?;
        gb.fill_brick(TANGENT, *key, tan, *mask).map_err(grid_err)?;
        gb.fill_brick(ID, *key, id, *mask).map_err(grid_err)?;
    }
    Ok(VoxelisedPatch {
        grid: gb.build(),
        level,
        voxel_size: hv,
        origin,
        dims,
        tile,
        wrapped: wrap,
        deposited_volume: dep,
        clamped_volume: clamped,
        deposits,
        mean_fibre_radius,
        acc,
        has_acc: true,
    })
}

impl VoxelisedPatch {
    /// Volume of one voxel (world units³).
    #[must_use]
    pub fn voxel_volume(&self) -> f64 {
        self.voxel_size.x * self.voxel_size.y * self.voxel_size.z
    }

    /// `Σ density × voxel volume` over the active voxels of the grid (world units³): the fibre
    /// volume the grid represents.
    #[must_use]
    pub fn volume(&self) -> f64 {
        GridStats::compute(&self.grid, DENSITY).sum[0] * self.voxel_volume()
    }

    /// Figures of this voxelisation against the analytic `fibre_volume` of its patch.
    #[must_use]
    pub fn stats(&self, fibre_volume: f64) -> VoxelStats {
        let mem = self.grid.memory_report();
        let vol = self.volume();
        VoxelStats {
            active_voxels: mem.active_voxels,
            bricks: self.grid.brick_count(),
            voxel_volume_sum: vol,
            conservation_error: if fibre_volume > 0.0 {
                vol / fibre_volume - 1.0
            } else {
                0.0
            },
            grid_bytes: mem.total_bytes,
            bytes_per_active_voxel: mem.total_bytes as f64 / mem.active_voxels.max(1) as f64,
            accumulator_bytes: self.acc.len() * BRICK_VOXELS * ACC * 4,
        }
    }

    /// The patch `levels` mip levels coarser (voxels `2^levels` times larger on each axis,
    /// same origin; `levels = 0` gives a copy). Density is the average of the fine voxels
    /// (so the volume is conserved, up to clamping), the tangent is the principal axis of the
    /// summed structure tensors, the id the family with the most summed volume. When the
    /// tile's voxel count is not a multiple of `2^levels`, the last coarse column covers
    /// space beyond the tile (the wrap is then not exact at this level).
    ///
    /// # Errors
    /// [`FabricError::InvalidParameter`] for `levels > 12`, or for a patch voxelised without
    /// [`VoxeliseOptions::keep_accumulators`].
    pub fn mip(&self, levels: u32) -> Result<VoxelisedPatch, FabricError> {
        if levels > 12 {
            return Err(super::invalid("mip level", levels, "0..=12"));
        }
        if !self.has_acc {
            return Err(super::invalid(
                "keep_accumulators",
                false,
                "true to build mip levels",
            ));
        }
        let mut map = AccMap::default();
        for (key, b) in &self.acc {
            let base = *key << 3;
            for v in 0..BRICK_VOXELS {
                let s = &b[v * ACC..(v + 1) * ACC];
                if s[6] == 0.0 && s[7] == 0.0 && s[8] == 0.0 {
                    continue;
                }
                let vi = v as i32;
                let cell = (base + IVec3::new(vi >> 6, (vi >> 3) & 7, vi & 7)) >> levels as i32;
                let dst = map.brick(cell >> 3);
                let o = voxel_offset(cell & 7) * ACC;
                for (x, y) in dst[o..o + ACC].iter_mut().zip(s) {
                    *x += *y;
                }
            }
        }
        let acc = map.into_sorted();
        let f = f64::from(1u32 << levels);
        let div = |n: u32| n.div_ceil(1 << levels);
        finish(
            acc,
            self.level + levels,
            self.voxel_size * f,
            self.origin,
            [div(self.dims[0]), div(self.dims[1])],
            self.tile,
            self.wrapped,
            self.grid.storage(),
            self.deposits,
            self.mean_fibre_radius,
        )
    }

    /// A patch from stored channels (a weave patch file read back): `grid` holds the
    /// [`DENSITY`], [`TANGENT`] and [`ID`] channels of mip level `level`, whose tile is `tile`
    /// (world units) covered by `dims` voxels along `x` and `y` at that level. The voxel size
    /// and origin come from the grid's index-to-world map; `x` and `y` wrap.
    ///
    /// The accumulators that [`VoxelisedPatch::mip`] sums are rebuilt from the channels: each
    /// voxel's volume (density × voxel volume) with the structure tensor `t tᵀ` of its stored
    /// tangent, all of it in the family of its stored id. Coarser levels built from them
    /// have the same densities as levels built while voxelising (volume is summed either way);
    /// their tangents and ids can differ where one coarse voxel gathers fine voxels whose
    /// fibres cross or whose families mix (the fine tensors' anisotropy and minority families
    /// are not stored).
    ///
    /// # Errors
    /// [`FabricError::InvalidParameter`] when the grid lacks one of the three channels (or has
    /// them with the wrong kind), or for a non-finite or non-positive voxel size.
    pub fn from_channels(
        grid: SparseGrid,
        level: u32,
        dims: [u32; 2],
        tile: [f64; 2],
    ) -> Result<VoxelisedPatch, FabricError> {
        let kinds = [
            (DENSITY, ChannelKind::Scalar, "density"),
            (TANGENT, ChannelKind::Vec3, "tangent"),
            (ID, ChannelKind::Scalar, "id"),
        ];
        for (c, kind, name) in kinds {
            if grid.channel_kind(c) != Some(kind) {
                return Err(super::invalid(
                    "patch channels",
                    name,
                    "density (scalar), tangent (vec3) and id (scalar) channels",
                ));
            }
        }
        let hv = grid.voxel_size();
        if !(hv.is_finite() && hv.min_element() > 0.0) {
            return Err(super::invalid("voxel size", hv, "finite and > 0"));
        }
        let origin = grid.index_to_world().translation - 0.5 * hv;
        let voxel_volume = (hv.x * hv.y * hv.z) as f32;
        let mut acc: Vec<(IVec3, BrickAcc)> = Vec::with_capacity(grid.brick_count());
        let mut deposited = 0.0f64;
        for b in 0..grid.brick_count() {
            let dens = grid.brick_data(DENSITY, b);
            let tan = grid.brick_data(TANGENT, b);
            let id = grid.brick_data(ID, b);
            let mask = grid.brick_active_mask(b);
            let mut a = new_brick();
            for v in 0..BRICK_VOXELS {
                if mask[v >> 6] & (1 << (v & 63)) == 0 {
                    continue;
                }
                let d = dens.get(v, 1, 0);
                if !(d > 0.0) || !d.is_finite() {
                    continue;
                }
                let vol = d * voxel_volume;
                deposited += f64::from(vol);
                let t = Vec3::new(tan.get(v, 3, 0), tan.get(v, 3, 1), tan.get(v, 3, 2))
                    .normalize_or_zero();
                let s = &mut a[v * ACC..(v + 1) * ACC];
                s[0] = vol * t.x * t.x;
                s[1] = vol * t.x * t.y;
                s[2] = vol * t.x * t.z;
                s[3] = vol * t.y * t.y;
                s[4] = vol * t.y * t.z;
                s[5] = vol * t.z * t.z;
                let family = id.get(v, 1, 0).round().clamp(0.0, 2.0) as usize;
                s[6 + family] = vol;
            }
            acc.push((grid.brick_origin(b) >> 3, a));
        }
        acc.sort_unstable_by_key(|(k, _)| (k.x, k.y, k.z));
        Ok(VoxelisedPatch {
            grid,
            level,
            voxel_size: hv,
            origin,
            dims,
            tile,
            wrapped: true,
            deposited_volume: deposited,
            clamped_volume: 0.0,
            deposits: 0,
            mean_fibre_radius: 0.0,
            acc,
            has_acc: true,
        })
    }

    /// The world-space point of index-space point `p` wrapped into the tile (`x, y`).
    fn wrap_index(&self, p: Vec3) -> Vec3 {
        if !self.wrapped {
            return p;
        }
        let n = Vec3::new(self.dims[0] as f32, self.dims[1] as f32, 1.0);
        Vec3::new(p.x.rem_euclid(n.x), p.y.rem_euclid(n.y), p.z)
    }
}

/// Writes the channels of one or more levels of a voxelised patch to an OpenVDB file:
/// level 0 (the first patch) as `density` (class `fog volume`), `tangent` (vec3s) and `id`;
/// every other patch as `density_mip{l}`, `tangent_mip{l}` and `id_mip{l}` with `l` its
/// [`VoxelisedPatch::level`]. `half` saves the density grids as 16-bit halves. Blosc
/// compression, as OpenVDB writes by default.
///
/// # Errors
/// [`FabricError::InvalidParameter`] for an empty list; [`FabricError::Io`] when the file
/// cannot be written.
pub fn write_patch_vdb(
    path: &Path,
    levels: &[&VoxelisedPatch],
    half: bool,
) -> Result<(), FabricError> {
    write_patch_vdb_with_metadata(path, levels, half, &[])
}

/// [`write_patch_vdb`] with file-level metadata (the generator parameters `velour weave`
/// records, [`super::patch_file::WeaveRecord`]).
///
/// # Errors
/// As [`write_patch_vdb`].
pub fn write_patch_vdb_with_metadata(
    path: &Path,
    levels: &[&VoxelisedPatch],
    half: bool,
    file_metadata: &[MetaEntry],
) -> Result<(), FabricError> {
    if levels.is_empty() {
        return Err(super::invalid(
            "levels",
            "[]",
            "at least one voxelised patch",
        ));
    }
    let mut names = Vec::new();
    for (i, p) in levels.iter().enumerate() {
        let suffix = if i == 0 {
            String::new()
        } else {
            format!("_mip{}", p.level)
        };
        names.push([
            format!("density{suffix}"),
            format!("tangent{suffix}"),
            format!("id{suffix}"),
        ]);
    }
    let id_meta = [MetaEntry::string(
        "velour_id_legend",
        "0 warp, 1 weft, 2 pile",
    )];
    let tan_meta = [MetaEntry::string(
        "velour_tangent",
        "principal axis of the fibre structure tensor (sign-agnostic)",
    )];
    let mut grids = Vec::new();
    for (p, n) in levels.iter().zip(&names) {
        grids.push(GridToWrite {
            class: "fog volume",
            channel: DENSITY,
            half,
            ..GridToWrite::new(&n[0], &p.grid)
        });
        grids.push(GridToWrite {
            channel: TANGENT,
            metadata: &tan_meta,
            ..GridToWrite::new(&n[1], &p.grid)
        });
        grids.push(GridToWrite {
            channel: ID,
            metadata: &id_meta,
            ..GridToWrite::new(&n[2], &p.grid)
        });
    }
    let opts = WriteOptions {
        compression: Compression::Blosc,
        active_mask: true,
    };
    write_vdb_with_metadata(path, &grids, &opts, file_metadata).map_err(|e| FabricError::Io {
        what: format!("OpenVDB file {}", path.display()),
        reason: e.to_string(),
    })
}

// ---------------------------------------------------------------------------------------
// Preview: a stand-alone single-scattering ray marcher.

/// Options of [`render_preview`].
#[derive(Clone, Debug, PartialEq)]
pub struct PreviewOptions {
    /// Image width and height in pixels (`16..=4096`).
    pub size: u32,
    /// Tiles shown across the image (`1..=16`); the grid wraps, so the swatch is seamless.
    pub tiles: u32,
    /// Direction *towards* the light (normalised internally).
    pub light_dir: Vec3,
    /// Irradiance of the directional light (RGB).
    pub light: Rgb,
    /// Direction from the swatch *towards* the viewer (normalised internally).
    pub view_dir: Vec3,
    /// Background colour (linear RGB).
    pub background: Rgb,
    /// Constant ambient radiance added to scattered light, `A·(1 − T)·albedo`-style, so that
    /// shadowed fibres are not black; 0 disables it.
    pub ambient: f32,
    /// Fibre scattering parameters (coloured per yarn family from the patch's albedos).
    pub phase: FibrePhaseParams,
    /// Ray-marching step in voxels (`(0, 4]`).
    pub step: f32,
}

impl Default for PreviewOptions {
    fn default() -> Self {
        PreviewOptions {
            size: 512,
            tiles: 2,
            light_dir: Vec3::new(-0.4, -0.6, 1.0),
            light: Rgb::splat(3.0),
            view_dir: Vec3::new(0.0, -0.5, 1.0),
            background: Rgb::new(0.05, 0.05, 0.06),
            ambient: 0.15,
            phase: FibrePhaseParams {
                h_nodes: 16,
                ..FibrePhaseParams::default()
            },
            step: 1.0,
        }
    }
}

/// A rendered preview: linear RGB pixels, row-major from the top.
#[derive(Clone, Debug)]
pub struct PreviewImage {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Linear RGB, `width × height`, row-major, top row first.
    pub pixels: Vec<Rgb>,
}

impl PreviewImage {
    /// Writes the image as an 8-bit sRGB PNG.
    ///
    /// # Errors
    /// [`FabricError::Io`] when the file cannot be written.
    pub fn write_png(&self, path: &Path) -> Result<(), FabricError> {
        let enc = |x: f32| {
            let x = x.clamp(0.0, 1.0);
            let s = if x <= 0.003_130_8 {
                12.92 * x
            } else {
                1.055 * x.powf(1.0 / 2.4) - 0.055
            };
            (s * 255.0 + 0.5) as u8
        };
        let mut buf = Vec::with_capacity(self.pixels.len() * 3);
        for p in &self.pixels {
            buf.extend_from_slice(&[enc(p[0]), enc(p[1]), enc(p[2])]);
        }
        image::save_buffer(
            path,
            &buf,
            self.width,
            self.height,
            image::ExtendedColorType::Rgb8,
        )
        .map_err(|e| FabricError::Io {
            what: format!("preview PNG {}", path.display()),
            reason: e.to_string(),
        })
    }
}

/// Phase values tabulated over tangent directions (the light and view are fixed, so the
/// single-scattering phase depends only on the tangent and the yarn family).
struct PhaseTable {
    n_theta: usize,
    n_phi: usize,
    values: Vec<Rgb>,
}

impl PhaseTable {
    fn new(shading: &FabricShading, wo: Vec3, wi: Vec3) -> PhaseTable {
        let (n_theta, n_phi) = (32, 64);
        let ids = [YarnId::Warp(0), YarnId::Weft(0), YarnId::Pile];
        let values = (0..3 * n_theta * n_phi)
            .into_par_iter()
            .map(|k| {
                let id = k / (n_theta * n_phi);
                let r = k % (n_theta * n_phi);
                let t = Self::dir((r / n_phi) as f32, (r % n_phi) as f32, n_theta, n_phi);
                shading.for_yarn(ids[id]).eval(wo, wi, t)
            })
            .collect();
        PhaseTable {
            n_theta,
            n_phi,
            values,
        }
    }
    /// Centre of bin `(i, j)` on the upper hemisphere (tangents are sign-agnostic).
    fn dir(i: f32, j: f32, n_theta: usize, n_phi: usize) -> Vec3 {
        let ct = (i + 0.5) / n_theta as f32;
        let st = (1.0 - ct * ct).max(0.0).sqrt();
        let phi = (j + 0.5) / n_phi as f32 * std::f32::consts::TAU;
        Vec3::new(st * phi.cos(), st * phi.sin(), ct)
    }
    fn lookup(&self, id: usize, t: Vec3) -> Rgb {
        let t = if t.z < 0.0 { -t } else { t };
        let i = ((t.z * self.n_theta as f32) as usize).min(self.n_theta - 1);
        let phi = t.y.atan2(t.x).rem_euclid(std::f32::consts::TAU);
        let j = ((phi / std::f32::consts::TAU * self.n_phi as f32) as usize).min(self.n_phi - 1);
        self.values[(id.min(2) * self.n_theta + i) * self.n_phi + j]
    }
}

/// Renders a lit swatch of a voxelised patch: an orthographic view of `tiles × tiles` tiles
/// lit by one directional light, by ray marching the density grid with **single scattering
/// only** (no multiple scattering), the fibre phase function ([`super::FibrePhase`]) around
/// the voxel tangent, warp/weft/pile colours from the patch's albedos, and the
/// direction-dependent fibre extinction `σ_t(ω) = density · 2/(π r) · sin∠(ω, t)`
/// (`λ D sin∠(ω, t)` with `λ = density/(π r²)` fibre length per volume and `D = 2r`). A
/// constant ambient term `ambient · albedo · (1 − T)` stands in for multiple scattering and
/// sky light. This is a stand-alone preview, not the production integrator.
///
/// # Errors
/// [`FabricError::InvalidParameter`] for options outside their ranges or phase parameters
/// that [`super::FibrePhase::new`] rejects.
pub fn render_preview(
    vp: &VoxelisedPatch,
    patch_albedos: [Rgb; 3],
    opts: &PreviewOptions,
) -> Result<PreviewImage, FabricError> {
    if !(16..=4096).contains(&opts.size) {
        return Err(super::invalid("preview size", opts.size, "16..=4096"));
    }
    if !(1..=16).contains(&opts.tiles) {
        return Err(super::invalid("preview tiles", opts.tiles, "1..=16"));
    }
    super::check_range("preview step", opts.step, 0.01, 4.0)?;
    let wl = opts.light_dir.normalize_or_zero();
    let wv = opts.view_dir.normalize_or_zero();
    if wl.z <= 0.0 || wv.z <= 0.0 {
        return Err(super::invalid(
            "preview light/view direction",
            format!("{wl} / {wv}"),
            "directions with z > 0 (above the cloth)",
        ));
    }
    let mk = |c: Rgb| {
        super::FibrePhase::new(
            opts.phase
                .clone()
                .with_colour(c.map(|x| x.clamp(1e-3, 1.0))),
        )
    };
    let shading = FabricShading {
        warp: mk(patch_albedos[0])?,
        weft: mk(patch_albedos[1])?,
        pile: mk(patch_albedos[2])?,
    };
    // wo points towards the viewer, wi towards the light (both away from the point).
    let table = PhaseTable::new(&shading, wv, wl);
    let g = &vp.grid;
    let h = vp.voxel_size.as_vec3();
    let r = vp.mean_fibre_radius as f32;
    let sigma_scale = 2.0 / (std::f32::consts::PI * r.max(1e-12));
    let (lo, hi) = match g.active_bbox() {
        Some(b) => b,
        None => {
            return Ok(PreviewImage {
                width: opts.size,
                height: opts.size,
                pixels: vec![opts.background; (opts.size * opts.size) as usize],
            })
        }
    };
    // Index-space slab of the cloth (with a voxel of margin).
    let z_lo = lo.z as f32 - 1.0;
    let z_hi = hi.z as f32 + 1.0;
    let to_index = |p: Vec3| (p - vp.origin.as_vec3()) / h - Vec3::splat(0.5);
    let tile = Vec3::new(vp.tile[0] as f32, vp.tile[1] as f32, 0.0);
    let extent = tile * opts.tiles as f32;
    // Orthographic camera: looks along −wv; image plane spanned by u (horizontal) and v.
    let up0 = if wv.z.abs() > 0.999 { Vec3::Y } else { Vec3::Z };
    let cam_u = up0.cross(wv).normalize();
    let cam_v = wv.cross(cam_u);
    let centre = Vec3::new(extent.x * 0.5, extent.y * 0.5, vp.origin.z as f32);
    // Image half-size: the projection of the swatch onto the image plane.
    let mut half_u = 0.0f32;
    let mut half_v = 0.0f32;
    for cx in [-0.5f32, 0.5] {
        for cy in [-0.5f32, 0.5] {
            let c = Vec3::new(cx * extent.x, cy * extent.y, 0.0);
            half_u = half_u.max(c.dot(cam_u).abs());
            half_v = half_v.max(c.dot(cam_v).abs());
        }
    }
    let half = half_u.max(half_v);
    let step = opts.step;
    let size = opts.size;
    let pixels: Vec<Rgb> = (0..size * size)
        .into_par_iter()
        .map(|pix| {
            let (px, py) = (pix % size, pix / size);
            let su = ((px as f32 + 0.5) / size as f32 * 2.0 - 1.0) * half;
            let sv = (1.0 - (py as f32 + 0.5) / size as f32 * 2.0) * half;
            let on_plane = centre + cam_u * su + cam_v * sv;
            // March along −wv (in index space) between the slab planes.
            let p0 = to_index(on_plane);
            let dir = -wv / h; // index units per world unit
            let t_top = (z_hi - p0.z) / dir.z;
            let t_bot = (z_lo - p0.z) / dir.z;
            let (t0, t1) = (t_top.min(t_bot), t_top.max(t_bot));
            let world_step = step * h.min_element();
            let mut acc = g.accessor(DENSITY);
            let mut tacc = g.accessor(TANGENT);
            let mut iacc = g.accessor(ID);
            let mut tr = 1.0f32;
            let mut radiance = Rgb::ZERO;
            let mut t = t0 + 0.5 * world_step;
            while t < t1 && tr > 1e-3 {
                let p = p0 + dir * t;
                // Footprint of the swatch only.
                let world = vp.origin.as_vec3() + (p + Vec3::splat(0.5)) * h;
                if world.x >= 0.0 && world.y >= 0.0 && world.x < extent.x && world.y < extent.y {
                    let q = vp.wrap_index(p).round().as_ivec3();
                    let d = acc.value(q);
                    if d > 0.0 {
                        let tan = tacc.value_vec3(q);
                        let id = iacc.value(q).round().max(0.0) as usize;
                        let st = d * sigma_scale * extinction_scale(wv, tan);
                        let albedo = patch_albedos[id.min(2)];
                        // Shadow ray towards the light.
                        let tl = light_transmittance(vp, p, wl, z_hi, world_step, sigma_scale);
                        let ph = table.lookup(id, tan);
                        let a = 1.0 - (-st * world_step).exp();
                        let li = ph * (opts.light * tl) + albedo * opts.ambient;
                        // Scattering per unit length ≈ σ_t(wo) (albedo is in the phase).
                        radiance += li * (tr * a);
                        tr *= 1.0 - a;
                    }
                }
                t += world_step;
            }
            radiance + opts.background * tr
        })
        .collect();
    Ok(PreviewImage {
        width: size,
        height: size,
        pixels,
    })
}

/// Transmittance from index-space point `p` towards the light (direction `wl`, world) up to
/// the top of the slab.
fn light_transmittance(
    vp: &VoxelisedPatch,
    p: Vec3,
    wl: Vec3,
    z_hi: f32,
    world_step: f32,
    sigma_scale: f32,
) -> f32 {
    let h = vp.voxel_size.as_vec3();
    let dir = wl / h;
    let t_end = (z_hi - p.z) / dir.z;
    let step = 2.0 * world_step;
    let mut acc = vp.grid.accessor(DENSITY);
    let mut tacc = vp.grid.accessor(TANGENT);
    let mut tau = 0.0f32;
    let mut t = step;
    while t < t_end && tau < 8.0 {
        let q = vp.wrap_index(p + dir * t).round().as_ivec3();
        let d = acc.value(q);
        if d > 0.0 {
            tau += d * sigma_scale * extinction_scale(wl, tacc.value_vec3(q)) * step;
        }
        t += step;
    }
    (-tau).exp()
}
