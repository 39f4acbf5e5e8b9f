//! Camera ray generation: look-at, field-of-view edges, projection round trip, thin-lens
//! focus plane, and parameter validation.

use velour::camera::{Camera, CameraError};
use velour::math::{Vec2, Vec3};
use velour::sampling::Rng;

fn angle(a: Vec3, b: Vec3) -> f32 {
    let (a, b) = (a.normalize(), b.normalize());
    a.cross(b).length().atan2(a.dot(b))
}

#[test]
fn centre_pixel_looks_at_target_and_edges_match_fov() {
    let eye = Vec3::new(1.0, 2.0, 5.0);
    let look = Vec3::new(-0.5, 0.3, 0.2);
    let (w, h) = (640u32, 360u32);
    let vfov = 40.0f32;
    let cam = Camera::pinhole(eye, look, Vec3::Y, vfov, w, h).unwrap();
    let fwd = (look - eye).normalize();
    let c = cam.generate_ray(
        Vec2::new(w as f32 / 2.0, h as f32 / 2.0),
        Vec2::new(0.3, 0.9),
    );
    assert_eq!(c.o, eye);
    assert!((c.d - fwd).length() < 1e-6);
    assert!((c.d.length() - 1.0).abs() < 1e-6);

    let half = vfov.to_radians() / 2.0;
    let top = cam.generate_ray(Vec2::new(w as f32 / 2.0, 0.0), Vec2::ZERO);
    let bottom = cam.generate_ray(Vec2::new(w as f32 / 2.0, h as f32), Vec2::ZERO);
    assert!((angle(top.d, fwd) - half).abs() < 1e-5);
    assert!((angle(bottom.d, fwd) - half).abs() < 1e-5);
    assert!((angle(top.d, bottom.d) - 2.0 * half).abs() < 1e-5);
    // Top of the image is up (world y here), left is left.
    assert!(top.d.y > bottom.d.y);
    let left = cam.generate_ray(Vec2::new(0.0, h as f32 / 2.0), Vec2::ZERO);
    let right = cam.generate_ray(Vec2::new(w as f32, h as f32 / 2.0), Vec2::ZERO);
    let hhalf = (half.tan() * w as f32 / h as f32).atan();
    assert!((angle(left.d, fwd) - hhalf).abs() < 1e-5);
    let right_dir = fwd.cross(Vec3::Y);
    assert!(right.d.dot(right_dir) > 0.0 && left.d.dot(right_dir) < 0.0);
    // Square pixels: one pixel step subtends the same angle horizontally and vertically at
    // the centre.
    let cx = cam.generate_ray(Vec2::new(w as f32 / 2.0 + 1.0, h as f32 / 2.0), Vec2::ZERO);
    let cy = cam.generate_ray(Vec2::new(w as f32 / 2.0, h as f32 / 2.0 + 1.0), Vec2::ZERO);
    assert!((angle(cx.d, fwd) - angle(cy.d, fwd)).abs() < 1e-6);
}

#[test]
fn projection_inverts_ray_generation() {
    let cam = Camera::pinhole(
        Vec3::new(0.0, 0.5, 3.0),
        Vec3::ZERO,
        Vec3::new(0.1, 1.0, 0.0),
        55.0,
        200,
        300,
    )
    .unwrap();
    let mut rng = Rng::new(1, 0);
    for _ in 0..1000 {
        let f = Vec2::new(rng.next_f32() * 200.0, rng.next_f32() * 300.0);
        let r = cam.generate_ray(f, Vec2::ZERO);
        let p = r.at(0.5 + 10.0 * rng.next_f32());
        let back = cam.project(p).unwrap();
        assert!((back - f).length() < 2e-3, "{f:?} -> {back:?}");
    }
    assert!(cam.project(Vec3::new(0.0, 0.5, 10.0)).is_none());
}

#[test]
fn thin_lens_rays_converge_on_the_focus_plane() {
    let eye = Vec3::new(0.0, 0.0, 4.0);
    let focus = 3.0;
    let aperture = 0.2;
    let cam = Camera::thin_lens(eye, Vec3::ZERO, Vec3::Y, 30.0, 100, 80, aperture, focus).unwrap();
    let pin = Camera::pinhole(eye, Vec3::ZERO, Vec3::Y, 30.0, 100, 80).unwrap();
    let fwd = -Vec3::Z;
    let mut rng = Rng::new(2, 0);
    let mut spread = 0.0f32;
    for _ in 0..200 {
        let f = Vec2::new(rng.next_f32() * 100.0, rng.next_f32() * 80.0);
        let centre_ray = pin.generate_ray(f, Vec2::ZERO);
        let target = centre_ray.o + centre_ray.d * (focus / centre_ray.d.dot(fwd));
        // The lens centre sample reproduces the pinhole ray.
        let c = cam.generate_ray(f, Vec2::new(0.5, 0.5));
        assert!((c.o - eye).length() < 1e-6 && (c.d - centre_ray.d).length() < 1e-5);
        for _ in 0..20 {
            let r = cam.generate_ray(f, rng.next_2d());
            assert!((r.d.length() - 1.0).abs() < 1e-5);
            let off = r.o - eye;
            assert!(off.dot(fwd).abs() < 1e-6 && off.length() <= aperture * 1.0001);
            spread = spread.max(off.length());
            // Intersect the plane z = eye.z − focus.
            let t = (focus - (r.o - eye).dot(fwd)) / r.d.dot(fwd);
            assert!(
                (r.at(t) - target).length() < 2e-5,
                "miss focus point by {}",
                (r.at(t) - target).length()
            );
        }
    }
    assert!(
        spread > aperture * 0.9,
        "lens samples do not cover the aperture"
    );
}

#[test]
fn invalid_parameters_are_errors() {
    let e = Vec3::new(0.0, 0.0, 1.0);
    let ok = |r: Result<Camera, CameraError>| r.is_ok();
    assert!(ok(Camera::pinhole(e, Vec3::ZERO, Vec3::Y, 45.0, 1, 1)));
    assert_eq!(
        Camera::pinhole(e, Vec3::ZERO, Vec3::Y, 0.0, 8, 8).unwrap_err(),
        CameraError::Fov(0.0)
    );
    assert!(Camera::pinhole(e, Vec3::ZERO, Vec3::Y, 180.0, 8, 8).is_err());
    assert!(Camera::pinhole(e, Vec3::ZERO, Vec3::Y, f32::NAN, 8, 8).is_err());
    assert_eq!(
        Camera::pinhole(e, Vec3::ZERO, Vec3::Y, 45.0, 0, 8).unwrap_err(),
        CameraError::Size(0, 8)
    );
    assert_eq!(
        Camera::pinhole(e, e, Vec3::Y, 45.0, 8, 8).unwrap_err(),
        CameraError::ZeroView
    );
    assert_eq!(
        Camera::pinhole(e, Vec3::ZERO, Vec3::Z, 45.0, 8, 8).unwrap_err(),
        CameraError::DegenerateUp
    );
    assert_eq!(
        Camera::pinhole(e, Vec3::ZERO, Vec3::ZERO, 45.0, 8, 8).unwrap_err(),
        CameraError::DegenerateUp
    );
    assert_eq!(
        Camera::pinhole(Vec3::splat(f32::INFINITY), Vec3::ZERO, Vec3::Y, 45.0, 8, 8).unwrap_err(),
        CameraError::NonFinite
    );
    assert!(Camera::thin_lens(e, Vec3::ZERO, Vec3::Y, 45.0, 8, 8, -0.1, 1.0).is_err());
    assert!(Camera::thin_lens(e, Vec3::ZERO, Vec3::Y, 45.0, 8, 8, 0.1, 0.0).is_err());
    assert!(Camera::thin_lens(e, Vec3::ZERO, Vec3::Y, 45.0, 8, 8, 0.1, f32::INFINITY).is_err());
    // Error messages name the parameter.
    let msg = Camera::pinhole(e, Vec3::ZERO, Vec3::Y, 200.0, 8, 8)
        .unwrap_err()
        .to_string();
    assert!(msg.contains("field of view"), "{msg}");
}
