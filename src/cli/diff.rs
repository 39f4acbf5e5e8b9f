//! `velour diff A.exr B.exr`: compares an image against a reference (B) and prints RMSE,
//! relative MSE, relative RMSE, mean bias and, when both files carry variance layers, a
//! per-pixel z-test summary with a verdict; optionally only over the white pixels of a mask
//! PNG, and optionally writes a false-colour error PNG. See `docs/diff.md`.

use super::CliResult;
use crate::image_io::{self, compare, ImageComparison};
use std::fmt::Write as _;
use std::path::PathBuf;

/// Arguments of `velour diff`.
#[derive(Debug, clap::Args)]
pub struct DiffArgs {
    /// The image under test (EXR).
    pub a: PathBuf,
    /// The reference image (EXR).
    pub b: PathBuf,
    /// Print one JSON object instead of the human-readable report.
    #[arg(long)]
    pub json: bool,
    /// Write a false-colour error map to this PNG (z-scores when both images have variance
    /// layers, else absolute error).
    #[arg(long, value_name = "PNG")]
    pub error_png: Option<PathBuf>,
    /// The layer to compare: empty for the default R, G, B; otherwise e.g. `albedo`, `normal`,
    /// `depth`.
    #[arg(long, value_name = "NAME", default_value = "")]
    pub layer: String,
    /// Where the error map's colour scale saturates: |z| for z-score maps (default 5), |a - b|
    /// for absolute-error maps (default: the 99th percentile of the per-pixel error).
    #[arg(long, value_name = "VALUE")]
    pub error_scale: Option<f64>,
    /// Exit with an error when the z-test verdict is "inconsistent".
    #[arg(long)]
    pub check: bool,
    /// Compare only the pixels that are white in this PNG (same size as the images; a pixel
    /// counts when its R, G and B are all at least 128): e.g. the pixels of one object. The
    /// error map still shows every pixel.
    #[arg(long, value_name = "PNG")]
    pub mask: Option<PathBuf>,
}

/// The JSON document printed by `--json`.
#[derive(serde::Serialize)]
struct JsonReport<'a> {
    a: String,
    b: String,
    mask: Option<String>,
    #[serde(flatten)]
    comparison: &'a ImageComparison,
    verdict: Option<&'static str>,
    error_png: Option<ErrorPngInfo>,
}

#[derive(serde::Serialize)]
struct ErrorPngInfo {
    path: String,
    mode: compare::ErrorMapMode,
    scale: f64,
}

fn verdict(c: &ImageComparison) -> Option<&'static str> {
    c.z_test.as_ref().map(|z| {
        if z.consistent {
            "consistent"
        } else {
            "inconsistent"
        }
    })
}

/// Runs `velour diff`.
pub fn run(args: &DiffArgs) -> CliResult {
    let a = image_io::read_exr(&args.a)?;
    let b = image_io::read_exr(&args.b)?;
    let mask = match &args.mask {
        Some(path) => Some(compare::PixelMask::read_png(path)?),
        None => None,
    };
    let cmp = compare::compare_layer_masked(&a, &b, &args.layer, mask.as_ref())?;
    let mut png_info = None;
    if let Some(path) = &args.error_png {
        let map = compare::error_map(&a, &b, &args.layer, args.error_scale)?;
        image_io::write_png_rgb8(path, map.width, map.height, &map.rgb8)?;
        png_info = Some(ErrorPngInfo {
            path: path.display().to_string(),
            mode: map.mode,
            scale: map.scale,
        });
    }
    if args.json {
        let report = JsonReport {
            a: args.a.display().to_string(),
            b: args.b.display().to_string(),
            mask: args.mask.as_ref().map(|m| m.display().to_string()),
            comparison: &cmp,
            verdict: verdict(&cmp),
            error_png: png_info,
        };
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print!("{}", human_report(args, &cmp, png_info.as_ref()));
    }
    if args.check && verdict(&cmp) == Some("inconsistent") {
        return Err(format!(
            "{} is inconsistent with the reference {} (z-test)",
            args.a.display(),
            args.b.display()
        )
        .into());
    }
    Ok(())
}

fn human_report(args: &DiffArgs, c: &ImageComparison, png: Option<&ErrorPngInfo>) -> String {
    let mut s = String::new();
    let layer = if c.layer.is_empty() {
        "default (R, G, B)"
    } else {
        &c.layer
    };
    let _ = writeln!(s, "A:         {}", args.a.display());
    let _ = writeln!(s, "B (ref):   {}", args.b.display());
    let _ = writeln!(s, "size:      {}x{}   layer: {layer}", c.width, c.height);
    if let Some(m) = &args.mask {
        let total = u64::from(c.width) * u64::from(c.height);
        let _ = writeln!(
            s,
            "mask:      {} ({} of {total} pixels compared)",
            m.display(),
            total - c.masked_out
        );
    }
    if c.skipped_non_finite > 0 {
        let _ = writeln!(
            s,
            "skipped:   {} pixel-channels with NaN/inf values",
            c.skipped_non_finite
        );
    }
    let _ = writeln!(
        s,
        "\n{:<12} {:>13} {:>13} {:>13} {:>13}",
        "channel", "RMSE", "relMSE", "mean bias", "max |a-b|"
    );
    for ch in &c.per_channel {
        let _ = writeln!(
            s,
            "{:<12} {:>13.6e} {:>13.6e} {:>13.6e} {:>13.6e}",
            ch.name, ch.rmse, ch.rel_mse, ch.mean_bias, ch.max_abs_error
        );
    }
    let _ = writeln!(
        s,
        "{:<12} {:>13.6e} {:>13.6e} {:>13.6e} {:>13.6e}",
        "all", c.rmse, c.rel_mse, c.mean_bias, c.max_abs_error
    );
    let rel: Vec<String> = c
        .per_channel
        .iter()
        .map(|ch| format!("{} {:.4}", ch.name, ch.rel_rmse))
        .collect();
    let _ = writeln!(
        s,
        "\nrelative RMSE sqrt(mean(((a-b)/b)^2)): {:.4} ({})",
        c.rel_rmse,
        rel.join(", ")
    );
    let over_mean = if c.mean_reference != 0.0 {
        format!("{:.4}", c.rmse / c.mean_reference.abs())
    } else {
        "undefined (mean of B is 0)".to_string()
    };
    let _ = writeln!(s, "RMSE / mean(b): {over_mean}");
    match &c.z_test {
        None => {
            let _ = writeln!(
                s,
                "\nz-test:    not run (variance layers missing in A or B)"
            );
        }
        Some(z) => {
            let _ = writeln!(
                s,
                "\nz-test over {} pixel-channels ({}; tails from {}):",
                z.tested,
                z.variance_channels.join(", "),
                if z.uses_sample_counts {
                    "Student's t with per-pixel sample counts"
                } else {
                    "the normal distribution"
                }
            );
            if z.untestable > 0 || z.zero_variance > 0 {
                let _ = writeln!(
                    s,
                    "  untestable: {}   zero variance: {}",
                    z.untestable, z.zero_variance
                );
            }
            let _ = writeln!(
                s,
                "  beyond 2 sigma: {:.4}% (expected {:.4}%)   beyond 3 sigma: {:.4}% (expected {:.4}%)",
                100.0 * z.frac_above_2,
                100.0 * z.expected_above_2,
                100.0 * z.frac_above_3,
                100.0 * z.expected_above_3
            );
            let bias: Vec<String> = c
                .per_channel
                .iter()
                .zip(&z.bias_z)
                .map(|(ch, b)| format!("{} {b:+.2}", ch.name))
                .collect();
            let _ = writeln!(
                s,
                "  mean z: {:+.4}   mean z^2: {:.4}   aggregate bias z: {}",
                z.mean_z,
                z.mean_z2,
                bias.join(", ")
            );
            let _ = writeln!(
                s,
                "  p-values: tail {:.3e}, bias {:.3e} (reject below {:.1e} each)",
                z.tail_p_value,
                z.bias_p_value,
                compare::VERDICT_ALPHA / 2.0
            );
            let _ = writeln!(
                s,
                "  verdict: {}",
                if z.consistent {
                    "consistent"
                } else {
                    "INCONSISTENT"
                }
            );
        }
    }
    if let Some(p) = png {
        let what = match p.mode {
            compare::ErrorMapMode::ZScore => "z-score, saturating at |z|",
            compare::ErrorMapMode::AbsoluteError => "mean |a-b|, saturating at",
        };
        let _ = writeln!(s, "\nerror map: {} ({what} {:.4e})", p.path, p.scale);
    }
    s
}
