//! The cost sweep: what a sample costs as the density grows from 1e-6 to 1e6 times the
//! generated explosion's, for each method with its default tracking (and line-fnee under
//! null collisions throughout).
//!
//! **What is measured.** The explosion (albedo 0.8, so paths scatter) rendered on one
//! thread at each density scale `10^k`, `k = −6 … 6`. The renderer's own counters give
//! the walks (rays tracked: camera and scattered segments, shadow rays) and their work,
//! voxel steps plus null collisions' tentative points, each one read of the field.
//!
//! **Why per walk.** A sample's cost is (walks per sample) × (cost per walk). The first
//! factor is the light transport's: in a thin medium a camera ray passes through, in a
//! dense one a path scatters until roulette ends it, several walks each with its shadow
//! ray. The second is the tracking's, and it is what must not grow with density
//! (`medium::null_tracking`, "Dense stretches": a walk costs at most about its voxels).
//! Both are reported; the check is on work per walk.
//!
//! **Growth** of a series `c(s)` over increasing densities is `max_{s < s'} c(s')/c(s)`:
//! the largest rise from any density to a denser one (a walk that gets cheaper as the
//! medium thickens is not a growth). The check: work per walk grows by at most
//! [`MAX_GROWTH`]. Time per walk is reported beside it; it is a figure, not a check
//! (STYLE.md §8: timings are never asserted).

use std::fmt::Write as _;
use std::time::Instant;

use super::check::Check;
use super::rows::{CostPoint, ExtremesConfig, Row};
use crate::bench::numbers::num;
use plume_core::error::Result;
use plume_engine::camera::Camera;
use plume_engine::integrator::{Integrator, Lights, Scene, Tracking};
use plume_engine::medium::{Emission, Medium};
use plume_engine::render::{render, RenderSettings, SampleBudget};
use plume_scene::choice::TrackingChoice;
use plume_scene::SceneDescription;
use plume_volume::majorant::MajorantGrid;
use plume_volume::proxy::ProxyGrid;
use plume_volume::{Field, Volume};

/// The largest growth of work per walk across the density range the check allows.
pub const MAX_GROWTH: f64 = 2.0;

/// Density scales of the sweep: `10^k`, `k = −6 … 6`.
const DECADES: std::ops::RangeInclusive<i32> = -6..=6;

/// One series of the sweep: a method preset and the tracking it runs with.
struct Series {
    preset: &'static str,
    tracking: TrackingChoice,
    /// Whether the growth check applies (each preset with its default tracking), or the
    /// series is a figure beside them.
    checked: bool,
}

/// The presets with their default tracking, checked; and line-fnee forced to null
/// collisions on every segment, a figure: its thinnest walks cost a few majorant
/// stretches, a fifth of a regular walk, so its rise is measured from a floor no other
/// tracking has.
const SERIES: [Series; 5] = [
    Series { preset: "line-fnee", tracking: TrackingChoice::Auto, checked: true },
    Series { preset: "line-nee", tracking: TrackingChoice::Auto, checked: true },
    Series { preset: "point-nee", tracking: TrackingChoice::Auto, checked: true },
    Series { preset: "ray-march", tracking: TrackingChoice::Auto, checked: true },
    Series { preset: "line-fnee", tracking: TrackingChoice::Null, checked: false },
];

/// The largest rise of `series` (in order of increasing density) from any point to a
/// later one: `max_{i < j} c_j / c_i` (1 for a series that never rises).
#[must_use]
pub fn growth(series: &[f64]) -> f64 {
    let mut lowest = f64::INFINITY;
    let mut rise = 1.0f64;
    for &c in series {
        if lowest > 0.0 && lowest.is_finite() {
            rise = rise.max(c / lowest);
        }
        lowest = lowest.min(c);
    }
    rise
}

/// Render every method at every density scale; add one check row per method.
///
/// # Errors
/// Scene construction (not expected: every case is a valid scene).
pub(super) fn cost_sweep(cfg: &ExtremesConfig, check: &mut Check) -> Result<Vec<CostPoint>> {
    let ex = plume_synth::explosion(&plume_synth::ExplosionParams {
        resolution: cfg.explosion_resolution,
        seed: 3,
        ..Default::default()
    });
    let emission = Emission::blackbody(1.0);
    let mut volume = Volume::build(&ex.density, Some(&ex.temperature), |v| emission.map_source(v))?;
    let plume_volume::Bounds3 { lo, hi } = volume.world_bounds();
    let camera = Camera::frame_bounds(
        lo,
        hi,
        glam::DVec3::new(0.35, 0.25, 1.0),
        glam::DVec3::Y,
        40.0,
        cfg.size,
        cfg.size,
    )?;
    let majorants = MajorantGrid::new(&volume, 0.0);
    let mut points = Vec::new();
    for Series { preset: name, tracking, checked } in SERIES {
        let spec = crate::bench::spec::parse_methods(name, 4.0)?.remove(0);
        let mut description = SceneDescription::new("explosion");
        description.medium.albedo = Some(0.8.into());
        description.integrator.tracking = tracking;
        let integrator =
            Integrator::for_scene_with(&description, spec.estimator, spec.light_sampling);
        let lights = Lights::build(
            &volume,
            &emission,
            spec.light_sampling,
            ProxyGrid::resolution_for(&volume, None),
        )?;
        let mut scene = Scene {
            field: volume,
            medium: Medium {
                sigma_t: 1.0,
                albedo: plume_core::color::Rgb::splat(0.8),
                g: 0.0,
                emission,
                extinction: Default::default(),
            },
            camera,
            lights,
            motion: None,
            majorants: (integrator.tracking != Tracking::Regular).then(|| majorants.clone()),
        };
        let mut series = Vec::new();
        for k in DECADES {
            scene.medium.sigma_t = 10f64.powi(k);
            let start = Instant::now();
            let r = render(
                &scene,
                &RenderSettings {
                    budget: SampleBudget::Spp(cfg.spp),
                    seed: 5,
                    sampler: plume_core::sampling::SamplerKind::default(),
                    threads: 1,
                    first_sample: 0,
                    adaptive: None,
                    integrator,
                },
                &|_, _| {},
            );
            let c = r.counters;
            series.push(CostPoint {
                method: name.into(),
                tracking: tracking_name(integrator.tracking).into(),
                density_scale: scene.medium.sigma_t,
                samples: c.samples,
                walks: c.walks,
                voxel_steps: c.voxel_steps,
                tentative_points: c.tentative_points,
                collisions: c.collisions,
                seconds: start.elapsed().as_secs_f64(),
            });
        }
        check.push(growth_row(&series, checked));
        points.extend(series);
        volume = scene.field;
    }
    Ok(points)
}

fn tracking_name(t: Tracking) -> &'static str {
    match t {
        Tracking::Regular => "regular",
        Tracking::Mixed => "mixed",
        Tracking::Null => "null",
    }
}

/// The check of one method's series: work per walk grows by at most [`MAX_GROWTH`]
/// (passes whatever the growth when not `checked`: a figure).
fn growth_row(series: &[CostPoint], checked: bool) -> Row {
    let work: Vec<f64> = series.iter().map(CostPoint::work_per_walk).collect();
    let time: Vec<f64> = series.iter().map(CostPoint::micros_per_walk).collect();
    let per_sample: Vec<f64> = series.iter().map(CostPoint::micros_per_sample).collect();
    let g = growth(&work);
    let finite = work.iter().all(|w| w.is_finite());
    Row {
        sweep: "cost".into(),
        case: "density scale 1e-6 … 1e6".into(),
        method: series[0].label(),
        expected: None,
        measured: g,
        error: g,
        tolerance: MAX_GROWTH,
        finite,
        pass: finite && (g <= MAX_GROWTH || !checked),
        note: format!(
            "{}growth of work per walk (voxel steps + tentative points); time per walk grew {}×, per sample {}×",
            if checked { "" } else { "figure, not checked: " },
            num(growth(&time)),
            num(growth(&per_sample))
        ),
    }
}

/// One figure of a render, as the table shows it.
type Figure = fn(&CostPoint) -> f64;

/// The sweep as Markdown: per method and density scale, time and work per walk and
/// walks per sample.
#[must_use]
pub fn cost_table(points: &[CostPoint]) -> String {
    let mut s = String::new();
    let _ = write!(s, "| method | value |");
    for k in DECADES {
        let _ = write!(s, " 1e{k} |");
    }
    let _ = writeln!(s, " growth |");
    let _ = writeln!(s, "|---|---|{}---|", "---|".repeat(DECADES.count()));
    let rows: [(&str, Figure); 4] = [
        ("µs per walk", CostPoint::micros_per_walk),
        ("work per walk", CostPoint::work_per_walk),
        ("walks per sample", CostPoint::walks_per_sample),
        ("µs per sample", CostPoint::micros_per_sample),
    ];
    for method in points.chunks(DECADES.count()) {
        for (what, value) in rows {
            let values: Vec<f64> = method.iter().map(value).collect();
            let _ = write!(s, "| {} | {what} |", method[0].label());
            for v in &values {
                let _ = write!(s, " {} |", num(*v));
            }
            let _ = writeln!(s, " {}× |", num(growth(&values)));
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::growth;

    #[test]
    fn growth_is_the_largest_rise_to_a_denser_point() {
        assert_eq!(growth(&[3.0, 2.0, 1.0]), 1.0);
        assert_eq!(growth(&[1.0, 3.0, 2.0]), 3.0);
        assert_eq!(growth(&[4.0, 1.0, 3.0, 2.0]), 3.0);
        assert_eq!(growth(&[2.0]), 1.0);
    }
}
