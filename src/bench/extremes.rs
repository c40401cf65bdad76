//! `plume bench extremes`: the numerical-extremes sweep. Every case renders, every pixel
//! must be finite, and where a closed form exists the mean must match it.
//!
//! **Scenes.** A voxel-aligned constant box of `n³` voxels (edge `n·h`), seen head-on by
//! a far camera (100 box edges away, 0.9° field of view), so the central third of the
//! pixels sees exactly the depth `d = n·h` (path-length deviation < 1e-5). For a box of
//! density ρ and emission density `L_e` (METHOD.md §11.1):
//! `L = L_e (1 − e^{−μd})/μ = L_e d φ(μd)`, `μ = σ_t ρ`, `φ(x) = (1 − e^{−x})/x`, and alpha
//! `1 − e^{−μd}`.
//!
//! **Sweeps.**
//! - *density*: `σ_t = 10^k`, `k = −6 … 6`, grid emission 1 per unit length in a 1 m box;
//! - *temperature*: blackbody box with `--temperature-map linear:0,T`, `T` from 300 K (below
//!   the 500 K cutoff: black) to 10⁷ K (solar-flare plasma); expected `C(T)` from the f64
//!   Planck × CIE integration ([`blackbody_rgb_exact`]), not the renderer's table;
//! - *voxel size*: the generated explosion with voxel edge `h = 10^k`, `k = −4 … 4`
//!   (`world_from_index` scaled), **density scale and emission scale both multiplied by
//!   `h₀/h`** so optical depths and radiance are unchanged; the images must equal the
//!   `h = h₀` image up to float rounding, 1e-5 (`h₀` is the generator's own voxel size);
//! - *invalid voxels*: a box whose density and source grids hold NaN, +inf, −inf and
//!   negative values; the build must clamp exactly those voxels to 0 and count them, and
//!   the image must equal (bit for bit) that of the same box with zeros written there.
//!
//! **Tolerances.** Ray-march (expected value) is deterministic along each ray: relative
//! 1e-4 (2e-3 for blackbody, the table's accuracy). Stochastic estimators: 5 standard
//! errors, with the standard error the larger of the empirical one (spread of the central
//! pixels) and the theoretical one for a homogeneous segment of optical depth `D`
//! (METHOD.md §4: point `e^{−D}/(1 − e^{−D})`, line
//! `2(1 − (1 + D)e^{−D})/(1 − e^{−D})² − 1`, per sample). With scattering (albedo 0.5,
//! line-fnee) there is no closed form; the mean must lie between the emission-only value
//! and the infinite-medium equilibrium `L_e/μ_a` (METHOD.md §11.2).
//!
//! - *cost*: the explosion with scattering at density scales 1e-6 … 1e6, per method:
//!   work per walk may grow at most 2× (`cost`, where the measure is explained).
//!
//! Files: the settings, rows and their table in `rows`; the scenes, renders and the
//! closed-form check shared by the sweeps in `check`; the four checks of the image in
//! `sweeps`; the cost sweep in `cost`.

mod check;
mod cost;
mod rows;
mod sweeps;

use plume_core::error::{Error, Result};

use check::Check;
use sweeps::{density_sweep, invalid_voxels, temperature_sweep, voxel_size_sweep};

pub use check::box_grid;
pub use cost::{cost_table, growth, MAX_GROWTH};
pub use rows::{CostPoint, ExtremesConfig, ExtremesReport, Row};

/// Run the sweep.
///
/// # Errors
/// Scene construction failures (not expected: every case is a valid scene).
pub fn run(cfg: &ExtremesConfig) -> Result<ExtremesReport> {
    let start = std::time::Instant::now();
    if cfg.box_voxels == 0 || cfg.box_voxels % 8 != 0 || cfg.size < 3 || cfg.spp == 0 {
        return Err(Error::invalid(
            "--box-voxels/--size/--spp",
            "box voxels must be a positive multiple of 8, size ≥ 3, spp ≥ 1",
        ));
    }
    let mut check = Check { cfg, rows: Vec::new() };
    density_sweep(cfg, &mut check)?;
    temperature_sweep(cfg, &mut check)?;
    voxel_size_sweep(cfg, &mut check)?;
    invalid_voxels(cfg, &mut check)?;
    let cost = cost::cost_sweep(cfg, &mut check)?;
    Ok(ExtremesReport {
        config: *cfg,
        rows: check.rows,
        cost,
        seconds: start.elapsed().as_secs_f64(),
    })
}
