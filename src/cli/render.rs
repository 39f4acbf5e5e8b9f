//! `velour render [SCENE.toml]`: renders a scene file (or the built-in default scene) to an
//! EXR with beauty, variance, albedo, normal and depth layers, plus a PNG preview; or one part
//! of it (`--tile`, `--samples`), or a frame range (`--frames`). Checkpoints go to
//! `OUT.partial.exr`; SIGINT/SIGTERM writes one and exits non-zero; `--resume` continues it.

use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Duration;

use super::CliResult;
use crate::farm::{self, FrameRange, PartInfo, SampleRange, TileSpec};
use crate::image_io::read_exr;
use crate::render::{
    partial_path_for, png_path_for, remove_partial, render_budget, write_film, write_state,
    Adaptive, Budget, BudgetOptions, Resume,
};
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
    /// Output EXR path (overrides film.output); the PNG preview is written next to it. With
    /// --frames it must contain {frame} or {frame:0N}.
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
    /// Path throughput below which Russian roulette plays, in (0, 1] (overrides
    /// film.roulette_threshold).
    #[arg(long)]
    pub roulette_threshold: Option<f32>,
    /// Seconds between checkpoints (OUT.partial.exr, with the exact film state).
    #[arg(
        long = "checkpoint-every",
        alias = "checkpoint",
        default_value_t = 20.0
    )]
    pub checkpoint_every: f64,
    /// Render only tile I of N (0-based): a horizontal band of whole rows. Writes a part file
    /// (OUT.tileI-N.exr unless -o is given) for `velour merge`.
    #[arg(long)]
    pub tile: Option<TileSpec>,
    /// Render only sample indices A..B-1 of every pixel (B <= spp). Writes a part file
    /// (OUT.samplesA-B.exr unless -o is given) for `velour merge`.
    #[arg(long)]
    pub samples: Option<SampleRange>,
    /// Render frames A..B (B excluded) or A..=B (B included), substituting {frame} and
    /// {frame:0N} in the scene's file paths and in the output.
    #[arg(long)]
    pub frames: Option<FrameRange>,
    /// Continue from the checkpoint (OUT.partial.exr) if there is one; refused if it belongs to
    /// another scene, seed, resolution, tile or sample range.
    #[arg(long)]
    pub resume: bool,
    /// Adaptive sampling: a pixel stops once the standard error of its luminance mean over
    /// max(luminance, 0.01) is below this (e.g. 0.01), tested every 16 samples after --min-spp.
    /// Slightly biased (see docs/farm.md). Not with --samples.
    #[arg(long)]
    pub noise_threshold: Option<f64>,
    /// Adaptive sampling: samples every pixel takes before it may stop (default 16, at most
    /// the maximum).
    #[arg(long)]
    pub min_spp: Option<u32>,
    /// Adaptive sampling: the most samples a pixel takes (default: --spp / film.spp).
    #[arg(long)]
    pub max_spp: Option<u32>,
    /// Stop starting new sample passes after this many seconds (the image then has fewer
    /// samples than asked; every pixel the same number unless adaptive). Not with --samples.
    #[arg(long)]
    pub time_limit: Option<f64>,
    /// No progress bar.
    #[arg(long, short = 'q')]
    pub quiet: bool,
}

/// Loads the scene named by `args` (or the default one) and applies the command-line overrides.
pub fn load_with_overrides(
    args: &RenderArgs,
) -> Result<Scene, Box<dyn std::error::Error + Send + Sync>> {
    load_frame(args, None).map(|(scene, _)| scene)
}

/// Loads the scene for `frame` (substituting `{frame}` in its text when given), applies the
/// overrides, and returns it with the text it was built from.
fn load_frame(
    args: &RenderArgs,
    frame: Option<u32>,
) -> Result<(Scene, String), Box<dyn std::error::Error + Send + Sync>> {
    let overrides = super::reference::SceneOverrides {
        width: args.width,
        height: args.height,
        max_depth: args.max_depth,
    };
    let (mut scene, text) = match (&args.scene, frame) {
        (Some(path), _) => {
            let raw = std::fs::read_to_string(path)
                .map_err(|e| format!("{}: cannot read: {e}", path.display()))?;
            let text = match frame {
                Some(f) => farm::split::substitute_frame(&raw, f)
                    .map_err(|e| format!("{}: {e}", path.display()))?,
                None => raw,
            };
            (crate::scene::load_scene_str(&text, path)?, text)
        }
        (None, Some(_)) => return Err("--frames needs a scene file".into()),
        (None, None) => {
            let scene = crate::scene::default_scene()?;
            (scene, crate::scene::DEFAULT_SCENE_TEXT.to_string())
        }
    };
    super::reference::apply_overrides(&mut scene, &overrides)?;
    if let Some(t) = args.roulette_threshold {
        if !(t > 0.0 && t <= 1.0) {
            return Err(format!("--roulette-threshold {t} is outside (0, 1]").into());
        }
        scene.film.roulette.threshold = t;
    }
    if let Some(spp) = args.spp {
        if spp == 0 || spp > 1 << 24 {
            return Err(format!("--spp {spp} is outside [1, 16777216]").into());
        }
        scene.film.spp = spp;
    }
    if let Some(seed) = args.seed {
        scene.film.seed = seed;
    }
    if let Some(max) = args.max_spp {
        if args.noise_threshold.is_none() {
            return Err("--max-spp needs --noise-threshold (use --spp for a fixed count)".into());
        }
        if max == 0 || max > 1 << 24 {
            return Err(format!("--max-spp {max} is outside [1, 16777216]").into());
        }
        scene.film.spp = max;
    }
    if let Some(o) = &args.output {
        scene.film.output = o.clone();
    }
    Ok((scene, text))
}

/// `OUT.tileI-N.samplesA-B.exr` from `OUT.exr` for the parts that are split.
fn part_path(output: &Path, tile: Option<TileSpec>, samples: Option<&SampleRange>) -> PathBuf {
    let stem = output.file_stem().unwrap_or_default().to_string_lossy();
    let ext = output
        .extension()
        .map_or_else(|| "exr".into(), |e| e.to_string_lossy());
    let mut name = stem.to_string();
    if let Some(t) = tile {
        name.push_str(&format!(".tile{}-{}", t.index, t.count));
    }
    if let Some(s) = samples {
        name.push_str(&format!(".samples{}-{}", s.0.start, s.0.end));
    }
    output.with_file_name(format!("{name}.{ext}"))
}

/// The command line, as Latin-1 text for the EXR header.
fn command_line() -> String {
    std::env::args()
        .collect::<Vec<_>>()
        .join(" ")
        .chars()
        .map(|c| if (c as u32) < 256 { c } else { '?' })
        .collect()
}

/// Runs `velour render`.
pub fn run(args: &RenderArgs) -> CliResult {
    if !(args.checkpoint_every > 0.0 && args.checkpoint_every.is_finite()) {
        return Err(format!(
            "--checkpoint-every {} must be a positive number of seconds",
            args.checkpoint_every
        )
        .into());
    }
    if args.samples.is_some() && (args.noise_threshold.is_some() || args.time_limit.is_some()) {
        return Err("--noise-threshold and --time-limit cannot be combined with --samples: a sample range must be rendered whole to merge exactly".into());
    }
    if let Some(t) = args.noise_threshold {
        if !(t > 0.0 && t.is_finite()) {
            return Err(format!("--noise-threshold {t} must be a positive number").into());
        }
    } else if args.min_spp.is_some() {
        return Err("--min-spp needs --noise-threshold".into());
    }
    if let Some(t) = args.time_limit {
        if !(t > 0.0 && t.is_finite()) {
            return Err(format!("--time-limit {t} must be a positive number of seconds").into());
        }
    }
    let stop = Arc::new(AtomicBool::new(false));
    for signal in [signal_hook::consts::SIGTERM, signal_hook::consts::SIGINT] {
        signal_hook::flag::register(signal, Arc::clone(&stop))
            .map_err(|e| format!("cannot install the signal handler: {e}"))?;
    }
    match &args.frames {
        Some(frames) => {
            let pattern = args
                .output
                .as_ref()
                .map(|o| o.to_string_lossy().to_string());
            if let Some(p) = &pattern {
                if !p.contains("{frame") {
                    return Err(format!(
                        "--frames with -o {p}: every frame would overwrite the same file; put {{frame}} or {{frame:04}} in the output"
                    )
                    .into());
                }
            }
            for f in frames.0.clone() {
                render_frame(args, Some(f), &stop)?;
            }
            Ok(())
        }
        None => render_frame(args, None, &stop),
    }
}

fn render_frame(args: &RenderArgs, frame: Option<u32>, stop: &Arc<AtomicBool>) -> CliResult {
    let (mut scene, text) = load_frame(args, frame)?;
    if let Some(f) = frame {
        let out = scene.film.output.to_string_lossy().to_string();
        if !out.contains("{frame") && args.output.is_none() {
            return Err(format!(
                "--frames: film.output {out} has no {{frame}} placeholder; every frame would overwrite it"
            )
            .into());
        }
        scene.film.output = PathBuf::from(farm::split::substitute_frame(&out, f)?);
    }
    for w in &scene.warnings {
        eprintln!("warning: {w}");
    }
    for n in &scene.notes {
        eprintln!("note: {n}");
    }
    let film = &scene.film;
    let settings = format!(
        "{}x{} max_depth={}",
        film.width, film.height, film.max_depth
    );
    let scene_hash = farm::hash::scene_hash(&text, &scene.inputs, &settings)?;
    let tile = args.tile;
    let rows = match tile {
        Some(t) => t.rows(film.height)?,
        None => 0..film.height,
    };
    let samples = args.samples.clone().map_or(0..film.spp, |s| s.0);
    if samples.end > film.spp {
        return Err(format!(
            "--samples {}..{} goes beyond the render's {} spp (set --spp to the whole render's count)",
            samples.start, samples.end, film.spp
        )
        .into());
    }
    let is_part = tile.is_some() || args.samples.is_some();
    let output = if is_part && args.output.is_none() {
        part_path(&film.output, tile, args.samples.as_ref())
    } else {
        film.output.clone()
    };
    let info = PartInfo {
        version: farm::version(),
        scene_hash,
        seed: film.seed,
        width: film.width,
        height: film.height,
        spp: film.spp,
        tile,
        rows: rows.clone(),
        samples: samples.clone(),
    };
    let mut attributes = info.to_attributes();
    attributes.insert("velour:command".into(), command_line());
    if let Some(f) = frame {
        attributes.insert("velour:frame".into(), f.to_string());
    }
    attributes.extend(super::metadata::estimator_attributes(&scene));
    let checkpoint = partial_path_for(&output);
    let adaptive = match args.noise_threshold {
        Some(threshold) => {
            let min_spp = args.min_spp.unwrap_or(16).clamp(2, film.spp.max(2));
            attributes.insert("velour:noise_threshold".into(), threshold.to_string());
            attributes.insert("velour:min_spp".into(), min_spp.to_string());
            Some(Adaptive { threshold, min_spp })
        }
        None => None,
    };
    let resume = if args.resume {
        resume_from(&checkpoint, &info)?
    } else {
        None
    };
    let options = BudgetOptions {
        threads: args.threads,
        progress: !args.quiet,
        checkpoint: Some(checkpoint.clone()),
        checkpoint_interval: Duration::from_secs_f64(args.checkpoint_every),
        attributes: attributes.clone(),
        rows: Some(rows.clone()),
        first_sample: samples.start,
        resume,
        stop: Some(Arc::clone(stop)),
        adaptive,
        time_limit: args.time_limit,
        ..BudgetOptions::new(Budget::Samples(samples.end - samples.start))
    };
    eprintln!(
        "rendering {}{} at {}x{}, samples {}..{} of {} spp{}, seed {}",
        scene.source.display(),
        frame.map_or_else(String::new, |f| format!(" frame {f}")),
        film.width,
        film.height,
        samples.start,
        samples.end,
        film.spp,
        tile.map_or_else(String::new, |t| format!(
            ", tile {t} (rows {}..{})",
            rows.start, rows.end
        )),
        film.seed
    );
    #[cfg(feature = "ray-log")]
    let ray_log = crate::geometry::ray_log::start_from_env()?;
    let r = render_budget(&scene, &options)?;
    #[cfg(feature = "ray-log")]
    if let Some(path) = ray_log {
        let log = crate::geometry::ray_log::finish(&scene.geometry);
        log.write_file(&path)?;
        eprintln!(
            "ray log: {} of {} queries written to {}",
            log.queries.len(),
            log.seen,
            path.display()
        );
    }
    attributes.insert(
        "velour:render_seconds".into(),
        format!("{:.3}", r.summary.seconds),
    );
    if is_part {
        write_state(&r.film, &output, scene.film.exposure, &attributes)?;
    } else {
        write_film(&r.film, &output, scene.film.exposure, &attributes)?;
    }
    remove_partial(&checkpoint);
    println!(
        "wrote {} and {}",
        output.display(),
        png_path_for(&output).display()
    );
    println!("{}", r.summary);
    for line in super::metadata::interior_summary(&scene) {
        println!("{line}");
    }
    Ok(())
}

/// The film and finished sample count of a checkpoint of this very render, or `None` when there
/// is no checkpoint. A checkpoint of another scene, seed, resolution, tile or sample range is an
/// error naming the file and what differs.
fn resume_from(
    checkpoint: &Path,
    info: &PartInfo,
) -> Result<Option<Resume>, Box<dyn std::error::Error + Send + Sync>> {
    if !checkpoint.exists() {
        eprintln!(
            "note: --resume: no checkpoint {} yet; starting from the first sample",
            checkpoint.display()
        );
        return Ok(None);
    }
    let img = read_exr(checkpoint)?;
    let bad = |why: String| format!("--resume: {}: {why}", checkpoint.display());
    let saved = PartInfo::from_attributes(&img.attributes).map_err(bad)?;
    let fields: [(&str, String, String); 7] = [
        (
            "scene hash",
            saved.scene_hash.clone(),
            info.scene_hash.clone(),
        ),
        ("seed", saved.seed.to_string(), info.seed.to_string()),
        (
            "resolution",
            format!("{}x{}", saved.width, saved.height),
            format!("{}x{}", info.width, info.height),
        ),
        ("spp", saved.spp.to_string(), info.spp.to_string()),
        (
            "rows",
            format!("{:?}", saved.rows),
            format!("{:?}", info.rows),
        ),
        (
            "samples",
            format!("{:?}", saved.samples),
            format!("{:?}", info.samples),
        ),
        (
            "velour version",
            saved.version.clone(),
            info.version.clone(),
        ),
    ];
    for (what, got, want) in fields {
        if got != want {
            return Err(bad(format!(
                "its {what} is {got}, this render's is {want}; it belongs to another render"
            ))
            .into());
        }
    }
    let resume = Resume::from_image(&img).map_err(bad)?;
    eprintln!(
        "resuming from {}: {} of {} samples per pixel done",
        checkpoint.display(),
        resume.done,
        info.samples.end - info.samples.start
    );
    Ok(Some(resume))
}
