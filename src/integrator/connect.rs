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

use super::direct::{shadow_transmittance, ShadowMode};
use super::interiors::{boundary_surface_at, is_false_intersection, InteriorStack};
use super::{RayCone, TraceStats};
use std::borrow::Cow;

use crate::bsdf::Surface;
use crate::geometry::Hit;
use crate::light::Light;
use crate::math::{Frame, Ray, Vec2, Vec3};
use crate::medium::{Medium, PreparedPhase};
use crate::sampling::{power_heuristic, PixelSampler};
use crate::scene::{Object, ObjectSurface, Scene, ShapeOwner};
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

/// A blend's `u_mask` that picks its look `a` whatever the mask (masks are in [0, 1]).
const PICK_A: f32 = -1.0;

/// A blend's `u_mask` that picks its look `b` whatever the mask.
const PICK_B: f32 = 2.0;

/// The ray cone's footprint, in texture units, where a ray of direction `dir` from the
/// vertex the cone `cone` stands at meets `hit` on `obj`: the width the unidirectional walk
/// sees there when its flight from the vertex reaches `hit` (the cone advanced by the hit
/// distance, seen at the hit's cosine; see `PathState::footprint`). 0 for objects with
/// nothing textured.
fn footprint_at(obj: &Object, cone: RayCone, hit: &Hit, dir: Vec3) -> f32 {
    if obj.uv_scale > 0.0 {
        let mut c = cone;
        c.advance(hit.t);
        c.width_uv(obj.uv_scale_at(hit.prim), dir.dot(hit.ng))
    } else {
        0.0
    }
}

/// True when the boundary of `obj` (seen from a medium of IOR `outside_ior`) can have a
/// non-delta lobe somewhere: a textured roughness or coat weight at its largest texel, either
/// look of a blend. Untextured surfaces answer exactly as their one BSDF does.
fn may_be_rough(obj: &Object, outside_ior: f32) -> bool {
    rough_somewhere::<true>(obj, outside_ior)
}

/// [`may_be_rough`], with an untextured dielectric seen from air answered from the surface
/// built at load (`BORROW_IN_AIR`, the renderer's way) or built again for the query (the
/// general way, which the tests compare the borrowed answer against).
fn rough_somewhere<const BORROW_IN_AIR: bool>(obj: &Object, outside_ior: f32) -> bool {
    let look = |s: &ObjectSurface| -> bool {
        match s {
            // Untextured, seen from air: the surface every hit borrows.
            ObjectSurface::Dielectric(d)
                if BORROW_IN_AIR && outside_ior == 1.0 && d.in_air.is_some() =>
            {
                d.in_air.as_ref().is_some_and(|s| !s.is_delta())
            }
            ObjectSurface::Dielectric(d) => {
                let eta = d.ior / outside_ior.max(1e-6);
                let Ok(s) = Surface::dielectric(eta, d.roughness.max(), d.distribution, Rgb::ONE)
                else {
                    return false;
                };
                match &d.coat {
                    Some(c) => s
                        .with_prepared_coat(&c.coat, c.weight.max())
                        .is_ok_and(|s| !s.is_delta()),
                    None => !s.is_delta(),
                }
            }
            ObjectSurface::Fixed(s) => !s.is_delta(),
            // Diffuse transmission (never delta), or opaque (no interior is reached).
            ObjectSurface::Textured(_) => true,
            ObjectSurface::Blend(_) | ObjectSurface::Null => false,
        }
    };
    match &obj.surface {
        ObjectSurface::Blend(b) => look(&b.a) || look(&b.b),
        s => look(s),
    }
}

/// The non-delta BSDFs of the boundary at the probe point, with the probabilities the
/// direction mixture gives them: the surface there (its textured parameters read at the
/// probe's texture coordinates), or a blend's two looks weighted by the mask there (one look
/// when the other is delta). Empty when every lobe there is delta. Only a proposal: any
/// choice keeps the connection unbiased, since it divides by the density it sampled from.
struct ProbeLobes<'a> {
    lobes: [Option<(Cow<'a, Surface>, f32)>; 2],
}

impl<'a> ProbeLobes<'a> {
    fn at(obj: &'a Object, outside_ior: f32, uv: Vec2, width_uv: f32) -> Self {
        let rough = |u_mask: f32| {
            boundary_surface_at(obj, outside_ior, uv, width_uv, u_mask).filter(|s| !s.is_delta())
        };
        let ObjectSurface::Blend(b) = &obj.surface else {
            return ProbeLobes {
                lobes: [rough(0.0).map(|s| (s, 1.0)), None],
            };
        };
        let m = b.mask.eval(uv, width_uv);
        match (rough(PICK_A), rough(PICK_B)) {
            (Some(a), Some(b)) => ProbeLobes {
                lobes: [Some((a, m)), Some((b, 1.0 - m))],
            },
            (Some(s), None) | (None, Some(s)) => ProbeLobes {
                lobes: [Some((s, 1.0)), None],
            },
            (None, None) => ProbeLobes {
                lobes: [None, None],
            },
        }
    }

    fn is_empty(&self) -> bool {
        self.lobes[0].is_none()
    }

    /// The BSDF to sample with `u_lobe`, and `u_lobe` remapped to [0, 1) for its own use.
    fn choose(&self, u_lobe: f32) -> Option<(&Surface, f32)> {
        match &self.lobes {
            [Some((a, wa)), Some((b, _))] => Some(if u_lobe < *wa {
                (&**a, u_lobe / *wa)
            } else {
                (&**b, ((u_lobe - *wa) / (1.0 - *wa)).min(1.0))
            }),
            [Some((a, _)), None] => Some((&**a, u_lobe)),
            _ => None,
        }
    }

    /// The mixture's density of `wi` given `wo` (local to the probe frame).
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        match &self.lobes {
            [Some((a, _)), None] => a.pdf(wo, wi),
            [Some((a, wa)), Some((b, wb))] => *wa * a.pdf(wo, wi) + *wb * b.pdf(wo, wi),
            _ => 0.0,
        }
    }
}

/// The guided connection from interior vertex `x` of object `oi` (filled with `medium`)
/// through its boundary to a light: the MIS-weighted contribution, without the path
/// throughput. Zero when the boundary is smooth (delta) everywhere, or absent.
///
/// A textured boundary is read as the unidirectional walk reads it: at the exit point's
/// texture coordinates, with the footprint the path's ray cone `cone` (at `x`) has there;
/// a blend picks its look at the exit point with its own random number and probability
/// mask(uv), as the walk picks at each hit, and the MIS weights use that look's densities,
/// as the walk's light hits do (the mask's probability cancels in them).
#[allow(clippy::too_many_arguments)]
pub(super) fn guided_connection(
    scene: &Scene,
    oi: u32,
    medium: &Medium,
    x: Vec3,
    phase: &PreparedPhase<'_>,
    stack: InteriorStack,
    cone: RayCone,
    sampler: &mut PixelSampler,
    stats: &mut TraceStats,
    chosen: &mut Option<usize>,
) -> Rgb {
    let obj = &scene.objects[oi as usize];
    let outside_ior = stack.ior(&scene.objects, Some(oi));
    if !may_be_rough(obj, outside_ior) {
        return Rgb::ZERO;
    }
    let u_light = sampler.next_1d();
    let u_dir = sampler.next_2d();
    let u_mix = sampler.next_1d();
    let u_lobe = sampler.next_1d();
    let u_m = sampler.next_2d();
    let u_rr = sampler.next_1d();
    // Drawn only for blends: other surfaces keep their sample sequence (and images).
    let u_pick = if matches!(obj.surface, ObjectSurface::Blend(_)) {
        sampler.next_1d()
    } else {
        0.0
    };
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

    // The probe: the boundary where x + t u leaves the interior frames the lobe, and gives
    // the texture coordinates its parameters are read at.
    stats.rays += 1;
    let probe = scene
        .geometry
        .intersect(&Ray::new(x, u), f32::INFINITY)
        .filter(|h| leaves_through(scene, &stack, oi, h, u));
    let lobes = probe.as_ref().map_or(
        ProbeLobes {
            lobes: [None, None],
        },
        |h| ProbeLobes::at(obj, outside_ior, h.uv(), footprint_at(obj, cone, h, u)),
    );
    let frame0 = probe
        .as_ref()
        .filter(|_| !lobes.is_empty())
        .map(|h| Frame::from_normal(h.ns));
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
    let d = match (frame0, lobes.choose(u_lobe)) {
        (Some(f0), Some((surface, u_lobe))) if u_mix >= DEFENSIVE => {
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
    let p_lobe = frame0.map_or(0.0, |f0| lobes.pdf(f0.to_local(u), f0.to_local(-d)));
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
    // The boundary at y as the walk would see it arriving along d (its look picked there);
    // an untextured one is the probe's (built once: a coat's tables are costly).
    let at_y;
    let surface = match (&lobes.lobes[0], obj.surface.is_textured()) {
        (Some((s, _)), false) => &**s,
        _ => {
            let width_y = footprint_at(obj, cone, &y, d);
            match boundary_surface_at(obj, outside_ior, y.uv(), width_y, u_pick) {
                Some(s) => {
                    at_y = s;
                    &at_y
                }
                None => return Rgb::ZERO,
            }
        }
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn roughness_from_air_is_answered_as_the_built_surfaces_answer() {
        let scene = crate::scene::load_scene_str(
            super::super::interiors::DIELECTRICS,
            std::path::Path::new("d.toml"),
        )
        .expect("scene");
        let mut answers = [0; 2];
        for obj in &scene.objects {
            for outside_ior in [1.0, 1.33, 1.4, 1.5, 0.999_999_9] {
                let fast = may_be_rough(obj, outside_ior);
                assert_eq!(
                    fast,
                    rough_somewhere::<false>(obj, outside_ior),
                    "{} from outside IOR {outside_ior}",
                    obj.name
                );
                answers[usize::from(fast)] += 1;
            }
        }
        // Smooth and index-matched boundaries (delta) and rough ones both occur.
        assert!(answers[0] >= 5 && answers[1] >= 15, "{answers:?}");
    }
}
