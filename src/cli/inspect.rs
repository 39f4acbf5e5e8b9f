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
    let mut buf = String::new();
    macro_rules! outln {
        ($($t:tt)*) => {{
            use std::fmt::Write as _;
            let _ = writeln!(buf, $($t)*);
        }};
    }
    let mut stdout = std::io::stdout();
    let mut flush = |buf: &mut String| -> std::io::Result<()> {
        use std::io::Write as _;
        stdout.write_all(buf.as_bytes())?;
        buf.clear();
        stdout.flush()
    };
    if !args.json {
        outln!(
            "{fname}: OpenVDB file version {}, written by library {}.{}",
            file.version,
            file.library_version.0,
            file.library_version.1
        );
        for e in &file.metadata {
            if let Some(v) = e.display() {
                outln!("  {} ({}): {v}", e.name, e.type_name);
            }
        }
    }
    let mut failures = Vec::new();
    for i in 0..file.grid_names().len() {
        let g = match file.read_index(i) {
            Ok(g) => g,
            Err(e) => {
                // Report the grid and go on with the others; fail at the end.
                eprintln!("error: {e}");
                failures.push(e.to_string());
                continue;
            }
        };
        let s = g.stats();
        if args.json {
            outln!("{}", grid_json(&fname, &g, &s));
            flush(&mut buf)?;
            continue;
        }
        let n = s.components;
        let m = g.grid.index_to_world();
        outln!("grid '{}'", g.name);
        outln!(
            "  value type:     {}{}",
            g.value_type.name(),
            if g.saved_as_half {
                " (saved as half)"
            } else {
                ""
            }
        );
        outln!("  class:          {}", g.class);
        outln!(
            "  compression:    {}",
            compression_name(g.compression_flags)
        );
        outln!(
            "  transform:      {} voxel size {:?}",
            g.map.type_name(),
            g.grid.voxel_size().to_array()
        );
        outln!(
            "    index (0,0,0) -> world {:?}",
            m.transform_point3(glam::DVec3::ZERO).to_array()
        );
        outln!(
            "    linear part rows {:?}",
            m.matrix3.transpose().to_cols_array_2d()
        );
        outln!(
            "  background:     {}",
            fmt3(&g.grid.background_vec3(0).as_dvec3().to_array(), n)
        );
        outln!(
            "  active voxels:  {} (root tiles {}, 128^3 tiles {}, 8^3 tiles {}, leaf voxels {})",
            s.active_voxels,
            s.active_voxels_by_level[0],
            s.active_voxels_by_level[1],
            s.active_voxels_by_level[2],
            s.active_voxels_by_level[3]
        );
        outln!("  leaf count:     {}", s.leaf_count);
        if let Some((a, b)) = s.active_bbox {
            outln!("  active bbox:    {:?} -> {:?}", a.to_array(), b.to_array());
        }
        if s.min[0] <= s.max[0] {
            outln!("  min:            {}", fmt3(&s.min, n));
            outln!("  max:            {}", fmt3(&s.max, n));
            outln!("  sum:            {}", fmt3(&s.sum, n));
        } else {
            outln!("  min, max, sum:  no finite active values");
        }
        if s.non_finite > 0 {
            outln!(
                "  WARNING: {} active values are NaN or infinite (left out of min/max/sum)",
                s.non_finite
            );
        }
        flush(&mut buf)?;
    }
    flush(&mut buf)?;
    if !failures.is_empty() {
        return Err(format!(
            "{}: {} of {} grids could not be read (see above)",
            fname,
            failures.len(),
            file.grid_names().len()
        )
        .into());
    }
    Ok(())
}
