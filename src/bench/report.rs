//! `plume bench report`: the benchmark suite that writes `docs/BENCHMARKS.md`, all of it.
//!
//! The document holds today's figures only: a header that names the machine once and says
//! how to regenerate the file, then one section per benchmark (what it measures, its
//! tables, and under them the command that reproduces them), and at the end one short
//! table of ideas tried and not kept ([`IDEAS`]). No commit hashes, dates or issue numbers:
//! git keeps the history ([`history`] finds them; the tests run it on the document).
//! Plots go to `DIR/img`, CSV and JSON to `DIR/bench`, the scene files that the commands
//! read to `DIR/bench/scenes`.
//!
//! Sections, in order:
//! 1. the headline ratio line-fnee ÷ point-nee, from 3 and 4;
//! 2. the core renderer's figures ([`crate::bench::core`]);
//! 3. the generated explosion, thin (σ_t = 1) and dense (σ_t = 20), the paper's two
//!    regimes, scattering (albedo 0.8, g 0.3), six methods at equal CPU time and spp;
//! 4. the FNEE proxy-resolution sweep (8³ … full) on the dense explosion;
//! 5. the openvdb.org smoke and the Disney cloud (1/16), each lit by its own density;
//! 6. renderer options at equal CPU time, each against the default on one scene
//!    ([`GROUPS`]): tracking, splitting, splitting by brightness, forced camera
//!    collisions, stochastic point lookups, and motion blur against the still image;
//! 7. trilinear against nearest reconstruction ([`crate::bench::interpolation`]);
//! 8. the numerical-extremes sweep ([`crate::bench::extremes`]);
//! 9. the README demo ([`crate::bench::demo`]; full form only: its two 512-spp references);
//! 10. out of core and the Cycles comparison: commands only (they need root, a memory
//!     cgroup, Blender, or hours and 40 GB of disk), run by neither form;
//! 11. ideas tried and not kept.
//!
//! Two forms ([`Budgets`]): the full one and the quick one (`--quick`: a quarter of the CPU
//! budgets, a 128³ explosion, no README demo), which fits in 20 minutes on 2 cores. Budgets
//! are CPU seconds (see [`crate::bench::progressive`]), so other work on a shared machine slows a
//! run down more than it moves the figures.
//!
//! Files: the forms and options in `budgets`; the report being written and one comparison
//! of methods as a section in `suite`; the explosion, proxy, smoke and cloud comparisons in
//! `comparisons`; the option groups in `groups` (what they measure) and `group_section`
//! (running one); the sections that run other benchmarks or give commands in `sections`;
//! the document's header, ideas table and history checks in `document`. This file runs
//! them in order.

use std::time::Instant;

use plume_core::error::{Error, Result};

mod adaptive;
mod budgets;
mod comparisons;
mod document;
mod group_section;
mod groups;
mod sections;
mod suite;

use adaptive::adaptive_section;
use comparisons::{explosion_sections, real_file_sections};
use document::{header, ideas_section};
use group_section::group_section;
use groups::GROUPS;
use sections::{
    core_section, demo_section, extremes_section, interpolation_section, CYCLES, OUT_OF_CORE,
};
use suite::Suite;

pub use budgets::{Budgets, ReportOptions, QUICK_TIME_SCALE};
pub use document::{check_document, history, IDEAS};

impl ReportOptions {
    /// Run the suite and write the report.
    ///
    /// # Errors
    /// See [`run`].
    pub fn run(&self) -> Result<()> {
        run(self)
    }
}

/// Run the suite and write `BENCHMARKS.md`, plots and data under `args.out`.
///
/// # Errors
/// A time scale that is not a positive number, unwritable outputs, scenes that cannot be
/// built. Missing data files skip their sections, and failed extremes checks are shown in
/// the document, not errors.
pub fn run(args: &ReportOptions) -> Result<()> {
    let b = args.budgets;
    if !(b.time_scale.is_finite() && b.time_scale > 0.0) {
        return Err(Error::invalid(
            "--time-scale",
            format!("{} must be a positive number", b.time_scale),
        ));
    }
    if !(8..=4096).contains(&b.resolution) {
        return Err(Error::invalid("--resolution", format!("{} must be 8 to 4096", b.resolution)));
    }
    for dir in [args.out.join("bench").join("scenes"), args.out.join("img")] {
        std::fs::create_dir_all(&dir)
            .map_err(|source| Error::Write { path: dir.clone(), source })?;
    }
    let start = Instant::now();
    let log = |l: &str| log::info!("{l}");
    let mut suite = Suite {
        args,
        md: String::new(),
        skipped: Vec::new(),
        references: Vec::new(),
        measured: Vec::new(),
        log: &log,
    };
    core_section(&mut suite)?;
    let headline = explosion_sections(&mut suite)?;
    real_file_sections(&mut suite)?;
    adaptive_section(&mut suite)?;
    for group in &GROUPS {
        group_section(&mut suite, group)?;
    }
    interpolation_section(&mut suite)?;
    extremes_section(&mut suite)?;
    demo_section(&mut suite)?;
    suite.md.push_str(OUT_OF_CORE);
    suite.md.push_str(CYCLES);
    suite.md.push_str(&ideas_section());
    let document = format!(
        "{}{}{}",
        header(args, &suite.skipped, start.elapsed().as_secs_f64()),
        headline,
        suite.md
    );
    let path = args.out.join("BENCHMARKS.md");
    plume_core::fs::write_atomic(&path, |w| std::io::Write::write_all(w, document.as_bytes()))?;
    for problem in history(&document) {
        log::warn!("{}: {problem}", path.display());
    }
    log::info!("wrote {}", path.display());
    Ok(())
}
