//! Interoperability with real OpenVDB (Debian's `python3-openvdb` and `libopenvdb-tools`,
//! installed by `.ci/run`): we read what OpenVDB writes with every codec, half floats, vec3s,
//! tiles at every level and every linear map, and OpenVDB reads what we write with the same
//! statistics. The tests that run OpenVDB skip with a notice when it is missing, and fail
//! instead under `VELOUR_REQUIRE_EXTERNAL=1` (as in CI); our own round trips always run.

mod common;

use common::external::{self, OPENVDB_TOOLS_PACKAGE};
use common::files::{repo_path, vdb_fixture, TempDir};
use common::vdb_figures::{assert_close, assert_index_to_world, components, counts, number, vec3};
use glam::{DAffine3, DMat3, DVec3, IVec3, Vec3};
use serde_json::Value;
use std::path::{Path, PathBuf};
use velour::grid::{ChannelKind, SparseGrid, SparseGridBuilder, Storage, TileLevel};
use velour::sampling::Rng;
use velour::vdb::{
    read_vdb, read_vdb_grids, write_vdb, Compression, GridStats, GridToWrite, VdbFile, VdbGrid,
    WriteOptions,
};

/// Coordinates at which OpenVDB's and our values are compared: noise, tiles of every level
/// (active and inactive), level-set interiors and far background.
fn probe_coords() -> Vec<[i32; 3]> {
    let mut rng = Rng::new(11, 0);
    let mut v = Vec::new();
    for _ in 0..400 {
        let r = |rng: &mut Rng| (rng.next_f32() * 44.0 - 22.0).floor() as i32;
        v.push([r(&mut rng), r(&mut rng), r(&mut rng)]);
    }
    v.extend_from_slice(&[
        [130, 5, 5],
        [255, 127, 127],
        [8197, 5, 5],
        [8192 + 4095, 4095, 4095],
        [-8000, 5, 5],
        [3, 3, 66],
        [0, 0, -2],
        [1, 1, -1],
        [515, 3, 3],
        [2, 258, 2],
        [67, 66, 65],
        [100000, -100000, 7],
    ]);
    v
}

fn write_coords(dir: &Path) -> PathBuf {
    let p = dir.join("coords.json");
    std::fs::write(&p, serde_json::to_string(&probe_coords()).unwrap()).unwrap();
    p
}

/// OpenVDB's statistics of every grid of `files`, one JSON object per grid.
fn openvdb_stats(dir: &Path, files: &[PathBuf]) -> Vec<Value> {
    let coords = write_coords(dir);
    let script = repo_path("tools/vdb/ovdb_stats.py");
    let mut args = vec![script, "--coords".into(), coords];
    args.extend(files.iter().cloned());
    external::run_python(&args)
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

/// Our grid against OpenVDB's figures for the same file. `values` compares the probes.
fn compare(t: &Value, g: &VdbGrid, s: &GridStats, what: &str) {
    let w = |k: &str| format!("{what} [{}] {k}", g.name);
    assert_eq!(t["name"].as_str().unwrap(), g.name, "{}", w("name"));
    assert_eq!(
        t["type"].as_str().unwrap(),
        g.value_type.name(),
        "{}",
        w("type")
    );
    assert_eq!(t["class"].as_str().unwrap(), g.class, "{}", w("class"));
    assert_eq!(
        t["save_half"].as_bool().unwrap(),
        g.saved_as_half,
        "{}",
        w("half")
    );
    assert_eq!(
        t["active_voxels"].as_u64().unwrap(),
        s.active_voxels,
        "{}",
        w("active voxels")
    );
    assert_eq!(
        t["leaf_count"].as_u64().unwrap(),
        s.leaf_count,
        "{}",
        w("leaf count")
    );
    assert_eq!(
        counts(&t["active_voxels_by_depth"]),
        s.active_voxels_by_level.to_vec(),
        "{}",
        w("by depth")
    );
    let bb = t["active_bbox"].as_array().unwrap();
    let (lo, hi) = s.active_bbox.expect("bbox");
    assert_eq!(vec3(&bb[0]), lo.as_dvec3().to_array(), "{}", w("bbox"));
    assert_eq!(vec3(&bb[1]), hi.as_dvec3().to_array(), "{}", w("bbox"));
    let n = s.components;
    let bg = g.grid.background_vec3(0);
    assert_eq!(
        components(&t["background"]),
        [bg.x, bg.y, bg.z][..n]
            .iter()
            .map(|&x| f64::from(x))
            .collect::<Vec<_>>(),
        "{}",
        w("background")
    );
    let (mn, mx, sm) = (
        components(&t["min"]),
        components(&t["max"]),
        components(&t["sum"]),
    );
    for k in 0..n {
        assert_close(s.min[k], mn[k], 1e-12, &w("min"));
        assert_close(s.max[k], mx[k], 1e-12, &w("max"));
        assert_close(s.sum[k], sm[k], 1e-6, &w("sum"));
    }
    if n == 1 {
        let m = components(&t["moment"]);
        let ext = lo.abs().max(hi.abs()).max_element() as f64 + 1.0;
        for k in 0..3 {
            assert!(
                (s.moment[k] - m[k]).abs() <= 1e-7 * s.sum[0].abs() * ext + 1e-9,
                "{}: {:?} vs {m:?}",
                w("moment"),
                s.moment
            );
        }
    } else {
        assert_close(s.sum_len, number(&t["sum_len"]), 1e-6, &w("sum_len"));
    }
    assert_index_to_world(t, g.grid.index_to_world(), 1e-9, &w("map"));
    let vals = t["values"].as_array().unwrap();
    let mut acc = g.grid.accessor(0);
    for (c, v) in probe_coords().iter().zip(vals) {
        let ijk = IVec3::from_array(*c);
        let ours = acc.value_vec3(ijk);
        let want = components(v);
        for k in 0..n {
            // Compare as f32: the JSON text of an f32 widened to f64 may parse 1 ulp (f64) off.
            assert_eq!(ours[k], want[k] as f32, "{} at {ijk}", w("value"));
        }
    }
}

fn find<'a>(all: &'a [Value], file: &Path, name: &str) -> &'a Value {
    all.iter()
        .find(|t| t["file"].as_str() == file.to_str() && t["name"].as_str() == Some(name))
        .unwrap_or_else(|| panic!("OpenVDB gave no figures for {} grid {name}", file.display()))
}

#[test]
fn we_read_what_openvdb_writes() {
    if !(external::require_python_openvdb()
        && external::require_tool("vdb_tool", OPENVDB_TOOLS_PACKAGE))
    {
        return;
    }
    let tmp = TempDir::new("interop-read");
    let dir = tmp.path();
    let script = repo_path("tools/vdb/make_interop.py");
    let list = external::run_python([script.as_path(), dir]);
    let files: Vec<PathBuf> = list.lines().map(PathBuf::from).collect();
    assert!(files.len() >= 24, "{list}");
    let theirs = openvdb_stats(dir, &files);
    let mut grids_checked = 0;
    let mut codecs = std::collections::BTreeSet::new();
    let mut maps = std::collections::BTreeSet::new();
    for f in &files {
        let grids = read_vdb(f).unwrap_or_else(|e| panic!("{e}"));
        for g in &grids {
            let t = find(&theirs, f, &g.name);
            compare(t, g, &g.stats(), &f.display().to_string());
            codecs.insert(g.compression_flags);
            maps.insert(g.map.type_name());
            grids_checked += 1;
        }
    }
    // Every codec (none, zip, blosc, each with active masks, and active-mask only) and map.
    assert_eq!(codecs.into_iter().collect::<Vec<_>>(), vec![0, 2, 3, 6]);
    for m in [
        "AffineMap",
        "UniformScaleMap",
        "ScaleMap",
        "ScaleTranslateMap",
        "UniformScaleTranslateMap",
    ] {
        assert!(maps.contains(m), "{m} not covered");
    }
    assert!(grids_checked >= 32);
    // Only the grids asked for are loaded, in the order asked.
    let multi = dir.join("multi_zip.vdb");
    let two = read_vdb_grids(&multi, &["vel", "density"]).unwrap();
    assert_eq!(
        two.iter().map(|g| g.name.as_str()).collect::<Vec<_>>(),
        ["vel", "density"]
    );
    let e = read_vdb_grids(&multi, &["smoke"]).unwrap_err().to_string();
    assert!(
        ["smoke", "density", "temperature", "vel"]
            .iter()
            .all(|n| e.contains(n)),
        "{e}"
    );
}

/// A grid with everything the writer must handle: a root tile, 128^3 and 8^3 tiles (active
/// and inactive with non-background values), noisy bricks with inactive voxels of many
/// values, and a rotated map.
fn rich_grid(storage: Storage) -> SparseGrid {
    let mut rng = Rng::new(23, 0);
    let mut b = SparseGridBuilder::new(storage);
    b.add_channel("density", ChannelKind::Scalar, Vec3::splat(0.0));
    for x in -13..12 {
        for y in -7..9 {
            for z in -5..14 {
                let p = IVec3::new(x, y, z);
                let v = rng.next_f32() * 3.0 - 0.5;
                b.set_value(0, p, v).unwrap();
                if rng.next_f32() < 0.25 {
                    b.set_active(p, false).unwrap();
                }
            }
        }
    }
    // Bricks whose inactive voxels are all one non-background value (flag 2).
    for x in 32..40 {
        for y in 0..8 {
            for z in 0..8 {
                b.set_value(0, IVec3::new(x, y, z), 0.9).unwrap();
            }
        }
    }
    b.set_active(IVec3::new(33, 1, 1), false).unwrap();
    b.set_tile(TileLevel::Root, IVec3::new(2, 0, 0), &[0.25], true)
        .unwrap();
    b.set_tile(TileLevel::Root, IVec3::new(-2, 0, 0), &[3.0], false)
        .unwrap();
    b.set_tile(TileLevel::Block, IVec3::new(1, 0, 0), &[1.5], true)
        .unwrap();
    b.set_tile(TileLevel::Block, IVec3::new(0, 2, 0), &[-2.0], false)
        .unwrap();
    b.set_tile(TileLevel::Brick, IVec3::new(0, 0, 8), &[0.75], true)
        .unwrap();
    b.set_tile(TileLevel::Brick, IVec3::new(0, 0, 9), &[0.5], false)
        .unwrap();
    let m = DAffine3 {
        matrix3: DMat3::from_rotation_y(0.4) * DMat3::from_diagonal(DVec3::new(0.1, 0.1, 0.2)),
        translation: DVec3::new(0.5, -1.0, 2.0),
    };
    b.set_index_to_world(m).unwrap();
    b.build()
}

fn vec_grid() -> SparseGrid {
    let mut rng = Rng::new(29, 0);
    let mut b = SparseGridBuilder::new(Storage::F32);
    b.add_channel("velocity", ChannelKind::Vec3, Vec3::ZERO);
    for x in -9..9 {
        for y in -5..9 {
            for z in 0..11 {
                let v = Vec3::new(rng.next_f32() - 0.5, rng.next_f32(), rng.next_f32() * 2.0);
                b.set_value_vec3(0, IVec3::new(x, y, z), v).unwrap();
            }
        }
    }
    b.set_tile(
        TileLevel::Brick,
        IVec3::new(8, 8, 8),
        &[1.0, -2.0, 0.5],
        true,
    )
    .unwrap();
    b.set_index_to_world(DAffine3::from_translation(DVec3::new(1.0, 2.0, 3.0)))
        .unwrap();
    b.build()
}

/// One grid written by [`write_interop_files`]: its file, name, the statistics of the source
/// grid and whether it was saved as half floats.
struct WrittenGrid {
    path: PathBuf,
    name: String,
    source_stats: GridStats,
    half: bool,
}

/// Writes a rich scalar grid, a vec3 grid and a committed fixture with every codec, with and
/// without active masks, at full and half precision; returns the files and what they hold.
fn write_interop_files(dir: &Path) -> (Vec<PathBuf>, Vec<WrittenGrid>) {
    let rich = rich_grid(Storage::F32);
    let vel = vec_grid();
    let fixture = read_vdb(vdb_fixture("tiles_internal.vdb"))
        .unwrap()
        .remove(0);
    let mut files = Vec::new();
    let mut written = Vec::new();
    let mut k = 0;
    for compression in [Compression::None, Compression::Zip, Compression::Blosc] {
        for active_mask in [false, true] {
            for half in [false, true] {
                let opts = WriteOptions {
                    compression,
                    active_mask,
                };
                let path = dir.join(format!("ours_{k}.vdb"));
                k += 1;
                let grids = [
                    GridToWrite {
                        class: "fog volume",
                        half,
                        ..GridToWrite::new("density", &rich)
                    },
                    GridToWrite {
                        half,
                        ..GridToWrite::new("velocity", &vel)
                    },
                    GridToWrite {
                        class: &fixture.class,
                        map: Some(fixture.map),
                        ..GridToWrite::new("tiles", &fixture.grid)
                    },
                ];
                write_vdb(&path, &grids, &opts).unwrap();
                for g in &grids {
                    written.push(WrittenGrid {
                        path: path.clone(),
                        name: g.name.to_string(),
                        source_stats: GridStats::compute(g.grid, 0),
                        half: g.half,
                    });
                }
                files.push(path);
            }
        }
    }
    (files, written)
}

/// Our reader on our files: at full precision the figures are those of the grid we wrote.
#[test]
fn we_read_what_we_write() {
    let dir = TempDir::new("interop-roundtrip");
    let (_, written) = write_interop_files(dir.path());
    for w in &written {
        let ours = VdbFile::open(&w.path).unwrap().read_grid(&w.name).unwrap();
        let (s, src_stats) = (ours.stats(), &w.source_stats);
        assert_eq!(s.active_voxels, src_stats.active_voxels);
        assert_eq!(s.leaf_count, src_stats.leaf_count);
        if !w.half {
            assert_eq!(&s, src_stats, "{} {}", w.path.display(), w.name);
        } else {
            for c in 0..s.components {
                let h = |x: f64| f64::from(half::f16::from_f32(x as f32).to_f32());
                assert_eq!(s.min[c], h(src_stats.min[c]));
                assert_eq!(s.max[c], h(src_stats.max[c]));
                assert_close(s.sum[c], src_stats.sum[c], 1e-3, "half sum");
            }
        }
    }
}

/// OpenVDB and our reader agree on our files, values included.
#[test]
fn openvdb_reads_what_we_write() {
    if !external::require_python_openvdb() {
        return;
    }
    let dir = TempDir::new("interop-write");
    let (files, written) = write_interop_files(dir.path());
    let theirs = openvdb_stats(dir.path(), &files);
    for w in &written {
        let ours = VdbFile::open(&w.path).unwrap().read_grid(&w.name).unwrap();
        compare(
            find(&theirs, &w.path, &w.name),
            &ours,
            &ours.stats(),
            &format!("our file {}", w.path.display()),
        );
    }
}

/// The fixtures `velour convert` rewrites in [`convert_command_rewrites_every_grid`] and
/// [`openvdb_reads_converted_files`]: (input, half, codec).
const CONVERSIONS: [(&str, bool, &str); 4] = [
    ("sphere_fog.vdb", false, "zip"),
    ("velocity_vec3s.vdb", true, "blosc"),
    ("xform_scaletranslate.vdb", false, "none"),
    ("noise_fbm_half.vdb", false, "zip"),
];

/// Converts every fixture of [`CONVERSIONS`] into `dir`; returns (source, output, half).
fn convert_fixtures(dir: &Path) -> Vec<(PathBuf, PathBuf, bool)> {
    use velour::cli::convert::{run, ConvertArgs};
    CONVERSIONS
        .iter()
        .map(|&(input, half, codec)| {
            let src = vdb_fixture(input);
            let out = dir.join(format!("conv_{input}"));
            run(&ConvertArgs {
                input: src.clone(),
                output: out.clone(),
                half,
                compression: codec.into(),
                no_active_mask: false,
            })
            .unwrap();
            (src, out, half)
        })
        .collect()
}

#[test]
fn convert_command_rewrites_every_grid() {
    use velour::cli::convert::{run, ConvertArgs};
    let tmp = TempDir::new("convert");
    let dir = tmp.path();
    for (src, out, half) in &convert_fixtures(dir) {
        let a = read_vdb(src).unwrap().remove(0);
        let b = read_vdb(out).unwrap().remove(0);
        assert_eq!(a.name, b.name);
        assert_eq!(a.class, b.class);
        assert_eq!(a.value_type, b.value_type);
        assert_eq!(a.map, b.map);
        assert_eq!(b.saved_as_half, *half || a.saved_as_half);
        if !half {
            assert_eq!(a.stats(), b.stats(), "{}", out.display());
        }
    }
    let e = run(&ConvertArgs {
        input: dir.join("missing.vdb"),
        output: dir.join("x.vdb"),
        half: false,
        compression: "zip".into(),
        no_active_mask: false,
    })
    .unwrap_err();
    assert!(e.to_string().contains("missing.vdb"), "{e}");
}

/// OpenVDB and our reader agree on the files `velour convert` writes.
#[test]
fn openvdb_reads_converted_files() {
    if !external::require_python_openvdb() {
        return;
    }
    let tmp = TempDir::new("convert-openvdb");
    let cases = convert_fixtures(tmp.path());
    let files: Vec<PathBuf> = cases.iter().map(|(_, out, _)| out.clone()).collect();
    let theirs = openvdb_stats(tmp.path(), &files);
    for (_, out, _) in &cases {
        let b = read_vdb(out).unwrap().remove(0);
        compare(
            find(&theirs, out, &b.name),
            &b,
            &b.stats(),
            &out.display().to_string(),
        );
    }
}
