//! The sections that run other benchmarks (the core figures, interpolation, numerical
//! extremes, the README demo) and the ones that give commands only (out of core, the
//! Cycles comparison).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use super::suite::Suite;
use crate::bench::demo::DemoReport;
use plume_core::error::{Error, Result};

/// The README demo's scene file, relative to the working directory.
const DEMO_SCENE: &str = "data/explosion.toml";

/// `plume bench core` at the budgets' resolution, timed on the openvdb.org smoke.
pub(super) fn core_section(suite: &mut Suite<'_>) -> Result<()> {
    (suite.log)("== core");
    let res = suite.args.budgets.core_resolution;
    let ttfs = suite.args.data.join("smoke/openvdb_org_smoke1.vdb");
    let title = "## Core renderer";
    if !ttfs.exists() {
        let _ = writeln!(suite.md, "{title}\n\nNot measured: {} was not found.\n", ttfs.display());
        suite.skipped.push("the core figures (data file missing)".into());
        return Ok(());
    }
    let report = crate::bench::core::run(res, 0, &ttfs)?;
    let json = suite.bench_dir().join("core.json");
    crate::bench::write_json(&Some(json.clone()), &report)?;
    let _ = writeln!(
        suite.md,
        "{title}\n\nThe renderer's own speed on the generated explosion ({res}³, blackbody, emission only): hierarchical DDA voxel steps per second on one core, for camera rays in tile order and for random chords (every brick a cold miss); the speed-up of a whole render on all cores against one; the time from opening a real file to the first sample; and the brick volume's memory against the raw f32 voxels it holds.\n\n{report}\n```sh\nplume bench core --resolution {res} --ttfs-file {} --json {}\n```\n",
        ttfs.display(),
        json.display()
    );
    Ok(())
}

/// Trilinear against nearest ([`crate::bench::interpolation`]), its picture in `DIR/img`, its
/// JSON in `DIR/bench`; skipped when a data file is missing.
pub(super) fn interpolation_section(suite: &mut Suite<'_>) -> Result<()> {
    (suite.log)("== interpolation");
    let out = &suite.args.out;
    let picture = out.join("img").join("interpolation-closeup.png");
    let mut cfg = crate::bench::interpolation::InterpolationConfig::standard(
        suite.args.data.clone(),
        Some(picture),
    );
    cfg.cpu_seconds = suite.seconds(cfg.cpu_seconds);
    let title = "## Interpolation: trilinear vs nearest";
    let missing = cfg.missing_files();
    if !missing.is_empty() {
        let names: Vec<String> = missing.iter().map(|p| p.display().to_string()).collect();
        let _ = writeln!(suite.md, "{title}\n\nNot measured: {} not found.\n", names.join(", "));
        suite.skipped.push("the interpolation section (data files missing)".into());
        return Ok(());
    }
    let report = crate::bench::interpolation::run(&cfg, suite.log)?;
    let json = out.join("bench").join("interpolation.json");
    crate::bench::write_json(&Some(json.clone()), &report)?;
    let command = format!("{} --json {}", cfg.command(), json.display());
    let _ = writeln!(
        suite.md,
        "{title}\n\n`--interpolation linear` (the default) against `nearest` on the real files: what trilinear reconstruction costs per sample, what memory it adds, how its emission rule differs from interpolating the temperature first, and what it looks like (METHOD.md §12; README, \"Interpolation\").\n\n{}Data: [`bench/interpolation.json`](bench/interpolation.json).\n",
        report.markdown(&command, Some("img/interpolation-closeup.png"))
    );
    Ok(())
}

/// The numerical-extremes sweep, its JSON in `DIR/bench`.
pub(super) fn extremes_section(suite: &mut Suite<'_>) -> Result<()> {
    (suite.log)("== extremes");
    let cfg = crate::bench::extremes::ExtremesConfig {
        box_voxels: 32,
        explosion_resolution: 64,
        size: 48,
        spp: 16,
    };
    let ex = crate::bench::extremes::run(&cfg)?;
    let json = suite.bench_dir().join("extremes.json");
    crate::bench::write_json(&Some(json.clone()), &ex)?;
    let _ = writeln!(
        suite.md,
        "## Numerical extremes\n\n{EXTREMES_INTRO}\n\n{}\n{EXTREMES_COST}\n\n{}\n```sh\nplume bench extremes --box-voxels {} --explosion-resolution {} --size {} --spp {} --json {}\n```\n\nA smaller version runs in `cargo test` (`tests/bench.rs`).\n",
        ex.table(),
        crate::bench::extremes::cost_table(&ex.cost),
        cfg.box_voxels,
        cfg.explosion_resolution,
        cfg.size,
        cfg.spp,
        json.display()
    );
    Ok(())
}

pub(super) const EXTREMES_INTRO: &str = "Boxes of constant density and emission seen head-on, where `L = L_e (1 − e^{−μd})/μ` (METHOD.md §11.1), and the generated explosion at voxel sizes from 1e-4 to 1e4.\n\n\
- *density*: σ_t from 1e-6 to 1e6 per metre in a 1 m box (optical depth 1e-6 … 1e6), emission 1 per metre; with scattering (albedo 0.5, line-fnee) the mean must lie between the emission-only value and `L_e/μ_a`.\n\
- *temperature*: blackbody box via `--temperature-map linear:0,T` up to 1e7 K (solar-flare plasma), against the f64 Planck × CIE integral; 300 K is below the 500 K cutoff and must be black.\n\
- *voxel size*: the explosion with voxel edge `h` = 1e-4 … 1e4 (its `world_from_index` scaled), **σ_t and the emission scale both multiplied by h₀/h** so optical depth and radiance do not change: images must match the generator's own voxel size `h₀` to float rounding, 1e-5 (ray-march: largest pixel difference; point/line: image mean, since a near-tie can flip one collision).\n\
- *invalid voxels*: NaN, ±inf and negative density and emission voxels must be clamped to 0 by the volume builder and counted exactly, and the image must be bit-identical to the box with zeros there. Through `plume render`, negative voxels in a file are clamped with a warning that gives the exact count (checked through the binary in `tests/bench.rs`); NaN and ±inf in a *file* are refused earlier, by the VDB reader, as a corrupt file (exit 3, naming the file and the count), so they never reach the clamp.\n\
- *cost*: the explosion with scattering (albedo 0.8) at density scales 1e-6 … 1e6, each method with its default tracking: the work of a walk, voxel steps plus null collisions' tentative points, may grow at most 2× (the table below).\n\
Stochastic tolerances are 5 standard errors (the larger of the pixel spread and METHOD.md §4's variance for a homogeneous segment); ray-march 1e-4 relative (2e-3 for blackbody: the table's accuracy).";

pub(super) const EXTREMES_COST: &str = "**Cost against density.** One thread, the explosion of the voxel-size sweep, albedo 0.8. A *walk* is a ray tracked (a camera or scattered segment, or a shadow ray); its *work* is voxel steps plus tentative points, each one read of the field, from the renderer's counters (`walks`, `voxel_steps`, `tentative_points` in `--stats`). A sample costs (walks per sample) × (cost per walk): the first factor is the light transport's (a thin medium lets a camera ray through; a dense one scatters every path until roulette ends it, a few walks per vertex), the second is the tracking's, and it is the one that must not grow with density. *Growth* is the largest rise from any density to a denser one. Null tracking on every segment (`--tracking null`) is shown as a figure: its thinnest walks cost a few majorant stretches, a fifth of a regular walk, so its rise is measured from a floor no other tracking has.";

/// Seeds of the README demo's timed renders.
const DEMO_SEEDS: [u64; 3] = [0, 2, 3];
/// Seeds of the README demo's references.
const DEMO_REFERENCE_SEEDS: [u64; 2] = [11, 12];
/// Samples per pixel of each README demo reference.
const DEMO_REFERENCE_SPP: u32 = 512;

pub(super) const DEMO_INTRO: &str = "The README's first picture: `scripts/demo.sh` renders the sample scene file `data/explosion.toml` (the generated explosion 128³, 640×480, 32 spp, scattering, denoised). `plume bench demo` renders that file as a user would, one `plume render` process per seed, and measures the wall time of the whole process and the image's relRMSE over the smoke against two 512-spp references with other seeds (their own noise subtracted), and the largest speck: a covered pixel's luminance against the median of its 5×5 neighbourhood. Targets: under a minute, relRMSE ≤ 0.03.";

/// The title of the README demo's section.
const DEMO_TITLE: &str = "## README demo";

/// Seeds as a command takes them: comma-separated.
fn seed_list(s: &[u64]) -> String {
    s.iter().map(ToString::to_string).collect::<Vec<_>>().join(",")
}

/// `plume bench demo` on the README's scene file (full form only).
pub(super) fn demo_section(suite: &mut Suite<'_>) -> Result<()> {
    let work = suite.args.work_dir.join("demo");
    let json = suite.bench_dir().join("demo.json");
    let command = format!(
        "plume bench demo --scene {DEMO_SCENE} --seeds {} --reference-spp {DEMO_REFERENCE_SPP} --reference-seeds {} --work-dir {} --json {}",
        seed_list(&DEMO_SEEDS),
        seed_list(&DEMO_REFERENCE_SEEDS),
        work.display(),
        json.display()
    );
    let scene = suite.args.working_dir.join(DEMO_SCENE);
    let Some(exe) = demo_exe(suite, &scene, &command) else { return Ok(()) };
    (suite.log)("== README demo");
    make_demo_volume(&scene, &suite.args.work_dir)?;
    let config = crate::bench::demo::DemoConfig {
        exe,
        scene,
        seeds: DEMO_SEEDS.to_vec(),
        reference_spp: DEMO_REFERENCE_SPP,
        reference_seeds: DEMO_REFERENCE_SEEDS.to_vec(),
        references: Vec::new(),
        work_dir: work,
        working_dir: suite.args.working_dir.clone(),
        target_seconds: 60.0,
        target_rel_rmse: 0.03,
    };
    let report = crate::bench::demo::run(&config)?;
    crate::bench::write_json(&Some(json.clone()), &report)?;
    demo_text(&mut suite.md, &report, &command);
    Ok(())
}

/// The binary that renders the demo, when this form runs it and its scene file is there;
/// otherwise `None`, with the section saying why and how to measure it (`command`).
fn demo_exe(suite: &mut Suite<'_>, scene: &Path, command: &str) -> Option<PathBuf> {
    let not_run = |why: &str| {
        format!("{DEMO_TITLE}\n\n{DEMO_INTRO}\n\n{why} Measure it with (after `scripts/demo.sh`, which makes its volume):\n\n```sh\n{command}\n```\n")
    };
    let exe = match (&suite.args.exe, suite.args.budgets.demo) {
        (_, false) => {
            let _ = writeln!(
                suite.md,
                "{}",
                not_run("The quick form does not run this section: its two references are 512-spp renders of the demo's 640×480, each 16 times the demo's own 32 spp (they are then kept in the work directory). The full form runs it.")
            );
            suite.skipped.push("the README demo".into());
            return None;
        }
        (None, true) => {
            let _ = writeln!(
                suite.md,
                "{}",
                not_run("Not measured: no `plume` binary was given to render it.")
            );
            suite.skipped.push("the README demo (no binary to render it)".into());
            return None;
        }
        (Some(exe), true) => exe.clone(),
    };
    if !scene.exists() {
        let _ = writeln!(
            suite.md,
            "{}",
            not_run(&format!(
                "Not measured: {} was not found (run the report from the repository root).",
                scene.display()
            ))
        );
        suite.skipped.push("the README demo (scene file missing)".into());
        return None;
    }
    Some(exe)
}

/// The demo's volume, made as scripts/demo.sh makes it when it is missing.
fn make_demo_volume(scene: &Path, work_dir: &Path) -> Result<()> {
    let (shot, _) = plume_scene::file::SceneFile::read(scene)?;
    let volume = &shot.scene.volume.file;
    if !volume.exists() {
        let generated = crate::bench::spec::scene_file("explosion:128:1", work_dir)?;
        if let Some(dir) = volume.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir)
                .map_err(|source| Error::Write { path: dir.to_path_buf(), source })?;
        }
        std::fs::copy(&generated, volume)
            .map_err(|source| Error::Write { path: volume.clone(), source })?;
    }
    Ok(())
}

/// The demo's section: its references, one row per seed, the command and the targets.
fn demo_text(md: &mut String, report: &DemoReport, command: &str) {
    let _ = writeln!(
        md,
        "{DEMO_TITLE}\n\n{DEMO_INTRO}\n\nReferences: {} × {} spp (seeds {}), their noise {:.4} of the mean, subtracted.\n\n| seed | wall s | CPU s | relRMSE | mean ÷ reference | largest speck (pixel) |\n|---|---|---|---|---|---|",
        report.reference_seeds.len(),
        report.reference_spp,
        seed_list(&report.reference_seeds),
        report.runs.first().map_or(0.0, |r| r.error.reference_noise)
    );
    for r in &report.runs {
        let e = &r.error;
        let _ = writeln!(
            md,
            "| {} | {:.1} | {:.1} | {:.4} | {:.4} | {:.1}× ({}, {}) |",
            r.seed,
            r.wall_seconds,
            r.cpu_seconds,
            e.rel_rmse,
            e.mean_ratio,
            e.speck.ratio,
            e.speck.x,
            e.speck.y
        );
    }
    let yes = |b: bool| if b { "yes" } else { "no" };
    let _ = writeln!(
        md,
        "\n```sh\n{command}\n```\n\nUnder {} s on every seed: {}; relRMSE ≤ {} on every seed: {}. Data: [`bench/demo.json`](bench/demo.json).\n",
        report.target_seconds,
        yes(report.runs.iter().all(|r| r.wall_seconds < report.target_seconds)),
        report.target_rel_rmse,
        yes(report.runs.iter().all(|r| r.error.rel_rmse <= report.target_rel_rmse))
    );
}

/// The out-of-core benchmarks, which neither form runs: commands only.
pub(super) const OUT_OF_CORE: &str = "## Out of core with scattering: the solar flare

The paper's solar-flare experiment: a generated 4096³ flare (a 33 GB brick cache, larger than the memory of a small machine) rendered from the mapped cache with scattering (albedo 0.5), line-fnee against classic NEE with its brick table (`--nee-table brick`; the voxel table would need about 90 GiB) at equal spp, against a longer line-fnee reference in two halves: RMSE, core-hours, picture. And the out-of-core harness: conversion throughput of `plume prepare`, time to first sample and peak anonymous memory under `--memory-budget 4GiB`, and render throughput against in-core renders of flares that fit in memory.

Neither form of the report runs these: the flare needs about 40 GB of free disk and a long run (its cache is made once; its reference alone takes 1200 CPU seconds), and the harness drops the page cache between runs, which needs root. Measure them with:

```sh
plume bench flare --resolution 4096 --spp 16 --reference-time 1200 --width 160 --height 120 --work-dir /tmp/ooc --out /tmp/ooc/flare
scripts/bench-out-of-core.sh /tmp/ooc
```

`plume bench flare` prints its table and writes `flare.csv`, `flare.json`, the plots and the reference under `--out`; `scripts/bench-out-of-core.sh` prints a Markdown table. Renders in a memory limit smaller than the data (a memory cgroup around `plume render` of a cache, page cache dropped first; `docs/out-of-core.md` says how plume reads the limit) are not scripted.

";

/// The peer comparison with Blender Cycles, which neither form runs.
pub(super) const CYCLES: &str = "## Peer comparison: Cycles 5.0.1

plume against Blender Cycles 5.0.1 on the shared Blender explosions with matched conventions (`docs/cycles.md`): each renderer's relRMSE against its own converged reference at several equal CPU budgets; and, with `--lights`, a sun, an environment map and a sphere light lighting the explosion's density, and with `--shots`, a coloured medium and depth of field, plume's image mean against Cycles'. Neither form of the report runs it: it installs Blender's `bpy` 5.0.1 from PyPI into a virtual environment and takes hours for the full set on 2 cores (the references dominate).

```sh
scripts/compare-cycles.sh            # the full table (target/compare-cycles/table.md)
scripts/compare-cycles.sh --quick    # one file, two settings, short references
scripts/compare-cycles.sh --lights   # external lights
scripts/compare-cycles.sh --adaptive # adaptive sampling at matched noise thresholds (docs/adaptive.md)
scripts/compare-cycles.sh --shots    # a coloured medium and depth of field (docs/cycles.md)
```

";
