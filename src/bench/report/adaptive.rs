//! The adaptive-sampling section: on an explosion with scattering, the smoke and the
//! cloud, the CPU time line-fnee needs to reach a target error, sampling uniformly and
//! adaptively, and each adaptive render against uniform sampling at the same CPU time
//! (docs/adaptive.md explains the estimate and the stopping rule).

use std::fmt::Write as _;

use super::comparisons::{CLOUD, SMOKE};
use super::groups::Base;
use super::suite::{RefArg, Suite, CURVE_POINTS, REFERENCE_SECONDS};
use crate::bench::compare::{compare, make_reference};
use plume_core::error::Result;

/// The method measured.
const METHOD: &str = "line-fnee";

const INTRO: &str = "`--noise-threshold T`: each pixel stops once its estimated relative error is at most `T` (docs/adaptive.md). For one method, the CPU time to reach a relative RMSE (√relMSE against the reference, its own noise included) of 0.05, 0.02 and 0.01, read off the uniform runs' error-against-time curve and off a series of adaptive renders at thresholds 0.1, 0.05, 0.025, … (`min_spp` 16, capped at 4× the uniform runs' spp, ending with the first render that spends the run's budget); and each adaptive render against the uniform curve at the same CPU time, with the render's own estimate of its error over the same pixels beside the measured one. The uniform curve's points fall at any sample count, so at a few spp it pays for incomplete Sobol nets where the adaptive renders stop at powers of two; docs/adaptive.md compares with uniform renders at powers of two. `~` marks a figure extrapolated at t^(−1/2) past a measured curve.";

/// Each run's CPU seconds are this many times the other sections' (× the time scale): the
/// adaptive series starts at `min_spp` 16, which a run must be able to afford.
const RUN_SCALE: f64 = 4.0;

/// Section: CPU time to a target error, uniform and adaptive, on three scenes, each at a
/// quarter of its pixels in the other sections (so that a run reaches tens of spp).
pub(super) fn adaptive_section(suite: &mut Suite<'_>) -> Result<()> {
    (suite.log)("== adaptive");
    let _ = writeln!(suite.md, "## Adaptive sampling: CPU time to a target error\n\n{INTRO}\n");
    let (kelvin, kelvin_keys) = Base::Kelvin40.spec(&suite.args.data);
    let scenes = [
        (
            "adaptive-kelvin40",
            "Blender's explosion, frame 40, albedo 0.8",
            kelvin,
            kelvin_keys,
            "[camera]\nwidth = 64\nheight = 64",
        ),
        (
            "adaptive-smoke",
            "The openvdb.org smoke",
            suite.args.data.join(SMOKE.0),
            SMOKE.1,
            "[camera]\nwidth = 75\nheight = 100",
        ),
        (
            "adaptive-cloud",
            "The Disney cloud, 1/16",
            suite.args.data.join(CLOUD.0),
            CLOUD.1,
            "[camera]\nwidth = 100\nheight = 75",
        ),
    ];
    for (name, title, path, keys, size) in scenes {
        if !path.exists() {
            let _ = writeln!(
                suite.md,
                "### {title}\n\nNot measured: {} was not found.\n",
                path.display()
            );
            suite.skipped.push(format!("the {name} section (data file missing)"));
            continue;
        }
        let (mut scene, scene_file) =
            suite.scene(name, &path.display().to_string(), &[keys, size])?;
        let reference_seconds = suite.seconds(REFERENCE_SECONDS);
        let reference = make_reference(&mut scene, reference_seconds, suite.log)?;
        let mut cfg = suite.config(&scene, METHOD, CURVE_POINTS)?;
        cfg.cpu_seconds *= RUN_SCALE;
        cfg.adaptive = true;
        let report = compare(&mut scene, &reference, &cfg, suite.log)?;
        let command = suite.compare_command_at(
            cfg.cpu_seconds,
            &scene_file,
            METHOD,
            CURVE_POINTS,
            &RefArg::Make(reference_seconds),
            None,
        );
        let _ = writeln!(
            suite.md,
            "### {title}\n\n{}\n\n**CPU time to a target error:**\n\n{}\n**Adaptive renders against uniform sampling at equal CPU:**\n\n{}\n```sh\n{command} --adaptive\n```\n",
            report.setup(),
            report.target_table(),
            report.adaptive_table()
        );
    }
    Ok(())
}
