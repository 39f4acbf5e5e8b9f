//! The light choice of next event estimation (`LightSampler::for_nee`): a constant sky beside
//! other lights keeps a tenth of its power share, renormalised; alone, or beside lights
//! without power, it keeps its share; the sampler picks each light with the probability it
//! reports.

use velour::light::{brightest_delta_sun, Light, LightSampler, CONSTANT_ENVIRONMENT_NEE_SHARE};
use velour::math::Vec3;
use velour::spectrum::Rgb;

fn sky() -> Light {
    Light::ConstantEnvironment {
        radiance: Rgb::new(0.25, 0.35, 0.55),
    }
}

fn sun() -> Light {
    Light::distant(Vec3::new(-0.5, 0.8, 0.4), Rgb::new(4.0, 3.7, 3.3), 0.0)
}

#[test]
fn a_sky_beside_a_sun_keeps_a_tenth_of_its_power_share() {
    let lights = [sky(), sun()];
    let power = LightSampler::new(&lights, 1.0);
    let nee = LightSampler::for_nee(&lights, 1.0);
    let (ps, pd) = (power.probability(0), power.probability(1));
    assert!(ps > 0.0 && pd > 0.0);
    let z = ps * CONSTANT_ENVIRONMENT_NEE_SHARE + pd;
    let want = ps * CONSTANT_ENVIRONMENT_NEE_SHARE / z;
    assert!(
        (nee.probability(0) - want).abs() < 1e-6,
        "{} vs {want}",
        nee.probability(0)
    );
    assert!((nee.probability(0) + nee.probability(1) - 1.0).abs() < 1e-6);
    // The sampler's choices follow the probabilities it reports.
    let n = 100_000;
    let mut skies = 0;
    for k in 0..n {
        let u = (k as f32 + 0.5) / n as f32;
        let (i, p) = nee.sample(u).unwrap();
        assert!((p - nee.probability(i)).abs() < 1e-7);
        skies += usize::from(i == 0);
    }
    let frac = skies as f32 / n as f32;
    assert!((frac - nee.probability(0)).abs() < 1e-3, "{frac}");
}

#[test]
fn a_sky_alone_or_beside_dark_lights_keeps_its_share() {
    for lights in [
        vec![sky()],
        vec![sky(), Light::distant(Vec3::Y, Rgb::ZERO, 0.0)],
    ] {
        let power = LightSampler::new(&lights, 1.0);
        let nee = LightSampler::for_nee(&lights, 1.0);
        for i in 0..lights.len() {
            assert_eq!(nee.probability(i), power.probability(i), "light {i}");
        }
        assert_eq!(nee.sample(0.999_999).map(|s| s.0), Some(0));
    }
    assert!(LightSampler::for_nee(&[], 1.0).sample(0.5).is_none());
}

#[test]
fn sun_lean_leans_towards_the_brightest_delta_sun() {
    let d = Vec3::new(0.0, 1.0, 0.0);
    let dim = Light::distant(d, Rgb::new(1.0, 1.0, 1.0), 0.0);
    let bright = Light::distant(d, Rgb::new(3.0, 3.0, 3.0), 0.0);
    let twin = Light::distant(d, Rgb::new(3.0, 3.0, 3.0), 0.0);
    // Brighter still, but a disc (0.5 degrees): not a delta sun.
    let disc = Light::distant(d, Rgb::new(9.0, 9.0, 9.0), 0.5);
    assert_eq!(
        brightest_delta_sun(&[sky(), dim.clone(), bright, twin, disc.clone()]),
        Some(2)
    );
    assert_eq!(brightest_delta_sun(&[sky(), disc]), None);
    assert_eq!(brightest_delta_sun(&[sky()]), None);
    assert_eq!(brightest_delta_sun(&[dim]), Some(0));
}
