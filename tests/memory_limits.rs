//! `plume render` inside a real memory cgroup: `--sample-order auto` and the default
//! memory budget follow the cgroup's limit, not the machine's RAM (`plume_volume::out_of_core::memory`; the
//! parsing is unit-tested on fake trees in `src/memory/tests.rs`).
//!
//! Each test makes a child cgroup with a small limit (cgroup v2: `/sys/fs/cgroup/
//! plume-test-<pid>-<name>`, the memory controller enabled in the root's
//! `cgroup.subtree_control` if needed; v1: under this process's own memory cgroup), runs
//! `plume` in it through `sh -c 'echo $$ > cgroup.procs; exec plume …'`, and removes the
//! cgroup once the child has exited. Where the machine does not allow that (not root, no
//! memory controller, a read-only cgroupfs, a cgroup that refuses processes) the test
//! prints `SKIPPED: <reason>` to stderr and passes.

use crate::common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::Duration;

use common::{exr_pixels, pixel_bits, plume, s, stderr, tmpdir, PLUME};
use plume_volume::out_of_core::memory::{CgroupVersion, MemoryLimits};

const MIB: u64 = 1 << 20;

/// Exit status of the wrapper shell when it cannot move itself into the cgroup.
const CANNOT_JOIN: i32 = 97;

/// A child memory cgroup made for one test, removed on drop.
struct TestCgroup {
    dir: PathBuf,
    version: CgroupVersion,
}

impl TestCgroup {
    /// A new cgroup limited to `limit` bytes, or why this machine cannot have one.
    fn new(name: &str, limit: u64) -> Result<TestCgroup, String> {
        let euid = std::fs::read_to_string("/proc/self/status").ok().and_then(|t| {
            t.lines().find_map(|l| {
                l.strip_prefix("Uid:").and_then(|v| v.split_whitespace().nth(1).map(str::to_owned))
            })
        });
        if euid.as_deref() != Some("0") {
            return Err(format!(
                "not root (effective uid {}); making a cgroup needs root",
                euid.as_deref().unwrap_or("unknown")
            ));
        }
        let leaf = format!("plume-test-{}-{name}", std::process::id());
        let unified = Path::new("/sys/fs/cgroup");
        if let Ok(controllers) = std::fs::read_to_string(unified.join("cgroup.controllers")) {
            if !controllers.split_whitespace().any(|c| c == "memory") {
                return Err(format!(
                    "cgroup v2 at {} has no memory controller (controllers: {:?})",
                    unified.display(),
                    controllers.trim()
                ));
            }
            let subtree = unified.join("cgroup.subtree_control");
            let enabled = std::fs::read_to_string(&subtree)
                .is_ok_and(|t| t.split_whitespace().any(|c| c == "memory"));
            if !enabled {
                std::fs::write(&subtree, "+memory").map_err(|e| {
                    format!("cannot enable the memory controller in {}: {e}", subtree.display())
                })?;
            }
            return TestCgroup::make(unified.join(leaf), CgroupVersion::V2, "memory.max", limit);
        }
        let v1 = Path::new("/sys/fs/cgroup/memory");
        if !v1.join("memory.limit_in_bytes").exists() {
            return Err("no memory cgroup controller mounted (neither cgroup v2 at /sys/fs/cgroup nor v1 at /sys/fs/cgroup/memory)".into());
        }
        // Under this process's own memory cgroup where it is visible, so its limits still apply
        let own = std::fs::read_to_string("/proc/self/cgroup").unwrap_or_default();
        let own = own.lines().find_map(|l| {
            let mut fields = l.splitn(3, ':');
            let (_, controllers, path) = (fields.next()?, fields.next()?, fields.next()?);
            controllers
                .split(',')
                .any(|c| c == "memory")
                .then(|| v1.join(path.trim_start_matches('/')))
        });
        let parent = own
            .filter(|p| p.is_dir() && !p.to_string_lossy().contains(".."))
            .unwrap_or(v1.to_path_buf());
        TestCgroup::make(parent.join(leaf), CgroupVersion::V1, "memory.limit_in_bytes", limit)
    }

    fn make(
        dir: PathBuf,
        version: CgroupVersion,
        limit_file: &str,
        limit: u64,
    ) -> Result<TestCgroup, String> {
        std::fs::create_dir(&dir).map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
        let cgroup = TestCgroup { dir, version };
        let path = cgroup.dir.join(limit_file);
        std::fs::write(&path, limit.to_string())
            .map_err(|e| format!("cannot write {}: {e}", path.display()))?;
        Ok(cgroup)
    }

    /// Run `plume args` in this cgroup; `Err` when the process could not join it.
    fn plume(&self, args: &[&str]) -> Result<Output, String> {
        let script = format!(
            "echo $$ > \"$PLUME_TEST_CGROUP/cgroup.procs\" || exit {CANNOT_JOIN}; exec \"$@\""
        );
        let o = Command::new("sh")
            .args(["-c", &script, "sh", PLUME])
            .args(args)
            .env("PLUME_TEST_CGROUP", &self.dir)
            .output()
            .expect("run sh");
        if o.status.code() == Some(CANNOT_JOIN) {
            return Err(format!(
                "cannot move a process into {}: {}",
                self.dir.display(),
                stderr(&o).trim()
            ));
        }
        Ok(o)
    }
}

impl Drop for TestCgroup {
    fn drop(&mut self) {
        // The children have exited; the kernel may take a moment to empty the cgroup
        for _ in 0..50 {
            if std::fs::remove_dir(&self.dir).is_ok() || !self.dir.exists() {
                return;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        eprintln!("warning: could not remove the test cgroup {}", self.dir.display());
    }
}

/// The cgroup, or `None` after printing why the test is skipped.
fn cgroup_or_skip(name: &str, limit: u64) -> Option<TestCgroup> {
    match TestCgroup::new(name, limit) {
        Ok(c) => Some(c),
        Err(reason) => {
            skip(&reason);
            None
        }
    }
}

/// Say loudly why the test did not run ([`common::skip`]).
fn skip(reason: &str) {
    common::skip("the real-cgroup test", reason);
}

/// A flare brick cache at `resolution` in `dir`.
fn flare(dir: &Path, resolution: u32) -> PathBuf {
    let p = dir.join(format!("flare{resolution}.plume"));
    let o = plume(&["synth", "flare", "--resolution", &resolution.to_string(), "-o", s(&p)]);
    assert!(o.status.success(), "synth: {}", stderr(&o));
    p
}

#[test]
fn a_cache_larger_than_the_cgroup_limit_renders_tile_by_tile() {
    // 384³ flare: a 56 MB cache, larger than the 32 MiB limit, far smaller than the machine
    let limit = 32 * MIB;
    let Some(cgroup) = cgroup_or_skip("order", limit) else { return };
    let dir = tmpdir("memory", "order");
    let cache = flare(&dir, 384);
    let cache_bytes = std::fs::metadata(&cache).unwrap().len();
    assert!(cache_bytes > limit, "the cache ({cache_bytes} bytes) must exceed the limit");
    let machine = MemoryLimits::read();
    if machine.mem_available.is_none_or(|a| a <= cache_bytes) {
        return skip(&format!(
            "MemAvailable ({:?}) is not above the cache's {cache_bytes} bytes, so the cgroup would not be what decides",
            machine.mem_available
        ));
    }
    let args = |out: &Path| {
        [
            "render",
            s(&cache),
            "-o",
            s(out),
            "--width",
            "32",
            "--height",
            "24",
            "--spp",
            "2",
            "--threads",
            "2",
        ]
        .map(str::to_owned)
    };
    let inside = dir.join("inside.exr");
    let args_inside = args(&inside);
    let o = match cgroup.plume(&args_inside.iter().map(String::as_str).collect::<Vec<_>>()) {
        Ok(o) => o,
        Err(reason) => return skip(&reason),
    };
    let message = stderr(&o);
    assert!(o.status.success(), "render in a {} MiB cgroup: {message}", limit / MIB);
    let cgroup_name = format!("{} memory limit", cgroup.version);
    assert!(
        message.contains("rendering tile by tile") && message.contains(&cgroup_name),
        "auto order in the cgroup: {message}"
    );
    eprintln!("in {}: {message}", cgroup.dir.display());
    // Outside the cgroup the same render stays progressive (when this process has room)
    if machine.available().is_some_and(|a| a.bytes > cache_bytes) {
        let outside = dir.join("outside.exr");
        let o = plume(&args(&outside).iter().map(String::as_str).collect::<Vec<_>>());
        assert!(
            o.status.success() && !stderr(&o).contains("tile by tile"),
            "outside the cgroup: {}",
            stderr(&o)
        );
        assert_eq!(
            pixel_bits(&exr_pixels(&inside)),
            pixel_bits(&exr_pixels(&outside)),
            "the order changes no pixel"
        );
    }
    drop(cgroup);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn the_default_memory_budget_is_half_the_cgroup_limit() {
    // Classic NEE's table for a 256³ flare (≈ 0.05 GiB) is refused by a budget of half of
    // 32 MiB, and the refusal names the budget
    let limit = 32 * MIB;
    let Some(cgroup) = cgroup_or_skip("budget", limit) else { return };
    let dir = tmpdir("memory", "budget");
    let cache = flare(&dir, 256);
    let out = dir.join("nee.exr");
    let args = [
        "render",
        s(&cache),
        "-o",
        s(&out),
        "--width",
        "16",
        "--height",
        "12",
        "--spp",
        "1",
        "--method",
        "line-nee",
        "--albedo",
        "0.5",
    ];
    let o = match cgroup.plume(&args) {
        Ok(o) => o,
        Err(reason) => return skip(&reason),
    };
    let message = stderr(&o);
    let budget =
        format!("more than the budget of {:.2} GiB", (limit / 2) as f64 / f64::from(1u32 << 30));
    assert_eq!(o.status.code(), Some(2), "{message}");
    assert!(
        message.contains("classic NEE") && message.contains(&budget),
        "{message:?} lacks {budget:?}"
    );
    // An explicit budget overrides the cgroup's, even one above the limit itself
    let o = cgroup
        .plume(&[&args[..], &["--memory-budget", "40MiB"]].concat())
        .expect("joined once already");
    assert!(stderr(&o).contains("more than the budget of 0.04 GiB"), "{}", stderr(&o));
    drop(cgroup);
    let _ = std::fs::remove_dir_all(&dir);
}

/// `--defer-paths auto` traces a scattering render's paths in rounds where the cache is
/// larger than what the cgroup leaves, with one path per camera collision, and not with
/// several (`integrator::deferred`); the image is the same as with `never`.
#[test]
fn a_cache_larger_than_the_cgroup_limit_defers_one_path_per_collision() {
    let limit = 32 * MIB;
    let Some(cgroup) = cgroup_or_skip("defer", limit) else { return };
    let dir = tmpdir("memory", "defer");
    let cache = flare(&dir, 384);
    // The pixels' bits and the number of deferred samples, or why the cgroup refused
    let render = |name: &str, extra: &[&str]| -> Result<(Vec<u32>, u64), String> {
        let (out, stats) = (dir.join(format!("{name}.exr")), dir.join(format!("{name}.json")));
        let args = [
            "render",
            s(&cache),
            "-o",
            s(&out),
            "--stats",
            s(&stats),
            "--width",
            "32",
            "--height",
            "24",
            "--spp",
            "2",
            "--threads",
            "2",
            "--albedo",
            "0.5",
        ];
        let o = cgroup.plume(&[&args[..], extra].concat())?;
        assert!(o.status.success(), "{name} in a {} MiB cgroup: {}", limit / MIB, stderr(&o));
        let stats: serde_json::Value =
            serde_json::from_slice(&std::fs::read(&stats).unwrap()).unwrap();
        let deferred = stats["counters"]["deferred_samples"]
            .as_u64()
            .unwrap_or_else(|| panic!("{name}: no deferred_samples in {stats}"));
        Ok((pixel_bits(&exr_pixels(&out)), deferred))
    };
    let (auto, deferred) = match render("auto", &["--split", "1"]) {
        Ok(r) => r,
        Err(reason) => return skip(&reason),
    };
    assert!(deferred > 0, "auto did not defer a cache larger than the limit");
    let (never, none) =
        render("never", &["--split", "1", "--defer-paths", "never"]).expect("joined once already");
    assert_eq!(none, 0, "--defer-paths never deferred");
    assert_eq!(auto, never, "deferral changed the image");
    // Several paths per collision outgrow the fills (`integrator::deferred`)
    let (_, split) = render("split", &["--split", "4"]).expect("joined once already");
    assert_eq!(split, 0, "auto deferred split paths");
    drop(cgroup);
    let _ = std::fs::remove_dir_all(&dir);
}
