//! The render loop: tiles rendered in parallel with rayon, in sample passes, with the film
//! written to disk after passes so that a long render never loses finished work.
//!
//! Every random number is a function of (seed, pixel, sample index, dimension), and each
//! pixel accumulates its samples in sample-index order, so the image is bit-identical whatever
//! the thread count, tile order or pass schedule.

use std::collections::BTreeMap;
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use rayon::prelude::*;

use crate::film::{Film, FilmTile, PixelSample};
use crate::integrator::{trace_path, TraceStats};
use crate::math::Vec2;
use crate::sampling::{PixelSampler, PixelSeed};
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
    /// The render was stopped by a signal; what was finished is in the checkpoint (if any).
    #[error("render interrupted after {done} samples per pixel{}", match checkpoint {
        Some(p) => format!("; finished work saved to {}", p.display()),
        None => String::new(),
    })]
    Interrupted {
        /// Samples per pixel finished (this run's range).
        done: u32,
        /// The checkpoint written.
        checkpoint: Option<PathBuf>,
    },
    /// Rows or samples outside the film or the sample budget.
    #[error("bad render region: {0}")]
    BadRegion(String),
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
            if t.probed > 0 {
                write!(
                    f,
                    ", {} tentative collisions rejected by local bounds, {} segments",
                    t.probed, t.segments
                )?;
            }
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

/// The checkpoint path of an output: `.partial` before the extension (`frame.exr` →
/// `frame.partial.exr`; its preview is `frame.partial.png`).
#[must_use]
pub fn partial_path_for(exr: &Path) -> PathBuf {
    let stem = exr.file_stem().unwrap_or_default().to_string_lossy();
    let ext = exr
        .extension()
        .map_or_else(|| "exr".into(), |e| e.to_string_lossy());
    exr.with_file_name(format!("{stem}.partial.{ext}"))
}

/// Removes a checkpoint and its preview once the final image is written (missing files are
/// fine).
pub fn remove_partial(partial: &Path) {
    let _ = std::fs::remove_file(partial);
    let _ = std::fs::remove_file(png_path_for(partial));
}

/// Renders `scene` with `scene.film.spp` samples per pixel and returns the film and a summary.
/// Writes checkpoints and the final image (EXR + PNG) to `options.output` when set.
pub fn render(
    scene: &Scene,
    options: &RenderOptions,
) -> Result<(Film, RenderSummary), RenderError> {
    let budget = BudgetOptions {
        threads: options.threads,
        progress: options.progress,
        checkpoint: options.output.as_deref().map(partial_path_for),
        checkpoint_interval: options.checkpoint_interval,
        ..BudgetOptions::new(Budget::Samples(scene.film.spp))
    };
    let r = render_budget(scene, &budget)?;
    if let Some(out) = &options.output {
        write_film(&r.film, out, scene.film.exposure, &BTreeMap::new())?;
        if let Some(partial) = &budget.checkpoint {
            remove_partial(partial);
        }
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
    /// Where to write checkpoints during the render (the exact film state, EXR + PNG preview,
    /// see [`partial_path_for`]); `None` = none.
    pub checkpoint: Option<PathBuf>,
    /// Minimum time between checkpoint writes.
    pub checkpoint_interval: Duration,
    /// Text attributes written into every checkpoint (besides `velour:done`).
    pub attributes: BTreeMap<String, String>,
    /// Film rows to render (a horizontal band; `None` = all). The film returned covers only
    /// these rows.
    pub rows: Option<Range<u32>>,
    /// Absolute index of the first sample of this render in every pixel (a sample range
    /// `A..B` renders from `A`).
    pub first_sample: u32,
    /// A render to continue (from a checkpoint, see [`Resume::from_image`]).
    pub resume: Option<Resume>,
    /// Set from a signal handler: the pass in flight is abandoned, a checkpoint written and
    /// [`RenderError::Interrupted`] returned.
    pub stop: Option<Arc<AtomicBool>>,
    /// Adaptive sampling: pixels stop once converged (the budget is then the maximum).
    pub adaptive: Option<Adaptive>,
    /// Wall-clock limit in seconds, on top of the budget: no pass starts that is predicted to
    /// end after it.
    pub time_limit: Option<f64>,
}

/// What a checkpoint holds: the exact film, the samples per pixel finished, and (adaptive
/// sampling) which pixels were still taking samples.
#[derive(Clone, Debug)]
pub struct Resume {
    /// The film so far.
    pub film: Film,
    /// Samples per pixel finished (of this render's range).
    pub done: u32,
    /// Adaptive sampling's mask of pixels still sampling, row-major over the film.
    pub active: Option<Vec<bool>>,
}

/// Name of the `UINT` checkpoint channel holding adaptive sampling's mask (1 = still sampling).
pub const ACTIVE_CHANNEL: &str = "state.active";

impl Resume {
    /// Reads a checkpoint image: its exact film state, `velour:done`, and the adaptive mask
    /// when present.
    pub fn from_image(img: &crate::image_io::ExrImage) -> Result<Resume, String> {
        let done = img
            .attributes
            .get("velour:done")
            .and_then(|d| d.parse().ok())
            .ok_or_else(|| "attribute velour:done is missing".to_string())?;
        let film = Film::from_exr_image(img).map_err(|e| e.to_string())?;
        let active = match img.uint_channels.get(ACTIVE_CHANNEL) {
            Some(v) if v.len() == img.pixel_count() => Some(v.iter().map(|&a| a != 0).collect()),
            Some(_) => return Err(format!("channel {ACTIVE_CHANNEL} has the wrong length")),
            None => None,
        };
        Ok(Resume { film, done, active })
    }
}

/// Adaptive sampling (`--noise-threshold`): after every pass, a pixel with at least `min_spp`
/// samples stops when the standard error of its luminance mean, divided by
/// max(luminance, 0.01), is below `threshold`. The standard error is bounded from above by
/// Σ_c w_c·se_c (Rec. 709 weights w_c; exact when the channels are perfectly correlated), so the
/// test is conservative. Stopping on a pixel's own samples is slightly biased (Kirk & Arvo
/// 1991, "Unbiased sampling techniques for image synthesis"): a pixel whose first samples
/// happen to agree stops early with them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Adaptive {
    /// Relative standard error at which a pixel stops (> 0).
    pub threshold: f64,
    /// Samples every pixel takes before the test applies (≥ 2).
    pub min_spp: u32,
}

/// Pass size while adaptive sampling is on: the convergence test runs every this many samples.
const ADAPTIVE_BLOCK: u32 = 16;

impl BudgetOptions {
    /// Options with the given budget, all cores, no progress, no checkpoints, the whole film
    /// from sample 0.
    #[must_use]
    pub fn new(budget: Budget) -> Self {
        BudgetOptions {
            budget,
            threads: 0,
            progress: false,
            checkpoint: None,
            checkpoint_interval: Duration::from_secs(60),
            attributes: BTreeMap::new(),
            rows: None,
            first_sample: 0,
            resume: None,
            stop: None,
            adaptive: None,
            time_limit: None,
        }
    }
}

/// What [`render_budget`] returns besides the film.
#[derive(Clone, Debug)]
pub struct BudgetResult {
    /// The accumulated film (only the requested rows).
    pub film: Film,
    /// Time, samples, rays and the non-finite sample count (as `velour render` prints).
    pub summary: RenderSummary,
    /// Samples per pixel taken (the same in every pixel), resumed ones included.
    pub spp: u32,
}

/// Whether pixel (`x`, `y`) of `film` has converged under `a` after `done` samples (see
/// [`Adaptive`]).
fn converged(film: &Film, x: u32, y: u32, done: u32, a: &Adaptive) -> bool {
    if done < a.min_spp {
        return false;
    }
    const W: [f64; 3] = [0.2126, 0.7152, 0.0722];
    let mean = film.mean(x, y);
    let var = film.variance_of_mean(x, y);
    let lum: f64 = (0..3).map(|c| W[c] * f64::from(mean.0[c])).sum();
    let se: f64 = (0..3)
        .map(|c| W[c] * f64::from(var.0[c]).max(0.0).sqrt())
        .sum();
    se / lum.abs().max(0.01) < a.threshold
}

/// Longest a sample pass is planned to take, so that a stop signal loses little work.
const MAX_PASS_SECONDS: f64 = 5.0;

/// Renders one pass of samples `s0..s1` into `tile`, whose rows are offset by `row0` in the
/// full film; returns the trace counters, or `None` when `stop` was raised during the pass.
fn render_tile_pass(
    scene: &Scene,
    seed: u64,
    tile: &mut FilmTile,
    row0: u32,
    (s0, s1): (u32, u32),
    stop: Option<&AtomicBool>,
    active: Option<(&[bool], u32)>,
) -> Option<TraceStats> {
    tile.clear();
    let mut stats = TraceStats::default();
    for y in tile.y0()..tile.y0() + tile.height() {
        if stop.is_some_and(|f| f.load(Ordering::Relaxed)) {
            return None;
        }
        let film_y = y + row0;
        for x in tile.x0()..tile.x0() + tile.width() {
            if let Some((mask, width)) = active {
                if !mask
                    .get(y as usize * width as usize + x as usize)
                    .copied()
                    .unwrap_or(false)
                {
                    continue;
                }
            }
            let pixel = PixelSeed::new(seed, x, film_y);
            for s in s0..s1 {
                let mut sampler = PixelSampler::in_pixel(&pixel, s);
                let film_pos = Vec2::new(x as f32, film_y as f32) + sampler.next_2d();
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
                        lights: r.lights,
                    },
                );
            }
        }
    }
    Some(stats)
}

/// Creates the folder an output file goes into.
fn create_parent(exr: &Path) -> Result<(), RenderError> {
    if let Some(dir) = exr.parent() {
        if !dir.as_os_str().is_empty() {
            std::fs::create_dir_all(dir).map_err(|source| RenderError::Io {
                path: dir.to_path_buf(),
                source,
            })?;
        }
    }
    Ok(())
}

/// Writes `film` to `exr` (every layer, with `attributes`) and its PNG preview next to it.
pub fn write_film(
    film: &Film,
    exr: &Path,
    exposure: f32,
    attributes: &BTreeMap<String, String>,
) -> Result<(), RenderError> {
    create_parent(exr)?;
    film.write_exr_with_attributes(exr, attributes)?;
    film.write_png(&png_path_for(exr), exposure)?;
    Ok(())
}

/// Writes `film` with its exact accumulator state (a part file or a checkpoint, see
/// [`Film::to_state_image`]) to `exr`, and its PNG preview next to it. Both are written through
/// a temporary file and renamed, so a failed write (a full disk) leaves the previous file whole.
pub fn write_state(
    film: &Film,
    exr: &Path,
    exposure: f32,
    attributes: &BTreeMap<String, String>,
) -> Result<(), RenderError> {
    write_state_image(film.to_state_image(attributes), film, exr, exposure)
}

/// Writes a state image made from `film` (with extra channels, e.g. the adaptive mask) and the
/// film's PNG preview.
fn write_state_image(
    img: crate::image_io::ExrImage,
    film: &Film,
    exr: &Path,
    exposure: f32,
) -> Result<(), RenderError> {
    create_parent(exr)?;
    crate::image_io::write_exr_owned(exr, img).map_err(crate::film::FilmError::from)?;
    film.write_png(&png_path_for(exr), exposure)?;
    Ok(())
}

/// Renders `scene` (with `scene.film.seed`; `scene.film.spp` is ignored) until `options.budget`
/// is spent, in passes over the whole region (1, 2, 4, … up to 64 samples per pixel per pass,
/// and no longer than about [`MAX_PASS_SECONDS`], shortened so that a time budget is not
/// overrun by more than the prediction error of one pass).
///
/// The samples taken in pixel (x, y) are `first_sample .. first_sample + spp` of the
/// deterministic sequence, whatever the rows, passes, threads or resumption, and the film's
/// sums are exact, so any split of a render merges to the same bits.
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
    let rows = options.rows.clone().unwrap_or(0..scene.film.height);
    if rows.start >= rows.end || rows.end > scene.film.height {
        return Err(RenderError::BadRegion(format!(
            "rows {}..{} are not inside the film's {} rows",
            rows.start, rows.end, scene.film.height
        )));
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(options.threads)
        .build()
        .map_err(|e| RenderError::ThreadPool {
            threads: options.threads,
            message: e.to_string(),
        })?;
    let threads = pool.current_num_threads();
    let band_height = rows.end - rows.start;
    let (mut film, mut done) = match &options.resume {
        Some(Resume { film, done, .. }) => {
            if (film.width(), film.height()) != (scene.film.width, band_height)
                || film.light_layer_names() != scene.light_layer_names.as_slice()
            {
                return Err(RenderError::BadRegion(format!(
                    "the film to resume is {}x{}, the region is {}x{}",
                    film.width(),
                    film.height(),
                    scene.film.width,
                    band_height
                )));
            }
            (film.clone(), *done)
        }
        None => (
            Film::with_light_layers(scene.film.width, band_height, &scene.light_layer_names)?,
            0,
        ),
    };
    let mut tiles = film.tiles(TILE_SIZE)?;
    let seed = scene.film.seed;
    let first = options.first_sample;
    // A progress bar over samples (a sample budget) or a spinner (a time budget).
    let bar = options.progress.then(|| {
        let pixels = u64::from(scene.film.width) * u64::from(band_height);
        let b = match options.budget {
            Budget::Samples(n) => indicatif::ProgressBar::new(pixels * u64::from(n)),
            Budget::Seconds(_) => indicatif::ProgressBar::new_spinner(),
        };
        b.set_style(
            indicatif::ProgressStyle::with_template("{bar:40} {percent:>3}% {pos}/{len} samples {msg}, {elapsed_precise} elapsed, eta {eta}")
                .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        b.set_position(pixels * u64::from(done));
        b
    });
    let start = Instant::now();
    let resumed = done;
    let mut last_write = Instant::now();
    let mut stats = TraceStats::default();
    let mut pass_size = 1u32;
    let stop = options.stop.as_deref();
    let width = scene.film.width;
    // Adaptive sampling: which pixels still take samples (restored from a checkpoint).
    let pixels = width as usize * band_height as usize;
    let mut active: Option<Vec<bool>> = match (&options.adaptive, &options.resume) {
        (None, _) => None,
        (
            Some(_),
            Some(Resume {
                active: Some(m), ..
            }),
        ) if m.len() == pixels => Some(m.clone()),
        (Some(_), Some(Resume { active: _, .. })) if done > 0 => {
            return Err(RenderError::BadRegion(
                "the checkpoint has no adaptive-sampling mask (it was not an adaptive render)"
                    .to_string(),
            ))
        }
        (Some(_), _) => Some(vec![true; pixels]),
    };
    let checkpoint = |film: &Film, done: u32, active: Option<&[bool]>| -> Result<(), RenderError> {
        if let Some(out) = &options.checkpoint {
            let mut attributes = options.attributes.clone();
            attributes.insert("velour:done".to_string(), done.to_string());
            let mut img = film.to_state_image(&attributes);
            if let Some(mask) = active {
                img.uint_channels.insert(
                    ACTIVE_CHANNEL.to_string(),
                    mask.iter().map(|&a| u32::from(a)).collect(),
                );
            }
            write_state_image(img, film, out, scene.film.exposure)?;
        }
        Ok(())
    };
    loop {
        let elapsed = start.elapsed().as_secs_f64();
        let per_spp = elapsed / f64::from((done - resumed).max(1));
        let target = match options.budget {
            Budget::Samples(n) => n,
            Budget::Seconds(budget) => {
                if done == resumed {
                    done + 1
                } else {
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
        if done > resumed {
            let fits = (MAX_PASS_SECONDS / per_spp.max(1e-12)).floor().max(1.0);
            pass_size = pass_size.min(fits.min(f64::from(MAX_SPP)) as u32);
            if let Some(limit) = options.time_limit {
                let fits = ((limit - elapsed) / per_spp.max(1e-12)).floor();
                if fits < 1.0 {
                    break;
                }
                pass_size = pass_size.min(fits.min(f64::from(MAX_SPP)) as u32);
            }
        }
        if let Some(a) = &options.adaptive {
            // Passes end on multiples of the block once past the minimum, so that the test runs
            // at the same sample counts however the render was split in time.
            let next_stop = if done < a.min_spp {
                a.min_spp
            } else {
                (done / ADAPTIVE_BLOCK + 1) * ADAPTIVE_BLOCK
            };
            pass_size = pass_size.min(next_stop - done);
        }
        let (s0, s1) = (done, target.min(done.saturating_add(pass_size)));
        let (a0, a1) = (first.saturating_add(s0), first.saturating_add(s1));
        let pass_stats: Vec<Option<TraceStats>> = pool.install(|| {
            tiles
                .par_iter_mut()
                .map(|tile| {
                    let mask = active.as_deref().map(|m| (m, width));
                    let st = render_tile_pass(scene, seed, tile, rows.start, (a0, a1), stop, mask);
                    if let Some(b) = &bar {
                        b.inc(u64::from(tile.width() * tile.height() * (s1 - s0)));
                    }
                    st
                })
                .collect()
        });
        if pass_stats.iter().any(Option::is_none) {
            if let Some(b) = &bar {
                b.abandon();
            }
            checkpoint(&film, done, active.as_deref())?;
            return Err(RenderError::Interrupted {
                done,
                checkpoint: options.checkpoint.clone(),
            });
        }
        for (tile, st) in tiles.iter().zip(pass_stats.iter().flatten()) {
            film.merge_tile(tile)?;
            stats.merge(st);
        }
        done = s1;
        pass_size = pass_size.saturating_mul(2).min(64);
        let test_point =
            |a: &Adaptive| done == a.min_spp || (done > a.min_spp && done % ADAPTIVE_BLOCK == 0);
        if let (Some(mask), Some(a)) = (
            active.as_mut(),
            options.adaptive.as_ref().filter(|a| test_point(a)),
        ) {
            for (i, on) in mask.iter_mut().enumerate() {
                if *on {
                    let (x, y) = ((i % width as usize) as u32, (i / width as usize) as u32);
                    *on = !converged(&film, x, y, done, a);
                }
            }
            if !mask.contains(&true) {
                break;
            }
        }
        if let Some(b) = &bar {
            b.set_message(format!("{done} spp"));
        }
        if last_write.elapsed() >= options.checkpoint_interval {
            // A periodic checkpoint that cannot be written (a full disk) leaves the previous
            // one whole; the render goes on and tries again at the next interval.
            if let Err(e) = checkpoint(&film, done, active.as_deref()) {
                let message =
                    format!("warning: checkpoint not written ({e}); the previous one is kept");
                match &bar {
                    Some(b) => b.println(message),
                    None => eprintln!("{message}"),
                }
            }
            last_write = Instant::now();
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
