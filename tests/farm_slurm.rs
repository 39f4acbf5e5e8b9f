//! The farm scripts on a real one-node Slurm cluster (Debian's `slurm-wlm` and `munge`),
//! started and stopped by the test: 4 tiles + merge and 4 sample passes + merge are
//! bit-identical to one render; a task requeued mid-render (as pre-emption does: SIGTERM, then
//! a new run) checkpoints and resumes; a failing task cancels the merge instead of leaving it
//! pending forever. Needs root; skips with a notice without Slurm unless
//! `VELOUR_REQUIRE_EXTERNAL=1`.

mod common;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use common::cli::{run_velour, VELOUR};
use common::external::{external_required, require_tool};
use common::files::{repo_path, TempDir};
use common::render::pixel_bits;

/// The cluster, stopped when dropped (also when the test fails).
struct Cluster {
    dir: PathBuf,
    conf: PathBuf,
}

impl Cluster {
    fn start(dir: &Path) -> Cluster {
        let script = repo_path("tools/farm/slurm_cluster.sh");
        let out = Command::new(&script)
            .arg("start")
            .arg(dir)
            .output()
            .unwrap();
        let cluster = Cluster {
            dir: dir.to_path_buf(),
            conf: dir.join("slurm.conf"),
        };
        assert!(
            out.status.success(),
            "slurm_cluster.sh start failed: {}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
        cluster
    }

    fn command(&self, program: &str) -> Command {
        let mut c = Command::new(program);
        c.env("SLURM_CONF", &self.conf);
        c
    }

    fn stdout(&self, program: &str, args: &[&str]) -> String {
        let out = self.command(program).args(args).output().unwrap();
        assert!(
            out.status.success(),
            "{program} {args:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8_lossy(&out.stdout).to_string()
    }

    /// Runs `tools/farm/submit.sh`; returns the job ids it prints by name (`array`, `merge`).
    fn submit(&self, args: &[&str]) -> BTreeMap<String, String> {
        let out = self
            .command(repo_path("tools/farm/submit.sh").to_str().unwrap())
            .args(["--velour", VELOUR])
            .args(args)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "submit.sh {args:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8_lossy(&out.stdout)
            .lines()
            .filter_map(|l| l.split_once(' '))
            .map(|(k, v)| (k.to_string(), v.trim().to_string()))
            .collect()
    }

    /// Whether any job of `ids` is still in the queue.
    fn queued(&self, ids: &[&str]) -> bool {
        let jobs = self.stdout("squeue", &["-h", "-o", "%i %T"]);
        jobs.lines().any(|l| {
            ids.iter()
                .any(|id| l.starts_with(&format!("{id} ")) || l.starts_with(&format!("{id}_")))
        })
    }

    fn wait_gone(&self, ids: &[&str], limit: Duration) {
        let start = Instant::now();
        while self.queued(ids) {
            assert!(
                start.elapsed() < limit,
                "jobs {ids:?} still queued after {limit:?}: {}",
                self.stdout("squeue", &[])
            );
            std::thread::sleep(Duration::from_millis(200));
        }
    }
}

impl Drop for Cluster {
    fn drop(&mut self) {
        let _ = Command::new(repo_path("tools/farm/slurm_cluster.sh"))
            .arg("stop")
            .arg(&self.dir)
            .output();
    }
}

fn slurm_usable() -> bool {
    let tools = [
        ("sbatch", "slurm-wlm"),
        ("slurmctld", "slurm-wlm"),
        ("slurmd", "slurm-wlm"),
        ("munged", "munge"),
    ];
    if !tools.iter().all(|(t, p)| require_tool(t, p)) {
        return false;
    }
    // SAFETY: geteuid has no preconditions and touches no memory.
    if unsafe { libc::geteuid() } != 0 {
        assert!(
            !external_required(),
            "the Slurm test starts daemons and needs root"
        );
        eprintln!("skipping the Slurm test: it starts daemons and needs root");
        return false;
    }
    true
}

#[test]
fn slurm_arrays_merge_requeue_and_cancel() {
    if !slurm_usable() {
        return;
    }
    let t0 = Instant::now();
    let stage = |what: &str| {
        eprintln!(
            "slurm test: {what} after {:.1} s",
            t0.elapsed().as_secs_f64()
        )
    };
    let dir = TempDir::new("slurm");
    let cluster = Cluster::start(&dir.join("cluster"));
    let scene = repo_path("scenes/skin_sphere.toml");
    let scene = scene.to_str().unwrap();
    let size = ["--width", "40", "--height", "30"];

    let one = dir.join("one.exr");
    let mut args = vec![
        "render",
        scene,
        "-q",
        "--spp",
        "8",
        "-o",
        one.to_str().unwrap(),
    ];
    args.extend(size);
    run_velour(&args).assert_success();
    let reference = pixel_bits(&one);
    stage("cluster up");

    // 4 tiles + merge, and 4 sample passes + merge.
    for (mode, extra) in [("tiles", vec![]), ("passes", vec!["--spp", "8"])] {
        let out = dir.join(format!("{mode}/out.exr"));
        let mut a = vec![
            "--mode",
            mode,
            "--count",
            "4",
            "-o",
            out.to_str().unwrap(),
            scene,
        ];
        a.extend(extra.iter().copied());
        if mode == "tiles" {
            a.extend(["--", "--spp", "8"]);
        } else {
            a.push("--");
        }
        a.extend(size);
        let ids = cluster.submit(&a);
        cluster.wait_gone(&[&ids["array"], &ids["merge"]], Duration::from_secs(120));
        assert!(out.exists(), "{mode}: the merge job wrote nothing");
        assert!(
            pixel_bits(&out) == reference,
            "{mode}: merged image differs from one render"
        );
        stage(mode);
    }

    // A task requeued mid-render (SIGTERM, then a new run) resumes from its checkpoint. The
    // spp is large enough that the first run is still going when it is requeued.
    let spp = "1200";
    let long_ref = dir.join("long_one.exr");
    let mut args = vec![
        "render",
        scene,
        "-q",
        "--spp",
        spp,
        "--threads",
        "2",
        "-o",
        long_ref.to_str().unwrap(),
    ];
    args.extend(size);
    run_velour(&args).assert_success();
    let out = dir.join("requeue/out.exr");
    let mut a = vec![
        "--mode",
        "passes",
        "--count",
        "2",
        "--spp",
        spp,
        "-o",
        out.to_str().unwrap(),
        scene,
        "--",
    ];
    a.extend(size);
    a.extend(["--checkpoint-every", "0.3"]);
    let ids = cluster.submit(&a);
    let task0 = format!("{}_0", ids["array"]);
    let partial = dir.join("requeue/out.samples0-600.partial.exr");
    let start = Instant::now();
    while !partial.exists() {
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "task 0 wrote no checkpoint"
        );
        std::thread::sleep(Duration::from_millis(100));
    }
    stage("checkpoint written");
    let requeue = cluster
        .command("scontrol")
        .args(["requeue", &task0])
        .output()
        .unwrap();
    assert!(
        requeue.status.success(),
        "scontrol requeue: {}",
        String::from_utf8_lossy(&requeue.stderr)
    );
    cluster.wait_gone(&[&ids["array"], &ids["merge"]], Duration::from_secs(300));
    assert!(
        pixel_bits(&out) == pixel_bits(&long_ref),
        "requeued render differs"
    );
    let log = std::fs::read_to_string(dir.join(format!(
        "requeue/slurm-logs/velour-passes-{}_0.out",
        ids["array"]
    )))
    .unwrap();
    assert!(
        log.contains("render interrupted"),
        "task 0 was not interrupted: {log}"
    );
    assert!(
        log.contains("resuming from"),
        "task 0 did not resume: {log}"
    );
    stage("requeue");

    // A failing task: the merge is cancelled, not left pending forever.
    let out = dir.join("failing/out.exr");
    let a = vec![
        "--mode",
        "tiles",
        "--count",
        "2",
        "-o",
        out.to_str().unwrap(),
        scene,
        "--",
        "--width",
        "-3",
    ];
    let ids = cluster.submit(&a);
    cluster.wait_gone(&[&ids["array"], &ids["merge"]], Duration::from_secs(60));
    assert!(!out.exists(), "a merge ran after a failed task");
    stage("failing task");
}
