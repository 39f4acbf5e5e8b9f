//! Sparse grid and OpenVDB benchmarks: load time against OpenVDB's own `vdb_print`,
//! trilinear lookups per second (coherent and random, one thread) and memory per active voxel.
//!
//! Run: `cargo bench --bench vdb_grid`. The large file is `$VELOUR_BENCH_VDB`, or
//! `target/bench/large.vdb`, made on first use by `tools/vdb/make_large.py` (real OpenVDB).
//! Ratios are measured in one run (machines here are shared and noisy).

use glam::Vec3;
use std::path::PathBuf;
use std::process::Command;
use std::time::Instant;
use velour::sampling::Rng;
use velour::vdb::VdbFile;

fn best_of<T>(n: usize, mut f: impl FnMut() -> T) -> (f64, T) {
    let mut best = f64::INFINITY;
    let mut out = None;
    for _ in 0..n {
        let t = Instant::now();
        let r = f();
        best = best.min(t.elapsed().as_secs_f64());
        out = Some(r);
    }
    (best, out.expect("n > 0"))
}

fn run_vdb_print(args: &[&str]) -> f64 {
    let t = Instant::now();
    let out = Command::new("vdb_print")
        .args(args)
        .env("OPENVDB_DISABLE_DELAYED_LOAD", "1")
        .output()
        .expect("vdb_print (Debian libopenvdb-tools) is needed for the load comparison");
    assert!(
        out.status.success(),
        "vdb_print failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    t.elapsed().as_secs_f64()
}

fn main() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let path = std::env::var_os("VELOUR_BENCH_VDB")
        .map_or_else(|| root.join("target/bench/large.vdb"), PathBuf::from);
    if !path.exists() {
        std::fs::create_dir_all(path.parent().expect("parent")).expect("mkdir");
        let ok = Command::new("/usr/bin/python3")
            .arg(root.join("tools/vdb/make_large.py"))
            .arg(&path)
            .status()
            .expect("run /usr/bin/python3 tools/vdb/make_large.py");
        assert!(ok.success(), "make_large.py failed");
    }
    let p = path.to_str().expect("utf-8 path");
    let bytes = std::fs::metadata(&path).expect("large file").len();
    println!("# Sparse grid and OpenVDB benchmarks");
    println!("file: {p} ({:.1} MB)", bytes as f64 / 1e6);

    // --- Load time -------------------------------------------------------------------
    let tiny = root.join("tests/data/vdb/xform_scaletranslate.vdb");
    let tiny = tiny.to_str().expect("utf-8");
    run_vdb_print(&[p]); // warm the page cache
    let (ours_load, grids) = best_of(5, || {
        VdbFile::open(&path)
            .and_then(|f| f.read_all())
            .expect("read")
    });
    let vdb_print = (0..5)
        .map(|_| run_vdb_print(&[p]))
        .fold(f64::INFINITY, f64::min);
    let startup = (0..5)
        .map(|_| run_vdb_print(&[tiny]))
        .fold(f64::INFINITY, f64::min);
    let (ours_stats, _) = best_of(3, || {
        let g = VdbFile::open(&path)
            .and_then(|f| f.read_all())
            .expect("read");
        g[0].stats()
    });
    let vdb_print_l = (0..3)
        .map(|_| run_vdb_print(&["-l", p]))
        .fold(f64::INFINITY, f64::min);
    let g = &grids[0];
    let s = g.stats();
    println!(
        "grid '{}': {} active voxels, {} leaves",
        g.name, s.active_voxels, s.leaf_count
    );
    println!("load (read every grid), best of 5:");
    println!("  velour read_all           {:8.1} ms", ours_load * 1e3);
    println!(
        "  vdb_print (no delay-load) {:8.1} ms  (process start-up {:.1} ms, measured on a 16 KB file)",
        vdb_print * 1e3,
        startup * 1e3
    );
    println!(
        "  ratio vdb_print / velour   {:.2}x   (start-up removed: {:.2}x)",
        vdb_print / ours_load,
        (vdb_print - startup) / ours_load
    );
    println!("load + statistics, best of 3:");
    println!("  velour read_all + stats    {:8.1} ms", ours_stats * 1e3);
    println!("  vdb_print -l               {:8.1} ms", vdb_print_l * 1e3);
    println!(
        "  ratio                      {:.2}x   (start-up removed: {:.2}x)",
        vdb_print_l / ours_stats,
        (vdb_print_l - startup) / ours_stats
    );

    // --- Lookups ---------------------------------------------------------------------
    let grid = &g.grid;
    let (lo, hi) = grid.active_bbox().expect("non-empty");
    let (lo, hi) = (lo.as_vec3(), hi.as_vec3());
    let mut rng = Rng::new(1, 0);
    let mut rnd3 = |rng: &mut Rng| Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
    // Coherent: rays through the volume, 0.37-voxel steps (as a ray marcher or tracker).
    let mut coherent = Vec::with_capacity(1 << 22);
    while coherent.len() < 1 << 22 {
        let o = lo + (hi - lo) * rnd3(&mut rng);
        let d = (rnd3(&mut rng) - 0.5).normalize_or(Vec3::X);
        for k in 0..512 {
            coherent.push(o + d * (0.37 * k as f32));
        }
    }
    let random: Vec<Vec3> = (0..1 << 22)
        .map(|_| lo + (hi - lo) * rnd3(&mut rng))
        .collect();
    let lookups = |pts: &[Vec3]| {
        let mut acc = grid.accessor(0);
        let mut sum = 0.0f32;
        for &p in pts {
            sum += acc.sample_trilinear(p);
        }
        std::hint::black_box(sum)
    };
    let (tc, _) = best_of(5, || lookups(&coherent));
    let (tr, _) = best_of(5, || lookups(&random));
    let (tw, _) = best_of(3, || {
        let mut acc = grid.accessor(0);
        let w2i = grid.world_to_index();
        let mut sum = 0.0f32;
        for &p in &coherent {
            let w = grid.index_to_world_point(p);
            sum += acc.sample_trilinear(w2i.transform_point3(w.as_dvec3()).as_vec3());
        }
        std::hint::black_box(sum)
    });
    let n = coherent.len() as f64;
    println!(
        "trilinear lookups, one thread, accessor, best of 5 ({} points):",
        coherent.len()
    );
    println!(
        "  coherent (rays, 0.37-voxel steps)  {:7.1} M/s",
        n / tc / 1e6
    );
    println!(
        "  random (uniform in the bbox)       {:7.1} M/s",
        random.len() as f64 / tr / 1e6
    );
    println!(
        "  coherent, world space (incl. map)  {:7.1} M/s",
        n / tw / 1e6
    );

    // --- Memory ----------------------------------------------------------------------
    let m = grid.memory_report();
    println!("memory:");
    println!(
        "  total {:.1} MB (brick values {:.1} MB, masks/origins {:.1} MB, topology {:.2} MB)",
        m.total_bytes as f64 / 1e6,
        m.brick_value_bytes as f64 / 1e6,
        m.brick_meta_bytes as f64 / 1e6,
        m.topology_bytes as f64 / 1e6
    );
    println!(
        "  {:.3} bytes per active voxel = {:.3}x the raw value size ({} bytes)",
        m.bytes_per_active_brick_voxel,
        m.bytes_per_active_brick_voxel / m.raw_value_bytes as f64,
        m.raw_value_bytes
    );
    for f in ["noise_fbm.vdb", "sphere_fog.vdb"] {
        let g = VdbFile::open(root.join("tests/data/vdb").join(f))
            .and_then(|v| v.read_all())
            .expect("fixture");
        let m = g[0].grid.memory_report();
        println!(
            "  {f}: {:.3} bytes per active leaf voxel = {:.2}x raw (sparse leaves)",
            m.bytes_per_active_brick_voxel,
            m.bytes_per_active_brick_voxel / m.raw_value_bytes as f64
        );
    }
}
