//! The volumetric path tracer of the course notes' Algorithm 1 (§2.3): refraction through a
//! microfacet boundary into an interior, free-flight sampling with the RGB channel chosen by
//! throughput and one-sample MIS over channels (REFERENCES §4.6), phase-function sampling, and
//! next event estimation either at boundary (exit-point) vertices or at every interior vertex
//! with transparent shadows (notes §2.3.3), combined with BSDF/phase sampling by MIS.
//!
//! Nested and overlapping interiors are resolved with an interior stack and priorities
//! (Schmidt & Budge 2002, "Simple Nested Dielectrics in Ray Traced Images"): a boundary of an
//! object whose priority is lower than the current interior's is a *false* intersection that
//! only updates the stack, so overlapping objects are never counted twice.

use crate::bsdf::fresnel::fresnel_dielectric;
use crate::bsdf::Surface;
use crate::math::{Frame, Ray, Vec3};
use crate::medium::{sample_free_flight, FreeFlight, FreeFlightMethod, Medium, NeeStrategy};
use crate::phase::PhaseFunction;
use crate::sampling::{power_heuristic, PixelSampler};
use crate::scene::{Object, ObjectSurface, Scene, ShapeOwner};
use crate::spectrum::Rgb;
use crate::tracking::{
    delta_track, ray_march_free_flight, transmittance, Flight, MajorantSegment, TrackingStats,
};

/// The deepest nesting of interiors tracked; deeper entries are ignored.
pub const MAX_NESTING: usize = 16;

/// Depth at which Russian roulette starts.
const RR_START_DEPTH: u32 = 5;

/// Counters gathered while tracing (summed over all paths for the render summary).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TraceStats {
    /// Camera paths traced.
    pub paths: u64,
    /// Rays cast (closest-hit and shadow).
    pub rays: u64,
    /// Scattering events (surface and volume) over all paths.
    pub vertices: u64,
    /// Samples whose radiance was NaN or infinite (dropped, not written).
    pub non_finite: u64,
    /// Heterogeneous-medium tracking counters (lookups, collisions, bound violations).
    pub tracking: TrackingStats,
}

impl TraceStats {
    /// Adds `o` to `self`.
    pub fn merge(&mut self, o: &TraceStats) {
        self.paths += o.paths;
        self.rays += o.rays;
        self.vertices += o.vertices;
        self.non_finite += o.non_finite;
        self.tracking.merge(&o.tracking);
    }
}

/// What one camera path returns.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PathResult {
    /// Radiance along the camera ray (already checked finite; zero if it was not).
    pub radiance: Rgb,
    /// Albedo of the first surface hit (AOV).
    pub albedo: Rgb,
    /// Shading normal at the first surface hit (AOV).
    pub normal: Vec3,
    /// Distance to the first surface hit, 0 if none (AOV).
    pub depth: f32,
}

/// The objects (by index) that a point is inside of, with their priorities.
#[derive(Clone, Copy, Debug)]
pub struct InteriorStack {
    entries: [u32; MAX_NESTING],
    len: usize,
}

impl Default for InteriorStack {
    fn default() -> Self {
        InteriorStack {
            entries: [0; MAX_NESTING],
            len: 0,
        }
    }
}

impl InteriorStack {
    /// The stack with nothing entered.
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }

    /// Entered objects, oldest first.
    #[must_use]
    pub fn entries(&self) -> &[u32] {
        &self.entries[..self.len]
    }

    /// True if `obj` is on the stack.
    #[must_use]
    pub fn contains(&self, obj: u32) -> bool {
        self.entries().contains(&obj)
    }

    /// Enters `obj`.
    pub fn push(&mut self, obj: u32) {
        if self.len < MAX_NESTING && !self.contains(obj) {
            self.entries[self.len] = obj;
            self.len += 1;
        }
    }

    /// Leaves `obj` (no-op if not entered).
    pub fn remove(&mut self, obj: u32) {
        if let Some(i) = self.entries().iter().position(|&o| o == obj) {
            self.entries.copy_within(i + 1..self.len, i);
            self.len -= 1;
        }
    }

    /// The governing object: highest priority, the most recently entered on ties;
    /// `exclude` is ignored.
    #[must_use]
    pub fn top(&self, objects: &[Object], exclude: Option<u32>) -> Option<u32> {
        let mut best: Option<u32> = None;
        for &o in self.entries() {
            if Some(o) == exclude {
                continue;
            }
            match best {
                Some(b) if objects[b as usize].priority > objects[o as usize].priority => {}
                _ => best = Some(o),
            }
        }
        best
    }

    /// IOR of the medium around, ignoring `exclude` (1 for vacuum).
    #[must_use]
    pub fn ior(&self, objects: &[Object], exclude: Option<u32>) -> f32 {
        self.top(objects, exclude)
            .map_or(1.0, |o| objects[o as usize].ior)
    }
}

/// The medium governing a point with the given stack, and the object it belongs to.
fn current_medium<'a>(scene: &'a Scene, stack: &InteriorStack) -> Option<(&'a Medium, &'a Object)> {
    let top = stack.top(&scene.objects, None)?;
    let obj = &scene.objects[top as usize];
    obj.medium.map(|m| (&scene.media[m as usize], obj))
}

/// Builds the boundary BSDF of `obj` for the media meeting there.
fn boundary_surface(obj: &Object, outside_ior: f32) -> Option<Surface> {
    match &obj.surface {
        ObjectSurface::Fixed(s) => Some(s.clone()),
        ObjectSurface::Null => None,
        ObjectSurface::Dielectric(d) => {
            let eta = d.ior / outside_ior.max(1e-6);
            let s = Surface::dielectric(eta, d.roughness, d.distribution, d.tint).ok()?;
            match d.coat {
                Some((ior, r, w)) => s.with_coat(ior, r, w).ok(),
                None => Some(s),
            }
        }
    }
}

/// True when a boundary of transmissive object `oi` does not interact: entering an object
/// under a higher-priority interior, leaving an object while a higher-priority one governs,
/// and the inconsistent cases that rounding can produce at silhouettes (entering an object
/// already entered, leaving one never entered), which pass straight through.
fn is_false_intersection(scene: &Scene, stack: &InteriorStack, oi: u32, entering: bool) -> bool {
    let governing = stack.top(&scene.objects, None);
    if entering {
        stack.contains(oi)
            || governing.is_some_and(|g| {
                scene.objects[g as usize].priority > scene.objects[oi as usize].priority
            })
    } else {
        !stack.contains(oi) || governing != Some(oi)
    }
}

/// What happened along a ray segment inside an interior.
/// The phase function at a scattering vertex.
#[derive(Clone, Copy)]
enum ScatterPhase<'a> {
    /// Henyey–Greenstein (single or double).
    Hg(&'a PhaseFunction),
    /// A fibre phase function around a tangent (voxelised fabric).
    Fibre(&'a crate::fabric::FibrePhase, Vec3),
}

impl ScatterPhase<'_> {
    /// Value (RGB, 1/sr) and pdf of scattering `wo → wi` (both pointing away).
    fn eval(&self, wo: Vec3, wi: Vec3) -> (Rgb, f32) {
        match self {
            ScatterPhase::Hg(p) => (Rgb::splat(p.eval(wo, wi)), p.pdf(wo, wi)),
            ScatterPhase::Fibre(f, t) => (f.eval(wo, wi, *t), f.pdf(wo, wi, *t)),
        }
    }
    /// A sampled direction with its weight (value/pdf) and pdf.
    fn sample(&self, wo: Vec3, sampler: &mut PixelSampler) -> Option<(Vec3, Rgb, f32)> {
        match self {
            ScatterPhase::Hg(p) => {
                let s = p.sample(wo, sampler.next_2d());
                (s.pdf > 0.0).then(|| (s.wi, Rgb::splat(s.value / s.pdf), s.pdf))
            }
            ScatterPhase::Fibre(f, t) => {
                let u = [
                    sampler.next_1d(),
                    sampler.next_1d(),
                    sampler.next_1d(),
                    sampler.next_1d(),
                ];
                let s = f.sample(wo, *t, u)?;
                (s.pdf > 0.0).then_some((s.wi, s.weight, s.pdf))
            }
        }
    }
}

/// The fibre phase function and tangent of a voxelised fabric at world point `p`.
fn fabric_phase<'a>(
    h: &'a crate::medium::HeterogeneousMedium,
    p: Vec3,
) -> Option<ScatterPhase<'a>> {
    let look = h.fabric.as_ref()?;
    let fibre = h.fibre_at(p)?;
    let yarn = if fibre.id < 0.5 {
        crate::fabric::YarnId::Warp(0)
    } else if fibre.id < 1.5 {
        crate::fabric::YarnId::Weft(0)
    } else {
        crate::fabric::YarnId::Pile
    };
    Some(ScatterPhase::Fibre(
        look.shading.for_yarn(yarn),
        fibre.tangent,
    ))
}

enum MediumEvent<'a> {
    /// A real scattering event at distance `t`.
    Scatter {
        t: f32,
        weight: Rgb,
        phase: ScatterPhase<'a>,
    },
    /// The ray reached `t_max`.
    Pass { weight: Rgb },
}

/// Samples the interior along `ray` up to `t_max` (Algorithm 1, lines 3–11).
fn sample_medium<'a>(
    medium: &'a Medium,
    ray: &Ray,
    t_max: f32,
    beta: Rgb,
    sampler: &mut PixelSampler,
    stats: &mut TraceStats,
    segments: &mut Vec<MajorantSegment>,
) -> MediumEvent<'a> {
    match medium {
        Medium::Absorbing { .. } => MediumEvent::Pass {
            weight: medium.transmittance(t_max),
        },
        Medium::Homogeneous(h) => {
            let u_channel = sampler.next_1d();
            let u_dist = sampler.next_1d();
            match sample_free_flight(&h.coefficients, beta, t_max, u_channel, u_dist) {
                FreeFlight::Escape { weight } => MediumEvent::Pass { weight },
                FreeFlight::Scatter { t, weight } => MediumEvent::Scatter {
                    t,
                    weight,
                    phase: ScatterPhase::Hg(&h.phase),
                },
            }
        }
        Medium::Heterogeneous(h) => {
            segments.clear();
            h.segments(ray, 0.0, t_max, segments);
            let mut lookup = h.density_along(ray);
            let mut u = || sampler.next_1d();
            let flight = match h.tracking.free_flight {
                FreeFlightMethod::DeltaTracking => delta_track(
                    segments.iter().copied(),
                    &h.coefficients,
                    |t| lookup.at(t),
                    beta,
                    &mut u,
                    &mut stats.tracking,
                ),
                FreeFlightMethod::RayMarching { step } => ray_march_free_flight(
                    segments.iter().copied(),
                    &h.coefficients,
                    |t| lookup.at(t),
                    step,
                    beta,
                    &mut u,
                    &mut stats.tracking,
                ),
            };
            match flight {
                Flight::Escape { weight } => MediumEvent::Pass { weight },
                Flight::Scatter { t, weight } => MediumEvent::Scatter {
                    t,
                    weight,
                    phase: fabric_phase(h, ray.at(t)).unwrap_or(ScatterPhase::Hg(&h.phase)),
                },
            }
        }
    }
}

/// Transmittance of the interior along `ray` over `[0, t_max]` (closed form for homogeneous
/// interiors, the interior's transmittance estimator for heterogeneous ones).
fn medium_transmittance(
    medium: &Medium,
    ray: &Ray,
    t_max: f32,
    sampler: &mut PixelSampler,
    stats: &mut TraceStats,
    segments: &mut Vec<MajorantSegment>,
) -> Rgb {
    match medium {
        Medium::Absorbing { .. } | Medium::Homogeneous(_) => medium.transmittance(t_max),
        Medium::Heterogeneous(h) => {
            segments.clear();
            h.segments(ray, 0.0, t_max, segments);
            let mut lookup = h.density_along(ray);
            let mut u = || sampler.next_1d();
            transmittance(
                segments.iter().copied(),
                &h.coefficients,
                |t| lookup.at(t),
                h.tracking.transmittance,
                &mut u,
                &mut stats.tracking,
            )
        }
    }
}

/// How a shadow ray treats the dielectric boundaries it meets.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum ShadowMode {
    /// Only null and false (priority) boundaries let it through.
    Opaque,
    /// Dielectric boundaries let it through with (1 − F) × tint, ignoring refraction
    /// ("transparent shadows", notes §2.3.3).
    Transparent,
}

/// Transmittance from `origin` along unit `dir` over `distance` (∞ for distant lights), through
/// media and boundaries. `ignore_shape` is the light's own shape (never an occluder).
fn shadow_transmittance(
    scene: &Scene,
    mut origin: Vec3,
    dir: Vec3,
    distance: f32,
    mut stack: InteriorStack,
    mode: ShadowMode,
    ignore_shape: Option<u32>,
    sampler: &mut PixelSampler,
    stats: &mut TraceStats,
) -> Rgb {
    let mut segments = Vec::new();
    let mut tr = Rgb::ONE;
    let mut remaining = distance;
    for _ in 0..4 * MAX_NESTING + 8 {
        stats.rays += 1;
        let hit = scene.geometry.intersect(&Ray::new(origin, dir), remaining);
        let seg = hit.as_ref().map_or(remaining, |h| h.t);
        if let Some((m, _)) = current_medium(scene, &stack) {
            tr *= medium_transmittance(
                m,
                &Ray::new(origin, dir),
                seg,
                sampler,
                stats,
                &mut segments,
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
            match &obj.surface {
                ObjectSurface::Null => {}
                ObjectSurface::Fixed(_) => return Rgb::ZERO,
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
                    tr *= d.tint * (1.0 - f);
                }
            }
        }
        if entering {
            stack.push(oi);
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
struct PrevVertex {
    p: Vec3,
    /// Solid-angle pdf of the direction sampled there.
    pdf: f32,
    /// True when that vertex did NEE (so light hits must be MIS-weighted against it).
    did_nee: bool,
}

/// Next event estimation from a point: picks a light, traces a shadow ray, returns the
/// MIS-weighted contribution (without the path throughput). `eval` gives (f·|cos| or phase
/// value, pdf of the scattering strategy) for a world direction.
#[allow(clippy::too_many_arguments)]
fn estimate_direct(
    scene: &Scene,
    p: Vec3,
    shadow_origin: impl Fn(Vec3) -> (Vec3, InteriorStack),
    eval: impl Fn(Vec3) -> (Rgb, f32),
    mode: ShadowMode,
    sampler: &mut PixelSampler,
    stats: &mut TraceStats,
) -> Rgb {
    let u_light = sampler.next_1d();
    let u = sampler.next_2d();
    let Some((li, p_sel)) = scene.light_sampler.sample(u_light) else {
        return Rgb::ZERO;
    };
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
        light_shape,
        sampler,
        stats,
    );
    if tr.is_black() {
        return Rgb::ZERO;
    }
    let light_pdf = p_sel * ls.pdf;
    let w = if ls.is_delta {
        1.0
    } else {
        power_heuristic(light_pdf, scatter_pdf)
    };
    f * tr * ls.radiance * (w / light_pdf)
}

/// Radiance arriving from lights hit by a sampled ray (sphere light `shape` or escaped rays),
/// MIS-weighted against the previous vertex's NEE.
fn emitted(scene: &Scene, dir: Vec3, prev: &PrevVertex, sphere_light: Option<usize>) -> Rgb {
    let weight = |li: usize| -> f32 {
        if !prev.did_nee {
            return 1.0;
        }
        let light_pdf = scene.light_sampler.probability(li) * scene.lights[li].pdf_li(prev.p, dir);
        power_heuristic(prev.pdf, light_pdf)
    };
    match sphere_light {
        Some(li) => {
            if let crate::light::Light::Sphere { radiance, .. } = &scene.lights[li] {
                *radiance * weight(li)
            } else {
                Rgb::ZERO
            }
        }
        None => {
            let mut l = Rgb::ZERO;
            for (li, light) in scene.lights.iter().enumerate() {
                if light.is_infinite() {
                    let le = light.escaped_radiance(dir);
                    if !le.is_black() {
                        l += le * weight(li);
                    }
                }
            }
            l
        }
    }
}

/// Traces one camera path and returns its radiance estimate and AOVs.
pub fn trace_path(
    scene: &Scene,
    camera_ray: Ray,
    sampler: &mut PixelSampler,
    stats: &mut TraceStats,
) -> PathResult {
    let (radiance, aov) = radiance(scene, camera_ray, sampler, stats);
    stats.paths += 1;
    let radiance = if radiance.is_finite() {
        radiance
    } else {
        stats.non_finite += 1;
        Rgb::ZERO
    };
    PathResult {
        radiance,
        albedo: aov.0,
        normal: aov.1,
        depth: aov.2,
    }
}

type Aov = (Rgb, Vec3, f32);

fn radiance(
    scene: &Scene,
    mut ray: Ray,
    sampler: &mut PixelSampler,
    stats: &mut TraceStats,
) -> (Rgb, Aov) {
    let max_depth = scene.film.max_depth;
    let mut l = Rgb::ZERO;
    let mut beta = Rgb::ONE;
    let mut eta_scale = 1.0f32;
    let mut stack = InteriorStack::new();
    let mut depth = 0u32;
    let mut prev = PrevVertex {
        p: ray.o,
        pdf: 0.0,
        did_nee: false,
    };
    let mut aov: Option<Aov> = None;
    // Bound on null/false boundary crossings so that a degenerate scene cannot loop forever.
    let mut crossings = 0u32;
    let mut segments: Vec<MajorantSegment> = Vec::new();

    loop {
        stats.rays += 1;
        let hit = scene.geometry.intersect(&ray, f32::INFINITY);
        let t_hit = hit.as_ref().map_or(f32::INFINITY, |h| h.t);

        // 1. The interior the ray travels through (Algorithm 1, lines 3–11).
        if let Some((medium, obj)) = current_medium(scene, &stack) {
            match sample_medium(medium, &ray, t_hit, beta, sampler, stats, &mut segments) {
                MediumEvent::Pass { weight } => beta *= weight,
                MediumEvent::Scatter { t, weight, phase } => {
                    beta *= weight;
                    depth += 1;
                    stats.vertices += 1;
                    if depth >= max_depth || beta.is_black() {
                        break;
                    }
                    let p = ray.at(t);
                    let wo = -ray.d;
                    if obj.nee == NeeStrategy::Interior {
                        let st = stack;
                        l += beta
                            * estimate_direct(
                                scene,
                                p,
                                |_| (p, st),
                                |wi| phase.eval(wo, wi),
                                ShadowMode::Transparent,
                                sampler,
                                stats,
                            );
                    }
                    let Some((wi, w, pdf)) = phase.sample(wo, sampler) else {
                        break;
                    };
                    beta *= w;
                    prev = PrevVertex {
                        p,
                        pdf,
                        did_nee: obj.nee == NeeStrategy::Interior,
                    };
                    ray = Ray::new(p, wi);
                    if !russian_roulette(&mut beta, eta_scale, depth, sampler) {
                        break;
                    }
                    continue;
                }
            }
            if beta.is_black() {
                break;
            }
        }

        // 2. Escaped rays see the infinite lights.
        let Some(hit) = hit else {
            l += beta * emitted(scene, ray.d, &prev, None);
            break;
        };

        // 3. Sphere lights are emitters only.
        let owner = scene.shape_owner[hit.shape as usize];
        let oi = match owner {
            ShapeOwner::Light(li) => {
                if ray.d.dot(hit.ng) < 0.0 {
                    l += beta * emitted(scene, ray.d, &prev, Some(li as usize));
                }
                if aov.is_none() {
                    aov = Some((Rgb::ZERO, hit.ns, hit.t));
                }
                break;
            }
            ShapeOwner::Object(oi) => oi,
        };
        let obj = &scene.objects[oi as usize];
        let entering = ray.d.dot(hit.ng) < 0.0;
        let transmits = obj.surface.transmits();

        // 4. False intersections with lower-priority boundaries only update the stack.
        if transmits {
            if is_false_intersection(scene, &stack, oi, entering)
                || matches!(obj.surface, ObjectSurface::Null)
            {
                if entering {
                    stack.push(oi);
                } else {
                    stack.remove(oi);
                }
                crossings += 1;
                if crossings > 64 * MAX_NESTING as u32 + max_depth {
                    break;
                }
                ray = Ray::new(hit.spawn_origin(ray.d), ray.d);
                continue;
            }
        }

        // 5. A true surface interaction.
        let outside_ior = stack.ior(&scene.objects, Some(oi));
        let Some(surface) = boundary_surface(obj, outside_ior) else {
            break;
        };
        // Opaque surfaces are two-sided: seen from behind, flip the frame.
        let (ng, ns) = if !transmits && !entering {
            (-hit.ng, -hit.ns)
        } else {
            (hit.ng, hit.ns)
        };
        let frame = Frame::from_normal(ns);
        let wo = -ray.d;
        let wo_local = frame.to_local(wo);
        if aov.is_none() {
            aov = Some((surface.albedo_hint(), hit.ns, hit.t));
        }
        depth += 1;
        stats.vertices += 1;
        if depth >= max_depth {
            break;
        }

        // The interior we arrived from: if it does NEE at interior vertices, the light is
        // already accounted for through transparent shadows; no exit-point NEE here.
        let from_interior_nee =
            !entering && transmits && obj.nee == NeeStrategy::Interior && obj.medium.is_some();
        let do_nee = !surface.is_delta() && !from_interior_nee;
        if do_nee {
            let st = stack;
            let p = hit.p;
            l += beta
                * estimate_direct(
                    scene,
                    p,
                    |wi| {
                        let mut s = st;
                        let crosses = (wi.dot(ng) > 0.0) != (wo.dot(ng) > 0.0);
                        if crosses && transmits {
                            if wi.dot(hit.ng) < 0.0 {
                                s.push(oi);
                            } else {
                                s.remove(oi);
                            }
                        }
                        (hit.spawn_origin(wi), s)
                    },
                    |wi| {
                        // Reject directions on the wrong side of the geometric surface for the lobe.
                        let wi_local = frame.to_local(wi);
                        let geometric_reflect = (wi.dot(ng) > 0.0) == (wo.dot(ng) > 0.0);
                        let shading_reflect = (wi_local.z > 0.0) == (wo_local.z > 0.0);
                        if geometric_reflect != shading_reflect {
                            return (Rgb::ZERO, 0.0);
                        }
                        let f = surface.eval(wo_local, wi_local) * wi_local.z.abs();
                        (f, surface.pdf(wo_local, wi_local))
                    },
                    ShadowMode::Opaque,
                    sampler,
                    stats,
                );
        }

        let uc = sampler.next_1d();
        let u = sampler.next_2d();
        let Some(bs) = surface.sample(wo_local, uc, u) else {
            break;
        };
        if !(bs.pdf > 0.0) || bs.weight.is_black() {
            break;
        }
        let wi = frame.to_world(bs.wi).normalize();
        // The geometric side must agree with the lobe, or the path would leak through the mesh.
        let geometric_transmit = (wi.dot(ng) > 0.0) != (wo.dot(ng) > 0.0);
        if geometric_transmit != bs.is_transmission {
            break;
        }
        beta *= bs.weight;
        if bs.is_transmission {
            eta_scale *= bs.eta * bs.eta;
            if wi.dot(hit.ng) < 0.0 {
                stack.push(oi);
            } else {
                stack.remove(oi);
            }
        }
        if !(bs.is_delta || from_interior_nee) {
            prev = PrevVertex {
                p: hit.p,
                pdf: bs.pdf,
                did_nee: do_nee,
            };
        } else if bs.is_delta && !from_interior_nee {
            prev.did_nee = false;
        }
        ray = Ray::new(hit.spawn_origin(wi), wi);
        if !russian_roulette(&mut beta, eta_scale, depth, sampler) {
            break;
        }
    }
    (l, aov.unwrap_or((Rgb::ZERO, Vec3::ZERO, 0.0)))
}

/// Russian roulette with survival probability min(1, max_c β_c · η-scale) after
/// [`RR_START_DEPTH`] events (pbrt-v4's rule; the η-scale undoes the radiance compression of
/// refraction so that entering skin does not trigger spurious termination). Returns false
/// when the path is terminated.
fn russian_roulette(
    beta: &mut Rgb,
    eta_scale: f32,
    depth: u32,
    sampler: &mut PixelSampler,
) -> bool {
    if beta.is_black() || !beta.is_finite() {
        return false;
    }
    if depth < RR_START_DEPTH {
        return true;
    }
    let q = (beta.max_component() * eta_scale).min(1.0);
    if q >= 1.0 {
        return true;
    }
    let u = sampler.next_1d();
    if u >= q {
        return false;
    }
    *beta /= q;
    true
}
