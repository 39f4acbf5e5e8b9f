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
use std::time::Duration;

use super::CliResult;
use crate::render::png_path_for;
pub use crate::render::{render_budget, write_film, Budget, BudgetOptions, BudgetResult, MAX_SPP};
use crate::scene::Scene;

/// Added to the scene's seed by `velour reference` (unless `--seed` is given), so that the
/// reference's samples are independent of a `velour render` of the same scene.
pub const REFERENCE_SEED_OFFSET: u64 = 0x5EED_0000_0000_0001;

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
    apply_overrides(&mut s, o)?;
    Ok(s)
}

/// Applies the resolution and depth overrides to a loaded scene.
pub fn apply_overrides(
    s: &mut Scene,
    o: &SceneOverrides,
) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
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
    Ok(())
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
        threads: args.threads,
        progress: !args.quiet,
        checkpoint: Some(crate::render::partial_path_for(&args.output)),
        checkpoint_interval: Duration::from_secs_f64(args.checkpoint),
        ..BudgetOptions::new(budget)
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
    if let Some(partial) = &options.checkpoint {
        crate::render::remove_partial(partial);
    }
    println!(
        "wrote {} and {} ({} spp)",
        args.output.display(),
        png_path_for(&args.output).display(),
        r.spp
    );
    println!("{}", r.summary);
    Ok(())
}
