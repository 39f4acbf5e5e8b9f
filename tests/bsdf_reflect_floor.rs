//! A dielectric's reflection floor (`min_reflect_probability`): seen from outside, sampling
//! picks reflection with probability max(F, floor) instead of F and weights the two branches
//! by F/q and (1 − F)/(1 − q). The BSDF is unchanged, so every estimate keeps its expectation:
//! the weighted integral of a test function over the sampled directions agrees with the one
//! sampled by Fresnel alone (z-test), `pdf` matches the sampling (χ²), and a water-like scene
//! renders the same image with and without the key (per-pixel z-test).

mod common;

use common::files::TempDir;
use common::render::{assert_images_agree, render_finite, scene_from_text};
use common::sphere::{assert_chi2, chi2_sphere, dir_from_theta_deg, SphereBins};
use common::stats::{estimate, Estimate};
use velour::bsdf::fresnel::fresnel_dielectric;
use velour::bsdf::{MicrofacetDistribution, Surface, MAX_REFLECT_FLOOR};
use velour::math::Vec3;
use velour::sampling::Rng;
use velour::spectrum::Rgb;

const GGX: MicrofacetDistribution = MicrofacetDistribution::Ggx;

fn water(roughness: f32, floor: f32) -> Surface {
    Surface::dielectric(1.34, roughness, GGX, Rgb::new(1.0, 0.8, 0.6))
        .and_then(|s| s.with_reflect_floor(floor))
        .expect("valid dielectric")
}

/// A smooth test function of the sampled direction, different on the two sides.
fn g(wi: Vec3) -> f64 {
    let w = f64::from(wi.x) * 0.7 + f64::from(wi.y) * 0.2;
    if wi.z > 0.0 {
        2.0 + w
    } else {
        0.5 + 0.3 * w
    }
}

/// E[weight · g(wi)] (green channel, which the tint scales) over `n` samples, and the share
/// of samples that reflected.
fn weighted_integral(s: &Surface, wo: Vec3, n: usize, seed: u64) -> (Estimate, f64) {
    let mut reflected = 0usize;
    let e = estimate(n, &mut Rng::new(seed, 11), |rng| {
        s.sample(wo, rng.next_f32(), rng.next_2d())
            .map_or(0.0, |x| {
                if !x.is_transmission {
                    reflected += 1;
                }
                f64::from(x.weight[1]) * g(x.wi)
            })
    });
    (e, reflected as f64 / n as f64)
}

#[test]
fn the_floor_changes_the_choice_but_not_the_integral() {
    let n = 60_000;
    let mut seed = 1;
    for roughness in [0.0f32, 0.12, 0.5] {
        for floor in [0.3f32, 0.7] {
            for theta in [0.0f32, 50.0, 70.0] {
                for inside in [false, true] {
                    let mut wo = dir_from_theta_deg(theta);
                    if inside {
                        wo.z = -wo.z;
                    }
                    seed += 1;
                    let (plain, r0) = weighted_integral(&water(roughness, 0.0), wo, n, seed);
                    let (floored, r1) = weighted_integral(&water(roughness, floor), wo, n, seed);
                    let z = (floored.mean - plain.mean)
                        / (floored.standard_error.powi(2) + plain.standard_error.powi(2)).sqrt();
                    let name =
                        format!("roughness {roughness} floor {floor} θ {theta} inside {inside}");
                    eprintln!(
                        "{name}: {:.5} ± {:.5} against {:.5} ± {:.5} (z = {z:.2}); reflected {r1:.3} against {r0:.3}",
                        floored.mean, floored.standard_error, plain.mean, plain.standard_error
                    );
                    assert!(z.abs() < 4.0, "{name}: z = {z:.2}");
                    if inside {
                        // Seen from inside the choice is Fresnel's: the same draws, the same
                        // samples.
                        assert_eq!(r0, r1, "{name}");
                    } else {
                        // From outside the floor takes effect wherever F is below it (F < 0.2
                        // at these angles, up to 70°; microfacets tilted away from the ray
                        // see more).
                        let f = f64::from(fresnel_dielectric(wo.z, 1.34));
                        assert!(f < 0.2, "{name}: F = {f}");
                        assert!(
                            r1 > 0.9 * f64::from(floor) && r0 < f64::from(floor) - 0.1,
                            "{name}: reflected {r1} with the floor, {r0} without"
                        );
                    }
                }
            }
        }
    }
}

#[test]
fn pdf_follows_the_floored_sampling() {
    let mut k = 0;
    for floor in [0.5f32, 0.9] {
        for theta in [0.0f32, 60.0] {
            for inside in [false, true] {
                let mut wo = dir_from_theta_deg(theta);
                if inside {
                    wo.z = -wo.z;
                }
                let s = water(0.6, floor);
                k += 1;
                let bins = SphereBins::uniform(36, 24);
                let r = chi2_sphere(
                    &bins,
                    2,
                    100_000,
                    500 + k,
                    |rng| s.sample(wo, rng.next_f32(), rng.next_2d()).map(|x| x.wi),
                    &|wi| s.pdf(wo, wi) as f64,
                );
                assert_chi2(&format!("floor {floor} θ {theta} inside {inside}"), &r);
            }
        }
    }
    // The sample's own pdf and weight are pdf() and eval·|cos|/pdf.
    let s = water(0.3, 0.6);
    let mut rng = Rng::new(3, 3);
    for _ in 0..5000 {
        let wo = velour::sampling::sample_uniform_sphere(rng.next_2d());
        let Some(x) = s.sample(wo, rng.next_f32(), rng.next_2d()) else {
            continue;
        };
        let pdf = s.pdf(wo, x.wi);
        assert!((pdf - x.pdf).abs() <= 1e-3 * pdf, "pdf {} vs {pdf}", x.pdf);
        let expect = s.eval(wo, x.wi) * (x.wi.z.abs() / pdf);
        for c in 0..3 {
            assert!((x.weight[c] - expect[c]).abs() <= 1e-3 * expect[c].max(1e-3));
        }
    }
}

#[test]
fn floors_outside_the_range_are_refused() {
    for bad in [-0.1f32, MAX_REFLECT_FLOOR + 0.01, f32::NAN] {
        let e = Surface::dielectric(1.34, 0.1, GGX, Rgb::ONE)
            .and_then(|s| s.with_reflect_floor(bad))
            .expect_err("out of range");
        assert!(e.to_string().contains("min_reflect_probability"), "{e}");
    }
    let dir = TempDir::new("reflect_floor_bad");
    let text = scene("min_reflect_probability = 0.99, ", 1, 1);
    let path = dir.join("scene.toml");
    std::fs::write(&path, text).expect("write scene");
    let err = velour::scene::Scene::load(&path).expect_err("0.99 is refused");
    let msg = err.to_string();
    assert!(msg.contains("min_reflect_probability"), "{msg}");
}

/// A rough water body (a large sphere of absorbing, scattering water under a sky and a sun, seen from
/// above at a glancing angle), its surface with the extra surface keys `extra`.
fn scene(extra: &str, spp: u32, seed: u64) -> String {
    format!(
        r#"
[camera]
eye = [0, 1.2, 3]
look_at = [0, -0.3, 0]
fov = 40
[film]
width = 16
height = 12
spp = {spp}
seed = {seed}
max_depth = 32
[[light]]
type = "environment"
radiance = [0.3, 0.45, 0.7]
[[light]]
type = "distant"
direction = [0.25, 0.42, -0.87]
irradiance = [5.0, 4.7, 4.2]
angular_radius = 0.5
[[object]]
name = "water"
shape = "sphere"
center = [0, -4, 0]
radius = 4
surface = {{ type = "dielectric", ior = 1.34, roughness = 0.3, {extra}tint = 1 }}
interior = {{ type = "homogeneous", albedo = [0.3, 0.6, 0.9], albedo_mode = "single", attenuation = [0.5, 1.0, 2.0], nee = "interior" }}
"#
    )
}

#[test]
fn water_renders_the_same_image_with_a_reflection_floor() {
    let dir = TempDir::new("reflect_floor_render");
    let render = |text: String| render_finite(&scene_from_text(&text, dir.join("scene.toml")), 0).0;
    let plain = render(scene("", 512, 1));
    let floored = render(scene("min_reflect_probability = 0.6, ", 512, 2));
    assert_images_agree(&plain, &floored);
}
