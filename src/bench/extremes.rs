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

use std::fmt::Write as _;

use glam::{DAffine3, DVec3, IVec3};
use serde::Serialize;

use crate::vdb::{leaf_offset, FloatGrid, LEAF_VOXELS};
use plume_core::color::blackbody::blackbody_rgb_exact;
use plume_core::color::Rgb;
use plume_core::error::{Error, Result};
use plume_engine::camera::Camera;
use plume_engine::integrator::{Integrator, LightSampling, Lights, MisHeuristic, Scene, Tracking};
use plume_engine::medium::tracking::phi;
use plume_engine::medium::{
    Collision, Convention, Emission, EmissionKind, Estimator, Medium, TemperatureMap,
};
use plume_engine::render::{render, RenderSettings, SampleBudget};
use plume_volume::{Field, Volume};

/// Sizes of the sweep.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct ExtremesConfig {
    /// Voxels along each box edge (a multiple of 8).
    pub box_voxels: u32,
    /// Resolution of the explosion of the voxel-size sweep.
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
    /// Wall seconds of the sweep.
    pub seconds: f64,
}

const EMISSION_ONLY: [(&str, Estimator); 4] = [
    ("ray-march", Estimator::RayMarch),
    ("line", Estimator::Line),
    ("point", Estimator::Point),
    ("blend", Estimator::Blend { kappa: 4.0 }),
];

/// A grid of `n³` voxels (from index 0) with voxel edge `h`, centred on the origin.
#[must_use]
pub fn box_grid(name: &str, n: u32, h: f64, value: impl Fn(IVec3) -> f32) -> FloatGrid {
    let b = (n / 8) as i32;
    let mut origins = Vec::new();
    let mut values = Vec::new();
    for bz in 0..b {
        for by in 0..b {
            for bx in 0..b {
                let o = IVec3::new(bx, by, bz) * 8;
                let mut block = vec![0.0f32; LEAF_VOXELS];
                for x in 0..8 {
                    for y in 0..8 {
                        for z in 0..8 {
                            block[leaf_offset(x, y, z)] = value(o + IVec3::new(x, y, z));
                        }
                    }
                }
                origins.push(o);
                values.extend(block);
            }
        }
    }
    let world_from_index = DAffine3::from_scale(DVec3::splat(h))
        * DAffine3::from_translation(DVec3::splat(0.5 - 0.5 * f64::from(n)));
    FloatGrid { name: name.into(), world_from_index, background: 0.0, origins, values }
}

fn grid_emission(convention: Convention) -> Emission {
    Emission {
        kind: EmissionKind::Grid,
        convention,
        scale: 1.0,
        color: Rgb::ONE,
        temperature_map: TemperatureMap::Kelvin,
        cutoff_kelvin: 500.0,
    }
}

/// A far camera looking at the origin along +z, the box covering ~2/3 of the image.
fn box_camera(edge: f64, size: u32) -> Result<Camera> {
    let distance = 100.0 * edge;
    let fov = 2.0 * (0.75 * edge / distance).atan().to_degrees();
    Camera::look_at(DVec3::new(0.0, 0.0, -distance), DVec3::ZERO, DVec3::Y, fov, size, size)
}

fn render_image(
    scene: &Scene<Volume>,
    integrator: Integrator,
    spp: u32,
    seed: u64,
) -> Vec<[f32; 4]> {
    let r = render(
        scene,
        &RenderSettings {
            budget: SampleBudget::Spp(spp),
            seed,
            sampler: plume_core::sampling::SamplerKind::default(),
            threads: 0,
            first_sample: 0,
            integrator,
        },
        &|_, _| {},
    );
    r.film.average(r.spp)
}

/// Mean over RGB of the central third of the pixels: (mean, standard error of the mean).
fn central(img: &[[f32; 4]], size: u32, channel: Option<usize>) -> (f64, f64) {
    let (a, b) = (size / 3, size - size / 3);
    let mut v = Vec::new();
    for y in a..b {
        for x in a..b {
            let p = img[(y * size + x) as usize];
            v.push(match channel {
                Some(c) => f64::from(p[c]),
                None => (f64::from(p[0]) + f64::from(p[1]) + f64::from(p[2])) / 3.0,
            });
        }
    }
    let s = super::metrics::Spread::of(&v);
    (s.mean, s.std / (v.len() as f64).sqrt())
}

fn all_finite(img: &[[f32; 4]]) -> bool {
    img.iter().flatten().all(|v| v.is_finite())
}

/// Relative variance per sample of an estimator on a homogeneous segment of optical
/// depth `d` crossing voxels of optical thickness `x` each (METHOD.md §4), if known. For
/// the blend, `F = α F_line + (1 − α) F_point` on one free path with the same `α` in every
/// voxel, so its standard deviation is at most `α σ_line + (1 − α) σ_point` (Minkowski).
fn relative_variance(est: Estimator, d: f64, x: f64) -> Option<f64> {
    let point = if d > 700.0 { 0.0 } else { (-d).exp() / -(-d).exp_m1() };
    let line = if d < 1e-3 {
        d / 3.0
    } else {
        2.0 * (1.0 - (1.0 + d) * (-d).exp()) / (-(-d).exp_m1()).powi(2) - 1.0
    };
    match est {
        Estimator::Point => Some(point),
        Estimator::Line => Some(line),
        Estimator::Blend { kappa } => {
            let alpha = 1.0 / (1.0 + kappa * x);
            Some((alpha * line.max(0.0).sqrt() + (1.0 - alpha) * point.sqrt()).powi(2))
        }
        Estimator::RayMarch => None,
    }
}

struct Check<'a> {
    cfg: &'a ExtremesConfig,
    rows: Vec<Row>,
}

impl Check<'_> {
    /// Compare the central mean of `img` with `expected` for a box of optical depth `depth`.
    #[allow(clippy::too_many_arguments)] // one per column of the row
    fn closed_form(
        &mut self,
        sweep: &str,
        case: &str,
        method: &str,
        est: Estimator,
        img: &[[f32; 4]],
        expected: f64,
        depth: f64,
        exact_tol: f64,
    ) {
        let size = self.cfg.size;
        let (mean, se_emp) = central(img, size, None);
        let n = f64::from((size - 2 * (size / 3)).pow(2)) * f64::from(self.cfg.spp);
        let se_theory = relative_variance(est, depth, depth / f64::from(self.cfg.box_voxels))
            .map_or(0.0, |rv| expected.abs() * (rv / n).sqrt());
        let abs_tol = if est == Estimator::RayMarch {
            exact_tol * expected.abs()
        } else {
            5.0 * se_emp.max(se_theory) + exact_tol * expected.abs()
        };
        let scale = if expected != 0.0 { expected.abs() } else { 1.0 };
        let finite = all_finite(img);
        let err = (mean - expected).abs();
        self.rows.push(Row {
            sweep: sweep.into(),
            case: case.into(),
            method: method.into(),
            expected: Some(expected),
            measured: mean,
            error: err / scale,
            tolerance: abs_tol.max(1e-30 * scale) / scale,
            finite,
            pass: finite && err <= abs_tol.max(1e-30 * scale),
            note: "mean vs L_e d φ(μd)".into(),
        });
    }

    fn push(&mut self, row: Row) {
        self.rows.push(row);
    }
}

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
    Ok(ExtremesReport { config: *cfg, rows: check.rows, seconds: start.elapsed().as_secs_f64() })
}

fn density_sweep(cfg: &ExtremesConfig, check: &mut Check) -> Result<()> {
    let n = cfg.box_voxels;
    let h = 1.0 / f64::from(n);
    let emission = grid_emission(Convention::Physical);
    let dens = box_grid("density", n, h, |_| 1.0);
    let src = box_grid("emission", n, h, |_| 1.0);
    for k in -6..=6 {
        let sigma = 10f64.powi(k);
        let vol = Volume::build(&dens, Some(&src), |v| emission.map_source(v))?;
        let mut scene = Scene {
            field: vol,
            medium: Medium { sigma_t: sigma, albedo: 0.0, g: 0.0, emission },
            camera: box_camera(1.0, cfg.size)?,
            lights: Lights::default(),
            motion: None,
            majorants: None,
        };
        let depth = sigma; // μ d with ρ = 1, d = 1 m
        let expected = phi(depth); // L_e d φ(μd) with L_e = 1, d = 1
        let case = format!("σ_t = 1e{k}");
        for (name, est) in EMISSION_ONLY {
            let img = render_image(&scene, Integrator::emission_only(est), cfg.spp, 1);
            check.closed_form("density", &case, name, est, &img, expected, depth, 1e-4);
        }
        // Scattering: between the emission-only value and the equilibrium L_e/μ_a
        scene.medium.albedo = 0.5;
        scene.lights = Lights::build(&scene.field, &emission, LightSampling::Fnee, 8)?;
        // The defaults' camera segment: ray-marched, its collision forced
        let integ = Integrator {
            estimator: Estimator::Line,
            camera_estimator: Some(Estimator::RayMarch),
            light_sampling: LightSampling::Fnee,
            mis: MisHeuristic::Power,
            max_depth: 64,
            tracking: Tracking::Regular,
            split: 1,
            camera_collision: Collision::Forced,
            point_lookup: plume_engine::integrator::PointLookup::Exact,
            split_by: plume_engine::integrator::SplitBy::Uniform,
        };
        let img = render_image(&scene, integ, cfg.spp, 1);
        let (mean, se) = central(&img, cfg.size, None);
        let upper = 1.0 / (0.5 * sigma);
        let finite = all_finite(&img);
        // Distance outside [emission-only, L_e/μ_a], relative to the emission-only value
        let outside = (expected - mean).max(mean - upper).max(0.0) / expected;
        let tolerance = (5.0 * se + 1e-6 * expected) / expected;
        check.push(Row {
            sweep: "density".into(),
            case,
            method: "line-fnee, albedo 0.5".into(),
            expected: None,
            measured: mean,
            error: outside,
            tolerance,
            finite,
            pass: finite && outside <= tolerance,
            note: format!(
                "between emission-only {} and L_e/μ_a {}",
                super::numbers::num(expected),
                super::numbers::num(upper)
            ),
        });
    }
    Ok(())
}

fn temperature_sweep(cfg: &ExtremesConfig, check: &mut Check) -> Result<()> {
    let n = cfg.box_voxels;
    let h = 1.0 / f64::from(n);
    let dens = box_grid("density", n, h, |_| 1.0);
    let temp = box_grid("temperature", n, h, |_| 1.0);
    for t in [300.0f64, 1e3, 1e4, 1e5, 1e6, 1e7] {
        let map: TemperatureMap = format!("linear:0,{t}").parse()?;
        let emission = Emission {
            kind: EmissionKind::Blackbody,
            convention: Convention::Physical,
            scale: 1.0,
            color: Rgb::ONE,
            temperature_map: map,
            cutoff_kelvin: 500.0,
        };
        let vol = Volume::build(&dens, Some(&temp), |v| emission.map_source(v))?;
        let sigma = 1.0;
        let scene = Scene {
            field: vol,
            medium: Medium { sigma_t: sigma, albedo: 0.0, g: 0.0, emission },
            camera: box_camera(1.0, cfg.size)?,
            lights: Lights::default(),
            motion: None,
            majorants: None,
        };
        let c = if t < 500.0 { [0.0; 3] } else { blackbody_rgb_exact(t) };
        let expected = (c[0] + c[1] + c[2]) / 3.0 * phi(sigma);
        for (name, est) in &EMISSION_ONLY[..3] {
            let img = render_image(&scene, Integrator::emission_only(*est), cfg.spp, 2);
            check.closed_form(
                "temperature",
                &format!("T = {} K", super::numbers::num(t)),
                name,
                *est,
                &img,
                expected,
                sigma,
                2e-3,
            );
        }
    }
    Ok(())
}

/// The generated explosion with voxel edge `h`, σ_t and emission scaled by `h₀/h`.
fn explosion_at(ex: &plume_synth::Explosion, h: f64, h0: f64, size: u32) -> Result<Scene<Volume>> {
    let rescale = |g: &FloatGrid| {
        let mut g = g.clone();
        g.world_from_index = DAffine3::from_scale(DVec3::splat(h / h0)) * g.world_from_index;
        g
    };
    let (d, t) = (rescale(&ex.density), rescale(&ex.temperature));
    let emission = Emission {
        kind: EmissionKind::Blackbody,
        convention: Convention::Physical,
        scale: (h0 / h) as f32,
        color: Rgb::ONE,
        temperature_map: TemperatureMap::Kelvin,
        cutoff_kelvin: 500.0,
    };
    let vol = Volume::build(&d, Some(&t), |v| emission.map_source(v))?;
    let plume_volume::Bounds3 { lo, hi } = vol.world_bounds();
    let camera =
        Camera::frame_bounds(lo, hi, DVec3::new(0.35, 0.25, 1.0), DVec3::Y, 40.0, size, size)?;
    Ok(Scene {
        field: vol,
        medium: Medium { sigma_t: 4.0 * h0 / h, albedo: 0.0, g: 0.0, emission },
        camera,
        lights: Lights::default(),
        motion: None,
        majorants: None,
    })
}

fn voxel_size_sweep(cfg: &ExtremesConfig, check: &mut Check) -> Result<()> {
    let res = cfg.explosion_resolution;
    let ex = plume_synth::explosion(&plume_synth::ExplosionParams {
        resolution: res,
        seed: 1,
        ..Default::default()
    });
    let h0 = plume_synth::WORLD_SIZE / f64::from(res);
    let base = explosion_at(&ex, h0, h0, cfg.size)?;
    let methods = &EMISSION_ONLY[..3];
    let refs: Vec<Vec<[f32; 4]>> = methods
        .iter()
        .map(|(_, e)| render_image(&base, Integrator::emission_only(*e), cfg.spp, 3))
        .collect();
    for k in -4..=4 {
        let h = 10f64.powi(k);
        let scene = explosion_at(&ex, h, h0, cfg.size)?;
        for ((name, est), reference) in methods.iter().zip(&refs) {
            let img = render_image(&scene, Integrator::emission_only(*est), cfg.spp, 3);
            let peak = reference
                .iter()
                .flat_map(|p| p[..3].iter())
                .fold(0.0f32, |m, v| m.max(*v))
                .max(f32::MIN_POSITIVE);
            let max_diff = img
                .iter()
                .zip(reference)
                .flat_map(|(a, b)| (0..3).map(move |c| (a[c] - b[c]).abs()))
                .fold(0.0f32, f32::max)
                / peak;
            let mean_diff =
                (super::metrics::mean_rgb(&img) / super::metrics::mean_rgb(reference) - 1.0).abs();
            // Stochastic estimators may flip a collision decision at a near-tie, which moves
            // one sample of one pixel; their mean must still agree closely.
            let (measured, tol, note) = if *est == Estimator::RayMarch {
                (f64::from(max_diff), 1e-5, "largest pixel difference / peak, vs h₀ image")
            } else {
                (mean_diff, 1e-5, "relative difference of image means, vs h₀ image")
            };
            let finite = all_finite(&img);
            check.push(Row {
                sweep: "voxel size".into(),
                case: format!("h = 1e{k} (σ_t, L_e × h₀/h)"),
                method: (*name).into(),
                expected: None,
                measured,
                error: measured,
                tolerance: tol,
                finite,
                pass: finite && measured <= tol,
                note: note.into(),
            });
        }
    }
    Ok(())
}

fn invalid_voxels(cfg: &ExtremesConfig, check: &mut Check) -> Result<()> {
    let n = cfg.box_voxels;
    let h = 1.0 / f64::from(n);
    let bad_density = |p: IVec3| match (p.x + 2 * p.y + 3 * p.z).rem_euclid(11) {
        0 => Some(f32::NAN),
        1 => Some(f32::INFINITY),
        2 => Some(f32::NEG_INFINITY),
        3 => Some(-1.0),
        _ => None,
    };
    let bad_source = |p: IVec3| match (3 * p.x + p.y + 5 * p.z).rem_euclid(13) {
        0 => Some(f32::NAN),
        1 => Some(f32::INFINITY),
        2 => Some(-2.5),
        _ => None,
    };
    let dirty_d = box_grid("density", n, h, |p| bad_density(p).unwrap_or(1.0));
    let dirty_s = box_grid("emission", n, h, |p| bad_source(p).unwrap_or(2.0));
    let clean_d = box_grid("density", n, h, |p| if bad_density(p).is_some() { 0.0 } else { 1.0 });
    let clean_s = box_grid("emission", n, h, |p| if bad_source(p).is_some() { 0.0 } else { 2.0 });
    let all = (0..n as i32).flat_map(|z| {
        (0..n as i32).flat_map(move |y| (0..n as i32).map(move |x| IVec3::new(x, y, z)))
    });
    let expected_d = all.clone().filter(|p| bad_density(*p).is_some()).count() as u64;
    let expected_s = all.filter(|p| bad_source(*p).is_some()).count() as u64;
    let emission = grid_emission(Convention::Physical);
    let dirty = Volume::build(&dirty_d, Some(&dirty_s), |v| emission.map_source(v))?;
    let clean = Volume::build(&clean_d, Some(&clean_s), |v| emission.map_source(v))?;
    let counts_ok = dirty.report.density_clamped == expected_d
        && dirty.report.source_invalid == expected_s
        && clean.report == Default::default();
    check.push(Row {
        sweep: "invalid voxels".into(),
        case: format!(
            "{expected_d} density + {expected_s} source voxels NaN/±inf/negative of {}",
            n * n * n
        ),
        method: "build".into(),
        expected: Some((expected_d + expected_s) as f64),
        measured: (dirty.report.density_clamped + dirty.report.source_invalid) as f64,
        error: if counts_ok { 0.0 } else { 1.0 },
        tolerance: 0.0,
        finite: true,
        pass: counts_ok,
        note: format!(
            "clamped and counted: density {}, source {}",
            dirty.report.density_clamped, dirty.report.source_invalid
        ),
    });
    let medium = Medium { sigma_t: 3.0, albedo: 0.0, g: 0.0, emission };
    let camera = box_camera(1.0, cfg.size)?;
    let dirty = Scene {
        field: dirty,
        medium,
        camera,
        lights: Lights::default(),
        motion: None,
        majorants: None,
    };
    let clean = Scene {
        field: clean,
        medium,
        camera,
        lights: Lights::default(),
        motion: None,
        majorants: None,
    };
    for (name, est) in EMISSION_ONLY {
        let a = render_image(&dirty, Integrator::emission_only(est), cfg.spp, 4);
        let b = render_image(&clean, Integrator::emission_only(est), cfg.spp, 4);
        let same =
            a.iter().flatten().zip(b.iter().flatten()).all(|(x, y)| x.to_bits() == y.to_bits());
        let finite = all_finite(&a);
        check.push(Row {
            sweep: "invalid voxels".into(),
            case: "render".into(),
            method: name.into(),
            expected: None,
            measured: if same { 0.0 } else { 1.0 },
            error: if same { 0.0 } else { 1.0 },
            tolerance: 0.0,
            finite,
            pass: finite && same,
            note: "bit-identical to the box with zeros written there".into(),
        });
    }
    Ok(())
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
            let n = super::numbers::num;
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
                r.sweep,
                r.case,
                r.method,
                r.expected.map_or("–".into(), n),
                n(r.measured),
                n(r.error),
                n(r.tolerance),
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
