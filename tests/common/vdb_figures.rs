//! OpenVDB's own figures of a grid, as JSON objects (one a line): the committed truth files
//! under `tests/data/vdb/` and the output of `tools/vdb/ovdb_stats.py`. Reading their fields
//! and comparing them with ours.

use glam::{DAffine3, DVec3};
use serde_json::Value;

/// A JSON number.
pub fn number(v: &Value) -> f64 {
    v.as_f64().unwrap_or_else(|| panic!("not a number: {v}"))
}

/// A scalar as one component, or an array of numbers as its components.
pub fn components(v: &Value) -> Vec<f64> {
    match v.as_array() {
        Some(a) => a.iter().map(number).collect(),
        None => vec![number(v)],
    }
}

/// An array of three numbers.
pub fn vec3(v: &Value) -> [f64; 3] {
    let a = v.as_array().unwrap_or_else(|| panic!("not an array: {v}"));
    assert_eq!(a.len(), 3, "not three numbers: {v}");
    [number(&a[0]), number(&a[1]), number(&a[2])]
}

/// An array of counts (such as `active_voxels_by_depth`).
pub fn counts(v: &Value) -> Vec<u64> {
    v.as_array()
        .unwrap_or_else(|| panic!("not an array: {v}"))
        .iter()
        .map(|c| c.as_u64().unwrap_or_else(|| panic!("not a count: {c}")))
        .collect()
}

/// Asserts `|ours − openvdb| ≤ rel · max(|ours|, |openvdb|)`.
pub fn assert_close(ours: f64, openvdb: f64, rel: f64, what: &str) {
    let tol = rel * ours.abs().max(openvdb.abs());
    assert!(
        (ours - openvdb).abs() <= tol,
        "{what}: ours {ours} vs OpenVDB {openvdb} (tolerance {tol})"
    );
}

/// Asserts that `index_to_world` sends the index-space origin and unit points where the
/// figures `index_to_world_origin`, `_x1`, `_y1` and `_z1` of `t` say, to within `tol` world
/// units per coordinate.
pub fn assert_index_to_world(t: &Value, index_to_world: DAffine3, tol: f64, what: &str) {
    for (key, p) in [
        ("index_to_world_origin", DVec3::ZERO),
        ("index_to_world_x1", DVec3::X),
        ("index_to_world_y1", DVec3::Y),
        ("index_to_world_z1", DVec3::Z),
    ] {
        let want = vec3(&t[key]);
        let got = index_to_world.transform_point3(p).to_array();
        for k in 0..3 {
            assert!(
                (got[k] - want[k]).abs() <= tol,
                "{what} {key}: {got:?} vs {want:?}"
            );
        }
    }
}
