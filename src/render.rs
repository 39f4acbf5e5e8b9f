//! The render loop: tiles rendered in parallel with rayon, in sample passes, with the film
//! written to disk after passes so that a long render never loses finished work.
//!
//! Every random number is a function of (seed, pixel, sample index, dimension), and each
//! pixel accumulates its samples in sample-index order, so the image is bit-identical whatever
//! the thread count, tile order or pass schedule.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use rayon::prelude::*;

use crate::film::{Film, FilmTile, PixelSample};
use crate::integrator::{trace_path, TraceStats};
use crate::math::Vec2;
use crate::sampling::PixelSampler;
use crate::scene::Scene;

/// Side of a square render tile, pixels.
pub const TILE_SIZE: u32 = 16;

/// Errors of the render loop.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    /// The thread pool could not be created.
    #[error("cannot create a pool of {threads} threads: {message}")]
    ThreadPool {
        /// Requested threads.
        threads: usize,
        /// Cause.
        message: String,
    },
    /// The film could not be created or written.
    #[error("{0}")]
    Film(#[from] crate::film::FilmError),
    /// A sample budget outside [1, MAX_SPP] or a time budget that is not a positive number.
    #[error("bad render budget: {0}")]
    BadBudget(String),
    /// The output folder could not be created.
    #[error("{path}: cannot create output folder: {source}")]
    Io {
        /// Folder.
        path: PathBuf,
        /// Cause.
        source: std::io::Error,
    },
}

/// Options of one render.
#[derive(Clone, Debug)]
pub struct RenderOptions {
    /// Worker threads (0 = all cores).
    pub threads: usize,
    /// Show a progress bar on stderr.
    pub progress: bool,
    /// Where to write the EXR (and the PNG next to it); `None` = keep in memory only.
    pub output: Option<PathBuf>,
    /// Minimum time between checkpoint writes.
    pub checkpoint_interval: Duration,
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
            threads: 0,
            progress: false,
            output: None,
            checkpoint_interval: Duration::from_secs(20),
        }
    }
}

/// Figures printed at the end of a render.
#[derive(Clone, Debug)]
pub struct RenderSummary {
    /// Wall-clock time, seconds.
    pub seconds: f64,
    /// Camera samples traced.
    pub samples: u64,
    /// Rays cast (closest-hit + shadow).
    pub rays: u64,
    /// Mean number of scattering events per path.
    pub mean_path_length: f64,
    /// Samples dropped because their radiance was NaN or infinite.
    pub non_finite: u64,
    /// Threads used.
    pub threads: usize,
    /// Heterogeneous-medium tracking counters.
    pub tracking: crate::tracking::TrackingStats,
    /// Manifold-walk counters (`nee = "manifold"`): attempts, solutions, failures by kind.
    pub manifold: crate::integrator::manifold::ManifoldStats,
}

impl std::fmt::Display for RenderSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let s = self.seconds.max(1e-9);
        write!(
            f,
            "time {:.2} s | {} samples, {:.3} M samples/s | {} rays, {:.3} M rays/s | mean path length {:.2} | non-finite samples dropped: {} | threads {}",
            self.seconds,
            self.samples,
            self.samples as f64 / s / 1e6,
            self.rays,
            self.rays as f64 / s / 1e6,
            self.mean_path_length,
            self.non_finite,
            self.threads
        )?;
        let t = &self.tracking;
        if t.lookups > 0 || t.real_collisions > 0 || t.transmittance_lookups > 0 {
            write!(
                f,
                " | tracking: {} free-flight lookups ({} real + {} null collisions, {:.2} lookups per real collision), {} transmittance lookups, {} bound violations",
                t.lookups,
                t.real_collisions,
                t.null_collisions,
                t.lookups as f64 / t.real_collisions.max(1) as f64,
                t.transmittance_lookups,
                t.violations
            )?;
        }
        if self.manifold.attempts > 0 {
            write!(f, " | manifold NEE: {}", self.manifold)?;
        }
        Ok(())
    }
}

/// The PNG preview path next to an EXR path.
#[must_use]
pub fn png_path_for(exr: &Path) -> PathBuf {
    exr.with_extension("png")
}

/// Renders `scene` with `scene.film.spp` samples per pixel and returns the film and a summary.
/// Writes checkpoints and the final image (EXR + PNG) to `options.output` when set.
pub fn render(
    scene: &Scene,
    options: &RenderOptions,
) -> Result<(Film, RenderSummary), RenderError> {
    let budget = BudgetOptions {
        budget: Budget::Samples(scene.film.spp),
        threads: options.threads,
        progress: options.progress,
        checkpoint: options.output.clone(),
        checkpoint_interval: options.checkpoint_interval,
    };
    let r = render_budget(scene, &budget)?;
    if let Some(out) = &options.output {
        write_film(&r.film, out, scene.film.exposure, &BTreeMap::new())?;
    }
    Ok((r.film, r.summary))
}

/// Largest number of samples per pixel a budgeted render takes.
pub const MAX_SPP: u32 = 1 << 24;

/// How long a budgeted render runs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Budget {
    /// Exactly this many samples per pixel (1 ..= [`MAX_SPP`]).
    Samples(u32),
    /// Wall-clock seconds (> 0): passes of whole-image samples are rendered while the next pass
    /// is predicted to end within the budget; at least one sample per pixel is always taken.
    Seconds(f64),
}

/// Options of [`render_budget`].
#[derive(Clone, Debug)]
pub struct BudgetOptions {
    /// When to stop.
    pub budget: Budget,
    /// Worker threads (0 = all cores).
    pub threads: usize,
    /// Show a progress bar on stderr.
    pub progress: bool,
    /// Where to write checkpoints (EXR + PNG) during the render; `None` = none.
    pub checkpoint: Option<PathBuf>,
    /// Minimum time between checkpoint writes.
    pub checkpoint_interval: Duration,
}

impl BudgetOptions {
    /// Options with the given budget, all cores, no progress, no checkpoints.
    #[must_use]
    pub fn new(budget: Budget) -> Self {
        BudgetOptions {
            budget,
            threads: 0,
            progress: false,
            checkpoint: None,
            checkpoint_interval: Duration::from_secs(60),
        }
    }
}

/// What [`render_budget`] returns besides the film.
#[derive(Clone, Debug)]
pub struct BudgetResult {
    /// The accumulated film.
    pub film: Film,
    /// Time, samples, rays and the non-finite sample count (as `velour render` prints).
    pub summary: RenderSummary,
    /// Samples per pixel taken (the same in every pixel).
    pub spp: u32,
}

/// Renders one pass of samples `s0..s1` into `tile`; returns the trace counters.
fn render_tile_pass(scene: &Scene, seed: u64, tile: &mut FilmTile, s0: u32, s1: u32) -> TraceStats {
    tile.clear();
    let mut stats = TraceStats::default();
    for y in tile.y0()..tile.y0() + tile.height() {
        for x in tile.x0()..tile.x0() + tile.width() {
            for s in s0..s1 {
                let mut sampler = PixelSampler::new(seed, x, y, s);
                let film_pos = Vec2::new(x as f32, y as f32) + sampler.next_2d();
                let lens = sampler.next_2d();
                let ray = scene.camera.generate_ray(film_pos, lens);
                let r = trace_path(scene, ray, &mut sampler, &mut stats);
                tile.add_sample(
                    x,
                    y,
                    &PixelSample {
                        radiance: r.radiance,
                        albedo: r.albedo,
                        normal: r.normal,
                        depth: r.depth,
                    },
                );
            }
        }
    }
    stats
}

/// Writes `film` to `exr` (every layer, with `attributes`) and its PNG preview next to it.
pub fn write_film(
    film: &Film,
    exr: &Path,
    exposure: f32,
    attributes: &BTreeMap<String, String>,
) -> Result<(), RenderError> {
    if let Some(dir) = exr.parent() {
        if !dir.as_os_str().is_empty() {
            std::fs::create_dir_all(dir).map_err(|source| RenderError::Io {
                path: dir.to_path_buf(),
                source,
            })?;
        }
    }
    film.write_exr_with_attributes(exr, attributes)?;
    film.write_png(&png_path_for(exr), exposure)?;
    Ok(())
}

/// Renders `scene` (with `scene.film.seed`; `scene.film.spp` is ignored) until `options.budget`
/// is spent, in passes over the whole image (1, 2, 4, … up to 64 samples per pixel per pass,
/// shortened so that a time budget is not overrun by more than the prediction error of one
/// pass).
pub fn render_budget(scene: &Scene, options: &BudgetOptions) -> Result<BudgetResult, RenderError> {
    match options.budget {
        Budget::Samples(n) if n == 0 || n > MAX_SPP => {
            return Err(RenderError::BadBudget(format!(
                "{n} samples per pixel is outside [1, {MAX_SPP}]"
            )))
        }
        Budget::Seconds(s) if !(s > 0.0 && s.is_finite()) => {
            return Err(RenderError::BadBudget(format!(
                "{s} s is not a positive number of seconds"
            )))
        }
        _ => {}
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(options.threads)
        .build()
        .map_err(|e| RenderError::ThreadPool {
            threads: options.threads,
            message: e.to_string(),
        })?;
    let threads = pool.current_num_threads();
    let mut film = Film::new(scene.film.width, scene.film.height)?;
    let mut tiles = film.tiles(TILE_SIZE)?;
    let seed = scene.film.seed;
    // A progress bar over samples (a sample budget) or a spinner (a time budget).
    let bar = options.progress.then(|| {
        let pixels = u64::from(scene.film.width) * u64::from(scene.film.height);
        let b = match options.budget {
            Budget::Samples(n) => indicatif::ProgressBar::new(pixels * u64::from(n)),
            Budget::Seconds(_) => indicatif::ProgressBar::new_spinner(),
        };
        b.set_style(
            indicatif::ProgressStyle::with_template("{bar:40} {percent:>3}% {pos}/{len} samples {msg}, {elapsed_precise} elapsed, eta {eta}")
                .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        b
    });
    let start = Instant::now();
    let mut last_write = Instant::now();
    let mut stats = TraceStats::default();
    let mut done = 0u32;
    let mut pass_size = 1u32;
    loop {
        let elapsed = start.elapsed().as_secs_f64();
        let target = match options.budget {
            Budget::Samples(n) => n,
            Budget::Seconds(budget) => {
                if done == 0 {
                    1
                } else {
                    let per_spp = elapsed / f64::from(done);
                    let fits = ((budget - elapsed) / per_spp.max(1e-12)).floor();
                    if fits < 1.0 {
                        break;
                    }
                    done.saturating_add(fits.min(f64::from(pass_size)) as u32)
                        .min(MAX_SPP)
                }
            }
        };
        if done >= target {
            break;
        }
        let (s0, s1) = (done, target.min(done.saturating_add(pass_size)));
        let pass_stats: Vec<TraceStats> = pool.install(|| {
            tiles
                .par_iter_mut()
                .map(|tile| {
                    let st = render_tile_pass(scene, seed, tile, s0, s1);
                    if let Some(b) = &bar {
                        b.inc(u64::from(tile.width() * tile.height() * (s1 - s0)));
                    }
                    st
                })
                .collect()
        });
        for (tile, st) in tiles.iter().zip(&pass_stats) {
            film.merge_tile(tile)?;
            stats.merge(st);
        }
        done = s1;
        pass_size = pass_size.saturating_mul(2).min(64);
        if let Some(b) = &bar {
            b.set_message(format!("{done} spp"));
        }
        if let Some(out) = &options.checkpoint {
            if last_write.elapsed() >= options.checkpoint_interval {
                write_film(&film, out, scene.film.exposure, &BTreeMap::new())?;
                last_write = Instant::now();
            }
        }
        if done >= MAX_SPP {
            break;
        }
    }
    if let Some(b) = &bar {
        b.finish_and_clear();
    }
    let seconds = start.elapsed().as_secs_f64();
    let summary = RenderSummary {
        seconds,
        samples: stats.paths,
        rays: stats.rays,
        mean_path_length: if stats.paths > 0 {
            stats.vertices as f64 / stats.paths as f64
        } else {
            0.0
        },
        non_finite: stats.non_finite + film.dropped_samples(),
        threads,
        tracking: stats.tracking,
        manifold: stats.manifold,
    };
    Ok(BudgetResult {
        film,
        summary,
        spp: done,
    })
}
