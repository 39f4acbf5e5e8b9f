//! Manifold next event estimation (`nee = "manifold"`; Hanika, Droske and Fascione 2015,
//! "Manifold next event estimation"; docs/references.md §5): direct light at interior
//! vertices behind a **smooth** dielectric boundary: the object's own, or, for a region
//! without a surface inside such an object (an iris in an eye), the enclosing one. The
//! interface is the first boundary the straight line to the light meets that is not null,
//! false or index-matched (`interface.rs`).
//!
//! Behind a smooth boundary neither exit-point NEE (the boundary is a delta lobe) nor
//! transparent shadows (which ignore refraction) can connect to a light: only phase-function
//! sampling that happens to refract into a finite light does, which is very noisy for small
//! lights. From an interior vertex `x0`, MNEE samples a light point `x2` (a sphere light) or
//! a direction (a sun disc, or a delta distant light), solves for the refraction point `x1`
//! on the boundary ([`solve`]), and evaluates
//!
//! `phase(x0; w_01) · T(x0, x1) · (1 − F) · tint · η² · T(x1, x2) · Le · G / p(x2)`
//!
//! with `G` the generalised geometry term (`dω0/dA(x2)`, or `dω0/dω_L`), `F` the Fresnel
//! reflectance at the solved configuration, `η = n_inside / n_outside` (the η² of the smooth
//! BTDF's radiance scaling, so that both estimators carry the same factor), `T(x0, x1)` the
//! interior's transmittance estimator and `T(x1, x2)` a shadow ray outside.
//!
//! **Light points.** The refraction point is not known when the light point is drawn, so a
//! sphere light's point comes from a defensive mixture: with probability `1 − ε` the cone
//! of the light seen from `x0` (the cap `x0` sees), with `ε` the whole sphere uniformly by
//! area; the estimator divides by the mixture's area density, so caps seen from `x1` but not
//! from `x0` are covered too (Hesterberg 1995).
//!
//! **Roulette.** After the seed, the walk is made with probability `min(1, T/0.1)` (at least
//! 0.05) of the transmittance `T` along the straight line to the first boundary, and weighted by
//! the inverse: deep vertices of dense media rarely pay for a walk whose result they would
//! almost entirely absorb.
//!
//! **No double counting.** MNEE has no tractable pdf for MIS, so the paths it samples are
//! given to it alone: a unidirectional path that scatters at an interior vertex of a
//! `manifold` interior, reaches that object's boundary straight (first hit), refracts out by
//! the smooth lobe and then reaches a sphere light or a distant light without another
//! scattering event (null and false boundaries aside, as for the shadow ray) contributes
//! nothing (`PathState::manifold_leg`). Those are exactly the paths `x0 → x1 → light`
//! MNEE integrates over; paths with internal reflections, other specular vertices, or that
//! end on an environment keep their unidirectional contribution.
//!
//! **Bias.** One seed (the straight line's crossing) finds one solution: where several
//! refraction points connect `x0` to the same light point, the others are missed, and
//! connections whose walk fails are lost (counted in [`ManifoldStats`]); docs/references.md
//! §5.6 and docs/choosing-estimators.md give the measured size.

mod interface;
pub mod solve;

pub(super) use interface::is_manifold_interface;
pub use solve::{Failure, Interface, InterfacePoint, LightTarget, Solution, SolverSettings};

use glam::DVec3;

use super::direct::{shadow_transmittance, ShadowMode};
use super::interiors::{current_medium, InteriorStack};
use super::TraceStats;
use crate::bsdf::fresnel::fresnel_dielectric;
use crate::light::Light;
use crate::math::{offset_ray_origin, Ray, Vec3};
use crate::medium::PreparedPhase;
use crate::sampling::{sample_uniform_sphere, PixelSampler};
use crate::scene::{Scene, ShapeOwner};
use crate::spectrum::Rgb;
use interface::SceneInterface;

/// Probability of sampling a sphere light's point uniformly over its whole area (the
/// defensive component of the light-point mixture).
const UNIFORM_AREA: f32 = 0.1;

/// Russian roulette on the walk (after the seed): it is made with probability
/// `clamp(T / ROULETTE_TRANSMITTANCE, ROULETTE_MIN, 1)` (max over channels, `T` the
/// vertex's medium's transmittance along the straight line to its first boundary) and weighted
/// by the inverse; deep vertices of dense media, whose connections carry almost nothing,
/// then rarely pay for the walk (as for `exit_guided`'s connections).
const ROULETTE_TRANSMITTANCE: f32 = 0.1;

/// Lowest walk probability of the roulette.
const ROULETTE_MIN: f32 = 0.05;

/// Counters of the manifold walks (summed over a render, printed in its summary).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ManifoldStats {
    /// Connections attempted towards a finite light (sphere or distant).
    pub attempts: u64,
    /// Walks that converged to a valid refracted connection.
    pub solved: u64,
    /// No seed: the straight line to the light leaves through another surface.
    pub seed: u64,
    /// Newton's method did not converge.
    pub no_convergence: u64,
    /// Total internal reflection at the walk's last point.
    pub total_internal_reflection: u64,
    /// Converged to a reflection-side point, or a light point facing away.
    pub wrong_side: u64,
    /// Singular constraint derivative (caustic fold).
    pub singular: u64,
    /// Newton iterations over all solved walks.
    pub iterations: u64,
    /// Walks skipped by the roulette on the transmittance to the seed (not failures).
    pub roulette: u64,
    /// Solved connections with no transmittance between the vertex and the refraction point.
    pub blocked_inside: u64,
    /// Solved connections whose shadow ray from the refraction point to the light is blocked.
    pub blocked_outside: u64,
}

impl ManifoldStats {
    /// Adds `o` into `self`.
    pub fn merge(&mut self, o: &ManifoldStats) {
        self.attempts += o.attempts;
        self.solved += o.solved;
        self.seed += o.seed;
        self.no_convergence += o.no_convergence;
        self.total_internal_reflection += o.total_internal_reflection;
        self.wrong_side += o.wrong_side;
        self.singular += o.singular;
        self.iterations += o.iterations;
        self.roulette += o.roulette;
        self.blocked_inside += o.blocked_inside;
        self.blocked_outside += o.blocked_outside;
    }

    /// Walks that did not give a connection.
    #[must_use]
    pub fn failures(&self) -> u64 {
        self.seed
            + self.no_convergence
            + self.total_internal_reflection
            + self.wrong_side
            + self.singular
    }

    fn count(&mut self, f: Failure) {
        match f {
            Failure::Seed => self.seed += 1,
            Failure::NoConvergence => self.no_convergence += 1,
            Failure::TotalInternalReflection => self.total_internal_reflection += 1,
            Failure::WrongSide => self.wrong_side += 1,
            Failure::Singular => self.singular += 1,
        }
    }
}

impl std::fmt::Display for ManifoldStats {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        // Rates among the walks made (no-seed failures happen before the roulette).
        let walks = self.attempts.saturating_sub(self.roulette).max(1);
        let pct = |n: u64| 100.0 * n as f64 / walks as f64;
        write!(
            f,
            "{} connections, {:.2} % skipped by roulette; of the walks made, {:.2} % solved ({:.2} iterations each); failed: {:.2} % no seed, {:.2} % no convergence, {:.2} % total internal reflection, {:.2} % wrong side, {:.2} % singular; of the solved, {:.2} % blocked inside, {:.2} % shadowed outside",
            self.attempts,
            100.0 * self.roulette as f64 / self.attempts.max(1) as f64,
            pct(self.solved),
            self.iterations as f64 / self.solved.max(1) as f64,
            pct(self.seed),
            pct(self.no_convergence),
            pct(self.total_internal_reflection),
            pct(self.wrong_side),
            pct(self.singular),
            100.0 * self.blocked_inside as f64 / self.solved.max(1) as f64,
            100.0 * self.blocked_outside as f64 / self.solved.max(1) as f64
        )
    }
}

/// True for the lights MNEE connects to (and that unidirectional paths through a manifold
/// boundary therefore must not count): sphere lights and distant lights.
#[must_use]
pub(super) fn is_manifold_light(light: &Light) -> bool {
    matches!(light, Light::Sphere { .. } | Light::Distant { .. })
}

fn v64(v: Vec3) -> DVec3 {
    DVec3::new(f64::from(v.x), f64::from(v.y), f64::from(v.z))
}

fn v32(v: DVec3) -> Vec3 {
    Vec3::new(v.x as f32, v.y as f32, v.z as f32)
}

/// A light sampled for a manifold connection: where it is, its radiance (irradiance for a
/// delta distant light) and the density of the sample (area density for a light point,
/// solid angle for a direction, 1 for a delta light).
struct LightDraw {
    target: LightTarget,
    radiance: Rgb,
    pdf: f32,
}

/// Samples light `light` for a connection from `x`.
fn draw_light(light: &Light, x: Vec3, u: crate::math::Vec2, u_mix: f32) -> Option<LightDraw> {
    match light {
        Light::Sphere {
            center,
            radius,
            radiance,
        } => {
            let point = if u_mix < UNIFORM_AREA {
                *center + sample_uniform_sphere(u) * *radius
            } else {
                let ls = light.sample_li(x, u)?;
                x + ls.wi * ls.distance
            };
            let n = (point - *center).try_normalize()?;
            // The mixture's area density at `point`.
            let area = 4.0 * crate::math::PI * radius * radius;
            let to = point - x;
            let d2 = to.length_squared();
            let dir = to / d2.sqrt();
            let cos_l = -n.dot(dir);
            let cap = if cos_l > 0.0 {
                light.pdf_li(x, dir) * cos_l / d2
            } else {
                0.0
            };
            let pdf = (1.0 - UNIFORM_AREA) * cap + UNIFORM_AREA / area;
            (pdf > 0.0 && pdf.is_finite()).then(|| LightDraw {
                target: LightTarget::Point {
                    p: v64(point),
                    n: v64(n),
                },
                radiance: *radiance,
                pdf,
            })
        }
        Light::Distant { .. } => {
            let ls = light.sample_li(x, u)?;
            (ls.pdf > 0.0).then(|| LightDraw {
                target: LightTarget::Direction(v64(ls.wi).normalize()),
                radiance: ls.radiance,
                pdf: ls.pdf,
            })
        }
        Light::ConstantEnvironment { .. } | Light::EnvironmentMap(_) => None,
    }
}

/// The manifold connection from interior vertex `x` (interior stack `stack`) to a light: the
/// contribution without the path throughput. The interface is the first real boundary the
/// straight line from `x` to the light meets (through null and false boundaries, whose media's
/// transmittance is included); it must be a smooth refractive dielectric the line leaves.
/// Zero when the chosen light is an environment (reached by unidirectional paths instead) or
/// the walk fails.
pub(super) fn manifold_connection(
    scene: &Scene,
    x: Vec3,
    phase: &PreparedPhase<'_>,
    stack: InteriorStack,
    sampler: &mut PixelSampler,
    stats: &mut TraceStats,
    chosen: &mut Option<usize>,
) -> Rgb {
    let u_light = sampler.next_1d();
    let u = sampler.next_2d();
    let u_mix = sampler.next_1d();
    let u_rr = sampler.next_1d();
    let Some((li, p_sel)) = scene.light_sampler.sample(u_light) else {
        return Rgb::ZERO;
    };
    *chosen = Some(li);
    let Some(light) = scene.lights.get(li) else {
        return Rgb::ZERO;
    };
    let Some(draw) = draw_light(light, x, u, u_mix) else {
        return Rgb::ZERO;
    };
    if draw.radiance.is_black() {
        return Rgb::ZERO;
    }
    stats.manifold.attempts += 1;
    let x0 = v64(x);
    let mut interface = SceneInterface::new(scene, &stack);
    let seed = interface.project(x0, draw.target.seed_target(x0));
    let (Some(seed), Some((ior_in, ior_out)), Some(oi)) =
        (seed, interface.iors(), interface.object)
    else {
        stats.rays += interface.rays;
        stats.manifold.count(Failure::Seed);
        return Rgb::ZERO;
    };
    let Some(tint) = scene
        .objects
        .get(oi as usize)
        .and_then(|o| interface::interface_tint(&o.surface, interface.uv))
    else {
        return Rgb::ZERO;
    };
    // The transmittance of the vertex's own medium up to the first boundary on the seed line.
    let dir_seed = (v32(seed.p) - x).normalize_or_zero();
    let mut scratch = None;
    let tr_seed = match current_medium(scene, &stack, &mut scratch) {
        Some((m, _)) => m.transmittance(
            &Ray::new(x, dir_seed),
            interface.seed_first_segment,
            &mut || sampler.next_1d(),
            &mut stats.tracking,
        ),
        None => Rgb::ONE,
    };
    let q = (tr_seed.max_component() / ROULETTE_TRANSMITTANCE).clamp(ROULETTE_MIN, 1.0);
    if !(u_rr < q) {
        stats.rays += interface.rays;
        stats.manifold.roulette += 1;
        return Rgb::ZERO;
    }
    let result = solve::solve_from_point(
        &mut interface,
        x0,
        seed,
        &draw.target,
        f64::from(ior_in),
        f64::from(ior_out),
        &SolverSettings::default(),
    );
    stats.rays += interface.rays;
    interface.rays = 0;
    let sol = match result {
        Ok(s) => s,
        Err(f) => {
            stats.manifold.count(f);
            return Rgb::ZERO;
        }
    };
    stats.manifold.solved += 1;
    stats.manifold.iterations += u64::from(sol.iterations);

    let w01 = v32(-sol.wa).normalize();
    let (ph, _) = phase.eval(w01);
    if ph.is_black() {
        return Rgb::ZERO;
    }
    // Fresnel seen from the light's side (outside), relative index n_inside / n_outside.
    let eta = ior_in / ior_out.max(1e-6);
    let cos_b = sol.wb.dot(sol.x1.ns) as f32;
    let transmit = tint * ((1.0 - fresnel_dielectric(cos_b, eta)) * eta * eta);
    if transmit.is_black() {
        return Rgb::ZERO;
    }
    // x0 → x1 through the media (and passable boundaries) on the way.
    let tr_inside = interface.transmittance(x, w01, &mut || sampler.next_1d(), &mut stats.tracking);
    stats.rays += interface.rays;
    if tr_inside.is_black() {
        stats.manifold.blocked_inside += 1;
        return Rgb::ZERO;
    }
    let mut outside = interface.inside;
    outside.remove(oi);
    let wb = v32(sol.wb).normalize();
    let origin = offset_ray_origin(v32(sol.x1.p), v32(sol.x1.ng), wb);
    let light_shape = scene
        .shape_owner
        .iter()
        .position(|o| *o == ShapeOwner::Light(li as u32))
        .map(|s| s as u32);
    let distance = if sol.lb.is_finite() {
        (sol.lb * (1.0 - 1e-4)) as f32
    } else {
        f32::INFINITY
    };
    let tr_outside = shadow_transmittance(
        scene,
        origin,
        wb,
        distance,
        outside,
        ShadowMode::Opaque,
        crate::medium::RayFootprint::POINT,
        light_shape,
        sampler,
        stats,
    );
    if tr_outside.is_black() {
        stats.manifold.blocked_outside += 1;
        return Rgb::ZERO;
    }
    let g = sol.geometry as f32;
    ph * tr_inside * transmit * tr_outside * draw.radiance * (g / (q * p_sel * draw.pdf))
}
