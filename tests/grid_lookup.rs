//! Lookups of the sparse brick grid against a direct evaluation of the same data.

use glam::{DAffine3, DMat3, DVec3, IVec3, Vec3};
use std::collections::HashMap;
use velour::grid::{ChannelKind, Node, SparseGrid, SparseGridBuilder, Storage, TileLevel};
use velour::sampling::Rng;

/// The reference: explicit voxels, constant boxes (tiles) and a background.
struct Reference {
    voxels: HashMap<IVec3, f32>,
    boxes: Vec<(IVec3, IVec3, f32)>,
    background: f32,
}

impl Reference {
    fn value(&self, p: IVec3) -> f32 {
        if let Some(&v) = self.voxels.get(&p) {
            return v;
        }
        for &(lo, hi, v) in &self.boxes {
            if p.cmpge(lo).all() && p.cmple(hi).all() {
                return v;
            }
        }
        self.background
    }
    /// Trilinear interpolation with voxel centres at integers, evaluated directly.
    fn trilinear(&self, p: Vec3) -> f64 {
        let pd = p.as_dvec3();
        let f = pd.floor();
        let i = f.as_ivec3();
        let t = pd - f;
        let mut acc = 0.0;
        for k in 0..8 {
            let d = IVec3::new(k >> 2, (k >> 1) & 1, k & 1);
            let w = (if d.x == 1 { t.x } else { 1.0 - t.x })
                * (if d.y == 1 { t.y } else { 1.0 - t.y })
                * (if d.z == 1 { t.z } else { 1.0 - t.z });
            acc += w * f64::from(self.value(i + d));
        }
        acc
    }
}

/// A grid with noisy bricks around the origin, an 8^3 tile, a 128^3 tile and a root tile,
/// plus the same data as a reference.
fn build(storage: Storage) -> (SparseGrid, Reference) {
    let mut rng = Rng::new(17, 0);
    let mut b = SparseGridBuilder::new(storage);
    let bg = 0.125;
    b.add_channel("density", ChannelKind::Scalar, Vec3::splat(bg));
    let mut r = Reference {
        voxels: HashMap::new(),
        boxes: Vec::new(),
        background: bg,
    };
    let round = |v: f32| {
        if storage == Storage::F16 {
            half::f16::from_f32(v).to_f32()
        } else {
            v
        }
    };
    for x in -12..13 {
        for y in -9..10 {
            for z in -10..11 {
                let p = IVec3::new(x, y, z);
                let v = rng.next_f32() * 2.0;
                b.set_value(0, p, v).unwrap();
                r.voxels.insert(p, round(v));
            }
        }
    }
    // An 8^3 tile adjoining the noisy region (brick key (2, 0, 0) = voxels 16..23).
    b.set_tile(TileLevel::Brick, IVec3::new(2, 0, 0), &[0.75], true)
        .unwrap();
    r.boxes
        .push((IVec3::new(16, 0, 0), IVec3::new(23, 7, 7), 0.75));
    // A 128^3 tile: block key (1, 0, 0) = voxels 128..255.
    b.set_tile(TileLevel::Block, IVec3::new(1, 0, 0), &[1.5], true)
        .unwrap();
    r.boxes
        .push((IVec3::new(128, 0, 0), IVec3::new(255, 127, 127), 1.5));
    // A root tile: 4096^3 voxels at root key (1, 0, 0), never expanded.
    b.set_tile(TileLevel::Root, IVec3::new(1, 0, 0), &[2.5], true)
        .unwrap();
    r.boxes
        .push((IVec3::new(4096, 0, 0), IVec3::new(8191, 4095, 4095), 2.5));
    // An inactive tile holding a non-background value.
    b.set_tile(TileLevel::Brick, IVec3::new(0, 5, 0), &[-1.0], false)
        .unwrap();
    r.boxes
        .push((IVec3::new(0, 40, 0), IVec3::new(7, 47, 7), -1.0));
    (b.build(), r)
}

fn check_points(g: &SparseGrid, r: &Reference, pts: &[Vec3], tol: f64) {
    let mut acc = g.accessor(0);
    for &p in pts {
        let want = r.trilinear(p);
        let got = f64::from(g.sample_trilinear_index(p));
        assert!(
            (got - want).abs() <= tol * (1.0 + want.abs()),
            "trilinear at {p}: {got} vs {want}"
        );
        let got2 = f64::from(acc.sample_trilinear(p));
        assert_eq!(got2, got, "accessor vs grid at {p}");
        let n = (p + Vec3::splat(0.5)).floor().as_ivec3();
        assert_eq!(g.sample_nearest_index(p), r.value(n), "nearest at {p}");
    }
}

#[test]
fn trilinear_matches_direct_evaluation() {
    for storage in [Storage::F32, Storage::F16] {
        let (g, r) = build(storage);
        let mut rng = Rng::new(5, 0);
        let mut pts = Vec::new();
        // Random points over the noisy region and the tiles next to it.
        for _ in 0..20000 {
            pts.push(Vec3::new(
                -14.0 + 40.0 * rng.next_f32(),
                -11.0 + 60.0 * rng.next_f32(),
                -12.0 + 25.0 * rng.next_f32(),
            ));
        }
        // Brick faces, edges and corners: coordinates whose floor sits on the last voxel of
        // a brick (7, 15, -1, -9...), so the 8 corners straddle up to 8 bricks.
        let faces = [
            -9.0f32, -8.5, -1.0, -0.5, -0.01, 0.0, 6.99, 7.0, 7.25, 7.5, 7.99, 8.0, 15.5, 23.5,
            24.0,
        ];
        for &x in &faces {
            for &y in &faces {
                for &z in &faces {
                    pts.push(Vec3::new(x, y.min(9.0), z.min(10.0)));
                }
            }
        }
        // Around and inside the block and root tiles.
        for _ in 0..5000 {
            pts.push(Vec3::new(
                120.0 + 150.0 * rng.next_f32(),
                -2.0 + 132.0 * rng.next_f32(),
                40.0 * rng.next_f32(),
            ));
            pts.push(Vec3::new(
                4090.0 + 20.0 * rng.next_f32(),
                -1.5 + 4.0 * rng.next_f32(),
                4094.0 + 2.5 * rng.next_f32(),
            ));
        }
        check_points(&g, &r, &pts, 2e-6);
    }
}

/// Lookups through the padded bricks (`SparseGrid::padded_accessor`, what media use) give the
/// plain accessor's values bit for bit: inside bricks, across brick faces, edges and corners
/// (neighbour bricks, brick tiles, block and root tiles, the background), in both storages
/// (16-bit grids keep the plain path).
#[test]
fn padded_lookups_match_the_plain_accessor_bit_for_bit() {
    for storage in [Storage::F32, Storage::F16] {
        let (g, _) = build(storage);
        let mut rng = Rng::new(9, 0);
        let mut pts = Vec::new();
        for _ in 0..40000 {
            pts.push(Vec3::new(
                -18.0 + 46.0 * rng.next_f32(),
                -14.0 + 66.0 * rng.next_f32(),
                -14.0 + 30.0 * rng.next_f32(),
            ));
        }
        // First corners on the last voxel of a brick along one, two or three axes.
        let faces = [
            -9.0f32, -8.5, -1.0, -0.5, 7.0, 7.25, 7.99, 15.5, 23.5, 39.5, 47.5,
        ];
        for &x in &faces {
            for &y in &faces {
                for &z in &faces {
                    pts.push(Vec3::new(x, y, z));
                }
            }
        }
        for _ in 0..5000 {
            pts.push(Vec3::new(
                120.0 + 150.0 * rng.next_f32(),
                -2.0 + 132.0 * rng.next_f32(),
                40.0 * rng.next_f32(),
            ));
        }
        let mut plain = g.accessor(0);
        let mut padded = g.padded_accessor(0);
        for &p in &pts {
            let a = plain.sample_trilinear(p);
            let b = padded.sample_trilinear(p);
            assert_eq!(a.to_bits(), b.to_bits(), "{storage:?} at {p}: {a} vs {b}");
        }
    }
}

#[test]
fn world_space_lookups_use_the_affine_map() {
    let (mut g, r) = build(Storage::F32);
    let rot = DMat3::from_rotation_y(0.4) * DMat3::from_rotation_z(-0.3);
    let m = DAffine3 {
        matrix3: rot * DMat3::from_diagonal(DVec3::new(0.1, 0.2, 0.05)),
        translation: DVec3::new(1.0, -2.0, 3.0),
    };
    g.set_index_to_world(m).unwrap();
    let mut rng = Rng::new(9, 0);
    for _ in 0..5000 {
        let p = Vec3::new(
            -12.0 + 30.0 * rng.next_f32(),
            -9.0 + 18.0 * rng.next_f32(),
            -10.0 + 20.0 * rng.next_f32(),
        );
        let w = m.transform_point3(p.as_dvec3()).as_vec3();
        let back = g.world_to_index_point(w);
        let want = r.trilinear(back);
        let got = f64::from(g.sample_trilinear_world(w));
        assert!((got - want).abs() <= 1e-5, "world {w}: {got} vs {want}");
        assert!((back - p).length() < 1e-4);
    }
    assert!(g
        .set_index_to_world(DAffine3::from_scale(DVec3::new(1.0, 0.0, 1.0)))
        .is_err());
}

#[test]
fn topology_queries_and_tiles_stay_constant() {
    let (g, r) = build(Storage::F32);
    // Tiles are never expanded: only the noisy region holds bricks.
    let noisy_bricks = 4 * 3 * 3 + 4 * 3 * 3 + 4 * 3 * 3; // x: -16..15 (4 bricks incl. partial), y: 3, z: 3
    assert!(
        g.brick_count() <= noisy_bricks,
        "{} bricks",
        g.brick_count()
    );
    assert_eq!(g.active_brick_voxels(), 25 * 19 * 21);
    let tiles = g.tiles();
    assert_eq!(tiles.len(), 4);
    let want_active = 25 * 19 * 21 + 512 + (1u64 << 21) + (1u64 << 36);
    assert_eq!(g.active_voxels(), want_active);
    let (lo, hi) = g.active_bbox().unwrap();
    assert_eq!(lo, IVec3::new(-12, -9, -10));
    assert_eq!(hi, IVec3::new(8191, 4095, 4095));
    assert!(matches!(
        g.node_at_brick(IVec3::new(2, 0, 0)),
        Node::Tile {
            level: TileLevel::Brick,
            active: true,
            ..
        }
    ));
    assert!(matches!(
        g.node_at_brick(IVec3::new(20, 3, 1)),
        Node::Tile {
            level: TileLevel::Block,
            ..
        }
    ));
    assert!(matches!(
        g.node_at_brick(IVec3::new(600, 3, 1)),
        Node::Tile {
            level: TileLevel::Root,
            active: true,
            ..
        }
    ));
    assert!(matches!(
        g.node_at_brick(IVec3::new(0, 0, 0)),
        Node::Brick(_)
    ));
    assert!(!g.is_active(IVec3::new(3, 44, 3)));
    assert_eq!(g.value_at(IVec3::new(3, 44, 3)), -1.0);
    assert_eq!(g.value_at(IVec3::new(-1000, 0, 0)), r.background);
    assert_eq!(g.background(0), 0.125);
    for t in &tiles {
        assert_eq!(g.value_at(t.origin), r.value(t.origin));
    }
}

#[test]
fn setting_a_voxel_inside_a_tile_splits_only_one_brick() {
    let mut b = SparseGridBuilder::new(Storage::F32);
    b.add_channel("d", ChannelKind::Scalar, Vec3::ZERO);
    b.set_tile(TileLevel::Root, IVec3::ZERO, &[2.0], true)
        .unwrap();
    b.set_value(0, IVec3::new(100, 200, 300), 7.0).unwrap();
    let g = b.build();
    assert_eq!(g.brick_count(), 1);
    assert_eq!(g.value_at(IVec3::new(100, 200, 300)), 7.0);
    assert_eq!(g.value_at(IVec3::new(101, 200, 300)), 2.0);
    assert_eq!(g.value_at(IVec3::new(4000, 10, 4000)), 2.0);
    assert_eq!(g.active_voxels(), 1u64 << 36);
    // Tiles over existing nodes are refused.
    let mut b = SparseGridBuilder::new(Storage::F32);
    b.add_channel("d", ChannelKind::Scalar, Vec3::ZERO);
    b.set_value(0, IVec3::new(1, 1, 1), 1.0).unwrap();
    assert!(b
        .set_tile(TileLevel::Brick, IVec3::ZERO, &[1.0], true)
        .is_err());
    assert!(b
        .set_tile(TileLevel::Block, IVec3::ZERO, &[1.0], true)
        .is_err());
    assert!(b
        .set_tile(TileLevel::Root, IVec3::ZERO, &[1.0], true)
        .is_err());
    assert!(b
        .set_tile(TileLevel::Root, IVec3::ONE, &[1.0, 2.0], true)
        .is_err());
}

#[test]
fn vec3_and_scalar_channels_share_the_topology() {
    let mut b = SparseGridBuilder::new(Storage::F32);
    let d = b.add_channel("density", ChannelKind::Scalar, Vec3::ZERO);
    let c = b.add_channel("albedo", ChannelKind::Vec3, Vec3::new(0.1, 0.2, 0.3));
    let mut rng = Rng::new(3, 0);
    let mut vals = HashMap::new();
    for x in 0..10 {
        for y in 0..10 {
            for z in 0..10 {
                let p = IVec3::new(x, y, z);
                let v = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
                b.set_value(d, p, v.x).unwrap();
                b.set_value_vec3(c, p, v).unwrap();
                vals.insert(p, v);
            }
        }
    }
    b.set_tile(
        TileLevel::Brick,
        IVec3::new(0, 0, 3),
        &[0.5, 1.0, 2.0, 3.0],
        true,
    )
    .unwrap();
    assert!(b.set_value(c, IVec3::ZERO, 1.0).is_err());
    let g = b.build();
    assert_eq!(g.channel_count(), 2);
    assert_eq!(g.channel_index("albedo"), Some(1));
    assert_eq!(
        g.value_at_vec3(c, IVec3::new(3, 4, 5)),
        vals[&IVec3::new(3, 4, 5)]
    );
    assert_eq!(
        g.value_at_vec3(c, IVec3::new(50, 4, 5)),
        Vec3::new(0.1, 0.2, 0.3)
    );
    assert_eq!(
        g.value_at_vec3(c, IVec3::new(1, 1, 25)),
        Vec3::new(1.0, 2.0, 3.0)
    );
    assert_eq!(g.value_at(IVec3::new(1, 1, 25)), 0.5);
    // Vec3 trilinear equals per-component direct evaluation.
    let p = Vec3::new(3.3, 7.6, 8.9);
    let f = p.floor().as_ivec3();
    let t = p - p.floor();
    let mut want = Vec3::ZERO;
    for k in 0..8 {
        let dd = IVec3::new(k >> 2, (k >> 1) & 1, k & 1);
        let w = (if dd.x == 1 { t.x } else { 1.0 - t.x })
            * (if dd.y == 1 { t.y } else { 1.0 - t.y })
            * (if dd.z == 1 { t.z } else { 1.0 - t.z });
        want += w * vals
            .get(&(f + dd))
            .copied()
            .unwrap_or(Vec3::new(0.1, 0.2, 0.3));
    }
    assert!((g.sample_trilinear_index_vec3(c, p) - want).length() < 1e-5);
}

/// The inlined vector read (`Accessor::value_vec3_hot`, a fabric's tangent lookups) gives
/// `Accessor::value_vec3` bit for bit: voxels in bricks, in a brick tile, in an inactive
/// tile, outside every brick (the background), in both storages, for a vector channel and
/// for a scalar one (splatted), read in one accessor each along a random walk (cache hits
/// and misses).
#[test]
fn inlined_vector_reads_match_value_vec3_bit_for_bit() {
    for storage in [Storage::F32, Storage::F16] {
        let mut b = SparseGridBuilder::new(storage);
        let d = b.add_channel("density", ChannelKind::Scalar, Vec3::splat(0.25));
        let c = b.add_channel("tangent", ChannelKind::Vec3, Vec3::new(0.1, -0.2, 0.3));
        let mut rng = Rng::new(31, 0);
        for x in -9..12 {
            for y in -3..20 {
                for z in -5..7 {
                    let p = IVec3::new(x, y, z);
                    let v = Vec3::new(rng.next_f32(), -rng.next_f32(), rng.next_f32());
                    b.set_value(d, p, v.x).unwrap();
                    b.set_value_vec3(c, p, v).unwrap();
                }
            }
        }
        b.set_tile(
            TileLevel::Brick,
            IVec3::new(3, 0, 0),
            &[0.5, 1.0, 2.0, 3.0],
            true,
        )
        .unwrap();
        b.set_tile(
            TileLevel::Brick,
            IVec3::new(0, 4, 0),
            &[0.7, -1.0, 0.0, 4.0],
            false,
        )
        .unwrap();
        let g = b.build();
        for ch in [c, d] {
            let (mut plain, mut hot) = (g.accessor(ch), g.accessor(ch));
            let mut p = IVec3::ZERO;
            let mut seen_bricks = 0;
            for n in 0..60_000 {
                if n % 97 == 0 {
                    let r = |lo: i32, span: f32, rng: &mut Rng| lo + (span * rng.next_f32()) as i32;
                    p = IVec3::new(
                        r(-20, 60.0, &mut rng),
                        r(-12, 52.0, &mut rng),
                        r(-12, 30.0, &mut rng),
                    );
                } else {
                    let k = (rng.next_f32() * 6.0) as usize % 6;
                    let step = [
                        IVec3::X,
                        IVec3::NEG_X,
                        IVec3::Y,
                        IVec3::NEG_Y,
                        IVec3::Z,
                        IVec3::NEG_Z,
                    ];
                    p += step[k];
                }
                let (a, h) = (plain.value_vec3(p), hot.value_vec3_hot(p));
                assert_eq!(
                    a.to_array().map(f32::to_bits),
                    h.to_array().map(f32::to_bits),
                    "{storage:?} channel {ch} at {p}: {a} vs {h}"
                );
                if g.is_active(p) {
                    seen_bricks += 1;
                }
            }
            assert!(seen_bricks > 1000, "{seen_bricks} reads in active voxels");
        }
    }
}

/// The interleaved padded table of a scalar and a vector channel (`SparseGrid::padded_pairs`,
/// a fabric's density and tangents) holds, at the 8 corners of every cell whose first corner
/// lies in a brick (`Accessor::padded_pair_cell`), the scalar channel's `value` and the vector
/// channel's `value_vec3` bit for bit: cells inside bricks and across brick faces, edges and
/// corners into neighbour bricks, tiles and the background, in both storages. Cells whose
/// first corner lies in a tile give `None`; the table is not made for other channel kinds
/// and is kept for the first scalar channel asked.
#[test]
fn padded_pairs_hold_both_channels_values_bit_for_bit() {
    for storage in [Storage::F32, Storage::F16] {
        let mut b = SparseGridBuilder::new(storage);
        let d = b.add_channel("density", ChannelKind::Scalar, Vec3::splat(0.25));
        let c = b.add_channel("tangent", ChannelKind::Vec3, Vec3::new(0.1, -0.2, 0.3));
        let e = b.add_channel("extra", ChannelKind::Scalar, Vec3::ZERO);
        let mut rng = Rng::new(37, 0);
        for x in -9..12 {
            for y in -3..20 {
                for z in -5..7 {
                    let p = IVec3::new(x, y, z);
                    let v = Vec3::new(rng.next_f32(), -rng.next_f32(), rng.next_f32());
                    b.set_value(d, p, 2.0 * v.y + 1.0).unwrap();
                    b.set_value_vec3(c, p, v).unwrap();
                    b.set_value(e, p, v.z).unwrap();
                }
            }
        }
        b.set_tile(
            TileLevel::Brick,
            IVec3::new(2, 0, 0),
            &[0.5, 1.0, 2.0, 3.0, 4.0],
            true,
        )
        .unwrap();
        b.set_tile(
            TileLevel::Brick,
            IVec3::new(0, 3, 0),
            &[0.7, -1.0, 0.0, 4.0, 5.0],
            false,
        )
        .unwrap();
        let g = b.build();
        assert!(
            g.padded_pairs(c, d).is_none(),
            "a vector channel as the scalar one"
        );
        assert!(
            g.padded_pairs(d, e).is_none(),
            "a scalar channel as the vector one"
        );
        let table = g.padded_pairs(d, c).expect("table");
        assert!(
            g.padded_pairs(e, c).is_none(),
            "kept for the first scalar channel"
        );
        let (mut dens, mut tan, mut cells) = (g.accessor(d), g.accessor(c), g.accessor(d));
        let (mut in_bricks, mut in_tiles) = (0, 0);
        for x in -20..28 {
            for y in -12..36 {
                for z in -12..14 {
                    let i = IVec3::new(x, y, z);
                    let Some(corners) = cells.padded_pair_cell(table, i) else {
                        assert!(g.brick_at_voxel(i).is_none(), "{storage:?} {i} in a brick");
                        in_tiles += 1;
                        continue;
                    };
                    assert!(g.brick_at_voxel(i).is_some(), "{storage:?} {i} in a tile");
                    in_bricks += 1;
                    for (k, got) in corners.iter().enumerate() {
                        let o = IVec3::new((k >> 2) as i32, ((k >> 1) & 1) as i32, (k & 1) as i32);
                        let t = tan.value_vec3(i + o);
                        let want = [dens.value(i + o), t.x, t.y, t.z];
                        assert_eq!(
                            got.map(f32::to_bits),
                            want.map(f32::to_bits),
                            "{storage:?} cell {i} corner {o}"
                        );
                    }
                }
            }
        }
        assert!(
            in_bricks > 10_000 && in_tiles > 10_000,
            "{in_bricks} {in_tiles}"
        );
    }
}

#[test]
fn memory_per_active_voxel_of_dense_bricks() {
    for (storage, raw) in [(Storage::F32, 4.0), (Storage::F16, 2.0)] {
        let mut b = SparseGridBuilder::new(storage);
        b.add_channel("d", ChannelKind::Scalar, Vec3::ZERO);
        let vals = vec![0.5f32; 512];
        for x in 0..16 {
            for y in 0..16 {
                for z in 0..16 {
                    b.fill_brick(0, IVec3::new(x, y, z), &vals, [u64::MAX; 8])
                        .unwrap();
                }
            }
        }
        let m = b.build().memory_report();
        assert_eq!(m.active_brick_voxels, 4096 * 512);
        assert_eq!(m.raw_value_bytes, raw as usize);
        assert!(m.bytes_per_active_brick_voxel >= raw);
        assert!(m.bytes_per_active_brick_voxel <= 1.25 * raw, "{m:?}");
    }
}

/// The grid's integer floor ([`velour::grid::floor_frac`]) and fabric's three-lane one
/// ([`velour::fabric::floor_ivec3`]) are one function: the same integers for every input,
/// the `i32` range's edges, infinities and NaN included.
#[test]
fn grid_and_fabric_floors_give_the_same_integers() {
    let edges = [
        0.0f32,
        -0.0,
        0.5,
        -0.5,
        -1.0e-30,
        8_388_607.5,
        -8_388_607.5,
        2_147_483_520.0,
        -2_147_483_520.0,
        2_147_483_648.0,
        -2_147_483_648.0,
        -2_147_483_904.0,
        f32::MAX,
        f32::MIN,
        f32::INFINITY,
        f32::NEG_INFINITY,
        f32::NAN,
    ];
    let mut cases: Vec<Vec3> = edges.iter().map(|&x| Vec3::new(x, -x, 0.25)).collect();
    let mut rng = Rng::new(24, 0);
    for _ in 0..100_000 {
        let scale = 2.0f32.powi((rng.next_f32() * 70.0) as i32 - 20);
        let mut r = || (rng.next_f32() * 2.0 - 1.0) * scale;
        cases.push(Vec3::new(r(), r(), r()));
    }
    for p in cases {
        assert_eq!(
            velour::grid::floor_frac(p).0,
            velour::fabric::floor_ivec3(p),
            "{p:?}"
        );
    }
}
