//! Fresnel reflectance of dielectric and conducting interfaces (unpolarised light).

use crate::spectrum::Rgb;

/// Unpolarised Fresnel reflectance of a dielectric interface (docs/references.md §3.1).
///
/// `cos_i` is the cosine between the incident direction and the (micro)normal, positive when
/// the incident direction is on the side the normal points to; `eta = η_other / η_normal-side`
/// is the relative index for light arriving from the normal's side (for an outward normal:
/// `n_inside / n_outside`). A negative `cos_i` means the light arrives from the other side and
/// the relative index `1/eta` is used. Total internal reflection returns exactly 1; `eta = 1`
/// returns exactly 0 (except at grazing incidence, where every formula gives 1).
#[must_use]
pub fn fresnel_dielectric(cos_i: f32, eta: f32) -> f32 {
    let (c, eta) = if cos_i < 0.0 {
        (-cos_i, 1.0 / eta)
    } else {
        (cos_i, eta)
    };
    let c = c.min(1.0);
    if !(eta > 0.0) || !c.is_finite() || !eta.is_finite() {
        return 1.0;
    }
    if eta == 1.0 && c > 0.0 {
        return 0.0;
    }
    // Evaluated in f64: near the critical angle cos θ_t is a small difference of O(1) terms.
    let (c, eta) = (c as f64, eta as f64);
    // cos²θ_t = 1 − (1 − c²)/η² = (η² − 1 + c²)/η² (Walter 2007's g²/η²).
    let cos2_t = (eta * eta - 1.0 + c * c) / (eta * eta);
    if cos2_t <= 0.0 {
        return 1.0;
    }
    let cos_t = cos2_t.sqrt();
    let r_s = (c - eta * cos_t) / (c + eta * cos_t);
    let r_p = (eta * c - cos_t) / (eta * c + cos_t);
    (0.5 * (r_s * r_s + r_p * r_p)).clamp(0.0, 1.0) as f32
}

/// A small complex number for the conductor Fresnel equations.
#[derive(Clone, Copy, Debug)]
struct Complex {
    re: f32,
    im: f32,
}

impl Complex {
    fn new(re: f32, im: f32) -> Self {
        Complex { re, im }
    }
    fn add(self, o: Complex) -> Complex {
        Complex::new(self.re + o.re, self.im + o.im)
    }
    fn sub(self, o: Complex) -> Complex {
        Complex::new(self.re - o.re, self.im - o.im)
    }
    fn mul(self, o: Complex) -> Complex {
        Complex::new(
            self.re * o.re - self.im * o.im,
            self.re * o.im + self.im * o.re,
        )
    }
    fn scale(self, s: f32) -> Complex {
        Complex::new(self.re * s, self.im * s)
    }
    fn norm2(self) -> f32 {
        self.re * self.re + self.im * self.im
    }
    fn div(self, o: Complex) -> Complex {
        let d = o.norm2();
        if d == 0.0 {
            return Complex::new(0.0, 0.0);
        }
        Complex::new(
            (self.re * o.re + self.im * o.im) / d,
            (self.im * o.re - self.re * o.im) / d,
        )
    }
    /// Principal square root (non-negative real part).
    fn sqrt(self) -> Complex {
        let n = self.norm2().sqrt();
        if n == 0.0 {
            return Complex::new(0.0, 0.0);
        }
        let t1 = (0.5 * (n + self.re.abs())).sqrt();
        let t2 = 0.5 * self.im / t1;
        if self.re >= 0.0 {
            Complex::new(t1, t2)
        } else {
            Complex::new(t2.abs(), t1.copysign(self.im))
        }
    }
}

/// Unpolarised Fresnel reflectance of a conductor with complex relative index `eta + i k`
/// (one channel), for light arriving from the outside at cosine `cos_i` (clamped to [0, 1]).
/// Same s/p amplitude formulas as the dielectric case with complex arithmetic
/// (Born & Wolf, *Principles of Optics*, §14.2).
#[must_use]
pub fn fresnel_conductor_scalar(cos_i: f32, eta: f32, k: f32) -> f32 {
    let c = cos_i.abs().min(1.0);
    if !c.is_finite() {
        return 1.0;
    }
    let n = Complex::new(eta, k);
    let sin2_i = (1.0 - c) * (1.0 + c);
    // sin²θ_t = sin²θ_i / n²; cosθ_t = sqrt(1 - sin²θ_t).
    let sin2_t = Complex::new(sin2_i, 0.0).div(n.mul(n));
    let cos_t = Complex::new(1.0, 0.0).sub(sin2_t).sqrt();
    let ci = Complex::new(c, 0.0);
    let r_s = ci.sub(n.mul(cos_t)).div(ci.add(n.mul(cos_t)));
    let r_p = n.scale(c).sub(cos_t).div(n.scale(c).add(cos_t));
    let f = 0.5 * (r_s.norm2() + r_p.norm2());
    if f.is_finite() {
        f.clamp(0.0, 1.0)
    } else {
        1.0
    }
}

/// [`fresnel_conductor_scalar`] for each RGB channel.
#[must_use]
pub fn fresnel_conductor(cos_i: f32, eta: Rgb, k: Rgb) -> Rgb {
    Rgb::new(
        fresnel_conductor_scalar(cos_i, eta[0], k[0]),
        fresnel_conductor_scalar(cos_i, eta[1], k[1]),
        fresnel_conductor_scalar(cos_i, eta[2], k[2]),
    )
}

/// Maps a normal-incidence reflectance `r` and an edge tint `g` (both in [0, 1)) to a complex
/// index `(n, k)` with the artist-friendly parameterisation of O. Gulbrandsen, "Artist Friendly
/// Metallic Fresnel" (JCGT 3(4), 2014). The mapping reproduces `F(0°) = r` exactly.
#[must_use]
pub fn gulbrandsen_eta_k(r: f32, g: f32) -> (f32, f32) {
    let r = r.clamp(0.0, 0.999);
    let g = g.clamp(0.0, 1.0);
    let sr = r.sqrt();
    let n_min = (1.0 - r) / (1.0 + r);
    let n_max = (1.0 + sr) / (1.0 - sr);
    let n = g * n_min + (1.0 - g) * n_max;
    let k2 = (r * (n + 1.0) * (n + 1.0) - (n - 1.0) * (n - 1.0)) / (1.0 - r);
    (n, k2.max(0.0).sqrt())
}
