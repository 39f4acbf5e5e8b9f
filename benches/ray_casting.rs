//! Ray casting: incoherent closest-hit and occlusion rays per second against a 20,480-triangle
//! icosphere (the skin peer scene's boundary), through velour's BVH traversal (conservative
//! node test, watertight triangle test) and through `obvhs`'s own traversal and triangle test
//! on the same BVH build, in one run, one thread.
//!
//! Run: `cargo bench --bench ray_casting`. Three ray sets: rays from outside through the
//! sphere's bounding box, rays from inside in random directions (what a walk inside the skin
//! traces to find the boundary), and short rays from inside (a walk's free flight in a dense
//! medium, traced only up to the sampled distance). Times are on-CPU times of the thread, best
//! of five passes. `RAY_CASTING_SUBDIV=n` changes the icosphere's subdivision level (default 5),
//! `RAY_CASTING_RAYS=n` the number of rays per set (default 200,000; fewer for callgrind).
//! `RAY_CASTING_SET=k` times only set `k` (0, 1, 2 in the order above; for per-set callgrind
//! counts). `RAY_CASTING_DUMP=path` writes the mesh and the three ray sets to `path` (little-endian:
//! `u32` vertex count, `f32` xyz per vertex, `u32` triangle count, `u32` indices per
//! triangle, `u32` set count, then per set `u32` ray count and `f32` origin xyz, direction xyz,
//! `t_max` per ray) for the peer benches in `tools/peers/embree/`.
//!
//! `RAY_CASTING_RECORDED=path` times instead the queries a render made, recorded with the
//! cargo feature `ray-log` (`VELOUR_RAY_LOG=path velour render …`, format in
//! `velour::geometry::ray_log`): on a geometry built from the log's meshes, every query is
//! first replayed and checked against the recorded answer bit for bit, then timed as
//! recorded (closest, occlusion or closest-and-beyond), every query as a closest-hit query
//! and every query as an occlusion query, for the whole mix and per bucket of recorded kind
//! and `t_max` ([`bucket`]; the Embree peer uses the same buckets).

use std::time::Duration;

use glam::Vec3A;
use obvhs::cwbvh::builder::build_cwbvh;
use obvhs::ray::{Ray as ORay, RayHit};
use obvhs::rt_triangle::RtTriangle;
use obvhs::BvhBuildParams;
use velour::geometry::ray_log::{Answer, QueryKind, RayLog};
use velour::geometry::{icosphere, SceneGeometry, Shape, TriangleMesh};
use velour::math::{Ray, Vec3};
use velour::sampling::{sample_uniform_sphere, Rng};

/// On-CPU time of the calling thread in seconds (`CLOCK_THREAD_CPUTIME_ID`, nanosecond
/// resolution; `/proc/thread-self/schedstat` advances in scheduler ticks on some kernels).
fn thread_cpu() -> f64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `ts` is a valid, writable timespec.
    let rc = unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) };
    if rc != 0 {
        return f64::NAN;
    }
    ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9
}

struct RaySet {
    name: &'static str,
    rays: Vec<(Ray, f32)>,
}

fn ray_sets(n: usize) -> Vec<RaySet> {
    let mut rng = Rng::new(7, 1);
    let outside = (0..n)
        .map(|_| {
            let target =
                (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - Vec3::ONE) * 1.1;
            let o = sample_uniform_sphere(rng.next_2d()) * 4.0;
            (Ray::new(o, (target - o).normalize()), f32::INFINITY)
        })
        .collect();
    let inside = (0..n)
        .map(|_| {
            let o = sample_uniform_sphere(rng.next_2d()) * rng.next_f32().cbrt() * 0.95;
            (
                Ray::new(o, sample_uniform_sphere(rng.next_2d())),
                f32::INFINITY,
            )
        })
        .collect();
    let short = (0..n)
        .map(|_| {
            let o = sample_uniform_sphere(rng.next_2d()) * rng.next_f32().cbrt() * 0.95;
            let t = -(1.0 - rng.next_f32()).ln() / 24.0;
            (Ray::new(o, sample_uniform_sphere(rng.next_2d())), t)
        })
        .collect();
    vec![
        RaySet {
            name: "outside → sphere",
            rays: outside,
        },
        RaySet {
            name: "inside, to the boundary",
            rays: inside,
        },
        RaySet {
            name: "inside, short (σ_t = 24)",
            rays: short,
        },
    ]
}

/// Rays per second of `f` over `rays`, best of `repeats` passes (on-CPU time).
fn rate(rays: &[(Ray, f32)], repeats: usize, mut f: impl FnMut(&Ray, f32) -> bool) -> (f64, usize) {
    let mut best = f64::INFINITY;
    let mut hits = 0;
    for _ in 0..repeats {
        hits = 0;
        let t0 = thread_cpu();
        for (r, t) in rays {
            hits += usize::from(f(r, *t));
        }
        best = best.min(thread_cpu() - t0);
    }
    (rays.len() as f64 / best, hits)
}

/// Writes the mesh and the ray sets for the peer benches (format in the module docs).
fn dump(
    path: &str,
    positions: &[Vec3],
    indices: &[[u32; 3]],
    sets: &[RaySet],
) -> std::io::Result<()> {
    let mut out: Vec<u8> = Vec::new();
    let u32s = |out: &mut Vec<u8>, v: u32| out.extend_from_slice(&v.to_le_bytes());
    u32s(&mut out, positions.len() as u32);
    for p in positions {
        for c in [p.x, p.y, p.z] {
            out.extend_from_slice(&c.to_le_bytes());
        }
    }
    u32s(&mut out, indices.len() as u32);
    for t in indices {
        for i in t {
            u32s(&mut out, *i);
        }
    }
    // Every set, whatever RAY_CASTING_SET selects for timing: the Embree peer selects by index.
    u32s(&mut out, sets.len() as u32);
    for set in sets {
        u32s(&mut out, set.rays.len() as u32);
        for (r, t) in &set.rays {
            for c in [r.o.x, r.o.y, r.o.z, r.d.x, r.d.y, r.d.z, *t] {
                out.extend_from_slice(&c.to_le_bytes());
            }
        }
    }
    std::fs::write(path, out)
}

fn main() {
    if let Ok(path) = std::env::var("RAY_CASTING_RECORDED") {
        recorded(&path);
        return;
    }
    let subdiv = std::env::var("RAY_CASTING_SUBDIV")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(5);
    let mesh = icosphere(subdiv);
    let triangles: Vec<RtTriangle> = mesh
        .indices
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| Vec3A::from(mesh.positions[i as usize]));
            RtTriangle::new(a, b, c)
        })
        .collect();
    let (mesh_positions, mesh_indices) = (mesh.positions.clone(), mesh.indices.clone());
    let geometry = SceneGeometry::build(vec![Shape::Mesh(mesh)]).expect("icosphere geometry");
    let stock = build_cwbvh(
        &triangles,
        BvhBuildParams::medium_build(),
        &mut Duration::default(),
    );
    println!(
        "icosphere: {} triangles, velour BVH depth {}",
        triangles.len(),
        geometry.bvh_depth()
    );
    let n = std::env::var("RAY_CASTING_RAYS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(200_000);
    println!(
        "{:<28} {:>14} {:>14} {:>14} {:>10}",
        "rays", "velour closest", "velour occl.", "obvhs closest", "velour/obvhs"
    );
    let sets = ray_sets(n);
    if let Ok(path) = std::env::var("RAY_CASTING_DUMP") {
        dump(&path, &mesh_positions, &mesh_indices, &sets).expect("ray dump");
        println!("wrote the mesh and the rays to {path}");
    }
    let only: Option<usize> = std::env::var("RAY_CASTING_SET")
        .ok()
        .and_then(|s| s.parse().ok());
    for (k, set) in sets.into_iter().enumerate() {
        if only.is_some_and(|o| o != k) {
            continue;
        }
        let (v, hv) = rate(&set.rays, 5, |r, t| geometry.intersect(r, t).is_some());
        let (o, _) = rate(&set.rays, 5, |r, t| geometry.occluded(r, t));
        let (s, hs) = rate(&set.rays, 5, |r, t| {
            let ray = ORay::new(Vec3A::from(r.o), Vec3A::from(r.d), 0.0, t);
            let mut hit = RayHit::none();
            stock.ray_traverse(ray, &mut hit, |ray, id| {
                triangles[stock.primitive_indices[id] as usize].intersect(ray)
            })
        });
        println!(
            "{:<28} {:>12.2} M {:>12.2} M {:>12.2} M {:>10.2}   (hits {hv} / {hs})",
            set.name,
            v / 1e6,
            o / 1e6,
            s / 1e6,
            v / s
        );
    }
}

/// The finite `t_max` classes of [`bucket`]: below these bounds.
const T_MAX_BOUNDS: [(f32, &str); 3] = [
    (0.1, "t_max < 0.1"),
    (1.0, "0.1 ≤ t_max < 1"),
    (f32::INFINITY, "t_max finite ≥ 1"),
];

/// Buckets of [`bucket`]: five classes for each of the three kinds.
const BUCKETS: usize = 15;

/// A recorded query's bucket: its kind (0 closest, 1 occlusion, 2 closest-and-beyond) × 5 +
/// its class: 0 unbounded from outside the meshes' bounding box `[lo, hi]`, 1 unbounded from
/// inside it (both ends included), then the finite classes of [`T_MAX_BOUNDS`].
/// `tools/peers/embree/embree_rays.cpp` computes the same.
fn bucket(kind: QueryKind, ray: &Ray, t_max: f32, lo: Vec3, hi: Vec3) -> usize {
    let class = if t_max == f32::INFINITY {
        usize::from(ray.o.cmpge(lo).all() && ray.o.cmple(hi).all())
    } else {
        2 + T_MAX_BOUNDS
            .iter()
            .position(|&(b, _)| t_max < b)
            .unwrap_or(T_MAX_BOUNDS.len() - 1)
    };
    kind as usize * 5 + class
}

fn bucket_name(b: usize) -> String {
    let kind = ["closest", "occlusion", "beyond"][b / 5];
    let class = match b % 5 {
        0 => "t_max = ∞, from outside",
        1 => "t_max = ∞, from inside box",
        c => T_MAX_BOUNDS[c - 2].1,
    };
    format!("{kind}, {class}")
}

/// One replayable query: the ray, `t_max`, and its recorded kind.
type Replay = (Ray, f32, QueryKind);

/// Answers `q` as recorded, in the log's numbering of triangles.
fn answer(geometry: &SceneGeometry, q: &Replay) -> Answer {
    let record = |h: Option<velour::geometry::Hit>, clear: bool| {
        h.map_or(Answer::MISS, |h| Answer {
            hit: true,
            clear,
            t: h.t,
            shape: h.shape,
            prim: h.prim,
        })
    };
    match q.2 {
        QueryKind::Closest => record(geometry.intersect(&q.0, q.1), false),
        QueryKind::Beyond => {
            let (h, clear) = geometry.intersect_and_beyond(&q.0, q.1);
            record(h, clear)
        }
        QueryKind::Occluded => Answer {
            hit: geometry.occluded(&q.0, q.1),
            ..Answer::MISS
        },
    }
}

/// `RAY_CASTING_RECORDED`: the recorded queries (see the module docs).
fn recorded(path: &str) {
    let log = RayLog::read_file(std::path::Path::new(path)).expect("a ray log");
    let (positions, indices) = log.merged_mesh();
    let ntri = indices.len();
    let positions_lo_hi = positions.iter().fold(
        (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
        |(lo, hi), p| (lo.min(*p), hi.max(*p)),
    );
    let geometry = SceneGeometry::build(vec![Shape::Mesh(TriangleMesh {
        positions,
        normals: None,
        uvs: None,
        indices,
    })])
    .expect("the log's meshes");
    println!(
        "recorded: {path}: {} queries of {} (every {}), {} triangles in {} mesh(es), velour BVH depth {}",
        log.queries.len(),
        log.seen,
        log.every,
        ntri,
        log.meshes.len(),
        geometry.bvh_depth()
    );
    let all: Vec<Replay> = log
        .queries
        .iter()
        .map(|q| (Ray::new(q.origin, q.dir), q.t_max, q.kind))
        .collect();
    // The replay against the recording, bit for bit (hit, clear, distance, triangle).
    let mut mismatches = 0usize;
    let mut occl_mismatches = 0usize;
    for (q, r) in log.queries.iter().zip(&all) {
        // The replay's geometry is the log's meshes merged into one: its triangle numbers
        // are the log's global ones, and its one shape is shape 0.
        let got = answer(&geometry, r);
        let recorded = Answer {
            prim: if q.answer.hit && r.2 != QueryKind::Occluded {
                log.global_prim(q.answer.shape, q.answer.prim)
                    .unwrap_or(u32::MAX)
            } else {
                q.answer.prim
            },
            ..q.answer
        };
        if got.hit != recorded.hit
            || got.clear != recorded.clear
            || got.t.to_bits() != recorded.t.to_bits()
            || got.prim != recorded.prim
        {
            mismatches += 1;
        }
        // An occlusion query hits exactly when a closest-hit query finds a hit.
        if r.2 != QueryKind::Occluded && geometry.occluded(&r.0, r.1) != q.answer.hit {
            occl_mismatches += 1;
        }
    }
    println!(
        "replay: {mismatches} of {} answers differ from the recording; occlusion disagrees with the recorded closest hit on {occl_mismatches}",
        all.len()
    );
    let lo = positions_lo_hi.0;
    let hi = positions_lo_hi.1;
    let mut buckets: Vec<Vec<Replay>> = vec![Vec::new(); BUCKETS];
    for r in &all {
        buckets[bucket(r.2, &r.0, r.1, lo, hi)].push(*r);
    }
    let time = |rays: &[Replay]| {
        let (rec, hr) = rate_replay(rays, 5, |q| answer(&geometry, q).hit);
        let (c, hc) = rate_replay(rays, 5, |q| geometry.intersect(&q.0, q.1).is_some());
        let (o, ho) = rate_replay(rays, 5, |q| geometry.occluded(&q.0, q.1));
        (rec, c, o, hr, hc, ho)
    };
    println!(
        "{:<38} {:>9} {:>7} {:>14} {:>14} {:>14}   hits (as recorded / closest / occl.)",
        "rays", "count", "share", "velour as rec.", "velour closest", "velour occl."
    );
    let row = |name: &str, rays: &[Replay]| {
        let (rec, c, o, hr, hc, ho) = time(rays);
        println!(
            "{:<38} {:>9} {:>6.1}% {:>12.2} M {:>12.2} M {:>12.2} M   ({hr} / {hc} / {ho})",
            name,
            rays.len(),
            100.0 * rays.len() as f64 / all.len() as f64,
            rec / 1e6,
            c / 1e6,
            o / 1e6
        );
    };
    row("whole mix", &all);
    for (b, rays) in buckets.iter().enumerate() {
        if !rays.is_empty() {
            row(&bucket_name(b), rays);
        }
    }
}

/// [`rate`] over recorded queries.
fn rate_replay(
    rays: &[Replay],
    repeats: usize,
    mut f: impl FnMut(&Replay) -> bool,
) -> (f64, usize) {
    let mut best = f64::INFINITY;
    let mut hits = 0;
    for _ in 0..repeats {
        hits = 0;
        let t0 = thread_cpu();
        for q in rays {
            hits += usize::from(f(q));
        }
        best = best.min(thread_cpu() - t0);
    }
    (rays.len() as f64 / best, hits)
}
