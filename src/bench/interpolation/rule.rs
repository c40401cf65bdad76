//! What trilinear reconstruction interpolates: the per-voxel emission rule against
//! interpolating the temperature first.
//!
//! At a point `x` with corners `c` and weights `w_c` ([`PointCorners`]):
//! - the **per-voxel rule** interpolates each voxel's emission density:
//!   `L_e(x) = Σ_c w_c le(ρ_c, T_c)` ([`PointCorners::emission`]), a cubic along a ray, so
//!   the line estimator integrates it in closed form (`volume::trilinear`); plume uses it
//!   in both conventions, and it is the expected value of Cycles 5.0.1's stochastic
//!   one-tap grid lookups;
//! - **temperature first** interpolates density and temperature and applies the emission
//!   after: `L_e(x) = le(ρ(x), T(x))`, with `ρ(x) = Σ w_c ρ_c`, `T(x) = Σ w_c T_c` (what a
//!   deterministic trilinear lookup, e.g. OpenVDB's `BoxSampler`, followed by the blackbody
//!   gives). The figures say how far apart the two are.
//!
//! The two differ where `le` is not linear in T (blackbody: `T⁴` in the Cycles convention,
//! Planck in the physical one) and, in the physical convention, where `ρ·C(T)` is not
//! linear across a cell; most of all at the fire's edge, where inactive temperature voxels
//! count as 0 K and pull an interpolated `T(x)` down.
//!
//! **Quadrature** (deterministic, the same for both): one ray per pixel centre, clipped to
//! the trilinear support; a midpoint march whose index-space step is at most
//! `step_voxels` (⅛ voxel by default); at each midpoint `s_m`,
//! `τ(s_m) = exp(−(OD(s_m − Δ/2) + σ_t ρ(s_m) Δ/2))` from the interpolated density, and
//! `L += τ(s_m) L_e(s_m) Δ`. The march stops once the optical depth passes 50
//! (τ < 2·10⁻²²). Same τ, same points: only the emission rule differs.
//!
//! **Figures**, with the temperature-first image as the reference `b` and the per-voxel rule's as `a`: the image mean
//! difference `(mean a − mean b)/mean b`; `relRMSE = √relMSE` with `bench::metrics`'
//! relMSE (`(a − b)²/(b² + ε)` per pixel and channel, top 0.1 % of pixels trimmed) of the
//! images divided by `mean b`, with the metrics' default ε = 10⁻² (an absolute
//! `ε · (mean b)²`: the conventions' radiances differ by orders of magnitude, 0.04 against
//! 600 here, and an absolute ε would swamp one and vanish in the other); and
//! `RMSE / mean b`.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use rayon::prelude::*;
use serde::Serialize;

use crate::bench::metrics::{mean_rgb, relmse, rmse, RELMSE_EPSILON, RELMSE_TRIM};
use crate::bench::spec::{bench_shot, load_file};
use plume_core::error::{Error, Result};
use plume_engine::integrator::AnyScene;
use plume_engine::medium::Medium;
use plume_scene::file::with_keys;
use plume_volume::field::{clip_to_box, Ray};
use plume_volume::trilinear::{PointCorners, Trilinear};
use plume_volume::{Bounds3, Field};

/// Optical depth after which a march stops (τ < 2·10⁻²²).
const OPTICAL_DEPTH_STOP: f64 = 50.0;

/// Settings of the comparison.
#[derive(Clone, Debug)]
pub struct RuleConfig {
    /// Files under the data directory; empty: every `explosion/mantaflow_explosion_kelvin_*.vdb`.
    pub files: Vec<PathBuf>,
    /// Image size.
    pub width: u32,
    /// Image size.
    pub height: u32,
    /// Largest index-space step of the march, in voxels.
    pub step_voxels: f64,
}

/// One file and convention.
#[derive(Clone, Debug, Serialize)]
pub struct RuleRow {
    /// File, relative to the data directory.
    pub file: String,
    /// `cycles` or `physical`.
    pub convention: String,
    /// Image mean (RGB) with the per-voxel rule.
    pub plume_mean: f64,
    /// Image mean (RGB) with the temperature interpolated first.
    pub cycles_mean: f64,
    /// `100 · (plume_mean − cycles_mean) / cycles_mean`.
    pub mean_difference_percent: f64,
    /// `√relMSE(plume / mean, cycles / mean)` (module docs).
    pub relrmse: f64,
    /// `RMSE(plume, cycles) / cycles_mean`.
    pub rmse_over_mean: f64,
    /// Midpoints evaluated per pixel, on average.
    pub steps_per_pixel: f64,
    /// Wall seconds of both images.
    pub seconds: f64,
}

/// The comparison's rows and settings.
#[derive(Clone, Debug, Default, Serialize)]
pub struct RuleReport {
    /// Image size.
    pub width: u32,
    /// Image size.
    pub height: u32,
    /// Largest index-space step, voxels.
    pub step_voxels: f64,
    /// ε of relMSE, in units of the reference image's mean squared.
    pub epsilon: f64,
    /// One row per file and convention.
    pub rows: Vec<RuleRow>,
}

/// Radiance of one ray by both rules, and the midpoints evaluated.
struct RayPair {
    plume: [f64; 3],
    cycles: [f64; 3],
    steps: u64,
}

/// March `ray` through `field` (module docs).
fn march(
    field: &Trilinear,
    medium: &Medium,
    bounds: &Bounds3,
    ray: &Ray,
    step_voxels: f64,
) -> RayPair {
    let mut out = RayPair { plume: [0.0; 3], cycles: [0.0; 3], steps: 0 };
    let Some((t0, t1)) =
        clip_to_box(ray.origin, ray.direction, bounds.lo, bounds.hi, 0.0, f64::INFINITY)
    else {
        return out;
    };
    // Index-space length of one world unit along the ray
    let index_per_world = (field.volume().index_from_world().matrix3 * ray.direction).length();
    let n = ((t1 - t0) * index_per_world / step_voxels).ceil().max(1.0);
    let h = (t1 - t0) / n;
    let le = |density: f32, source: f32| medium.emission.le(density, source);
    let mut optical_depth = 0.0;
    for i in 0..n as u64 {
        let corners: PointCorners = field.interpolate_world(ray.at(t0 + (i as f64 + 0.5) * h));
        out.steps += 1;
        let density = corners.density();
        let mu_t = medium.sigma_t * density;
        // τ at the midpoint, then the optical depth to the step's end
        let weight = (-(optical_depth + 0.5 * mu_t * h)).exp() * h;
        optical_depth += mu_t * h;
        let plume = corners.emission(&le);
        let cycles = le(density as f32, corners.source() as f32).to_f64();
        for c in 0..3 {
            out.plume[c] += weight * plume[c];
            out.cycles[c] += weight * cycles[c];
        }
        if optical_depth > OPTICAL_DEPTH_STOP {
            break;
        }
    }
    out
}

/// Both images of a loaded linear scene (rows in parallel, each pixel on its own).
fn images(
    field: &Trilinear,
    medium: &Medium,
    camera: &plume_engine::camera::Camera,
    step_voxels: f64,
) -> (Vec<[f32; 4]>, Vec<[f32; 4]>, u64) {
    let bounds = field.world_bounds();
    let rows: Vec<Vec<RayPair>> = (0..camera.height)
        .into_par_iter()
        .map(|y| {
            (0..camera.width)
                .map(|x| {
                    march(
                        field,
                        medium,
                        &bounds,
                        &camera.ray(f64::from(x) + 0.5, f64::from(y) + 0.5),
                        step_voxels,
                    )
                })
                .collect()
        })
        .collect();
    let px = |v: [f64; 3]| [v[0] as f32, v[1] as f32, v[2] as f32, 1.0];
    let pairs = rows.iter().flatten();
    let plume = pairs.clone().map(|p| px(p.plume)).collect();
    let cycles = pairs.clone().map(|p| px(p.cycles)).collect();
    (plume, cycles, pairs.map(|p| p.steps).sum())
}

/// Every `explosion/mantaflow_explosion_kelvin_*.vdb` under `data`, sorted.
fn kelvin_frames(data: &Path) -> Result<Vec<PathBuf>> {
    let dir = data.join("explosion");
    let entries =
        std::fs::read_dir(&dir).map_err(|source| Error::Open { path: dir.clone(), source })?;
    let mut out: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.file_name().to_string_lossy().into_owned()))
        .filter(|n| n.starts_with("mantaflow_explosion_kelvin_") && n.ends_with(".vdb"))
        .map(|n| Path::new("explosion").join(n))
        .collect();
    out.sort();
    Ok(out)
}

/// Compare the rules on each file, in the Cycles and the physical convention.
///
/// # Errors
/// A missing or unreadable file, or no file at all.
pub fn run(data: &Path, cfg: &RuleConfig, log: &dyn Fn(&str)) -> Result<RuleReport> {
    let files = if cfg.files.is_empty() { kelvin_frames(data)? } else { cfg.files.clone() };
    if files.is_empty() {
        return Err(Error::invalid(
            "--rule-files",
            format!("no explosion/mantaflow_explosion_kelvin_*.vdb under {}", data.display()),
        ));
    }
    if !(cfg.step_voxels > 0.0 && cfg.step_voxels <= 1.0) {
        return Err(Error::invalid(
            "--rule-step",
            format!("{} is not in (0, 1] voxels", cfg.step_voxels),
        ));
    }
    let mut rows = Vec::new();
    for file in &files {
        for convention in ["cycles", "physical"] {
            let start = Instant::now();
            let keys = format!(
                "[volume]\ninterpolation = \"linear\"\n[emission]\nconvention = \"{convention}\"\n[camera]\nup_axis = \"z\"\nwidth = {}\nheight = {}",
                cfg.width, cfg.height
            );
            let shot = with_keys(&bench_shot(&data.join(file).display().to_string()), &keys)?;
            let scene = load_file(shot, vec![])?.loaded.scene;
            let AnyScene::Linear(s) = &scene else {
                unreachable!("invariant: loaded with linear interpolation")
            };
            let (plume, cycles, steps) = images(&s.field, &s.medium, &s.camera, cfg.step_voxels);
            let (pm, cm) = (mean_rgb(&plume), mean_rgb(&cycles));
            let row = RuleRow {
                file: file.display().to_string(),
                convention: convention.into(),
                plume_mean: pm,
                cycles_mean: cm,
                mean_difference_percent: 100.0 * (pm - cm) / cm,
                // ε relative to the image mean (module docs)
                relrmse: relmse(&plume, &cycles, RELMSE_EPSILON * cm * cm, RELMSE_TRIM).sqrt(),
                rmse_over_mean: rmse(&plume, &cycles) / cm,
                steps_per_pixel: steps as f64 / plume.len().max(1) as f64,
                seconds: start.elapsed().as_secs_f64(),
            };
            log(&format!(
                "{} {convention}: mean {:+.2} %, relRMSE {:.4}, RMSE/mean {:.4} ({:.0} steps per pixel, {:.1} s)",
                row.file, row.mean_difference_percent, row.relrmse, row.rmse_over_mean, row.steps_per_pixel, row.seconds
            ));
            rows.push(row);
        }
    }
    Ok(RuleReport {
        width: cfg.width,
        height: cfg.height,
        step_voxels: cfg.step_voxels,
        epsilon: RELMSE_EPSILON,
        rows,
    })
}

impl RuleReport {
    /// The comparison as Markdown: what was done and the table.
    #[must_use]
    pub fn markdown(&self) -> String {
        let mut s = format!(
            "**Emission rule: per-voxel against temperature first.** The per-voxel rule interpolates each voxel's emission density, `L_e(x) = Σ w_c le(ρ_c, T_c)` (plume, in both conventions: a cubic, integrated in closed form; the expected value of Cycles 5.0.1's stochastic one-tap lookups); the other interpolates ρ and T and applies the blackbody after, `le(ρ(x), T(x))`. Emission-only images ({}×{}, auto-framed, σ_t = 1 per metre as Blender's default density), one ray per pixel centre, a deterministic midpoint march with an index-space step of at most {} voxel, the same transmittance (interpolated ρ) for both: only the emission rule differs. Reference = temperature first. relRMSE = √relMSE, relMSE as in the metrics above (top 0.1 % trimmed) on both images divided by the reference's mean, ε = {} (the conventions' radiances differ by orders of magnitude).\n\n",
            self.width, self.height, crate::bench::numbers::num(self.step_voxels), self.epsilon
        );
        s.push_str("| file | convention | image mean, per-voxel rule | image mean, temperature first | mean difference | relRMSE | RMSE ÷ mean |\n|---|---|---|---|---|---|---|\n");
        for r in &self.rows {
            let _ = writeln!(
                s,
                "| `{}` | {} | {} | {} | **{:+.2} %** | {:.4} | {:.4} |",
                r.file,
                r.convention,
                crate::bench::numbers::num(r.plume_mean),
                crate::bench::numbers::num(r.cycles_mean),
                r.mean_difference_percent,
                r.relrmse,
                r.rmse_over_mean
            );
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use glam::DVec3;

    use super::*;
    use crate::bench::extremes::box_grid;
    use plume_core::color::Rgb;
    use plume_engine::camera::Camera;
    use plume_engine::medium::{Convention, Emission, EmissionKind, TemperatureMap};
    use plume_volume::Volume;

    /// A 16³ box of varying density and source (1500 … 2500, zero on one face), seen
    /// head-on by a 12×12 camera.
    fn scene(kind: EmissionKind, convention: Convention) -> (Trilinear, Medium, Camera) {
        let density =
            box_grid("density", 16, 0.1, |p| 0.2 + 0.05 * ((p.x * 7 + p.y * 3 + p.z) % 11) as f32);
        let source = box_grid("temperature", 16, 0.1, |p| {
            if p.x == 0 {
                0.0
            } else {
                1500.0 + 60.0 * ((p.x * 5 + p.y * 11 + p.z * 3) % 17) as f32
            }
        });
        let volume = Volume::build(&density, Some(&source), |v| v).unwrap();
        let emission = Emission {
            kind,
            convention,
            scale: 1e-3,
            color: Rgb::ONE,
            temperature_map: TemperatureMap::Kelvin,
            cutoff_kelvin: 0.0,
        };
        let medium = Medium {
            sigma_t: 2.0,
            albedo: plume_core::color::Rgb::splat(0.0),
            g: 0.0,
            emission,
            extinction: Default::default(),
        };
        let camera =
            Camera::look_at(DVec3::new(0.3, 0.2, 5.0), DVec3::ZERO, DVec3::Y, 30.0, 12, 12)
                .unwrap();
        (Trilinear::new(volume), medium, camera)
    }

    #[test]
    fn rules_agree_when_emission_is_linear_in_the_source() {
        // Cycles-convention grid emission, scale · v: interpolating v or le(v) is the same
        let (field, medium, camera) = scene(EmissionKind::Grid, Convention::Cycles);
        let (plume, cycles, steps) = images(&field, &medium, &camera, 0.125);
        assert!(steps > 0 && mean_rgb(&cycles) > 0.0);
        for (a, b) in plume.iter().zip(&cycles) {
            for c in 0..3 {
                assert!((a[c] - b[c]).abs() <= 1e-5 * b[c].abs().max(1e-6), "{a:?} vs {b:?}");
            }
        }
    }

    #[test]
    fn blackbody_rules_differ_and_plume_is_brighter_at_a_cold_face() {
        // T⁴ is convex, and the x = 0 face holds no temperature: interpolating T pulls it down
        let (field, medium, camera) = scene(EmissionKind::Blackbody, Convention::Cycles);
        let (plume, cycles, _) = images(&field, &medium, &camera, 0.125);
        let (p, c) = (mean_rgb(&plume), mean_rgb(&cycles));
        assert!(p > c && c > 0.0, "plume {p}, cycles {c}");
        // A finer march changes neither mean by much: the quadrature converges
        let (fine, _, _) = images(&field, &medium, &camera, 0.03125);
        assert!((mean_rgb(&fine) - p).abs() < 1e-3 * p, "{} vs {p}", mean_rgb(&fine));
    }
}
