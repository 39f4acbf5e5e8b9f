//! `velour weave`: generates a woven fabric patch (procedural yarns on a weave pattern),
//! voxelises it into density, tangent and id grids and writes them as OpenVDB; optionally
//! the fibres as OBJ polylines, mip levels, a lit PNG preview and statistics.

use super::CliResult;
use crate::fabric::{
    generate_patch, render_preview, voxelise, write_patch_vdb_with_metadata, PreviewOptions,
    VoxeliseOptions, WeaveParams, WeavePattern, WeaveRecord, YarnParams,
};
use crate::grid::Storage;
use std::path::PathBuf;
use std::time::Instant;

/// Arguments of `velour weave`.
#[derive(Debug, clap::Args)]
pub struct WeaveArgs {
    /// Weave pattern: plain, twill (= twill22), twill21, twill22, twill31, basket, satin,
    /// sateen, velvet.
    #[arg(long, default_value = "plain")]
    pub pattern: String,
    /// Yarn preset for warp and weft (cotton1, cotton2, polyester1, rayon1..4, silk1, silk2;
    /// aliases cotton, polyester, rayon, silk). Lengths in cm.
    #[arg(long, default_value = "cotton1")]
    pub yarn: String,
    /// Yarn preset of the warps (overrides --yarn for the warps).
    #[arg(long)]
    pub warp_yarn: Option<String>,
    /// Yarn preset of the wefts (overrides --yarn for the wefts).
    #[arg(long)]
    pub weft_yarn: Option<String>,
    /// Voxels across the tile's largest side (1..=8192).
    #[arg(long, default_value_t = 256, allow_hyphen_values = true)]
    pub resolution: i64,
    /// Flyaway amount: multiplies the fitted hair and loop densities (0 = none, 1 = as
    /// fitted, up to 100).
    #[arg(long, default_value_t = 1.0, allow_hyphen_values = true)]
    pub flyaways: f32,
    /// Pattern repeats in x and y: `N` or `NxM` (each 1..=1024).
    #[arg(long, default_value = "2")]
    pub repeats: String,
    /// Random seed of the fibre generator.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Save the density grids as 16-bit halves.
    #[arg(long)]
    pub half: bool,
    /// Also write the fibres as Wavefront OBJ polylines.
    #[arg(long)]
    pub obj: Option<PathBuf>,
    /// Output OpenVDB file (grids density, tangent, id; the generator parameters as file
    /// metadata `velour_weave.*`, so that `interior = { type = "fabric", file = … }` renders it).
    #[arg(short = 'o', long = "output")]
    pub output: Option<PathBuf>,
    /// Extra mip levels written as density_mip1, tangent_mip1, id_mip1, ... (0..=8).
    #[arg(long, default_value_t = 0, allow_hyphen_values = true)]
    pub mip: i64,
    /// Print fibre counts, volumes, conservation error, active voxels, memory and timings.
    #[arg(long)]
    pub stats: bool,
    /// Render a lit swatch of the patch to this PNG (stand-alone single-scattering ray
    /// marcher, see docs/fabric.md).
    #[arg(long)]
    pub preview: Option<PathBuf>,
    /// Preview size in pixels (16..=4096).
    #[arg(long, default_value_t = 512, allow_hyphen_values = true)]
    pub preview_size: i64,
    /// Tiles across the preview (1..=16).
    #[arg(long, default_value_t = 2, allow_hyphen_values = true)]
    pub preview_tiles: i64,
}

fn preset(flag: &str, name: &str) -> Result<YarnParams, String> {
    YarnParams::preset(name).map_err(|e| format!("{flag}: {e}"))
}

fn parse_repeats(s: &str) -> Result<[u32; 2], String> {
    let bad =
        || format!("--repeats `{s}` is invalid: allowed N or NxM with each count in 1..=1024");
    let parts: Vec<&str> = s.split(['x', 'X']).collect();
    let nums: Result<Vec<u32>, _> = parts.iter().map(|p| p.trim().parse::<u32>()).collect();
    let nums = nums.map_err(|_| bad())?;
    let r = match nums.as_slice() {
        [n] => [*n, *n],
        [a, b] => [*a, *b],
        _ => return Err(bad()),
    };
    if r.iter().any(|&n| n == 0 || n > 1024) {
        return Err(bad());
    }
    Ok(r)
}

/// Checks the flags and builds the weave parameters (errors name the flag and its range).
fn params(args: &WeaveArgs) -> Result<WeaveParams, String> {
    let pattern = WeavePattern::from_name(&args.pattern).map_err(|e| format!("--pattern: {e}"))?;
    let base = preset("--yarn", &args.yarn)?;
    let warp = match &args.warp_yarn {
        Some(n) => preset("--warp-yarn", n)?,
        None => base.clone(),
    };
    let weft = match &args.weft_yarn {
        Some(n) => preset("--weft-yarn", n)?,
        None => base,
    };
    if !(args.flyaways.is_finite() && (0.0..=100.0).contains(&args.flyaways)) {
        return Err(format!(
            "--flyaways {} is invalid: allowed [0, 100] (0 = none, 1 = as fitted)",
            args.flyaways
        ));
    }
    let mut p = WeaveParams::with_yarns(pattern, warp, weft);
    p.flyaway_fraction = args.flyaways;
    p.repeats = parse_repeats(&args.repeats)?;
    Ok(p)
}

fn check_args(args: &WeaveArgs) -> Result<(), String> {
    if !(1..=i64::from(crate::fabric::voxelise::MAX_RESOLUTION)).contains(&args.resolution) {
        return Err(format!(
            "--resolution {} is invalid: allowed 1..={} voxels across the tile's largest side",
            args.resolution,
            crate::fabric::voxelise::MAX_RESOLUTION
        ));
    }
    if !(0..=8).contains(&args.mip) {
        return Err(format!(
            "--mip {} is invalid: allowed 0..=8 extra levels",
            args.mip
        ));
    }
    if !(16..=4096).contains(&args.preview_size) {
        return Err(format!(
            "--preview-size {} is invalid: allowed 16..=4096 pixels",
            args.preview_size
        ));
    }
    if !(1..=16).contains(&args.preview_tiles) {
        return Err(format!(
            "--preview-tiles {} is invalid: allowed 1..=16",
            args.preview_tiles
        ));
    }
    if args.output.is_none() && args.obj.is_none() && args.preview.is_none() && !args.stats {
        return Err("nothing to do: give -o patch.vdb, --obj, --preview or --stats".to_string());
    }
    Ok(())
}

/// Runs `velour weave`.
pub fn run(args: &WeaveArgs) -> CliResult {
    check_args(args)?;
    let p = params(args)?;
    let t0 = Instant::now();
    let patch = generate_patch(&p, args.seed)?;
    let t_gen = t0.elapsed().as_secs_f64();
    if let Some(obj) = &args.obj {
        let f = std::fs::File::create(obj).map_err(|e| format!("--obj {}: {e}", obj.display()))?;
        let mut w = std::io::BufWriter::new(f);
        patch.write_obj(&mut w)?;
        std::io::Write::flush(&mut w).map_err(|e| format!("--obj {}: {e}", obj.display()))?;
    }
    let need_grid = args.output.is_some() || args.preview.is_some() || args.stats;
    if !need_grid {
        return Ok(());
    }
    let t1 = Instant::now();
    let opts = VoxeliseOptions {
        storage: Storage::F32,
        wrap: true,
        keep_accumulators: args.mip > 0,
    };
    let vp = voxelise(&patch, args.resolution as u32, &opts)
        .map_err(|e| format!("--resolution {}: {e}", args.resolution))?;
    let t_vox = t1.elapsed().as_secs_f64();
    let t2 = Instant::now();
    let mut mips = Vec::new();
    for l in 1..=args.mip as u32 {
        mips.push(vp.mip(l)?);
    }
    let t_mip = t2.elapsed().as_secs_f64();
    let t3 = Instant::now();
    if let Some(out) = &args.output {
        let mut levels = vec![&vp];
        levels.extend(mips.iter());
        let names = [
            args.pattern.as_str(),
            args.warp_yarn.as_deref().unwrap_or(&args.yarn),
            args.weft_yarn.as_deref().unwrap_or(&args.yarn),
        ];
        let record = WeaveRecord::new(
            names,
            &p,
            args.seed,
            args.resolution as u32,
            patch.pile_albedo,
            &vp,
        );
        write_patch_vdb_with_metadata(out, &levels, args.half, &record.to_metadata())?;
    }
    let t_write = t3.elapsed().as_secs_f64();
    let t4 = Instant::now();
    if let Some(png) = &args.preview {
        let popts = PreviewOptions {
            size: args.preview_size as u32,
            tiles: args.preview_tiles as u32,
            ..PreviewOptions::default()
        };
        let img = render_preview(
            &vp,
            [patch.warp_albedo, patch.weft_albedo, patch.pile_albedo],
            &popts,
        )?;
        img.write_png(png)?;
    }
    let t_prev = t4.elapsed().as_secs_f64();
    if args.stats {
        let s = vp.stats(patch.fibre_volume);
        let count = |f: fn(&crate::fabric::YarnId) -> bool| {
            patch.fibres.iter().filter(|x| f(&x.yarn)).count()
        };
        use crate::fabric::YarnId;
        println!(
            "pattern {}  warp {}  weft {}  tile {:.4} x {:.4} (patch units, cm for presets)",
            p.pattern.name(),
            args.warp_yarn.as_deref().unwrap_or(&args.yarn),
            args.weft_yarn.as_deref().unwrap_or(&args.yarn),
            patch.tile.x,
            patch.tile.y
        );
        println!(
            "fibres {} (warp {}, weft {}, pile {}; loops {}, hairs {})",
            patch.fibres.len(),
            count(|y| matches!(y, YarnId::Warp(_))),
            count(|y| matches!(y, YarnId::Weft(_))),
            count(|y| matches!(y, YarnId::Pile)),
            patch.loop_count,
            patch.hair_count
        );
        let d = vp
            .grid
            .active_bbox()
            .map_or([0; 3], |(a, b)| (b - a + 1).to_array());
        println!(
            "grid {} x {} x {} voxels (active bbox), voxel {:.3e} x {:.3e} x {:.3e}, {} bricks",
            d[0], d[1], d[2], vp.voxel_size.x, vp.voxel_size.y, vp.voxel_size.z, s.bricks
        );
        println!(
            "fibre volume {:.6e}  voxel volume {:.6e}  conservation error {:+.3e}  clamped {:.3e}",
            patch.fibre_volume, s.voxel_volume_sum, s.conservation_error, vp.clamped_volume
        );
        println!(
            "active voxels {}  deposits {}  grid memory {:.1} MiB = {:.1} bytes per active voxel (accumulators kept for mips {:.1} MiB)",
            s.active_voxels,
            vp.deposits,
            s.grid_bytes as f64 / (1 << 20) as f64,
            s.bytes_per_active_voxel,
            s.accumulator_bytes as f64 / (1 << 20) as f64
        );
        for m in &mips {
            let ms = m.stats(patch.fibre_volume);
            println!(
                "mip {}: voxel {:.3e}, active voxels {}, conservation error {:+.3e}",
                m.level, m.voxel_size.x, ms.active_voxels, ms.conservation_error
            );
        }
        println!(
            "time: generate {t_gen:.3} s, voxelise {t_vox:.3} s ({} threads), mips {t_mip:.3} s, write {t_write:.3} s, preview {t_prev:.3} s",
            rayon::current_num_threads()
        );
    }
    Ok(())
}
