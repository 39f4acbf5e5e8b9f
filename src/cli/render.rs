//! `velour render [SCENE.toml]`: renders a scene file (or the built-in default scene) to an
//! EXR with beauty, variance, albedo, normal and depth layers, plus a PNG preview.

use std::path::PathBuf;
use std::time::Duration;

use super::CliResult;
use crate::render::{png_path_for, render, RenderOptions};
use crate::scene::Scene;

/// Arguments of `velour render`.
#[derive(Debug, clap::Args)]
pub struct RenderArgs {
    /// Scene file (TOML). Without it, the built-in default scene (the translucent creature).
    pub scene: Option<PathBuf>,
    /// Samples per pixel (overrides film.spp).
    #[arg(long)]
    pub spp: Option<u32>,
    /// Random seed (overrides film.seed).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Worker threads (0 = all cores).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Output EXR path (overrides film.output); the PNG preview is written next to it.
    #[arg(short = 'o', long = "output")]
    pub output: Option<PathBuf>,
    /// Image width in pixels (overrides film.width).
    #[arg(long)]
    pub width: Option<u32>,
    /// Image height in pixels (overrides film.height).
    #[arg(long)]
    pub height: Option<u32>,
    /// Maximum scattering events per path (overrides film.max_depth).
    #[arg(long)]
    pub max_depth: Option<u32>,
    /// Seconds between checkpoint writes of the partial image.
    #[arg(long, default_value_t = 20.0)]
    pub checkpoint: f64,
    /// No progress bar.
    #[arg(long, short = 'q')]
    pub quiet: bool,
}

/// Loads the scene named by `args` (or the default one) and applies the command-line overrides.
pub fn load_with_overrides(
    args: &RenderArgs,
) -> Result<Scene, Box<dyn std::error::Error + Send + Sync>> {
    let overrides = super::reference::SceneOverrides {
        width: args.width,
        height: args.height,
        max_depth: args.max_depth,
    };
    let mut scene = super::reference::load_scene_with(args.scene.as_deref(), &overrides)?;
    if let Some(spp) = args.spp {
        if spp == 0 || spp > 1 << 24 {
            return Err(format!("--spp {spp} is outside [1, 16777216]").into());
        }
        scene.film.spp = spp;
    }
    if let Some(seed) = args.seed {
        scene.film.seed = seed;
    }
    if let Some(o) = &args.output {
        scene.film.output = o.clone();
    }
    Ok(scene)
}

/// Runs `velour render`.
pub fn run(args: &RenderArgs) -> CliResult {
    if !(args.checkpoint > 0.0) || !args.checkpoint.is_finite() {
        return Err(format!(
            "--checkpoint {} must be a positive number of seconds",
            args.checkpoint
        )
        .into());
    }
    let scene = load_with_overrides(args)?;
    for w in &scene.warnings {
        eprintln!("warning: {w}");
    }
    for n in &scene.notes {
        eprintln!("note: {n}");
    }
    let output = scene.film.output.clone();
    let options = RenderOptions {
        threads: args.threads,
        progress: !args.quiet,
        output: Some(output.clone()),
        checkpoint_interval: Duration::from_secs_f64(args.checkpoint),
    };
    eprintln!(
        "rendering {} at {}x{}, {} spp, seed {}",
        scene.source.display(),
        scene.film.width,
        scene.film.height,
        scene.film.spp,
        scene.film.seed
    );
    let (_film, summary) = render(&scene, &options)?;
    println!(
        "wrote {} and {}",
        output.display(),
        png_path_for(&output).display()
    );
    println!("{summary}");
    Ok(())
}
