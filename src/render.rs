//! The render loop: tiles rendered in parallel with rayon, in sample passes, with the film
//! written to disk after passes so that a long render never loses finished work.
//!
//! Every random number is a function of (seed, pixel, sample index, dimension), and each
//! pixel accumulates its samples in sample-index order, so the image is bit-identical whatever
//! the thread count, tile order or pass schedule.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use rayon::prelude::*;

use crate::film::{Film, PixelSample};
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
        Ok(())
    }
}

/// The PNG preview path next to an EXR path.
#[must_use]
pub fn png_path_for(exr: &Path) -> PathBuf {
    exr.with_extension("png")
}

fn write_outputs(film: &Film, exr: &Path, exposure: f32) -> Result<(), RenderError> {
    if let Some(dir) = exr.parent() {
        if !dir.as_os_str().is_empty() {
            std::fs::create_dir_all(dir).map_err(|source| RenderError::Io {
                path: dir.to_path_buf(),
                source,
            })?;
        }
    }
    film.write_exr(exr)?;
    film.write_png(&png_path_for(exr), exposure)?;
    Ok(())
}

/// Renders one sample range of one tile; returns the samples pixel by pixel in sample order.
fn render_tile(
    scene: &Scene,
    x0: u32,
    y0: u32,
    x1: u32,
    y1: u32,
    s0: u32,
    s1: u32,
    stats: &mut TraceStats,
) -> Vec<PixelSample> {
    let mut out = Vec::with_capacity(((x1 - x0) * (y1 - y0) * (s1 - s0)) as usize);
    for y in y0..y1 {
        for x in x0..x1 {
            for s in s0..s1 {
                let mut sampler = PixelSampler::new(scene.film.seed, x, y, s);
                let film_pos = Vec2::new(x as f32, y as f32) + sampler.next_2d();
                let lens = sampler.next_2d();
                let ray = scene.camera.generate_ray(film_pos, lens);
                let r = trace_path(scene, ray, &mut sampler, stats);
                out.push(PixelSample {
                    radiance: r.radiance,
                    albedo: r.albedo,
                    normal: r.normal,
                    depth: r.depth,
                });
            }
        }
    }
    out
}

/// Renders `scene` and returns the film and a summary. Writes checkpoints and the final image
/// to `options.output` when set.
pub fn render(
    scene: &Scene,
    options: &RenderOptions,
) -> Result<(Film, RenderSummary), RenderError> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(options.threads)
        .build()
        .map_err(|e| RenderError::ThreadPool {
            threads: options.threads,
            message: e.to_string(),
        })?;
    let threads = pool.current_num_threads();
    let (w, h) = (scene.film.width, scene.film.height);
    let spp = scene.film.spp;
    let mut film = Film::new(w, h)?;
    let mut tiles = Vec::new();
    for ty in (0..h).step_by(TILE_SIZE as usize) {
        for tx in (0..w).step_by(TILE_SIZE as usize) {
            tiles.push((tx, ty, (tx + TILE_SIZE).min(w), (ty + TILE_SIZE).min(h)));
        }
    }
    let bar = if options.progress {
        let b = indicatif::ProgressBar::new(w as u64 * h as u64 * spp as u64);
        b.set_style(
            indicatif::ProgressStyle::with_template(
                "{bar:40} {percent:>3}% {pos}/{len} samples, {elapsed_precise} elapsed, eta {eta}",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        Some(b)
    } else {
        None
    };
    let start = Instant::now();
    let mut last_write = Instant::now();
    let mut stats = TraceStats::default();
    let mut done = 0u32;
    let mut pass_size = 1u32;
    while done < spp {
        let s0 = done;
        let s1 = (done + pass_size).min(spp);
        let results: Vec<(Vec<PixelSample>, TraceStats)> = pool.install(|| {
            tiles
                .par_iter()
                .map(|&(x0, y0, x1, y1)| {
                    let mut st = TraceStats::default();
                    let samples = render_tile(scene, x0, y0, x1, y1, s0, s1, &mut st);
                    if let Some(b) = &bar {
                        b.inc(samples.len() as u64);
                    }
                    (samples, st)
                })
                .collect()
        });
        for (&(x0, y0, x1, y1), (samples, st)) in tiles.iter().zip(results.iter()) {
            stats.merge(st);
            let mut it = samples.iter();
            for y in y0..y1 {
                for x in x0..x1 {
                    for _ in s0..s1 {
                        if let Some(s) = it.next() {
                            film.add_sample(x, y, s);
                        }
                    }
                }
            }
        }
        done = s1;
        pass_size = (pass_size * 2).min(64);
        if let Some(out) = &options.output {
            if done < spp && last_write.elapsed() >= options.checkpoint_interval {
                write_outputs(&film, out, scene.film.exposure)?;
                last_write = Instant::now();
            }
        }
    }
    if let Some(b) = &bar {
        b.finish_and_clear();
    }
    let seconds = start.elapsed().as_secs_f64();
    if let Some(out) = &options.output {
        write_outputs(&film, out, scene.film.exposure)?;
    }
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
    };
    Ok((film, summary))
}
