//! Light sampling: the environment map's importance sampling has a pdf that integrates to 1
//! and matches its samples, and every light's sampler integrates its radiance correctly
//! (Monte-Carlo estimates against closed forms or against uniform sampling, by z-test).

mod common;

use common::files::TempDir;
use common::render::{pixel_means, render_scene, scene_from_text};
use common::stats::{estimate, Estimate};
use velour::image_io::{write_exr, ExrImage, LatLongMap};
use velour::light::{EnvironmentMap, Light};
use velour::math::{Vec3, PI};
use velour::sampling::{sample_uniform_sphere, Rng};
use velour::spectrum::Rgb;

/// Mean and standard error of `n` values of `f`, every estimate from the same seed.
fn mean_se(n: usize, f: impl FnMut(&mut Rng) -> f64) -> (f64, f64) {
    let e = estimate(n, &mut Rng::new(21, 4), f);
    (e.mean, e.standard_error)
}

fn test_map() -> LatLongMap {
    let (w, h) = (32u32, 16u32);
    let mut rng = Rng::new(5, 5);
    let texels = (0..w * h)
        .map(|i| {
            let hot = if i % 97 == 3 { 40.0 } else { 1.0 };
            Rgb::new(rng.next_f32() * hot, rng.next_f32() * hot, rng.next_f32()) + Rgb::splat(0.01)
        })
        .collect();
    LatLongMap {
        width: w,
        height: h,
        texels,
    }
}

#[test]
fn environment_map_pdf_integrates_to_one_and_matches_samples() {
    let light = Light::EnvironmentMap(Box::new(EnvironmentMap::new(test_map(), 1.0, 30.0)));
    let (m, se) = mean_se(400_000, |rng| {
        light.pdf_li(Vec3::ZERO, sample_uniform_sphere(rng.next_2d())) as f64 * 4.0 * PI as f64
    });
    assert!((m - 1.0).abs() < 4.5 * se + 1e-3, "∫pdf = {m} ± {se}");
    let mut rng = Rng::new(1, 2);
    for _ in 0..10_000 {
        // Samples within ~1e-6 rad of a pole are refused (sinθ → 0); they carry no weight.
        let Some(s) = light.sample_li(Vec3::ZERO, rng.next_2d()) else {
            continue;
        };
        let p = light.pdf_li(Vec3::ZERO, s.wi);
        assert!(
            (s.pdf - p).abs() <= 1e-3 * p.max(1e-3),
            "sampled pdf {} vs pdf_li {p}",
            s.pdf
        );
        let l = light.escaped_radiance(s.wi);
        assert!((l[0] - s.radiance[0]).abs() <= 1e-5 * l[0].max(1.0));
    }
}

#[test]
fn environment_map_importance_sampling_is_unbiased() {
    let light = Light::EnvironmentMap(Box::new(EnvironmentMap::new(test_map(), 2.0, -75.0)));
    // ∫ L dω by uniform sampling and by importance sampling.
    let (a, sa) = mean_se(600_000, |rng| {
        light.escaped_radiance(sample_uniform_sphere(rng.next_2d()))[0] as f64 * 4.0 * PI as f64
    });
    let (b, sb) = mean_se(200_000, |rng| {
        match light.sample_li(Vec3::ZERO, rng.next_2d()) {
            Some(s) => (s.radiance[0] / s.pdf) as f64,
            None => 0.0,
        }
    });
    assert!(
        (a - b).abs() < 4.5 * (sa * sa + sb * sb).sqrt(),
        "uniform {a} ± {sa} vs importance {b} ± {sb}"
    );
    assert!(
        sb < sa,
        "importance sampling should reduce the error: {sb} vs {sa}"
    );
}

#[test]
fn sphere_and_disc_lights_integrate_to_their_solid_angle() {
    let p = Vec3::new(0.3, -0.2, 0.1);
    let sphere = Light::Sphere {
        center: Vec3::new(1.0, 2.0, -0.5),
        radius: 0.4,
        radiance: Rgb::splat(3.0),
    };
    let d2 = (Vec3::new(1.0, 2.0, -0.5) - p).length_squared();
    let solid = 2.0 * PI as f64 * (1.0 - (1.0 - 0.16 / d2 as f64).sqrt());
    let (m, se) = mean_se(100_000, |rng| match sphere.sample_li(p, rng.next_2d()) {
        Some(s) => {
            assert!((s.pdf - sphere.pdf_li(p, s.wi)).abs() < 1e-3 * s.pdf);
            (s.radiance[0] / s.pdf) as f64
        }
        None => 0.0,
    });
    assert!(
        (m - 3.0 * solid).abs() < 4.5 * se + 1e-4 * m,
        "{m} vs {}",
        3.0 * solid
    );
    // A distant disc of irradiance E: ∫ L cosθ dω over the disc = E at normal incidence.
    let sun = Light::distant(Vec3::new(0.0, 0.0, 1.0), Rgb::splat(5.0), 10.0);
    let (m, se) = mean_se(100_000, |rng| match sun.sample_li(p, rng.next_2d()) {
        Some(s) => (s.radiance[0] * s.wi.z / s.pdf) as f64,
        None => 0.0,
    });
    // ∫ L cosθ dω = L π sin²r = E exactly for a uniform disc.
    assert!((m - 5.0).abs() < 4.5 * se + 1e-4, "{m} vs 5");
}

#[test]
fn white_furnace_under_a_constant_environment_map() {
    let dir = TempDir::new("envmap");
    let mut img = ExrImage::new(16, 8);
    for c in ["R", "G", "B"] {
        img.channels.insert(c.to_string(), vec![1.0; 128]);
    }
    write_exr(&dir.join("white.exr"), &img).expect("write");
    let text = r#"
[camera]
eye = [0, 0, 4]
look_at = [0, 0, 0]
fov = 20
[film]
width = 16
height = 16
spp = 32
max_depth = 100000
[[light]]
type = "envmap"
file = "white.exr"
[[object]]
shape = "sphere"
radius = 1.0
surface = { type = "dielectric", ior = 1.33 }
interior = { type = "homogeneous", albedo = 1.0, albedo_mode = "single", attenuation = 0.3 }
"#;
    let scene = scene_from_text(text, dir.join("scene.toml"));
    let (film, _) = render_scene(&scene, 0);
    let furnace = Estimate::of(&pixel_means(&film, 1));
    let (m, se) = (furnace.mean, furnace.standard_error);
    assert!((m - 1.0).abs() < 4.5 * se + 2e-3, "furnace {m} ± {se}");
}
