//! Level-set boundaries: closest-hit rays per second against level-set spheres of radius 24, 96
//! and 192 voxels (written as `tests/common/levelset.rs` writes them: exact distances in a
//! 3-voxel band), next to the analytic sphere and a 20,480-triangle icosphere of the same
//! radius, through `SceneGeometry`, one thread, in one run.
//!
//! Run: `cargo bench --bench levelset`. Two ray sets: from outside (distance 4) towards points
//! of the box [−1.1, 1.1]³, and from inside in random directions. Times are on-CPU times of
//! the thread, best of five passes. `LEVELSET_BENCH_RAYS=n` changes the number of rays (default
//! 100,000; small counts for `valgrind --tool=callgrind`, whose instruction counts are
//! deterministic).

#[path = "../tests/common/levelset.rs"]
#[allow(dead_code)]
mod levelset;

use std::sync::Arc;

use glam::DVec3;
use velour::geometry::{icosphere, LevelSet, SceneGeometry, Shape};
use velour::math::{Ray, Vec3};
use velour::sampling::{sample_uniform_sphere, Rng};

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

/// Rays per second of closest hits over `rays`, best of five passes, and the hit count.
fn rate(geo: &SceneGeometry, rays: &[Ray]) -> (f64, usize) {
    let mut best = f64::INFINITY;
    let mut hits = 0;
    for _ in 0..5 {
        hits = 0;
        let t0 = thread_cpu();
        for r in rays {
            hits += usize::from(geo.intersect(r, f32::INFINITY).is_some());
        }
        best = best.min(thread_cpu() - t0);
    }
    (rays.len() as f64 / best, hits)
}

fn main() {
    let n: usize = std::env::var("LEVELSET_BENCH_RAYS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(100_000);
    let mut rng = Rng::new(7, 3);
    let outside: Vec<Ray> = (0..n)
        .map(|_| {
            let target =
                (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - Vec3::ONE) * 1.1;
            let o = sample_uniform_sphere(rng.next_2d()) * 4.0;
            Ray::new(o, (target - o).normalize())
        })
        .collect();
    let inside: Vec<Ray> = (0..n)
        .map(|_| {
            let o = sample_uniform_sphere(rng.next_2d()) * rng.next_f32().cbrt() * 0.95;
            Ray::new(o, sample_uniform_sphere(rng.next_2d()))
        })
        .collect();
    let mut cases: Vec<(String, SceneGeometry)> = vec![
        (
            "analytic sphere".to_string(),
            SceneGeometry::build(vec![Shape::Sphere {
                center: Vec3::ZERO,
                radius: 1.0,
            }])
            .expect("sphere"),
        ),
        (
            "icosphere (20,480 triangles)".to_string(),
            SceneGeometry::build(vec![Shape::Mesh(icosphere(5))]).expect("mesh"),
        ),
    ];
    for r in [24.0, 96.0, 192.0] {
        let grid = levelset::sphere_grid(DVec3::ZERO, 1.0, 1.0 / r, 3.0);
        let bricks = grid.brick_count();
        let ls = LevelSet::new(grid).expect("level set");
        cases.push((
            format!("level set R = {r} voxels ({bricks} bricks)"),
            SceneGeometry::build(vec![Shape::LevelSet(Arc::new(ls))]).expect("level set"),
        ));
    }
    println!(
        "{:<40} {:>16} {:>16}",
        "shape", "outside rays/s", "inside rays/s"
    );
    for (name, geo) in &cases {
        let (o, ho) = rate(geo, &outside);
        let (i, hi) = rate(geo, &inside);
        println!("{name:<40} {o:>16.0} {i:>16.0}   ({ho} / {hi} hits)");
    }
}
