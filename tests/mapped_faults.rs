//! Files that fail under plume: a brick cache truncated or replaced while
//! `plume render` or `plume info` maps it, and a `.vdb` truncated while `plume prepare`
//! streams it, end the process with one line on stderr naming the file and exit code 4,
//! never a death by SIGBUS, and leave earlier outputs as they were; in a sequence, they
//! end the run at once with exit code 4 too.
//!
//! No test depends on timing: the process that maps the file is stopped (SIGSTOP) once
//! `/proc/PID/maps` shows the mapping, the file is changed, and the process continued.
//! Whatever plume was doing at that moment, it finds the change: a lost page faults, the
//! checksum pass cannot read it, or the final check of the file sees it.

use crate::common;

use std::fs::File;
use std::os::unix::fs::MetadataExt;
use std::os::unix::process::ExitStatusExt;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

use common::{plume, s, stderr, tmpdir, PLUME};

/// Longest a child may take on a loaded machine before the test fails.
const PATIENCE: Duration = Duration::from_secs(300);
/// CPU time (clock ticks, 1/100 s) after which a render of the small flare is surely
/// past loading and tracing rays.
const RENDERING: u64 = 30;

fn send(pid: u32, signal: &str) {
    let ok =
        Command::new("kill").args([signal, &pid.to_string()]).status().expect("run kill").success();
    assert!(ok, "kill {signal} {pid}");
}

/// `pid` and its children (the isolated reader).
fn family(pid: u32) -> Vec<u32> {
    let mut all = vec![pid];
    for entry in std::fs::read_dir("/proc").unwrap().flatten() {
        let Some(child) = entry.file_name().to_str().and_then(|n| n.parse::<u32>().ok()) else {
            continue;
        };
        let Ok(stat) = std::fs::read_to_string(format!("/proc/{child}/stat")) else { continue };
        // pid (comm) state ppid …: comm may hold spaces, so parse after the last ')'
        let ppid = stat
            .rsplit_once(')')
            .and_then(|(_, rest)| rest.split_whitespace().nth(1)?.parse::<u32>().ok());
        if ppid == Some(pid) {
            all.push(child);
        }
    }
    all
}

/// True when process `pid` maps the file with inode `ino`.
fn maps(pid: u32, ino: u64) -> bool {
    let Ok(maps) = std::fs::read_to_string(format!("/proc/{pid}/maps")) else { return false };
    maps.lines().any(|l| l.split_whitespace().nth(4) == Some(ino.to_string().as_str()))
}

/// User + system CPU time of `pid` in clock ticks.
fn cpu_ticks(pid: u32) -> u64 {
    let Ok(stat) = std::fs::read_to_string(format!("/proc/{pid}/stat")) else { return 0 };
    let fields: Vec<&str> =
        stat.rsplit_once(')').map_or(vec![], |(_, rest)| rest.split_whitespace().collect());
    // Fields 14 and 15 of stat(5), counted from the state (field 3) here
    fields.get(11).and_then(|u| u.parse::<u64>().ok()).unwrap_or(0)
        + fields.get(12).and_then(|u| u.parse::<u64>().ok()).unwrap_or(0)
}

/// Wait until a process of `child`'s family maps `file` and has used `ticks` of CPU,
/// then stop it (SIGSTOP) and return its pid; `None` when `child` ended first.
fn stop_when_mapped(child: &mut Child, file: &Path, ticks: u64) -> Option<u32> {
    let ino = std::fs::metadata(file).unwrap().ino();
    let start = Instant::now();
    while child.try_wait().unwrap().is_none() {
        assert!(start.elapsed() < PATIENCE, "{} was never mapped", file.display());
        // plume itself first (cheap), then its children
        let found = if maps(child.id(), ino) {
            Some(child.id())
        } else {
            family(child.id()).into_iter().find(|&p| maps(p, ino))
        };
        if let Some(pid) = found {
            // A process that ended between the look and the signal (an isolated reader
            // finishing its file) is not stopped: look again
            if cpu_ticks(pid) >= ticks
                && Command::new("kill")
                    .args(["-STOP", &pid.to_string()])
                    .status()
                    .expect("run kill")
                    .success()
            {
                return Some(pid);
            }
        }
        std::thread::yield_now();
    }
    None
}

/// Run plume with `args` in `dir` (where a core dump would go), output captured.
fn spawn(dir: &Path, args: &[&str]) -> Child {
    Command::new(PLUME)
        .args(args)
        .current_dir(dir)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run plume")
}

/// Wait for `child` (at most [`PATIENCE`]).
fn finish(mut child: Child) -> Output {
    let start = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if start.elapsed() > PATIENCE {
            let _ = child.kill();
            panic!("plume did not end within {PATIENCE:?}");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    child.wait_with_output().unwrap()
}

/// Exit code 4, no signal, and exactly one line on stderr: an error naming `file` and
/// holding every one of `needles`.
#[track_caller]
fn assert_failed_cleanly(o: &Output, file: &Path, needles: &[&str]) -> String {
    let err = stderr(o);
    assert_eq!(o.status.signal(), None, "plume died by a signal: {err}");
    assert_eq!(o.status.code(), Some(4), "{err}");
    let lines: Vec<&str> = err.lines().collect();
    assert_eq!(lines.len(), 1, "one line on stderr: {err}");
    assert!(
        lines[0].starts_with("plume: error: ") && lines[0].contains(s(file)),
        "the line names {}: {err}",
        file.display()
    );
    for needle in needles {
        assert!(lines[0].contains(needle), "{err:?} lacks {needle:?}");
    }
    err
}

fn truncate(file: &Path, bytes: u64) {
    File::options().write(true).open(file).unwrap().set_len(bytes).unwrap();
}

/// The names in `dir`, sorted.
fn listing(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

/// A 128³ flare written straight to a cache (3.7 MB).
fn flare(dir: &Path, name: &str, seed: &str) -> PathBuf {
    let cache = dir.join(name);
    let o = plume(&["synth", "flare", "--resolution", "128", "--seed", seed, "-o", s(&cache)]);
    assert!(o.status.success(), "{}", stderr(&o));
    cache
}

#[test]
fn a_cache_truncated_under_a_render_ends_it_with_exit_code_4() {
    let dir = tmpdir("faults", "render");
    let cache = flare(&dir, "flare.plume", "1");
    let out = dir.join("out.exr");
    // An earlier output, which a failed render must leave as it was
    let o = plume(&[
        "render",
        s(&cache),
        "-o",
        s(&out),
        "--spp",
        "1",
        "--width",
        "32",
        "--height",
        "24",
        "-q",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let before = std::fs::read(&out).unwrap();
    for (order, progress) in [("tile-major", "openjd"), ("progressive", "json")] {
        let victim = dir.join(format!("{order}.plume"));
        std::fs::copy(&cache, &victim).unwrap();
        // Far more samples than it can take before the file is truncated. The camera is
        // inside the volume's bounds, so that every ray reads the brick table: in
        // tile-major order, a first tile whose rays all miss the volume would render its
        // million samples without touching the file
        let args = [
            "render",
            s(&victim),
            "-o",
            s(&out),
            "--overwrite",
            "--spp",
            "1000000",
            "--width",
            "64",
            "--height",
            "48",
            "--sample-order",
            order,
        ];
        let inside = [
            "--camera-from",
            "0,20,0",
            "--camera-at",
            "10,20,10",
            "--threads",
            "2",
            "-q",
            "--progress",
            progress,
        ];
        let mut child = spawn(&dir, &[&args[..], &inside].concat());
        let pid = stop_when_mapped(&mut child, &victim, RENDERING)
            .expect("the render ended before the test truncated its input");
        // The header page stays: every section is lost
        truncate(&victim, 8192);
        send(pid, "-CONT");
        let o = finish(child);
        let err = assert_failed_cleanly(&o, &victim, &["brick cache", "truncated"]);
        eprintln!("{order}: {err}");
        // The progress protocol's failure line ends stdout, with the same message
        let message = err.trim_end().strip_prefix("plume: error: ").unwrap();
        let stdout = String::from_utf8(o.stdout.clone()).unwrap();
        let last = stdout.lines().last().unwrap_or_default();
        if progress == "openjd" {
            assert_eq!(last, format!("openjd_fail: exit code 4: {message}"), "{stdout}");
        } else {
            let event: serde_json::Value =
                serde_json::from_str(last).unwrap_or_else(|e| panic!("{e}: {stdout}"));
            assert_eq!(
                (event["event"].as_str(), event["exit_code"].as_i64(), event["error"].as_str()),
                (Some("done"), Some(4), Some(message))
            );
        }
        assert_eq!(std::fs::read(&out).unwrap(), before, "{order}: the earlier output is intact");
        std::fs::remove_file(&victim).unwrap();
        assert_eq!(listing(&dir), ["flare.plume", "out.exr"], "{order}: no temporary file is left");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_cache_truncated_while_info_checks_it_fails_cleanly() {
    let dir = tmpdir("faults", "info");
    let cache = flare(&dir, "flare.plume", "1");
    let victim = dir.join("victim.plume");
    // `info` maps the file, checks every checksum and the file again, and exits: a few
    // milliseconds for this file, so it may end before the test stops it; then again
    for attempt in 0..50 {
        std::fs::copy(&cache, &victim).unwrap();
        let mut child = spawn(&dir, &["info", s(&victim)]);
        let Some(pid) = stop_when_mapped(&mut child, &victim, 0) else {
            let o = finish(child);
            assert!(o.status.success(), "the whole file: {}", stderr(&o));
            continue;
        };
        truncate(&victim, 3 * 4096);
        send(pid, "-CONT");
        let o = finish(child);
        if o.status.success() {
            // Stopped after its last check, while printing
            continue;
        }
        let err = assert_failed_cleanly(&o, &victim, &["brick cache", "truncated"]);
        eprintln!("attempt {attempt}: {err}");
        assert!(o.stdout.is_empty(), "nothing printed about a file that failed");
        // Truncated before it is opened, the same file is refused as damaged (exit 3)
        let o = plume(&["info", s(&victim)]);
        assert_eq!(o.status.code(), Some(3), "{}", stderr(&o));
        let _ = std::fs::remove_dir_all(&dir);
        return;
    }
    panic!("info never stopped between mapping the file and its last check in 50 attempts");
}

#[test]
fn a_cache_replaced_under_a_render_is_refused_before_writing() {
    let dir = tmpdir("faults", "replaced");
    let cache = flare(&dir, "flare.plume", "1");
    let other = flare(&dir, "other.plume", "2");
    let victim = dir.join("victim.plume");
    let staged = dir.join("staged.plume");
    let out = dir.join("out.exr");
    // About a second unloaded; stopped when the cache is mapped, long before it ends
    let render = || {
        spawn(
            &dir,
            &[
                "render",
                s(&victim),
                "-o",
                s(&out),
                "--spp",
                "4096",
                "--width",
                "32",
                "--height",
                "24",
                "-q",
            ],
        )
    };
    // Another cache renamed over it (`plume prepare` again with changed data): the render
    // goes on from the file it mapped, then refuses to save a frame of a file that is
    // no longer the one at that path. (On a loaded machine the stop may come only after
    // the last check; then again.)
    let mut refused = false;
    for _ in 0..10 {
        std::fs::copy(&cache, &victim).unwrap();
        let mut child = render();
        let pid = stop_when_mapped(&mut child, &victim, 0)
            .expect("the render ended before it was stopped");
        std::fs::copy(&other, &staged).unwrap();
        std::fs::rename(&staged, &victim).unwrap();
        send(pid, "-CONT");
        let o = finish(child);
        if o.status.success() {
            std::fs::remove_file(&out).unwrap();
            continue;
        }
        let err = assert_failed_cleanly(
            &o,
            &victim,
            &["brick cache", "replaced by another file", "nothing computed from it was written"],
        );
        eprintln!("{err}");
        assert!(!out.exists(), "no output from a replaced input");
        refused = true;
        break;
    }
    assert!(refused, "the render was never stopped before its last check in 10 attempts");
    // The same contents renamed over it (an automatic cache rebuilt by another process)
    // change nothing
    std::fs::copy(&cache, &victim).unwrap();
    let mut child = render();
    let pid =
        stop_when_mapped(&mut child, &victim, 0).expect("the render ended before it was stopped");
    std::fs::copy(&cache, &staged).unwrap();
    std::fs::rename(&staged, &victim).unwrap();
    send(pid, "-CONT");
    let o = finish(child);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(out.exists());
    let _ = std::fs::remove_dir_all(&dir);
}

/// A sequence stops at an input that fails while in use, with exit code 4, whichever way
/// the failure is found (docs/farm.md, "Exit codes"): frame 1's cache replaced
/// under the render (no fault: the final check of the file refuses it) or truncated
/// (a lost page, SIGBUS). Frames 2 and 3 are not started, nothing is written, and the
/// rerun of the same command with whole files renders all three.
#[test]
fn a_sequence_stops_at_an_input_that_fails_while_in_use_with_exit_code_4() {
    let dir = tmpdir("faults", "sequence");
    let cache = flare(&dir, "flare.plume", "1");
    let other = flare(&dir, "other.plume", "2");
    let staged = dir.join("staged.plume");
    let frame = |n: u32| dir.join(format!("seq.{n:04}.plume"));
    let out = |n: u32| dir.join(format!("out.{n:04}.exr"));
    let (inputs, outputs) = (dir.join("seq.####.plume"), dir.join("out.####.exr"));
    let args = [
        "render",
        s(&inputs),
        "-o",
        s(&outputs),
        "--frames",
        "1-3",
        "--width",
        "32",
        "--height",
        "24",
        "-q",
        "--progress",
        "json",
    ];
    let sequence = |spp: &str, extra: &[&str]| {
        for n in 1..=3 {
            std::fs::copy(&cache, frame(n)).unwrap();
        }
        spawn(&dir, &[&args[..], &["--spp", spp], extra].concat())
    };
    let stopped = |o: &Output, needles: &[&str]| {
        let err = assert_failed_cleanly(o, &frame(1), needles);
        let message = err.trim_end().strip_prefix("plume: error: ").unwrap();
        let stdout = String::from_utf8(o.stdout.clone()).unwrap();
        let event: serde_json::Value =
            serde_json::from_str(stdout.lines().last().unwrap_or_default())
                .unwrap_or_else(|e| panic!("{e}: {stdout}"));
        assert_eq!(
            (event["event"].as_str(), event["exit_code"].as_i64(), event["error"].as_str()),
            (Some("done"), Some(4), Some(message))
        );
        let events =
            stdout.lines().filter_map(|l| serde_json::from_str::<serde_json::Value>(l).ok());
        let started: Vec<i64> = events
            .filter(|e| e["event"] == "frame_start")
            .filter_map(|e| e["frame"].as_i64())
            .collect();
        assert_eq!(started, [1], "frames after the failed one were started: {stdout}");
        for n in 1..=3 {
            assert!(!out(n).exists(), "frame {n} was written");
        }
        err
    };
    // Replaced (about a second per frame unloaded; on a loaded machine the stop may come
    // only after frame 1's last check: then again)
    let mut refused = false;
    for _ in 0..10 {
        let mut child = sequence("4096", &[]);
        let pid = stop_when_mapped(&mut child, &frame(1), 0)
            .expect("the render ended before it was stopped");
        std::fs::copy(&other, &staged).unwrap();
        std::fs::rename(&staged, frame(1)).unwrap();
        send(pid, "-CONT");
        let o = finish(child);
        if o.status.success() {
            (1..=3).for_each(|n| std::fs::remove_file(out(n)).unwrap());
            continue;
        }
        eprintln!("replaced: {}", stopped(&o, &["brick cache", "replaced by another file"]));
        refused = true;
        break;
    }
    assert!(refused, "the render was never stopped before its last check in 10 attempts");
    // Truncated under frame 1, far from its end (camera inside the volume, as above)
    let mut child = sequence("1000000", &["--camera-from", "0,20,0", "--camera-at", "10,20,10"]);
    let pid = stop_when_mapped(&mut child, &frame(1), RENDERING)
        .expect("the render ended before the test truncated its input");
    truncate(&frame(1), 8192);
    send(pid, "-CONT");
    eprintln!("truncated: {}", stopped(&finish(child), &["brick cache", "truncated"]));
    // The same command again, with whole files: every frame
    let o = finish(sequence("16", &[]));
    assert!(o.status.success(), "{}", stderr(&o));
    assert!((1..=3).all(|n| out(n).exists()));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_sigbus_from_elsewhere_still_kills() {
    let dir = tmpdir("faults", "kill");
    let cache = flare(&dir, "flare.plume", "1");
    let mut child = spawn(
        &dir,
        &[
            "render",
            s(&cache),
            "-o",
            s(&dir.join("out.exr")),
            "--spp",
            "1000000",
            "--width",
            "32",
            "--height",
            "24",
            "-q",
        ],
    );
    let pid =
        stop_when_mapped(&mut child, &cache, 0).expect("the render ended before it was stopped");
    // Sent, not a fault in a mapped file: the handler leaves it to the default action
    send(pid, "-BUS");
    send(pid, "-CONT");
    let o = finish(child);
    assert_eq!(o.status.signal(), Some(7), "death by SIGBUS: {:?} {}", o.status, stderr(&o));
    assert!(stderr(&o).is_empty(), "{}", stderr(&o));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_vdb_truncated_while_prepare_streams_it_fails_cleanly() {
    let dir = tmpdir("faults", "prepare");
    let vdb = dir.join("explosion.vdb");
    let o = plume(&["synth", "explosion", "--resolution", "128", "-o", s(&vdb)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let bytes = std::fs::metadata(&vdb).unwrap().len();
    let out = dir.join("explosion.plume");
    let victim = dir.join("victim.vdb");
    // OpenVDB maps the file in the isolated reader (default) or in plume itself
    for isolation in [&[][..], &["--no-isolation"][..]] {
        std::fs::copy(&vdb, &victim).unwrap();
        let mut child =
            spawn(&dir, &[&["prepare", s(&victim), "-o", s(&out), "-q"][..], isolation].concat());
        let pid =
            stop_when_mapped(&mut child, &victim, 0).expect("prepare ended before it was stopped");
        truncate(&victim, bytes / 2);
        // The stopped reader may be gone already: plume itself can notice the truncation,
        // fail, and take its isolated reader with it (PDEATHSIG), stopped or not
        if pid == child.id() {
            send(pid, "-CONT");
        } else {
            let _ = Command::new("kill").args(["-CONT", &pid.to_string()]).status();
        }
        let err = assert_failed_cleanly(&finish(child), &victim, &["VDB file", "truncated"]);
        eprintln!("{isolation:?}: {err}");
        assert!(!out.exists(), "{isolation:?}: no cache from a truncated file");
    }
    // The conversion's temporary file is removed by the next conversion, which succeeds
    let o = plume(&["prepare", s(&vdb), "-o", s(&out), "-q"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(
        listing(&dir),
        ["explosion.plume", "explosion.vdb", "victim.vdb"],
        "no temporary file is left"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
