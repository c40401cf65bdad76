//! `farm/slurm/plume-array.sh` run by a real Slurm: a one-node cluster ([`cluster`]) takes
//! the script's real `sbatch` submissions, and the tests wait on `squeue` and read
//! `sacct`, as a user on a cluster would.
//!
//! One test starts the cluster and runs the scenarios side by side (the time limit alone
//! takes Slurm 60 to 90 s to enforce, its check runs every 30 s; the test harness starts
//! tests in name order, and this module's name, a batch system, lets it start among the
//! first, to wait beside the other tests rather than after them): tiles and sample ranges
//! merged bit-identically, a failing task that holds back the merge, `scancel` and a
//! resubmission that continues the part, a `--time` limit reaching plume as SIGTERM, and
//! `--mem` reaching plume's memory budget through the job's cgroup. Where the machine
//! cannot run the cluster (not root, no packages, daemons that do not start), the test
//! says so loudly and skips.

mod cluster;

use crate::common;

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use cluster::{Cluster, Finished};
use common::{pixel_bits, plume, s, stderr, synth_explosion, tmpdir, PLUME};
use plume::output::read_exr_contents;

/// How long a small array job may take, from submission to its merge.
const JOB_TIMEOUT: Duration = Duration::from_secs(120);

#[test]
fn the_array_script_runs_under_a_real_slurm() {
    let started = Instant::now();
    let cluster = match Cluster::start() {
        Ok(cluster) => cluster,
        Err(reason) => return skip(&reason),
    };
    let up = started.elapsed();
    std::thread::scope(|scope| {
        scope.spawn(|| a_time_limit_reaches_plume_as_sigterm(&cluster));
        scope.spawn(|| tiles_and_sample_ranges_merge_bit_identically(&cluster));
        scope.spawn(|| a_failed_task_fails_the_array_and_holds_back_the_merge(&cluster));
        scope.spawn(|| scancel_leaves_a_part_that_a_resubmission_continues(&cluster));
        scope.spawn(|| mem_reaches_plumes_memory_budget(&cluster));
    });
    drop(cluster);
    let _ = std::io::Write::write_all(
        &mut std::io::stderr(),
        format!(
            "slurm: cluster up in {up:.1?}, all scenarios and shutdown in {:.1?}\n",
            started.elapsed()
        )
        .as_bytes(),
    );
}

/// Say loudly why the test did not run ([`common::skip`]).
fn skip(reason: &str) {
    common::skip("the real-Slurm test", reason);
}

/// One scenario's submissions: the script's settings, in a scratch directory that is also
/// the submission's working directory (where Slurm writes `plume-<job>_<task>.log`).
struct Submission<'a> {
    cluster: &'a Cluster,
    dir: PathBuf,
    name: String,
    env: Vec<(&'static str, String)>,
}

/// The job ids `submit` printed: the render array, and the merge array when tiled.
struct Submitted {
    render: String,
    merge: Option<String>,
}

impl<'a> Submission<'a> {
    /// Frames of a 32³ explosion sequence `ex.NNNN.vdb` in a fresh directory; one-CPU
    /// tasks (the script's header asks for 8) named `plume-<name>`.
    fn new(cluster: &'a Cluster, name: &str, frames: &[i64]) -> Submission<'a> {
        let dir = tmpdir("slurm", name);
        for f in frames {
            synth_explosion(&dir.join(format!("ex.{f:04}.vdb")), 32, Some(*f));
        }
        let name = format!("plume-{name}");
        let env = vec![
            ("PLUME", PLUME.to_string()),
            ("INPUT", dir.join("ex.####.vdb").display().to_string()),
            ("OUTPUT", dir.join("renders/beauty.%04d.exr").display().to_string()),
            ("WIDTH", "30".into()),
            ("HEIGHT", "20".into()),
            ("SPP", "5".into()),
            ("EXTRA_ARGS", "--density-scale 3".into()),
            ("SBATCH_ARGS", format!("--job-name={name} --cpus-per-task=1 --mem=256M")),
        ];
        Submission { cluster, dir, name, env }
    }

    fn set(mut self, key: &'static str, value: impl Into<String>) -> Self {
        let value = value.into();
        match self.env.iter_mut().find(|(k, _)| *k == key) {
            Some(entry) => entry.1 = value,
            None => self.env.push((key, value)),
        }
        self
    }

    fn get(&self, key: &str) -> &str {
        self.env.iter().find(|(k, _)| *k == key).map_or("", |(_, v)| v.as_str())
    }

    /// Run `plume-array.sh submit`, as a user would, and parse the ids it prints.
    fn submit(&self) -> Submitted {
        let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("farm/slurm/plume-array.sh");
        let o = self
            .cluster
            .command("bash")
            .arg(&script)
            .arg("submit")
            .envs(self.env.iter().map(|(k, v)| (k, v)))
            .current_dir(&self.dir)
            .output()
            .unwrap();
        let printed = String::from_utf8_lossy(&o.stdout);
        assert!(o.status.success(), "{}: submit: {printed}{}", self.name, stderr(&o));
        let mut ids = printed.lines().map(|l| l.split(';').next().unwrap().trim().to_owned());
        let render = ids.next().expect("submit prints the render job's id");
        Submitted { render, merge: ids.next() }
    }

    /// Slurm's log of one array task (`--output=plume-%A_%a.log` in the script's header).
    fn log(&self, job: &str, task: usize) -> String {
        std::fs::read_to_string(self.dir.join(format!("plume-{job}_{task}.log")))
            .unwrap_or_default()
    }

    /// The output of `frame`, and the part of `tile`, `split` (the script's names).
    fn output(&self, frame: i64) -> PathBuf {
        PathBuf::from(self.get("OUTPUT").replace("%04d", &format!("{frame:04}")))
    }

    fn part(&self, frame: i64, tile: usize, split: usize) -> PathBuf {
        let out = self.output(frame);
        out.with_extension(format!("tile{tile}.s{split}.exr"))
    }

    /// `plume render` of the same frame in one process, for the bit-identity checks.
    fn single_render(&self, frame: i64) -> PathBuf {
        let out = self.dir.join(format!("single.{frame:04}.exr"));
        let spp = self.get("SPP");
        // EXTRA_ARGS without --progress and its value
        let mut extra = Vec::new();
        let mut words = self.get("EXTRA_ARGS").split_whitespace();
        while let Some(word) = words.next() {
            if word == "--progress" {
                words.next();
            } else {
                extra.push(word);
            }
        }
        let frame_text = frame.to_string();
        let input = self.get("INPUT");
        let mut args =
            vec!["render", input, "-o", s(&out), "--frames", &frame_text, "--spp", spp, "-q"];
        args.extend(["--width", self.get("WIDTH"), "--height", self.get("HEIGHT")]);
        args.extend(extra);
        let o = plume(&args);
        assert!(o.status.success(), "single render: {}", stderr(&o));
        out
    }

    /// Remove the scenario's directory (after it passed: a failure keeps it to look at).
    fn clean_up(&self) {
        let _ = std::fs::remove_dir_all(&self.dir);
    }

    /// Finished records of this scenario's jobs.
    fn finished(&self) -> Vec<Finished> {
        self.cluster.finished(&self.name)
    }
}

/// Pixel bits of an EXR.
fn bits(p: &Path) -> Vec<u32> {
    pixel_bits(&read_exr_contents(p).unwrap_or_else(|e| panic!("{}: {e}", p.display())).pixels)
}

/// A `plume:` attribute of an EXR.
fn meta(p: &Path, key: &str) -> String {
    let contents = read_exr_contents(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
    contents.metadata.get(&format!("plume:{key}")).cloned().unwrap_or_default()
}

/// The stats lines plume appended beside `output` (`<output>.stats.jsonl`).
fn stats(output: &Path) -> Vec<serde_json::Value> {
    let path = output.with_extension("stats.jsonl");
    std::fs::read_to_string(&path)
        .unwrap_or_default()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

/// The `--progress json` events in a task's log.
fn events(log: &str) -> Vec<serde_json::Value> {
    log.lines()
        .filter(|l| l.starts_with('{'))
        .filter_map(|l| serde_json::from_str(l).ok())
        .collect()
}

fn tiles_and_sample_ranges_merge_bit_identically(cluster: &Cluster) {
    // Two frames × 2 tiles × 2 sample ranges: 8 render tasks, then a merge array of 2,
    // into a directory that does not exist yet.
    let job = Submission::new(cluster, "tiles", &[7, 8])
        .set("FIRST", "7")
        .set("LAST", "8")
        .set("TILES", "2")
        .set("SAMPLE_SPLITS", "2");
    let ids = job.submit();
    let merge = ids.merge.clone().expect("a tiled submission has a merge job");
    cluster.wait_until_done(&[&ids.render, &merge], JOB_TIMEOUT);
    let finished = job.finished();
    assert_eq!(finished.len(), 10, "8 render tasks and 2 merges: {finished:?}");
    assert!(
        finished.iter().all(|f| f.state == "COMPLETED" && f.exit_code == "0:0"),
        "{finished:?}"
    );
    for frame in [7, 8] {
        let merged = job.output(frame);
        assert_eq!(bits(&merged), bits(&job.single_render(frame)), "frame {frame}");
        assert_eq!(meta(&merged, "status"), "complete");
        // Each task rendered with the CPUs Slurm gave it (--threads $SLURM_CPUS_PER_TASK)
        let part = stats(&job.part(frame, 1, 1));
        assert_eq!(part.len(), 1, "one stats line per part");
        assert_eq!(part[0]["threads"], 1, "{}", part[0]);
        assert_eq!(part[0]["sample_range"], "2..5", "{}", part[0]);
    }
    job.clean_up();
}

fn a_failed_task_fails_the_array_and_holds_back_the_merge(cluster: &Cluster) {
    // Frame 8 is missing: its two tasks fail with plume's exit code 3 (an input)
    let job = Submission::new(cluster, "failed", &[7])
        .set("FIRST", "7")
        .set("LAST", "8")
        .set("TILES", "2");
    let ids = job.submit();
    let merge = ids.merge.clone().expect("a tiled submission has a merge job");
    cluster.wait_until_done(&[&ids.render], JOB_TIMEOUT);
    // afterok cannot be satisfied any more: the merge stays pending, never started
    cluster.poll("the merge's dependency to fail", Duration::from_secs(30), || {
        let queue = cluster.queue(&[&merge]);
        !queue.is_empty() && queue.iter().all(|l| l.ends_with("PENDING DependencyNeverSatisfied"))
    });
    let finished = job.finished();
    let mut states: Vec<String> =
        finished.iter().map(|f| format!("{} {}", f.state, f.exit_code)).collect();
    states.sort();
    assert_eq!(
        states,
        ["COMPLETED 0:0", "COMPLETED 0:0", "FAILED 3:0", "FAILED 3:0"],
        "{finished:?}"
    );
    for task in [2, 3] {
        let log = job.log(&ids.render, task);
        assert!(log.contains("plume: error:") && log.contains("ex.0008.vdb"), "task {task}: {log}");
    }
    assert!(job.part(7, 0, 0).exists() && job.part(7, 1, 0).exists(), "frame 7's parts");
    cluster.run("scancel", &[&merge]).unwrap();
    cluster.wait_until_done(&[&merge], JOB_TIMEOUT);
    assert!(!job.output(7).exists() && !job.output(8).exists(), "no merge ran");
    job.clean_up();
}

fn scancel_leaves_a_part_that_a_resubmission_continues(cluster: &Cluster) {
    // Two tiles of about 4 s each on one CPU
    let job = Submission::new(cluster, "scancel", &[7])
        .set("FIRST", "7")
        .set("LAST", "7")
        .set("TILES", "2")
        .set("WIDTH", "64")
        .set("HEIGHT", "48")
        .set("SPP", "4096")
        .set("EXTRA_ARGS", "--density-scale 3 --progress json");
    let first = job.submit();
    let merge = first.merge.clone().expect("a tiled submission has a merge job");
    cluster.poll("task 0 to render its first samples", JOB_TIMEOUT, || {
        events(&job.log(&first.render, 0))
            .iter()
            .any(|e| e["event"] == "progress" && e["spp"].as_u64() > Some(0))
    });
    let task0 = format!("{}_0", first.render);
    cluster.run("scancel", &[&task0]).unwrap();
    cluster.wait_until_done(&[&first.render], JOB_TIMEOUT);
    cluster.poll("the merge's dependency to fail", Duration::from_secs(30), || {
        cluster.queue(&[&merge]).iter().all(|l| l.ends_with("DependencyNeverSatisfied"))
    });
    cluster.run("scancel", &[&merge]).unwrap();
    cluster.wait_until_done(&[&merge], JOB_TIMEOUT);
    // The cancelled task got SIGTERM, finished its pass and wrote the part with its samples
    let part = job.part(7, 0, 0);
    assert_eq!(meta(&part, "status"), "interrupted", "{}", job.log(&first.render, 0));
    let reached: u64 = meta(&part, "spp").parse().unwrap();
    assert!((1..4096).contains(&reached), "the part reached {reached} spp");
    let done = events(&job.log(&first.render, 0));
    assert!(done.iter().any(|e| e["event"] == "done" && e["exit_code"] == 5), "{done:?}");
    let finished = job.finished();
    let states: Vec<&str> = finished.iter().map(|f| f.state.as_str()).collect();
    assert!(states.contains(&"CANCELLED") && states.contains(&"COMPLETED"), "{states:?}");

    // The same submission again: tile 1 is skipped, tile 0 continues, the merge runs
    let second = job.submit();
    let merge = second.merge.clone().unwrap();
    cluster.wait_until_done(&[&second.render, &merge], JOB_TIMEOUT);
    let tile0 = stats(&part);
    assert_eq!(tile0.len(), 2, "tile 0 rendered twice: {tile0:?}");
    assert_eq!(tile0[1]["resumed_from_spp"], reached, "{}", tile0[1]);
    assert_eq!(stats(&job.part(7, 1, 0)).len(), 1, "tile 1 was complete and skipped");
    assert_eq!(
        bits(&job.output(7)),
        bits(&job.single_render(7)),
        "bit-identical after the resubmission"
    );
    job.clean_up();
}

/// `PLUME` for the time-limit scenario: plume, run 5 % of the time (stopped with SIGSTOP
/// for 0.95 s of every second) so that waiting for the limit costs the other tests almost
/// no CPU. Slurm signals the batch script's own process only (which is why the script
/// `exec`s plume): this wrapper, which passes SIGTERM on to plume and lets it run, so that
/// it finishes its pass and writes the image; plume's exit status is the wrapper's.
const SLOW_PLUME: &str = r#"#!/usr/bin/env bash
PLUME_BINARY "$@" &
pid=$!
stopping=0
trap 'stopping=1; kill -CONT $pid 2>/dev/null; kill -TERM $pid 2>/dev/null' TERM
while [ $stopping = 0 ] && kill -0 $pid 2>/dev/null; do
    sleep 0.05
    [ $stopping = 0 ] && kill -STOP $pid 2>/dev/null
    sleep 0.95
    kill -CONT $pid 2>/dev/null
done
while :; do
    wait $pid
    status=$?
    kill -0 $pid 2>/dev/null || exit $status
done
"#;

fn a_time_limit_reaches_plume_as_sigterm(cluster: &Cluster) {
    // A frame far longer than the limit, which comes 60 to 90 s after the start (Slurm's
    // limits are in minutes, checked every 30 s). plume's own --time-limit is only a
    // backstop in case the cluster were gone.
    let job = Submission::new(cluster, "timelimit", &[7])
        .set("FIRST", "7")
        .set("LAST", "7")
        .set("WIDTH", "64")
        .set("HEIGHT", "48")
        .set("SPP", "1000000")
        .set("EXTRA_ARGS", "--density-scale 3 --progress json --time-limit 400");
    let wrapper = job.dir.join("slow-plume");
    std::fs::write(&wrapper, SLOW_PLUME.replace("PLUME_BINARY", PLUME)).unwrap();
    std::fs::set_permissions(&wrapper, std::os::unix::fs::PermissionsExt::from_mode(0o755))
        .unwrap();
    let output = job.dir.join("renders/beauty.####.exr");
    let sbatch = format!("{} --time=1", job.get("SBATCH_ARGS"));
    let job = job.set("PLUME", s(&wrapper)).set("OUTPUT", s(&output)).set("SBATCH_ARGS", sbatch);
    let ids = job.submit();
    assert!(ids.merge.is_none(), "an untiled submission has no merge");
    cluster.wait_until_done(&[&ids.render], Duration::from_secs(180));
    let finished = job.finished();
    assert_eq!(finished.len(), 1, "{finished:?}");
    assert_eq!(finished[0].state, "TIMEOUT", "{finished:?}");
    let log = job.log(&ids.render, 0);
    assert!(log.contains("DUE TO TIME LIMIT"), "{log}");
    let written = job.dir.join("renders/beauty.0007.exr");
    assert_eq!(meta(&written, "status"), "interrupted", "{log}");
    let reached: u64 = meta(&written, "spp").parse().unwrap();
    assert!(reached > 0, "{log}");
    let done = events(&log);
    assert!(done.iter().any(|e| e["event"] == "done" && e["exit_code"] == 5), "{log}");

    // Resubmitted (here with plume's own 3 s limit instead of Slurm's), it continues
    let unlimited = job.get("SBATCH_ARGS").replace(" --time=1", "");
    let job = job
        .set("SBATCH_ARGS", unlimited)
        .set("EXTRA_ARGS", "--density-scale 3 --progress json --time-limit 3");
    let again = job.submit();
    cluster.wait_until_done(&[&again.render], JOB_TIMEOUT);
    let lines = stats(&written);
    assert_eq!(lines.len(), 2, "{lines:?}");
    assert_eq!(lines[1]["resumed_from_spp"], reached, "{}", lines[1]);
    assert_eq!(lines[1]["status"], "time-limit", "{}", lines[1]);
    let finished = job.finished();
    assert!(finished.iter().any(|f| f.state == "FAILED" && f.exit_code == "6:0"), "{finished:?}");
    job.clean_up();
}

fn mem_reaches_plumes_memory_budget(cluster: &Cluster) {
    if let Err(reason) = cluster.confined() {
        return skip(&format!("--mem is not enforced by this cluster: {reason}"));
    }
    // A 56 MB brick cache: with --mem=40M it renders tile by tile, with --mem=1G in the
    // default order, and the order changes no pixel.
    let job = Submission::new(cluster, "mem", &[]);
    let cache = job.dir.join("flare.plume");
    let o = plume(&["synth", "flare", "--resolution", "384", "-o", s(&cache)]);
    assert!(o.status.success(), "synth: {}", stderr(&o));
    let run = |mem: &str| {
        let name = format!("{}-{mem}", job.name);
        let j =
            Submission { cluster, dir: job.dir.clone(), name: name.clone(), env: job.env.clone() }
                .set("INPUT", s(&cache))
                .set("OUTPUT", s(&job.dir.join(format!("mem{mem}.####.exr"))))
                .set("FIRST", "1")
                .set("LAST", "1")
                .set("SPP", "2")
                .set("WIDTH", "32")
                .set("HEIGHT", "24")
                .set("EXTRA_ARGS", "")
                .set("SBATCH_ARGS", format!("--job-name={name} --cpus-per-task=1 --mem={mem}"));
        let ids = j.submit();
        cluster.wait_until_done(&[&ids.render], JOB_TIMEOUT);
        let finished = j.finished();
        assert!(
            finished.len() == 1 && finished[0].state == "COMPLETED",
            "{finished:?}: {}",
            j.log(&ids.render, 0)
        );
        (j.log(&ids.render, 0), job.dir.join(format!("mem{mem}.0001.exr")))
    };
    let (small, small_image) = run("40M");
    assert!(
        small.contains("rendering tile by tile")
            && small.contains("cgroup")
            && small.contains("memory limit"),
        "{small}"
    );
    let (large, large_image) = run("1G");
    assert!(!large.contains("tile by tile"), "{large}");
    assert_eq!(bits(&small_image), bits(&large_image), "the order changes no pixel");
    job.clean_up();
}
