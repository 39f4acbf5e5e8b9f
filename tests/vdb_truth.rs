//! Our reader against OpenVDB's own figures (`tests/data/vdb/truth.jsonl`, computed by
//! OpenVDB 10 on the real files), against `vdb-rs` on 32-bit float files, and its errors.

mod common;

use common::files::vdb_fixture;
use common::vdb_figures::{assert_close, assert_index_to_world, components, counts, number, vec3};
use glam::IVec3;
use serde_json::Value;
use velour::vdb::{read_vdb, GridStats, VdbError, VdbFile, VdbGrid};

fn truth() -> Vec<Value> {
    let text = std::fs::read_to_string(vdb_fixture("truth.jsonl")).expect("truth.jsonl");
    text.lines()
        .map(|l| serde_json::from_str(l).expect("json line"))
        .collect()
}

fn check_grid(t: &Value, g: &VdbGrid, s: &GridStats) {
    let file = t["file"].as_str().unwrap_or("?");
    let w = |k: &str| format!("{file} {k}");
    assert_eq!(g.name, t["name"].as_str().unwrap(), "{}", w("name"));
    assert_eq!(
        g.value_type.name(),
        t["type"].as_str().unwrap(),
        "{}",
        w("type")
    );
    assert_eq!(g.class, t["class"].as_str().unwrap(), "{}", w("class"));
    assert_eq!(
        g.map.type_name(),
        t["map"].as_str().unwrap(),
        "{}",
        w("map")
    );
    assert_eq!(
        g.saved_as_half,
        t["save_half"].as_bool().unwrap(),
        "{}",
        w("save_half")
    );
    assert_eq!(
        velour::cli::inspect::compression_name(g.compression_flags),
        t["file_compression"].as_str().unwrap(),
        "{}",
        w("compression")
    );
    assert_eq!(
        s.active_voxels,
        t["active_voxels"].as_u64().unwrap(),
        "{}",
        w("active_voxels")
    );
    assert_eq!(
        s.leaf_count,
        t["leaf_count"].as_u64().unwrap(),
        "{}",
        w("leaf_count")
    );
    assert_eq!(
        s.active_voxels_by_level.to_vec(),
        counts(&t["active_voxels_by_depth"]),
        "{}",
        w("by depth")
    );
    let bb = t["active_bbox"].as_array().unwrap();
    let lo = vec3(&bb[0]);
    let hi = vec3(&bb[1]);
    let (a, b) = s.active_bbox.expect("active bbox");
    assert_eq!(a.as_dvec3().to_array(), lo, "{}", w("bbox min"));
    assert_eq!(b.as_dvec3().to_array(), hi, "{}", w("bbox max"));
    // Transform: voxel size and where the unit points land.
    let m = g.grid.index_to_world();
    let vs = vec3(&t["voxel_size"]);
    for (k, &want) in vs.iter().enumerate() {
        assert_close(g.grid.voxel_size()[k], want, 1e-12, &w("voxel size"));
    }
    assert_index_to_world(t, m, 1e-12, file);
    let n = s.components;
    if n == 1 {
        assert_eq!(
            f64::from(g.grid.background(0)),
            number(&t["background"]),
            "{}",
            w("background")
        );
        assert_close(s.min[0], number(&t["min"]), 1e-12, &w("min"));
        assert_close(s.max[0], number(&t["max"]), 1e-12, &w("max"));
        assert_close(s.sum[0], number(&t["sum"]), 1e-6, &w("sum"));
        let want = vec3(&t["moment"]);
        let max_coord = lo
            .iter()
            .chain(hi.iter())
            .fold(0.0f64, |m, c| m.max(c.abs()))
            + 1.0;
        let scale = s.sum[0].abs() * max_coord;
        for k in 0..3 {
            let tol = 1e-7 * scale;
            assert!(
                (s.moment[k] - want[k]).abs() <= tol,
                "{}: {:?} vs {want:?}",
                w("moment"),
                s.moment
            );
        }
    } else {
        let (mn, mx, sm) = (vec3(&t["min"]), vec3(&t["max"]), vec3(&t["sum"]));
        for k in 0..3 {
            assert_close(s.min[k], mn[k], 1e-12, &w("min"));
            assert_close(s.max[k], mx[k], 1e-12, &w("max"));
            assert_close(s.sum[k], sm[k], 1e-6, &w("sum"));
        }
        assert_close(s.sum_len, number(&t["sum_len"]), 1e-6, &w("sum_len"));
    }
    assert_eq!(s.non_finite, 0);
}

#[test]
fn every_fixture_matches_openvdb_truth() {
    let truth = truth();
    assert_eq!(truth.len(), 6);
    for t in &truth {
        let file = t["file"].as_str().unwrap();
        let grids = read_vdb(vdb_fixture(file)).unwrap_or_else(|e| panic!("{file}: {e}"));
        assert_eq!(grids.len(), 1, "{file}");
        let g = &grids[0];
        check_grid(t, g, &g.stats());
    }
}

#[test]
fn half_file_loads_into_f16_storage_exactly() {
    let full = read_vdb(vdb_fixture("noise_fbm.vdb")).unwrap().remove(0);
    let half = read_vdb(vdb_fixture("noise_fbm_half.vdb"))
        .unwrap()
        .remove(0);
    assert_eq!(half.grid.storage(), velour::grid::Storage::F16);
    assert_eq!(full.grid.storage(), velour::grid::Storage::F32);
    // Every voxel of the half grid is the half rounding of the float grid's voxel.
    let mut checked = 0;
    for b in 0..full.grid.brick_count() {
        let o = full.grid.brick_origin(b);
        for v in (0..512).step_by(7) {
            let p = o + IVec3::new(v >> 6, (v >> 3) & 7, v & 7);
            let want = half::f16::from_f32(full.grid.value_at(p)).to_f32();
            assert_eq!(half.grid.value_at(p), want, "voxel {p}");
            checked += 1;
        }
    }
    assert!(checked > 1000);
}

/// `vdb-rs` reads 32-bit float files correctly: every active item it yields must hold our
/// value at the same coordinate, and the totals must agree.
#[test]
fn vdb_rs_agrees_on_float_files() {
    for file in [
        "noise_fbm.vdb",
        "sphere_fog.vdb",
        "tiles_internal.vdb",
        "xform_scaletranslate.vdb",
    ] {
        let ours = read_vdb(vdb_fixture(file)).unwrap().remove(0);
        let fh = std::fs::File::open(vdb_fixture(file)).unwrap();
        let mut reader = vdb_rs::VdbReader::new(std::io::BufReader::new(fh)).unwrap();
        let theirs = reader.read_grid::<f32>("density").unwrap();
        let mut count = 0u64;
        let mut sum = 0.0f64;
        for (c, v, level) in theirs.iter() {
            let ijk = IVec3::new(c.x as i32, c.y as i32, c.z as i32);
            assert_eq!(ours.grid.value_at(ijk), v, "{file} at {ijk}");
            assert!(ours.grid.is_active(ijk), "{file}: {ijk} inactive in ours");
            let n = f64::from(level.scale()).powi(3);
            count += n as u64;
            sum += f64::from(v) * n;
        }
        let s = ours.stats();
        assert_eq!(count, s.active_voxels, "{file}");
        assert_close(sum, s.sum[0], 1e-9, file);
    }
}

#[test]
fn unknown_grid_name_lists_the_grids() {
    let f = VdbFile::open(vdb_fixture("sphere_fog.vdb")).unwrap();
    let e = f.read_grid("temperature").unwrap_err();
    assert!(matches!(e, VdbError::NoSuchGrid { .. }));
    let msg = e.to_string();
    assert!(
        msg.contains("temperature") && msg.contains("density") && msg.contains("sphere_fog.vdb"),
        "{msg}"
    );
}

#[test]
fn unsupported_grid_type_is_named() {
    let mut bytes = std::fs::read(vdb_fixture("xform_scaletranslate.vdb")).unwrap();
    let pat = b"Tree_float_5_4_3";
    let at = bytes.windows(pat.len()).position(|w| w == pat).unwrap();
    bytes[at..at + pat.len()].copy_from_slice(b"Tree_int32_5_4_3");
    let f = VdbFile::from_bytes("patched.vdb", bytes).unwrap();
    assert_eq!(f.grid_names(), vec!["density".to_string()]);
    let e = f.read_grid("density").unwrap_err();
    assert!(matches!(e, VdbError::UnsupportedType { .. }));
    assert!(e.to_string().contains("Tree_int32_5_4_3"), "{e}");
}

#[test]
fn non_finite_values_are_reported_and_refused() {
    use velour::grid::{ChannelKind, SparseGridBuilder, Storage};
    use velour::vdb::{write_vdb_to_vec, GridToWrite, WriteOptions};
    let mut b = SparseGridBuilder::new(Storage::F32);
    b.add_channel("density", ChannelKind::Scalar, glam::Vec3::ZERO);
    b.set_value(0, IVec3::new(1, 2, 3), 0.5).unwrap();
    b.set_value(0, IVec3::new(1, 2, 4), f32::NAN).unwrap();
    b.set_value(0, IVec3::new(9, 2, 4), f32::INFINITY).unwrap();
    let g = b.build();
    let bytes =
        write_vdb_to_vec(&[GridToWrite::new("smoke", &g)], &WriteOptions::default()).unwrap();
    let back = VdbFile::from_bytes("nan.vdb", bytes)
        .unwrap()
        .read_grid("smoke")
        .unwrap();
    let s = back.stats();
    assert_eq!(s.non_finite, 2);
    assert_eq!(s.max[0], 0.5);
    let e = back.check_finite().unwrap_err();
    assert!(e.to_string().contains("smoke"), "{e}");
}

/// Files written by OpenVDB's C++ API (`tools/vdb/make_cpp_fixtures.cpp`): double and vec3d
/// grids, zip and blosc without active-mask compression, half, root/128^3/8^3 tiles, an
/// inactive non-background tile, affine maps, an instanced grid (sharing its parent's tree);
/// figures computed by OpenVDB itself.
#[test]
fn cpp_fixtures_match_openvdb_figures() {
    let text = std::fs::read_to_string(vdb_fixture("cpp/truth_cpp.jsonl")).unwrap();
    let mut seen = std::collections::BTreeSet::new();
    for line in text.lines() {
        let t: Value = serde_json::from_str(line).unwrap();
        let file = t["file"].as_str().unwrap();
        let name = t["name"].as_str().unwrap();
        let g = VdbFile::open(vdb_fixture(&format!("cpp/{file}")))
            .unwrap()
            .read_grid(name)
            .unwrap();
        let s = g.stats();
        let w = format!("{file} {name}");
        assert_eq!(g.value_type.name(), t["type"].as_str().unwrap(), "{w}");
        assert_eq!(g.map.type_name(), t["map"].as_str().unwrap(), "{w}");
        assert_eq!(g.saved_as_half, t["save_half"].as_bool().unwrap(), "{w}");
        assert_eq!(s.active_voxels, t["active_voxels"].as_u64().unwrap(), "{w}");
        assert_eq!(s.leaf_count, t["leaf_count"].as_u64().unwrap(), "{w}");
        assert_eq!(
            s.active_voxels_by_level.to_vec(),
            counts(&t["active_voxels_by_depth"]),
            "{w}"
        );
        let bb = t["active_bbox"].as_array().unwrap();
        let (lo, hi) = s.active_bbox.unwrap();
        assert_eq!(lo.as_dvec3().to_array(), vec3(&bb[0]), "{w}");
        assert_eq!(hi.as_dvec3().to_array(), vec3(&bb[1]), "{w}");
        // Doubles are stored as f32: compare to f32 precision.
        let rel = if g.value_type.component_bytes() == 8 {
            1e-7
        } else {
            1e-12
        };
        let n = s.components;
        let get = |k: &str| components(&t[k]);
        let (mn, mx, sm, bg) = (get("min"), get("max"), get("sum"), get("background"));
        for k in 0..n {
            assert_close(s.min[k], mn[k], rel, &format!("{w} min"));
            assert_close(s.max[k], mx[k], rel, &format!("{w} max"));
            assert_close(s.sum[k], sm[k], 1e-6, &format!("{w} sum"));
            assert_eq!(
                f64::from(g.grid.background_vec3(0)[k]),
                bg[k],
                "{w} background"
            );
        }
        if n == 1 {
            let want = vec3(&t["moment"]);
            for (&got, &expected) in s.moment.iter().zip(&want) {
                assert_close(got, expected, 1e-6, &format!("{w} moment"));
            }
        }
        assert_index_to_world(&t, g.grid.index_to_world(), 1e-12, &w);
        // The inactive 128^3 tile with a non-background value is kept.
        let inactive = g.grid.value_at_vec3(0, IVec3::new(5, 600, 5));
        assert!(!g.grid.is_active(IVec3::new(5, 600, 5)));
        assert_ne!(inactive, g.grid.background_vec3(0), "{w}");
        seen.insert((g.value_type.name(), g.compression_flags, g.saved_as_half));
    }
    // double, vec3d, float, vec3s x zip, blosc (no mask), zip + mask, each full and half.
    assert_eq!(seen.len(), 20, "{seen:?}");
    assert_eq!(
        text.lines()
            .filter(|l| l.contains("density_instance"))
            .count(),
        5
    );
    // Unsupported grids and maps give errors that name them.
    let f = VdbFile::open(vdb_fixture("cpp/cpp_unsupported.vdb")).unwrap();
    for (grid, what) in [
        ("labels", "Tree_int32_5_4_3"),
        ("mask", "Tree_bool_5_4_3"),
        ("frustum", "NonlinearFrustumMap"),
    ] {
        let e = f.read_grid(grid).unwrap_err().to_string();
        assert!(e.contains(what) && e.contains(grid), "{e}");
    }
}
