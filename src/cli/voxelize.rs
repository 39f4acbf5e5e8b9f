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
    /// Half width of the level set's band, in voxels (1..=64).
    #[arg(long, default_value_t = DEFAULT_WIDTH, allow_hyphen_values = true, requires = "levelset")]
    pub half_width: f64,
    /// Write a fog volume (grid `density`, class `fog volume`): 0 outside, a ramp from 0 at the
    /// surface to 1 across --band voxels inside, 1 deeper (OpenVDB's sdfToFogVolume).
    #[arg(long)]
    pub fog: bool,
    /// Width of the fog's ramp inside the surface, in voxels (0 < B ≤ 64).
    #[arg(long, default_value_t = DEFAULT_WIDTH, allow_hyphen_values = true, requires = "fog")]
    pub band: f64,
    /// Noise base frequency in 1 / world unit (fog only).
    #[arg(
        long,
        default_value_t = 1.0,
        allow_hyphen_values = true,
        requires = "fog"
    )]
    pub noise_frequency: f64,
    /// Noise amplitude: the density is multiplied by max(0, 1 + A·fbm(F·p)), fbm ∈ [−1, 1] at
    /// the voxel's rest-space (mesh) position p; 0 = no noise (fog only).
    #[arg(
        long,
        default_value_t = 0.0,
        allow_hyphen_values = true,
        requires = "fog"
    )]
    pub noise_amplitude: f64,
    /// Noise octaves (1..=16; lacunarity 2, gain 0.5) (fog only).
    #[arg(
        long,
        default_value_t = 4,
        allow_hyphen_values = true,
        requires = "fog"
    )]
    pub noise_octaves: i64,
    /// Noise seed (fog only).
    #[arg(long, default_value_t = 1, requires = "fog")]
    pub noise_seed: u32,
    /// Print nothing but warnings.
    #[arg(short, long)]
    pub quiet: bool,
}

fn options(args: &VoxelizeArgs) -> Result<VoxelizeOptions, String> {
    let kind = if args.levelset {
        VolumeKind::LevelSet {
            half_width: args.half_width,
        }
    } else {
        VolumeKind::Fog { band: args.band }
    };
    if !(1..=16).contains(&args.noise_octaves) {
        return Err(format!(
            "--noise-octaves {} is invalid: allowed 1..=16",
            args.noise_octaves
        ));
    }
    let noise = args.fog.then_some(NoiseOptions {
        frequency: args.noise_frequency,
        amplitude: args.noise_amplitude,
        octaves: args.noise_octaves as u32,
        seed: args.noise_seed,
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
