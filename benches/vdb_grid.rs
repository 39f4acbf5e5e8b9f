//! Sparse grid and OpenVDB benchmarks: load time against OpenVDB's own `vdb_print`,
//! trilinear lookups per second (coherent and random, one thread) and memory per active voxel.
//!
//! Run: `cargo bench --bench vdb_grid`. The large file is `$VELOUR_BENCH_VDB`, or
//! `target/bench/large.vdb`, made on first use by `tools/vdb/make_large.py` (real OpenVDB).
//! Ratios are measured in one run (machines here are shared and noisy). CPU times are
//! on-CPU times (all threads for loads, `/proc`), which are steadier than wall times on a
//! loaded machine.

use glam::Vec3;
use std::path::PathBuf;
use std::process::Command;
use std::time::Instant;
use velour::sampling::Rng;
use velour::vdb::VdbFile;

/// On-CPU time of the calling thread in seconds (Linux `/proc/thread-self/schedstat`):
/// on a shared machine it excludes the time other processes hold the core.
fn thread_cpu() -> f64 {
    std::fs::read_to_string("/proc/thread-self/schedstat")
        .ok()
        .and_then(|s| {
            s.split_whitespace()
                .next()
                .and_then(|x| x.parse::<f64>().ok())
        })
        .map_or(f64::NAN, |ns| ns * 1e-9)
}

/// User + system CPU time of the whole process (all threads), seconds, from
/// `/proc/self/stat` (clock ticks of 10 ms).
fn process_cpu() -> f64 {
    let text = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
    // Fields after the parenthesised command name: state is field 3, utime 14, stime 15.
    let rest = text.rsplit_once(')').map_or("", |(_, r)| r);
    let f: Vec<f64> = rest
        .split_whitespace()
        .map(|x| x.parse().unwrap_or(0.0))
        .collect();
    if f.len() > 13 {
        (f[11] + f[12]) / 100.0
    } else {
        f64::NAN
    }
}

/// Like `best_of` but counting the CPU time of every thread of the process.
fn best_of_process<T>(n: usize, mut f: impl FnMut() -> T) -> (Time, T) {
    let mut best = Time {
        wall: f64::INFINITY,
        cpu: f64::INFINITY,
    };
    let mut out = None;
    for _ in 0..n {
        let t = Instant::now();
        let c = process_cpu();
        let r = f();
        best.cpu = best.cpu.min(process_cpu() - c);
        best.wall = best.wall.min(t.elapsed().as_secs_f64());
        out = Some(r);
    }
    (best, out.expect("n > 0"))
}

/// A wall-clock and on-CPU duration, seconds.
#[derive(Clone, Copy)]
struct Time {
    wall: f64,
    cpu: f64,
}

fn best_of<T>(n: usize, mut f: impl FnMut() -> T) -> (Time, T) {
    let mut best = Time {
        wall: f64::INFINITY,
        cpu: f64::INFINITY,
    };
    let mut out = None;
    for _ in 0..n {
        let t = Instant::now();
        let c = thread_cpu();
        let r = f();
        best.cpu = best.cpu.min(thread_cpu() - c);
        best.wall = best.wall.min(t.elapsed().as_secs_f64());
        out = Some(r);
    }
    (best, out.expect("n > 0"))
}

/// Runs `vdb_print` (delayed loading off, so every leaf is read and decompressed) under
/// `/usr/bin/time`; returns wall and user+system CPU time (10 ms resolution).
fn run_vdb_print(args: &[&str]) -> Time {
    let log = std::env::temp_dir().join(format!("velour_bench_time_{}", std::process::id()));
    let t = Instant::now();
    let out = Command::new("/usr/bin/time")
        .arg("-f")
        .arg("%U %S")
        .arg("-o")
        .arg(&log)
        .arg("vdb_print")
        .args(args)
        .env("OPENVDB_DISABLE_DELAYED_LOAD", "1")
        .output()
        .expect("vdb_print (Debian libopenvdb-tools) and /usr/bin/time are needed");
    let wall = t.elapsed().as_secs_f64();
    assert!(
        out.status.success(),
        "vdb_print failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(&log).unwrap_or_default();
    let cpu: f64 = text
        .split_whitespace()
        .filter_map(|x| x.parse::<f64>().ok())
        .sum();
    Time { wall, cpu }
}

fn best(n: usize, args: &[&str]) -> Time {
    let mut b = Time {
        wall: f64::INFINITY,
        cpu: f64::INFINITY,
    };
    for _ in 0..n {
        let t = run_vdb_print(args);
        b.wall = b.wall.min(t.wall);
        b.cpu = b.cpu.min(t.cpu);
    }
    b
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
    let read = || {
        VdbFile::open(&path)
            .and_then(|f| f.read_all())
            .expect("read")
    };
    let (ours_load, grids) = best_of_process(5, read);
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("pool");
    let (ours_load1, _) = one.install(|| best_of_process(5, read));
    let vdb_print = best(5, &[p]);
    let startup = best(5, &[tiny]);
    let (ours_stats, _) = best_of_process(3, || {
        let g = VdbFile::open(&path)
            .and_then(|f| f.read_all())
            .expect("read");
        g[0].stats()
    });
    let vdb_print_l = best(3, &["-l", p]);
    let g = &grids[0];
    let s = g.stats();
    println!(
        "grid '{}': {} active voxels, {} leaves",
        g.name, s.active_voxels, s.leaf_count
    );
    let ms = |t: Time| format!("{:8.1} ms wall, {:8.1} ms CPU", t.wall * 1e3, t.cpu * 1e3);
    println!("load (read every grid; best of 5):");
    println!(
        "  velour read_all            {}  ({} threads)",
        ms(ours_load),
        rayon::current_num_threads()
    );
    println!("  velour read_all, 1 thread  {}", ms(ours_load1));
    println!("  vdb_print (no delay-load)  {}", ms(vdb_print));
    println!(
        "  vdb_print on a 16 KB file  {}  (process start-up)",
        ms(startup)
    );
    println!(
        "  ratio vdb_print / velour, start-up removed: wall {:.2}x, CPU {:.2}x; 1 thread: wall {:.2}x, CPU {:.2}x",
        (vdb_print.wall - startup.wall) / ours_load.wall,
        (vdb_print.cpu - startup.cpu) / ours_load.cpu,
        (vdb_print.wall - startup.wall) / ours_load1.wall,
        (vdb_print.cpu - startup.cpu) / ours_load1.cpu
    );
    println!(
        "load + statistics (best of 3; velour: counts, min, max, sum, moments, bbox, the \
         statistics in one thread; vdb_print -l: counts, min, max, multi-threaded):"
    );
    println!("  velour read_all + stats    {}", ms(ours_stats));
    println!("  vdb_print -l               {}", ms(vdb_print_l));
    println!(
        "  ratio, start-up removed: wall {:.2}x, CPU {:.2}x",
        (vdb_print_l.wall - startup.wall) / ours_stats.wall,
        (vdb_print_l.cpu - startup.cpu) / ours_stats.cpu
    );

    // --- Lookups ---------------------------------------------------------------------
    let grid = &g.grid;
    let (lo, hi) = grid.active_bbox().expect("non-empty");
    let (lo, hi) = (lo.as_vec3(), hi.as_vec3());
    let mut rng = Rng::new(1, 0);
    let rnd3 = |rng: &mut Rng| Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
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
    let rate = |t: Time, n: f64| {
        format!(
            "{:7.1} M/s wall, {:7.1} M/s on-CPU",
            n / t.wall / 1e6,
            n / t.cpu / 1e6
        )
    };
    println!(
        "trilinear lookups, one thread, accessor, best of 5 ({} points):",
        coherent.len()
    );
    println!("  coherent (rays, 0.37-voxel steps)  {}", rate(tc, n));
    println!(
        "  random (uniform in the bbox)       {}",
        rate(tr, random.len() as f64)
    );
    println!("  coherent, world space (incl. map)  {}", rate(tw, n));

    // The same coherent walk on a small (cache-resident) grid: the cost of the lookup itself.
    let small = VdbFile::open(root.join("tests/data/vdb/sphere_fog.vdb"))
        .and_then(|v| v.read_all())
        .expect("fixture");
    let sg = &small[0].grid;
    let (slo, shi) = sg.active_bbox().expect("non-empty");
    let (slo, shi) = (slo.as_vec3(), shi.as_vec3());
    let mut small_pts = Vec::with_capacity(1 << 22);
    while small_pts.len() < 1 << 22 {
        let o = slo + (shi - slo) * rnd3(&mut rng);
        let d = (rnd3(&mut rng) - 0.5).normalize_or(Vec3::X);
        for k in 0..128 {
            small_pts.push(o + d * (0.37 * k as f32));
        }
    }
    let (ts, _) = best_of(5, || {
        let mut acc = sg.accessor(0);
        let mut sum = 0.0f32;
        for &p in &small_pts {
            sum += acc.sample_trilinear(p);
        }
        std::hint::black_box(sum)
    });
    println!(
        "  coherent, sphere_fog fixture (1.6 MB of bricks, cache-resident) {}",
        rate(ts, small_pts.len() as f64)
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
