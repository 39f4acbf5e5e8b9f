//! Light sources: constant and lat-long environment maps, distant lights with an angular
//! radius (sun-like discs), and spherical area lights. Every light can be sampled from a
//! reference point and evaluated for MIS (docs/references.md §9; Veach 1997).

use crate::image_io::LatLongMap;
use crate::math::{Frame, Vec2, Vec3, PI};
use crate::sampling::{
    sample_uniform_cone, sample_uniform_sphere, uniform_cone_pdf, Distribution2D,
};
use crate::spectrum::Rgb;

/// A direction sampled towards a light.
#[derive(Clone, Copy, Debug)]
pub struct LightSample {
    /// Unit direction from the reference point to the light.
    pub wi: Vec3,
    /// Distance to the sampled light point (∞ for infinitely distant lights).
    pub distance: f32,
    /// Emitted radiance arriving along `-wi` (W/(m² sr)).
    pub radiance: Rgb,
    /// Solid-angle pdf of `wi` (1 for delta lights).
    pub pdf: f32,
    /// True for lights that cannot be hit by a ray (a distant light of zero angular radius).
    pub is_delta: bool,
}

/// A lat-long environment map with luminance × sinθ importance sampling.
#[derive(Clone, Debug)]
pub struct EnvironmentMap {
    map: LatLongMap,
    scale: f32,
    /// Rotation about +y, radians.
    rotation: f32,
    distribution: Option<Distribution2D>,
}

impl EnvironmentMap {
    /// Builds the sampling distribution. `scale` multiplies the texels; `rotation_deg` rotates
    /// the map about +y.
    #[must_use]
    pub fn new(map: LatLongMap, scale: f32, rotation_deg: f32) -> Self {
        let w = map.width as usize;
        let h = map.height as usize;
        let mut weights = vec![0.0f32; w * h];
        for y in 0..h {
            let sin_theta = (PI * (y as f32 + 0.5) / h as f32).sin();
            for x in 0..w {
                let t = map.texels[y * w + x];
                weights[y * w + x] = t.max_component().max(0.0) * sin_theta;
            }
        }
        let distribution = Distribution2D::new(&weights, w, h);
        EnvironmentMap {
            map,
            scale,
            rotation: rotation_deg.to_radians(),
            distribution,
        }
    }

    /// Direction → (u, v) in [0,1)²: θ = acos(y) from +y (v = θ/π), φ = atan2(z, x) from +x
    /// towards +z (u = φ/2π), after undoing the map rotation.
    fn dir_to_uv(&self, d: Vec3) -> Vec2 {
        let (s, c) = (-self.rotation).sin_cos();
        let x = c * d.x - s * d.z;
        let z = s * d.x + c * d.z;
        let theta = d.y.clamp(-1.0, 1.0).acos();
        let mut phi = z.atan2(x);
        if phi < 0.0 {
            phi += 2.0 * PI;
        }
        Vec2::new(
            (phi / (2.0 * PI)).min(0.999_999_9),
            (theta / PI).min(0.999_999_9),
        )
    }

    fn uv_to_dir(&self, uv: Vec2) -> (Vec3, f32) {
        let theta = uv.y * PI;
        let phi = uv.x * 2.0 * PI;
        let sin_theta = theta.sin();
        let x = sin_theta * phi.cos();
        let z = sin_theta * phi.sin();
        let (s, c) = self.rotation.sin_cos();
        let d = Vec3::new(c * x - s * z, theta.cos(), s * x + c * z);
        (d, sin_theta)
    }

    fn lookup(&self, uv: Vec2) -> Rgb {
        let w = self.map.width as usize;
        let h = self.map.height as usize;
        let x = ((uv.x * w as f32) as usize).min(w - 1);
        let y = ((uv.y * h as f32) as usize).min(h - 1);
        self.map.texels[y * w + x] * self.scale
    }

    /// Radiance arriving from direction `d` (pointing away from the receiver).
    #[must_use]
    pub fn radiance(&self, d: Vec3) -> Rgb {
        self.lookup(self.dir_to_uv(d))
    }

    fn sample(&self, u: Vec2) -> Option<(Vec3, Rgb, f32)> {
        let dist = self.distribution.as_ref()?;
        let (uv, pdf_uv) = dist.sample(u);
        let (d, sin_theta) = self.uv_to_dir(uv);
        if sin_theta <= 1e-6 || pdf_uv <= 0.0 {
            return None;
        }
        // Evaluate the pdf and radiance through the direction, exactly as `pdf` and `radiance`
        // do for MIS, so that both strategies agree even at cell boundaries.
        let pdf = self.pdf(d);
        if !(pdf > 0.0) {
            return None;
        }
        Some((d, self.radiance(d), pdf))
    }

    fn pdf(&self, d: Vec3) -> f32 {
        let Some(dist) = self.distribution.as_ref() else {
            return 0.0;
        };
        let uv = self.dir_to_uv(d);
        let sin_theta = (uv.y * PI).sin();
        if sin_theta <= 1e-6 {
            return 0.0;
        }
        dist.pdf(uv) / (2.0 * PI * PI * sin_theta)
    }
}

/// A light source.
#[derive(Clone, Debug)]
pub enum Light {
    /// Uniform radiance from every direction.
    ConstantEnvironment {
        /// Radiance (W/(m² sr)).
        radiance: Rgb,
    },
    /// A lat-long environment map.
    EnvironmentMap(Box<EnvironmentMap>),
    /// A distant light: a disc of angular radius `angular_radius` around `to_light`.
    Distant {
        /// Unit direction from the scene towards the light.
        to_light: Vec3,
        /// Irradiance at normal incidence (W/m²).
        irradiance: Rgb,
        /// cos of the angular radius (1 for a delta light).
        cos_radius: f32,
    },
    /// A spherical area light (also a shape that rays can hit).
    Sphere {
        /// Centre (world space).
        center: Vec3,
        /// Radius (world units).
        radius: f32,
        /// Emitted radiance (W/(m² sr)).
        radiance: Rgb,
    },
}

impl Light {
    /// A distant light towards `to_light` (need not be normalised) with angular radius in
    /// degrees (0 = delta light) and irradiance at normal incidence.
    #[must_use]
    pub fn distant(to_light: Vec3, irradiance: Rgb, angular_radius_deg: f32) -> Self {
        let cos_radius = if angular_radius_deg > 0.0 {
            angular_radius_deg.to_radians().cos()
        } else {
            1.0
        };
        Light::Distant {
            to_light: to_light.normalize(),
            irradiance,
            cos_radius,
        }
    }

    /// True for infinitely distant lights (reached by rays that escape the scene).
    #[must_use]
    pub fn is_infinite(&self) -> bool {
        !matches!(self, Light::Sphere { .. })
    }

    /// Radiance of a distant disc light (irradiance E at normal incidence spread uniformly
    /// over the cone: E = L π sin²r ⇒ L = E / (π (1 − cos² r))).
    fn distant_radiance(irradiance: Rgb, cos_radius: f32) -> Rgb {
        let sin2 = (1.0 - cos_radius * cos_radius).max(1e-12);
        irradiance / (PI * sin2)
    }

    /// Samples a direction from `p` towards the light.
    #[must_use]
    pub fn sample_li(&self, p: Vec3, u: Vec2) -> Option<LightSample> {
        match self {
            Light::ConstantEnvironment { radiance } => {
                let wi = sample_uniform_sphere(u);
                Some(LightSample {
                    wi,
                    distance: f32::INFINITY,
                    radiance: *radiance,
                    pdf: 1.0 / (4.0 * PI),
                    is_delta: false,
                })
            }
            Light::EnvironmentMap(env) => {
                let (wi, radiance, pdf) = env.sample(u)?;
                Some(LightSample {
                    wi,
                    distance: f32::INFINITY,
                    radiance,
                    pdf,
                    is_delta: false,
                })
            }
            Light::Distant {
                to_light,
                irradiance,
                cos_radius,
            } => {
                if *cos_radius >= 1.0 {
                    return Some(LightSample {
                        wi: *to_light,
                        distance: f32::INFINITY,
                        radiance: *irradiance,
                        pdf: 1.0,
                        is_delta: true,
                    });
                }
                let local = sample_uniform_cone(u, *cos_radius);
                let wi = Frame::from_normal(*to_light).to_world(local).normalize();
                Some(LightSample {
                    wi,
                    distance: f32::INFINITY,
                    radiance: Self::distant_radiance(*irradiance, *cos_radius),
                    pdf: uniform_cone_pdf(*cos_radius),
                    is_delta: false,
                })
            }
            Light::Sphere {
                center,
                radius,
                radiance,
            } => {
                let to_c = *center - p;
                let dc2 = to_c.length_squared();
                let r2 = radius * radius;
                if dc2 <= r2 * 1.000_01 {
                    // Inside (or on) the sphere: uniform over all directions; the sphere is hit
                    // from inside, which emits nothing (one-sided emitter).
                    return None;
                }
                let dc = dc2.sqrt();
                let sin2_max = r2 / dc2;
                let cos_max = (1.0 - sin2_max).max(0.0).sqrt();
                let axis = to_c / dc;
                let local = sample_uniform_cone(u, cos_max);
                let wi = Frame::from_normal(axis).to_world(local).normalize();
                // Distance to the sphere along wi (near root).
                let b = wi.dot(to_c);
                let disc = (r2 - (to_c - wi * b).length_squared()).max(0.0);
                let distance = (b - disc.sqrt()).max(0.0);
                Some(LightSample {
                    wi,
                    distance,
                    radiance: *radiance,
                    pdf: uniform_cone_pdf(cos_max),
                    is_delta: false,
                })
            }
        }
    }

    /// Solid-angle pdf that [`Light::sample_li`] gives direction `wi` from `p` (0 for delta lights).
    #[must_use]
    pub fn pdf_li(&self, p: Vec3, wi: Vec3) -> f32 {
        match self {
            Light::ConstantEnvironment { .. } => 1.0 / (4.0 * PI),
            Light::EnvironmentMap(env) => env.pdf(wi),
            Light::Distant {
                to_light,
                cos_radius,
                ..
            } => {
                if *cos_radius >= 1.0 || wi.dot(*to_light) < *cos_radius {
                    0.0
                } else {
                    uniform_cone_pdf(*cos_radius)
                }
            }
            Light::Sphere { center, radius, .. } => {
                let to_c = *center - p;
                let dc2 = to_c.length_squared();
                let r2 = radius * radius;
                if dc2 <= r2 * 1.000_01 {
                    return 0.0;
                }
                let cos_max = (1.0 - r2 / dc2).max(0.0).sqrt();
                if wi.dot(to_c) < cos_max * dc2.sqrt() {
                    return 0.0;
                }
                uniform_cone_pdf(cos_max)
            }
        }
    }

    /// Radiance reaching a ray that escapes the scene in direction `d` (infinite lights only).
    #[must_use]
    pub fn escaped_radiance(&self, d: Vec3) -> Rgb {
        match self {
            Light::ConstantEnvironment { radiance } => *radiance,
            Light::EnvironmentMap(env) => env.radiance(d),
            Light::Distant {
                to_light,
                irradiance,
                cos_radius,
            } => {
                if *cos_radius < 1.0 && d.dot(*to_light) >= *cos_radius {
                    Self::distant_radiance(*irradiance, *cos_radius)
                } else {
                    Rgb::ZERO
                }
            }
            Light::Sphere { .. } => Rgb::ZERO,
        }
    }

    /// A rough power estimate used to choose lights in proportion to their contribution.
    #[must_use]
    pub fn power_estimate(&self, scene_radius: f32) -> f32 {
        let area = PI * scene_radius * scene_radius;
        match self {
            Light::ConstantEnvironment { radiance } => radiance.average() * PI * area,
            Light::EnvironmentMap(env) => {
                let mean = env.map.texels.iter().map(|t| t.average()).sum::<f32>()
                    / env.map.texels.len().max(1) as f32;
                mean * env.scale * PI * area
            }
            Light::Distant { irradiance, .. } => irradiance.average() * area,
            Light::Sphere {
                radius, radiance, ..
            } => radiance.average() * PI * 4.0 * PI * radius * radius,
        }
    }
}

/// The factor on a constant environment's share of next event estimation when the scene has
/// other lights ([`LightSampler::for_nee`]). Under a constant environment the radiance arriving
/// from any direction differs only by its transmittance, so the phase function's (or BSDF's)
/// own sampling, MIS-weighted on escape, already samples it as well as it can be sampled; a
/// shadow ray towards a random sky direction mostly duplicates that work, while one towards a
/// small light (the sun) finds light the phase sampling rarely hits. Measured on the peer
/// clouds and `scenes/cloud.toml` (docs/BENCHMARKS.md, "Shadow rays: where the lookups go,
/// and the sky's share of NEE"): the image's efficiency rises as the sky's share falls, up to
/// 1.3× (dense cloud), 1.6× (thin cloud) and 1.25× (`scenes/cloud.toml`) at 0; a tenth of its
/// power share is kept so that a sky whose other lights are dim is still sampled.
pub const CONSTANT_ENVIRONMENT_NEE_SHARE: f32 = 0.1;

/// Picks one light per NEE query with probability proportional to [`Light::power_estimate`]
/// (or, for next event estimation, [`LightSampler::for_nee`]'s shares).
#[derive(Clone, Debug)]
pub struct LightSampler {
    cdf: Vec<f32>,
    probabilities: Vec<f32>,
}

/// The radiance that every ray escaping the scene sees, when it does not depend on the
/// direction: the escape's sum over `lights` (each infinite light's
/// [`Light::escaped_radiance`], black ones skipped, in order, at unit weight) when the
/// infinite lights are constant environments and delta distant lights only (an escaping ray
/// never sees a delta light); `None` when an environment map or a distant light with an
/// angular radius makes the escape depend on the direction.
#[must_use]
pub fn direction_free_escape(lights: &[Light]) -> Option<Rgb> {
    let mut l = Rgb::ZERO;
    for light in lights {
        match light {
            // The escape's own operations: the sum of `le * w` with the weight w = 1.
            Light::ConstantEnvironment { radiance } if !radiance.is_black() => {
                l += *radiance * 1.0;
            }
            Light::ConstantEnvironment { .. } | Light::Sphere { .. } => {}
            Light::Distant { cos_radius, .. } if !(*cos_radius < 1.0) => {}
            Light::Distant { .. } | Light::EnvironmentMap(_) => return None,
        }
    }
    Some(l)
}

/// The index of the delta distant light (a sun with no angular radius) of greatest
/// irradiance summed over RGB, the first of equals; `None` when `lights` has none.
#[must_use]
pub fn brightest_delta_sun(lights: &[Light]) -> Option<usize> {
    brightest_distant(lights, false)
}

/// The index of the distant light of greatest irradiance summed over RGB, the first of
/// equals, among delta suns and, with `discs`, suns with an angular radius too; `None` when
/// `lights` has none.
#[must_use]
pub fn brightest_distant(lights: &[Light], discs: bool) -> Option<usize> {
    let mut best: Option<(f32, usize)> = None;
    for (li, light) in lights.iter().enumerate() {
        if let Light::Distant {
            irradiance,
            cos_radius,
            ..
        } = light
        {
            let power = irradiance[0] + irradiance[1] + irradiance[2];
            if (discs || *cos_radius >= 1.0) && best.is_none_or(|(b, _)| power > b) {
                best = Some((power, li));
            }
        }
    }
    best.map(|(_, li)| li)
}

impl LightSampler {
    /// Builds the selection distribution (uniform when every estimate is zero).
    #[must_use]
    pub fn new(lights: &[Light], scene_radius: f32) -> Self {
        let mut w: Vec<f32> = lights
            .iter()
            .map(|l| l.power_estimate(scene_radius).max(0.0))
            .collect();
        let sum: f32 = w.iter().sum();
        if !(sum > 0.0) || !sum.is_finite() {
            w = vec![1.0; lights.len()];
        }
        let sum: f32 = w.iter().sum();
        Self::from_probabilities(w.iter().map(|x| x / sum).collect())
    }

    /// The distribution next event estimation picks its light from: [`LightSampler::new`]'s
    /// power shares with every constant environment's share scaled by
    /// [`CONSTANT_ENVIRONMENT_NEE_SHARE`] and renormalised, when the scene has another light
    /// with a share (otherwise the power shares unchanged). Built once per scene.
    #[must_use]
    pub fn for_nee(lights: &[Light], scene_radius: f32) -> Self {
        let power = Self::new(lights, scene_radius);
        let factor = |l: &Light| match l {
            Light::ConstantEnvironment { .. } => CONSTANT_ENVIRONMENT_NEE_SHARE,
            _ => 1.0,
        };
        let other: f32 = lights
            .iter()
            .zip(&power.probabilities)
            .filter(|(l, _)| factor(l) == 1.0)
            .map(|(_, p)| p)
            .sum();
        let w: Vec<f32> = lights
            .iter()
            .zip(&power.probabilities)
            .map(|(l, p)| p * factor(l))
            .collect();
        let z: f32 = w.iter().sum();
        if !(other > 0.0) || !(z > 0.0) {
            return power;
        }
        Self::from_probabilities(w.iter().map(|x| x / z).collect())
    }

    /// The sampler of normalised `probabilities`.
    fn from_probabilities(probabilities: Vec<f32>) -> Self {
        let mut cdf = Vec::with_capacity(probabilities.len());
        let mut acc = 0.0;
        for p in &probabilities {
            acc += p;
            cdf.push(acc);
        }
        LightSampler { cdf, probabilities }
    }

    /// Chooses a light index for uniform `u`; returns it and its probability.
    #[must_use]
    pub fn sample(&self, u: f32) -> Option<(usize, f32)> {
        if self.cdf.is_empty() {
            return None;
        }
        // Past the last step of the CDF (rounding): the last light that can be chosen.
        let i = self
            .cdf
            .iter()
            .position(|&c| u < c)
            .or_else(|| self.probabilities.iter().rposition(|&p| p > 0.0))?;
        Some((i, self.probabilities[i]))
    }

    /// Probability of choosing light `i`.
    #[must_use]
    pub fn probability(&self, i: usize) -> f32 {
        self.probabilities.get(i).copied().unwrap_or(0.0)
    }
}
