//! The sun lean at fibre vertices (a fabric interior's `sun_lean`, on by default): at each
//! fibre vertex one extra direction from the vertex's own fibre lobe prepared for the
//! outgoing direction −sun, a free flight along it and the sun's NEE where it collides,
//! balance-weighted against the path's own sun NEE at its next vertex. The image must not
//! change in expectation: a twill patch under a disc sun and a dim sky renders the same image,
//! per pixel (z-test) and in its means, with `sun_lean = false`, and with less variance.

mod common;

use common::files::TempDir;
use common::render::{assert_images_agree, render_text, total_variance};

/// A free-standing twill patch seen from above at a grazing sun (3° disc), NEE at every
/// vertex.
fn twill(sun_lean: bool, spp: u32, seed: u64) -> String {
    format!(
        r#"
[camera]
eye = [0.2, 0.2, 1.6]
look_at = [0.2, 0.2, 0.0]
up = [0.0, 1.0, 0.0]
fov = 10
[film]
width = 16
height = 16
spp = {spp}
seed = {seed}
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
interior = {{ type = "fabric", pattern = "twill", yarn = "cotton1", resolution = 32, flyaways = 0, warp_albedo = [0.8, 0.2, 0.1], weft_albedo = [0.85, 0.85, 0.8], attenuation = 0.004, nee = "interior", sun_lean = {sun_lean} }}
"#
    )
}

#[test]
fn the_fibre_lean_renders_the_same_image_with_less_variance() {
    let dir = TempDir::new("fibre_lean");
    let lean = render_text(&twill(true, 256, 1), dir.path());
    let plain = render_text(&twill(false, 256, 2), dir.path());
    assert_images_agree(&lean, &plain);
    let (vl, vp) = (total_variance(&lean), total_variance(&plain));
    eprintln!("variance of the pixel means: lean {vl:.4e}, plain {vp:.4e}");
    assert!(vl < 0.9 * vp, "no less variance: {vl:.4e} against {vp:.4e}");
}
