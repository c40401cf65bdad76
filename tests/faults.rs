//! Faults of the file system, each through the binary:
//!
//! - a **full disk** while writing each kind of output (EXR, PNG preview, stats line, a
//!   `plume prepare` cache, a streamed `plume synth flare` cache, the automatic cache of
//!   `plume render`): exit code 4, one error line naming the file, the previous file's
//!   bytes unchanged and no temporary file left;
//! - **read-only cache directories**: an explicit `--cache-dir` that cannot be written is
//!   an error naming it and the flag, one that holds a current cache is used; an input
//!   directory that cannot be written falls back to `$XDG_CACHE_HOME/plume`, then to an
//!   in-core read if that fits the memory budget, and to an error otherwise;
//! - **two processes making the same automatic cache at once**: both succeed with the
//!   same image, one converts and the other waits and uses its cache, which is valid;
//! - **a conversion lock that is never released** (a hung holder): the wait ends after
//!   `--cache-lock-timeout`, and the frame is read in core or fails with one line.
//!
//! Full disks and read-only directories are real: a small tmpfs mounted on a directory
//! the test makes (remounted read-only where needed) and unmounted when the test ends.
//! That needs root and `CAP_SYS_ADMIN`; without them those tests print `SKIPPED: <reason>`
//! to stderr and pass. The concurrency and lock tests run anywhere.

use crate::common;

use std::ffi::CString;
use std::io::Write as _;
use std::os::unix::ffi::OsStrExt as _;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

use common::{
    explosion, exr_pixels, names_in, pixel_bits, plume, s, skip, stderr, synth_explosion, tmpdir,
    PLUME,
};

const MIB: u64 = 1 << 20;

/// A tmpfs of a given size mounted on a directory for one test; unmounted on drop.
struct Tmpfs {
    dir: PathBuf,
}

impl Tmpfs {
    /// Mount a tmpfs of `bytes` on `dir` (created), or say why this machine cannot.
    fn mount(dir: &Path, bytes: u64) -> Result<Tmpfs, String> {
        // SAFETY: geteuid has no preconditions.
        let euid = unsafe { libc::geteuid() };
        if euid != 0 {
            return Err(format!("not root (effective uid {euid}); mounting a tmpfs needs root"));
        }
        std::fs::create_dir_all(dir)
            .map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
        let target = c_path(dir);
        let options = CString::new(format!("size={bytes},mode=0755")).unwrap();
        // SAFETY: every pointer is a NUL-terminated string that outlives the call.
        let r = unsafe {
            libc::mount(
                c"plume-test".as_ptr(),
                target.as_ptr(),
                c"tmpfs".as_ptr(),
                0,
                options.as_ptr().cast(),
            )
        };
        if r != 0 {
            let e = std::io::Error::last_os_error();
            return Err(format!(
                "cannot mount a tmpfs on {}: {e} (a container without CAP_SYS_ADMIN?)",
                dir.display()
            ));
        }
        Ok(Tmpfs { dir: dir.to_path_buf() })
    }

    /// Remount it read-only (root can write through directory permissions, not through
    /// a read-only mount).
    fn read_only(&self) -> Result<(), String> {
        let target = c_path(&self.dir);
        // SAFETY: as in `mount`; null source, type and data are allowed for a remount.
        let r = unsafe {
            libc::mount(
                std::ptr::null(),
                target.as_ptr(),
                std::ptr::null(),
                libc::MS_REMOUNT | libc::MS_RDONLY,
                std::ptr::null(),
            )
        };
        if r != 0 {
            return Err(format!(
                "cannot remount {} read-only: {}",
                self.dir.display(),
                std::io::Error::last_os_error()
            ));
        }
        Ok(())
    }
}

impl Drop for Tmpfs {
    fn drop(&mut self) {
        let target = c_path(&self.dir);
        // SAFETY: a NUL-terminated path. Lazily if a process still holds a file there.
        let r = unsafe { libc::umount2(target.as_ptr(), 0) };
        if r != 0 && unsafe { libc::umount2(target.as_ptr(), libc::MNT_DETACH) } != 0 {
            let _ = writeln!(
                std::io::stderr(),
                "warning: cannot unmount {}: {}",
                self.dir.display(),
                std::io::Error::last_os_error()
            );
        }
    }
}

fn c_path(p: &Path) -> CString {
    CString::new(p.as_os_str().as_bytes()).unwrap()
}

/// A tmpfs of `bytes` on `dir/name`, or `None` after saying loudly why the test is
/// skipped (and removing the test's directory `dir`).
fn tmpfs_or_skip(test: &str, dir: &Path, name: &str, bytes: u64) -> Option<Tmpfs> {
    match Tmpfs::mount(&dir.join(name), bytes) {
        Ok(t) => Some(t),
        Err(reason) => {
            skip(test, &reason);
            let _ = std::fs::remove_dir_all(dir);
            None
        }
    }
}

/// Fill the file system of `dir` to the last block with `dir/filler`.
fn fill(dir: &Path) {
    let mut f = std::fs::File::create(dir.join("filler")).unwrap();
    let block = [0x55u8; 4096];
    loop {
        match f.write(&block) {
            Ok(0) => break,
            Ok(_) => {}
            Err(e) if e.raw_os_error() == Some(libc::ENOSPC) => break,
            Err(e) => panic!("filling {}: {e}", dir.display()),
        }
    }
    let _ = f.flush();
    assert!(
        std::fs::write(dir.join("probe-full"), [0u8; 4096]).is_err(),
        "{} is not full",
        dir.display()
    );
    let _ = std::fs::remove_file(dir.join("probe-full"));
}

/// Names of temporary files in `dir` (`.NAME.HOST.PID.tmp`, or anything ending in `.tmp`).
fn temporaries(dir: &Path) -> Vec<String> {
    names_in(dir, |n| n.ends_with(".tmp"))
}

/// The `plume: error:` lines of a run.
fn error_lines(o: &Output) -> Vec<String> {
    stderr(o).lines().filter(|l| l.starts_with("plume: error:")).map(str::to_owned).collect()
}

/// `o` failed with exit 4 and exactly one error line, which names `file` and `what`.
#[track_caller]
fn assert_output_failure(o: &Output, file: &Path, what: &str) {
    let lines = error_lines(o);
    assert_eq!(o.status.code(), Some(4), "{}", stderr(o));
    assert_eq!(lines.len(), 1, "one error line: {}", stderr(o));
    assert!(
        lines[0].contains(s(file)) && lines[0].contains(what),
        "{:?} names {} and {what:?}",
        lines[0],
        file.display()
    );
}

/// Render `input` small and fast with `extra` flags.
fn render(input: &Path, out: &Path, extra: &[&str]) -> Output {
    let mut args = vec![
        "render",
        s(input),
        "-o",
        s(out),
        "--spp",
        "2",
        "--width",
        "32",
        "--height",
        "24",
        "--seed",
        "3",
        "-q",
    ];
    args.extend_from_slice(extra);
    plume(&args)
}

#[test]
fn a_full_disk_leaves_every_render_output_as_it_was() {
    let test = "a_full_disk_leaves_every_render_output_as_it_was";
    let dir = tmpdir("faults", "full-outputs");
    let Some(disk) = tmpfs_or_skip(test, &dir, "full", 2 * MIB) else { return };
    let full = disk.dir.clone();
    let vdb = explosion(&dir, 32, Some(2));
    // The previous files: not plume images, so every render below writes anew. The stats
    // file ends 100 bytes short of a page, so a full disk takes the start of a new line
    // and refuses the rest: half a line, unless plume cuts it off again.
    let old_exr = b"the previous image".to_vec();
    let old_png = b"the previous preview".to_vec();
    let mut old_stats = String::new();
    while old_stats.len() < 4096 - 100 - 16 {
        old_stats.push_str(&format!("{{\"old\":{:>6}}}\n", old_stats.len()));
    }
    let old_stats =
        format!("{old_stats}{}\n", "x".repeat(4096 - 100 - old_stats.len() - 1)).into_bytes();
    assert_eq!(old_stats.len(), 3996);
    for (name, bytes) in
        [("out.exr", &old_exr), ("preview.png", &old_png), ("stats.jsonl", &old_stats)]
    {
        std::fs::write(full.join(name), bytes).unwrap();
    }
    fill(&full);
    let unchanged = |name: &str, bytes: &[u8]| {
        assert_eq!(std::fs::read(full.join(name)).unwrap(), bytes, "{name} changed");
    };

    let exr = full.join("out.exr");
    let o = render(&vdb, &exr, &[]);
    assert_output_failure(&o, &exr, "No space left on device");
    let preview = full.join("preview.png");
    let o = render(&vdb, &dir.join("a.exr"), &["--preview", s(&preview)]);
    assert_output_failure(&o, &preview, "No space left on device");
    let stats = full.join("stats.jsonl");
    let o = render(&vdb, &dir.join("b.exr"), &["--stats", s(&stats)]);
    assert_output_failure(&o, &stats, "No space left on device");
    // A stats file that did not exist is not left behind empty
    let new_stats = full.join("new-stats.jsonl");
    let o = render(&vdb, &dir.join("c.exr"), &["--stats", s(&new_stats)]);
    assert_output_failure(&o, &new_stats, "No space left on device");
    assert!(!new_stats.exists(), "an empty stats file was left");

    unchanged("out.exr", &old_exr);
    unchanged("preview.png", &old_png);
    unchanged("stats.jsonl", &old_stats);
    assert_eq!(temporaries(&full), Vec::<String>::new(), "temporaries left");
    // With room again, the same outputs are written
    std::fs::remove_file(full.join("filler")).unwrap();
    let o = render(&vdb, &exr, &["--preview", s(&preview), "--stats", s(&stats)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let stats_now = std::fs::read(&stats).unwrap();
    assert!(
        stats_now.starts_with(&old_stats)
            && stats_now.len() > old_stats.len()
            && stats_now.ends_with(b"}\n"),
        "one whole line appended"
    );
    assert!(!exr_pixels(&exr).is_empty());
    drop(disk);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_full_disk_while_writing_a_cache_leaves_the_previous_file() {
    let test = "a_full_disk_while_writing_a_cache_leaves_the_previous_file";
    let dir = tmpdir("faults", "full-caches");
    let Some(disk) = tmpfs_or_skip(test, &dir, "full", 2 * MIB) else { return };
    let full = disk.dir.clone();
    // 256³: a 16 MiB cache, so the writer's 8 MiB buffer fills and the disk refuses it
    // while the leaves stream in, not only when the file is finished
    let big = dir.join("big.vdb");
    synth_explosion(&big, 256, Some(4));
    let small = explosion(&dir, 64, Some(4));
    let previous = b"the previous cache, which a failed conversion must leave alone".to_vec();
    for name in ["big.plume", "small.plume", "flare.plume"] {
        std::fs::write(full.join(name), &previous).unwrap();
    }
    fill(&full);
    for (input, name) in [(&big, "big.plume"), (&small, "small.plume")] {
        let out = full.join(name);
        let o = plume(&["prepare", s(input), "-o", s(&out)]);
        assert_output_failure(&o, &out, "No space left on device");
        assert_eq!(std::fs::read(&out).unwrap(), previous, "{name} changed");
    }
    let flare = full.join("flare.plume");
    let o = plume(&["synth", "flare", "--resolution", "192", "-o", s(&flare)]);
    assert_output_failure(&o, &flare, "No space left on device");
    assert_eq!(std::fs::read(&flare).unwrap(), previous, "flare.plume changed");
    assert_eq!(temporaries(&full), Vec::<String>::new(), "temporaries left");
    drop(disk);
    let _ = std::fs::remove_dir_all(&dir);
}

/// The name of the automatic cache `render` makes for `vdb` with `flags` (found by
/// making it in a scratch directory).
fn auto_cache_name(vdb: &Path, scratch: &Path, flags: &[&str]) -> String {
    std::fs::create_dir_all(scratch).unwrap();
    let o = render(vdb, &scratch.join("name.exr"), &[flags, &["--cache-dir", s(scratch)]].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    let made = names_in(scratch, |n| n.ends_with(".plume"));
    assert_eq!(made.len(), 1, "{made:?}");
    made[0].clone()
}

#[test]
fn a_full_cache_directory_fails_the_render_and_keeps_the_old_cache() {
    let test = "a_full_cache_directory_fails_the_render_and_keeps_the_old_cache";
    let dir = tmpdir("faults", "full-auto");
    let Some(disk) = tmpfs_or_skip(test, &dir, "full", 2 * MIB) else { return };
    let full = disk.dir.clone();
    let vdb = explosion(&dir, 64, Some(6));
    let budget = ["--memory-budget", "64KiB"];
    let scratch = dir.join("scratch");
    let name = auto_cache_name(&vdb, &scratch, &budget);
    // A damaged cache where the automatic one goes: rebuilt, and the disk is full
    let damaged = b"a damaged automatic cache".to_vec();
    std::fs::write(full.join(&name), &damaged).unwrap();
    let old_exr = b"the previous image".to_vec();
    let exr = dir.join("out.exr");
    std::fs::write(&exr, &old_exr).unwrap();
    fill(&full);
    let o = render(&vdb, &exr, &[&budget[..], &["--cache-dir", s(&full)]].concat());
    assert_output_failure(&o, &full.join(&name), "No space left on device");
    assert!(stderr(&o).contains("rebuilding the automatic cache"), "{}", stderr(&o));
    assert_eq!(
        std::fs::read(full.join(&name)).unwrap(),
        damaged,
        "the old cache stays until a new one replaces it"
    );
    assert_eq!(std::fs::read(&exr).unwrap(), old_exr, "no image was written");
    assert_eq!(temporaries(&full), Vec::<String>::new(), "temporaries left");
    // With room again the cache is rebuilt and renders as in the scratch directory
    std::fs::remove_file(full.join("filler")).unwrap();
    let o = render(&vdb, &exr, &[&budget[..], &["--cache-dir", s(&full)]].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(pixel_bits(&exr_pixels(&exr)), pixel_bits(&exr_pixels(&scratch.join("name.exr"))));
    let info = plume(&["info", s(&full.join(&name))]);
    assert!(info.status.success(), "{}", stderr(&info));
    drop(disk);
    let _ = std::fs::remove_dir_all(&dir);
}

/// Estimated peak memory of reading `vdb`'s `density` and `temperature` in core, as
/// plume estimates it: every leaf's 2 KiB of values, twice.
fn in_core_estimate(vdb: &Path) -> u64 {
    let o = plume(&["info", "--json", s(vdb)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let grids: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let leaves: u64 =
        grids.as_array().unwrap().iter().map(|g| g["leaf_count"].as_u64().unwrap()).sum();
    leaves * 2 * 512 * 4
}

#[test]
fn read_only_cache_directories() {
    let test = "read_only_cache_directories";
    let dir = tmpdir("faults", "read-only");
    let Some(ro) = tmpfs_or_skip(test, &dir, "ro", 16 * MIB) else { return };
    let (input_dir, shared, xdg) =
        (ro.dir.join("input"), ro.dir.join("shared"), ro.dir.join("xdg"));
    for d in [&input_dir, &shared, &xdg] {
        std::fs::create_dir(d).unwrap();
    }
    // 128³: 1.3 MB on disk, 4.8 MiB estimated in core, so a budget between the two
    // (below four times the file) both asks for an automatic cache and fits in memory
    let vdb = input_dir.join("ex.vdb");
    synth_explosion(&vdb, 128, Some(8));
    let file_bytes = std::fs::metadata(&vdb).unwrap().len();
    let estimate = in_core_estimate(&vdb);
    assert!(estimate < 4 * file_bytes, "the explosion changed: {estimate} bytes in core vs {file_bytes} on disk; pick another resolution");
    let fits = ((estimate + 4 * file_bytes) / 2).to_string();
    let budget = ["--memory-budget", &fits];
    // A cache prepared in the shared directory before it becomes read-only
    let o = render(
        &vdb,
        &dir.join("shared.exr"),
        &[&budget[..], &["--cache-dir", s(&shared)]].concat(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let reference = pixel_bits(&exr_pixels(&dir.join("shared.exr")));
    if let Err(reason) = ro.read_only() {
        drop(ro);
        let _ = std::fs::remove_dir_all(&dir);
        return skip(test, &reason);
    }
    let run = |out: &str, flags: &[&str], xdg_home: &Path| {
        Command::new(PLUME)
            .args([
                "render",
                s(&vdb),
                "-o",
                s(&dir.join(out)),
                "--spp",
                "2",
                "--width",
                "32",
                "--height",
                "24",
                "--seed",
                "3",
                "-q",
            ])
            .args(flags)
            .env("XDG_CACHE_HOME", xdg_home)
            .output()
            .unwrap()
    };
    let writable_xdg = dir.join("xdg");

    // An explicit --cache-dir that cannot be written: exit 4, naming it and the flag,
    // whether it exists or would have to be made
    for cache_dir in [ro.dir.join("empty"), xdg.clone()] {
        let o =
            run("x.exr", &[&budget[..], &["--cache-dir", s(&cache_dir)]].concat(), &writable_xdg);
        assert_output_failure(&o, &cache_dir, "--cache-dir");
        assert!(stderr(&o).contains("Read-only file system"), "{}", stderr(&o));
        assert!(!dir.join("x.exr").exists());
    }
    // …but a read-only one that holds a current cache is used as it is
    let o =
        run("shared-ro.exr", &[&budget[..], &["--cache-dir", s(&shared)]].concat(), &writable_xdg);
    assert!(o.status.success() && !stderr(&o).contains("converting"), "{}", stderr(&o));
    assert_eq!(pixel_bits(&exr_pixels(&dir.join("shared-ro.exr"))), reference);

    // The input's directory is read-only: the cache goes to $XDG_CACHE_HOME/plume
    let o = run("xdg.exr", &budget, &writable_xdg);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains(s(&writable_xdg.join("plume"))), "{}", stderr(&o));
    assert_eq!(names_in(&writable_xdg.join("plume"), |n| n.ends_with(".plume")).len(), 1);
    assert_eq!(pixel_bits(&exr_pixels(&dir.join("xdg.exr"))), reference);
    // Neither is writable: read in core, as it fits the budget, with a warning
    let o = run("core.exr", &budget, &xdg);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("nowhere to write the automatic brick cache")
            && stderr(&o).contains("reading it into memory"),
        "{}",
        stderr(&o)
    );
    assert_eq!(pixel_bits(&exr_pixels(&dir.join("core.exr"))), reference);
    // …and refused when it does not fit
    let o = run("none.exr", &["--memory-budget", "1MiB"], &xdg);
    assert_output_failure(&o, &input_dir, "--memory-budget");
    let line = &error_lines(&o)[0];
    assert!(line.contains(s(&xdg.join("plume"))) && line.contains("--cache-dir"), "{line}");
    assert!(!dir.join("none.exr").exists());
    drop(ro);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn two_processes_making_the_same_automatic_cache_share_it() {
    let dir = tmpdir("faults", "concurrent");
    let vdb = explosion(&dir, 64, Some(9));
    let in_core = dir.join("core.exr");
    let o = render(&vdb, &in_core, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let reference = pixel_bits(&exr_pixels(&in_core));
    let mut waited = 0;
    for round in 0..6 {
        let cache_dir = dir.join(format!("cache{round}"));
        std::fs::create_dir_all(&cache_dir).unwrap();
        // Odd rounds start from a damaged cache, which both find stale: the one that
        // waited must use the other's new cache, not delete it as stale
        if round % 2 == 1 {
            let name =
                names_in(&dir.join(format!("cache{}", round - 1)), |n| n.ends_with(".plume"))
                    .pop()
                    .unwrap();
            std::fs::write(cache_dir.join(name), b"damaged").unwrap();
        }
        let children: Vec<_> = (0..2)
            .map(|k| {
                let out = dir.join(format!("r{round}-{k}.exr"));
                Command::new(PLUME)
                    .args([
                        "render",
                        s(&vdb),
                        "-o",
                        s(&out),
                        "--spp",
                        "2",
                        "--width",
                        "32",
                        "--height",
                        "24",
                        "--seed",
                        "3",
                        "-q",
                    ])
                    .args(["--memory-budget", "64KiB", "--cache-dir", s(&cache_dir)])
                    .stderr(Stdio::piped())
                    .spawn()
                    .unwrap()
            })
            .collect();
        let outputs: Vec<Output> =
            children.into_iter().map(|c| c.wait_with_output().unwrap()).collect();
        let messages: Vec<String> = outputs.iter().map(stderr).collect();
        for (k, o) in outputs.iter().enumerate() {
            assert!(o.status.success(), "round {round}, render {k}: {}", messages[k]);
            assert_eq!(
                pixel_bits(&exr_pixels(&dir.join(format!("r{round}-{k}.exr")))),
                reference,
                "round {round}, render {k}"
            );
        }
        let conversions = messages.iter().filter(|m| m.contains("converting it once")).count();
        assert_eq!(
            conversions, 1,
            "round {round}: one process converts, the other uses its cache: {messages:#?}"
        );
        waited += messages.iter().filter(|m| m.contains("waiting for another process")).count();
        let caches = names_in(&cache_dir, |n| n.ends_with(".plume"));
        assert_eq!(caches.len(), 1, "{caches:?}");
        let info = plume(&["info", s(&cache_dir.join(&caches[0]))]);
        assert!(
            info.status.success() && String::from_utf8_lossy(&info.stdout).contains("checksums ok"),
            "{}",
            stderr(&info)
        );
        assert_eq!(
            temporaries(&cache_dir),
            Vec::<String>::new(),
            "round {round}: temporaries left"
        );
    }
    // How often the two overlapped (the second waited for the first's lock) depends on
    // the scheduler; the assertions above hold either way
    let _ = writeln!(std::io::stderr(), "two_processes_making_the_same_automatic_cache_share_it: one waited for the other in {waited} of 6 rounds");
    let _ = std::fs::remove_dir_all(&dir);
}

/// A process that holds the conversion lock of an automatic cache and never
/// lets go (it hangs) holds up a render only for `--cache-lock-timeout`: then the frame is
/// rendered from the .vdb read into memory, with one warning naming the lock file, when
/// that fits the memory budget, and fails with one error line naming it (exit 4) when it
/// does not. The lock is held by this test (`flock` of its own open file).
#[test]
fn a_cache_lock_held_past_the_timeout_is_given_up() {
    use std::os::fd::AsRawFd;
    use std::time::{Duration, Instant};
    let dir = tmpdir("faults", "lock-timeout");
    // As in read_only_cache_directories: a budget that asks for an automatic cache and
    // fits the in-core read
    let vdb = dir.join("ex.vdb");
    synth_explosion(&vdb, 128, Some(8));
    let estimate = in_core_estimate(&vdb);
    let file_bytes = std::fs::metadata(&vdb).unwrap().len();
    assert!(estimate < 4 * file_bytes, "the explosion changed: {estimate} bytes in core vs {file_bytes} on disk; pick another resolution");
    let fits = ((estimate + 4 * file_bytes) / 2).to_string();
    let budget = ["--memory-budget", &fits];
    let name = auto_cache_name(&vdb, &dir.join("scratch"), &budget);
    let reference = pixel_bits(&exr_pixels(&dir.join("scratch").join("name.exr")));
    let cache_dir = dir.join("shared");
    std::fs::create_dir_all(&cache_dir).unwrap();
    let lock_path = cache_dir.join(format!(".{name}.lock"));
    let lock = std::fs::File::create(&lock_path).unwrap();
    // SAFETY: flock on a descriptor `lock` owns, released when it is dropped.
    assert_eq!(unsafe { libc::flock(lock.as_raw_fd(), libc::LOCK_EX | libc::LOCK_NB) }, 0);
    let timed = |out: &str, flags: &[&str]| {
        let start = Instant::now();
        let mut child = Command::new(PLUME)
            .args([
                "render",
                s(&vdb),
                "-o",
                s(&dir.join(out)),
                "--spp",
                "2",
                "--width",
                "32",
                "--height",
                "24",
                "--seed",
                "3",
                "-q",
            ])
            .args(["--cache-dir", s(&cache_dir), "--cache-lock-timeout", "1"])
            .args(flags)
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        while child.try_wait().unwrap().is_none() {
            if start.elapsed() > Duration::from_secs(120) {
                let _ = child.kill();
                panic!("plume still waits for the lock after 120 s");
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        (child.wait_with_output().unwrap(), start.elapsed())
    };
    // Fits the budget: read in core after the timeout, the same image, no cache made
    let (o, took) = timed("core.exr", &budget);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(took >= Duration::from_secs(1), "it gave up before the timeout: {took:?}");
    let warnings: Vec<String> = stderr(&o)
        .lines()
        .filter(|l| l.starts_with("plume: warning:"))
        .map(str::to_owned)
        .collect();
    assert_eq!(warnings.len(), 1, "{}", stderr(&o));
    assert!(
        warnings[0].contains(s(&lock_path))
            && warnings[0].contains("--cache-lock-timeout")
            && warnings[0].contains("into memory"),
        "{}",
        warnings[0]
    );
    assert!(stderr(&o).contains("waiting for another process"), "{}", stderr(&o));
    assert_eq!(pixel_bits(&exr_pixels(&dir.join("core.exr"))), reference);
    assert_eq!(
        names_in(&cache_dir, |n| n.ends_with(".plume") || n.ends_with(".tmp")),
        Vec::<String>::new()
    );
    // Does not fit: exit 4, one line naming the lock file and the way out; no image
    let (o, _) = timed("none.exr", &["--memory-budget", "1MiB"]);
    assert_output_failure(&o, &lock_path, "--cache-lock-timeout");
    assert!(
        error_lines(&o)[0].contains(s(&cache_dir.join(&name)))
            && error_lines(&o)[0].contains("--memory-budget"),
        "{}",
        stderr(&o)
    );
    assert!(!dir.join("none.exr").exists());
    // Once the holder lets go, the cache is made and used as usual
    drop(lock);
    let (o, _) = timed("cached.exr", &budget);
    assert!(o.status.success() && stderr(&o).contains("converting it once"), "{}", stderr(&o));
    assert_eq!(pixel_bits(&exr_pixels(&dir.join("cached.exr"))), reference);
    let _ = std::fs::remove_dir_all(&dir);
}
