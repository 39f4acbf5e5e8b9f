//! `velour inspect FILE.vdb [--json]`: per grid, the figures OpenVDB's tools give.

use super::CliResult;
use crate::vdb::{GridStats, VdbFile, VdbGrid};
use std::path::PathBuf;

/// Arguments of `velour inspect`.
#[derive(Debug, clap::Args)]
pub struct InspectArgs {
    /// The OpenVDB file to describe.
    pub file: PathBuf,
    /// Print one JSON object per grid (one per line) instead of text.
    #[arg(long)]
    pub json: bool,
}

fn json_num(x: f64) -> serde_json::Value {
    serde_json::Number::from_f64(x).map_or(serde_json::Value::Null, serde_json::Value::Number)
}

fn comps(v: &[f64; 3], n: usize) -> serde_json::Value {
    if n == 1 {
        json_num(v[0])
    } else {
        serde_json::Value::Array(v.iter().map(|&x| json_num(x)).collect())
    }
}

/// A JSON description of a grid with the field names of the fixtures' `truth.jsonl`.
#[must_use]
pub fn grid_json(file: &str, g: &VdbGrid, s: &GridStats) -> serde_json::Value {
    let m = g.grid.index_to_world();
    let pt = |p: glam::DVec3| serde_json::json!(m.transform_point3(p).to_array());
    let n = s.components;
    let bg = g.grid.background_vec3(0);
    let bg = [f64::from(bg.x), f64::from(bg.y), f64::from(bg.z)];
    let mut j = serde_json::json!({
        "file": file,
        "name": g.name,
        "type": g.value_type.name(),
        "class": g.class,
        "background": comps(&bg, n),
        "map": g.map.type_name(),
        "voxel_size": g.grid.voxel_size().to_array(),
        "index_to_world_origin": pt(glam::DVec3::ZERO),
        "index_to_world_x1": pt(glam::DVec3::X),
        "index_to_world_y1": pt(glam::DVec3::Y),
        "index_to_world_z1": pt(glam::DVec3::Z),
        "active_voxels": s.active_voxels,
        "active_leaf_voxels": s.active_voxels_by_level[3],
        "leaf_count": s.leaf_count,
        "active_voxels_by_depth": s.active_voxels_by_level,
        "active_bbox": s.active_bbox.map(|(a, b)| [a.to_array(), b.to_array()]),
        "save_half": g.saved_as_half,
        "file_compression": compression_name(g.compression_flags),
        "min": comps(&s.min, n),
        "max": comps(&s.max, n),
        "sum": comps(&s.sum, n),
        "non_finite": s.non_finite,
    });
    if n == 1 {
        j["moment"] = serde_json::json!(s.moment);
    } else {
        j["sum_len"] = json_num(s.sum_len);
    }
    j
}

/// OpenVDB's name of a compression flag set (`blosc + active values`, `zip`, `none`, ...).
#[must_use]
pub fn compression_name(flags: u32) -> String {
    let mut parts = Vec::new();
    if flags & 1 != 0 {
        parts.push("zip");
    }
    if flags & 4 != 0 {
        parts.push("blosc");
    }
    if flags & 2 != 0 {
        parts.push("active values");
    }
    if parts.is_empty() {
        "none".into()
    } else {
        parts.join(" + ")
    }
}

fn fmt3(v: &[f64; 3], n: usize) -> String {
    if n == 1 {
        format!("{}", v[0])
    } else {
        format!("[{}, {}, {}]", v[0], v[1], v[2])
    }
}

/// Runs `velour inspect`.
pub fn run(args: &InspectArgs) -> CliResult {
    let file = VdbFile::open(&args.file)?;
    let fname = args.file.display().to_string();
    if !args.json {
        println!(
            "{fname}: OpenVDB file version {}, written by library {}.{}",
            file.version, file.library_version.0, file.library_version.1
        );
    }
    for g in file.read_all()? {
        let s = g.stats();
        if args.json {
            println!("{}", grid_json(&fname, &g, &s));
            continue;
        }
        let n = s.components;
        let m = g.grid.index_to_world();
        println!("grid '{}'", g.name);
        println!(
            "  value type:     {}{}",
            g.value_type.name(),
            if g.saved_as_half {
                " (saved as half)"
            } else {
                ""
            }
        );
        println!("  class:          {}", g.class);
        println!(
            "  compression:    {}",
            compression_name(g.compression_flags)
        );
        println!(
            "  transform:      {} voxel size {:?}",
            g.map.type_name(),
            g.grid.voxel_size().to_array()
        );
        println!(
            "    index (0,0,0) -> world {:?}",
            m.transform_point3(glam::DVec3::ZERO).to_array()
        );
        println!(
            "    linear part rows {:?}",
            m.matrix3.transpose().to_cols_array_2d()
        );
        println!(
            "  background:     {}",
            fmt3(&g.grid.background_vec3(0).as_dvec3().to_array(), n)
        );
        println!(
            "  active voxels:  {} (root tiles {}, 128^3 tiles {}, 8^3 tiles {}, leaf voxels {})",
            s.active_voxels,
            s.active_voxels_by_level[0],
            s.active_voxels_by_level[1],
            s.active_voxels_by_level[2],
            s.active_voxels_by_level[3]
        );
        println!("  leaf count:     {}", s.leaf_count);
        if let Some((a, b)) = s.active_bbox {
            println!("  active bbox:    {:?} -> {:?}", a.to_array(), b.to_array());
        }
        println!("  min:            {}", fmt3(&s.min, n));
        println!("  max:            {}", fmt3(&s.max, n));
        println!("  sum:            {}", fmt3(&s.sum, n));
        if s.non_finite > 0 {
            println!(
                "  WARNING: {} active values are NaN or infinite (left out of min/max/sum)",
                s.non_finite
            );
        }
    }
    Ok(())
}
