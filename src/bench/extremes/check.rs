//! What the sweeps share: the scenes (a voxel-aligned constant box seen head-on by a far
//! camera), the renders, the statistics of the central pixels, and the check of a mean
//! against a closed form within its tolerance ([`Check`]).

use glam::{DAffine3, DVec3, IVec3};

use super::rows::{ExtremesConfig, Row};
use crate::bench::metrics::Spread;
use crate::vdb::{leaf_offset, FloatGrid, LEAF_VOXELS};
use plume_core::color::Rgb;
use plume_core::error::Result;
use plume_engine::camera::Camera;
use plume_engine::integrator::{Integrator, Scene};
use plume_engine::medium::{Convention, Emission, EmissionKind, Estimator, TemperatureMap};
use plume_engine::render::{render, RenderSettings, SampleBudget};
use plume_volume::Volume;

pub(super) const EMISSION_ONLY: [(&str, Estimator); 4] = [
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

pub(super) fn grid_emission(convention: Convention) -> Emission {
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
pub(super) fn box_camera(edge: f64, size: u32) -> Result<Camera> {
    let distance = 100.0 * edge;
    let fov = 2.0 * (0.75 * edge / distance).atan().to_degrees();
    Camera::look_at(DVec3::new(0.0, 0.0, -distance), DVec3::ZERO, DVec3::Y, fov, size, size)
}

pub(super) fn render_image(
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
            adaptive: None,
            integrator,
        },
        &|_, _| {},
    );
    r.film.average()
}

/// Mean over RGB of the central third of the pixels: (mean, standard error of the mean).
pub(super) fn central(img: &[[f32; 4]], size: u32, channel: Option<usize>) -> (f64, f64) {
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
    let s = Spread::of(&v);
    (s.mean, s.std / (v.len() as f64).sqrt())
}

pub(super) fn all_finite(img: &[[f32; 4]]) -> bool {
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

pub(super) struct Check<'a> {
    /// The sweep's sizes.
    pub(super) cfg: &'a ExtremesConfig,
    /// The checks so far, in order.
    pub(super) rows: Vec<Row>,
}

impl Check<'_> {
    /// Compare the central mean of `img` with `expected` for a box of optical depth `depth`.
    #[allow(clippy::too_many_arguments)] // one per column of the row
    pub(super) fn closed_form(
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

    pub(super) fn push(&mut self, row: Row) {
        self.rows.push(row);
    }
}
