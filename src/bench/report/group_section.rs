//! One option group ([`super::groups::Group`]) run and written as a section: every
//! variant at equal CPU time against the base scene's reference (or its own), a table,
//! the commands, the JSON.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use super::groups::{Base, Group};
use super::suite::{RefArg, Suite, REFERENCE_SECONDS, RUNS, RUN_SECONDS};
use crate::bench::compare::{compare, make_reference, CompareReport, Reference};
use crate::bench::numbers::{arg, num, pm, pm_count};
use plume_core::error::{Error, Result};

/// One variant's row: its label, its flags and its comparison.
type Row = (&'static str, &'static str, CompareReport);

/// What every variant of one group shares.
struct GroupRun<'a> {
    group: &'a Group,
    /// The base scene's spec.
    spec: String,
    /// The base scene's scene-file keys.
    base_keys: &'static str,
    /// CPU seconds of each reference.
    reference_seconds: f64,
    /// Where the shared reference is saved for the commands that read it.
    saved: PathBuf,
    /// The base scene's reference, when the variants share one.
    shared: Option<Reference>,
}

/// One option group: every variant at equal CPU time against the base scene's reference
/// (or its own); a table, the commands, the JSON.
pub(super) fn group_section(suite: &mut Suite<'_>, group: &Group) -> Result<()> {
    let title = format!("## {}", group.title);
    (suite.log)(&format!("== {}", group.title));
    let (spec, base_keys) = group.base.spec(&suite.args.data);
    if group.base == Base::Kelvin40 && !spec.exists() {
        let _ = writeln!(
            suite.md,
            "{title}\n\n{}\n\nNot measured: {} was not found.\n",
            group.intro,
            spec.display()
        );
        suite.skipped.push(format!("the {} section (data file missing)", group.name));
        return Ok(());
    }
    let mut commands = Vec::new();
    let run = group_run(suite, group, spec.display().to_string(), base_keys, &mut commands)?;
    let wall = Instant::now();
    let mut rows = Vec::new();
    for &variant in group.variants {
        rows.push(run.variant(suite, variant, &mut commands)?);
    }
    let wall = wall.elapsed().as_secs_f64();
    let json = suite.bench_dir().join(format!("{}.json", group.name));
    let value: Vec<serde_json::Value> =
        rows.iter().map(|(label, flags, r)| serde_json::json!({ "variant": label, "flags": flags, "report": r })).collect();
    crate::bench::write_json(&Some(json), &value)?;
    group_text(suite, group, &title, &rows, &commands, wall);
    Ok(())
}

/// What the variants of `group` share; with a shared reference, it is made (or taken
/// from an earlier group) and its command is the first of `commands`.
fn group_run<'a>(
    suite: &mut Suite<'_>,
    group: &'a Group,
    spec: String,
    base_keys: &'static str,
    commands: &mut Vec<String>,
) -> Result<GroupRun<'a>> {
    let reference_seconds =
        suite.seconds(REFERENCE_SECONDS) / if group.shared_reference { 1.0 } else { 2.0 };
    let saved = suite.args.work_dir.join(format!("{}-reference.exr", group.base.name()));
    let shared = if group.shared_reference {
        let (_, file, _) = suite.write_scene(group.base.name(), &spec, &[base_keys])?;
        commands.push(suite.compare_command(
            &file,
            group.method,
            1,
            &RefArg::MakeAndSave(reference_seconds, &saved),
            None,
        ));
        Some(base_reference(suite, group.base, (&spec, base_keys), reference_seconds, &saved)?)
    } else {
        None
    };
    Ok(GroupRun { group, spec, base_keys, reference_seconds, saved, shared })
}

impl GroupRun<'_> {
    /// One variant: its scene file and command (added to `commands`), and its comparison,
    /// taken from an earlier group when it renders the same scene against the same
    /// reference.
    fn variant(
        &self,
        suite: &mut Suite<'_>,
        (label, flags, keys): (&'static str, &'static str, &'static str),
        commands: &mut Vec<String>,
    ) -> Result<Row> {
        let group = self.group;
        let (spec, base_keys) = (self.spec.as_str(), self.base_keys);
        let stem = format!("{}-{}", group.name, label.split(' ').next().unwrap_or(label));
        let (_, file, text) = suite.write_scene(&stem, spec, &[base_keys, keys])?;
        commands.push(match &self.shared {
            Some(_) => {
                suite.compare_command(&file, group.method, 1, &RefArg::Given(&self.saved), None)
            }
            None => suite.compare_command(
                &file,
                group.method,
                1,
                &RefArg::Make(self.reference_seconds),
                None,
            ),
        });
        if let Some((_, r)) =
            suite.measured.iter().find(|(t, _)| *t == text).filter(|_| self.shared.is_some())
        {
            return Ok((label, flags, r.clone()));
        }
        let (mut scene, _) = suite.scene(&stem, spec, &[base_keys, keys])?;
        let own;
        let reference = match &self.shared {
            Some(r) => r,
            None => {
                own = make_reference(&mut scene, self.reference_seconds, suite.log)?;
                &own
            }
        };
        let cfg = suite.config(&scene, group.method, 1)?;
        let report = compare(&mut scene, reference, &cfg, suite.log)?;
        if self.shared.is_some() {
            suite.measured.push((text, report.clone()));
        }
        Ok((label, flags, report))
    }
}

/// The group's section: its scene, the table of variants, the commands.
fn group_text(
    suite: &mut Suite<'_>,
    group: &Group,
    title: &str,
    rows: &[Row],
    commands: &[String],
    wall: f64,
) {
    let run_seconds = suite.seconds(RUN_SECONDS);
    let md = &mut suite.md;
    let _ = writeln!(md, "{title}\n\n{}\n", group.intro);
    let _ = writeln!(
        md,
        "Scene: {}. {} runs (seeds) per variant of {} CPU s each, mean ± std. Reference: {}. Efficiency = 1/(RMSE² · CPU s), relative to the first row.\n",
        group.base.about(),
        RUNS,
        arg(run_seconds),
        if group.shared_reference {
            format!("one, of the scene with the default settings: {}", rows[0].2.reference.description)
        } else {
            "each variant's own, a long line-fnee run".to_string()
        }
    );
    let _ = writeln!(md, "| variant | flags | spp | samples / CPU s | RMSE | relMSE | bias | efficiency |\n|---|---|---|---|---|---|---|---|");
    let base_cost = rows.first().map_or(f64::NAN, |(_, _, r)| cost(r));
    for (label, flags, r) in rows {
        let m = &r.methods[0];
        let e = &m.equal_time;
        let _ = writeln!(
            md,
            "| {label} | {} | {} | {} | {} | {} | {} | {:.2}× |",
            if flags.is_empty() { "–".to_string() } else { format!("`{flags}`") },
            pm_count(&e.spp),
            num(m.samples_per_cpu_second.mean),
            pm(&e.rmse),
            pm(&e.relmse),
            pm(&e.bias),
            base_cost / cost(r)
        );
    }
    let _ = writeln!(
        md,
        "\n```sh\n{}\n```\n\nThe scene files are in `bench/scenes`{}. Data: [`bench/{name}.json`](bench/{name}.json). Section wall time {wall:.0} s.\n",
        commands.join("\n"),
        if group.shared_reference { "; the first command makes and saves the reference the others read" } else { "" },
        name = group.name
    );
}

/// RMSE² × CPU s of a one-method comparison: the inverse of its efficiency.
fn cost(r: &CompareReport) -> f64 {
    let e = &r.methods[0].equal_time;
    e.rmse.mean.powi(2) * e.cpu_seconds.mean
}

/// The reference of a base scene (`spec` with `keys`), computed once per report and saved
/// to `saved`, which the commands read.
fn base_reference(
    suite: &mut Suite<'_>,
    base: Base,
    (spec, keys): (&str, &str),
    seconds: f64,
    saved: &Path,
) -> Result<Reference> {
    if let Some((_, r)) = suite.references.iter().find(|(b, _)| *b == base) {
        return Ok(r.clone());
    }
    (suite.log)(&format!("== reference of {}", base.name()));
    let (mut scene, _) = suite.scene(base.name(), spec, &[keys])?;
    let r = make_reference(&mut scene, seconds, suite.log)?;
    std::fs::create_dir_all(&suite.args.work_dir)
        .map_err(|source| Error::Write { path: suite.args.work_dir.clone(), source })?;
    crate::output::write_exr(
        saved,
        r.width,
        r.height,
        &r.pixels,
        &[("plume:reference".to_string(), r.description.clone())],
    )?;
    suite.references.push((base, r.clone()));
    Ok(r)
}
