//! `velour reference SCENE -o ref.exr [--spp N | --time S]`: renders a high-sample reference
//! image with its per-pixel variance (the `variance.R/G/B` layers of the EXR, see
//! [`crate::film`]), for `velour diff` and `velour tradeoff`.
//!
//! The render is driven here, in passes over the whole image, so that it can stop after a time
//! budget as well as after a sample count ([`Budget`]). Every sample uses the same deterministic
//! sampler as [`crate::render`] (`PixelSampler::new(seed, x, y, sample_index)`), so for a sample
//! budget the image is bit-identical whatever the thread count. For a time budget the number of
//! samples depends on the machine's speed; the result is still an unbiased estimate with an
//! exact per-pixel sample count (the `samples.N` layer).
//!
//! **Seed.** A reference must be statistically independent of the images compared against it:
//! sample `i` of pixel (x, y) is the same random sequence in any render with the same seed. So
//! `velour reference` uses the seed `scene seed + REFERENCE_SEED_OFFSET` unless `--seed` is
//! given.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use rayon::prelude::*;

use super::CliResult;
use crate::film::{Film, FilmTile, PixelSample};
use crate::integrator::{trace_path, TraceStats};
use crate::math::Vec2;
use crate::render::{png_path_for, RenderError, RenderSummary, TILE_SIZE};
use crate::sampling::PixelSampler;
use crate::scene::Scene;

/// Added to the scene's seed by `velour reference` (unless `--seed` is given), so that the
/// reference's samples are independent of a `velour render` of the same scene.
pub const REFERENCE_SEED_OFFSET: u64 = 0x5EED_0000_0000_0001;

/// Largest number of samples per pixel a budgeted render takes.
pub const MAX_SPP: u32 = 1 << 24;

/// Errors of [`render_budget`].
#[derive(Debug, thiserror::Error)]
pub enum ReferenceError {
    /// A sample budget outside [1, MAX_SPP] or a time budget that is not a positive number.
    #[error("bad render budget: {0}")]
    BadBudget(String),
    /// The render loop failed (thread pool, film, output).
    #[error("{0}")]
    Render(#[from] RenderError),
    /// The film could not be created or merged.
    #[error("{0}")]
    Film(#[from] crate::film::FilmError),
}

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
    /// Show a progress line on stderr after each pass.
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
pub fn render_budget(
    scene: &Scene,
    options: &BudgetOptions,
) -> Result<BudgetResult, ReferenceError> {
    match options.budget {
        Budget::Samples(n) if n == 0 || n > MAX_SPP => {
            return Err(ReferenceError::BadBudget(format!(
                "{n} samples per pixel is outside [1, {MAX_SPP}]"
            )))
        }
        Budget::Seconds(s) if !(s > 0.0 && s.is_finite()) => {
            return Err(ReferenceError::BadBudget(format!(
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
                .map(|tile| render_tile_pass(scene, seed, tile, s0, s1))
                .collect()
        });
        for (tile, st) in tiles.iter().zip(&pass_stats) {
            film.merge_tile(tile)?;
            stats.merge(st);
        }
        done = s1;
        pass_size = pass_size.saturating_mul(2).min(64);
        if options.progress {
            eprint!("\r{done} spp, {:.1} s   ", start.elapsed().as_secs_f64());
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
    if options.progress {
        eprintln!();
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
    };
    Ok(BudgetResult {
        film,
        summary,
        spp: done,
    })
}

/// Scene and film overrides shared by `velour reference` and `velour tradeoff`.
#[derive(Debug, Clone, Default, clap::Args)]
pub struct SceneOverrides {
    /// Image width in pixels (overrides film.width).
    #[arg(long)]
    pub width: Option<u32>,
    /// Image height in pixels (overrides film.height).
    #[arg(long)]
    pub height: Option<u32>,
    /// Maximum scattering events per path (overrides film.max_depth).
    #[arg(long)]
    pub max_depth: Option<u32>,
}

/// Loads `scene` (or the built-in default scene) and applies the overrides.
pub fn load_scene_with(
    scene: Option<&Path>,
    o: &SceneOverrides,
) -> Result<Scene, Box<dyn std::error::Error + Send + Sync>> {
    let mut s = match scene {
        Some(p) => Scene::load(p)?,
        None => crate::scene::default_scene()?,
    };
    if let Some(d) = o.max_depth {
        if d == 0 || d > 1_000_000 {
            return Err(format!("--max-depth {d} is outside [1, 1000000]").into());
        }
        s.film.max_depth = d;
    }
    if o.width.is_some() || o.height.is_some() {
        let w = o.width.unwrap_or(s.film.width);
        let h = o.height.unwrap_or(s.film.height);
        if w == 0 || h == 0 || w > 32768 || h > 32768 {
            return Err(format!("--width/--height {w}x{h} outside [1, 32768]").into());
        }
        s.set_resolution(w, h)?;
    }
    Ok(s)
}

/// Arguments of `velour reference`.
#[derive(Debug, clap::Args)]
pub struct ReferenceArgs {
    /// Scene file (TOML). Without it, the built-in default scene.
    pub scene: Option<PathBuf>,
    /// Output EXR (beauty, variance of the mean, samples, AOVs); a PNG preview goes next to it.
    #[arg(short = 'o', long = "output")]
    pub output: PathBuf,
    /// Samples per pixel.
    #[arg(long, conflicts_with = "time")]
    pub spp: Option<u32>,
    /// Time budget in seconds (whole-image passes until the budget is spent).
    #[arg(long)]
    pub time: Option<f64>,
    /// Random seed (default: the scene's seed + 0x5EED000000000001, independent of `velour
    /// render`).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Worker threads (0 = all cores).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Seconds between checkpoint writes of the partial image.
    #[arg(long, default_value_t = 60.0)]
    pub checkpoint: f64,
    /// No progress line.
    #[arg(long, short = 'q')]
    pub quiet: bool,
    /// Film overrides.
    #[command(flatten)]
    pub overrides: SceneOverrides,
}

/// Runs `velour reference`.
pub fn run(args: &ReferenceArgs) -> CliResult {
    let budget = match (args.spp, args.time) {
        (Some(n), None) => {
            if n == 0 || n > MAX_SPP {
                return Err(format!("--spp {n} is outside [1, {MAX_SPP}]").into());
            }
            Budget::Samples(n)
        }
        (None, Some(t)) => {
            if !(t > 0.0 && t.is_finite() && t < 1e8) {
                return Err(format!("--time {t} must be a positive number of seconds").into());
            }
            Budget::Seconds(t)
        }
        _ => return Err("give exactly one of --spp N or --time SECONDS".into()),
    };
    if !(args.checkpoint > 0.0 && args.checkpoint.is_finite()) {
        return Err(format!(
            "--checkpoint {} must be a positive number of seconds",
            args.checkpoint
        )
        .into());
    }
    let mut scene = load_scene_with(args.scene.as_deref(), &args.overrides)?;
    for w in &scene.warnings {
        eprintln!("warning: {w}");
    }
    scene.film.seed = args
        .seed
        .unwrap_or(scene.film.seed.wrapping_add(REFERENCE_SEED_OFFSET));
    eprintln!(
        "reference of {} at {}x{}, {}, seed {}",
        scene.source.display(),
        scene.film.width,
        scene.film.height,
        match budget {
            Budget::Samples(n) => format!("{n} spp"),
            Budget::Seconds(s) => format!("{s} s"),
        },
        scene.film.seed
    );
    let options = BudgetOptions {
        budget,
        threads: args.threads,
        progress: !args.quiet,
        checkpoint: Some(args.output.clone()),
        checkpoint_interval: Duration::from_secs_f64(args.checkpoint),
    };
    let r = render_budget(&scene, &options)?;
    let mut attributes = BTreeMap::new();
    attributes.insert("velour:kind".to_string(), "reference".to_string());
    attributes.insert("velour:spp".to_string(), r.spp.to_string());
    attributes.insert("velour:seed".to_string(), scene.film.seed.to_string());
    attributes.insert(
        "velour:seconds".to_string(),
        format!("{:.3}", r.summary.seconds),
    );
    attributes.insert(
        "velour:non_finite".to_string(),
        r.summary.non_finite.to_string(),
    );
    let scene_name: String = scene
        .source
        .display()
        .to_string()
        .chars()
        .filter(|c| (*c as u32) < 256)
        .collect();
    attributes.insert("velour:scene".to_string(), scene_name);
    write_film(&r.film, &args.output, scene.film.exposure, &attributes)?;
    println!(
        "wrote {} and {} ({} spp)",
        args.output.display(),
        png_path_for(&args.output).display(),
        r.spp
    );
    println!("{}", r.summary);
    Ok(())
}
