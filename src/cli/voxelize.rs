//! `velour voxelize`: a PLY mesh into an OpenVDB level set (`--levelset`) or fog volume
//! (`--fog`, optionally with rest-space fBm noise), following OpenVDB's conventions
//! (docs/voxelize.md).

use super::CliResult;
use crate::geometry::load_ply;
use crate::voxelize::{voxelize, write, NoiseOptions, VolumeKind, VoxelizeOptions, DEFAULT_WIDTH};
use std::path::PathBuf;
use std::time::Instant;

/// Arguments of `velour voxelize`.
#[derive(Debug, clap::Args)]
#[command(group(clap::ArgGroup::new("kind").required(true).args(["levelset", "fog"])))]
pub struct VoxelizeArgs {
    /// The mesh (PLY, world units). Closed meshes give exact results; open or non-manifold
    /// ones are converted with a warning (the inside is decided by a vote of six axis rays).
    pub mesh: PathBuf,
    /// Output OpenVDB file (one grid: `surface` for --levelset, `density` for --fog).
    #[arg(short = 'o', long = "output")]
    pub output: PathBuf,
    /// Voxel edge in world units (required, > 0); voxel (i, j, k) is centred at (iV, jV, kV).
    #[arg(long, allow_hyphen_values = true)]
    pub voxel_size: f64,
    /// Write a narrow-band signed distance level set (grid `surface`, class `level set`,
    /// negative inside, background = half width × voxel size).
    #[arg(long)]
    pub levelset: bool,
    /// Half width of the level set's band, in voxels (1..=64) [default: 3].
    #[arg(long, allow_hyphen_values = true)]
    pub half_width: Option<f64>,
    /// Write a fog volume (grid `density`, class `fog volume`): 0 outside, a ramp from 0 at the
    /// surface to 1 across --band voxels inside, 1 deeper (OpenVDB's sdfToFogVolume).
    #[arg(long)]
    pub fog: bool,
    /// Width of the fog's ramp inside the surface, in voxels (0 < B ≤ 64) [default: 3].
    #[arg(long, allow_hyphen_values = true)]
    pub band: Option<f64>,
    /// Noise base frequency in 1 / world unit (> 0; fog only) [default: 1].
    #[arg(long, allow_hyphen_values = true)]
    pub noise_frequency: Option<f64>,
    /// Noise amplitude A ≥ 0: the density is multiplied by max(0, 1 + A·fbm(F·p)), fbm ∈ [−1, 1]
    /// at the voxel's rest-space (mesh) position p; 0 = no noise (fog only) [default: 0].
    #[arg(long, allow_hyphen_values = true)]
    pub noise_amplitude: Option<f64>,
    /// Noise octaves (1..=16; lacunarity 2, gain 0.5; fog only) [default: 4].
    #[arg(long, allow_hyphen_values = true)]
    pub noise_octaves: Option<i64>,
    /// Noise seed (fog only) [default: 1].
    #[arg(long)]
    pub noise_seed: Option<u32>,
    /// Print nothing but warnings.
    #[arg(short, long)]
    pub quiet: bool,
}

fn options(args: &VoxelizeArgs) -> Result<VoxelizeOptions, String> {
    let only = |flag: &str, given: bool, mode: &str| {
        if given {
            Err(format!("{flag} applies to {mode} only"))
        } else {
            Ok(())
        }
    };
    let noise_given = args.noise_frequency.is_some()
        || args.noise_amplitude.is_some()
        || args.noise_octaves.is_some()
        || args.noise_seed.is_some();
    let kind = if args.levelset {
        only("--band", args.band.is_some(), "--fog")?;
        only(
            "--noise-amplitude, --noise-frequency, --noise-octaves and --noise-seed",
            noise_given,
            "--fog (noise multiplies a fog density; a level set holds distances)",
        )?;
        VolumeKind::LevelSet {
            half_width: args.half_width.unwrap_or(DEFAULT_WIDTH),
        }
    } else {
        only("--half-width", args.half_width.is_some(), "--levelset")?;
        VolumeKind::Fog {
            band: args.band.unwrap_or(DEFAULT_WIDTH),
        }
    };
    let octaves = args.noise_octaves.unwrap_or(4);
    if !(1..=16).contains(&octaves) {
        return Err(format!(
            "--noise-octaves {octaves} is invalid: allowed 1..=16"
        ));
    }
    let noise = args.fog.then_some(NoiseOptions {
        frequency: args.noise_frequency.unwrap_or(1.0),
        amplitude: args.noise_amplitude.unwrap_or(0.0),
        octaves: octaves as u32,
        seed: args.noise_seed.unwrap_or(1),
    });
    let o = VoxelizeOptions {
        voxel_size: args.voxel_size,
        kind,
        noise,
    };
    o.validate().map_err(|e| e.to_string())?;
    Ok(o)
}

/// Runs `velour voxelize`. Nothing is written when the mesh or a flag is bad.
pub fn run(args: &VoxelizeArgs) -> CliResult {
    let opts = options(args)?;
    let t0 = Instant::now();
    let mesh = load_ply(&args.mesh)?;
    let name = args.mesh.display().to_string();
    let vol = voxelize(&mesh, &name, &opts)?;
    let r = &vol.report;
    let topo = r.topology;
    if topo.boundary_edges > 0 || topo.non_manifold_edges > 0 {
        eprintln!(
            "warning: {name} is not a closed manifold ({topo}); voxels are inside where at \
             least 4 of the 6 axis half-rays cross the surface an odd number of times \
             (docs/voxelize.md), {} band voxels had split votes",
            r.split_votes
        );
    }
    write(&args.output, &vol, &name, &opts)?;
    if !args.quiet {
        let (lo, hi) = r.domain;
        let size = hi - lo + glam::IVec3::ONE;
        println!(
            "{name}: {} triangles ({}), domain {} x {} x {} voxels of {} (world units)",
            r.triangles, topo, size.x, size.y, size.z, opts.voxel_size
        );
        println!(
            "{}: grid `{}` ({}), {} active voxels, {} band bricks, {} inside bricks, {} axis crossings, {} split votes",
            args.output.display(),
            vol.name,
            vol.class,
            r.active_voxels,
            r.band_bricks,
            r.inside_bricks,
            r.crossings,
            r.split_votes
        );
        if args.fog {
            println!(
                "fog integral {:.6e}, mesh volume {:.6e} (ratio {:.4}), mesh area {:.6e}",
                r.integral,
                r.mesh_volume,
                r.integral / r.mesh_volume,
                r.mesh_area
            );
        }
        println!(
            "time {:.3} s ({} threads)",
            t0.elapsed().as_secs_f64(),
            rayon::current_num_threads()
        );
    }
    Ok(())
}
