//! `velour bench [SCENE]`: renders a scene (default: the built-in creature) at fixed settings
//! without writing images and prints paths/s and rays/s, for `docs/BENCHMARKS.md`.

use super::CliResult;
use crate::render::{render, RenderOptions};

/// Arguments of `velour bench`.
#[derive(Debug, clap::Args)]
pub struct BenchArgs {
    /// Scene file (TOML); default: the built-in default scene.
    pub scene: Option<std::path::PathBuf>,
    /// Samples per pixel.
    #[arg(long, default_value_t = 4)]
    pub spp: u32,
    /// Image width (height follows the scene's aspect ratio).
    #[arg(long, default_value_t = 160)]
    pub width: u32,
    /// Worker threads (0 = all cores).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Repetitions (the best and the median are printed).
    #[arg(long, default_value_t = 3)]
    pub repeat: u32,
}

/// Runs `velour bench`.
pub fn run(args: &BenchArgs) -> CliResult {
    if args.spp == 0
        || args.width == 0
        || args.width > 32768
        || args.repeat == 0
        || args.repeat > 1000
    {
        return Err(
            "--spp, --width and --repeat must be positive (width ≤ 32768, repeat ≤ 1000)".into(),
        );
    }
    let mut scene = match &args.scene {
        Some(p) => crate::scene::Scene::load(p)?,
        None => crate::scene::default_scene()?,
    };
    let aspect = scene.film.height as f64 / scene.film.width as f64;
    let height = ((args.width as f64 * aspect).round() as u32).max(1);
    scene.set_resolution(args.width, height)?;
    scene.film.spp = args.spp;
    let mut runs = Vec::new();
    for _ in 0..args.repeat {
        let (_, s) = render(
            &scene,
            &RenderOptions {
                threads: args.threads,
                ..RenderOptions::default()
            },
        )?;
        runs.push(s);
    }
    runs.sort_by(|a, b| a.seconds.total_cmp(&b.seconds));
    let best = &runs[0];
    let median = &runs[runs.len() / 2];
    println!(
        "scene: {}  {}x{} @ {} spp, {} threads",
        scene.source.display(),
        args.width,
        height,
        args.spp,
        best.threads
    );
    for (name, s) in [("best", best), ("median", median)] {
        println!(
            "{name:>6}: {:.3} s  {:.1} k paths/s  {:.2} M rays/s  mean path length {:.1}",
            s.seconds,
            s.samples as f64 / s.seconds / 1e3,
            s.rays as f64 / s.seconds / 1e6,
            s.mean_path_length
        );
    }
    Ok(())
}
