//! Light transport towards the lights: next event estimation through shadow rays with
//! transparent or opaque boundaries, and MIS weights for lights hit by sampled directions.

use super::interiors::{current_medium, enter, is_false_intersection, InteriorStack, MAX_NESTING};
use super::TraceStats;
use crate::bsdf::fresnel::fresnel_dielectric;
use crate::film::MAX_LIGHT_LAYERS;
use crate::math::{Ray, Vec3};
use crate::medium::RayFootprint;
use crate::phase::PhaseFunction;
use crate::sampling::{power_heuristic, PixelSampler};
use crate::scene::{ObjectSurface, Scene, ShapeOwner};
use crate::spectrum::Rgb;

/// How a shadow ray treats the dielectric boundaries it meets.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum ShadowMode {
    /// Only null and false (priority) boundaries let it through.
    Opaque,
    /// Dielectric boundaries let it through with (1 − F) × tint, ignoring refraction
    /// ("transparent shadows", notes §2.3.3).
    Transparent,
}

/// Transmittance from `origin` along unit `dir` over `distance` (∞ for distant lights), through
/// media and boundaries. `ignore_shape` is the light's own shape (never an occluder).
/// `cone` is the path's ray cone at the shadow ray's origin: the media it crosses pick a
/// per-ray fabric mip level with it (the path's own level at an interior vertex;
/// [`RayFootprint::POINT`] = the finest).
#[allow(clippy::too_many_arguments)]
pub(super) fn shadow_transmittance(
    scene: &Scene,
    mut origin: Vec3,
    dir: Vec3,
    distance: f32,
    mut stack: InteriorStack,
    mode: ShadowMode,
    cone: RayFootprint,
    ignore_shape: Option<u32>,
    sampler: &mut PixelSampler,
    stats: &mut TraceStats,
) -> Rgb {
    let mut tr = Rgb::ONE;
    let mut remaining = distance;
    // Set when the search that found the last surface crossed also proved that no other
    // surface lies beyond it on the ray: the rest of the ray then needs no search (one
    // traversal for a shadow ray that leaves a closed mesh, not two). Asked only of rays
    // that start inside an object, whose first surface is usually where they leave it.
    let mut clear_beyond = false;
    for _ in 0..4 * MAX_NESTING + 8 {
        let hit = if clear_beyond {
            None
        } else {
            stats.rays += 1;
            let ray = Ray::new(origin, dir);
            if stack.entries().is_empty() {
                // Outside every object the first surface is as likely opaque as not: a
                // plain search stops sooner.
                scene.geometry.intersect(&ray, remaining)
            } else {
                let (hit, clear) = scene.geometry.intersect_and_beyond(&ray, remaining);
                clear_beyond = clear;
                hit
            }
        };
        let seg = hit.as_ref().map_or(remaining, |h| h.t);
        let mut scratch = None;
        if let Some((m, _)) = current_medium(scene, &stack, &mut scratch) {
            tr *= m.transmittance_in_cone(
                &Ray::new(origin, dir),
                seg,
                cone,
                &mut || sampler.next_1d(),
                &mut stats.tracking,
            );
            if tr.is_black() {
                return Rgb::ZERO;
            }
        }
        let Some(h) = hit else { return tr };
        if Some(h.shape) == ignore_shape {
            return tr;
        }
        let owner = scene.shape_owner[h.shape as usize];
        let ShapeOwner::Object(oi) = owner else {
            // Another light's sphere: opaque.
            return Rgb::ZERO;
        };
        let obj = &scene.objects[oi as usize];
        if !obj.surface.transmits() {
            return Rgb::ZERO;
        }
        let entering = dir.dot(h.ng) < 0.0;
        if !is_false_intersection(scene, &stack, oi, entering) {
            let surface = match &obj.surface {
                ObjectSurface::Blend(_) => obj.surface.pick(h.uv(), 0.0, sampler.next_1d()),
                s => s,
            };
            match surface {
                ObjectSurface::Null => {}
                ObjectSurface::Fixed(_) | ObjectSurface::Textured(_) | ObjectSurface::Blend(_) => {
                    return Rgb::ZERO
                }
                ObjectSurface::Dielectric(d) => {
                    let outside = stack.ior(&scene.objects, Some(oi));
                    if mode == ShadowMode::Opaque && (d.ior - outside).abs() > 1e-6 {
                        return Rgb::ZERO;
                    }
                    let eta = d.ior / outside;
                    let cos = dir.dot(h.ng).abs();
                    // Fresnel seen from the side the shadow ray comes from.
                    let f = if entering {
                        fresnel_dielectric(cos, eta)
                    } else {
                        fresnel_dielectric(cos, 1.0 / eta)
                    };
                    tr *= d.tint.eval(h.uv(), 0.0) * (1.0 - f);
                }
            }
        }
        if entering {
            enter(scene, &mut stack, oi, h.uv(), 0.0, || sampler.next_1d());
        } else {
            stack.remove(oi);
        }
        remaining -= h.t;
        if remaining <= 0.0 {
            return tr;
        }
        origin = h.spawn_origin(dir);
    }
    Rgb::ZERO
}

/// State remembered about the previous scattering vertex, for MIS on light hits.
#[derive(Clone, Copy, Debug)]
pub(super) struct PrevVertex {
    pub p: Vec3,
    /// Solid-angle pdf of the direction sampled there.
    pub pdf: f32,
    /// True when that vertex did NEE (so light hits must be MIS-weighted against it).
    pub did_nee: bool,
    /// For an exit vertex reached straight from an `exit_guided` interior vertex (and left
    /// by transmission): that interior vertex's position and its phase pdf of the direction
    /// to this vertex; light hits are then MIS-weighted against the guided connection
    /// ([`super::connect`]) instead of exit-point NEE. `None` otherwise.
    pub guided: Option<GuidedPrev>,
}

/// What a light hit needs to weight itself against the guided connection that could have
/// produced the same path ([`super::connect::guided_connection`]).
#[derive(Clone, Copy, Debug)]
pub(super) struct GuidedPrev {
    /// The interior vertex the connection starts from.
    pub x: Vec3,
    /// Its phase-function pdf of the direction to the exit vertex.
    pub phase_pdf: f32,
    /// The boundary's pdf of sampling the inside direction from the light direction
    /// (`Surface::pdf(wi, wo)`, the connection's direction strategy).
    pub reverse_pdf: f32,
}

/// Next event estimation from a point: picks a light, traces a shadow ray, returns the
/// MIS-weighted contribution (without the path throughput). `eval` gives (f·|cos| or phase
/// value, pdf of the scattering strategy) for a world direction. `cone`: the path's
/// ray cone at `p` (see [`shadow_transmittance`]). The light drawn is written to `chosen`.
/// With `only` = `Some(li)` light `li` is taken with probability 1 instead of being drawn
/// from the scene's NEE distribution: an estimate of that light's part alone. `seen` receives
/// the shadow ray's transmittance estimate (its largest channel) when a shadow ray was traced
/// (`None` otherwise; 0 when it was ended by the roulette below). With `survival` other than
/// [`ShadowRoulette::Off`], the shadow ray is traced only with a probability `s` (Russian
/// roulette before any lookup, once the light and its direction are drawn; `s` does not
/// depend on the random numbers it decides) and the estimate of the survivors is divided by
/// `s`.
#[allow(clippy::too_many_arguments)]
pub(super) fn estimate_direct(
    scene: &Scene,
    p: Vec3,
    shadow_origin: impl Fn(Vec3) -> (Vec3, InteriorStack),
    eval: impl Fn(Vec3) -> (Rgb, f32),
    mode: ShadowMode,
    cone: RayFootprint,
    sampler: &mut PixelSampler,
    stats: &mut TraceStats,
    chosen: &mut Option<usize>,
    only: Option<usize>,
    seen: &mut Option<f32>,
    survival: ShadowRoulette,
) -> Rgb {
    let u_light = sampler.next_1d();
    let u = sampler.next_2d();
    let picked = match only {
        Some(li) if li < scene.lights.len() => Some((li, 1.0)),
        Some(_) => None,
        None => scene.nee_light_sampler.sample(u_light),
    };
    let Some((li, p_sel)) = picked else {
        return Rgb::ZERO;
    };
    *chosen = Some(li);
    let light = &scene.lights[li];
    let Some(ls) = light.sample_li(p, u) else {
        return Rgb::ZERO;
    };
    if ls.pdf <= 0.0 || ls.radiance.is_black() {
        return Rgb::ZERO;
    }
    let (f, scatter_pdf) = eval(ls.wi);
    if f.is_black() {
        return Rgb::ZERO;
    }
    let light_pdf = p_sel * ls.pdf;
    let w = if ls.is_delta {
        1.0
    } else {
        power_heuristic(light_pdf, scatter_pdf)
    };
    // Russian roulette on the shadow ray before it is traced, with a survival probability
    // that depends on what is known before the ray (not on the random numbers it decides):
    // unbiased.
    let survive = match survival {
        ShadowRoulette::Light(l, s) if l == li && s > 0.0 => s.min(1.0),
        ShadowRoulette::Contribution { beta, reference } => {
            // The estimate were the transmittance 1.
            contribution_survival(beta * f * ls.radiance * (w / light_pdf), reference)
        }
        _ => 1.0,
    };
    if survive < 1.0 && !(sampler.next_1d() < survive) {
        *seen = Some(0.0);
        return Rgb::ZERO;
    }
    let (origin, stack) = shadow_origin(ls.wi);
    let light_shape = scene
        .shape_owner
        .iter()
        .position(|o| *o == ShapeOwner::Light(li as u32))
        .map(|s| s as u32);
    let distance = if ls.distance.is_finite() {
        ls.distance * (1.0 - 1e-4)
    } else {
        f32::INFINITY
    };
    let tr = shadow_transmittance(
        scene,
        origin,
        ls.wi,
        distance,
        stack,
        mode,
        cone,
        light_shape,
        sampler,
        stats,
    );
    *seen = Some(tr.max_component());
    if tr.is_black() {
        return Rgb::ZERO;
    }
    f * tr * ls.radiance * (w / (light_pdf * survive))
}

/// Russian roulette of a shadow ray before it is traced ([`estimate_direct`]).
#[derive(Clone, Copy, Debug)]
pub(super) enum ShadowRoulette {
    /// Every shadow ray is traced.
    Off,
    /// A shadow ray to light `.0` is traced with probability `.1`.
    Light(usize, f32),
    /// By the estimate's predicted contribution (path throughput `beta` × value per unit
    /// transmittance) against the radiance `reference` the path has gathered so far.
    Contribution {
        /// The path throughput at the vertex.
        beta: Rgb,
        /// The radiance gathered so far.
        reference: Rgb,
    },
}

/// The predicted contribution, as a fraction of the radiance the path has gathered so far,
/// below which a shadow ray from a fibre vertex is rouletted ([`contribution_survival`]):
/// chosen on `scenes/draped_cloth.toml` (docs/BENCHMARKS.md, "draped_cloth: shadow rays
/// rouletted by their predicted contribution").
const CONTRIBUTION_ROULETTE_FRACTION: f32 = 0.5;

/// The smallest survival probability of that roulette: a survivor's weight stays at most 20.
const CONTRIBUTION_ROULETTE_FLOOR: f32 = 0.05;

/// The survival probability of a shadow ray whose estimate, were its transmittance 1, would
/// add `c` (path throughput included) to a path that has gathered `reference` so far: the
/// largest over the channels of c / (f · reference), f =
/// [`CONTRIBUTION_ROULETTE_FRACTION`], clamped to [[`CONTRIBUTION_ROULETTE_FLOOR`], 1]; 1
/// where a channel of `c` is above 0 and the path has gathered nothing in it yet (the first
/// vertex's rays are always traced). Shadow rays that could add little to what the path
/// already carries (at a fibre vertex, directions off the fibre's narrow lobes, at deep
/// vertices of low throughput) are traced only now and then; the ones on a lobe, which carry
/// the large values, always.
fn contribution_survival(c: Rgb, reference: Rgb) -> f32 {
    let mut s: f32 = 0.0;
    for ch in 0..3 {
        let r = reference[ch] * CONTRIBUTION_ROULETTE_FRACTION;
        if r > 0.0 {
            s = s.max(c[ch] / r);
        } else if c[ch] > 0.0 {
            return 1.0;
        }
    }
    if s.is_nan() {
        return 1.0;
    }
    s.clamp(CONTRIBUTION_ROULETTE_FLOOR, 1.0)
}

/// Radiance arriving from lights hit by a sampled ray (sphere light `shape` or escaped rays),
/// MIS-weighted against the previous vertex's NEE. With `after_manifold` (the ray refracted
/// out of a `manifold` object straight from an interior vertex), the lights the manifold
/// connection samples (sphere and distant lights) give nothing: that connection alone
/// accounts for those paths (`super::manifold`).
pub(super) fn emitted(
    scene: &Scene,
    dir: Vec3,
    prev: &PrevVertex,
    sphere_light: Option<(usize, Vec3)>,
    after_manifold: bool,
    per_layer: &mut [Rgb; MAX_LIGHT_LAYERS],
) -> Rgb {
    let mut to_layer = |li: usize, value: Rgb| {
        if let Some(Some(slot)) = scene.light_layers.get(li) {
            if let Some(l) = per_layer.get_mut(*slot as usize) {
                *l += value;
            }
        }
        value
    };
    let weight = |li: usize, light_point: Option<Vec3>| -> f32 {
        if !prev.did_nee {
            return 1.0;
        }
        let light = &scene.lights[li];
        match prev.guided {
            None => {
                let light_pdf = scene.nee_light_sampler.probability(li) * light.pdf_li(prev.p, dir);
                power_heuristic(prev.pdf, light_pdf)
            }
            Some(g) => {
                let light_pdf = scene.light_sampler.probability(li) * light.pdf_li(prev.p, dir);
                // The guided connection samples sphere-light points visible from x only.
                let seen_from_x = match (light, light_point) {
                    (crate::light::Light::Sphere { center, .. }, Some(l)) => {
                        (l - *center).dot(g.x - l) > 0.0
                    }
                    _ => true,
                };
                let q_connect = if seen_from_x {
                    light_pdf * g.reverse_pdf
                } else {
                    0.0
                };
                power_heuristic(g.phase_pdf * prev.pdf, q_connect)
            }
        }
    };
    match sphere_light {
        Some(_) if after_manifold => Rgb::ZERO,
        Some((li, point)) => {
            if let crate::light::Light::Sphere { radiance, .. } = &scene.lights[li] {
                let w = if prev.did_nee {
                    weight(li, Some(point))
                } else {
                    1.0
                };
                to_layer(li, *radiance * w)
            } else {
                Rgb::ZERO
            }
        }
        None => {
            let mut l = Rgb::ZERO;
            for (li, light) in scene.lights.iter().enumerate() {
                if light.is_infinite()
                    && !(after_manifold && super::manifold::is_manifold_light(light))
                {
                    let le = light.escaped_radiance(dir);
                    if !le.is_black() {
                        // Without NEE at the previous vertex the weight is 1: decided here,
                        // without calling the weight's closure.
                        let w = if prev.did_nee { weight(li, None) } else { 1.0 };
                        l += to_layer(li, le * w);
                    }
                }
            }
            l
        }
    }
}

/// The lean's play probability per unit of the vertex's sun transmittance estimate
/// ([`SunLean::play_probability`]): chosen on the dense peer cloud (docs/BENCHMARKS.md, "The
/// sun lean played by chance").
const LEAN_PLAY_PER_TRANSMITTANCE: f32 = 5.0;

/// The lean's smallest play probability ([`SunLean::play_probability`]): where the vertex's
/// own sun shadow ray came back black (mostly ended by its Russian roulette).
const LEAN_PLAY_FLOOR: f32 = 0.3;

/// The predicted sun transmittance (largest channel) below which the sun's shadow rays from
/// a medium vertex are rouletted before they are traced ([`SunLean::shadow_survival`]):
/// chosen on the dense peer cloud (docs/BENCHMARKS.md, "Shadow rays to the sun rouletted by a
/// predicted transmittance").
const SHADOW_ROULETTE_TRANSMITTANCE: f32 = 0.1;

/// The smallest survival probability of that roulette: where the prediction is far below the
/// ray's true transmittance, a survivor's weight stays at most 20.
const SHADOW_ROULETTE_FLOOR: f32 = 0.05;

/// The sun-leaned estimate of second-vertex sun light (`sun_lean` in a medium's `tracking`
/// table). In an optically thin, forward-scattering medium under a sun, most of the image's
/// noise is the sun's NEE at the vertex *after* a medium vertex: it is large only where the
/// ray between the two runs towards the sun (the sun then lies in the second vertex's forward
/// peak), a direction the phase sampling rarely picks. So at each medium vertex one extra
/// direction is drawn from a Henyey–Greenstein lobe of the vertex's own `g` centred on the
/// sun, a free flight follows it to the interior's boundary, and where it collides the sun's
/// NEE there is added; that path and the main path's own next vertex both estimate the
/// same sun light, and the two are combined with the balance heuristic over the direction
/// between the vertices (Veach 1997, §9.2): weight q/(q + p) for the leaned ray, p/(p + q)
/// for the main path's sun NEE at its next vertex when reached in the same interior, where p
/// is the phase pdf and q the leaned lobe's. Unbiased; it costs one extra free flight per
/// medium vertex and a shadow ray where that flight collides. The lean is played only with a
/// probability P ([`SunLean::play_probability`]) and its estimate divided by P; q is then
/// replaced by P·q in both weights. The NEE at the leaned collision takes the sun with
/// probability 1 (it estimates the sun's part alone).
#[derive(Clone, Copy, Debug)]
pub(super) struct SunLean {
    /// Unit direction from the scene towards the light.
    to_light: Vec3,
    /// The light's index in the scene.
    pub light: usize,
}

impl SunLean {
    /// The lean towards the scene's brightest delta sun (found at load,
    /// [`Scene::brightest_delta_sun`]); `None` when the scene has none.
    pub(super) fn for_scene(scene: &Scene) -> Option<SunLean> {
        let li = scene.brightest_delta_sun?;
        match scene.lights.get(li) {
            Some(crate::light::Light::Distant { to_light, .. }) => Some(SunLean {
                to_light: *to_light,
                light: li,
            }),
            _ => None,
        }
    }

    /// Unit direction towards the light.
    #[inline]
    pub(super) fn to_light(self) -> Vec3 {
        self.to_light
    }

    /// The survival probability of a shadow ray to the sun from a point whose transmittance
    /// towards it is predicted (not estimated) as `predicted`
    /// ([`crate::medium::Medium::sun_transmittance_hint`]): `predicted /
    /// SHADOW_ROULETTE_TRANSMITTANCE` clamped to [`SHADOW_ROULETTE_FLOOR`, 1]. Deep in a dense
    /// cloud most sun rays come back (nearly) black, and half of them used to be ended by
    /// ratio tracking's own roulette only after their walk and several lookups; this one
    /// decides before the walk. Unbiased (the survivors are divided by it) whatever the
    /// prediction's error, which costs variance only.
    #[inline]
    pub(super) fn shadow_survival(predicted: f32) -> f32 {
        (predicted / SHADOW_ROULETTE_TRANSMITTANCE).clamp(SHADOW_ROULETTE_FLOOR, 1.0)
    }

    /// Balance weight p/(p + P·q) of the main path's direction `wi` (sampled from `phase` at
    /// a vertex with outgoing direction `wo`), where the lean was played with probability
    /// `play` = P.
    #[inline]
    pub(super) fn main_weight(&self, phase: &PhaseFunction, wo: Vec3, wi: Vec3, play: f32) -> f32 {
        let p = phase.pdf(wo, wi);
        let q = play * phase.pdf(-self.to_light, wi);
        if p + q > 0.0 {
            p / (p + q)
        } else {
            1.0
        }
    }

    /// Draws the leaned direction at a vertex with outgoing direction `wo`, the lean played
    /// with probability `play` = P: returns (direction, phase value / q, balance weight
    /// P·q/(p + P·q)), or `None` for a zero pdf (the caller divides by P).
    pub(super) fn sample(
        &self,
        phase: &PhaseFunction,
        wo: Vec3,
        play: f32,
        sampler: &mut PixelSampler,
    ) -> Option<(Vec3, f32, f32)> {
        let wi = phase.sample_direction(-self.to_light, sampler.next_2d());
        let q = phase.pdf(-self.to_light, wi);
        // The phase value is its pdf (`PhaseFunction::pdf` is `eval`).
        let p = phase.pdf(wo, wi);
        (q > 0.0 && q.is_finite()).then_some((wi, p / q, play * q / (p + play * q)))
    }

    /// The probability with which the lean is played at a vertex whose own sun NEE estimated
    /// the transmittance to the sun as `seen` (its largest channel; `None` when that NEE
    /// picked another light): `LEAN_PLAY_PER_TRANSMITTANCE · seen` clamped to
    /// [`LEAN_PLAY_FLOOR`, 1], and 1 for `None`. Where the sun is hidden from the vertex it
    /// is mostly hidden from the leaned collision a mean free path away as well, and the lean
    /// pays little for its flight and shadow ray. The played estimate is divided by this
    /// probability, and the balance heuristic weighs the lean's pdf by it (the expected number
    /// of leaned samples), at the vertex and at the path's next vertex alike: unbiased for any
    /// probability in (0, 1] that does not depend on the two directions.
    #[inline]
    pub(super) fn play_probability(seen: Option<f32>) -> f32 {
        match seen {
            Some(t) if t * LEAN_PLAY_PER_TRANSMITTANCE >= LEAN_PLAY_FLOOR => {
                (t * LEAN_PLAY_PER_TRANSMITTANCE).min(1.0)
            }
            Some(_) => LEAN_PLAY_FLOOR,
            None => 1.0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::medium::RayFootprint;
    use crate::scene::load_scene_str;

    /// A sky and a 3° sun over an absorbing, scattering ball whose boundary lets shadow rays
    /// through (an index-matched dielectric): NEE from a point inside it.
    const BALL: &str = r#"
[camera]
eye = [0.0, 0.0, 5.0]
look_at = [0.0, 0.0, 0.0]
fov = 30
[film]
width = 4
height = 4
spp = 1
[[light]]
type = "environment"
radiance = [0.3, 0.3, 0.35]
[[light]]
type = "distant"
direction = [-0.45, 0.75, 0.5]
irradiance = [3.2, 3.0, 2.8]
angular_radius = 3.0
[[object]]
name = "ball"
shape = "sphere"
center = [0.0, 0.0, 0.0]
radius = 1.0
surface = { type = "dielectric", ior = 1.0 }
interior = { type = "homogeneous", albedo = [0.8, 0.5, 0.2], albedo_mode = "single", attenuation = [0.5, 1.0, 2.0], nee = "interior" }
"#;

    /// Mean and variance of the mean, per channel, of `n` NEE estimates from a point inside
    /// the ball with a narrow lobe at the sun's centre (value up to ~5 within 1° of it, 0.05
    /// elsewhere), sampler seed `seed`, and the fraction of shadow rays the roulette ended.
    fn estimates(survival: ShadowRoulette, seed: u64, n: u32) -> ([f64; 3], [f64; 3], f64) {
        let scene = load_scene_str(BALL, std::path::Path::new("ball.toml"))
            .unwrap_or_else(|e| panic!("scene: {e}"));
        let axis = Vec3::new(-0.45, 0.75, 0.5).normalize();
        let p = Vec3::new(0.2, -0.1, 0.3);
        let mut stack = InteriorStack::new();
        stack.push(0);
        let mut stats = TraceStats::default();
        let (mut sum, mut sq, mut ended) = ([0.0f64; 3], [0.0f64; 3], 0u32);
        for i in 0..n {
            let mut sampler = PixelSampler::new(seed, 0, 0, i);
            sampler.start_vertex();
            let mut chosen = None;
            let mut seen = None;
            let c = estimate_direct(
                &scene,
                p,
                |_| (p, stack),
                |wi| {
                    let lobe = (20_000.0 * (wi.dot(axis) - 1.0)).exp();
                    (Rgb([0.9, 0.5, 0.2]) * (0.05 + 5.0 * lobe), 0.3)
                },
                ShadowMode::Transparent,
                RayFootprint::POINT,
                &mut sampler,
                &mut stats,
                &mut chosen,
                None,
                &mut seen,
                survival,
            );
            if seen == Some(0.0) && c.is_black() {
                ended += 1;
            }
            for ch in 0..3 {
                let v = f64::from(c[ch]);
                sum[ch] += v;
                sq[ch] += v * v;
            }
        }
        let n = f64::from(n);
        let mean = sum.map(|s| s / n);
        let var = [0, 1, 2].map(|ch| (sq[ch] / n - mean[ch] * mean[ch]) / n);
        (mean, var, f64::from(ended) / n)
    }

    #[test]
    fn shadow_rays_rouletted_by_contribution_keep_the_estimate_unbiased() {
        let n = 40_000;
        let (plain, plain_var, none_ended) = estimates(ShadowRoulette::Off, 11, n);
        // A path that has gathered 3 already: the rays off the lobe (about 0.15) survive with
        // about a tenth, the ones on it always.
        let (rr, rr_var, ended) = estimates(
            ShadowRoulette::Contribution {
                beta: Rgb::ONE,
                reference: Rgb([3.0, 2.0, 1.0]),
            },
            12,
            n,
        );
        eprintln!("shadow rays ended by the roulette: {ended}");
        assert_eq!(none_ended, 0.0);
        assert!(ended > 0.3, "the roulette ended only {ended} of the rays");
        for ch in 0..3 {
            let z = (rr[ch] - plain[ch]) / (rr_var[ch] + plain_var[ch]).sqrt();
            eprintln!(
                "channel {ch}: plain {:.5} ± {:.5}, rouletted {:.5} ± {:.5}, z {z:+.2}",
                plain[ch],
                plain_var[ch].sqrt(),
                rr[ch],
                rr_var[ch].sqrt()
            );
            assert!(z.abs() < 4.0, "channel {ch}: z = {z}");
        }
    }

    #[test]
    fn contribution_survival_follows_the_largest_channel_against_the_gathered_radiance() {
        let r = Rgb([1.0, 1.0, 0.0]);
        // Nothing gathered yet in a channel the ray would light: always traced.
        assert_eq!(contribution_survival(Rgb([0.0, 0.0, 0.01]), r), 1.0);
        let s = contribution_survival(Rgb([0.1, 0.2, 0.0]), r);
        assert!((s - 0.2 / CONTRIBUTION_ROULETTE_FRACTION).abs() < 1e-6);
        assert_eq!(
            contribution_survival(Rgb([1e-6, 0.0, 0.0]), r),
            CONTRIBUTION_ROULETTE_FLOOR
        );
        assert_eq!(contribution_survival(Rgb([5.0, 0.0, 0.0]), r), 1.0);
    }
}
