//! A camera path's result depends on its own numbers only: the integrator's per-path state
//! (the fibre slots made at the first scattering vertex that needs them, the boundary hit
//! written in place by each step's ray cast) starts afresh for every path. The same paths,
//! traced in pixel order and then in reverse after paths of other pixels, give the same bits.

mod common;

use common::files::TempDir;
use common::render::scene_from_text;
use velour::integrator::{trace_path, PathResult, TraceStats};
use velour::math::Vec2;
use velour::sampling::{PixelSampler, PixelSeed};
use velour::scene::{load_scene, Scene};

/// A free-standing twill patch under a disc sun and a dim sky (fibre vertices, the sun
/// lean's slot), with NEE at every vertex.
const TWILL: &str = r#"
[camera]
eye = [0.2, 0.2, 1.6]
look_at = [0.2, 0.2, 0.0]
up = [0.0, 1.0, 0.0]
fov = 10
[film]
width = 12
height = 12
spp = 4
seed = 5
max_depth = 64
[[light]]
type = "environment"
radiance = [0.05, 0.05, 0.06]
[[light]]
type = "distant"
direction = [-0.45, -0.3, 0.6]
irradiance = [3.0, 2.9, 2.7]
angular_radius = 3.0
[[object]]
name = "twill"
shape = "bounds"
interior = { type = "fabric", pattern = "twill", yarn = "cotton1", resolution = 32, flyaways = 0, warp_albedo = [0.8, 0.2, 0.1], weft_albedo = [0.85, 0.85, 0.8], attenuation = 0.004, nee = "interior" }
"#;

/// The bits of one path's result.
fn bits(r: &PathResult) -> Vec<u32> {
    let mut v: Vec<u32> = [r.radiance, r.albedo]
        .iter()
        .flat_map(|c| (0..3).map(move |k| c[k].to_bits()))
        .collect();
    v.extend(r.normal.to_array().map(f32::to_bits));
    v.push(r.depth.to_bits());
    v
}

/// Traces sample `s` of pixel `(x, y)` as the renderer does.
fn trace(scene: &Scene, x: u32, y: u32, s: u32, stats: &mut TraceStats) -> Vec<u32> {
    let pixel = PixelSeed::new(scene.film.seed, x, y);
    let mut sampler = PixelSampler::in_pixel(&pixel, s);
    let film_pos = Vec2::new(x as f32, y as f32) + sampler.next_2d();
    let lens = sampler.next_2d();
    let ray = scene.camera.generate_ray(film_pos, lens);
    bits(&trace_path(scene, ray, &mut sampler, stats))
}

/// The paths of a 12 × 8 window at the film's centre, 3 samples each, traced in order, then
/// in reverse with other paths of the window traced between them: the same bits. Returns
/// the vertices scattered at.
fn order_does_not_matter(scene: &Scene) -> u64 {
    let (x0, y0) = (scene.film.width / 2 - 6, scene.film.height / 2 - 4);
    let keys: Vec<(u32, u32, u32)> = (y0..y0 + 8)
        .flat_map(|y| (x0..x0 + 12).flat_map(move |x| (0..3).map(move |s| (x, y, s))))
        .collect();
    let mut stats = TraceStats::default();
    let first: Vec<Vec<u32>> = keys
        .iter()
        .map(|&(x, y, s)| trace(scene, x, y, s, &mut stats))
        .collect();
    let mut other = TraceStats::default();
    for (i, &(x, y, s)) in keys.iter().enumerate().rev() {
        // A path of another pixel in between (it may scatter, or escape at once).
        let (ox, oy, os) = keys[(i * 7 + 3) % keys.len()];
        let _ = trace(scene, ox, oy, os, &mut other);
        assert_eq!(
            trace(scene, x, y, s, &mut other),
            first[i],
            "pixel ({x}, {y}) sample {s}"
        );
    }
    stats.vertices
}

#[test]
fn a_path_is_traced_alike_whatever_was_traced_before_it() {
    let dir = TempDir::new("path_state");
    let twill = scene_from_text(TWILL, dir.path().join("twill.toml"));
    let cloud_path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cloud.toml");
    let cloud = load_scene(&cloud_path).unwrap_or_else(|e| panic!("cloud: {e}"));
    for (name, scene) in [("twill", &twill), ("cloud", &cloud)] {
        // Paths that scatter (the fibre slots made) among the window's 288.
        let vertices = order_does_not_matter(scene);
        assert!(vertices > 20, "{name}: {vertices} vertices over 288 paths");
    }
}
