//! The numerical-extremes sweep's settings ([`ExtremesConfig`]), its checks ([`Row`]) and
//! what it reports ([`ExtremesReport`]): the verdict and the Markdown table.

use std::fmt::Write as _;

use serde::Serialize;

use crate::bench::numbers::num;
use plume_core::error::{Error, Result};

/// Sizes of the sweep.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct ExtremesConfig {
    /// Voxels along each box edge (a multiple of 8).
    pub box_voxels: u32,
    /// Resolution of the explosion of the voxel-size and cost sweeps.
    pub explosion_resolution: u32,
    /// Image width and height.
    pub size: u32,
    /// Samples per pixel.
    pub spp: u32,
}

/// One check.
#[derive(Clone, Debug, Serialize)]
pub struct Row {
    /// Sweep name.
    pub sweep: String,
    /// Case within the sweep.
    pub case: String,
    /// Method.
    pub method: String,
    /// Expected mean (central pixels, mean over RGB), if a closed form exists.
    pub expected: Option<f64>,
    /// Measured value (mean, or the largest relative difference for image comparisons).
    pub measured: f64,
    /// `|measured − expected| / |expected|` (or the measured difference itself).
    pub error: f64,
    /// Allowed error.
    pub tolerance: f64,
    /// Every pixel of the image is finite.
    pub finite: bool,
    /// Finite and within tolerance.
    pub pass: bool,
    /// What was compared.
    pub note: String,
}

/// Everything the sweep checked.
#[derive(Clone, Debug, Serialize)]
pub struct ExtremesReport {
    /// Sizes used.
    pub config: ExtremesConfig,
    /// Checks in order.
    pub rows: Vec<Row>,
    /// The cost sweep's renders, method by method in order of density.
    pub cost: Vec<super::cost::CostPoint>,
    /// Wall seconds of the sweep.
    pub seconds: f64,
}

impl ExtremesReport {
    /// `Ok` when every check passed; else [`Error::Scene`] saying how many failed (exit
    /// code 4), to end with once the table is shown.
    ///
    /// # Errors
    /// As said: a failed check.
    pub fn verdict(&self) -> Result<()> {
        let failed = self.rows.iter().filter(|r| !r.pass).count();
        if failed > 0 {
            return Err(Error::Scene(format!("{failed} extremes checks failed (see the table)")));
        }
        Ok(())
    }

    /// The rows as a Markdown table.
    #[must_use]
    pub fn table(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(s, "| sweep | case | method | expected | measured | error | tolerance | finite | pass | check |");
        let _ = writeln!(s, "|---|---|---|---|---|---|---|---|---|---|");
        for r in &self.rows {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
                r.sweep,
                r.case,
                r.method,
                r.expected.map_or("–".into(), num),
                num(r.measured),
                num(r.error),
                num(r.tolerance),
                if r.finite { "yes" } else { "**no**" },
                if r.pass { "✓" } else { "**FAIL**" },
                r.note
            );
        }
        let failed = self.rows.iter().filter(|r| !r.pass).count();
        let _ =
            writeln!(s, "\n{} checks, {} failed, {:.1} s.", self.rows.len(), failed, self.seconds);
        s
    }
}
