//! Farm behaviour of the `plume` binary, as a render farm runs it: real child processes,
//! real files, real signals. Volumes are generated 32³ explosions and images are tiny, so
//! the whole file runs in seconds.

use crate::common;

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::Instant;

use common::{names_in, pixel_bits, plume, plume_exits, s, stderr, synth_explosion, tmpdir, PLUME};
use plume::farm::part::{read_part, Completion};
use plume::output::read_exr_contents;

fn spawn(args: &[&str]) -> Child {
    Command::new(PLUME)
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn plume")
}

/// `dir/ex.NNNN.vdb` for each frame: 32³ explosions, noise seed = frame, so frames differ.
fn sequence(dir: &Path, frames: &[i64]) {
    for f in frames {
        synth_explosion(&dir.join(format!("ex.{f:04}.vdb")), 32, Some(*f));
    }
}

/// Pixel bits of an EXR (the comparison for "bit-identical").
fn bits(p: &Path) -> Vec<u32> {
    pixel_bits(&read_exr_contents(p).unwrap().pixels)
}

fn meta(p: &Path, key: &str) -> String {
    read_exr_contents(p).unwrap().metadata.get(&format!("plume:{key}")).cloned().unwrap_or_default()
}

fn stats_lines(p: &Path) -> Vec<serde_json::Value> {
    std::fs::read_to_string(p).unwrap().lines().map(|l| serde_json::from_str(l).unwrap()).collect()
}

fn temporaries(d: &Path) -> Vec<String> {
    names_in(d, |n| n.ends_with(".tmp"))
}

/// Small render settings shared by the tests.
const SMALL: [&str; 6] = ["--width", "24", "--height", "16", "--density-scale", "3"];

#[test]
fn sequence_with_patterns_renders_each_frame_with_its_seed_and_skips_complete_outputs() {
    let d = tmpdir("farm", "seq");
    sequence(&d, &[1001, 1002, 1003]);
    let input = d.join("ex.$F4.vdb");
    let output = d.join("out.%04d.exr");
    let preview = d.join("prev.####.png");
    let stats = d.join("stats.jsonl");
    let mut args = vec![
        "render",
        s(&input),
        "-o",
        s(&output),
        "--preview",
        s(&preview),
        "--stats",
        s(&stats),
        "--frames",
        "1001-1003",
        "--spp",
        "2",
        "-q",
    ];
    args.extend(SMALL);
    let o = plume(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    let outs: Vec<PathBuf> = (1001..=1003).map(|f| d.join(format!("out.{f}.exr"))).collect();
    for (f, out) in (1001..=1003).zip(&outs) {
        assert!(d.join(format!("prev.{f}.png")).exists());
        assert_eq!(meta(out, "seed"), f.to_string(), "the default seed is the frame number");
        assert_eq!(meta(out, "frame"), f.to_string());
        assert_eq!(meta(out, "status"), "complete");
        assert_eq!(meta(out, "spp"), "2");
        for key in [
            "coreHours",
            "cpuSeconds",
            "wallSeconds",
            "peakRssBytes",
            "inputSha256",
            "host",
            "commandLine",
            "samplesPerSecond",
        ] {
            assert!(!meta(out, key).is_empty(), "header lacks plume:{key}");
        }
    }
    assert_ne!(bits(&outs[0]), bits(&outs[1]));
    let lines = stats_lines(&stats);
    assert_eq!(lines.len(), 3, "one JSON line per frame");
    for (l, f) in lines.iter().zip(1001..) {
        assert_eq!(l["frame"], f);
        assert_eq!(l["seed"], f);
        assert_eq!(l["spp"], 2);
        assert_eq!(l["input_sha256"].as_str().unwrap().len(), 64);
        for key in [
            "wall_seconds",
            "cpu_seconds",
            "core_hours",
            "allocated_core_hours",
            "samples_per_second",
            "peak_rss_bytes",
            "plume_version",
            "command_line",
            "host",
        ] {
            assert!(l.get(key).is_some(), "stats lack {key}");
        }
    }
    let first = bits(&outs[1]);

    // Rerun: every output is complete, so nothing is rendered
    let o = plume(&args);
    assert!(o.status.success());
    assert_eq!(stderr(&o).matches("already complete").count(), 3, "{}", stderr(&o));
    assert_eq!(stats_lines(&stats).len(), 3);

    // A truncated output is not complete: rendered again, to the same bits
    let bytes = std::fs::read(&outs[1]).unwrap();
    std::fs::write(&outs[1], &bytes[..bytes.len() / 2]).unwrap();
    let o = plume(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("not a valid plume image"), "{}", stderr(&o));
    assert_eq!(bits(&outs[1]), first);
    assert_eq!(stats_lines(&stats).len(), 4);

    // Other settings: rendered again; --overwrite: everything rendered again
    let mut other = vec![
        "render",
        s(&input),
        "-o",
        s(&output),
        "--stats",
        s(&stats),
        "--frames",
        "1001",
        "--spp",
        "2",
        "--seed",
        "7",
        "-q",
    ];
    other.extend(SMALL);
    let o = plume(&other);
    assert!(o.status.success());
    assert!(stderr(&o).contains("other settings"), "{}", stderr(&o));
    assert_eq!(meta(&outs[0], "seed"), "7");
    let mut again = args.clone();
    again.push("--overwrite");
    assert!(plume(&again).status.success());
    assert_eq!(stats_lines(&stats).len(), 8);
    assert_eq!(meta(&outs[0], "seed"), "1001");
}

#[test]
fn frame_numbers_wider_than_the_padding_are_printed_in_full() {
    let d = tmpdir("farm", "pad");
    sequence(&d, &[1]);
    let out = d.join("o.##.exr");
    let mut args = vec!["render", "-q", "--spp", "1", "--frames", "99-100", "-o", s(&out)];
    let input = d.join("ex.0001.vdb");
    args.push(s(&input));
    args.extend(SMALL);
    let o = plume(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(d.join("o.99.exr").exists() && d.join("o.100.exr").exists());
}

/// Every documented exit code, each from a real failing invocation (5 is in the signal test).
#[test]
fn every_exit_code_comes_from_a_real_failure() {
    let d = tmpdir("farm", "codes");
    sequence(&d, &[1, 3]);
    let seq = d.join("ex.####.vdb");
    let out = d.join("o.####.exr");
    let one = d.join("one.exr");
    let (seq, out, one) = (s(&seq).to_string(), s(&out).to_string(), s(&one).to_string());
    let first = d.join("ex.0001.vdb");
    let first = s(&first).to_string();
    let cases: Vec<(Vec<&str>, i32, &str)> = vec![
        (vec!["render", &seq, "-o", &out, "--frames", "1", "--spp", "1"], 0, ""),
        (vec!["render", &seq, "-o", &out, "--frames", "5-1"], 2, "--frames"),
        (vec!["render", &seq, "-o", &out], 2, "--frames"),
        (vec!["render", &first, "-o", &one, "--frames", "1-3"], 2, "--output"),
        (vec!["render", &first, "-o", &one, "--tile", "4/4"], 2, "--tile"),
        (vec!["render", &first, "-o", &one, "--crop", "0,0,25,8"], 2, "--crop"),
        (vec!["render", &first, "-o", &one, "--sample-range", "4..2"], 2, "--sample-range"),
        (vec!["render", &first, "-o", &one, "--time-limit", "0"], 2, "--time-limit"),
        (vec!["render", &seq, "-o", &out, "--frames", "2"], 3, "ex.0002.vdb"),
        (vec!["render", &first, "-o", "/nonexistent-dir/o.exr"], 4, "/nonexistent-dir/o.exr"),
        (
            vec!["render", &first, "-o", &one, "--spp", "100000000", "--time-limit", "0.5"],
            6,
            "time limit",
        ),
        (
            vec!["render", &seq, "-o", &out, "--frames", "1-3", "--spp", "1"],
            7,
            "1 of 3 frames failed: 2",
        ),
        (vec!["merge", "-o", &one, &first], 3, "ex.0001.vdb"),
        (vec!["merge", "-o", &one, "/nonexistent.exr"], 3, "/nonexistent.exr"),
    ];
    for (mut args, code, needle) in cases {
        if args[0] == "render" {
            args.extend(SMALL);
            args.push("-q");
        }
        plume_exits(&args, code, &[needle]);
    }
    // Exit 7: the other frames were rendered
    assert!(d.join("o.0001.exr").exists() && d.join("o.0003.exr").exists());
    // Exit 6: a valid image with the spp reached, which the rerun continues
    let (info, _) = read_part(Path::new(&one)).unwrap();
    assert_eq!(info.status, Completion::TimeLimit);
    let spp = info.samples.end;
    assert!((1..100_000_000).contains(&spp), "{spp}");
    let stats = d.join("s.jsonl");
    let mut args = vec![
        "render",
        &first,
        "-o",
        &one,
        "--spp",
        "100000000",
        "--time-limit",
        "0.5",
        "-q",
        "--stats",
        s(&stats),
    ];
    args.extend(SMALL);
    let o = plume(&args);
    assert_eq!(o.status.code(), Some(6), "{}", stderr(&o));
    let line = &stats_lines(&stats)[0];
    assert_eq!(line["resumed_from_spp"], spp, "continued, not restarted");
    assert!(line["spp"].as_u64().unwrap() > spp);
    assert_eq!(line["status"], "time-limit");
}

fn wait_for_progress(child: &mut Child) {
    let out = child.stdout.take().unwrap();
    let mut lines = BufReader::new(out).lines();
    loop {
        let l = lines.next().expect("plume printed progress").unwrap();
        if l.contains("\"event\":\"progress\"") {
            break;
        }
    }
    // Keep draining stdout so plume never blocks on a full pipe
    std::thread::spawn(move || for _ in lines {});
}

#[test]
fn sigterm_writes_a_valid_partial_image_and_the_rerun_finishes_it_bit_identically() {
    let d = tmpdir("farm", "term");
    sequence(&d, &[1]);
    let input = d.join("ex.0001.vdb");
    let reference = d.join("ref.exr");
    let out = d.join("o.exr");
    let base = |o: &Path, spp: &str| {
        let mut a: Vec<String> = [
            "render",
            s(&input),
            "-o",
            s(o),
            "--spp",
            spp,
            "--width",
            "32",
            "--height",
            "32",
            "--threads",
            "1",
            "-q",
            "--progress",
            "json",
        ]
        .iter()
        .map(|x| x.to_string())
        .collect();
        a.extend(["--density-scale", "3"].iter().map(|x| x.to_string()));
        a
    };
    // Raise the budget until the signal lands while passes remain (a slow machine or a
    // fast one: whichever)
    for spp in ["400", "4000", "40000"] {
        let _ = std::fs::remove_file(&out);
        let args = base(&out, spp);
        let mut child = spawn(&args.iter().map(String::as_str).collect::<Vec<_>>());
        wait_for_progress(&mut child);
        // SAFETY: a plain kill(2) of our own child.
        unsafe { libc::kill(child.id() as i32, libc::SIGTERM) };
        let o = child.wait_with_output().unwrap();
        if o.status.code() == Some(0) {
            continue;
        }
        assert_eq!(o.status.code(), Some(5), "{}", stderr(&o));
        assert!(stderr(&o).contains("SIGTERM"), "{}", stderr(&o));
        let (info, contents) = read_part(&out).unwrap();
        assert_eq!(info.status, Completion::Interrupted);
        let total: u64 = spp.parse().unwrap();
        assert!(info.samples.end >= 1 && info.samples.end < total, "{:?}", info.samples);
        assert!(contents.pixels.iter().flatten().all(|v| v.is_finite()));
        assert!(temporaries(&d).is_empty());
        // The rerun continues from the sums and ends where one uninterrupted render ends
        let o = plume(&args.iter().map(String::as_str).collect::<Vec<_>>());
        assert!(o.status.success(), "{}", stderr(&o));
        assert!(stderr(&o).contains("continuing from samples"), "{}", stderr(&o));
        assert_eq!(meta(&out, "status"), "complete");
        let r = base(&reference, spp);
        let o = plume(&r.iter().map(String::as_str).collect::<Vec<_>>());
        assert!(o.status.success());
        assert_eq!(bits(&out), bits(&reference), "interrupted + resumed = one render, bit for bit");
        return;
    }
    panic!("the render always finished before SIGTERM arrived");
}

#[test]
fn a_larger_budget_continues_an_image_rendered_with_sums() {
    let d = tmpdir("farm", "more");
    sequence(&d, &[1]);
    let input = d.join("ex.0001.vdb");
    let (out, reference) = (d.join("o.exr"), d.join("ref.exr"));
    let render = |o: &Path, spp: &str, sums: bool| {
        let mut a = vec!["render", s(&input), "-o", s(o), "--spp", spp, "-q"];
        a.extend(SMALL);
        if sums {
            a.push("--sums");
        }
        plume(&a)
    };
    assert!(render(&out, "2", true).status.success());
    let o = render(&out, "7", true);
    assert!(o.status.success());
    assert!(stderr(&o).contains("continuing from samples 0..2"), "{}", stderr(&o));
    assert!(render(&reference, "7", false).status.success());
    assert_eq!(bits(&out), bits(&reference));
    // Without sums there is nothing to continue from
    let o = render(&reference, "9", false);
    assert!(stderr(&o).contains("without exact sums"), "{}", stderr(&o));
}

#[test]
fn kill_9_at_any_moment_leaves_only_complete_outputs_and_the_rerun_finishes() {
    let d = tmpdir("farm", "kill");
    sequence(&d, &[1, 2, 3]);
    let input = d.join("ex.####.vdb");
    let out = d.join("o.####.exr");
    let reference = d.join("ref.####.exr");
    let args = |o: &Path| -> Vec<String> {
        [
            "render",
            s(&input),
            "-o",
            s(o),
            "--frames",
            "1-3",
            "--spp",
            "160",
            "--width",
            "48",
            "--height",
            "32",
            "--albedo",
            "0.5",
            "--max-depth",
            "3",
            "--proxy-resolution",
            "16",
            "-q",
        ]
        .iter()
        .map(|x| x.to_string())
        .collect()
    };
    let run = |a: &[String]| plume(&a.iter().map(String::as_str).collect::<Vec<_>>());
    let t = Instant::now();
    let o = run(&args(&reference));
    assert!(o.status.success(), "{}", stderr(&o));
    let full = t.elapsed();
    let outs: Vec<PathBuf> = (1..=3).map(|f| d.join(format!("o.{f:04}.exr"))).collect();
    for fraction in [0.1, 0.3, 0.5, 0.7, 0.9] {
        let a = args(&out);
        let mut child = spawn(&a.iter().map(String::as_str).collect::<Vec<_>>());
        std::thread::sleep(full.mul_f64(fraction));
        let _ = child.kill(); // SIGKILL
        let _ = child.wait();
        for o in &outs {
            if o.exists() {
                let (info, _) = read_part(o).unwrap_or_else(|e| panic!("{}: {e}", o.display()));
                assert_eq!(info.status, Completion::Complete, "SIGKILL writes nothing partial");
            }
        }
    }
    let o = run(&args(&out));
    assert!(o.status.success(), "{}", stderr(&o));
    for (f, o) in (1..=3).zip(&outs) {
        assert_eq!(bits(o), bits(&d.join(format!("ref.{f:04}.exr"))), "frame {f}");
    }
    assert!(temporaries(&d).is_empty(), "stale temporaries removed: {:?}", temporaries(&d));
}

#[test]
fn four_tiles_times_two_sample_ranges_merge_bit_identical_to_one_render() {
    let d = tmpdir("farm", "merge");
    sequence(&d, &[5]);
    let input = d.join("ex.####.vdb");
    // Scattering paths with FNEE, an image size no tile divides evenly
    let common = [
        "--frames",
        "5",
        "--width",
        "37",
        "--height",
        "23",
        "--albedo",
        "0.6",
        "--max-depth",
        "4",
        "--proxy-resolution",
        "16",
        "--density-scale",
        "2",
        "-q",
    ];
    let single = d.join("single.exr");
    let mut a = vec!["render", s(&input), "-o", s(&single), "--spp", "6"];
    a.extend(common);
    let o = plume(&a);
    assert!(o.status.success(), "{}", stderr(&o));
    let mut parts = Vec::new();
    let mut children = Vec::new();
    for tile in 0..4 {
        for (k, range) in ["0..2", "2..6"].iter().enumerate() {
            let p = d.join(format!("part.t{tile}.s{k}.exr"));
            let tile_arg = format!("{tile}/4");
            let mut a = vec![
                "render",
                s(&input),
                "-o",
                s(&p),
                "--tile",
                &tile_arg,
                "--sample-range",
                range,
                "--threads",
                "1",
            ];
            a.extend(common);
            children.push(Command::new(PLUME).args(&a).output());
            parts.push(p);
        }
    }
    for c in children {
        let o = c.unwrap();
        assert!(o.status.success(), "{}", stderr(&o));
    }
    let merged = d.join("merged.exr");
    let mut m = vec!["merge", "-o", s(&merged), "--sums"];
    m.extend(parts.iter().rev().map(|p| s(p)));
    let o = plume(&m);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(bits(&merged), bits(&single), "8 processes merged = 1 process, bit for bit");
    assert_eq!(meta(&merged, "spp"), "6");
    assert_eq!(meta(&merged, "sampleRange"), "0..6");
    assert_eq!(meta(&merged, "mergedParts"), "8");
    assert_eq!(meta(&merged, "settingsHash"), meta(&single, "settingsHash"));
    // With the default reconstruction, trilinear: this is also the linear + scattering check
    assert!(
        meta(&single, "scene").contains("interpolation = \"linear\""),
        "{}",
        meta(&single, "scene")
    );
    let c = read_exr_contents(&parts[0]).unwrap();
    assert_eq!((c.width, c.height), (37, 23), "display window: the whole image");
    assert!(c.crop.width() < 37, "data window: the tile");

    // Wrong sets are refused, naming the part
    let bad = d.join("bad.exr");
    let refuse = |files: &[&Path], needle: &str| {
        let mut a = vec!["merge", "-o", s(&bad)];
        a.extend(files.iter().map(|p| s(p)));
        let o = plume(&a);
        assert_eq!(o.status.code(), Some(3), "{}", stderr(&o));
        assert!(stderr(&o).contains(needle), "{needle}: {}", stderr(&o));
    };
    let all: Vec<&Path> = parts.iter().map(PathBuf::as_path).collect();
    refuse(&all[1..], "have samples");
    refuse(&all[2..], "no part covers pixels");
    let mut dup = all.clone();
    dup.push(all[0]);
    refuse(&dup, "overlap");
    refuse(&[all[0], all[1], &single], "no exact sums");
    let other = d.join("other.exr");
    let mut a = vec![
        "render",
        s(&input),
        "-o",
        s(&other),
        "--tile",
        "0/4",
        "--sample-range",
        "0..2",
        "--seed",
        "9",
    ];
    a.extend(common);
    assert!(plume(&a).status.success());
    let mut mixed = all.clone();
    mixed[0] = &other;
    refuse(&mixed, "seed");
    assert!(!d.join("bad.exr").exists());
}

#[test]
fn progress_lines_for_openjd_and_json() {
    let d = tmpdir("farm", "progress");
    sequence(&d, &[1, 2]);
    let input = d.join("ex.####.vdb");
    let out = d.join("o.####.exr");
    let args = |mode: &'static str| {
        let mut a = vec![
            "render".to_string(),
            s(&input).into(),
            "-o".into(),
            s(&out).into(),
            "--frames".into(),
            "1-2".into(),
            "--spp".into(),
            "2".into(),
            "-q".into(),
            "--overwrite".into(),
            "--progress".into(),
            mode.into(),
        ];
        a.extend(SMALL.iter().map(|x| x.to_string()));
        a
    };
    let o = Command::new(PLUME).args(args("openjd")).output().unwrap();
    assert!(o.status.success());
    let text = String::from_utf8(o.stdout).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert!(
        lines
            .iter()
            .all(|l| l.starts_with("openjd_progress: ") || l.starts_with("openjd_status: ")),
        "{text}"
    );
    let progress: Vec<f64> = lines
        .iter()
        .filter_map(|l| l.strip_prefix("openjd_progress: "))
        .map(|v| v.parse().unwrap())
        .collect();
    assert!(progress.windows(2).all(|w| w[0] <= w[1]), "{progress:?}");
    assert_eq!(progress.last(), Some(&100.0));
    assert!(text.contains("openjd_status: frame 2 (2/2)"), "{text}");

    let o = Command::new(PLUME).args(args("json")).output().unwrap();
    assert!(o.status.success());
    let events: Vec<serde_json::Value> = String::from_utf8(o.stdout)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    let names: Vec<&str> = events.iter().map(|e| e["event"].as_str().unwrap()).collect();
    assert_eq!(names.first(), Some(&"frame_start"));
    assert_eq!(names.iter().filter(|n| **n == "frame_done").count(), 2);
    assert_eq!(events.last().unwrap()["event"], "done");
    assert_eq!(events.last().unwrap()["exit_code"], 0);
    let done = events.iter().find(|e| e["event"] == "frame_done").unwrap();
    assert_eq!(done["stats"]["frame"], 1);

    // A failing run says so in the protocol
    let mut bad =
        vec!["render", s(&input), "-o", s(&out), "--frames", "7", "-q", "--progress", "openjd"];
    bad.extend(SMALL);
    let o = plume(&bad);
    assert_eq!(o.status.code(), Some(3));
    assert!(String::from_utf8(o.stdout).unwrap().contains("openjd_fail: exit code 3"));
}

/// `openjd-cli` in a venv under `target/`, installed as a user would (`scripts/test.sh`
/// installs it first, so CI runs this test). `None` only if installation is impossible.
fn openjd_cli() -> Option<PathBuf> {
    let venv = Path::new(env!("CARGO_TARGET_TMPDIR")).parent().unwrap().join("openjd-venv");
    let bin = venv.join("bin").join("openjd");
    if !bin.exists() {
        let ok = Command::new("python3")
            .args(["-m", "venv", s(&venv)])
            .status()
            .is_ok_and(|st| st.success())
            && Command::new(venv.join("bin").join("python"))
                .args(["-m", "pip", "install", "--quiet", "openjd-cli"])
                .status()
                .is_ok_and(|st| st.success());
        if !ok || !bin.exists() {
            eprintln!("\n!!!!!!!!!! SKIPPED openjd_template: cannot install openjd-cli into {} (python3 -m venv + pip install openjd-cli failed; offline?) !!!!!!!!!!\n", venv.display());
            return None;
        }
    }
    Some(bin)
}

#[test]
fn openjd_template_validates_and_renders_a_sequence_with_openjd_run() {
    let Some(openjd) = openjd_cli() else { return };
    let template = Path::new(env!("CARGO_MANIFEST_DIR")).join("farm/openjd/plume-render.yaml");
    let o = Command::new(&openjd).args(["check", s(&template)]).output().unwrap();
    assert!(
        o.status.success(),
        "openjd check: {}{}",
        String::from_utf8_lossy(&o.stdout),
        stderr(&o)
    );
    let d = tmpdir("farm", "openjd");
    sequence(&d, &[1, 2, 3]);
    let stats = d.join("stats.jsonl");
    let params = [
        format!("PlumeExecutable={PLUME}"),
        format!("InputPattern={}", d.join("ex.####.vdb").display()),
        format!("OutputPattern={}", d.join("render/beauty.####.exr").display()),
        format!("StatsFile={}", stats.display()),
        "Frames=1-3".into(),
        "ChunkSize=2".into(),
        "Spp=3".into(),
        "Width=24".into(),
        "Height=16".into(),
        "Threads=1".into(),
        "ExtraArgs=--density-scale 3".into(),
    ];
    let mut cmd = Command::new(&openjd);
    cmd.args(["run", s(&template)]);
    for p in &params {
        cmd.args(["-p", p]);
    }
    let o = cmd.output().unwrap();
    let log = format!("{}{}", String::from_utf8_lossy(&o.stdout), stderr(&o));
    assert!(o.status.success(), "openjd run: {log}");
    for f in 1..=3 {
        let out = d.join(format!("render/beauty.{f:04}.exr"));
        let (info, contents) = read_part(&out).unwrap_or_else(|e| panic!("{e}\n{log}"));
        assert_eq!((info.status, info.samples.end, info.seed), (Completion::Complete, 3, f as u64));
        assert!(contents.pixels.iter().any(|p| p[0] > 0.0), "frame {f} emits");
    }
    let lines = stats_lines(&stats);
    let mut frames: Vec<i64> = lines.iter().map(|l| l["frame"].as_i64().unwrap()).collect();
    frames.sort_unstable();
    assert_eq!(frames, [1, 2, 3], "one stats line per frame");
    assert!(lines.iter().all(|l| l["core_hours"].as_f64().unwrap() >= 0.0 && l["spp"] == 3));
}
