//! Guided connections through a rough dielectric boundary (`nee = "exit_guided"`).
//!
//! Exit-point NEE evaluates the boundary BTDF `f(wo, wl)` for the direction `wo` the random
//! walk happened to arrive with; behind a rough dielectric of small roughness that lobe is
//! narrow, so only the few walks arriving near the refracted light direction contribute
//! (high variance whatever the light sampling does). The guided connection instead works
//! from each interior scattering vertex `x`: it samples a light direction `u`, then samples
//! the inside direction `d` to the boundary by sampling the boundary BSDF *from the light's
//! side* (`Surface::sample` with `wo = u`, i.e. the microfacet transmission lobe of Walter
//! et al. 2007, "Microfacet Models for Refraction through Rough Surfaces", eq. 15–17, run
//! from the light), traces `x → y` and evaluates the exact path contribution
//! `phase(d) · T(x, y) · f(y; −d, wl) |cos| · Le`. This is the light-aware BTDF sampling
//! (half vectors that refract towards the light) placed where the freedom is: at `x`.
//!
//! The frame of that lobe is the boundary normal `n0` where the ray `x + t u` leaves the
//! interior (a probe ray), since the exit point `y` is not known before `d` is. The density
//! of `d` is a defensive mixture `(1 − ε) p_bsdf(d | u, n0) + ε / 4π` (Hesterberg 1995), so
//! every direction can be sampled whatever `n0` is; the estimator divides by that exact
//! density, hence it is unbiased for any `n0`.
//!
//! The path `x → y → light` can also be produced by BTDF sampling at the exit vertex `y`
//! (the walk's own phase sample reaches `y`, the BTDF sample hits the light). The two are
//! combined by MIS (Veach 1997) with power-heuristic weights computed from the path alone,
//! `q_connect = p_light(wl | y) · p_bsdf(−d | wl, n_y)` against
//! `q_walk = p_phase(d) · p_bsdf(wl | −d, n_y)`: any weights that sum to one over the
//! strategies able to sample a path keep the sum unbiased (Veach 1997, §9.2), and these
//! approximate the true densities (the probe normal `n0` replaced by `n_y`, the
//! transmittance factors omitted). Exit-point NEE is not done at such exit vertices; it
//! remains for exit vertices reached otherwise (internal reflections, unscattered flights).

// Comparisons are written `!(x > 0.0)` on purpose: they also reject NaN.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

use super::direct::{shadow_transmittance, ShadowMode};
use super::interiors::{boundary_surface, is_false_intersection, InteriorStack};
use super::TraceStats;
use crate::geometry::Hit;
use crate::light::Light;
use crate::math::{Frame, Ray, Vec3};
use crate::medium::{Medium, PreparedPhase};
use crate::sampling::{power_heuristic, PixelSampler};
use crate::scene::{Scene, ShapeOwner};
use crate::spectrum::Rgb;

/// Probability of the uniform-sphere component of the direction mixture.
const DEFENSIVE: f32 = 0.1;

/// Russian roulette on the connection (after the probe): it is made with probability
/// `clamp(T(x, probe exit) / ROULETTE_TRANSMITTANCE, ROULETTE_MIN, 1)` (max over channels),
/// and weighted by the inverse. Deep vertices, whose connections carry almost nothing, then
/// rarely pay for the connection and shadow rays.
const ROULETTE_TRANSMITTANCE: f32 = 0.1;

/// Lowest connection probability of the roulette (also used when the probe finds no exit).
const ROULETTE_MIN: f32 = 0.05;

/// Uniform solid-angle density on the sphere.
const UNIFORM_SPHERE_PDF: f32 = 1.0 / (4.0 * std::f32::consts::PI);

/// True when `hit`, on a ray with direction `dir` from inside object `oi` (stack `stack`),
/// is a real boundary of `oi` that the ray leaves through.
fn leaves_through(scene: &Scene, stack: &InteriorStack, oi: u32, hit: &Hit, dir: Vec3) -> bool {
    scene.shape_owner[hit.shape as usize] == ShapeOwner::Object(oi)
        && dir.dot(hit.ng) > 0.0
        && !is_false_intersection(scene, stack, oi, false)
}

/// The guided connection from interior vertex `x` of object `oi` (filled with `medium`)
/// through its boundary to a light: the MIS-weighted contribution, without the path
/// throughput. Zero when the boundary is smooth (delta) or absent.
#[allow(clippy::too_many_arguments)]
pub(super) fn guided_connection(
    scene: &Scene,
    oi: u32,
    medium: &Medium,
    x: Vec3,
    phase: &PreparedPhase<'_>,
    stack: InteriorStack,
    sampler: &mut PixelSampler,
    stats: &mut TraceStats,
    chosen: &mut Option<usize>,
) -> Rgb {
    let obj = &scene.objects[oi as usize];
    let outside_ior = stack.ior(&scene.objects, Some(oi));
    let Some(surface) = boundary_surface(obj, outside_ior) else {
        return Rgb::ZERO;
    };
    if surface.is_delta() {
        return Rgb::ZERO;
    }
    let u_light = sampler.next_1d();
    let u_dir = sampler.next_2d();
    let u_mix = sampler.next_1d();
    let u_lobe = sampler.next_1d();
    let u_m = sampler.next_2d();
    let u_rr = sampler.next_1d();
    let Some((li, p_sel)) = scene.light_sampler.sample(u_light) else {
        return Rgb::ZERO;
    };
    *chosen = Some(li);
    let light = &scene.lights[li];
    let Some(ls) = light.sample_li(x, u_dir) else {
        return Rgb::ZERO;
    };
    if !(ls.pdf > 0.0) || ls.radiance.is_black() {
        return Rgb::ZERO;
    }
    let u = ls.wi;

    // The probe: the boundary normal where x + t u leaves the interior frames the lobe.
    stats.rays += 1;
    let probe = scene
        .geometry
        .intersect(&Ray::new(x, u), f32::INFINITY)
        .filter(|h| leaves_through(scene, &stack, oi, h, u));
    let frame0 = probe.as_ref().map(|h| Frame::from_normal(h.ns));
    let q = match &probe {
        Some(h) => {
            let tr = medium.transmittance(
                &Ray::new(x, u),
                h.t,
                &mut || sampler.next_1d(),
                &mut stats.tracking,
            );
            (tr.max_component() / ROULETTE_TRANSMITTANCE).clamp(ROULETTE_MIN, 1.0)
        }
        None => ROULETTE_MIN,
    };
    if !(u_rr < q) {
        return Rgb::ZERO;
    }

    // The inside direction d (x → boundary), from the mixture.
    let d = match frame0 {
        Some(f0) if u_mix >= DEFENSIVE => {
            let Some(s) = surface.sample(f0.to_local(u), u_lobe, u_m) else {
                return Rgb::ZERO;
            };
            if s.is_delta {
                return Rgb::ZERO;
            }
            -f0.to_world(s.wi).normalize()
        }
        _ => crate::sampling::sample_uniform_sphere(u_m),
    };
    let p_lobe = frame0.map_or(0.0, |f0| surface.pdf(f0.to_local(u), f0.to_local(-d)));
    let p_d = match frame0 {
        Some(_) => (1.0 - DEFENSIVE) * p_lobe + DEFENSIVE * UNIFORM_SPHERE_PDF,
        None => UNIFORM_SPHERE_PDF,
    };
    if !(p_d > 0.0) {
        return Rgb::ZERO;
    }
    let (ph, ph_pdf) = phase.eval(d);
    if ph.is_black() {
        return Rgb::ZERO;
    }

    // x → y: the first hit must be where the ray leaves the interior.
    stats.rays += 1;
    let Some(y) = scene.geometry.intersect(&Ray::new(x, d), f32::INFINITY) else {
        return Rgb::ZERO;
    };
    if !leaves_through(scene, &stack, oi, &y, d) {
        return Rgb::ZERO;
    }

    // y → light: the light point sampled from x, seen from y.
    let (wl, distance, jacobian) = match (light, ls.distance.is_finite()) {
        (Light::Sphere { center, .. }, true) => {
            let l = x + u * ls.distance;
            let to_l = l - y.p;
            let dist2 = to_l.length_squared();
            let Some(wl) = to_l.try_normalize() else {
                return Rgb::ZERO;
            };
            let nl = (l - *center).normalize();
            let cos_y = -nl.dot(wl);
            let cos_x = -nl.dot(u);
            if !(cos_y > 0.0) || !(cos_x > 0.0) {
                return Rgb::ZERO;
            }
            // Area measure at the light: sampled from x, integrated from y.
            let j = (cos_y / dist2) / (cos_x / (ls.distance * ls.distance));
            (wl, dist2.sqrt(), j)
        }
        _ => (u, f32::INFINITY, 1.0),
    };
    let frame = Frame::from_normal(y.ns);
    let wo_local = frame.to_local(-d);
    let wl_local = frame.to_local(wl);
    if !(wl.dot(y.ng) > 0.0) || !(wl_local.z > 0.0) || !(wo_local.z < 0.0) {
        return Rgb::ZERO;
    }
    let f = surface.eval(wo_local, wl_local) * wl_local.z.abs();
    if f.is_black() {
        return Rgb::ZERO;
    }
    let tr_medium = medium.transmittance(
        &Ray::new(x, d),
        y.t,
        &mut || sampler.next_1d(),
        &mut stats.tracking,
    );
    if tr_medium.is_black() {
        return Rgb::ZERO;
    }
    let mut outside = stack;
    outside.remove(oi);
    let light_shape = scene
        .shape_owner
        .iter()
        .position(|o| *o == ShapeOwner::Light(li as u32))
        .map(|s| s as u32);
    let shadow_distance = if distance.is_finite() {
        distance * (1.0 - 1e-4)
    } else {
        f32::INFINITY
    };
    let tr_shadow = shadow_transmittance(
        scene,
        y.spawn_origin(wl),
        wl,
        shadow_distance,
        outside,
        ShadowMode::Opaque,
        crate::medium::RayFootprint::POINT,
        light_shape,
        sampler,
        stats,
    );
    if tr_shadow.is_black() {
        return Rgb::ZERO;
    }
    let w = if ls.is_delta {
        1.0
    } else {
        let q_connect = p_sel * light.pdf_li(y.p, wl) * surface.pdf(wl_local, wo_local);
        let q_walk = ph_pdf * surface.pdf(wo_local, wl_local);
        power_heuristic(q_connect, q_walk)
    };
    ph * tr_medium * f * tr_shadow * ls.radiance * (w * jacobian / (q * p_sel * ls.pdf * p_d))
}
