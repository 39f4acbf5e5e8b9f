//! A mixture's free flight searches the boundary only up to its collision
//! (`Medium::sample_flight_rewinding`, docs/architecture.md, "The integrator", item 1): for
//! rays through a mixture of a homogeneous medium and a voxel grid, with the boundary at
//! random distances, the rewinding flight returns the same event as the flight to
//! the boundary (bit for bit, from the same random numbers), leaves the random state where
//! that flight leaves it, and asks for the boundary only up to the collision it sampled.

mod common;

use common::files::{repo_path, TempDir};
use velour::math::Ray;
use velour::medium::{Medium, MediumEvent, RayFootprint};
use velour::scene::load_scene_str;
use velour::spectrum::Rgb;
use velour::tracking::TrackingStats;

/// A counter-based random state (a hashed index), cheap to copy and rewind.
#[derive(Clone, Debug, PartialEq)]
struct Counter {
    seed: u64,
    index: u64,
}

impl Counter {
    fn next(&mut self) -> f32 {
        self.index += 1;
        let mut x = self.seed ^ self.index.wrapping_mul(0x9E37_79B9_7F4A_7C15);
        x ^= x >> 30;
        x = x.wrapping_mul(0xBF58_476D_1CE4_E5B9);
        x ^= x >> 27;
        x = x.wrapping_mul(0x94D0_49BB_1331_11EB);
        x ^= x >> 31;
        (x >> 40) as f32 / (1u64 << 24) as f32
    }
}

fn mixture_medium(dir: &TempDir) -> Medium {
    let cloud = repo_path("volumes/cloud.vdb");
    let text = format!(
        r#"
[camera]
eye = [0.0, 0.5, 4.0]
look_at = [0.0, 0.5, 0.0]
fov = 30
[film]
width = 4
height = 4
spp = 1
[[light]]
type = "environment"
radiance = 1.0
[[object]]
name = "water"
shape = "sphere"
center = [0.0, 0.5, 0.0]
radius = 1.5
surface = {{ type = "dielectric", ior = 1.33 }}
interior = {{ type = "mixture", nee = "interior", media = [
    {{ type = "homogeneous", albedo = [0.1, 0.5, 0.9], albedo_mode = "single", attenuation = [0.5, 2.0, 8.0] }},
    {{ type = "voxel", file = "{}", albedo = 0.95, albedo_mode = "single", attenuation = 0.1, phase = {{ g = 0.8 }} }},
] }}
"#,
        cloud.display()
    );
    let scene = load_scene_str(&text, &dir.join("scene.toml")).unwrap_or_else(|e| panic!("{e}"));
    let medium = scene.media.first().cloned();
    let medium = medium.unwrap_or_else(|| panic!("no medium"));
    assert!(matches!(medium, Medium::Mixture(_)), "not a mixture");
    assert!(medium.flight_before_boundary());
    medium
}

/// The bits of an event (weight, emission, collision distance and point, albedo).
fn bits(e: &MediumEvent<'_>) -> Vec<u32> {
    let mut v: Vec<u32> = e
        .weight
        .0
        .iter()
        .chain(&e.emitted.0)
        .map(|x| x.to_bits())
        .collect();
    if let Some(s) = &e.scatter {
        v.push(s.t.to_bits());
        v.extend(s.p.to_array().iter().map(|x| x.to_bits()));
        v.extend(s.albedo.0.iter().map(|x| x.to_bits()));
    }
    v
}

#[test]
fn a_mixture_flight_searches_the_boundary_only_up_to_its_collision() {
    let dir = TempDir::new("mixture-boundary-search");
    let medium = mixture_medium(&dir);
    let mut rng = Counter { seed: 7, index: 0 };
    let (mut before, mut after, mut passed) = (0, 0, 0);
    for i in 0..4000u64 {
        let o = glam::Vec3::new(
            -1.0 + 2.0 * rng.next(),
            -0.1 + 1.2 * rng.next(),
            -0.8 + 1.5 * rng.next(),
        );
        let d = loop {
            let d = glam::Vec3::new(rng.next(), rng.next(), rng.next()) * 2.0 - 1.0;
            if d.length_squared() > 1e-3 && d.length_squared() <= 1.0 {
                break d.normalize();
            }
        };
        let ray = Ray::new(o, d);
        let boundary = 3.0 * rng.next();
        let beta = Rgb::new(rng.next(), rng.next(), rng.next()) + Rgb::splat(0.05);
        let start = Counter {
            seed: 1000 + i,
            index: 0,
        };

        // The flight to the boundary, as without the rewinding.
        let mut a = start.clone();
        let mut stats = TrackingStats::default();
        let reference =
            medium
                .sample_flight_to_boundary(&ray, beta, &mut || a.next(), &mut stats, |_| boundary);

        let mut b = start.clone();
        let mut limits = Vec::new();
        let event = medium.sample_flight_rewinding(
            &ray,
            RayFootprint::POINT,
            beta,
            &mut b,
            Counter::next,
            &mut stats,
            |limit| {
                limits.push(limit);
                if boundary < limit {
                    boundary
                } else {
                    f32::INFINITY
                }
            },
        );
        assert_eq!(
            bits(&event),
            bits(&reference),
            "ray {i}: {ray:?}, boundary {boundary}"
        );
        assert_eq!(
            b, a,
            "ray {i}: the random state must end where the flight's does"
        );
        assert_eq!(limits.len(), 1, "ray {i}: the boundary is asked once");
        match &reference.scatter {
            // The boundary was searched only up to the collision.
            Some(s) => {
                assert_eq!(limits[0], s.t, "ray {i}");
                before += 1;
            }
            None if limits[0].is_finite() => after += 1,
            None => passed += 1,
        }
    }
    // Both cases occur: a collision before the boundary, and a boundary before the sampled
    // collision (the flight then sampled again to the boundary). The water component
    // extinguishes every channel, so no flight passes everything.
    assert!(before > 200 && after > 200, "{before} {after} {passed}");
}
