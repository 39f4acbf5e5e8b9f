//! Rendering small scenes written inline in tests, and reading pixel values back.

use std::path::Path;

use velour::film::Film;
use velour::render::{render, RenderOptions, RenderSummary};
use velour::scene::{load_scene_str, Scene};

/// Loads scene text as if read from `path` (relative file names in it resolve against the
/// directory of `path`); panics with the scene error.
pub fn scene_from_text(text: &str, path: impl AsRef<Path>) -> Scene {
    let path = path.as_ref();
    load_scene_str(text, path).unwrap_or_else(|e| panic!("scene {}: {e}", path.display()))
}

/// Renders `scene` in memory on `threads` worker threads (0 = all cores); panics with the
/// render error.
pub fn render_scene(scene: &Scene, threads: usize) -> (Film, RenderSummary) {
    let options = RenderOptions {
        threads,
        ..RenderOptions::default()
    };
    render(scene, &options).unwrap_or_else(|e| panic!("render: {e}"))
}

/// [`render_scene`], asserting that no sample was dropped as non-finite.
pub fn render_finite(scene: &Scene, threads: usize) -> (Film, RenderSummary) {
    let (film, summary) = render_scene(scene, threads);
    assert_eq!(summary.non_finite, 0, "non-finite samples");
    (film, summary)
}

/// Channel `c` (0 = R, 1 = G, 2 = B) of every pixel mean of `film`, row by row.
pub fn pixel_means(film: &Film, c: usize) -> Vec<f64> {
    let mut values = Vec::with_capacity((film.width() * film.height()) as usize);
    for y in 0..film.height() {
        for x in 0..film.width() {
            values.push(f64::from(film.mean(x, y)[c]));
        }
    }
    values
}

/// Mean of channel `c` over the pixels `(x, y)` for which `keep` holds, and its standard
/// error from the pixels' own variances of the mean (the pixels are independent estimates).
pub fn region_mean(film: &Film, c: usize, keep: impl Fn(u32, u32) -> bool) -> (f64, f64) {
    let (mut sum, mut var, mut n) = (0.0, 0.0, 0.0);
    for y in 0..film.height() {
        for x in 0..film.width() {
            if keep(x, y) {
                sum += f64::from(film.mean(x, y)[c]);
                var += f64::from(film.variance_of_mean(x, y)[c]);
                n += 1.0;
            }
        }
    }
    assert!(n > 0.0, "empty region");
    (sum / n, var.sqrt() / n)
}

/// Two renders of the same expected image agree: the per-pixel z-test is consistent and each
/// channel's image mean differs by |z| < 4 (the standard errors from the pixels' variances).
pub fn assert_images_agree(a: &Film, b: &Film) {
    let cmp = velour::image_io::compare::compare(
        &a.to_exr_image(&std::collections::BTreeMap::new()),
        &b.to_exr_image(&std::collections::BTreeMap::new()),
    )
    .expect("compare");
    let z = cmp.z_test.expect("variance layers");
    eprintln!("per-pixel z-test: {z:?}");
    assert!(z.consistent, "per-pixel z-test fails: {z:?}");
    for c in 0..3 {
        let (ma, sa) = region_mean(a, c, |_, _| true);
        let (mb, sb) = region_mean(b, c, |_, _| true);
        let zc = (ma - mb) / (sa * sa + sb * sb).sqrt();
        eprintln!("channel {c}: {ma:.5} ± {sa:.5} against {mb:.5} ± {sb:.5} (z = {zc:.2})");
        assert!(zc.abs() < 4.0, "channel {c} means differ: z = {zc:.2}");
    }
}

/// Summed variance of the pixel means over the image and its three channels.
pub fn total_variance(f: &Film) -> f64 {
    let mut v = 0.0;
    for y in 0..f.height() {
        for x in 0..f.width() {
            let p = f.variance_of_mean(x, y);
            v += f64::from(p[0]) + f64::from(p[1]) + f64::from(p[2]);
        }
    }
    v
}

/// [`region_mean`] over the whole image.
pub fn image_mean(film: &Film, c: usize) -> (f64, f64) {
    region_mean(film, c, |_, _| true)
}

/// Every float channel of an EXR file as bit patterns, by channel name: two images are
/// bit-identical when these are equal.
pub fn pixel_bits(path: &Path) -> std::collections::BTreeMap<String, Vec<u32>> {
    let img =
        velour::image_io::read_exr(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    img.channels
        .into_iter()
        .map(|(k, v)| (k, v.into_iter().map(f32::to_bits).collect()))
        .collect()
}

/// Renders scene `text` as if it were the file `dir/scene.toml` (relative paths resolve in
/// `dir`), on all threads, failing on any non-finite sample.
#[allow(dead_code)]
pub fn render_text(text: &str, dir: &Path) -> Film {
    render_finite(&scene_from_text(text, dir.join("scene.toml")), 0).0
}

/// Where the centre ray of pixel `(i, j)` of a 16×16 pinhole camera at (0, 0, 4) looking at
/// the origin with vertical field of view `fov` degrees first meets the unit sphere at the
/// origin: the hit's x coordinate and the cosine between the ray and the normal there.
#[allow(dead_code)]
pub fn unit_sphere_hit_x(fov: f32, i: u32, j: u32) -> Option<(f32, f32)> {
    use velour::camera::Camera;
    use velour::math::{Vec2, Vec3};
    let cam = Camera::pinhole(Vec3::new(0.0, 0.0, 4.0), Vec3::ZERO, Vec3::Y, fov, 16, 16).ok()?;
    let r = cam.generate_ray(Vec2::new(i as f32 + 0.5, j as f32 + 0.5), Vec2::ZERO);
    let b = r.o.dot(r.d);
    let disc = b * b - (r.o.length_squared() - 1.0);
    if disc <= 0.0 {
        return None;
    }
    let p = r.o + r.d * (-b - disc.sqrt());
    Some((p.x, -p.normalize().dot(r.d)))
}
