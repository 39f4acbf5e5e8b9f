//! Perspective cameras: pinhole and thin lens, set up by eye / look-at / up and a vertical
//! field of view. Film coordinates are continuous pixel coordinates with `(0, 0)` at the
//! top-left corner of the image and `(width, height)` at the bottom-right; pixels are square.

use crate::math::{Ray, Vec2, Vec3};
use crate::sampling::sample_uniform_disk_concentric;

/// Invalid camera parameters (each variant names the parameter).
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum CameraError {
    /// `vfov` outside (0°, 180°) or not finite.
    #[error("camera: vertical field of view {0}° must be in (0, 180)")]
    Fov(f32),
    /// Zero image width or height.
    #[error("camera: image size {0}x{1} must be at least 1x1")]
    Size(u32, u32),
    /// `eye`, `look_at` or `up` not finite.
    #[error("camera: eye, look_at and up must be finite")]
    NonFinite,
    /// `eye == look_at`.
    #[error("camera: eye and look_at coincide")]
    ZeroView,
    /// `up` is zero or parallel to the view direction.
    #[error("camera: up vector is zero or parallel to the view direction")]
    DegenerateUp,
    /// Negative or non-finite aperture radius.
    #[error("camera: aperture radius {0} must be finite and >= 0")]
    Aperture(f32),
    /// Non-positive or non-finite focus distance.
    #[error("camera: focus distance {0} must be finite and > 0")]
    FocusDistance(f32),
}

/// A perspective camera (pinhole when `aperture_radius == 0`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    eye: Vec3,
    forward: Vec3,
    right: Vec3,
    up: Vec3,
    tan_half_vfov: f32,
    width: u32,
    height: u32,
    aperture_radius: f32,
    focus_distance: f32,
    /// [`Camera::pixel_spread_angle`], computed once (an `atan` per camera path otherwise).
    pixel_spread: f32,
}

impl Camera {
    /// A pinhole camera at `eye` looking at `look_at`, with `up` giving the image's upward
    /// direction (need not be orthogonal to the view), vertical field of view `vfov_deg`
    /// (degrees, full angle between the top and bottom image edges) and the image size in
    /// pixels (which sets the aspect ratio).
    pub fn pinhole(
        eye: Vec3,
        look_at: Vec3,
        up: Vec3,
        vfov_deg: f32,
        width: u32,
        height: u32,
    ) -> Result<Camera, CameraError> {
        Self::thin_lens(eye, look_at, up, vfov_deg, width, height, 0.0, 1.0)
    }

    /// A thin-lens camera: like [`Camera::pinhole`] with a circular lens of radius
    /// `aperture_radius` (world units) centred at `eye` and perpendicular to the view
    /// direction, focused on the plane perpendicular to the view direction at
    /// `focus_distance` (world units) from the lens (pbrt-v4 §5.2.3 model).
    #[allow(clippy::too_many_arguments)]
    pub fn thin_lens(
        eye: Vec3,
        look_at: Vec3,
        up: Vec3,
        vfov_deg: f32,
        width: u32,
        height: u32,
        aperture_radius: f32,
        focus_distance: f32,
    ) -> Result<Camera, CameraError> {
        if !(vfov_deg > 0.0 && vfov_deg < 180.0) {
            return Err(CameraError::Fov(vfov_deg));
        }
        if width == 0 || height == 0 {
            return Err(CameraError::Size(width, height));
        }
        if !eye.is_finite() || !look_at.is_finite() || !up.is_finite() {
            return Err(CameraError::NonFinite);
        }
        if !(aperture_radius >= 0.0 && aperture_radius.is_finite()) {
            return Err(CameraError::Aperture(aperture_radius));
        }
        if !(focus_distance > 0.0 && focus_distance.is_finite()) {
            return Err(CameraError::FocusDistance(focus_distance));
        }
        let forward = (look_at - eye)
            .try_normalize()
            .ok_or(CameraError::ZeroView)?;
        let right = forward
            .cross(up)
            .try_normalize()
            .ok_or(CameraError::DegenerateUp)?;
        if forward.cross(up).length() < 1e-6 * up.length() {
            return Err(CameraError::DegenerateUp);
        }
        let up = right.cross(forward);
        let tan_half_vfov = (vfov_deg.to_radians() * 0.5).tan();
        Ok(Camera {
            eye,
            forward,
            right,
            up,
            tan_half_vfov,
            width,
            height,
            aperture_radius,
            focus_distance,
            pixel_spread: (2.0 * tan_half_vfov / height as f32).atan(),
        })
    }

    /// Image width in pixels.
    #[must_use]
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Image height in pixels.
    #[must_use]
    pub fn height(&self) -> u32 {
        self.height
    }

    /// Camera position (lens centre).
    #[must_use]
    pub fn eye(&self) -> Vec3 {
        self.eye
    }

    /// Unit view direction.
    #[must_use]
    pub fn forward(&self) -> Vec3 {
        self.forward
    }

    /// Direction (not normalised) through film position `film_pos` from the lens centre,
    /// with unit component along `forward`.
    fn film_dir(&self, film_pos: Vec2) -> Vec3 {
        let aspect = self.width as f32 / self.height as f32;
        let sx = (2.0 * film_pos.x / self.width as f32 - 1.0) * self.tan_half_vfov * aspect;
        let sy = (1.0 - 2.0 * film_pos.y / self.height as f32) * self.tan_half_vfov;
        self.forward + self.right * sx + self.up * sy
    }

    /// The primary ray through `film_pos` (continuous pixel coordinates, `(0, 0)` top-left;
    /// pixel `(i, j)` covers `[i, i+1) × [j, j+1)`), with `lens_u ∈ [0,1)²` choosing the
    /// point on the lens (concentric disc mapping; ignored by pinhole cameras). The
    /// direction is unit length.
    #[must_use]
    pub fn generate_ray(&self, film_pos: Vec2, lens_u: Vec2) -> Ray {
        let dir = self.film_dir(film_pos);
        if self.aperture_radius == 0.0 {
            return Ray::new(self.eye, dir.normalize());
        }
        // `dir` has unit forward component, so the focus-plane point is eye + dir·focus.
        let focus = self.eye + dir * self.focus_distance;
        let lens = sample_uniform_disk_concentric(lens_u) * self.aperture_radius;
        let o = self.eye + self.right * lens.x + self.up * lens.y;
        Ray::new(o, (focus - o).normalize())
    }

    /// The spread angle of a ray cone through one pixel (Akenine-Möller et al. 2019;
    /// docs/references.md §14.2): atan(2 tan(fov/2) / height), radians.
    #[must_use]
    #[inline]
    pub fn pixel_spread_angle(&self) -> f32 {
        self.pixel_spread
    }

    /// The film position a world point projects to through the lens centre, or `None` when
    /// the point is not in front of the camera. (Inverse of the pinhole mapping; the point
    /// may fall outside `[0, width] × [0, height]`.)
    #[must_use]
    pub fn project(&self, p: Vec3) -> Option<Vec2> {
        let v = p - self.eye;
        let z = v.dot(self.forward);
        if z.is_nan() || z <= 0.0 {
            return None;
        }
        let aspect = self.width as f32 / self.height as f32;
        let sx = v.dot(self.right) / z / (self.tan_half_vfov * aspect);
        let sy = v.dot(self.up) / z / self.tan_half_vfov;
        Some(Vec2::new(
            (sx + 1.0) * 0.5 * self.width as f32,
            (1.0 - sy) * 0.5 * self.height as f32,
        ))
    }
}
