//! The volumetric path tracer of the course notes' Algorithm 1 (§2.3): refraction through a
//! microfacet boundary into an interior, free-flight sampling with the RGB channel chosen by
//! throughput and one-sample MIS over channels (docs/references.md §4.6), phase-function sampling, and
//! next event estimation either at boundary (exit-point) vertices or at every interior vertex
//! with transparent shadows (notes §2.3.3), combined with BSDF/phase sampling by MIS; or, for
//! `nee = "exit_guided"`, guided connections from interior vertices through a rough boundary
//! (`connect.rs`) MIS-combined with BTDF sampling at the exit.
//!
//! Nested and overlapping interiors are resolved with an interior stack and priorities
//! (Schmidt & Budge 2002, "Simple Nested Dielectrics in Ray Traced Images"): a boundary of an
//! object whose priority is lower than the current interior's is a *false* intersection that
//! only updates the stack, so overlapping objects are never counted twice.

mod connect;
mod direct;
mod fibre_lean;
mod interiors;
pub mod manifold;

pub use interiors::{InteriorStack, MAX_NESTING};

use direct::{emitted, estimate_direct, PrevVertex, ShadowMode, ShadowRoulette, SunLean};
use fibre_lean::{FibreLean, LeanWeight};
use interiors::{boundary_surface_at, current_medium, enter, is_false_intersection, scene_medium};

use crate::bsdf::Surface;
use crate::fabric::PreparedFibre;
use crate::film::MAX_LIGHT_LAYERS;
use crate::geometry::Hit;
use crate::math::{Frame, Ray, Vec3};
use crate::medium::{Medium, NeeStrategy, PreparedPhase, ScatterVertex, VertexPhase, VertexSlots};
use crate::sampling::PixelSampler;
use crate::scene::{Object, ObjectSurface, Roulette, Scene, ShapeOwner};
use crate::spectrum::Rgb;
use crate::tracking::TrackingStats;

/// The spread angle (radians) a ray cone takes at least after a non-specular event (rough
/// or diffuse surface scattering, volume scattering): a widening policy for texture
/// filtering only (docs/textures.md), not from a paper.
const NON_SPECULAR_SPREAD: f32 = 0.2;

/// A ray cone (Akenine-Möller et al. 2019/2021; docs/references.md §14.2): the footprint
/// width at the ray's origin (world units) and how fast it grows per unit distance.
#[derive(Clone, Copy, Debug)]
struct RayCone {
    /// Width at the ray's origin, world units.
    width: f32,
    /// Spread angle, radians (width grows by `spread · t`).
    spread: f32,
}

impl RayCone {
    /// The cone advanced by `t` (finite) along the ray.
    #[inline]
    fn advance(&mut self, t: f32) {
        self.width += self.spread * t;
    }

    /// The cone as media see it (fabric mip levels chosen per ray).
    #[inline]
    fn footprint(self) -> crate::medium::RayFootprint {
        crate::medium::RayFootprint {
            width: self.width,
            spread: self.spread,
        }
    }

    /// After a non-specular event.
    #[inline]
    fn widen(&mut self) {
        self.spread = self.spread.max(NON_SPECULAR_SPREAD);
    }

    /// The footprint width in texture units at a hit seen at `cos` to the normal, where the
    /// surface has `uv_scale` texture units per world unit: width / |cos| (the long axis of
    /// the cone's elliptic cross-section, at most 4× the width: an isotropic filter cannot
    /// follow the ellipse, and would blur silhouettes to the texture's mean) × `uv_scale`.
    #[inline]
    fn width_uv(&self, uv_scale: f32, cos: f32) -> f32 {
        self.width / cos.abs().max(0.25) * uv_scale
    }
}

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
    /// Manifold-walk counters (`nee = "manifold"`).
    pub manifold: manifold::ManifoldStats,
}

impl TraceStats {
    /// Adds `o` to `self`.
    pub fn merge(&mut self, o: &TraceStats) {
        self.paths += o.paths;
        self.rays += o.rays;
        self.vertices += o.vertices;
        self.non_finite += o.non_finite;
        self.tracking.merge(&o.tracking);
        self.manifold.merge(&o.manifold);
    }
}

/// What one camera path returns.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PathResult {
    /// Radiance along the camera ray (already checked finite; zero if it was not).
    pub radiance: Rgb,
    /// Albedo at the first non-specular event (AOV): a surface's albedo; at the boundary of an
    /// interior with an artist albedo (skin, clouds), that albedo; glass and fabric boundaries
    /// are looked through to the first event behind or inside them.
    pub albedo: Rgb,
    /// World-space shading normal there; for a medium event, the normal of the boundary the
    /// path entered by (zero when it entered none).
    pub normal: Vec3,
    /// Distance from the camera to that event; +inf when there was none.
    pub depth: f32,
    /// The part of `radiance` from each named light, by layer slot (zero for unused slots).
    pub lights: [Rgb; MAX_LIGHT_LAYERS],
}

/// Traces one camera path and returns its radiance estimate and AOVs.
pub fn trace_path(
    scene: &Scene,
    camera_ray: Ray,
    sampler: &mut PixelSampler,
    stats: &mut TraceStats,
) -> PathResult {
    let (radiance, aov, lights) = radiance(scene, camera_ray, sampler, stats);
    stats.paths += 1;
    let named = scene.light_layer_names.len();
    let finite = radiance.is_finite() && lights.iter().take(named).all(|l| l.is_finite());
    let (radiance, lights) = if finite {
        (radiance, lights)
    } else {
        stats.non_finite += 1;
        (Rgb::ZERO, [Rgb::ZERO; MAX_LIGHT_LAYERS])
    };
    PathResult {
        radiance,
        albedo: aov.0,
        normal: aov.1,
        depth: aov.2,
        lights,
    }
}

/// Albedo, shading normal and depth of the first non-specular event (AOVs).
type Aov = (Rgb, Vec3, f32);

/// What the path does after a step.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Step {
    /// A new ray was started (scattered in a medium, reflected, refracted or passed through a
    /// boundary): trace it.
    Trace,
    /// The flight through the current interior reached the next boundary (or escaped):
    /// interact with it.
    Boundary,
    /// The path ends.
    Stop,
}

/// The state of one camera path between steps (the course notes' Algorithm 1); `'s` is the
/// scene's lifetime (a fibre lean's deferred weight borrows the scene's phase functions).
struct PathState<'s> {
    /// The ray being followed.
    ray: Ray,
    /// Path throughput.
    beta: Rgb,
    /// Radiance gathered so far.
    radiance: Rgb,
    /// Product of η² over refractions (undoes radiance compression for Russian roulette).
    eta_scale: f32,
    /// The interiors the ray is inside of.
    stack: InteriorStack,
    /// Scattering events so far (surface and volume).
    depth: u32,
    /// The previous scattering vertex, for MIS on light hits.
    prev: PrevVertex,
    /// AOVs of the first non-specular event.
    aov: Option<Aov>,
    /// The camera ray's origin (AOV depth is measured from it).
    origin: Vec3,
    /// Shading normal of the last boundary the path entered an interior by (AOV normal of a
    /// medium event).
    entry_normal: Vec3,
    /// Null and false boundary crossings, bounded so that a degenerate scene cannot loop.
    crossings: u32,
    /// The object whose `exit_guided` interior vertex (a guided connection was made there)
    /// the ray now leaves, with that vertex's phase pdf of the ray direction; cleared by any
    /// boundary.
    guided_from: Option<u32>,
    /// The ray's cone, for texture footprints.
    cone: RayCone,
    /// Where the path stands with respect to a manifold connection (no double counting of
    /// the paths `nee = "manifold"` samples, see [`ManifoldLeg`]).
    manifold_leg: ManifoldLeg,
    /// The part of `radiance` from each named light, by layer slot.
    lights: [Rgb; MAX_LIGHT_LAYERS],
    /// Balance-heuristic weight of this vertex-to-be's sun NEE against the sun-leaned
    /// second-vertex estimate made at the previous vertex ([`direct::SunLean`],
    /// [`FibreLean`]: evaluated only where that NEE adds something, [`LeanWeight`]), and
    /// the sun's index; `None` when none was made or a boundary was met since.
    lean_weight: Option<(LeanWeight<'s>, usize)>,
}

/// The unidirectional counterpart of a manifold connection (`src/integrator/manifold`): a
/// path that scatters at an interior vertex of a `manifold` object, reaches that object's
/// boundary first, refracts out through its smooth lobe and then reaches a sphere or
/// distant light with nothing but null or false boundaries (and index-matched pass-through
/// dielectrics) on the way is the path `x0 → x1 → light` that MNEE samples; its light hit
/// contributes nothing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum ManifoldLeg {
    /// Not on such a path.
    None,
    /// Left an interior vertex of a `manifold` interior; no real boundary crossed since.
    Inside,
    /// Refracted out of that object's smooth boundary straight from the vertex.
    Through,
}

fn radiance(
    scene: &Scene,
    ray: Ray,
    sampler: &mut PixelSampler,
    stats: &mut TraceStats,
) -> (Rgb, Aov, [Rgb; MAX_LIGHT_LAYERS]) {
    let mut path = PathState::new(ray, scene.camera.pixel_spread_angle());
    // The fibre slots (two 2.6 KiB records) are made at the path's first scattering vertex
    // that needs them: most paths through a thin medium scatter nowhere.
    let mut slots = None;
    // The step's boundary hit, written in place by the ray cast (a hit returned by value
    // was copied twice on its way here, through loads wider than the cast's stores).
    let mut hit = None;
    loop {
        stats.rays += 1;
        sampler.start_vertex();
        let step = path.interior_step(scene, sampler, stats, &mut slots, &mut hit);
        match step {
            Step::Trace => continue,
            Step::Stop => break,
            Step::Boundary => path.lean_weight = None,
        }
        let Some(h) = &hit else {
            path.escape(scene);
            break;
        };
        if path.boundary_step(scene, h, sampler, stats) == Step::Stop {
            break;
        }
    }
    (
        path.radiance,
        path.aov.unwrap_or((Rgb::ZERO, Vec3::ZERO, f32::INFINITY)),
        path.lights,
    )
}

impl<'s> PathState<'s> {
    /// Adds a contribution `c` (throughput included) from light `li`: to the radiance, and to
    /// the light's own layer when it is named.
    #[inline]
    fn add_light(&mut self, scene: &Scene, li: Option<usize>, c: Rgb) {
        self.radiance += c;
        if let Some(Some(slot)) = li.and_then(|l| scene.light_layers.get(l)) {
            if let Some(layer) = self.lights.get_mut(*slot as usize) {
                *layer += c;
            }
        }
    }

    /// Adds emitted radiance `e` seen along the path (before the throughput), with its named
    /// lights' parts `layers`.
    #[inline]
    fn add_emitted(&mut self, scene: &Scene, e: Rgb, layers: &[Rgb; MAX_LIGHT_LAYERS]) {
        self.radiance += self.beta * e;
        let named = scene.light_layer_names.len();
        for (l, v) in self.lights.iter_mut().zip(layers).take(named) {
            *l += self.beta * *v;
        }
    }

    fn new(ray: Ray, spread: f32) -> Self {
        PathState {
            ray,
            beta: Rgb::ONE,
            radiance: Rgb::ZERO,
            eta_scale: 1.0,
            stack: InteriorStack::new(),
            depth: 0,
            prev: PrevVertex {
                p: ray.o,
                pdf: 0.0,
                did_nee: false,
                guided: None,
            },
            aov: None,
            origin: ray.o,
            entry_normal: Vec3::ZERO,
            crossings: 0,
            guided_from: None,
            cone: RayCone { width: 0.0, spread },
            manifold_leg: ManifoldLeg::None,
            lights: [Rgb::ZERO; MAX_LIGHT_LAYERS],
            lean_weight: None,
        }
    }

    /// 1. The interior the ray travels through, up to the next boundary (Algorithm 1, lines
    ///    3–11): a free flight that passes, or scatters. Sets `hit` to the boundary hit when
    ///    the flight reached it (the closest hit of the ray; in vacuum, the ray is traced to
    ///    the first hit), to `None` otherwise. The boundary is searched only as far as the
    ///    medium needs: up to the sampled distance in a homogeneous medium. `slots` holds the
    ///    path's fibre slots once a scattering vertex has made them.
    fn interior_step(
        &mut self,
        scene: &'s Scene,
        sampler: &mut PixelSampler,
        stats: &mut TraceStats,
        slots: &mut Option<VertexSlots>,
        hit: &mut Option<Hit>,
    ) -> Step {
        // In vacuum (no interior entered: the stack's top is `None`, and so is the current
        // medium) the ray is traced to the first hit without looking for a medium.
        if self.stack.entries().is_empty() {
            return self.vacuum_step(scene, hit);
        }
        // A medium of the scene itself outlives the step: a fibre lean made in it can leave
        // its weight to the next vertex. One made for this walk (`scratch`) cannot.
        if let Some((medium, obj)) =
            scene_medium(scene, &self.stack).filter(|_| !fibre_lean::eager_weights())
        {
            return self.interior_step_in(scene, medium, obj, sampler, stats, slots, hit, Some);
        }
        let mut scratch = None;
        let Some((medium, obj)) = current_medium(scene, &self.stack, &mut scratch) else {
            return self.vacuum_step(scene, hit);
        };
        self.interior_step_in(scene, medium, obj, sampler, stats, slots, hit, |_| None)
    }

    /// [`PathState::interior_step`] outside every interior: the ray's first hit.
    #[inline]
    fn vacuum_step(&mut self, scene: &Scene, hit: &mut Option<Hit>) -> Step {
        *hit = scene.geometry.intersect(&self.ray, f32::INFINITY);
        if let Some(h) = hit {
            self.cone.advance(h.t);
        }
        Step::Boundary
    }

    /// [`PathState::interior_step`] in `medium`, the interior of `obj`; `keep` gives a fibre
    /// lean of this medium a lifetime of the scene's where it has one
    /// ([`PathState::scatter_in_medium`]).
    #[allow(clippy::too_many_arguments)]
    fn interior_step_in<'m>(
        &mut self,
        scene: &Scene,
        medium: &'m Medium,
        obj: &Object,
        sampler: &mut PixelSampler,
        stats: &mut TraceStats,
        slots: &mut Option<VertexSlots>,
        hit: &mut Option<Hit>,
        keep: impl Fn(FibreLean<'m>) -> Option<FibreLean<'s>>,
    ) -> Step {
        *hit = None;
        let ray = self.ray;
        // What lies behind a thin medium, estimated by transmittance: the boundary is needed
        // first, and the flight below then only samples collisions.
        let mut behind_estimated = false;
        let mut known_boundary = None;
        if medium.estimates_behind() {
            *hit = scene.geometry.intersect(&ray, f32::INFINITY);
            if let Some(h) = hit {
                known_boundary = Some(h.t);
                behind_estimated = self.add_light_behind(scene, medium, h, sampler, stats);
            }
        }
        let event = medium.sample_flight_rewinding(
            &ray,
            self.cone.footprint(),
            self.beta,
            sampler,
            PixelSampler::next_1d,
            &mut stats.tracking,
            |limit| match known_boundary {
                Some(t) if t <= limit => t,
                Some(_) => f32::INFINITY,
                None => {
                    *hit = scene.geometry.intersect(&ray, limit);
                    hit.as_ref().map_or(f32::INFINITY, |h| h.t)
                }
            },
        );
        if !event.emitted.is_black() {
            self.radiance += self.beta * event.emitted;
        }
        self.beta *= event.weight;
        let step = match event.scatter {
            Some(vertex) => {
                // Inside a walk the cone only widens: the width the next boundary sees is the
                // entry's grown over the walk's last segment (the sum of a random walk's
                // segments would overstate how far it spread).
                self.cone.widen();
                let slots = slots.get_or_insert_with(VertexSlots::new);
                self.scatter_in_medium(scene, medium, obj, &vertex, sampler, stats, slots, keep)
            }
            None if self.beta.is_black() || behind_estimated => Step::Stop,
            None => {
                if let Some(h) = hit {
                    self.cone.advance(h.t);
                }
                Step::Boundary
            }
        };
        step
    }

    /// The light behind the current medium along the ray, estimated by transmittance
    /// ([`crate::tracking::BehindMode::Transmittance`]): where the ray leaves the medium at
    /// `exit` through a boundary it crosses unchanged (a null or false boundary) into vacuum,
    /// and then reaches the environment or a sphere light with nothing in between, adds what
    /// the path would see there had it survived the free flight (with the same MIS weight),
    /// times the interior's transmittance estimate to `exit`, and returns true: the flight's
    /// escape then adds nothing. Returns false (nothing added) where something else lies
    /// behind; the path then survives or dies as in plain delta tracking.
    fn add_light_behind(
        &mut self,
        scene: &Scene,
        medium: &Medium,
        exit: &Hit,
        sampler: &mut PixelSampler,
        stats: &mut TraceStats,
    ) -> bool {
        let ShapeOwner::Object(oi) = scene.shape_owner[exit.shape as usize] else {
            return false;
        };
        let obj = &scene.objects[oi as usize];
        let entering = self.ray.d.dot(exit.ng) < 0.0;
        let passes = obj.surface.transmits()
            && (matches!(obj.surface, ObjectSurface::Null)
                || is_false_intersection(scene, &self.stack, oi, entering));
        if entering || !passes {
            return false;
        }
        let mut outside = self.stack;
        outside.remove(oi);
        if !outside.entries().is_empty() {
            return false;
        }
        let d = self.ray.d;
        let beyond = Ray::new(exit.spawn_origin(d), d);
        stats.rays += 1;
        let light = match scene.geometry.intersect(&beyond, f32::INFINITY) {
            None => None,
            Some(h) => match scene.shape_owner[h.shape as usize] {
                ShapeOwner::Light(li) => Some((li as usize, h)),
                ShapeOwner::Object(_) => return false,
            },
        };
        let through = self.manifold_leg == ManifoldLeg::Through;
        let mut layers = [Rgb::ZERO; MAX_LIGHT_LAYERS];
        let e = match light {
            None => emitted(scene, d, &self.prev, None, through, &mut layers),
            // Seen from behind, a sphere light's surface emits nothing and stops the path.
            Some((_, h)) if d.dot(h.ng) >= 0.0 => return true,
            Some((li, h)) => emitted(scene, d, &self.prev, Some((li, h.p)), through, &mut layers),
        };
        if e.is_black() && layers.iter().all(|l| l.is_black()) {
            return true;
        }
        let tr = medium.transmittance_in_cone(
            &self.ray,
            exit.t,
            self.cone.footprint(),
            &mut || sampler.next_1d(),
            &mut stats.tracking,
        );
        let layers = layers.map(|l| l * tr);
        self.add_emitted(scene, e * tr, &layers);
        true
    }

    /// A real collision inside an interior: NEE at the vertex if the interior does it there,
    /// then a new direction from the vertex's phase function. A fibre lean made here leaves
    /// the main direction's balance weight to the next vertex's sun NEE, which needs it only
    /// where it adds something, when `keep` gives the lean the scene's lifetime; otherwise
    /// the weight is evaluated here (the same bits either way).
    #[allow(clippy::too_many_arguments)]
    fn scatter_in_medium<'m>(
        &mut self,
        scene: &Scene,
        medium: &Medium,
        obj: &Object,
        vertex: &ScatterVertex<'m>,
        sampler: &mut PixelSampler,
        stats: &mut TraceStats,
        slots: &mut VertexSlots,
        keep: impl Fn(FibreLean<'m>) -> Option<FibreLean<'s>>,
    ) -> Step {
        self.depth += 1;
        stats.vertices += 1;
        if self.depth >= scene.film.max_depth || self.beta.is_black() {
            return Step::Stop;
        }
        let p = vertex.p;
        if self.aov.is_none() {
            let albedo = obj.aov_albedo.unwrap_or(vertex.albedo);
            self.aov = Some((albedo, self.entry_normal, (p - self.origin).length()));
        }
        let wo = -self.ray.d;
        let interior_nee = obj.nee == NeeStrategy::Interior;
        let phase = vertex.phase.prepare(wo, &mut slots.vertex);
        let lean = if interior_nee && medium.sun_lean() && matches!(phase, PreparedPhase::Hg { .. })
        {
            SunLean::for_scene(scene)
        } else {
            None
        };
        let fibre_lean = match lean {
            None if interior_nee && medium.sun_lean() => FibreLean::at_vertex(scene, &vertex.phase),
            _ => None,
        };
        let lean_light = lean
            .map(|l| l.light)
            .or(fibre_lean.as_ref().map(|l| l.light));
        let lean_weight = self.lean_weight.take();
        // The sun's shadow ray from here is rouletted by the sun's transmittance predicted
        // from the medium's map (where the medium has one) before it is traced; at a fibre
        // vertex, any shadow ray by its predicted contribution against the radiance the path
        // has gathered so far.
        let survival = match lean.and_then(|l| {
            medium
                .sun_transmittance_hint(p, l.to_light())
                .map(|t| ShadowRoulette::Light(l.light, SunLean::shadow_survival(t)))
        }) {
            Some(r) => r,
            None if matches!(vertex.phase, VertexPhase::Fibre { .. }) => {
                ShadowRoulette::Contribution {
                    beta: self.beta,
                    reference: self.radiance,
                }
            }
            None => ShadowRoulette::Off,
        };
        let mut seen = None;
        if interior_nee {
            let st = self.stack;
            let mut li = None;
            let c = estimate_direct(
                scene,
                p,
                |_| (p, st),
                |wi| phase.eval(wi),
                ShadowMode::Transparent,
                self.cone.footprint(),
                sampler,
                stats,
                &mut li,
                None,
                &mut seen,
                survival,
            );
            if lean_light.is_none_or(|l| li != Some(l)) {
                seen = None;
            }
            let c = match lean_weight {
                // A black estimate stays black whatever the (finite, positive) weight.
                Some((w, light)) if li == Some(light) && !c.is_black() => c * w.value(),
                _ => c,
            };
            self.add_light(scene, li, self.beta * c);
        }
        // The lean is played by chance where the vertex's own sun NEE saw little of the sun.
        let play = match &fibre_lean {
            Some(f) => f.play_probability(seen),
            None => SunLean::play_probability(seen),
        };
        if let Some(light) = lean_light {
            if self.depth + 1 < scene.film.max_depth && (play >= 1.0 || sampler.next_1d() < play) {
                let drawn = match (lean, &phase, &fibre_lean) {
                    (Some(l), PreparedPhase::Hg { phase: hg, wo }, _) => l
                        .sample(hg, *wo, play, sampler)
                        .map(|(d, f_over_q, w)| (d, Rgb::splat(f_over_q), w)),
                    (_, _, Some(f)) => f.sample(&phase, play, sampler),
                    _ => None,
                };
                if let Some(drawn) = drawn {
                    let c = self.lean_estimate(
                        scene,
                        medium,
                        light,
                        drawn,
                        p,
                        sampler,
                        stats,
                        &mut slots.lean,
                    );
                    self.add_light(scene, Some(light), c / play);
                }
            }
        }
        self.guided_from = None;
        if obj.nee == NeeStrategy::ExitGuided && self.depth + 1 < scene.film.max_depth {
            if let Some(oi) = self.stack.top(&scene.objects, None) {
                let mut li = None;
                let c = connect::guided_connection(
                    scene, oi, medium, p, &phase, self.stack, self.cone, sampler, stats, &mut li,
                );
                self.add_light(scene, li, self.beta * c);
                self.guided_from = Some(oi);
            }
        }
        self.manifold_leg = ManifoldLeg::None;
        if obj.nee == NeeStrategy::Manifold {
            if self.depth + 1 < scene.film.max_depth {
                let mut li = None;
                let c = manifold::manifold_connection(
                    scene, p, &phase, self.stack, sampler, stats, &mut li,
                );
                self.add_light(scene, li, self.beta * c);
            }
            self.manifold_leg = ManifoldLeg::Inside;
        }
        let Some(s) = phase.sample(sampler) else {
            return Step::Stop;
        };
        self.beta *= s.weight;
        if let (Some(l), PreparedPhase::Hg { phase: hg, wo }) = (lean, &phase) {
            self.lean_weight = Some((
                LeanWeight::Known(l.main_weight(hg, *wo, s.wi, play)),
                l.light,
            ));
        }
        if let Some(f) = fibre_lean {
            let light = f.light;
            let w = match keep(f) {
                Some(lean) => LeanWeight::Deferred {
                    lean,
                    p: s.pdf,
                    wi: s.wi,
                    play,
                },
                None => LeanWeight::Known(f.main_weight(s.pdf, s.wi, play)),
            };
            self.lean_weight = Some((w, light));
        }
        self.prev = PrevVertex {
            p,
            pdf: s.pdf,
            did_nee: interior_nee,
            guided: None,
        };
        self.ray = Ray::new(p, s.wi);
        self.continue_with_roulette(scene.film.roulette, sampler)
    }

    /// The sun-leaned estimate of the sun's light scattered at the *next* vertex
    /// ([`direct::SunLean`], [`fibre_lean::FibreLean`]): `drawn` = (a direction from the lobe
    /// centred on the sun, phase value / that lobe's pdf, the balance weight against the main
    /// path's own sun NEE at its next vertex); a free flight along it up to the interior's next
    /// boundary, and where it collides the NEE there of the sun, light `light`. Returns the
    /// contribution with the path throughput included (the caller divides by the lean's play
    /// probability).
    #[allow(clippy::too_many_arguments)]
    fn lean_estimate(
        &self,
        scene: &Scene,
        medium: &Medium,
        light: usize,
        (d, f_over_q, w): (Vec3, Rgb, f32),
        p: Vec3,
        sampler: &mut PixelSampler,
        stats: &mut TraceStats,
        slot: &mut PreparedFibre,
    ) -> Rgb {
        let ray = Ray::new(p, d);
        stats.rays += 1;
        let event = medium.sample_flight_in_cone(
            &ray,
            self.cone.footprint(),
            self.beta,
            &mut || sampler.next_1d(),
            &mut stats.tracking,
            |limit| {
                scene
                    .geometry
                    .intersect(&ray, limit)
                    .map_or(f32::INFINITY, |h| h.t)
            },
        );
        let Some(v2) = event.scatter else {
            return Rgb::ZERO;
        };
        let beta = self.beta * event.weight * (f_over_q * w);
        if beta.is_black() {
            return Rgb::ZERO;
        }
        let phase2 = v2.phase.prepare(-d, slot);
        let st = self.stack;
        let p2 = v2.p;
        // The same roulette as the vertex's own sun shadow ray ([`SunLean::shadow_survival`]).
        let survival = match scene.lights.get(light) {
            Some(crate::light::Light::Distant { to_light, .. }) => medium
                .sun_transmittance_hint(p2, *to_light)
                .map(|t| ShadowRoulette::Light(light, SunLean::shadow_survival(t))),
            _ => None,
        }
        .unwrap_or(ShadowRoulette::Off);
        let mut li = None;
        let c = estimate_direct(
            scene,
            p2,
            |_| (p2, st),
            |wi| phase2.eval(wi),
            ShadowMode::Transparent,
            self.cone.footprint(),
            sampler,
            stats,
            &mut li,
            Some(light),
            &mut None,
            survival,
        );
        if li == Some(light) {
            beta * c
        } else {
            Rgb::ZERO
        }
    }

    /// 2. An escaped ray sees the infinite lights.
    fn escape(&mut self, scene: &Scene) {
        // Without NEE at the last vertex every light's weight is 1: where the escape sees the
        // same radiance in every direction (and no light has a layer), that sum, found at load.
        if !self.prev.did_nee {
            if let Some(e) = scene.escape_radiance {
                self.radiance += self.beta * e;
                return;
            }
        }
        let through = self.manifold_leg == ManifoldLeg::Through;
        let mut layers = [Rgb::ZERO; MAX_LIGHT_LAYERS];
        let e = emitted(scene, self.ray.d, &self.prev, None, through, &mut layers);
        self.add_emitted(scene, e, &layers);
    }

    /// 3–5. What the ray hit: a light, a false or null boundary, or a surface.
    fn boundary_step(
        &mut self,
        scene: &Scene,
        hit: &Hit,
        sampler: &mut PixelSampler,
        stats: &mut TraceStats,
    ) -> Step {
        let oi = match scene.shape_owner[hit.shape as usize] {
            ShapeOwner::Light(li) => {
                self.hit_light(scene, hit, li as usize);
                return Step::Stop;
            }
            ShapeOwner::Object(oi) => oi,
        };
        let obj = &scene.objects[oi as usize];
        let entering = self.ray.d.dot(hit.ng) < 0.0;
        let guided_from = self.guided_from.take();
        if crosses_unchanged(scene, &self.stack, obj, oi, entering) {
            return self.cross_boundary(scene, hit, oi, entering, sampler);
        }
        let guided = guided_from == Some(oi) && !entering;
        self.surface_interaction(scene, hit, oi, entering, guided, sampler, stats)
    }

    /// 3. Sphere lights are emitters only.
    fn hit_light(&mut self, scene: &Scene, hit: &Hit, light: usize) {
        let through = self.manifold_leg == ManifoldLeg::Through;
        if self.ray.d.dot(hit.ng) < 0.0 {
            let mut layers = [Rgb::ZERO; MAX_LIGHT_LAYERS];
            let e = emitted(
                scene,
                self.ray.d,
                &self.prev,
                Some((light, hit.p)),
                through,
                &mut layers,
            );
            self.add_emitted(scene, e, &layers);
        }
        if self.aov.is_none() {
            self.aov = Some((Rgb::ZERO, hit.ns, (hit.p - self.origin).length()));
        }
    }

    /// 4. False intersections with lower-priority boundaries, and null boundaries, only
    ///    update the stack.
    fn cross_boundary(
        &mut self,
        scene: &Scene,
        hit: &Hit,
        oi: u32,
        entering: bool,
        sampler: &mut PixelSampler,
    ) -> Step {
        // The manifold connection passes null and false boundaries on both sides of the
        // interface, as its projection and shadow rays do: `manifold_leg` is kept.
        if entering {
            self.entry_normal = hit.ns;
            let obj = &scene.objects[oi as usize];
            let width = self.footprint(obj, hit);
            enter(scene, &mut self.stack, oi, hit.uv(), width, || {
                sampler.next_1d()
            });
        } else {
            self.stack.remove(oi);
        }
        self.crossings += 1;
        if self.crossings > 64 * MAX_NESTING as u32 + scene.film.max_depth {
            return Step::Stop;
        }
        self.ray = Ray::new(hit.spawn_origin(self.ray.d), self.ray.d);
        Step::Trace
    }

    /// 5. A true surface interaction: the boundary BSDF for the media meeting there, NEE
    ///    through it, and a sampled reflection or refraction.
    // The hit's parts and the path's sampler and counters, as the other steps take them.
    #[allow(clippy::too_many_arguments)]
    fn surface_interaction(
        &mut self,
        scene: &Scene,
        hit: &Hit,
        oi: u32,
        entering: bool,
        guided: bool,
        sampler: &mut PixelSampler,
        stats: &mut TraceStats,
    ) -> Step {
        let obj = &scene.objects[oi as usize];
        let transmits = obj.surface.transmits();
        let outside_ior = self.stack.ior(&scene.objects, Some(oi));
        let width_uv = self.footprint(obj, hit);
        let u_mask = if matches!(obj.surface, ObjectSurface::Blend(_)) {
            sampler.next_1d()
        } else {
            0.0
        };
        let Some(surface) = boundary_surface_at(obj, outside_ior, hit.uv(), width_uv, u_mask)
        else {
            return Step::Stop;
        };
        // Opaque surfaces are two-sided: seen from behind, flip the frame.
        let (ng, ns) = if !transmits && !entering {
            (-hit.ng, -hit.ns)
        } else {
            (hit.ng, hit.ns)
        };
        let frame = Frame::from_normal(ns);
        let wo = -self.ray.d;
        if self.aov.is_none() {
            let distance = (hit.p - self.origin).length();
            match (obj.medium.is_some() && transmits, obj.aov_albedo) {
                // The boundary of an interior with an artist albedo (skin): the interior's
                // albedo, noise-free, at the boundary.
                (true, Some(albedo)) => self.aov = Some((albedo, hit.ns, distance)),
                // Other interiors (glass, fabric): looked through; a scatter inside sets the
                // AOVs with this boundary's normal.
                (true, None) => self.entry_normal = hit.ns,
                (false, _) => self.aov = Some((surface.albedo_hint(), hit.ns, distance)),
            }
        }
        self.depth += 1;
        stats.vertices += 1;
        if self.depth >= scene.film.max_depth {
            return Step::Stop;
        }

        // The interior we arrived from: if it does NEE at interior vertices, the light is
        // already accounted for through transparent shadows; no exit-point NEE here.
        let from_interior_nee =
            !entering && transmits && obj.nee == NeeStrategy::Interior && obj.medium.is_some();
        let do_nee = !surface.is_delta() && !from_interior_nee;
        // Straight from an `exit_guided` interior vertex: the guided connection made there
        // replaces exit-point NEE here (BTDF sampling below is MIS-weighted against it).
        let guided = guided && do_nee;
        if do_nee && !guided {
            // A shadow ray into an interior resolved per walk enters it here.
            let entry = if obj.walk.is_some() && transmits {
                shadow_entry(obj, hit, width_uv, sampler)
            } else {
                None
            };
            let at = SurfaceVertex {
                hit,
                oi,
                transmits,
                ng,
                frame,
                wo,
                entry,
            };
            let mut li = None;
            let c = at.direct_light(
                scene,
                &surface,
                self.stack,
                self.cone.footprint(),
                sampler,
                stats,
                &mut li,
            );
            self.add_light(scene, li, self.beta * c);
        }

        let uc = sampler.next_1d();
        let u = sampler.next_2d();
        let wo_local = frame.to_local(wo);
        let Some(bs) = surface.sample(wo_local, uc, u) else {
            return Step::Stop;
        };
        if !(bs.pdf > 0.0) || bs.weight.is_black() {
            return Step::Stop;
        }
        let wi = frame.to_world(bs.wi).normalize();
        // The geometric side must agree with the lobe, or the path would leak through the mesh.
        let geometric_transmit = (wi.dot(ng) > 0.0) != (wo.dot(ng) > 0.0);
        if geometric_transmit != bs.is_transmission {
            return Step::Stop;
        }
        self.manifold_leg = match self.manifold_leg {
            ManifoldLeg::Inside
                if !entering
                    && bs.is_delta
                    && bs.is_transmission
                    && manifold::is_manifold_interface(obj, outside_ior) =>
            {
                ManifoldLeg::Through
            }
            // An index-matched pass-through, which the connection's walk to the interface
            // (plain dielectrics only, not blends) and its shadow ray (any) also cross.
            ManifoldLeg::Inside
                if bs.is_delta
                    && bs.is_transmission
                    && bs.eta == 1.0
                    && matches!(obj.surface, ObjectSurface::Dielectric(_)) =>
            {
                ManifoldLeg::Inside
            }
            ManifoldLeg::Through if bs.is_delta && bs.is_transmission && bs.eta == 1.0 => {
                ManifoldLeg::Through
            }
            _ => ManifoldLeg::None,
        };
        self.beta *= bs.weight;
        if !bs.is_delta {
            self.cone.widen();
        }
        if bs.is_transmission {
            self.eta_scale *= bs.eta * bs.eta;
            if wi.dot(hit.ng) < 0.0 {
                enter(scene, &mut self.stack, oi, hit.uv(), width_uv, || {
                    sampler.next_1d()
                });
            } else {
                self.stack.remove(oi);
            }
        }
        if !(bs.is_delta || from_interior_nee) {
            let guided_prev = (guided && bs.is_transmission).then(|| direct::GuidedPrev {
                x: self.prev.p,
                phase_pdf: self.prev.pdf,
                reverse_pdf: surface.pdf(bs.wi, wo_local),
            });
            self.prev = PrevVertex {
                p: hit.p,
                pdf: bs.pdf,
                did_nee: if guided {
                    guided_prev.is_some()
                } else {
                    do_nee
                },
                guided: guided_prev,
            };
        } else if bs.is_delta && !from_interior_nee {
            self.prev.did_nee = false;
        }
        self.ray = Ray::new(hit.spawn_origin(wi), wi);
        self.continue_with_roulette(scene.film.roulette, sampler)
    }

    /// The ray cone's footprint at `hit` on `obj` in texture units (0, unused, for objects
    /// with nothing textured: their `uv_scale` is 0).
    #[inline]
    fn footprint(&self, obj: &Object, hit: &Hit) -> f32 {
        if obj.uv_scale > 0.0 {
            self.cone
                .width_uv(obj.uv_scale_at(hit.prim), self.ray.d.dot(hit.ng))
        } else {
            0.0
        }
    }

    /// Russian roulette after a scattering event: [`Step::Trace`] if the path survives.
    fn continue_with_roulette(&mut self, roulette: Roulette, sampler: &mut PixelSampler) -> Step {
        if russian_roulette(
            &mut self.beta,
            self.eta_scale,
            self.depth,
            roulette,
            sampler,
        ) {
            Step::Trace
        } else {
            Step::Stop
        }
    }
}

/// True when the ray crosses the boundary of `obj` (object `oi`) without interacting: a null
/// boundary, or a false intersection of a transmissive one ([`is_false_intersection`]). A
/// null boundary (it transmits) is crossed whatever the stack holds, so it is asked first:
/// a bounds box skips the stack's priority search at both of its crossings.
#[inline]
fn crosses_unchanged(
    scene: &Scene,
    stack: &InteriorStack,
    obj: &Object,
    oi: u32,
    entering: bool,
) -> bool {
    matches!(obj.surface, ObjectSurface::Null)
        || (obj.surface.transmits() && is_false_intersection(scene, stack, oi, entering))
}

/// The medium a shadow ray entering `obj`'s per-walk interior at `hit` uses (out of line:
/// untextured scenes never get here).
#[cold]
#[inline(never)]
fn shadow_entry(
    obj: &Object,
    hit: &Hit,
    width_uv: f32,
    sampler: &mut PixelSampler,
) -> Option<crate::medium::WalkMedium> {
    let w = obj.walk.as_deref()?;
    let r = if w.is_random() {
        sampler.next_1d()
    } else {
        0.0
    };
    Some(w.resolve(hit.uv(), width_uv, r))
}

/// A surface vertex seen from the path, for next event estimation through its BSDF.
struct SurfaceVertex<'a> {
    hit: &'a Hit,
    oi: u32,
    transmits: bool,
    /// Geometric normal, flipped towards the viewer for two-sided opaque surfaces.
    ng: Vec3,
    /// Shading frame.
    frame: Frame,
    /// Direction towards the previous vertex.
    wo: Vec3,
    /// The medium a shadow ray entering the object's per-walk interior here uses.
    entry: Option<crate::medium::WalkMedium>,
}

impl SurfaceVertex<'_> {
    /// NEE through the boundary BSDF (exit-point NEE for the interior behind it), MIS against
    /// BSDF sampling; shadow rays see opaque dielectric boundaries.
    // The path's state this NEE reads, passed as parts (the vertex is borrowed beside them).
    #[allow(clippy::too_many_arguments)]
    fn direct_light(
        &self,
        scene: &Scene,
        surface: &Surface,
        stack: InteriorStack,
        cone: crate::medium::RayFootprint,
        sampler: &mut PixelSampler,
        stats: &mut TraceStats,
        chosen: &mut Option<usize>,
    ) -> Rgb {
        let (hit, oi, ng, frame, wo) = (self.hit, self.oi, self.ng, self.frame, self.wo);
        let transmits = self.transmits;
        let wo_local = frame.to_local(wo);
        estimate_direct(
            scene,
            hit.p,
            |wi| {
                let mut s = stack;
                let crosses = (wi.dot(ng) > 0.0) != (wo.dot(ng) > 0.0);
                if crosses && transmits {
                    if wi.dot(hit.ng) < 0.0 {
                        match self.entry {
                            Some(m) => s.push_walk(oi, m),
                            None => s.push(oi),
                        }
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
            cone,
            sampler,
            stats,
            chosen,
            None,
            &mut None,
            ShadowRoulette::Off,
        )
    }
}

/// Russian roulette after a scattering event ([`Roulette`]): from `roulette.start_depth`
/// events on, a path whose throughput m = max_c β_c · η-scale is below `roulette.threshold`
/// survives with probability m / threshold and is reweighted by its inverse. The η-scale undoes
/// the radiance compression of refraction so that entering skin does not trigger spurious
/// termination (as in pbrt-v4). Returns false when the path is terminated.
fn russian_roulette(
    beta: &mut Rgb,
    eta_scale: f32,
    depth: u32,
    roulette: Roulette,
    sampler: &mut PixelSampler,
) -> bool {
    if beta.is_black() || !beta.is_finite() {
        return false;
    }
    if depth < roulette.start_depth {
        return true;
    }
    let q = (beta.max_component() * eta_scale / roulette.threshold).min(1.0);
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

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::*;
    use crate::sampling::Rng;
    use crate::scene::load_scene_str;

    /// A glass sphere without an interior (an object on the stack with no medium) beside a
    /// sphere of medium, under a sky.
    const SPHERES: &str = r#"
[camera]
eye = [0.0, 0.0, 5.0]
look_at = [0.0, 0.0, 0.0]
fov = 40
[film]
width = 8
height = 8
spp = 1
[[light]]
type = "environment"
radiance = 0.5
[[object]]
name = "glass"
shape = "sphere"
center = [1.0, 0.0, 0.0]
radius = 0.6
surface = { type = "dielectric", ior = 1.5 }
[[object]]
name = "fog"
shape = "sphere"
center = [-1.0, 0.0, 0.0]
radius = 0.8
interior = { type = "homogeneous", albedo = 0.9, attenuation = 1.0 }
"#;

    /// Fog (no surface: a null boundary) and glass at priorities 0 and 2, an opaque diffuse
    /// ball at priority 1, and a null boundary at priority 3.
    const NESTED: &str = r#"
[camera]
eye = [0.0, 0.0, 5.0]
look_at = [0.0, 0.0, 0.0]
fov = 40
[film]
width = 8
height = 8
spp = 1
[[light]]
type = "environment"
radiance = 0.5
[[object]]
name = "fog"
shape = "sphere"
center = [-1.0, 0.0, 0.0]
radius = 0.8
interior = { type = "homogeneous", albedo = 0.9, attenuation = 1.0 }
[[object]]
name = "ball"
shape = "sphere"
center = [0.0, 1.0, 0.0]
radius = 0.3
priority = 1
surface = { type = "lambertian", reflectance = 0.5 }
[[object]]
name = "glass"
shape = "sphere"
center = [1.0, 0.0, 0.0]
radius = 0.6
priority = 2
surface = { type = "dielectric", ior = 1.5 }
interior = { type = "homogeneous", albedo = 0.5, attenuation = 2.0 }
[[object]]
name = "haze"
shape = "sphere"
center = [0.0, -1.0, 0.0]
radius = 0.5
priority = 3
interior = { type = "homogeneous", albedo = 0.9, attenuation = 0.5 }
"#;

    #[test]
    fn a_boundary_is_crossed_unchanged_as_the_search_first_form_decides() {
        let scene = load_scene_str(NESTED, Path::new("nested.toml")).expect("scene");
        let n = scene.objects.len() as u32;
        assert_eq!(n, 4);
        assert!(scene
            .objects
            .iter()
            .any(|o| matches!(o.surface, ObjectSurface::Null)));
        assert!(scene.objects.iter().any(|o| !o.surface.transmits()));
        let mut rng = Rng::new(5, 9);
        let (mut crossed, mut met) = (0, 0);
        for _ in 0..20_000 {
            // Any stack of distinct objects (silhouette cases included: an object entered
            // twice, left without being entered).
            let mut stack = InteriorStack::new();
            for _ in 0..(rng.next_u32() % 4) {
                stack.push(rng.next_u32() % n);
            }
            let oi = rng.next_u32() % n;
            let entering = rng.next_u32().is_multiple_of(2);
            let obj = &scene.objects[oi as usize];
            // The order the test had before null boundaries were asked first.
            let searched_first = obj.surface.transmits()
                && (is_false_intersection(&scene, &stack, oi, entering)
                    || matches!(obj.surface, ObjectSurface::Null));
            let fast = crosses_unchanged(&scene, &stack, obj, oi, entering);
            assert_eq!(
                fast,
                searched_first,
                "object {oi}, entering {entering}, stack {:?}",
                stack.entries()
            );
            if fast {
                crossed += 1;
            } else {
                met += 1;
            }
        }
        assert!(crossed > 1000 && met > 1000, "{crossed} crossed, {met} met");
    }

    /// The sky, with or without a delta sun, a second sky, a disc sun or a sphere light.
    fn sky_scene(extra: &str) -> Scene {
        let text = format!(
            r#"
[camera]
eye = [0.0, 0.0, 5.0]
look_at = [0.0, 0.0, 0.0]
fov = 40
[film]
width = 8
height = 8
spp = 1
[[light]]
type = "environment"
radiance = [0.25, 0.35, 0.55]
{extra}
[[object]]
name = "fog"
shape = "sphere"
center = [0.0, 0.0, 0.0]
radius = 0.8
interior = {{ type = "homogeneous", albedo = 0.9, attenuation = 1.0 }}
"#
        );
        load_scene_str(&text, Path::new("sky.toml")).expect("scene")
    }

    #[test]
    fn an_escape_without_nee_adds_what_the_lights_give_every_direction() {
        let sun = "[[light]]\ntype = \"distant\"\ndirection = [-0.5, 0.8, 0.4]\nirradiance = [4.0, 3.7, 3.3]\n";
        let sky2 = "[[light]]\ntype = \"environment\"\nradiance = [0.1, 0.3, 0.7]\n";
        let disc = "[[light]]\ntype = \"distant\"\ndirection = [0.0, 1.0, 0.0]\nirradiance = 3.0\nangular_radius = 20.0\n";
        let ball = "[[light]]\ntype = \"sphere\"\ncenter = [0.0, 3.0, 0.0]\nradius = 0.5\nradiance = 8.0\n";
        let cases = [
            (String::new(), true),
            (sun.to_string(), true),
            (format!("{sun}{sky2}"), true),
            (ball.to_string(), true),
            (disc.to_string(), false),
            (format!("{sun}{disc}"), false),
        ];
        let mut rng = Rng::new(3, 4);
        for (extra, direction_free) in cases {
            let scene = sky_scene(&extra);
            assert_eq!(scene.escape_radiance.is_some(), direction_free, "{extra}");
            let mut seen_disc = false;
            for _ in 0..3000 {
                let z = 2.0 * rng.next_f32() - 1.0;
                let phi = 2.0 * std::f32::consts::PI * rng.next_f32();
                let r = (1.0 - z * z).max(0.0).sqrt();
                let d = Vec3::new(r * phi.cos(), r * phi.sin(), z);
                let beta = Rgb([rng.next_f32(), rng.next_f32() * 3.0, rng.next_f32()]);
                for through in [false, true] {
                    let mut path = PathState::new(Ray::new(Vec3::new(0.0, 0.0, 2.0), d), 0.0);
                    path.beta = beta;
                    path.radiance = Rgb([0.5, 0.25, 0.125]);
                    if through {
                        path.manifold_leg = ManifoldLeg::Through;
                    }
                    let mut layers = [Rgb::ZERO; MAX_LIGHT_LAYERS];
                    let e = emitted(&scene, d, &path.prev, None, through, &mut layers);
                    let expected = path.radiance + beta * e;
                    seen_disc |= e
                        != emitted(
                            &scene,
                            Vec3::new(0.0, 0.0, -1.0),
                            &path.prev,
                            None,
                            through,
                            &mut layers,
                        );
                    path.escape(&scene);
                    assert_eq!(
                        path.radiance.0.map(f32::to_bits),
                        expected.0.map(f32::to_bits),
                        "{extra} d = {d:?}"
                    );
                }
            }
            // A disc sun is seen in some directions and not others.
            assert_eq!(seen_disc, !direction_free, "{extra}");
        }
    }

    #[test]
    fn a_step_in_vacuum_is_the_first_hit_with_its_cone_advanced() {
        let scene = load_scene_str(SPHERES, Path::new("spheres.toml")).expect("scene");
        let glass = scene
            .objects
            .iter()
            .position(|o| o.medium.is_none())
            .expect("glass") as u32;
        let mut rng = Rng::new(11, 2);
        let (mut hits, mut misses) = (0, 0);
        for r in 0..4000 {
            let o = Vec3::new(rng.next_f32() - 0.5, rng.next_f32() - 0.5, 1.0) * 4.0;
            let target = Vec3::new(rng.next_f32() - 0.5, rng.next_f32() - 0.5, 0.0) * 5.0;
            let ray = Ray::new(o, (target - o).normalize());
            let expected = scene.geometry.intersect(&ray, f32::INFINITY);
            // An empty stack (the vacuum's own step) and the glass on the stack (no medium:
            // the general step's vacuum), each with a stale hit in the slot.
            for inside_glass in [false, true] {
                let mut path = PathState::new(ray, 0.01);
                path.cone.width = 0.5;
                if inside_glass {
                    path.stack.push(glass);
                }
                let mut sampler = PixelSampler::new(1, 0, 0, r);
                sampler.start_vertex();
                let (mut stats, mut slots) = (TraceStats::default(), None);
                let mut hit = Some(Hit {
                    t: -1.0,
                    ..expected.unwrap_or_else(|| {
                        scene
                            .geometry
                            .intersect(&Ray::new(Vec3::new(1.0, 0.0, 3.0), -Vec3::Z), 9.0)
                            .expect("the glass")
                    })
                });
                let step =
                    path.interior_step(&scene, &mut sampler, &mut stats, &mut slots, &mut hit);
                assert_eq!(step, Step::Boundary, "ray {r}");
                assert_eq!(hit, expected, "ray {r}");
                let width = expected.map_or(0.5, |h| 0.5 + 0.01 * h.t);
                assert_eq!(path.cone.width.to_bits(), width.to_bits(), "ray {r}");
                assert_eq!(sampler.position(), (1, 0), "ray {r}: no number drawn");
                assert!(slots.is_none(), "ray {r}");
            }
            if expected.is_some() {
                hits += 1;
            } else {
                misses += 1;
            }
        }
        assert!(hits > 500 && misses > 500, "{hits} hits, {misses} misses");
    }
}
