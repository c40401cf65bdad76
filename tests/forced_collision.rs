//! Forced collisions on the ray-marched camera segment (`medium::forced`): the weighted
//! collision has the analog law (`E[w · 1{t ∈ bin}] = τ(a) − τ(b)` for every bin), on
//! nearest and trilinear fields, thin to dense; the collision probability is the boosted
//! one; and images keep their means when the camera's collision is forced. Fixed seeds,
//! k·σ tolerances.

use crate::common;

use common::{explosion_scene, explosion_volume, region_means_with};
use glam::DVec3;
use plume_core::sampling::{Sampler, SamplerKind};
use plume_engine::integrator::{Integrator, LightSampling, Lights, MisHeuristic, Tracking};
use plume_engine::medium::forced::BOOST;
use plume_engine::medium::tracking::optical_depth;
use plume_engine::medium::{track, Collision, DistanceSample, Estimator, Medium};
use plume_volume::field::{Constant, Ray};
use plume_volume::trilinear::Trilinear;
use plume_volume::{Field, Interpolation, Volume};

/// A ray through the volume, slightly off its axes, and the range it crosses (the world
/// box of the index bounds, grown by a voxel for the trilinear support).
fn crossing(volume: &Volume) -> (Ray, f64, f64) {
    let b = volume.index_bounds();
    let xf = volume.world_from_index();
    let (lo, hi) = (xf.transform_point3(b.lo - 1.0), xf.transform_point3(b.hi + 1.0));
    let centre = 0.5 * (lo + hi);
    let direction = DVec3::new(1.0, 0.21, -0.13).normalize();
    let reach = (hi - lo).length();
    (Ray { origin: centre - direction * reach, direction }, 0.0, 2.0 * reach)
}

/// Weighted collision mass per bin of `[t0, t1]` over `n` forced walks, with standard
/// errors, the fraction of walks that collided, and the exact `τ(a) − τ(b)` per bin (bins
/// pooled as below).
fn masses<F: Field>(
    field: &F,
    medium: &Medium,
    ray: &Ray,
    (t0, t1): (f64, f64),
    bins: usize,
    n: u64,
    seed: u64,
) -> (Vec<(f64, f64)>, f64, Vec<f64>) {
    let (mut sum, mut sum_sq) = (vec![0.0f64; bins], vec![0.0f64; bins]);
    let mut collided = 0u64;
    for i in 0..n {
        let mut sampler = Sampler::new(seed, 0, i);
        let u = sampler.next_f64();
        let r = track(
            field,
            medium,
            ray,
            f64::INFINITY,
            Estimator::RayMarch,
            Collision::Forced,
            u,
            &mut sampler,
        );
        if let DistanceSample::Collided { t, .. } = r.event {
            collided += 1;
            assert!(
                r.collision_weight > 0.0 && r.collision_weight.is_finite(),
                "weight {}",
                r.collision_weight
            );
            let k = (((t - t0) / (t1 - t0)) * bins as f64).clamp(0.0, bins as f64 - 1.0) as usize;
            sum[k] += r.collision_weight;
            sum_sq[k] += r.collision_weight * r.collision_weight;
        } else {
            assert_eq!(
                r.collision_weight, 1.0,
                "a walk without a collision has no collision weight"
            );
        }
    }
    let tau = |t: f64| (-optical_depth(field, medium, ray, t, f64::INFINITY).optical_depth).exp();
    let edges: Vec<f64> =
        (0..=bins).map(|k| tau(t0 + (t1 - t0) * k as f64 / bins as f64)).collect();
    // Bins pooled with their successors until they expect a mass of 10⁻³ (hundreds of
    // hits in `n` walks, fewer where roulette's weights are large); a sample lands in one
    // bin only, so pooled sums of squares stay exact
    let mut pooled: Vec<(f64, f64, f64)> = Vec::new();
    let mut open = (0.0, 0.0, 0.0);
    for (k, w) in edges.windows(2).enumerate() {
        open = (open.0 + sum[k], open.1 + sum_sq[k], open.2 + (w[0] - w[1]));
        if open.2 >= 1e-3 || open.2 == 0.0 {
            pooled.push(std::mem::take(&mut open));
        }
    }
    if open.2 > 0.0 {
        match pooled.last_mut() {
            Some(last) => *last = (last.0 + open.0, last.1 + open.1, last.2 + open.2),
            None => pooled.push(open),
        }
    }
    let nf = n as f64;
    let got = pooled
        .iter()
        .map(|(s, s2, _)| (s / nf, ((s2 / nf - (s / nf).powi(2)).max(0.0) / nf).sqrt()))
        .collect();
    (got, collided as f64 / nf, pooled.iter().map(|p| p.2).collect())
}

#[test]
fn forced_collisions_have_the_analog_law_on_nearest_and_trilinear_fields() {
    // 2 fields × 3 densities × 24 bins = 144 comparisons; Šidák at α = 0.01 gives
    // |z| < 4.3. A bin's standard error comes from its own weights; bins with no expected
    // mass must receive none.
    let volume = explosion_volume();
    let (ray, t0, t1) = crossing(&volume);
    let emission = common::explosion_emission();
    let unit = Medium {
        sigma_t: 1.0,
        albedo: plume_core::color::Rgb::splat(0.8),
        g: 0.0,
        emission,
        extinction: Default::default(),
    };
    let trilinear = Trilinear::new(explosion_volume());
    for (name, field) in
        [("nearest", &volume as &dyn FieldRef), ("trilinear", &trilinear as &dyn FieldRef)]
    {
        let od = field.od(&unit, &ray, t1);
        assert!(od > 0.0, "{name}: the ray misses the volume");
        // Total optical depths 0.05 (thin: 1 − τ ≈ 0.05, so the boost shows), 1, and 9
        // (τ ≈ 1e-4: ray-march's roulette plays, and its weights reach the masses)
        for target in [0.05, 1.0, 9.0] {
            let medium = Medium { sigma_t: target / od, ..unit };
            let (got, collided, expected) = field.masses(&medium, &ray, (t0, t1), 24, 40_000, 11);
            for (k, ((m, se), e)) in got.iter().zip(&expected).enumerate() {
                if *e <= 0.0 {
                    assert_eq!(
                        *m, 0.0,
                        "{name} OD {target} bin {k}: mass {m} where τ does not fall"
                    );
                    continue;
                }
                let z = (m - e) / se.max(1e-15);
                assert!(z.abs() < 4.3, "{name} OD {target} bin {k}: weighted mass {m} ± {se} vs exact {e} (z = {z:.2})");
            }
            let w: f64 = expected.iter().sum();
            let q = (BOOST * w).min(1.0);
            if target < 5.0 {
                // No roulette: W is exact, and the walk collides with probability min(1, K W)
                let se = (q * (1.0 - q) / 40_000.0).sqrt().max(1e-9);
                assert!(
                    (collided - q).abs() < 4.3 * se + 1e-12,
                    "{name} OD {target}: collided {collided}, expected {q} (analog {w})"
                );
            }
            if target < 0.1 {
                assert!(
                    collided > 2.0 * w,
                    "{name} OD {target}: forcing collided {collided}, no more than the analog {w}"
                );
            }
        }
    }
}

/// The two fields behind one interface for the test's loop.
trait FieldRef {
    fn od(&self, medium: &Medium, ray: &Ray, t: f64) -> f64;
    fn masses(
        &self,
        medium: &Medium,
        ray: &Ray,
        range: (f64, f64),
        bins: usize,
        n: u64,
        seed: u64,
    ) -> (Vec<(f64, f64)>, f64, Vec<f64>);
}

impl<F: Field> FieldRef for F {
    fn od(&self, medium: &Medium, ray: &Ray, t: f64) -> f64 {
        optical_depth(self, medium, ray, t, f64::INFINITY).optical_depth
    }
    fn masses(
        &self,
        medium: &Medium,
        ray: &Ray,
        range: (f64, f64),
        bins: usize,
        n: u64,
        seed: u64,
    ) -> (Vec<(f64, f64)>, f64, Vec<f64>) {
        masses(self, medium, ray, range, bins, n, seed)
    }
}

#[test]
fn forced_collisions_have_the_analog_law_within_one_dense_piece() {
    // A homogeneous box is one piece: the position within a piece (the truncated
    // exponential) is all there is to get right. Optical depth 3 (τ = 0.05, no roulette):
    // 24 bins, |z| < 3.9 (Šidák at α = 0.01 over 24)
    let field =
        Constant { lo: DVec3::ZERO, hi: DVec3::new(2.0, 1.0, 1.0), density: 1.5, source: 1.0 };
    let medium = Medium {
        sigma_t: 1.0,
        albedo: plume_core::color::Rgb::splat(0.8),
        g: 0.0,
        emission: common::explosion_emission(),
        extinction: Default::default(),
    };
    let ray = Ray { origin: DVec3::new(-1.0, 0.5, 0.5), direction: DVec3::X };
    let (got, collided, expected) = masses(&field, &medium, &ray, (1.0, 3.0), 24, 40_000, 12);
    assert_eq!(got.len(), 24, "no bin was pooled");
    for (k, ((m, se), e)) in got.iter().zip(&expected).enumerate() {
        let z = (m - e) / se.max(1e-15);
        assert!(z.abs() < 3.9, "bin {k}: weighted mass {m} ± {se} vs exact {e} (z = {z:.2})");
    }
    assert_eq!(collided, 1.0, "1 − τ = 0.95 > 1/K: every walk collides");
}

#[test]
fn analog_and_skipped_collisions_are_unchanged_by_the_forced_walk() {
    // The same numbers: an analog walk and a skipped one return the emission and
    // transmittance a forced walk returns (forcing only adds the collision), and the
    // analog collision has weight 1
    let volume = explosion_volume();
    let (ray, _, t1) = crossing(&volume);
    let unit = Medium {
        sigma_t: 1.0,
        albedo: plume_core::color::Rgb::splat(0.8),
        g: 0.0,
        emission: common::explosion_emission(),
        extinction: Default::default(),
    };
    let medium = Medium {
        sigma_t: 1.0 / optical_depth(&volume, &unit, &ray, t1, f64::INFINITY).optical_depth,
        ..unit
    };
    for i in 0..200 {
        let run = |collision| {
            let mut sampler = Sampler::new(5, 0, i);
            let u = sampler.next_f64();
            track(
                &volume,
                &medium,
                &ray,
                f64::INFINITY,
                Estimator::RayMarch,
                collision,
                u,
                &mut sampler,
            )
        };
        let (forced, analog, skip) =
            (run(Collision::Forced), run(Collision::Analog), run(Collision::Skip));
        assert_eq!(forced.emission, skip.emission);
        assert_eq!(forced.transmittance, skip.transmittance);
        assert_eq!(analog.emission, skip.emission);
        assert_eq!(analog.collision_weight, 1.0);
        assert_eq!(skip.event, DistanceSample::Escaped);
    }
}

#[test]
fn forced_camera_collisions_give_the_same_image_means() {
    // Only how the camera ray's collision is drawn changes, so every region's mean must
    // stay: thin and dense, both reconstructions, the paper's method, MIS in volume
    // measure and forward paths, split as the defaults: 2 × 2 × 3 × 5 regions = 60
    // comparisons, |z| < 4.2 (Šidák at α = 0.01)
    for (interpolation, sigma_t) in [Interpolation::Nearest, Interpolation::Linear]
        .into_iter()
        .flat_map(|i| [(i, 1.5), (i, 25.0)])
    {
        for (est, ls) in [
            (Estimator::Line, LightSampling::Fnee),
            (Estimator::Point, LightSampling::Nee),
            (Estimator::Line, LightSampling::None),
        ] {
            let scene = explosion_scene(sigma_t, interpolation, false, |vol, e| {
                Lights::build(vol, e, ls, 8).unwrap()
            });
            let analog = Integrator {
                estimator: est,
                camera_estimator: Some(Estimator::RayMarch),
                light_sampling: ls,
                mis: MisHeuristic::Power,
                max_depth: 64,
                tracking: Tracking::Regular,
                split: 4,
                camera_collision: Collision::Analog,
                point_lookup: plume_engine::integrator::PointLookup::Exact,
                split_by: plume_engine::integrator::SplitBy::Uniform,
            };
            let forced = Integrator { camera_collision: Collision::Forced, ..analog };
            let reference = region_means_with(SamplerKind::Sobol, &scene, analog, 8, 12, 900);
            let got = region_means_with(SamplerKind::Sobol, &scene, forced, 8, 12, 900);
            assert_ne!(got, reference, "forcing the camera collision changed nothing");
            common::assert_same_means(
                &format!("{interpolation} σ_t={sigma_t} {est:?}/{ls:?}, forced vs analog"),
                &got,
                &reference,
                4.2,
            );
        }
    }
}

#[test]
fn where_paths_scatter_the_camera_is_ray_marched_and_its_collision_forced_by_default() {
    use plume_scene::{CameraCollision, SceneDescription};
    let mut scene = SceneDescription::new("x.vdb");
    // No scattering: the camera segment keeps the estimator, no collision is forced
    let ea = plume_engine::integrator::Integrator::for_scene(&scene);
    assert_eq!(ea.camera_estimator(), ea.estimator);
    scene.medium.albedo = Some(0.8.into());
    let scattering = plume_engine::integrator::Integrator::for_scene(&scene);
    assert_eq!(scattering.camera_estimator(), Estimator::RayMarch);
    assert_eq!(scattering.camera_collision, Collision::Forced);
    assert_eq!(
        scattering.estimator,
        Estimator::Line,
        "the other segments keep the method's estimator"
    );
    scene.integrator.camera_collision = CameraCollision::Analog;
    assert_eq!(
        plume_engine::integrator::Integrator::for_scene(&scene).camera_collision,
        Collision::Analog
    );
    scene.integrator.camera_estimator = Some(plume_scene::EstimatorKind::Line);
    assert_eq!(
        plume_engine::integrator::Integrator::for_scene(&scene).camera_estimator(),
        Estimator::Line,
        "an asked camera estimator wins"
    );
}

#[test]
fn camera_collision_is_a_flag_a_scene_key_and_part_of_the_settings_hash() {
    use common::{exr_pixels, plume, s, tmpdir};
    let dir = tmpdir("forced", "cli");
    let vdb = common::explosion(&dir, 32, Some(3));
    let base = [
        "render",
        s(&vdb),
        "--width",
        "24",
        "--height",
        "16",
        "--spp",
        "4",
        "--albedo",
        "0.8",
        "--stats",
    ];
    let hashes = common::settings_hashes(
        &dir,
        &base,
        "--camera-collision",
        &[("forced", Some("forced")), ("analog", Some("analog")), ("default", None)],
    );
    assert_eq!(
        exr_pixels(&dir.join("default.exr")),
        exr_pixels(&dir.join("forced.exr")),
        "forced is the default"
    );
    assert_ne!(exr_pixels(&dir.join("analog.exr")), exr_pixels(&dir.join("forced.exr")));
    assert_eq!(hashes[0], hashes[2]);
    assert_ne!(hashes[0], hashes[1], "the camera collision is not in the settings hash");
    // A scene file's key renders what the flag renders
    let scene_file = dir.join("scene.toml");
    let text =
        format!("[volume]\nfile = {:?}\n[integrator]\ncamera_collision = \"analog\"\n[medium]\nalbedo = 0.8\n[camera]\nwidth = 24\nheight = 16\n", s(&vdb));
    std::fs::write(&scene_file, text).unwrap();
    let out = dir.join("file.exr");
    let o = plume(&["render", s(&scene_file), "--spp", "4", "-o", s(&out)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(exr_pixels(&out), exr_pixels(&dir.join("analog.exr")));
    // A misspelt value names the flag and the choices
    let o = plume(&[
        "render",
        s(&vdb),
        "--camera-collision",
        "sometimes",
        "-o",
        s(&dir.join("bad.exr")),
    ]);
    assert!(!o.status.success());
    let err = common::stderr(&o);
    assert!(
        err.contains("--camera-collision") && err.contains("forced") && err.contains("analog"),
        "{err}"
    );
}
