//! What a report spends and where it writes: the full and the quick form ([`Budgets`]),
//! and the options of `plume bench report` ([`ReportOptions`]; it runs as
//! `bench::report::run`).

use std::path::PathBuf;

/// CPU-time scale of the quick form.
pub const QUICK_TIME_SCALE: f64 = 0.25;

/// How much a report spends: the full form or the quick one, with any overrides.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Budgets {
    /// The quick form (the document says so in its header).
    pub quick: bool,
    /// Multiplies every CPU-time budget.
    pub time_scale: f64,
    /// Resolution of the generated explosion of the thin, dense and proxy sections.
    pub resolution: u32,
    /// Resolution of the generated explosion of the core figures.
    pub core_resolution: u32,
    /// Run the README demo section (`plume bench demo`: two 512-spp references, rendered
    /// once into the work directory, then kept).
    pub demo: bool,
}

impl Budgets {
    /// The full form: budgets × 1, a 256³ explosion, every section that runs from the
    /// binary.
    pub const FULL: Budgets = Budgets {
        quick: false,
        time_scale: 1.0,
        resolution: 256,
        core_resolution: 256,
        demo: true,
    };
    /// The quick form: budgets × [`QUICK_TIME_SCALE`], a 128³ explosion, no README demo;
    /// under 20 minutes of wall time on 2 cores.
    pub const QUICK: Budgets = Budgets {
        quick: true,
        time_scale: QUICK_TIME_SCALE,
        resolution: 128,
        core_resolution: 128,
        demo: false,
    };

    /// The quick form or the full one.
    #[must_use]
    pub fn form(quick: bool) -> Budgets {
        if quick {
            Budgets::QUICK
        } else {
            Budgets::FULL
        }
    }

    /// These budgets with the time scale and the explosion resolution replaced where given.
    #[must_use]
    pub fn with_overrides(mut self, time_scale: Option<f64>, resolution: Option<u32>) -> Budgets {
        if let Some(t) = time_scale {
            self.time_scale = t;
        }
        if let Some(r) = resolution {
            self.resolution = r;
        }
        self
    }
}

/// `plume bench report`.
#[derive(Clone, Debug)]
pub struct ReportOptions {
    /// Directory of BENCHMARKS.md; plots go to DIR/img, CSV and JSON to DIR/bench.
    pub out: PathBuf,
    /// The form and its budgets.
    pub budgets: Budgets,
    /// Directory of the shared data (smoke, cloud and Blender files).
    pub data: PathBuf,
    /// Where generated explosions, saved references and the demo's renders are written.
    pub work_dir: PathBuf,
    /// The directory the command runs in: the README demo's scene file is found, and the
    /// scene files of its renders are made absolute, against it.
    pub working_dir: PathBuf,
    /// The `plume` binary, which renders the README demo in processes of its own; without
    /// it that section is skipped.
    pub exe: Option<PathBuf>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn overrides_replace_only_what_is_given() {
        assert_eq!(Budgets::form(true).with_overrides(None, None), Budgets::QUICK);
        let b = Budgets::form(false).with_overrides(Some(0.5), None);
        assert_eq!((b.time_scale, b.resolution, b.quick, b.demo), (0.5, 256, false, true));
    }
}
