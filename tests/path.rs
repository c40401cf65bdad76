//! Path-integrator tier (METHOD.md §5–8, §11.2): equilibrium radiance of an infinite
//! emitting, scattering medium; a white furnace; every method/estimator combination gives
//! the same image means on thin and dense explosions; the FNEE proxy resolution changes
//! variance only; extremes stay finite. Fixed seeds; k·σ tolerances from independent runs.

use crate::common;

use common::{
    assert_same_means, explosion_emission, grid_emission, mean_stderr, mean_stderr_from_sums,
    region_means_with,
};
use glam::{DAffine3, DMat3, DVec3, IVec3};
use plume::vdb::{FloatGrid, LEAF_VOXELS};
use plume_core::color::Rgb;
use plume_core::sampling::phase::sample_uniform_sphere;
use plume_core::sampling::Sampler;
use plume_core::sampling::SamplerKind;
use plume_engine::camera::Camera;
use plume_engine::integrator::{
    AnyScene, Counters, Integrator, LightSampling, Lights, MisHeuristic, NoTrace, Scene, Tracking,
};
use plume_engine::light::external::{Environment, ExternalLights, Light, Radiance};
use plume_engine::medium::{Collision, Convention, Emission, EmissionKind, Estimator, Medium};
use plume_engine::render::{render, RenderSettings, SampleBudget};
use plume_synth::{explosion, ExplosionParams};
use plume_volume::field::Ray;
use plume_volume::{Interpolation, Volume};

/// A constant cube of `8n` voxels a side spanning `[0, size]³` metres.
fn cube(n: i32, size: f64, density: f32, source: f32) -> Volume {
    let xf = DAffine3::from_mat3_translation(
        DMat3::from_diagonal(DVec3::splat(size / f64::from(8 * n))),
        DVec3::splat(size / f64::from(16 * n)),
    );
    let origins: Vec<IVec3> =
        (0..n * n * n).map(|i| IVec3::new(i % n, (i / n) % n, i / (n * n)) * 8).collect();
    let g = |name: &str, v: f32| FloatGrid {
        name: name.into(),
        world_from_index: xf,
        background: 0.0,
        origins: origins.clone(),
        values: vec![v; origins.len() * LEAF_VOXELS],
    };
    let e = grid_emission(Convention::Cycles);
    Volume::build(&g("density", density), Some(&g("emission", source)), |v| e.map_source(v))
        .unwrap()
}

fn integrator(
    estimator: Estimator,
    light_sampling: LightSampling,
    mis: MisHeuristic,
    max_depth: u32,
) -> Integrator {
    Integrator {
        estimator,
        camera_estimator: None,
        light_sampling,
        mis,
        max_depth,
        tracking: Tracking::Regular,
        split: 1,
        camera_collision: Collision::Analog,
        point_lookup: plume_engine::integrator::PointLookup::Exact,
        split_by: plume_engine::integrator::SplitBy::Uniform,
    }
}

/// Every estimator × light strategy.
const COMBOS: [(Estimator, LightSampling); 12] = [
    (Estimator::Line, LightSampling::None),
    (Estimator::Point, LightSampling::None),
    (Estimator::RayMarch, LightSampling::None),
    (Estimator::Blend { kappa: 4.0 }, LightSampling::None),
    (Estimator::Point, LightSampling::Nee),
    (Estimator::Line, LightSampling::Nee),
    (Estimator::RayMarch, LightSampling::Nee),
    (Estimator::Blend { kappa: 4.0 }, LightSampling::Nee),
    (Estimator::Line, LightSampling::Fnee),
    (Estimator::Point, LightSampling::Fnee),
    (Estimator::RayMarch, LightSampling::Fnee),
    (Estimator::Blend { kappa: 4.0 }, LightSampling::Fnee),
];

/// Mean and standard error of the red channel from a point inside, over random directions.
/// The standard error comes from the samples' own spread, which needs independent samples:
/// the `random` stream (`Sampler::new`), not Sobol points.
fn mean_from_inside(
    scene: &Scene<Volume>,
    integ: &Integrator,
    origin: DVec3,
    n: u64,
    seed: u64,
) -> (f64, f64) {
    let (mut s, mut s2) = (0.0, 0.0);
    let mut c = Counters::default();
    for i in 0..n {
        let mut sampler = Sampler::new(seed, 1, i);
        let dir = sample_uniform_sphere([sampler.next_f64(), sampler.next_f64()]);
        let l =
            integ.li(scene, &Ray { origin, direction: dir }, &mut sampler, &mut c, &mut NoTrace)[0];
        s += l;
        s2 += l * l;
    }
    mean_stderr_from_sums(s, s2, n)
}

#[test]
fn infinite_medium_reaches_equilibrium_radiance_with_every_method() {
    // μ_t = 40 /m, a = 0.8, L_e = 2: L = L_e/μ_a = 0.25 from the centre of a 2 m cube
    // (μ_t R = 40, escape odds e^-40). With at most n bounces: L_n = L_e/μ_a (1 − a^{n+1}).
    let (sigma_t, albedo, le) = (40.0, 0.8f32, 2.0f32);
    let vol = cube(4, 2.0, 1.0, le);
    let e = grid_emission(Convention::Cycles);
    let mu_a = sigma_t * f64::from(1.0 - albedo);
    for (est, ls) in COMBOS {
        let lights = Lights::build(&vol, &e, ls, 8).unwrap();
        let cam = Camera::look_at(DVec3::ZERO, DVec3::ONE, DVec3::Y, 40.0, 1, 1).unwrap();
        let scene = Scene {
            field: cube(4, 2.0, 1.0, le),
            medium: Medium {
                sigma_t,
                albedo: plume_core::color::Rgb::splat(albedo),
                g: 0.3,
                emission: e,
                extinction: Default::default(),
            },
            camera: cam,
            lights,
            motion: None,
            majorants: None,
        };
        for (max_depth, expected) in
            [(10_000u32, f64::from(le) / mu_a), (2, f64::from(le) / mu_a * (1.0 - 0.8f64.powi(3)))]
        {
            let integ = integrator(est, ls, MisHeuristic::Power, max_depth);
            let (m, se) = mean_from_inside(&scene, &integ, DVec3::ONE, 3000, 11);
            assert!(
                (m - expected).abs() < 4.0 * se + 2e-3 * expected,
                "{est:?}/{ls:?} depth {max_depth}: {m} ± {se} vs {expected}"
            );
        }
    }
}

#[test]
fn white_furnace_with_albedo_one_renders_the_environment() {
    // Albedo 1, unit environment, no emission: radiance 1 everywhere. The environment is
    // an external light, sampled at every vertex and MIS-weighted against phase sampling,
    // so a path's value is 1 only in expectation: compare the image mean with 4σ from the
    // spread of the pixels (each pixel has its own Sobol scramble, so pixels are
    // independent).
    let e = Emission { kind: EmissionKind::None, ..grid_emission(Convention::Cycles) };
    let cam =
        Camera::look_at(DVec3::new(1.0, 1.0, -3.0), DVec3::ONE, DVec3::Y, 50.0, 8, 8).unwrap();
    for est in [Estimator::Line, Estimator::Point, Estimator::RayMarch] {
        for ls in [LightSampling::None, LightSampling::Fnee, LightSampling::Nee] {
            let vol = cube(2, 2.0, 1.0, 0.0);
            let mut lights = Lights::build(&vol, &e, ls, 8).unwrap();
            let env = Environment::new(Radiance::Constant(Rgb::ONE), 1.0, DVec3::Y, 0.0, true);
            lights.external = ExternalLights::new(vec![Light::Environment(env)], 2.0);
            let scene = Scene {
                field: vol,
                medium: Medium {
                    sigma_t: 2.0,
                    albedo: plume_core::color::Rgb::splat(1.0),
                    g: 0.5,
                    emission: e,
                    extinction: Default::default(),
                },
                camera: cam,
                lights,
                motion: None,
                majorants: None,
            };
            let integ = integrator(est, ls, MisHeuristic::Power, 100_000);
            let r = render(
                &scene,
                &RenderSettings {
                    budget: SampleBudget::Spp(32),
                    seed: 3,
                    sampler: SamplerKind::Sobol,
                    threads: 0,
                    first_sample: 0,
                    adaptive: None,
                    integrator: integ,
                },
                &|_, _| {},
            );
            let px: Vec<f64> = r.film.average().iter().map(|p| f64::from(p[0])).collect();
            let (mean, se) = mean_stderr(&px);
            assert!(
                (mean - 1.0).abs() < 4.0 * se + 1e-6,
                "{est:?}/{ls:?}: furnace mean {mean} ± {se}"
            );
            assert!(se < 0.02, "{est:?}/{ls:?}: furnace spread {se} is too large for a furnace");
        }
    }
}

/// [`common::region_means_with`] with Sobol points.
fn region_means(
    scene: &AnyScene,
    integ: Integrator,
    spp: u32,
    runs: u64,
    seed0: u64,
) -> Vec<(f64, f64)> {
    region_means_with(SamplerKind::Sobol, scene, integ, spp, runs, seed0)
}

fn explosion_scene(
    sigma_t: f64,
    ls: LightSampling,
    proxy_resolution: u32,
    interpolation: Interpolation,
) -> AnyScene {
    common::explosion_scene(sigma_t, interpolation, false, |vol, e| {
        Lights::build(vol, e, ls, proxy_resolution).unwrap()
    })
}

#[test]
fn every_method_gives_the_same_image_means_on_thin_and_dense_explosions() {
    // Reference: forward-only line integration with many runs, per reconstruction (nearest
    // and trilinear are different volumes). 2 reconstructions × 2 densities × ≈ 10 combos
    // × 5 regions ≈ 200 comparisons; Šidák at α = 0.01 gives |z| < 4.1 per test; we use 4.2.
    for (interpolation, sigma_t) in [Interpolation::Nearest, Interpolation::Linear]
        .into_iter()
        .flat_map(|i| [(i, 1.5), (i, 25.0)])
    {
        let reference = region_means(
            &explosion_scene(sigma_t, LightSampling::None, 8, interpolation),
            integrator(Estimator::Line, LightSampling::None, MisHeuristic::Power, 64),
            16,
            24,
            1000,
        );
        assert!(reference[0].0 > 0.0);
        for (est, ls) in COMBOS {
            // Line + classic NEE has no MIS partner, so NEE from vertices inside dense
            // emitters keeps its 1/r² singularity: finite mean, infinite variance (tail
            // index 3/2), and a run mean that converges like n^(−1/3), so a k·σ test is
            // meaningless there (METHOD §6, the paper's conclusion table). It is tested
            // thin here and in the equilibrium test above.
            if sigma_t > 10.0 && ls == LightSampling::Nee && est != Estimator::Point {
                continue;
            }
            for mis in [MisHeuristic::Power, MisHeuristic::Balance] {
                if mis == MisHeuristic::Balance && ls != LightSampling::Fnee {
                    continue;
                }
                let scene = explosion_scene(sigma_t, ls, 8, interpolation);
                let got = region_means(&scene, integrator(est, ls, mis, 64), 8, 12, 7);
                assert_same_means(
                    &format!("{interpolation} σ_t={sigma_t} {est:?}/{ls:?}/{mis:?}"),
                    &got,
                    &reference,
                    4.2,
                );
            }
        }
    }
}

#[test]
fn sobol_and_random_samplers_converge_to_the_same_means() {
    // Thin and dense, nearest and trilinear, line-fnee and ray-march (the one-point rule's
    // Sobol draw): 2 × 2 × 2 × 5 regions = 40 comparisons, |z| < 4.2 as above
    for (interpolation, sigma_t) in [Interpolation::Nearest, Interpolation::Linear]
        .into_iter()
        .flat_map(|i| [(i, 1.5), (i, 25.0)])
    {
        for (est, ls) in
            [(Estimator::Line, LightSampling::Fnee), (Estimator::RayMarch, LightSampling::None)]
        {
            let scene = explosion_scene(sigma_t, ls, 8, interpolation);
            let integ = integrator(est, ls, MisHeuristic::Power, 64);
            let sobol = region_means_with(SamplerKind::Sobol, &scene, integ, 8, 12, 300);
            let random = region_means_with(SamplerKind::Random, &scene, integ, 8, 12, 400);
            assert_same_means(
                &format!("{interpolation} σ_t={sigma_t} {est:?}/{ls:?}, sobol vs random"),
                &sobol,
                &random,
                4.2,
            );
        }
    }
}

#[test]
fn splitting_changes_variance_not_the_mean() {
    // 4 paths per camera collision against 1, thin and dense, both reconstructions, the
    // paper's method, MIS in volume measure, forward paths, and ray-march with FNEE:
    // 2 × 2 × 4 × 5 regions = 80 comparisons, |z| < 4.2 as above
    for (interpolation, sigma_t) in [Interpolation::Nearest, Interpolation::Linear]
        .into_iter()
        .flat_map(|i| [(i, 1.5), (i, 25.0)])
    {
        for (est, ls) in [
            (Estimator::Line, LightSampling::Fnee),
            (Estimator::Point, LightSampling::Nee),
            (Estimator::Line, LightSampling::None),
            (Estimator::RayMarch, LightSampling::Fnee),
        ] {
            let scene = explosion_scene(sigma_t, ls, 8, interpolation);
            let one = integrator(est, ls, MisHeuristic::Power, 64);
            let split = Integrator { split: 4, ..one };
            let reference = region_means(&scene, one, 8, 12, 500);
            let got = region_means(&scene, split, 8, 12, 600);
            assert_same_means(
                &format!("{interpolation} σ_t={sigma_t} {est:?}/{ls:?}, split 4 vs 1"),
                &got,
                &reference,
                4.2,
            );
        }
    }
}

#[test]
fn a_ray_marched_camera_segment_gives_the_same_means() {
    // `--camera-estimator ray-march`: only the camera segment's estimator changes (its
    // emission is then exact along each ray), so every region's mean must stay; with
    // splitting, as the demo renders. 2 reconstructions × 2 densities × 3 combos × 5
    // regions = 60 comparisons, |z| < 4.2 as above.
    for (interpolation, sigma_t) in [Interpolation::Nearest, Interpolation::Linear]
        .into_iter()
        .flat_map(|i| [(i, 1.5), (i, 25.0)])
    {
        for (est, ls) in [
            (Estimator::Line, LightSampling::Fnee),
            (Estimator::Point, LightSampling::Nee),
            (Estimator::Line, LightSampling::None),
        ] {
            let scene = explosion_scene(sigma_t, ls, 8, interpolation);
            let one = Integrator { split: 4, ..integrator(est, ls, MisHeuristic::Power, 64) };
            let marched = Integrator { camera_estimator: Some(Estimator::RayMarch), ..one };
            assert_eq!(marched.camera_estimator(), Estimator::RayMarch);
            // The same numbers for both (correlated runs only make |z| smaller), so the
            // runs differ by the camera estimator alone and must differ
            let reference = region_means(&scene, one, 8, 12, 700);
            let got = region_means(&scene, marched, 8, 12, 700);
            assert_ne!(got, reference, "the camera estimator changed nothing");
            assert_same_means(
                &format!("{interpolation} σ_t={sigma_t} {est:?}/{ls:?}, ray-marched camera vs not"),
                &got,
                &reference,
                4.2,
            );
        }
    }
}

#[test]
fn splitting_divides_the_variance_of_the_paths() {
    // From inside the uniform infinite medium of the equilibrium test, ray-march gives
    // every direction the same camera-segment emission, so all variance is the scattered
    // paths': n independent paths per collision divide it by n. Variances from 4000
    // samples each are within ±10 % at 4σ; the bound leaves room for that. A split that did
    // nothing, or gave its paths the same numbers, keeps the ratio at 1.
    let (sigma_t, albedo, le) = (40.0, 0.8f32, 2.0f32);
    let e = grid_emission(Convention::Cycles);
    let vol = cube(4, 2.0, 1.0, le);
    let lights = Lights::build(&vol, &e, LightSampling::Fnee, 8).unwrap();
    let cam = Camera::look_at(DVec3::ZERO, DVec3::ONE, DVec3::Y, 40.0, 1, 1).unwrap();
    let scene = Scene {
        field: vol,
        medium: Medium {
            sigma_t,
            albedo: plume_core::color::Rgb::splat(albedo),
            g: 0.3,
            emission: e,
            extinction: Default::default(),
        },
        camera: cam,
        lights,
        motion: None,
        majorants: None,
    };
    let expected = f64::from(le) / (sigma_t * f64::from(1.0 - albedo));
    let one = integrator(Estimator::RayMarch, LightSampling::Fnee, MisHeuristic::Power, 10_000);
    let n = 4000;
    let (m1, se1) = mean_from_inside(&scene, &one, DVec3::ONE, n, 21);
    for split in [4u32, 16] {
        let (m, se) = mean_from_inside(&scene, &Integrator { split, ..one }, DVec3::ONE, n, 22);
        assert!(
            (m - expected).abs() < 4.0 * se + 2e-3 * expected,
            "split {split}: {m} ± {se} vs {expected}"
        );
        let ratio = (se / se1).powi(2);
        assert!(
            ratio < 1.5 / f64::from(split),
            "split {split}: variance ratio {ratio} (expected about 1/{split})"
        );
    }
    assert!(
        (m1 - expected).abs() < 4.0 * se1 + 2e-3 * expected,
        "split 1: {m1} ± {se1} vs {expected}"
    );
}

#[test]
fn proxy_resolution_changes_variance_not_the_mean() {
    let integ = integrator(Estimator::Line, LightSampling::Fnee, MisHeuristic::Power, 64);
    let results: Vec<_> = [8u32, 16, 32]
        .iter()
        .map(|&r| {
            region_means(
                &explosion_scene(8.0, LightSampling::Fnee, r, Interpolation::Nearest),
                integ,
                8,
                12,
                50 + u64::from(r),
            )
        })
        .collect();
    for other in &results[1..] {
        for ((m, se), (rm, rse)) in other.iter().zip(&results[0]) {
            let z = (m - rm) / (se * se + rse * rse).sqrt();
            assert!(z.abs() < 4.0, "{m} ± {se} vs proxy 8: {rm} ± {rse}");
        }
    }
}

#[test]
fn extreme_phase_albedo_and_density_stay_finite() {
    // Both reconstructions: trilinear adds Newton solves and cubics, which must hold at
    // σ_t from 10⁻⁵ to 10⁷ too
    for (interpolation, sigma_t) in [Interpolation::Nearest, Interpolation::Linear]
        .into_iter()
        .flat_map(|i| [(i, 1e-6 * 8.0), (i, 8.0), (i, 1e6 * 8.0)])
    {
        for (g, albedo) in [(0.999, 1.0f32), (-0.999, 0.5), (0.0, 0.0), (0.5, 1.0)] {
            for (est, ls) in COMBOS {
                let mut scene = explosion_scene(sigma_t, ls, 8, interpolation);
                plume_engine::with_scene!(&mut scene, s => {
                    s.medium.g = g;
                    s.medium.albedo = plume_core::color::Rgb::splat(albedo);
                });
                let settings = RenderSettings {
                    budget: SampleBudget::Spp(2),
                    seed: 1,
                    sampler: SamplerKind::Sobol,
                    threads: 0,
                    first_sample: 0,
                    adaptive: None,
                    integrator: integrator(est, ls, MisHeuristic::Power, 32),
                };
                let r = plume_engine::with_scene!(&scene, s => render(s, &settings, &|_, _| {}));
                assert_eq!(
                    r.counters.nonfinite_samples, 0,
                    "{interpolation} σ={sigma_t} g={g} a={albedo} {est:?}/{ls:?}"
                );
                assert!(r.film.average().iter().flatten().all(|v| v.is_finite()));
            }
        }
    }
}

#[test]
fn mis_weights_sum_to_one() {
    for h in [MisHeuristic::Balance, MisHeuristic::Power] {
        for (a, b) in [(1.0, 2.0), (1e-300, 1e300), (0.0, 1.0), (5.0, 0.0), (f64::INFINITY, 1.0)] {
            let s = h.weight(a, b) + h.weight(b, a);
            assert!((s - 1.0).abs() < 1e-12, "{h:?} {a} {b}: {s}");
        }
    }
}

#[test]
fn albedo_grid_matches_constant_albedo_and_varies_per_voxel() {
    // A constant albedo grid of 0.8 with medium albedo 1 is bit-identical to medium
    // albedo 0.8 without a grid; a grid of 0 removes all scattering.
    let ex = explosion(&ExplosionParams { resolution: 32, seed: 5, ..Default::default() });
    let e = explosion_emission();
    let albedo_grid = |a: f32| FloatGrid {
        name: "albedo".into(),
        values: vec![a; ex.density.values.len()],
        ..ex.density.clone()
    };
    let cam = Camera::look_at(
        DVec3::new(0.0, 0.2, -6.5),
        DVec3::new(0.0, 0.2, 0.0),
        DVec3::Y,
        40.0,
        10,
        8,
    )
    .unwrap();
    let render_with = |grid: Option<FloatGrid>, albedo: f32| {
        let vol = Volume::build_with_albedo(
            &ex.density,
            Some(&ex.temperature),
            |v| e.map_source(v),
            grid.as_ref(),
        )
        .unwrap();
        let lights = Lights::build(&vol, &e, LightSampling::Fnee, 8).unwrap();
        let scene = Scene {
            field: vol,
            medium: Medium {
                sigma_t: 5.0,
                albedo: plume_core::color::Rgb::splat(albedo),
                g: 0.3,
                emission: e,
                extinction: Default::default(),
            },
            camera: cam,
            lights,
            motion: None,
            majorants: None,
        };
        let integ = integrator(Estimator::Line, LightSampling::Fnee, MisHeuristic::Power, 16);
        let r = render(
            &scene,
            &RenderSettings {
                budget: SampleBudget::Spp(4),
                seed: 2,
                sampler: SamplerKind::Sobol,
                threads: 0,
                first_sample: 0,
                adaptive: None,
                integrator: integ,
            },
            &|_, _| {},
        );
        (r.film.average(), r.counters)
    };
    let (a, ca) = render_with(Some(albedo_grid(0.8)), 1.0);
    let (b, cb) = render_with(None, 0.8);
    assert_eq!(a, b, "albedo grid 0.8 × 1 == constant 0.8");
    assert_eq!(ca, cb);
    let (_, c0) = render_with(Some(albedo_grid(0.0)), 1.0);
    assert!(ca.fnee_samples > 0);
    assert_eq!(c0.fnee_samples, 0, "albedo 0: no scattering vertex survives to sample light");
}

/// The explosion lit by a sun (a 5° disc, so phase sampling reaches it too), a sphere
/// light and a constant environment, besides its own fire.
fn lit_explosion_scene(sigma_t: f64, ls: LightSampling, interpolation: Interpolation) -> AnyScene {
    use plume_engine::light::external::{
        Distant, Environment, ExternalLights, Light, Radiance, Sphere,
    };
    let mut scene = explosion_scene(sigma_t, ls, 8, interpolation);
    let lights = vec![
        Light::Distant(Distant::new(
            DVec3::new(0.4, -0.8, 0.45).normalize(),
            Rgb([6.0, 5.0, 4.0]),
            5f64.to_radians(),
        )),
        Light::Sphere(Sphere::new(DVec3::new(-2.5, 1.0, -1.5), 0.4, Rgb([80.0, 90.0, 120.0]))),
        Light::Environment(Environment::new(
            Radiance::Constant(Rgb([0.3, 0.35, 0.45])),
            1.0,
            DVec3::Y,
            0.0,
            true,
        )),
    ];
    let external = ExternalLights::new(lights, 2.0);
    plume_engine::with_scene!(&mut scene, s => s.lights.external = external);
    scene
}

#[test]
fn every_method_gives_the_same_image_means_under_external_lights() {
    // Lights are a strategy of their own beside NEE/FNEE: every estimator × volume light
    // sampling, both reconstructions, against forward line integration; 2 × 12 combos × 5
    // regions = 120 comparisons, |z| < 4.2 as above.
    for interpolation in [Interpolation::Nearest, Interpolation::Linear] {
        let reference = region_means(
            &lit_explosion_scene(1.5, LightSampling::None, interpolation),
            integrator(Estimator::Line, LightSampling::None, MisHeuristic::Power, 64),
            16,
            24,
            2000,
        );
        let unlit = region_means(
            &explosion_scene(1.5, LightSampling::None, 8, interpolation),
            integrator(Estimator::Line, LightSampling::None, MisHeuristic::Power, 64),
            8,
            4,
            2000,
        );
        // The lights carry a good part of the image, so an error in them would show
        assert!(
            reference[0].0 > 1.5 * unlit[0].0,
            "{interpolation}: lit {:?} vs unlit {:?}",
            reference[0],
            unlit[0]
        );
        for (est, ls) in COMBOS {
            let scene = lit_explosion_scene(1.5, ls, interpolation);
            let got =
                region_means(&scene, integrator(est, ls, MisHeuristic::Power, 64), 8, 12, 2007);
            assert_same_means(&format!("{interpolation} {est:?}/{ls:?}"), &got, &reference, 4.2);
        }
    }
}
