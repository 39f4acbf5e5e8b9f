//! `velour majorants FILE.vdb|SCENE.toml [--json]`: how tight and how safe the majorant bounds
//! are, per pyramid level and for the single global majorant.
//!
//! Figures per level (docs/references.md §4.8; docs/architecture.md, "The majorant pyramid"):
//! - `cells`, `occupied`, `homogeneous`: cells of the level, those with non-zero bounds, and
//!   those whose min equals max (sampled in closed form, no lookups);
//! - `tightness`: ∫ density dt / ∫ majorant dt along random rays through the volume (1 = exact);
//! - `lookups_per_unit_depth`: expected density lookups of delta/ratio tracking per unit of
//!   real optical depth, ∫ majorant dt over non-homogeneous segments / ∫ density dt;
//! - `segments_per_ray`: segments the walk emits per ray (each costs about one lookup);
//! - `walk %` (level rows): the share of the adaptive walk's length through non-empty cells
//!   that it covers with whole cells of that level, before merging: the levels it picks;
//! - the `adaptive` row: the walk renders use ([`MajorantPyramid::segments_adaptive`]), which
//!   opens a cell, at any level, only where that saves lookups at the medium's extinction
//!   (`--sigma`, or the interior's largest σ_t⁰ for a scene) along the ray's direction;
//! - the `local Nvx` row (grids; N the cell edge in voxels): the per-point bounds of `tracking.local_bounds`
//!   ([`crate::majorant::LocalBounds`]; docs/references.md §4.10) sampled at 1,024 points per
//!   ray: tightness ∫ density / ∫ local majorant, and the free-flight lookups per unit optical
//!   depth they leave (rejected tentative collisions need none); `segments/ray` is the walk the
//!   free flights then use at `--sigma`;
//! - `max_violation`: the largest excess of a densely sampled density over its cell's bounds
//!   (zero for grids, whose bounds are exact; measured for estimated procedural bounds).

use std::path::{Path, PathBuf};

use super::CliResult;
use crate::majorant::MajorantSegment;
use crate::majorant::{MajorantMode, MajorantPyramid};
use crate::math::{Aabb, Ray, Vec3};
use crate::medium::{DensityField, HeterogeneousMedium, Medium};
use crate::sampling::{sample_uniform_sphere, Rng};
use crate::tracking::{DensityCoefficients, TrackingConfig};

/// Arguments of `velour majorants`.
#[derive(Debug, clap::Args)]
pub struct MajorantsArgs {
    /// An OpenVDB file (every scalar grid) or a scene file (every heterogeneous interior).
    pub input: PathBuf,
    /// Only this grid of a VDB file.
    #[arg(long)]
    pub grid: Option<String>,
    /// Random rays used for tightness figures.
    #[arg(long, default_value_t = 2000)]
    pub rays: u32,
    /// Density samples per level-0 cell for the violation search.
    #[arg(long, default_value_t = 64)]
    pub samples: u32,
    /// Extinction per unit density (1/length) for the adaptive walk; default: the interior's
    /// largest σ_t⁰ for a scene, 1 for a VDB file.
    #[arg(long)]
    pub sigma: Option<f32>,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
}

/// Figures of one pyramid level (or of the global majorant).
#[derive(Clone, Debug, serde::Serialize)]
pub struct LevelFigures {
    /// "level N" or "global".
    pub level: String,
    /// Cells of the level.
    pub cells: usize,
    /// Cells with non-zero bounds.
    pub occupied: usize,
    /// Occupied cells with min == max.
    pub homogeneous: usize,
    /// Mean density over mean majorant along random rays.
    pub tightness: f64,
    /// Expected lookups per unit optical depth.
    pub lookups_per_unit_depth: f64,
    /// Segments emitted per ray.
    pub segments_per_ray: f64,
    /// Level rows: the share of the adaptive walk's length through non-empty cells covered by
    /// whole cells of this level (0 for the other rows).
    pub walk_share: f64,
}

/// Figures of one volume.
#[derive(Clone, Debug, serde::Serialize)]
pub struct VolumeFigures {
    /// Grid or interior name.
    pub name: String,
    /// Global bounds (min, max) of the density.
    pub global_min: f32,
    /// Global maximum.
    pub global_max: f32,
    /// Per level, then the global majorant.
    pub levels: Vec<LevelFigures>,
    /// Largest bound violation found by dense sampling (density units).
    pub max_violation: f64,
    /// Samples taken in the violation search.
    pub violation_samples: u64,
    /// Extinction per unit density of the adaptive row.
    pub sigma: f32,
}

/// Measures one interior.
pub fn measure(name: &str, medium: &HeterogeneousMedium, rays: u32, samples: u32) -> VolumeFigures {
    let pyramid = &medium.pyramid;
    let global = pyramid.global_bounds();
    let bounds = pyramid.world_bounds().unwrap_or(Aabb {
        min: Vec3::ZERO,
        max: Vec3::ZERO,
    });
    let centre = bounds.center();
    let radius = (bounds.extent().length() * 0.5).max(1e-6);
    let sigma = medium.coefficients.max_sigma_t();
    let mut modes: Vec<(String, MajorantMode, Option<f32>)> = (0..pyramid.level_count())
        .map(|l| {
            (
                format!("level {l}"),
                MajorantMode::Hierarchical { finest: l as u8 },
                None,
            )
        })
        .collect();
    modes.push(("global".to_string(), MajorantMode::Global, None));
    if pyramid.level_count() > 0 {
        modes.push((
            "adaptive".to_string(),
            MajorantMode::Hierarchical { finest: 0 },
            Some(sigma),
        ));
    }
    let reports = pyramid.level_reports();
    let mut walk_length = vec![0.0f64; pyramid.level_count()];
    let mut levels = Vec::new();
    for (i, (label, mode, adaptive)) in modes.iter().enumerate() {
        let mut rng = Rng::new(17, 3);
        let mut segment_count = 0u64;
        let mut density_integral = 0.0f64;
        let mut majorant_integral = 0.0f64;
        let mut lookup_integral = 0.0f64;
        let mut segs: Vec<MajorantSegment> = Vec::new();
        for _ in 0..rays {
            let d = sample_uniform_sphere(rng.next_2d());
            let offset =
                sample_uniform_sphere(rng.next_2d()) * (rng.next_f32().sqrt() * radius * 0.5);
            let ray = Ray::new(centre + offset - d * (2.0 * radius), d);
            segs.clear();
            match adaptive {
                Some(s) => {
                    pyramid.segments_adaptive(&ray, 0.0, 4.0 * radius, *mode, *s, &mut segs);
                    pyramid.adaptive_level_lengths(
                        &ray,
                        0.0,
                        4.0 * radius,
                        *s,
                        crate::majorant::LookupModel::Majorant,
                        &mut walk_length,
                    );
                }
                None => pyramid.segments(&ray, 0.0, 4.0 * radius, *mode, &mut segs),
            }
            segment_count += segs.len() as u64;
            let mut lookup = medium.density_along(&ray);
            for s in &segs {
                let len = (s.t1 - s.t0) as f64;
                majorant_integral += s.max as f64 * len;
                if !s.is_homogeneous() {
                    lookup_integral += s.max as f64 * len;
                }
                // Midpoint rule with 8 points per segment for the density integral.
                let n = 8;
                for k in 0..n {
                    let t = s.t0 + (s.t1 - s.t0) * (k as f32 + 0.5) / n as f32;
                    density_integral += lookup.at(t) as f64 * len / n as f64;
                }
            }
        }
        let (cells, occupied, homogeneous) = match reports.get(i) {
            Some(r) if i < reports.len() => (r.cells, r.occupied, r.homogeneous),
            // The adaptive walk mixes levels.
            _ if adaptive.is_some() => (0, 0, 0),
            _ => (
                1,
                usize::from(global.max > 0.0),
                usize::from(global.max > 0.0 && global.min == global.max),
            ),
        };
        levels.push(LevelFigures {
            level: label.clone(),
            cells,
            occupied,
            homogeneous,
            tightness: if majorant_integral > 0.0 {
                density_integral / majorant_integral
            } else {
                1.0
            },
            lookups_per_unit_depth: if density_integral > 0.0 {
                lookup_integral / density_integral
            } else {
                0.0
            },
            segments_per_ray: segment_count as f64 / f64::from(rays.max(1)),
            walk_share: 0.0,
        });
    }
    // The adaptive row ran last: share its length out to the level rows.
    let total: f64 = walk_length.iter().sum();
    if total > 0.0 {
        for (row, len) in levels.iter_mut().zip(&walk_length) {
            row.walk_share = len / total;
        }
    }
    if let Some(row) = local_bounds_row(medium, rays, centre, radius, sigma) {
        levels.push(row);
    }
    let (max_violation, violation_samples) = violation_search(medium, samples);
    VolumeFigures {
        name: name.to_string(),
        global_min: global.min,
        global_max: global.max,
        levels,
        max_violation,
        violation_samples,
        sigma,
    }
}

/// The `local bounds` row: tightness and lookups per unit depth of the per-point bounds along
/// the same random rays as the level rows, and the segments per ray of the free flights' walk.
fn local_bounds_row(
    medium: &HeterogeneousMedium,
    rays: u32,
    centre: Vec3,
    radius: f32,
    sigma: f32,
) -> Option<LevelFigures> {
    use crate::majorant::{LocalBounds, LookupModel};
    use crate::tracking::PointBounds;
    let DensityField::Grid { grid, channel } = &medium.field else {
        return None;
    };
    let owned;
    let table = match medium.pyramid.local_bounds() {
        Some(t) => t,
        None => {
            owned = LocalBounds::from_grid(grid, *channel).ok()?;
            &owned
        }
    };
    let mut rng = Rng::new(17, 3);
    let (mut density_integral, mut majorant_integral, mut segments) = (0.0f64, 0.0f64, 0u64);
    let n = 1024;
    for _ in 0..rays {
        let d = sample_uniform_sphere(rng.next_2d());
        let offset = sample_uniform_sphere(rng.next_2d()) * (rng.next_f32().sqrt() * radius * 0.5);
        let ray = Ray::new(centre + offset - d * (2.0 * radius), d);
        let len = 4.0 * radius;
        segments += medium
            .pyramid
            .segments_along(
                &ray,
                0.0,
                len,
                medium.tracking.majorant,
                Some(sigma),
                LookupModel::Probed,
            )
            .count() as u64;
        let mut lookup = medium.density_along(&ray);
        let mut probe = crate::medium::LocalProbe::new(table, grid, &ray, false);
        let dt = f64::from(len) / f64::from(n);
        for k in 0..n {
            let t = (k as f32 + 0.5) * len / n as f32;
            density_integral += f64::from(lookup.at(t)) * dt;
            if let Some((_, hi)) = probe.at(t) {
                majorant_integral += f64::from(hi) * dt;
            }
        }
    }
    Some(LevelFigures {
        level: format!("local {}vx", table.cell_voxels()),
        cells: table.cell_count(),
        occupied: 0,
        homogeneous: 0,
        tightness: if majorant_integral > 0.0 {
            density_integral / majorant_integral
        } else {
            1.0
        },
        lookups_per_unit_depth: if density_integral > 0.0 {
            majorant_integral / density_integral
        } else {
            0.0
        },
        segments_per_ray: segments as f64 / f64::from(rays.max(1)),
        walk_share: 0.0,
    })
}

/// Samples every occupied level-0 cell densely along random rays and reports the largest excess
/// of the density over the segment bounds.
fn violation_search(medium: &HeterogeneousMedium, samples: u32) -> (f64, u64) {
    let pyramid = &medium.pyramid;
    let Some(bounds) = pyramid.world_bounds() else {
        return (0.0, 0);
    };
    let occupied = pyramid
        .level_reports()
        .first()
        .map_or(0, |r| r.occupied)
        .max(1);
    let rays = ((occupied as u64 * samples as u64) / 64).clamp(64, 200_000);
    let mut rng = Rng::new(99, 5);
    let mut worst = 0.0f64;
    let mut count = 0u64;
    let mut segs = Vec::new();
    for _ in 0..rays {
        let o = bounds.min
            + (bounds.max - bounds.min) * Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
        let d = sample_uniform_sphere(rng.next_2d());
        let ray = Ray::new(o, d);
        segs.clear();
        pyramid.segments(
            &ray,
            0.0,
            bounds.extent().length(),
            MajorantMode::Hierarchical { finest: 0 },
            &mut segs,
        );
        let mut lookup = medium.density_along(&ray);
        for s in &segs {
            for _ in 0..4 {
                let t = s.t0 + (s.t1 - s.t0) * rng.next_f32();
                let v = lookup.at(t) as f64;
                count += 1;
                worst = worst.max(v - s.max as f64).max(s.min as f64 - v);
            }
        }
    }
    (worst, count)
}

fn grids_from_vdb(
    path: &Path,
    only: Option<&str>,
) -> Result<Vec<(String, HeterogeneousMedium)>, Box<dyn std::error::Error + Send + Sync>> {
    let file = crate::vdb::VdbFile::open(path)?;
    let names: Vec<String> = match only {
        Some(n) => vec![n.to_string()],
        None => file.grid_names(),
    };
    let mut out = Vec::new();
    for n in names {
        let g = file.read_grid(&n)?;
        if g.grid.channel_kind(0) != Some(crate::grid::ChannelKind::Scalar) {
            eprintln!("skipping grid `{n}`: not scalar ({})", g.value_type.name());
            continue;
        }
        g.check_finite()?;
        let pyramid = MajorantPyramid::from_grid(&g.grid, 0)?;
        let medium = HeterogeneousMedium {
            field: DensityField::Grid {
                grid: g.grid,
                channel: 0,
            },
            pyramid,
            coefficients: DensityCoefficients::new(
                crate::spectrum::Rgb::ONE,
                crate::spectrum::Rgb::ONE,
            ),
            phase: crate::phase::PhaseFunction::henyey_greenstein(0.0)?,
            tracking: TrackingConfig::default(),
            fabric: None,
            mips: None,
        };
        out.push((n, medium));
    }
    Ok(out)
}

/// Runs `velour majorants`.
pub fn run(args: &MajorantsArgs) -> CliResult {
    if args.rays == 0 || args.rays > 10_000_000 || args.samples == 0 || args.samples > 1_000_000 {
        return Err("--rays must be in 1..=10000000 and --samples in 1..=1000000".into());
    }
    let is_scene = args.input.extension().is_some_and(|e| e == "toml");
    let volumes: Vec<(String, HeterogeneousMedium)> = if is_scene {
        if args.grid.is_some() {
            return Err("--grid applies to VDB files only".into());
        }
        let scene = crate::scene::Scene::load(&args.input)?;
        let mut v = Vec::new();
        for obj in &scene.objects {
            if let Some(m) = obj.medium {
                match &scene.media[m as usize] {
                    Medium::Heterogeneous(h) => v.push((obj.name.clone(), (**h).clone())),
                    // A textured voxel/fbm interior: its field at the textures' means.
                    Medium::Scaled(f) => v.push((obj.name.clone(), (*f.medium).clone())),
                    // A fabric with textured yarn colours: the fabric itself.
                    Medium::Dyed(f) => v.push((obj.name.clone(), (*f.medium).clone())),
                    // A surface-projected voxel/fbm interior: its field at the textures' means.
                    Medium::Projected(p) => {
                        if let Some(f) = &p.field {
                            v.push((obj.name.clone(), (*f.medium).clone()));
                        }
                    }
                    Medium::Mixture(_) | Medium::ScaledMixture(_) => {
                        let mix = match &scene.media[m as usize] {
                            Medium::ScaledMixture(s) => &*s.medium,
                            Medium::Mixture(b) => &**b,
                            _ => continue,
                        };
                        for (i, c) in mix.components.iter().enumerate() {
                            if let crate::medium::ComponentDensity::Field(h) = &c.density {
                                v.push((format!("{} (media[{i}])", obj.name), (**h).clone()));
                            }
                        }
                    }
                    _ => {}
                }
            }
        }
        if v.is_empty() {
            return Err(format!(
                "{}: the scene has no heterogeneous (voxel or fbm) interior",
                args.input.display()
            )
            .into());
        }
        v
    } else {
        grids_from_vdb(&args.input, args.grid.as_deref())?
    };
    let mut volumes = volumes;
    if let Some(s) = args.sigma {
        if !(s.is_finite() && s > 0.0) {
            return Err(
                format!("--sigma {s}: expected a positive extinction per unit density").into(),
            );
        }
        for (_, m) in &mut volumes {
            m.coefficients = DensityCoefficients::new(
                crate::spectrum::Rgb::splat(s),
                crate::spectrum::Rgb::splat(s),
            );
        }
    }
    let figures: Vec<VolumeFigures> = volumes
        .iter()
        .map(|(n, m)| measure(n, m, args.rays, args.samples))
        .collect();
    if args.json {
        println!("{}", serde_json::to_string_pretty(&figures)?);
        return Ok(());
    }
    for f in &figures {
        println!(
            "{}: density in [{}, {}]; adaptive walk at σ_t = {} per unit density",
            f.name, f.global_min, f.global_max, f.sigma
        );
        println!(
            "  {:<9} {:>9} {:>9} {:>11} {:>10} {:>16} {:>13} {:>7}",
            "level",
            "cells",
            "occupied",
            "homogeneous",
            "tightness",
            "lookups/depth",
            "segments/ray",
            "walk %"
        );
        for l in &f.levels {
            let (cells, occupied, homogeneous) = if l.cells == 0 {
                ("-".to_string(), "-".to_string(), "-".to_string())
            } else {
                (
                    l.cells.to_string(),
                    l.occupied.to_string(),
                    l.homogeneous.to_string(),
                )
            };
            let share = if l.level.starts_with("level") {
                format!("{:.1}", 100.0 * l.walk_share)
            } else {
                String::new()
            };
            println!(
                "  {:<9} {:>9} {:>9} {:>11} {:>10.4} {:>16.3} {:>13.2} {:>7}",
                l.level,
                cells,
                occupied,
                homogeneous,
                l.tightness,
                l.lookups_per_unit_depth,
                l.segments_per_ray,
                share
            );
        }
        println!(
            "  largest bound violation: {:.3e} (over {} dense samples)",
            f.max_violation, f.violation_samples
        );
    }
    Ok(())
}
