//! Local bounds (`tracking = { local_bounds = true }`; docs/references.md §4.10): tentative
//! collisions of coarse segments are decided against per-point bounds from a table over the
//! grid's dual lattice before the density is looked up.
//!
//! - the table is conservative: no trilinear lookup anywhere exceeds its cell's bounds, and
//!   with one-voxel cells the bounds are exactly the corner voxels' range;
//! - the trackers stay unbiased: escape and scattering weights of delta and decomposition
//!   tracking, and ratio / residual ratio transmittance (`tracking::transmittance_local`, which
//!   the media do not use), against closed forms on a chromatic ramp (also with violated point
//!   bounds), and media with local bounds against the same media without (z-tests of the
//!   difference, tolerance from the estimators' variance);
//! - on a dense fBm grid (σ_t = 40 per unit density over a unit cube, as the peer cloud) free
//!   flights need at most 2 lookups per real collision at 32³ and 64³ voxels of the same field;
//! - a `voxel` interior loaded without a `tracking` table uses them when its extinction is grey
//!   (at most 2 lookups per real collision), not when it is chromatic.

// `!(coarse < hi)` is the crate's NaN-rejecting idiom (src/lib.rs): true for NaN, here the
// value left when the probe never reads a block maximum.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

mod common;

use common::stats::{assert_rgb_agrees, difference_z_score, estimate_rgb, Estimate};
use glam::{DAffine3, DVec3, IVec3, Vec3};
use velour::grid::{ChannelKind, SparseGrid, SparseGridBuilder, Storage, BRICK_DIM};
use velour::majorant::{Bounds, LocalBounds, MajorantPyramid, MajorantSegment};
use velour::math::Ray;
use velour::medium::{DensityField, GridLookup, HeterogeneousMedium, LocalProbe, Medium};
use velour::phase::PhaseFunction;
use velour::sampling::{sample_uniform_sphere, Rng};
use velour::spectrum::Rgb;
use velour::tracking::{
    decomposition_track_local, delta_track_local, transmittance_local, ControlVariate,
    DensityCoefficients, Flight, FreeFlightMethod, PointBounds, Probe, TrackingConfig,
    TrackingStats, TransmittanceMode,
};

// ---------------------------------------------------------------------------------------------
// A small fBm cloud (value noise, clamped, with empty holes and saturated cores, like
// tools/peers/make_fbm_cloud.py) sampled at the voxel centres of an n³ grid over the unit cube.

fn hash(x: i32, y: i32, z: i32, seed: u32) -> f64 {
    let mut h = (x as u32).wrapping_mul(0x8DA6_B343)
        ^ (y as u32).wrapping_mul(0xD816_3841)
        ^ (z as u32).wrapping_mul(0xCB1A_B31F)
        ^ seed;
    h ^= h >> 16;
    h = h.wrapping_mul(0x7FEB_352D);
    h ^= h >> 15;
    h = h.wrapping_mul(0x846C_A68B);
    h ^= h >> 16;
    f64::from(h & 0xFF_FFFF) / f64::from(1u32 << 24)
}

fn value_noise(p: DVec3, seed: u32) -> f64 {
    let f = p.floor();
    let t = p - f;
    let w = t * t * t * (t * (t * 6.0 - 15.0) + 10.0);
    let i = f.as_ivec3();
    let mut out = 0.0;
    for k in 0..8 {
        let (dx, dy, dz) = (k & 1, (k >> 1) & 1, (k >> 2) & 1);
        let v = hash(i.x + dx, i.y + dy, i.z + dz, seed);
        let wx = if dx == 1 { w.x } else { 1.0 - w.x };
        let wy = if dy == 1 { w.y } else { 1.0 - w.y };
        let wz = if dz == 1 { w.z } else { 1.0 - w.z };
        out += wx * wy * wz * v;
    }
    out
}

fn fbm_cloud(p: DVec3) -> f32 {
    let q = (p - 0.5) * 3.2 + DVec3::new(17.3, 5.1, 9.7);
    let (mut total, mut amp, mut norm, mut freq) = (0.0, 1.0, 0.0, 1.0);
    for o in 0..4 {
        total += amp * value_noise(q * freq, 1 + 101 * o);
        norm += amp;
        amp *= 0.5;
        freq *= 2.0;
    }
    let n = total / norm;
    let r = (p - 0.5).length() / 0.5;
    let s = ((0.92 - r) / 0.25).clamp(0.0, 1.0);
    let s = s * s * (3.0 - 2.0 * s);
    ((4.0 * (n - 0.5) + 1.4 * (1.0 - r) - 0.3).clamp(0.0, 1.0) * s) as f32
}

fn grid(n: i32, field: impl Fn(DVec3) -> f32) -> SparseGrid {
    let mut b = SparseGridBuilder::new(Storage::F32);
    let c = b.add_channel("density", ChannelKind::Scalar, Vec3::ZERO);
    let voxel = 1.0 / f64::from(n);
    b.set_index_to_world(
        DAffine3::from_translation(DVec3::splat(0.5 * voxel))
            * DAffine3::from_scale(DVec3::splat(voxel)),
    )
    .unwrap_or_else(|e| panic!("{e}"));
    let bricks = n / BRICK_DIM;
    for bz in 0..bricks {
        for by in 0..bricks {
            for bx in 0..bricks {
                let key = IVec3::new(bx, by, bz);
                let mut values = vec![0.0f32; 512];
                let mut any = false;
                for x in 0..BRICK_DIM {
                    for y in 0..BRICK_DIM {
                        for z in 0..BRICK_DIM {
                            let ijk = key * BRICK_DIM + IVec3::new(x, y, z);
                            let v = field((ijk.as_dvec3() + 0.5) * voxel);
                            any |= v != 0.0;
                            values[((x << 6) | (y << 3) | z) as usize] = v;
                        }
                    }
                }
                if any {
                    b.fill_brick(c, key, &values, [u64::MAX; 8])
                        .unwrap_or_else(|e| panic!("{e}"));
                }
            }
        }
    }
    b.build()
}

/// A heterogeneous medium over `g` with the given estimators (local bounds attached when the
/// configuration asks for them).
fn medium(g: SparseGrid, coeff: DensityCoefficients, tracking: TrackingConfig) -> Medium {
    let pyramid = MajorantPyramid::from_grid(&g, 0).unwrap_or_else(|e| panic!("{e}"));
    let mut m = HeterogeneousMedium {
        field: DensityField::Grid {
            grid: g,
            channel: 0,
        },
        pyramid,
        coefficients: coeff,
        phase: PhaseFunction::HenyeyGreenstein { g: 0.0 },
        tracking,
        fabric: None,
        mips: None,
    };
    m.attach_local_bounds().unwrap_or_else(|e| panic!("{e}"));
    Medium::Heterogeneous(Box::new(m))
}

fn config(free_flight: FreeFlightMethod, local_bounds: bool) -> TrackingConfig {
    TrackingConfig {
        free_flight,
        local_bounds,
        ..TrackingConfig::default()
    }
}

/// A random ray through the unit cube, starting outside it.
fn random_ray(rng: &mut Rng) -> Ray {
    let d = sample_uniform_sphere(rng.next_2d());
    let o = Vec3::splat(0.5) - d * 1.0 + sample_uniform_sphere(rng.next_2d()) * 0.25;
    Ray::new(o, d)
}

// ---------------------------------------------------------------------------------------------
// The table.

#[test]
fn local_bounds_are_conservative_and_exact_at_one_voxel() {
    let g = grid(32, fbm_cloud);
    let table = LocalBounds::from_grid(&g, 0).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(
        table.cell_voxels(),
        1,
        "a 32³ grid fits with one-voxel cells"
    );
    let mut acc = g.accessor(0);
    let mut rng = Rng::new(5, 1);
    let (mut checked, mut slack_sum, mut nonzero) = (0u32, 0.0f64, 0u32);
    for _ in 0..200_000 {
        let p = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 36.0 - 2.0;
        let v = acc.sample_trilinear(p);
        let (lo, hi) = table.at(p);
        assert!(
            v >= lo && v <= hi,
            "lookup {v} at {p:?} outside its local bounds [{lo}, {hi}]"
        );
        // One-voxel dual cells: the bounds are the 8 corner voxels' range, up to the 16-bit
        // codes' rounding.
        let i = p.floor().as_ivec3();
        let (mut mn, mut mx) = (f32::INFINITY, f32::NEG_INFINITY);
        for k in 0..8 {
            let c = acc.value(i + IVec3::new(k & 1, (k >> 1) & 1, (k >> 2) & 1));
            mn = mn.min(c);
            mx = mx.max(c);
        }
        assert!(lo <= mn && hi >= mx, "[{lo}, {hi}] misses [{mn}, {mx}]");
        assert!(
            mn - lo <= 2.0 / 65535.0 && hi - mx <= 2.0 / 65535.0,
            "[{lo}, {hi}] looser than the corners [{mn}, {mx}]"
        );
        if hi > 0.0 {
            nonzero += 1;
            slack_sum += f64::from(hi - v);
        }
        checked += 1;
    }
    assert!(
        checked > 0 && nonzero > 10_000,
        "{nonzero} samples in the cloud"
    );
    eprintln!(
        "mean local majorant excess over {nonzero} lookups: {:.4}",
        slack_sum / f64::from(nonzero)
    );
}

#[test]
fn large_grids_get_coarser_cells_within_the_cell_budget() {
    let g = grid(128, fbm_cloud);
    let table = LocalBounds::from_grid(&g, 0).unwrap_or_else(|e| panic!("{e}"));
    assert!(table.cell_count() <= velour::majorant::MAX_LOCAL_CELLS);
    assert_eq!(
        table.cell_voxels(),
        2,
        "129³ one-voxel cells exceed the budget"
    );
    let mut acc = g.accessor(0);
    let mut rng = Rng::new(6, 1);
    for _ in 0..100_000 {
        let p = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 130.0 - 1.0;
        let v = acc.sample_trilinear(p);
        let (lo, hi) = table.at(p);
        assert!(v >= lo && v <= hi, "{v} at {p:?} outside [{lo}, {hi}]");
    }
}

/// Point bounds that read every cell: `probe` is the trait's default, without the table's
/// block maxima.
struct CellsOnly<P>(P);

impl<P: PointBounds> PointBounds for CellsOnly<P> {
    fn at(&mut self, t: f32) -> Option<(f32, f32)> {
        self.0.at(t)
    }
    fn proven_minorant(&self) -> bool {
        self.0.proven_minorant()
    }
}

/// Counts the tentative collisions the wrapped bounds' coarse level decided.
struct Counting<'a, P>(P, &'a mut u64);

impl<P: PointBounds> PointBounds for Counting<'_, P> {
    fn at(&mut self, t: f32) -> Option<(f32, f32)> {
        self.0.at(t)
    }
    fn probe(&mut self, t: f32, skip: impl FnOnce(f32) -> bool) -> Probe {
        let p = self.0.probe(t, skip);
        *self.1 += u64::from(p == Probe::Skipped);
        p
    }
    fn proven_minorant(&self) -> bool {
        self.0.proven_minorant()
    }
}

/// The table's block maxima (`LocalBounds::probe`) bound every cell of their block, and delta
/// tracking that skips cell reads where its block's maximum already rejects a tentative
/// collision takes the same flights, bit for bit, as the tracker reading every cell, while
/// most rejections on the dense cloud need no cell read.
#[test]
fn block_maxima_skip_cell_reads_without_changing_flights() {
    let g = grid(128, fbm_cloud);
    let table = LocalBounds::from_grid(&g, 0).unwrap_or_else(|e| panic!("{e}"));
    let mut rng = Rng::new(7, 1);
    for _ in 0..100_000 {
        let p = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 130.0 - 1.0;
        let (lo, hi) = table.at(p);
        let mut coarse = f32::NAN;
        let skip_at = rng.next_f32();
        let probed = table.probe(p, |ub| {
            coarse = ub;
            ub <= skip_at
        });
        assert!(
            !(coarse < hi),
            "block maximum {coarse} below the cell's {hi} at {p:?}"
        );
        match probed {
            Some(b) => assert_eq!(b, (lo, hi)),
            None => assert!(coarse <= skip_at),
        }
    }
    let coeff = DensityCoefficients::new(Rgb::splat(40.0), Rgb::splat(36.0));
    let (mut with, mut without) = (TrackingStats::default(), TrackingStats::default());
    let mut skipped = 0u64;
    let seg = MajorantSegment::new(
        0.0,
        2.5,
        Bounds {
            min: 0.0,
            max: 1.0,
            mean: 0.2,
        },
        true,
    );
    for i in 0..4_000u64 {
        let ray = random_ray(&mut rng);
        let mut run = |cells_only: bool, stats: &mut TrackingStats| -> Flight {
            let mut lookup = GridLookup::new(&g, 0, &ray);
            let probe = LocalProbe::new(&table, &g, &ray, false);
            let mut r = Rng::new(100 + i, 3);
            let mut u = || r.next_f32();
            let density = |t: f32| lookup.at(t);
            if cells_only {
                let probe = CellsOnly(probe);
                delta_track_local([seg], &coeff, density, probe, Rgb::ONE, &mut u, stats)
            } else {
                let probe = Counting(probe, &mut skipped);
                delta_track_local([seg], &coeff, density, probe, Rgb::ONE, &mut u, stats)
            }
        };
        let a = run(false, &mut with);
        let b = run(true, &mut without);
        assert_eq!(a, b, "ray {i}");
    }
    assert_eq!(with, without);
    eprintln!(
        "{} real collisions, {} tentative collisions rejected by the table, {skipped} of them by a block maximum",
        with.real_collisions, with.probed
    );
    assert!(with.real_collisions > 1_000 && with.probed > 4 * with.real_collisions);
    assert!(
        4 * skipped > with.probed,
        "{skipped} of {} skipped",
        with.probed
    );
}

// ---------------------------------------------------------------------------------------------
// The trackers against closed forms on a chromatic ramp.

const L: f32 = 2.0;

fn ramp(t: f32) -> f32 {
    0.2 + 0.9 * t
}
fn ramp_depth(t: f64) -> f64 {
    0.2 * t + 0.45 * t * t
}

/// Point bounds over cells of width 0.05 along the ramp: exact, or (`violated`) with the
/// maximum of the cell's first 70 % only, which the density exceeds at its end.
struct RampBounds {
    violated: bool,
}

impl PointBounds for RampBounds {
    fn at(&mut self, t: f32) -> Option<(f32, f32)> {
        let w = 0.05f32;
        let a = (t / w).floor() * w;
        let top = if self.violated { a + 0.7 * w } else { a + w };
        Some((ramp(a), ramp(top)))
    }
}

/// Two coarse segments with the ramp's bounds.
fn coarse() -> Vec<MajorantSegment> {
    [(0.0f32, 0.7f32), (0.7, L)]
        .iter()
        .map(|&(a, b)| {
            let bounds = Bounds {
                min: ramp(a),
                max: ramp(b),
                mean: 0.5 * (ramp(a) + ramp(b)),
            };
            MajorantSegment::new(a, b, bounds, true)
        })
        .collect()
}

fn chromatic() -> DensityCoefficients {
    let mut c = DensityCoefficients::new(Rgb::new(1.0, 1.6, 0.6), Rgb::new(0.9, 1.0, 0.3));
    c.base_t = Rgb::new(0.1, 0.05, 0.2);
    c.base_s = Rgb::new(0.08, 0.05, 0.02);
    c
}

/// (∫₀^L σ_s(t) T(t) dt, T(L)) per channel by the midpoint rule.
fn expected(coeff: &DensityCoefficients) -> (Rgb, Rgb) {
    let n = 20_000;
    let dt = f64::from(L) / n as f64;
    let mut sum = [0.0f64; 3];
    for i in 0..n {
        let t = (i as f64 + 0.5) * dt;
        for (k, sum_k) in sum.iter_mut().enumerate() {
            let tau = f64::from(coeff.base_t[k]) * t + f64::from(coeff.sigma_t[k]) * ramp_depth(t);
            let ss = f64::from(coeff.base_s[k])
                + f64::from(coeff.sigma_s[k]) * f64::from(ramp(t as f32));
            *sum_k += ss * (-tau).exp() * dt;
        }
    }
    let lf = f64::from(L);
    let tr = Rgb([0, 1, 2].map(|k| {
        (-(f64::from(coeff.base_t[k]) * lf + f64::from(coeff.sigma_t[k]) * ramp_depth(lf))).exp()
            as f32
    }));
    (Rgb(sum.map(|x| x as f32)), tr)
}

#[test]
fn delta_and_decomposition_tracking_with_point_bounds_are_unbiased() {
    let coeff = chromatic();
    let (scatter, escape) = expected(&coeff);
    let segs = coarse();
    let beta = Rgb::new(1.0, 0.6, 0.3);
    for decompose in [false, true] {
        for violated in [false, true] {
            let n = 200_000;
            let mut stats = TrackingStats::default();
            let mut run = |rng: &mut Rng| {
                let mut u = || rng.next_f32();
                let local = RampBounds { violated };
                if decompose {
                    decomposition_track_local(
                        segs.iter().copied(),
                        &coeff,
                        ramp,
                        local,
                        beta,
                        &mut u,
                        &mut stats,
                    )
                } else {
                    delta_track_local(
                        segs.iter().copied(),
                        &coeff,
                        ramp,
                        local,
                        beta,
                        &mut u,
                        &mut stats,
                    )
                }
            };
            let mut rng = Rng::new(21, u64::from(decompose) * 2 + u64::from(violated));
            let flights: Vec<Flight> = (0..n).map(|_| run(&mut rng)).collect();
            let mut it = flights.iter();
            let esc = estimate_rgb(n, &mut Rng::new(0, 0), |_| match it.next() {
                Some(Flight::Escape { weight }) => *weight,
                _ => Rgb::ZERO,
            });
            let mut it = flights.iter();
            let sca = estimate_rgb(n, &mut Rng::new(0, 0), |_| match it.next() {
                Some(Flight::Scatter { weight, .. }) => *weight,
                _ => Rgb::ZERO,
            });
            let what = format!("decompose {decompose}, violated bounds {violated}");
            assert_rgb_agrees(&esc, escape, 4.0, 1e-4, &format!("escape, {what}"));
            assert_rgb_agrees(&sca, scatter, 4.0, 1e-4, &format!("scatter, {what}"));
            assert!(stats.probed > 0, "{what}: no tentative collision rejected");
            if violated {
                assert!(
                    stats.violations > 0,
                    "{what}: the violation was not exercised"
                );
            } else {
                assert_eq!(stats.violations, 0, "{what}");
            }
        }
    }
}

#[test]
fn ratio_and_residual_ratio_tracking_with_point_bounds_are_unbiased() {
    let coeff = chromatic();
    let (_, exact) = expected(&coeff);
    let segs = coarse();
    for mode in [
        TransmittanceMode::Ratio,
        TransmittanceMode::ResidualRatio(ControlVariate::Novak),
        TransmittanceMode::ResidualRatio(ControlVariate::Minorant),
    ] {
        for violated in [false, true] {
            let mut stats = TrackingStats::default();
            let est = estimate_rgb(200_000, &mut Rng::new(31, u64::from(violated)), |rng| {
                let mut u = || rng.next_f32();
                transmittance_local(
                    segs.iter().copied(),
                    &coeff,
                    ramp,
                    RampBounds { violated },
                    mode,
                    &mut u,
                    &mut stats,
                )
            });
            assert_rgb_agrees(
                &est,
                exact,
                4.0,
                1e-4,
                &format!("{mode:?}, violated bounds {violated}"),
            );
            assert!(stats.probed > 0, "{mode:?}: nothing rejected");
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Media: the same estimator with and without local bounds, and the lookups they need.

/// Mean escape weight, mean scatter weight × (1, t, t²) and mean transmittance over random
/// rays through the medium, as independent estimates per quantity.
fn medium_estimates(m: &Medium, seed: u64, n: usize) -> (Vec<[Estimate; 3]>, TrackingStats) {
    let mut stats = TrackingStats::default();
    let mut rng = Rng::new(seed, 7);
    let beta = Rgb::new(1.0, 0.7, 0.4);
    let mut rows: Vec<[Vec<f64>; 3]> = vec![Default::default(); 4];
    for _ in 0..n {
        let ray = random_ray(&mut rng);
        let mut u = || rng.next_f32();
        let ev = m.sample_flight(&ray, 2.0, beta, &mut u, &mut stats);
        let (esc, sca, sca_t) = match ev.scatter {
            None => (ev.weight, Rgb::ZERO, Rgb::ZERO),
            Some(v) => (Rgb::ZERO, ev.weight, ev.weight * v.t),
        };
        let mut u = || rng.next_f32();
        let tr = m.transmittance(&ray, 2.0, &mut u, &mut stats);
        for (row, v) in rows.iter_mut().zip([esc, sca, sca_t, tr]) {
            for k in 0..3 {
                row[k].push(f64::from(v[k]));
            }
        }
    }
    let est = rows
        .into_iter()
        .map(|r| r.map(|xs| Estimate::of(&xs)))
        .collect();
    (est, stats)
}

#[test]
fn local_bounds_agree_with_the_plain_estimators_on_an_fbm_grid() {
    // A chromatic medium with a constant part, so that the weights of the two estimators
    // differ (with grey media they coincide).
    let mut coeff = DensityCoefficients::new(Rgb::new(20.0, 30.0, 12.0), Rgb::new(18.0, 24.0, 6.0));
    coeff.base_t = Rgb::new(0.5, 0.2, 1.0);
    coeff.base_s = Rgb::new(0.4, 0.1, 0.2);
    for ff in [
        FreeFlightMethod::DeltaTracking,
        FreeFlightMethod::Decomposition,
    ] {
        let plain = medium(grid(32, fbm_cloud), coeff, config(ff, false));
        let local = medium(grid(32, fbm_cloud), coeff, config(ff, true));
        let n = 60_000;
        let (a, sa) = medium_estimates(&plain, 1, n);
        let (b, sb) = medium_estimates(&local, 2, n);
        let names = ["escape", "scatter", "scatter × t", "transmittance"];
        for (q, name) in names.iter().enumerate() {
            for k in 0..3 {
                let z = difference_z_score(&a[q][k], &b[q][k]);
                assert!(
                    z.abs() < 4.0,
                    "{ff:?} {name} channel {k}: plain {} ± {}, local bounds {} ± {} (z = {z:.2})",
                    a[q][k].mean,
                    a[q][k].standard_error,
                    b[q][k].mean,
                    b[q][k].standard_error
                );
            }
        }
        assert!(sb.probed > 0 && sa.probed == 0);
        assert!(
            2 * sb.lookups < sa.lookups,
            "{ff:?}: free-flight lookups {} with local bounds, {} without",
            sb.lookups,
            sa.lookups
        );
    }
}

/// Free-flight lookups per real collision on the fBm grid at `n`³ voxels, σ_t = 40 per unit
/// density (grey, albedo 0.9).
fn lookups_per_collision(n: i32, tracking: TrackingConfig) -> f64 {
    let coeff = DensityCoefficients::new(Rgb::splat(40.0), Rgb::splat(36.0));
    let m = medium(grid(n, fbm_cloud), coeff, tracking);
    let mut rng = Rng::new(3, 1);
    let mut stats = TrackingStats::default();
    for _ in 0..20_000 {
        let ray = random_ray(&mut rng);
        let mut u = || rng.next_f32();
        let _ = m.sample_flight(&ray, 2.0, Rgb::ONE, &mut u, &mut stats);
    }
    assert!(stats.real_collisions > 5_000, "{stats:?}");
    stats.lookups as f64 / stats.real_collisions as f64
}

#[test]
fn at_most_two_lookups_per_real_collision_on_a_dense_fbm_grid_at_two_resolutions() {
    let mut with = Vec::new();
    for n in [32, 64] {
        let plain = lookups_per_collision(n, config(FreeFlightMethod::DeltaTracking, false));
        let local = lookups_per_collision(n, config(FreeFlightMethod::DeltaTracking, true));
        let decomposed = lookups_per_collision(n, config(FreeFlightMethod::Decomposition, true));
        eprintln!(
            "{n}³: lookups per real collision {plain:.2} plain, {local:.2} with local bounds, {decomposed:.2} decomposition with local bounds"
        );
        assert!(local <= 2.0, "{n}³: {local:.2} lookups per real collision");
        assert!(decomposed <= local, "{n}³: {decomposed:.2} > {local:.2}");
        assert!(
            local < 0.6 * plain,
            "{n}³: {local:.2} against {plain:.2} without"
        );
        with.push(local);
    }
    assert!(
        with[1] <= 1.1 * with[0],
        "lookups per real collision grow with the resolution: {with:?}"
    );
}

/// The 32³ fBm cloud as `cloud.vdb` in `dir`, and a scene text with it as a `voxel` interior
/// (albedo 0.9) with the further keys `keys` (`attenuation`, `tracking`).
fn cloud_scene(dir: &common::files::TempDir, keys: &str) -> String {
    use velour::vdb::{write_vdb, GridToWrite, WriteOptions};
    let g = grid(32, fbm_cloud);
    let list = [GridToWrite {
        class: "fog volume",
        ..GridToWrite::new("density", &g)
    }];
    write_vdb(dir.join("cloud.vdb"), &list, &WriteOptions::default())
        .unwrap_or_else(|e| panic!("{e}"));
    format!(
        r#"
[camera]
eye = [0.5, 0.5, 3.0]
look_at = [0.5, 0.5, 0.5]
fov = 30
[film]
width = 24
height = 24
spp = 4
seed = 1
max_depth = 1000
[[light]]
type = "environment"
radiance = 1.0
[[object]]
name = "cloud"
shape = "bounds"
interior = {{ type = "voxel", file = "cloud.vdb", grid = "density", albedo = 0.9, albedo_mode = "single", nee = "interior"{keys} }}
"#
    )
}

#[test]
fn a_voxel_interior_uses_local_bounds_by_default() {
    // The scene loader's default (no `tracking` key) decides tentative collisions against the
    // local bounds where σ_t is grey (σ_t = 40 per unit density); `local_bounds = false`
    // switches them off. Chromatic extinction is tracked without them unless asked for.
    let dir = common::files::TempDir::new("local_bounds_default");
    let path = dir.join("scene.toml");
    let render = |keys: &str| {
        let scene = common::render::scene_from_text(&cloud_scene(&dir, keys), &path);
        common::render::render_scene(&scene, 1).1.tracking
    };
    let default = render(", attenuation = 0.025");
    let off = render(", attenuation = 0.025, tracking = { local_bounds = false }");
    // Chromatic extinction: off unless asked for.
    let chromatic = render(", attenuation = [0.025, 0.03, 0.04]");
    let forced = render(", attenuation = [0.025, 0.03, 0.04], tracking = { local_bounds = true }");
    assert!(
        chromatic.probed == 0 && forced.probed > 0,
        "{chromatic:?} {forced:?}"
    );
    let per = |s: &TrackingStats| s.lookups as f64 / s.real_collisions.max(1) as f64;
    eprintln!(
        "free-flight lookups per real collision: {:.2} by default, {:.2} with local_bounds = false",
        per(&default),
        per(&off)
    );
    assert!(default.real_collisions > 1_000, "{default:?}");
    assert!(default.probed > 0 && off.probed == 0, "{default:?} {off:?}");
    assert!(per(&default) <= 2.0, "{default:?}");
}
