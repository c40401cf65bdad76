//! The document's frame: its header (the machine, named once, and how to regenerate it),
//! the short table of ideas tried and not kept, and the checks that keep history out of
//! it ([`history`], [`check_document`]).

use std::fmt::Write as _;

use super::budgets::{Budgets, ReportOptions};
use crate::bench::numbers::arg;

/// Ideas measured and not kept: the idea, its measured effect, why it was not kept. The
/// figures are those measured when each was tried.
pub const IDEAS: [(&str, &str, &str); 10] = [
    (
        "Out of core: fill windows of deferred paths read with direct I/O (`O_DIRECT` into fresh memory, moved over the mapping)",
        "2048³ flare in a 1.5 GiB memory cgroup, `--split 1`: 93.5 s against 77.9 s through the mapping",
        "in a full cgroup a window came in at about 0.5 GB/s, no faster than the kernel's read-ahead, and the workers still faulted on neighbouring blocks",
    ),
    (
        "Out of core: each fill bucket's block ranges populated in one call (`MADV_POPULATE_READ`)",
        "the same render: 127.6 s and 1.81 M major faults, against 79.6 s and 0.55 M",
        "under `MADV_RANDOM` it faults every page of the range one at a time, the pages no lookup reads included",
    ),
    (
        "Out of core: smaller deferred lookups (89 bytes counted per lookup instead of 152, simulated with a larger cgroup)",
        "67.2 s and 8 rounds against 81.0 s and 11 rounds (0.32× against 0.27× the cached throughput)",
        "a keyed request and its answer take 40 bytes each, so 89 bytes is out of reach; about 128 would give 1.19× the lookups per round, a few seconds",
    ),
    (
        "Independent hashed random numbers instead of Owen-scrambled Sobol points (the scene key `render.sampler = \"random\"`)",
        "128², line-fnee, equal CPU (3 and 12 s), Sobol's error ÷ random's: kelvin40 albedo 0.8 0.53 / 0.52, blender40 albedo 0.8 0.62 / 0.60, kelvin40 emission only 0.14 / 0.055",
        "never better; the flag was removed, the key kept to reproduce this row",
    ),
    (
        "Cycles' blackbody evaluated directly, without the per-thread emission memo",
        "kelvin40 ray-march, linear: 1.38–1.43 s against 1.09 s with the memo",
        "slower",
    ),
    (
        "Splitting by brightness with the mean weighted by opacity (fewer paths)",
        "README demo at 32 spp: denoised relRMSE 0.0288 / 0.0308 / 0.0297 against 0.0278 / 0.0288 / 0.0283; efficiency 1.04× against 1.09× of uniform",
        "the plain brightness rule is more efficient and meets the demo's 0.03",
    ),
    (
        "Picked (one-voxel) emission points after scattering as the default (now `--point-lookup stochastic-emission`)",
        "README demo: −18 % instructions at the same RMS error; one seed showed a pixel 55× its neighbours",
        "a heavier tail of single samples: a visible speck in the first picture",
    ),
    (
        "Camera-ray collision splitting: K stratified free paths from one walk, each a path of weight 1/K",
        "kelvin40, albedo 0.8: efficiency 27.8 → 22.1 / 21.9 / 17.2 for K = 2 / 4 / 8",
        "in thin smoke K free paths still give about one collision per ray; splitting the path after the collision is what pays",
    ),
    (
        "A second denoising pass guided by the first",
        "README demo at 32 spp: 0.0258 / 0.0272 against 0.0277 / 0.0287",
        "its larger strength blurs edges: a unit step's error beside the edge 0.173 against the test's limit of 0.1",
    ),
    (
        "One codegen unit (with fat LTO) for the release build",
        "README demo render −3.9 % instructions; six alternated timed renders showed no gain",
        "no gain the clock could show, for twice the rebuild time",
    ),
];

/// The closing section: [`IDEAS`] as a table.
pub(super) fn ideas_section() -> String {
    let mut s = String::from(
        "## Ideas tried and not kept\n\nEach measured when it was tried, on the machine of its time; git's history has the details.\n\n| idea | measured effect | why not kept |\n|---|---|---|\n",
    );
    for (idea, effect, why) in IDEAS {
        let _ = writeln!(s, "| {idea} | {effect} | {why} |");
    }
    s
}

/// The document's head: what wrote it, how to regenerate it, the form, the machine (once),
/// the metrics and methods.
pub(super) fn header(args: &ReportOptions, skipped: &[String], seconds: f64) -> String {
    let b = &args.budgets;
    let machine = crate::bench::machine();
    let mut md = String::from(
        "# plume benchmarks\n\n`plume bench report` writes this whole file, its plots in `docs/img` and its data and scene files in `docs/bench`. Regenerate it from the repository root, with the shared data in `../shared/data` (`plume` in the commands below is `target/release/plume`):\n\n\
         ```sh\ncargo build --release\ntarget/release/plume bench report           # the full form\ntarget/release/plume bench report --quick   # the quick form: under 20 minutes on 2 cores\n```\n\n",
    );
    let defaults = Budgets::form(b.quick);
    let mut form = if b.quick {
        format!(
            "**This is the quick form**: CPU-time budgets × {} of the full form's and the generated explosion at {}³ (the full form: 256³), so every figure is noisier than the full form's",
            arg(b.time_scale),
            b.resolution
        )
    } else {
        format!(
            "This is the full form: CPU-time budgets × {}, the generated explosion at {}³",
            arg(b.time_scale),
            b.resolution
        )
    };
    if b.time_scale != defaults.time_scale || b.resolution != defaults.resolution {
        form.push_str(" (budgets set on the command line)");
    }
    form.push('.');
    if !skipped.is_empty() {
        let _ = write!(form, " Not run: {}.", skipped.join("; "));
    }
    let _ = writeln!(
        md,
        "{form} Neither form runs the out-of-core flare and memory-limit renders or the Cycles comparison; their sections give the commands.\n"
    );
    let memory = if machine.memory_bytes > 0 {
        format!(", {:.1} GiB memory", machine.memory_bytes as f64 / f64::from(1u32 << 30))
    } else {
        String::new()
    };
    let _ = writeln!(
        md,
        "**Machine:** {}, {} logical CPUs{memory}. Budgets are **CPU seconds** (user + system of all threads): other work on the machine slows a run down more than it changes the figures, though it competes for caches and memory bandwidth. This run took {} of wall time.\n",
        machine.model,
        machine.cpus,
        duration(seconds)
    );
    let _ = writeln!(md, "**Metrics.** RMSE over all RGB values; relMSE = per-pixel mean over RGB of (x − ref)²/(ref² + ε), ε = {}, with the top 0.1 % of pixel values trimmed; bias = mean(x) − mean(ref); spread = sample std over seeds. Efficiency = 1/(RMSE² · CPU s) relative to the first method. Core-hours = CPU s / 3600. Peak RSS is per method (the kernel's high-water mark reset before each method) and includes the loaded volume and reference. The computed references' own noise is estimated from two independent halves and stated; it is included in every RMSE.\n", crate::bench::metrics::RELMSE_EPSILON);
    let _ = writeln!(md, "**Methods.** `point-nee`: collision estimator + classic NEE (MIS in volume measure). `line-nee`: line integration + classic NEE (no MIS partner). `line-fnee`: line integration + forward NEE with MIS (the paper's method). `ray-march`: expected-value estimator, forward paths only. `line+none`: line integration, forward paths only. `blend+fnee`: the line/point blend (κ = 4) + FNEE. FNEE proxy 64³ unless stated.\n");
    md
}

/// Wall time in words: `12 min 5 s`, or seconds under a minute.
pub(super) fn duration(seconds: f64) -> String {
    let s = seconds.round() as u64;
    if s < 60 {
        format!("{s} s")
    } else {
        format!("{} min {} s", s / 60, s % 60)
    }
}

/// Where `md` holds history: commit hashes, dates, issue numbers, or words that date a
/// figure ("today", "yesterday", …). One line per finding, with its line number; empty
/// when there is none.
#[must_use]
pub fn history(md: &str) -> Vec<String> {
    const WORDS: [&str; 8] = [
        "today",
        "yesterday",
        "this morning",
        "this afternoon",
        "last week",
        "this session",
        "next session",
        "last session",
    ];
    const MONTHS: [&str; 12] = [
        "January",
        "February",
        "March",
        "April",
        "May",
        "June",
        "July",
        "August",
        "September",
        "October",
        "November",
        "December",
    ];
    let mut found = Vec::new();
    for (n, line) in md.lines().enumerate() {
        let n = n + 1;
        let bytes = line.as_bytes();
        // Commit hashes: 7–40 lowercase hex digits with a letter and a digit, not a number
        // in e notation (1234e56)
        for word in line.split(|c: char| !c.is_ascii_alphanumeric()) {
            let hex = word.bytes().all(|c| c.is_ascii_digit() || (b'a'..=b'f').contains(&c));
            let letters = word.bytes().filter(u8::is_ascii_lowercase).count();
            let digits = word.bytes().filter(u8::is_ascii_digit).count();
            let e_notation = letters == 1
                && word.split_once('e').is_some_and(|(a, b)| !a.is_empty() && !b.is_empty());
            if (7..=40).contains(&word.len()) && hex && letters > 0 && digits > 0 && !e_notation {
                found.push(format!("line {n}: commit hash? `{word}`"));
            }
        }
        // Dates: 2024-05-17, or a month name next to a number
        for i in 0..bytes.len().saturating_sub(9) {
            let d = |k: usize| bytes[i + k].is_ascii_digit();
            if d(0)
                && d(1)
                && d(2)
                && d(3)
                && bytes[i + 4] == b'-'
                && d(5)
                && d(6)
                && bytes[i + 7] == b'-'
                && d(8)
                && d(9)
            {
                found.push(format!("line {n}: date `{}`", &line[i..i + 10]));
            }
        }
        for month in MONTHS {
            for (i, _) in line.match_indices(month) {
                let after = line[i + month.len()..]
                    .trim_start()
                    .chars()
                    .next()
                    .is_some_and(|c| c.is_ascii_digit());
                let before =
                    line[..i].trim_end().chars().last().is_some_and(|c| c.is_ascii_digit());
                if after || before {
                    found.push(format!("line {n}: date with `{month}`"));
                }
            }
        }
        // Issue numbers: #16, issue 16
        for (i, _) in line.match_indices('#') {
            let digits: String = line[i + 1..].chars().take_while(char::is_ascii_digit).collect();
            if !digits.is_empty() {
                found.push(format!("line {n}: issue number `#{digits}`"));
            }
        }
        let lower = line.to_lowercase();
        for (i, _) in lower.match_indices("issue ") {
            if lower[i + 6..].chars().next().is_some_and(|c| c.is_ascii_digit()) {
                found.push(format!("line {n}: issue number"));
            }
        }
        for w in WORDS {
            for (i, _) in lower.match_indices(w) {
                let edge = |c: Option<char>| c.is_none_or(|c| !c.is_alphanumeric());
                if edge(lower[..i].chars().last()) && edge(lower[i + w.len()..].chars().next()) {
                    found.push(format!("line {n}: `{w}`"));
                }
            }
        }
    }
    found
}

/// Whether `md` has the form `plume bench report` writes: no [`history`], the machine
/// named on one line, the regenerating commands, a command block after the last table of
/// every section with tables (except the ideas table), and that table at most 10 rows.
/// One line per problem; empty when there is none.
#[must_use]
pub fn check_document(md: &str) -> Vec<String> {
    let mut problems = history(md);
    let machine_lines = md.lines().filter(|l| l.starts_with("**Machine:**")).count();
    if machine_lines != 1 {
        problems.push(format!("{machine_lines} lines name the machine, not 1"));
    }
    // The regenerating commands, each on a line of its own (a comment may follow)
    let commands: Vec<&str> =
        md.lines().map(|l| l.split('#').next().unwrap_or_default().trim()).collect();
    for c in ["plume bench report", "plume bench report --quick"] {
        if !commands.iter().any(|l| l.ends_with(c)) {
            problems.push(format!("no `{c}` command"));
        }
    }
    for section in md.split("\n## ").skip(1) {
        let title = section.lines().next().unwrap_or_default();
        let lines: Vec<&str> = section.lines().collect();
        let Some(last_table) = lines.iter().rposition(|l| l.starts_with('|')) else { continue };
        if title.starts_with("Ideas tried and not kept") {
            let rows = lines.iter().filter(|l| l.starts_with('|')).count().saturating_sub(2);
            if rows > 10 {
                problems.push(format!("\"{title}\": {rows} rows, more than 10"));
            }
            continue;
        }
        if !lines[last_table..].iter().any(|l| l.starts_with("```sh")) {
            problems.push(format!("\"{title}\": no command under its last table"));
        }
    }
    if !md.contains("\n## Ideas tried and not kept") {
        problems.push("no \"Ideas tried and not kept\" section".into());
    }
    problems
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bench::report::groups::GROUPS;
    use crate::bench::report::sections::{CYCLES, DEMO_INTRO, EXTREMES_INTRO, OUT_OF_CORE};

    #[test]
    fn history_finds_hashes_dates_issues_and_days() {
        for bad in [
            "Measured at `25fc21c` on the 2-core machine.",
            "commit 25fc21cb35d610e69c086c42d716231d4ada1048",
            "rerun on 2026-11-27",
            "measured 27 November, then",
            concat!("for issue", " #16's target"),
            "as issue 17 asks",
            "Rerun today, 3 runs each.",
            "The next session tried it.",
        ] {
            assert!(!history(bad).is_empty(), "{bad:?}");
        }
        for good in [
            "σ_t = 1e-6, 1.000e10, 7.745e10 and 16384 slots, 0x7265",
            "| `explosion/mantaflow_explosion_kelvin_0040.vdb` | cycles | 0.04388 |",
            "## Headline: line-fnee against point-nee",
            "METHOD.md §9; the cache's 1.2 M dense bricks; May the figures agree",
            "openvdb_org_smoke1.vdb, wdas_cloud_sixteenth.vdb, line-fnee@128",
        ] {
            assert_eq!(history(good), Vec::<String>::new(), "{good:?}");
        }
    }

    #[test]
    fn the_written_prose_holds_no_history_and_the_ideas_fit_one_short_table() {
        for text in [OUT_OF_CORE, CYCLES, EXTREMES_INTRO, DEMO_INTRO, &ideas_section()] {
            assert_eq!(history(text), Vec::<String>::new());
        }
        for g in &GROUPS {
            assert_eq!(history(g.intro), Vec::<String>::new(), "{}", g.title);
        }
        assert!(IDEAS.len() <= 10);
        for form in [Budgets::FULL, Budgets::QUICK] {
            let args = ReportOptions {
                out: "docs".into(),
                budgets: form,
                data: "../shared/data".into(),
                work_dir: "/tmp/w".into(),
                working_dir: ".".into(),
                exe: None,
            };
            let head = header(&args, &["the README demo".into()], 600.0);
            assert_eq!(history(&head), Vec::<String>::new());
            assert_eq!(head.contains("quick form**"), form.quick, "{head}");
            let document = format!("{head}{}", ideas_section());
            assert_eq!(check_document(&document), Vec::<String>::new());
        }
    }

    #[test]
    fn a_table_without_its_command_is_found() {
        let args = ReportOptions {
            out: "docs".into(),
            budgets: Budgets::QUICK,
            data: "d".into(),
            work_dir: "w".into(),
            working_dir: ".".into(),
            exe: None,
        };
        let head = header(&args, &[], 60.0);
        let with = format!(
            "{head}## A\n\n| a |\n|---|\n| 1 |\n\n```sh\nplume bench core\n```\n{}",
            ideas_section()
        );
        assert_eq!(check_document(&with), Vec::<String>::new());
        let without = format!("{head}## A\n\n| a |\n|---|\n| 1 |\n\n{}", ideas_section());
        assert_eq!(check_document(&without).len(), 1, "{:?}", check_document(&without));
        assert_eq!(check_document(&format!("{head}{head}{}", ideas_section())).len(), 1);
    }
}
