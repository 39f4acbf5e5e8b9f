//! `nee = "exit_guided"` (guided connections from interior vertices through a rough
//! dielectric boundary, MIS-combined with BTDF sampling at the exit) against `nee = "exit"`:
//! unbiased (a z-test of the two estimators' image means at fixed seeds, with the tolerance
//! from their own variances, under an environment and under small lights) and of much lower variance behind a small
//! light.

mod common;

use std::path::Path;

use common::render::{image_mean, render_finite, scene_from_text};
use common::stats::z_score;
use velour::film::Film;

fn render(text: &str) -> Film {
    render_finite(&scene_from_text(text, Path::new("test.toml")), 0).0
}

/// Relative variance of the image: the pixels' variances of the mean over their squared
/// means, both summed over pixels and channels (dark pixels do not dominate).
fn relative_variance(film: &Film) -> f64 {
    let (mut var, mut mean2) = (0.0, 0.0);
    for y in 0..film.height() {
        for x in 0..film.width() {
            let m = film.mean(x, y);
            let v = film.variance_of_mean(x, y);
            for c in 0..3 {
                var += f64::from(v[c]);
                mean2 += f64::from(m[c]) * f64::from(m[c]);
            }
        }
    }
    var / mean2
}

fn furnace(nee: &str, roughness: f32, g: f32, spp: u32, seed: u32) -> String {
    format!(
        r#"
[camera]
eye = [0, 0, 4]
look_at = [0, 0, 0]
fov = 20
[film]
width = 16
height = 16
spp = {spp}
seed = {seed}
max_depth = 100000
[[light]]
type = "environment"
radiance = 1.0
[[object]]
name = "ball"
shape = "sphere"
radius = 1.0
surface = {{ type = "dielectric", ior = 1.4, roughness = {roughness} }}
interior = {{ type = "homogeneous", albedo = 1.0, albedo_mode = "single", attenuation = [0.5, 0.25, 1.0], phase = {{ g = {g} }}, nee = "{nee}" }}
"#
    )
}

/// Agreement of the image means within 4 standard errors of their difference (fixed seeds;
/// the standard errors come from each render's per-pixel variances).
fn assert_agree(exit: &Film, guided: &Film, what: &str) {
    for c in 0..3 {
        let (me, se) = image_mean(exit, c);
        let (mg, sg) = image_mean(guided, c);
        let z = z_score(mg, me, (se * se + sg * sg).sqrt());
        assert!(
            z.abs() < 4.0,
            "{what}, channel {c}: exit_guided {mg} ± {sg} vs exit {me} ± {se} (z = {z:.2})"
        );
    }
}

/// Under a uniform environment (a broad light: the connection's MIS weights matter most).
/// Not a white furnace: the single-scattering microfacet boundary loses energy (≈ 0.62 at
/// roughness 0.7), for both estimators alike.
#[test]
fn exit_guided_agrees_with_exit_point_nee_in_a_furnace() {
    for (roughness, g) in [(0.3, 0.0), (0.7, 0.6)] {
        let exit = render(&furnace("exit", roughness, g, 64, 5));
        let guided = render(&furnace("exit_guided", roughness, g, 32, 6));
        assert_agree(&exit, &guided, &format!("roughness {roughness}, g {g}"));
    }
}

/// A dense sphere behind a rough dielectric with an opaque core, lit by a sphere light (the
/// area-measure Jacobian of the connection), a delta sun (no MIS) and a small disc sun.
fn lit_sphere(nee: &str, roughness: f32, spp: u32, seed: u32) -> String {
    lit_sphere_behind(
        nee,
        &format!("{{ type = \"dielectric\", ior = 1.4, roughness = {roughness} }}"),
        spp,
        seed,
    )
}

/// [`lit_sphere`] behind any `surface` (a scene-file inline table).
fn lit_sphere_behind(nee: &str, surface: &str, spp: u32, seed: u32) -> String {
    format!(
        r#"
[camera]
eye = [0, 0, 4]
look_at = [0, 0, 0]
fov = 24
[film]
width = 16
height = 16
spp = {spp}
seed = {seed}
max_depth = 100000
[[light]]
type = "sphere"
center = [-1.5, 2.0, 1.5]
radius = 0.4
radiance = 20.0
[[light]]
type = "distant"
direction = [0.7, 0.2, 0.6]
irradiance = 1.5
[[light]]
type = "distant"
direction = [-0.2, -0.7, 0.5]
irradiance = 2.0
angular_radius = 6.0
[[object]]
name = "skin"
shape = "sphere"
radius = 1.0
priority = 1
surface = {surface}
interior = {{ type = "homogeneous", albedo = [0.97, 0.9, 0.7], albedo_mode = "single", density = 8.0, attenuation = [1.0, 0.8, 0.6], phase = {{ g = 0.3 }}, nee = "{nee}" }}
[[object]]
name = "core"
shape = "sphere"
radius = 0.5
priority = 2
surface = {{ type = "lambertian", reflectance = 0.5 }}
"#
    )
}

/// The image means of the two estimators agree within 4 standard errors of their difference
/// (fixed seeds; the standard errors come from each render's per-pixel variances).
#[test]
fn exit_guided_agrees_with_exit_point_nee() {
    for roughness in [0.45, 0.8] {
        let exit = render(&lit_sphere("exit", roughness, 512, 11));
        let guided = render(&lit_sphere("exit_guided", roughness, 128, 12));
        assert_agree(&exit, &guided, &format!("roughness {roughness}"));
    }
}

/// The same behind a rough dielectric under a specular coat (the connection evaluates the
/// coated boundary; the default `nee` picks `"exit_guided"` there too). The first coat is
/// strong (IOR 2.2): a connection that ignored it would be off by z ≈ 7 in blue.
#[test]
fn exit_guided_agrees_with_exit_point_nee_behind_a_coat() {
    for (roughness, coat_ior, coat) in [(0.45, 2.2, 0.1), (0.8, 1.5, 0.5)] {
        let surface = format!(
            "{{ type = \"dielectric\", ior = 1.4, roughness = {roughness}, coat = {{ ior = {coat_ior}, roughness = {coat} }} }}"
        );
        let exit = render(&lit_sphere_behind("exit", &surface, 512, 13));
        let guided = render(&lit_sphere_behind("exit_guided", &surface, 128, 14));
        assert_agree(
            &exit,
            &guided,
            &format!("roughness {roughness}, coat IOR {coat_ior}, roughness {coat}"),
        );
    }
}

/// Behind a rough dielectric (roughness 0.3) lit by a 1°-radius disc sun, the guided
/// connection removes most of the variance of exit-point NEE at equal sample count: about
/// 1400× by the two-seed `velour diff` metric of docs/choosing-estimators.md; here about 13×,
/// the sample variance of exit-point NEE underestimating its heavy tail at 16 spp.
#[test]
fn exit_guided_lowers_variance_behind_a_small_light() {
    let scene = |nee: &str| {
        format!(
            r#"
[camera]
eye = [0, 0, 4]
look_at = [0, 0, 0]
fov = 24
[film]
width = 16
height = 16
spp = 16
seed = 3
max_depth = 100000
[[light]]
type = "distant"
direction = [-0.6, 0.8, 0.5]
irradiance = 4.0
angular_radius = 1.0
[[object]]
name = "skin"
shape = "sphere"
radius = 1.0
surface = {{ type = "dielectric", ior = 1.4, roughness = 0.3 }}
interior = {{ type = "homogeneous", albedo = 0.95, albedo_mode = "single", density = 20.0, nee = "{nee}" }}
"#
        )
    };
    let exit = relative_variance(&render(&scene("exit")));
    let guided = relative_variance(&render(&scene("exit_guided")));
    assert!(
        guided * 5.0 < exit,
        "relative variance: exit_guided {guided} vs exit {exit}"
    );
}
