//! The numerical-extremes sweep's settings ([`ExtremesConfig`]), its checks ([`Row`]), the
//! cost sweep's renders ([`CostPoint`]) and what it reports ([`ExtremesReport`]): the
//! verdict and the Markdown table.

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

/// One render of the sweep.
#[derive(Clone, Debug, Serialize)]
pub struct CostPoint {
    /// Method preset.
    pub method: String,
    /// Tracking the method ran with.
    pub tracking: String,
    /// Density scale (σ_t per unit of the grid's density).
    pub density_scale: f64,
    /// Camera samples.
    pub samples: u64,
    /// Rays tracked.
    pub walks: u64,
    /// Voxel steps of all walks.
    pub voxel_steps: u64,
    /// Tentative points of null collisions.
    pub tentative_points: u64,
    /// Real collisions.
    pub collisions: u64,
    /// Render seconds (one thread).
    pub seconds: f64,
}

impl CostPoint {
    /// Voxel steps plus tentative points.
    #[must_use]
    pub fn work(&self) -> u64 {
        self.voxel_steps + self.tentative_points
    }
    /// Work per walk.
    #[must_use]
    pub fn work_per_walk(&self) -> f64 {
        self.work() as f64 / self.walks.max(1) as f64
    }
    /// Walks per sample.
    #[must_use]
    pub fn walks_per_sample(&self) -> f64 {
        self.walks as f64 / self.samples.max(1) as f64
    }
    /// Microseconds per walk.
    #[must_use]
    pub fn micros_per_walk(&self) -> f64 {
        1e6 * self.seconds / self.walks.max(1) as f64
    }
    /// Microseconds per sample.
    #[must_use]
    pub fn micros_per_sample(&self) -> f64 {
        1e6 * self.seconds / self.samples.max(1) as f64
    }
    pub(super) fn label(&self) -> String {
        format!("{}, {} tracking", self.method, self.tracking)
    }
}

/// Everything the sweep checked.
#[derive(Clone, Debug, Serialize)]
pub struct ExtremesReport {
    /// Sizes used.
    pub config: ExtremesConfig,
    /// Checks in order.
    pub rows: Vec<Row>,
    /// The cost sweep's renders, method by method in order of density.
    pub cost: Vec<CostPoint>,
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
