//! `velour tradeoff SCENE --reference ref.exr [--budgets 1,2,4,8] [--unit seconds|spp]`:
//! renders a scene with each applicable estimator configuration at a ladder of budgets and
//! measures error against a reference (from `velour reference`): time, RMSE, relative MSE,
//! mean bias, efficiency = 1/(MSE × time) and density lookups per path. Writes a CSV and an
//! SVG plot (RMSE against time, log–log, one line per configuration) and names the most
//! efficient configuration at the largest budget.
//!
//! Configurations ([`configurations`]) are edits of the scene file's interiors, so any option
//! the scene format gains can be added here as one more [`Configuration`]:
//! - heterogeneous (`voxel`, `fbm`) interiors: delta tracking with residual ratio tracking
//!   (Novák control, the default), with ratio tracking, with the mean-density control; delta and
//!   decomposition tracking with local bounds (the default) and without (`local_bounds =
//!   false`); without the sun-leaned estimate (`sun_lean = false`); the
//!   global majorant against each level of the majorant pyramid; ray marching (free flight and
//!   transmittance) at several step sizes (fractions of the medium's bounding-box diagonal);
//!   baked against exact procedural (`fbm`) density;
//! - every scattering interior: next event estimation at exit points, with guided connections
//!   (`exit_guided`, offered where an interior has a rough dielectric boundary), and at
//!   interior vertices;
//! - manifold next event estimation (`nee = "manifold"`, "NEE manifold") on every scattering
//!   interior where the scene loader accepts it (a smooth dielectric boundary, its own or an
//!   enclosing one, and a sphere or distant light: see [`manifold_objects`]); the other
//!   interiors keep the scene file's strategy.
//!
//! Each configuration's edit is applied to every interior it concerns. Renders use the scene's
//! seed; the reference should come from `velour reference` (which offsets the seed) with many
//! more samples than the largest budget, since its own variance adds to every measured MSE.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use super::reference::{load_scene_with, render_budget, Budget, BudgetOptions, SceneOverrides};
use super::CliResult;
use crate::image_io::{self, compare};
use crate::light::Light;
use crate::medium::Medium;
use crate::scene::{load_scene_str, Scene};

/// One edit of an interior table of the scene file: `interior.<key> = value`.
#[derive(Clone, Debug, PartialEq)]
pub struct Edit {
    /// Which interiors: heterogeneous (`voxel`/`fbm`) ones, `fbm` ones, or every scattering one.
    pub target: Target,
    /// Key inside the `interior` table (e.g. `tracking`, `nee`, `evaluation`).
    pub key: String,
    /// The new value.
    pub value: toml::Value,
}

/// Which interiors an [`Edit`] applies to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Target {
    /// `voxel` and `fbm` interiors.
    Heterogeneous,
    /// `fbm` interiors only.
    Procedural,
    /// Every interior except `absorption`.
    Scattering,
    /// The interior of the scene file's `index`-th `[[object]]` (counting from 0).
    Object(usize),
}

/// A named estimator configuration: edits applied to the scene file.
#[derive(Clone, Debug, PartialEq)]
pub struct Configuration {
    /// Name used in the CSV, the plot and the report.
    pub name: String,
    /// The edits (empty: the scene as written).
    pub edits: Vec<Edit>,
}

/// One measurement: a configuration at a budget.
#[derive(Clone, Debug, PartialEq)]
pub struct Measurement {
    /// Configuration name.
    pub config: String,
    /// The budget asked for (seconds or samples per pixel, see `unit`).
    pub budget: f64,
    /// "seconds" or "spp".
    pub unit: &'static str,
    /// Render time, seconds.
    pub seconds: f64,
    /// Samples per pixel taken.
    pub spp: u32,
    /// RMSE against the reference, over all pixels and RGB channels.
    pub rmse: f64,
    /// Mean of (a − b)² / (b² + 0.01).
    pub rel_mse: f64,
    /// Mean of a − b.
    pub bias: f64,
    /// Efficiency 1 / (RMSE² × seconds).
    pub efficiency: f64,
    /// Density lookups (heterogeneous media) per camera path.
    pub lookups_per_path: f64,
    /// Samples dropped as non-finite.
    pub non_finite: u64,
}

fn table(entries: &[(&str, toml::Value)]) -> toml::Value {
    let mut t = toml::Table::new();
    for (k, v) in entries {
        t.insert((*k).to_string(), v.clone());
    }
    toml::Value::Table(t)
}

fn s(v: &str) -> toml::Value {
    toml::Value::String(v.to_string())
}

fn tracking(entries: &[(&str, toml::Value)]) -> Edit {
    Edit {
        target: Target::Heterogeneous,
        key: "tracking".into(),
        value: table(entries),
    }
}

/// The configurations that apply to `scene` (loaded from `doc`): see the module documentation.
/// `steps` are the ray-marching steps in world units; empty = 1/32, 1/128 and 1/512 of the
/// largest heterogeneous medium's bounding-box diagonal.
#[must_use]
pub fn configurations(doc: &toml::Table, scene: &Scene, steps: &[f64]) -> Vec<Configuration> {
    let kinds: Vec<String> = interiors(doc).map(|(_, t)| estimator_kind(t)).collect();
    let heterogeneous = kinds.iter().any(|k| k == "voxel" || k == "fbm");
    let procedural = kinds.iter().any(|k| k == "fbm");
    let scattering = kinds.iter().any(|k| k != "absorption");
    let mut out = vec![Configuration {
        name: "scene file".into(),
        edits: vec![],
    }];
    if heterogeneous {
        let mut levels = 1usize;
        let mut diagonal = 0.0f64;
        for m in &scene.media {
            let h = match m {
                Medium::Heterogeneous(h) => &**h,
                // A textured voxel/fbm interior's field.
                Medium::Scaled(f) => &*f.medium,
                Medium::Dyed(f) => &*f.medium,
                _ => continue,
            };
            levels = levels.max(h.pyramid.level_count());
            if let Some(b) = h.pyramid.world_bounds() {
                diagonal = diagonal.max(f64::from(b.extent().length()));
            }
        }
        out.push(Configuration {
            name: "delta + residual ratio (novak), pyramid L0, no local bounds".into(),
            edits: vec![tracking(&[("local_bounds", toml::Value::Boolean(false))])],
        });
        out.push(Configuration {
            name: "decomposition + residual ratio (novak), pyramid L0, no local bounds".into(),
            edits: vec![tracking(&[
                ("free_flight", s("decomposition")),
                ("local_bounds", toml::Value::Boolean(false)),
            ])],
        });
        out.push(Configuration {
            name: "delta + residual ratio (novak), local bounds".into(),
            edits: vec![tracking(&[("local_bounds", toml::Value::Boolean(true))])],
        });
        out.push(Configuration {
            name: "decomposition + residual ratio (novak), local bounds".into(),
            edits: vec![tracking(&[
                ("free_flight", s("decomposition")),
                ("local_bounds", toml::Value::Boolean(true)),
            ])],
        });
        out.push(Configuration {
            name: "delta + ratio, pyramid L0".into(),
            edits: vec![tracking(&[("transmittance", s("ratio"))])],
        });
        out.push(Configuration {
            name: "split flight + residual ratio (novak)".into(),
            edits: vec![tracking(&[("free_flight", s("split"))])],
        });
        out.push(Configuration {
            name: "delta + residual ratio (novak), transmittance behind".into(),
            edits: vec![tracking(&[("behind", s("transmittance"))])],
        });
        out.push(Configuration {
            name: "delta + residual ratio (novak), no sun lean".into(),
            edits: vec![tracking(&[("sun_lean", toml::Value::Boolean(false))])],
        });
        out.push(Configuration {
            name: "delta + unbiased ray marching".into(),
            edits: vec![tracking(&[("transmittance", s("unbiased_ray_march"))])],
        });
        out.push(Configuration {
            name: "delta + jackknife (biased)".into(),
            edits: vec![tracking(&[("transmittance", s("jackknife"))])],
        });
        out.push(Configuration {
            name: "delta + residual ratio (mean)".into(),
            edits: vec![tracking(&[("control", s("mean"))])],
        });
        out.push(Configuration {
            name: "delta + residual ratio, global majorant".into(),
            edits: vec![tracking(&[("majorant", s("global"))])],
        });
        for level in 1..levels.min(6) {
            out.push(Configuration {
                name: format!("delta + residual ratio, pyramid L{level}"),
                edits: vec![tracking(&[("level", toml::Value::Integer(level as i64))])],
            });
        }
        let steps: Vec<f64> = if steps.is_empty() && diagonal > 0.0 {
            [32.0, 128.0, 512.0].iter().map(|d| diagonal / d).collect()
        } else {
            steps.to_vec()
        };
        for step in steps {
            out.push(Configuration {
                name: format!("ray marching, step {step:.3e}"),
                edits: vec![tracking(&[
                    ("free_flight", s("ray_march")),
                    ("transmittance", s("ray_march")),
                    ("step", toml::Value::Float(step)),
                ])],
            });
        }
    }
    if procedural {
        out.push(Configuration {
            name: "exact procedural density".into(),
            edits: vec![Edit {
                target: Target::Procedural,
                key: "evaluation".into(),
                value: s("exact"),
            }],
        });
    }
    if scattering {
        // Guided connections only differ from exit-point NEE behind a rough dielectric.
        let guided = scene
            .objects
            .iter()
            .any(|o| o.medium.is_some() && crate::scene::guided_boundary(&o.surface));
        let strategies: &[&str] = if guided {
            &["exit", "exit_guided", "interior"]
        } else {
            &["exit", "interior"]
        };
        for &nee in strategies {
            out.push(Configuration {
                name: format!("NEE {nee}"),
                edits: vec![Edit {
                    target: Target::Scattering,
                    key: "nee".into(),
                    value: s(nee),
                }],
            });
        }
        let manifold = manifold_objects(doc, scene);
        if !manifold.is_empty() {
            out.push(Configuration {
                name: "NEE manifold".into(),
                edits: manifold
                    .into_iter()
                    .map(|index| Edit {
                        target: Target::Object(index),
                        key: "nee".into(),
                        value: s("manifold"),
                    })
                    .collect(),
            });
        }
    }
    out
}

/// Indices (in the scene file's `[[object]]` array) of the scattering interiors where
/// `nee = "manifold"` is valid. The scene loader decides: the scene file is loaded again (from
/// `scene.source`) with that one interior switched to `"manifold"`, and the interior counts
/// when it loads. Loads that would certainly fail are skipped: objects whose surface is neither
/// absent nor `type = "dielectric"`, and every object when the scene has no sphere or distant
/// light (the only lights manifold NEE connects to).
#[must_use]
pub fn manifold_objects(doc: &toml::Table, scene: &Scene) -> Vec<usize> {
    let finite_light = scene
        .lights
        .iter()
        .any(|l| matches!(l, Light::Sphere { .. } | Light::Distant { .. }));
    if !finite_light {
        return Vec::new();
    }
    let objects = doc.get("object").and_then(|o| o.as_array());
    interiors(doc)
        .filter(|(_, t)| estimator_kind(t) != "absorption")
        .filter(|(i, _)| {
            let surface = objects
                .and_then(|o| o.get(*i))
                .and_then(|o| o.get("surface"));
            match surface {
                None => true,
                Some(s) => s.get("type").and_then(|t| t.as_str()) == Some("dielectric"),
            }
        })
        .map(|(i, _)| i)
        .filter(|&i| {
            let trial = Configuration {
                name: String::new(),
                edits: vec![Edit {
                    target: Target::Object(i),
                    key: "nee".into(),
                    value: s("manifold"),
                }],
            };
            apply(doc, &trial)
                .ok()
                .is_some_and(|text| load_scene_str(&text, &scene.source).is_ok())
        })
        .collect()
}

fn interiors(doc: &toml::Table) -> impl Iterator<Item = (usize, &toml::Table)> {
    doc.get("object")
        .and_then(|o| o.as_array())
        .into_iter()
        .flatten()
        .enumerate()
        .filter_map(|(i, o)| o.get("interior").and_then(|t| t.as_table()).map(|t| (i, t)))
}

/// An interior table's `type`, except that a `voxel` interior with albedo or emission grids
/// is a one-component mixture (`"mixture"`): it has none of the free-flight estimators the
/// heterogeneous configurations switch between.
fn estimator_kind(t: &toml::Table) -> String {
    let kind = t.get("type").and_then(|v| v.as_str()).unwrap_or("");
    let grids = ["albedo_grid", "emission_grid", "temperature_grid"]
        .iter()
        .any(|k| t.contains_key(*k));
    if kind == "voxel" && grids {
        "mixture".to_string()
    } else {
        kind.to_string()
    }
}

/// The scene file text with `config`'s edits applied.
pub fn apply(doc: &toml::Table, config: &Configuration) -> Result<String, String> {
    let mut doc = doc.clone();
    if let Some(objects) = doc.get_mut("object").and_then(|o| o.as_array_mut()) {
        for (index, o) in objects.iter_mut().enumerate() {
            let Some(interior) = o.get_mut("interior").and_then(|t| t.as_table_mut()) else {
                continue;
            };
            let kind = estimator_kind(interior);
            for e in &config.edits {
                let applies = match e.target {
                    Target::Heterogeneous => kind == "voxel" || kind == "fbm",
                    Target::Procedural => kind == "fbm",
                    Target::Scattering => kind != "absorption",
                    Target::Object(i) => i == index,
                };
                if applies {
                    interior.insert(e.key.clone(), e.value.clone());
                }
            }
        }
    }
    toml::to_string(&doc).map_err(|e| format!("cannot write the edited scene: {e}"))
}

/// Renders `scene_text` (a scene file whose relative paths resolve against `scene_path`) at
/// each budget and measures it against `reference`.
#[allow(clippy::too_many_arguments)]
pub fn measure(
    scene_text: &str,
    scene_path: &Path,
    overrides: &SceneOverrides,
    config: &str,
    budgets: &[Budget],
    reference: &image_io::ExrImage,
    threads: usize,
    adaptive: Option<crate::render::Adaptive>,
) -> Result<Vec<Measurement>, Box<dyn std::error::Error + Send + Sync>> {
    let mut scene = load_scene_str(scene_text, scene_path)?;
    if let Some(d) = overrides.max_depth {
        scene.film.max_depth = d;
    }
    scene.set_resolution(reference.width, reference.height)?;
    let mut out = Vec::new();
    for &budget in budgets {
        let r = render_budget(
            &scene,
            &BudgetOptions {
                threads,
                adaptive,
                ..BudgetOptions::new(budget)
            },
        )?;
        let img = r.film.to_exr_image(&BTreeMap::new());
        let c = compare::compare(&img, reference)?;
        let mse = c.rmse * c.rmse;
        let (value, unit) = match budget {
            Budget::Seconds(s) => (s, "seconds"),
            Budget::Samples(n) => (f64::from(n), "spp"),
        };
        out.push(Measurement {
            config: config.to_string(),
            budget: value,
            unit,
            seconds: r.summary.seconds,
            spp: r.spp,
            rmse: c.rmse,
            rel_mse: c.rel_mse,
            bias: c.mean_bias,
            efficiency: if mse > 0.0 && r.summary.seconds > 0.0 {
                1.0 / (mse * r.summary.seconds)
            } else {
                f64::INFINITY
            },
            lookups_per_path: if r.summary.samples > 0 {
                r.summary.tracking.lookups as f64 / r.summary.samples as f64
            } else {
                0.0
            },
            non_finite: r.summary.non_finite,
        });
    }
    Ok(out)
}

/// The measurements as CSV (header + one row per measurement).
#[must_use]
pub fn csv(rows: &[Measurement]) -> String {
    let mut s = String::from(
        "config,budget,unit,seconds,spp,rmse,rel_mse,bias,efficiency,lookups_per_path,non_finite\n",
    );
    for m in rows {
        let _ = writeln!(
            s,
            "\"{}\",{},{},{:.4},{},{:.6e},{:.6e},{:.6e},{:.6e},{:.3},{}",
            m.config.replace('"', "'"),
            m.budget,
            m.unit,
            m.seconds,
            m.spp,
            m.rmse,
            m.rel_mse,
            m.bias,
            m.efficiency,
            m.lookups_per_path,
            m.non_finite
        );
    }
    s
}

/// An SVG plot of RMSE against render time (log–log), one polyline per configuration.
#[must_use]
pub fn svg_plot(rows: &[Measurement], title: &str) -> String {
    const PALETTE: [&str; 12] = [
        "#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f",
        "#bcbd22", "#17becf", "#000000", "#aec7e8",
    ];
    let (w, h, left, right, top, bottom) = (900.0, 520.0, 70.0, 330.0, 40.0, 50.0);
    let pts: Vec<&Measurement> = rows
        .iter()
        .filter(|m| m.seconds > 0.0 && m.rmse > 0.0 && m.rmse.is_finite())
        .collect();
    let mut svg = format!("<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{h}\" font-family=\"sans-serif\" font-size=\"12\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n");
    let _ = writeln!(
        svg,
        "<text x=\"{}\" y=\"22\" font-size=\"14\">{}</text>",
        left,
        xml_escape(title)
    );
    if pts.is_empty() {
        svg.push_str("<text x=\"100\" y=\"100\">no data</text>\n</svg>\n");
        return svg;
    }
    let lx: Vec<f64> = pts.iter().map(|m| m.seconds.log10()).collect();
    let ly: Vec<f64> = pts.iter().map(|m| m.rmse.log10()).collect();
    let (x0, x1) = (
        lx.iter().cloned().fold(f64::INFINITY, f64::min).floor(),
        lx.iter().cloned().fold(f64::NEG_INFINITY, f64::max).ceil(),
    );
    let (y0, y1) = (
        ly.iter().cloned().fold(f64::INFINITY, f64::min).floor(),
        ly.iter().cloned().fold(f64::NEG_INFINITY, f64::max).ceil(),
    );
    let (x1, y1) = (
        if x1 > x0 { x1 } else { x0 + 1.0 },
        if y1 > y0 { y1 } else { y0 + 1.0 },
    );
    let pw = w - left - right;
    let ph = h - top - bottom;
    let px = |v: f64| left + (v - x0) / (x1 - x0) * pw;
    let py = |v: f64| top + (1.0 - (v - y0) / (y1 - y0)) * ph;
    let _ = writeln!(svg, "<rect x=\"{left}\" y=\"{top}\" width=\"{pw}\" height=\"{ph}\" fill=\"none\" stroke=\"#444\"/>");
    let mut d = x0;
    while d <= x1 + 1e-9 {
        let x = px(d);
        let _ = writeln!(svg, "<line x1=\"{x:.1}\" y1=\"{top}\" x2=\"{x:.1}\" y2=\"{:.1}\" stroke=\"#ddd\"/><text x=\"{x:.1}\" y=\"{:.1}\" text-anchor=\"middle\">1e{}</text>", top + ph, top + ph + 16.0, d as i64);
        d += 1.0;
    }
    let mut d = y0;
    while d <= y1 + 1e-9 {
        let y = py(d);
        let _ = writeln!(svg, "<line x1=\"{left}\" y1=\"{y:.1}\" x2=\"{:.1}\" y2=\"{y:.1}\" stroke=\"#ddd\"/><text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"end\">1e{}</text>", left + pw, left - 6.0, y + 4.0, d as i64);
        d += 1.0;
    }
    let _ = writeln!(
        svg,
        "<text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"middle\">render time (s)</text>",
        left + pw / 2.0,
        h - 12.0
    );
    let _ = writeln!(svg, "<text x=\"16\" y=\"{:.1}\" transform=\"rotate(-90 16 {:.1})\" text-anchor=\"middle\">RMSE vs reference</text>", top + ph / 2.0, top + ph / 2.0);
    let mut names: Vec<&str> = Vec::new();
    for m in &pts {
        if !names.contains(&m.config.as_str()) {
            names.push(&m.config);
        }
    }
    for (k, name) in names.iter().enumerate() {
        let colour = PALETTE[k % PALETTE.len()];
        let dash = if k >= PALETTE.len() {
            " stroke-dasharray=\"5,3\""
        } else {
            ""
        };
        let mut series: Vec<&&Measurement> = pts.iter().filter(|m| m.config == *name).collect();
        series.sort_by(|a, b| a.seconds.total_cmp(&b.seconds));
        let path: Vec<String> = series
            .iter()
            .map(|m| format!("{:.1},{:.1}", px(m.seconds.log10()), py(m.rmse.log10())))
            .collect();
        let _ = writeln!(
            svg,
            "<polyline points=\"{}\" fill=\"none\" stroke=\"{colour}\" stroke-width=\"2\"{dash}/>",
            path.join(" ")
        );
        for p in &path {
            let (x, y) = p.split_once(',').unwrap_or(("0", "0"));
            let _ = writeln!(
                svg,
                "<circle cx=\"{x}\" cy=\"{y}\" r=\"3\" fill=\"{colour}\"/>"
            );
        }
        let ly = top + 10.0 + 18.0 * k as f64;
        let lx = left + pw + 16.0;
        let _ = writeln!(svg, "<line x1=\"{lx}\" y1=\"{ly}\" x2=\"{}\" y2=\"{ly}\" stroke=\"{colour}\" stroke-width=\"2\"{dash}/><text x=\"{}\" y=\"{}\">{}</text>", lx + 22.0, lx + 28.0, ly + 4.0, xml_escape(name));
    }
    svg.push_str("</svg>\n");
    svg
}

fn xml_escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// The most efficient configuration at the largest budget (highest 1/(MSE × time)).
#[must_use]
pub fn most_efficient(rows: &[Measurement]) -> Option<&Measurement> {
    let top = rows
        .iter()
        .map(|m| m.budget)
        .fold(f64::NEG_INFINITY, f64::max);
    rows.iter()
        .filter(|m| m.budget == top && m.efficiency.is_finite())
        .max_by(|a, b| a.efficiency.total_cmp(&b.efficiency))
}

/// Arguments of `velour tradeoff`.
#[derive(Debug, clap::Args)]
pub struct TradeoffArgs {
    /// Scene file (TOML).
    pub scene: PathBuf,
    /// Reference EXR of the same scene (from `velour reference`); its size sets the resolution.
    #[arg(long)]
    pub reference: PathBuf,
    /// Budget ladder, comma-separated (seconds or samples per pixel, see --unit).
    #[arg(long, default_value = "1,2,4,8", value_delimiter = ',')]
    pub budgets: Vec<f64>,
    /// Unit of --budgets: "seconds" or "spp".
    #[arg(long, default_value = "seconds")]
    pub unit: String,
    /// Ray-marching steps in world units, comma-separated (default: 1/32, 1/128, 1/512 of the
    /// heterogeneous medium's bounding-box diagonal).
    #[arg(long, value_delimiter = ',')]
    pub steps: Vec<f64>,
    /// Only the configurations whose name contains one of these strings (comma-separated).
    #[arg(long, value_delimiter = ',')]
    pub only: Vec<String>,
    /// Output folder for tradeoff.csv and tradeoff.svg.
    #[arg(short = 'o', long = "output", default_value = "out/tradeoff")]
    pub output: PathBuf,
    /// Worker threads (0 = all cores).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Maximum scattering events per path (overrides film.max_depth).
    #[arg(long)]
    pub max_depth: Option<u32>,
    /// Also measure the scene file with adaptive sampling at these noise thresholds (see
    /// `velour render --noise-threshold`); at a sample budget the budget is the maximum spp.
    #[arg(long, value_delimiter = ',')]
    pub adaptive: Vec<f64>,
    /// Adaptive sampling's minimum samples per pixel.
    #[arg(long, default_value_t = 16)]
    pub min_spp: u32,
}

/// Runs `velour tradeoff`.
pub fn run(args: &TradeoffArgs) -> CliResult {
    if args.budgets.is_empty() {
        return Err("--budgets needs at least one value".into());
    }
    let budgets: Vec<Budget> = match args.unit.as_str() {
        "seconds" => args
            .budgets
            .iter()
            .map(|&b| {
                if b > 0.0 && b.is_finite() && b < 1e7 {
                    Ok(Budget::Seconds(b))
                } else {
                    Err(format!(
                        "--budgets: {b} is not a positive number of seconds"
                    ))
                }
            })
            .collect::<Result<_, _>>()?,
        "spp" => args
            .budgets
            .iter()
            .map(|&b| {
                if b >= 1.0 && b <= f64::from(super::reference::MAX_SPP) && b.fract() == 0.0 {
                    Ok(Budget::Samples(b as u32))
                } else {
                    Err(format!(
                        "--budgets: {b} is not a whole number of samples in [1, {}]",
                        super::reference::MAX_SPP
                    ))
                }
            })
            .collect::<Result<_, _>>()?,
        other => return Err(format!("--unit {other:?}: expected \"seconds\" or \"spp\"").into()),
    };
    if args.steps.iter().any(|s| !(*s > 0.0 && s.is_finite())) {
        return Err("--steps must be positive lengths".into());
    }
    if args.adaptive.iter().any(|t| !(*t > 0.0 && t.is_finite())) {
        return Err("--adaptive thresholds must be positive numbers".into());
    }
    if args.min_spp < 2 {
        return Err("--min-spp must be at least 2".into());
    }
    let overrides = SceneOverrides {
        width: None,
        height: None,
        max_depth: args.max_depth,
    };
    let base = load_scene_with(Some(&args.scene), &overrides)?;
    let text = std::fs::read_to_string(&args.scene)
        .map_err(|e| format!("{}: {e}", args.scene.display()))?;
    let doc: toml::Table =
        toml::from_str(&text).map_err(|e| format!("{}: {e}", args.scene.display()))?;
    let reference = image_io::read_exr(&args.reference)?;
    let mut configs = configurations(&doc, &base, &args.steps);
    if !args.only.is_empty() {
        configs.retain(|c| args.only.iter().any(|o| c.name.contains(o.as_str())));
    }
    std::fs::create_dir_all(&args.output).map_err(|e| format!("{}: {e}", args.output.display()))?;
    let mut rows = Vec::new();
    // The adaptive runs use the scene file as written.
    let adaptive_runs = args.adaptive.iter().map(|&threshold| {
        (
            Configuration {
                name: format!("scene file, adaptive {threshold}"),
                edits: vec![],
            },
            Some(crate::render::Adaptive {
                threshold,
                min_spp: args.min_spp,
            }),
        )
    });
    let runs: Vec<(Configuration, Option<crate::render::Adaptive>)> = configs
        .into_iter()
        .map(|c| (c, None))
        .chain(adaptive_runs)
        .collect();
    for (c, adaptive) in &runs {
        let edited = apply(&doc, c)?;
        eprintln!("{}", c.name);
        match measure(
            &edited,
            &args.scene,
            &overrides,
            &c.name,
            &budgets,
            &reference,
            args.threads,
            *adaptive,
        ) {
            Ok(m) => {
                for r in &m {
                    eprintln!("  {:>8} {:<7} {:>8.2} s {:>6} spp  RMSE {:.4e}  relMSE {:.4e}  bias {:+.3e}  eff {:.4e}  lookups/path {:.1}", r.budget, r.unit, r.seconds, r.spp, r.rmse, r.rel_mse, r.bias, r.efficiency, r.lookups_per_path);
                }
                rows.extend(m);
            }
            Err(e) => eprintln!("  skipped: {e}"),
        }
    }
    let csv_path = args.output.join("tradeoff.csv");
    let svg_path = args.output.join("tradeoff.svg");
    std::fs::write(&csv_path, csv(&rows)).map_err(|e| format!("{}: {e}", csv_path.display()))?;
    let title = format!("{} — RMSE vs time", args.scene.display());
    std::fs::write(&svg_path, svg_plot(&rows, &title))
        .map_err(|e| format!("{}: {e}", svg_path.display()))?;
    println!("wrote {} and {}", csv_path.display(), svg_path.display());
    match most_efficient(&rows) {
        Some(best) => println!(
            "most efficient at {} {}: {} (efficiency {:.4e}, RMSE {:.4e} in {:.2} s, {} spp)",
            best.budget, best.unit, best.config, best.efficiency, best.rmse, best.seconds, best.spp
        ),
        None => println!("no configuration could be measured"),
    }
    Ok(())
}
