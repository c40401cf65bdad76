//! Several volumes in one scene (METHOD.md §14, `plume_engine::overlap`): two overlapping
//! constant slabs are the slab of summed coefficients (optical depth, emission and shadow
//! transmittance to float tolerance; every estimator's emission and alpha against the
//! closed form; multiple scattering with FNEE in the mean against one volume holding the
//! sums), volumes with different colours and asymmetries scatter as the mixture of their
//! phase functions (a sun's single scattering per channel), FNEE's mixture of proxies is a
//! density over directions, and a volume hidden from the camera or from shadow rays is.
//! Fixed seeds; means within 4 standard errors.

use std::sync::Arc;

use crate::common;

use common::{grid, grid_emission, mean_stderr_from_sums};
use glam::{DAffine3, DMat3, DVec3, IVec3};
use plume_core::color::Rgb;
use plume_core::sampling::phase::hg_pdf;
use plume_core::sampling::Sampler;
use plume_engine::camera::Camera;
use plume_engine::integrator::lights::proxy_weight;
use plume_engine::integrator::{
    light_power, Counters, Integrator, LightSampling, Lights, MisHeuristic, NoTrace, Scene,
    Tracking,
};
use plume_engine::light::external::{Distant, ExternalLights, Light};
use plume_engine::light::fnee::ProxySampling;
use plume_engine::light::mixture::{PlacedProxy, ProxyMixture};
use plume_engine::medium::{Collision, Convention, Emission, EmissionKind, Estimator, Medium};
use plume_engine::overlap::member::Member;
use plume_engine::overlap::volumes::Volumes;
use plume_volume::field::{Field, Piece, Ray};
use plume_volume::proxy::ProxyGrid;
use plume_volume::Volume;

/// Half-width of the slabs.
const HALF: f64 = 16.0;
/// Voxel thickness along z.
const H: f64 = 0.05;

/// A slab `[−HALF, HALF]² × [z0, z0 + nz H]` whose voxel layer `k` holds `values(k)`
/// (density, emission source; Cycles convention: the source is `L_e`).
pub(crate) fn slab(z0: f64, nz: i32, values: impl Fn(i32) -> (f32, f32)) -> Volume {
    let n = 8; // leaves a side
    let w = 2.0 * HALF / f64::from(8 * n);
    let xf = DAffine3::from_mat3_translation(
        DMat3::from_diagonal(DVec3::new(w, w, H)),
        DVec3::new(-HALF + 0.5 * w, -HALF + 0.5 * w, z0 + 0.5 * H),
    );
    let leaves: Vec<IVec3> = (0..n * n)
        .flat_map(|i| (0..nz / 8).map(move |z| IVec3::new(i % n, i / n, z) * 8))
        .collect();
    let e = grid_emission(Convention::Cycles);
    let density = grid("density", xf, &leaves, |v| values(v.z).0);
    let emission = grid("emission", xf, &leaves, |v| values(v.z).1);
    Volume::build(&density, Some(&emission), |v| e.map_source(v)).unwrap()
}

pub(crate) fn medium(sigma_t: f64, albedo: [f32; 3], g: f64, emits: bool) -> Medium {
    let e = grid_emission(Convention::Cycles);
    let emission = if emits { e } else { Emission { kind: EmissionKind::None, ..e } };
    Medium::principled(sigma_t, albedo, [0.0; 3], g, emission)
}

/// The two overlapping slabs: A over `z ∈ [0, 0.4]` (σ_t 3, `L_e` 2), B over
/// `[0.2, 0.6]` (σ_t 5, `L_e` 1.5), with the albedos and asymmetries given.
pub(crate) fn two_slabs(
    a: ([f32; 3], f64),
    b: ([f32; 3], f64),
    emits: bool,
) -> Vec<Member<Volume>> {
    let member = |v: Volume, m: Medium| Member {
        field: Arc::new(v),
        instance: None,
        medium: m,
        visible_to_camera: true,
        casts_shadows: true,
    };
    vec![
        member(slab(0.0, 8, |_| (1.0, 2.0)), medium(3.0, a.0, a.1, emits)),
        member(slab(0.2, 8, |_| (1.0, 1.5)), medium(5.0, b.0, b.1, emits)),
    ]
}

/// Regions of the summed medium along z: `(z0, z1, μ_t, L_e)`.
const REGIONS: [(f64, f64, f64, f64); 3] =
    [(0.0, 0.2, 3.0, 2.0), (0.2, 0.4, 8.0, 3.5), (0.4, 0.6, 5.0, 1.5)];

/// One volume holding the sums, walked with `σ_t = 1` (its density is `μ_t`).
pub(crate) fn merged() -> Volume {
    slab(0.0, 16, |k| match k {
        0..=3 => (3.0, 2.0),
        4..=7 => (8.0, 3.5),
        8..=11 => (5.0, 1.5),
        _ => (0.0, 0.0),
    })
}

fn camera() -> Camera {
    Camera::look_at(DVec3::new(0.0, 0.0, -1.0), DVec3::ZERO, DVec3::Y, 1.0, 1, 1).unwrap()
}

pub(crate) fn scene<F: Field>(field: F, medium: Medium, lights: Lights) -> Scene<F> {
    Scene { field, medium, camera: camera(), lights, motion: None, majorants: None }
}

pub(crate) fn integrator(
    estimator: Estimator,
    max_depth: u32,
    light_sampling: LightSampling,
) -> Integrator {
    Integrator {
        estimator,
        camera_estimator: None,
        light_sampling,
        mis: MisHeuristic::Power,
        max_depth,
        tracking: Tracking::Regular,
        split: 1,
        camera_collision: Collision::Analog,
        point_lookup: plume_engine::integrator::PointLookup::Exact,
        split_by: plume_engine::integrator::SplitBy::Uniform,
    }
}

const ESTIMATORS: [Estimator; 4] =
    [Estimator::Line, Estimator::Point, Estimator::Blend { kappa: 2.0 }, Estimator::RayMarch];

/// Mean and standard error of each channel and alpha along `ray`.
fn along<F: Field>(
    scene: &Scene<F>,
    integ: Integrator,
    ray: Ray,
    n: u64,
    seed: u64,
) -> [(f64, f64); 4] {
    let (mut sum, mut sum2) = ([0.0f64; 4], [0.0f64; 4]);
    let mut c = Counters::default();
    for i in 0..n {
        let l = integ.li(scene, &ray, &mut Sampler::new(seed, 0, i), &mut c, &mut NoTrace);
        for ch in 0..4 {
            sum[ch] += l[ch];
            sum2[ch] += l[ch] * l[ch];
        }
    }
    std::array::from_fn(|ch| mean_stderr_from_sums(sum[ch], sum2[ch], n))
}

fn normal() -> Ray {
    Ray { origin: DVec3::new(0.3, -0.2, -1.0), direction: DVec3::Z }
}

fn assert_close(label: &str, (m, se): (f64, f64), expected: f64) {
    assert!(
        (m - expected).abs() <= 4.0 * se + 1e-9 * expected.abs(),
        "{label}: {m} ± {se} vs {expected}"
    );
}

/// `∫ OD` and `∫ L_e` over every piece of `field` along `ray`, with `le` and `σ_t`.
fn integrals<F: Field>(
    field: &F,
    sigma_t: f64,
    le: impl Fn(f32, f32) -> Rgb,
    ray: &Ray,
) -> (f64, f64) {
    let (mut od, mut e) = (0.0, 0.0);
    let mut last: Option<f64> = None;
    let mut it = field.segments(ray, 0.0, f64::INFINITY);
    for p in it.by_ref() {
        if let Some(t) = last {
            assert_eq!(t.to_bits(), p.t0().to_bits(), "pieces are contiguous");
        }
        last = Some(p.t1());
        od += p.optical_depth(sigma_t, p.length());
        e += p.emission_integral(&le, p.length())[0];
    }
    (od, e)
}

#[test]
fn overlapping_slabs_are_the_summed_medium_exactly() {
    let volumes = Volumes::new(two_slabs(([0.0; 3], 0.0), ([0.0; 3], 0.0), true)).unwrap();
    let one = merged();
    let cycles = grid_emission(Convention::Cycles);
    let le = |d: f32, s: f32| cycles.le(d, s);
    for ray in [
        normal(),
        Ray {
            origin: DVec3::new(-0.4, 0.1, -1.0),
            direction: DVec3::new(0.3, -0.2, 1.0).normalize(),
        },
    ] {
        let cos = ray.direction.z;
        let want_od = REGIONS.iter().map(|r| r.2 * (r.1 - r.0)).sum::<f64>() / cos;
        let want_e = REGIONS.iter().map(|r| r.3 * (r.1 - r.0)).sum::<f64>() / cos;
        let (od, e) = integrals(&volumes, 1.0, |_, _| Rgb::ZERO, &ray);
        let (od1, e1) = integrals(&one, 1.0, le, &ray);
        for (label, got, want) in [
            ("OD", od, want_od),
            ("emission", e, want_e),
            ("merged OD", od1, want_od),
            ("merged emission", e1, want_e),
        ] {
            assert!((got - want).abs() < 1e-9 * want, "{label}: {got} vs {want}");
        }
        let (shadow, _) = volumes.optical_depth(1.0, &ray, 100.0, f64::INFINITY);
        assert!((shadow - want_od).abs() < 1e-9 * want_od, "shadow OD {shadow} vs {want_od}");
    }
}

/// `∫ τ L_e` and `1 − τ` along the normal through [`REGIONS`].
fn emission_closed_form() -> (f64, f64) {
    let (mut l, mut od) = (0.0f64, 0.0f64);
    for (z0, z1, mu, le) in REGIONS {
        l += (-od).exp() * le * (1.0 - (-mu * (z1 - z0)).exp()) / mu;
        od += mu * (z1 - z0);
    }
    (l, 1.0 - (-od).exp())
}

#[test]
fn emission_and_alpha_through_overlapping_slabs_match_the_closed_form() {
    let volumes = Volumes::new(two_slabs(([0.0; 3], 0.0), ([0.0; 3], 0.0), true)).unwrap();
    let m = volumes.medium();
    let sc = scene(volumes, m, Lights::default());
    let (l, alpha) = emission_closed_form();
    for estimator in ESTIMATORS {
        let got = along(&sc, Integrator::emission_only(estimator), normal(), 20_000, 3);
        for (ch, &value) in got[..3].iter().enumerate() {
            assert_close(&format!("{estimator:?} channel {ch}"), value, l);
        }
        assert_close(&format!("{estimator:?} alpha"), got[3], alpha);
    }
    // The merged volume's expected value is the closed form, to rounding
    let one = scene(merged(), medium(1.0, [0.0; 3], 0.0, true), Lights::default());
    let got = along(&one, Integrator::emission_only(Estimator::RayMarch), normal(), 4, 3);
    assert!((got[0].0 - l).abs() < 1e-9 * l, "{got:?} vs {l}");
}

/// FNEE over the members' proxies, each chosen by its power.
pub(crate) fn mixture_lights(members: &[Member<Volume>]) -> Lights {
    let proxies = members
        .iter()
        .filter_map(|m| {
            let e = &m.medium.emission;
            let p = ProxyGrid::build(&m.field, 16, light_power(e)).unwrap()?;
            let w = proxy_weight(&p, e);
            Some((PlacedProxy { proxy: Arc::new(p), instance: None }, w))
        })
        .collect();
    Lights { proxies: ProxyMixture::new(proxies), ..Lights::default() }
}

#[test]
fn scattering_in_overlapping_slabs_is_the_summed_medium_in_the_mean() {
    // One class (same albedo and g): the sum is one volume of the summed coefficients,
    // lit by its own emission through FNEE and by a sun
    let (albedo, g) = ([0.7f32; 3], 0.4);
    let members = two_slabs((albedo, g), (albedo, g), true);
    let lights = mixture_lights(&members);
    let volumes = Volumes::new(members).unwrap();
    let view = |cam: Camera| cam;
    let cam = view(
        Camera::look_at(
            DVec3::new(0.5, -0.3, -2.0),
            DVec3::new(0.0, 0.0, 0.3),
            DVec3::Y,
            50.0,
            8,
            6,
        )
        .unwrap(),
    );
    let external = || {
        let sun = Light::Distant(Distant::new(
            DVec3::new(-0.3, 0.2, -1.0).normalize(),
            Rgb::splat(2.0),
            0.0,
        ));
        ExternalLights::new(vec![sun], HALF)
    };
    let m = volumes.medium();
    let sc = Scene { camera: cam, ..scene(volumes, m, Lights { external: external(), ..lights }) };
    let one_medium = medium(1.0, albedo, g, true);
    let one_volume = merged();
    let one_lights =
        Lights::build(&one_volume, &one_medium.emission, LightSampling::Fnee, 16).unwrap();
    let one = Scene {
        camera: cam,
        ..scene(one_volume, one_medium, Lights { external: external(), ..one_lights })
    };
    let integ = integrator(Estimator::Line, 8, LightSampling::Fnee);
    let (got, want) =
        (common::image_means(&sc, integ, 100, 32), common::image_means(&one, integ, 200, 32));
    for c in 0..3 {
        let ((a, sa), (b, sb)) = (got[c], want[c]);
        let z = (a - b) / (sa * sa + sb * sb).sqrt();
        assert!(z.abs() < 4.0, "channel {c}: {a} ± {sa} vs one volume {b} ± {sb}");
        assert!(sa < 0.02 * a, "channel {c}: noise {sa} of {a}");
    }
}

#[test]
fn volumes_that_scatter_differently_mix_their_phase_functions() {
    // A sun's single scattering per channel: ∫ τ_cam Σ_i μ_s,i,c p_i(cos α) τ_sun dz over
    // the three regions, by Simpson's rule on each (smooth within a region)
    let (ca, ga) = ([0.9f32, 0.5, 0.2], 0.6);
    let (cb, gb) = ([0.3f32, 0.6, 0.9], -0.3);
    let volumes = Volumes::new(two_slabs((ca, ga), (cb, gb), false)).unwrap();
    let alpha = 40f64.to_radians();
    let to_light = DVec3::new(alpha.sin(), 0.0, alpha.cos());
    let e = 3.0;
    let sun = Light::Distant(Distant::new(-to_light, Rgb::splat(e as f32), 0.0));
    let lights = Lights { external: ExternalLights::new(vec![sun], HALF), ..Lights::default() };
    let m = volumes.medium();
    let sc = scene(volumes, m, lights);
    let od_below = |z: f64| REGIONS.iter().map(|r| r.2 * (z.min(r.1) - r.0).max(0.0)).sum::<f64>();
    let total = od_below(0.6);
    let expected: [f64; 3] = std::array::from_fn(|c| {
        let mu_s = |z: f64| {
            let a = if z < 0.4 { 3.0 * f64::from(ca[c]) * hg_pdf(ga, alpha.cos()) } else { 0.0 };
            let b = if z >= 0.2 { 5.0 * f64::from(cb[c]) * hg_pdf(gb, alpha.cos()) } else { 0.0 };
            a + b
        };
        let f = |z: f64| mu_s(z) * (-od_below(z) - (total - od_below(z)) / alpha.cos()).exp();
        REGIONS
            .iter()
            .map(|&(z0, z1, _, _)| {
                let n = 200;
                let h = (z1 - z0) / f64::from(n);
                let inner = |k: i32| f(z0 + (f64::from(k) + 0.5) * h); // midpoints, away from the edges
                (0..n).map(inner).sum::<f64>() * h
            })
            .sum::<f64>()
            * e
    });
    for estimator in ESTIMATORS {
        let got = along(&sc, integrator(estimator, 1, LightSampling::None), normal(), 40_000, 7);
        for c in 0..3 {
            // Midpoint rule on a smooth exponential: far below the 4σ of the estimate
            assert_close(&format!("{estimator:?} channel {c}"), got[c], expected[c]);
            assert!(got[c].1 < 0.05 * expected[c], "{estimator:?} channel {c}: noise {got:?}");
        }
    }
}

#[test]
fn the_mixture_of_proxies_is_a_density_over_directions() {
    // ∫ p_σ dω = 1 (uniform directions, 200 000 of them), and a sampled direction's pdf is
    // the mixture's pdf of it
    let members = two_slabs(([0.5; 3], 0.0), ([0.5; 3], 0.0), true);
    let lights = mixture_lights(&members);
    let mix = lights.proxies.as_ref().unwrap();
    let x = DVec3::new(0.5, 0.2, 0.3);
    let mut s = Sampler::new(5, 0, 0);
    let n = 200_000;
    let mut sum = 0.0;
    for _ in 0..n {
        let (u, v) = (s.next_f64(), s.next_f64());
        let z = 1.0 - 2.0 * u;
        let r = (1.0 - z * z).max(0.0).sqrt();
        let phi = std::f64::consts::TAU * v;
        let w = DVec3::new(r * phi.cos(), r * phi.sin(), z);
        sum += mix.direction_pdf(x, w) * 4.0 * std::f64::consts::PI;
    }
    let mean = sum / f64::from(n);
    assert!((mean - 1.0).abs() < 0.02, "∫ p_σ dω = {mean}");
    for k in 0..100 {
        let u = (f64::from(k) + 0.5) / 100.0;
        if let Some(d) = mix.sample_direction(x, u, [0.3, 0.6, 0.9]) {
            assert_eq!(d.pdf, mix.direction_pdf(x, d.direction));
        }
    }
    // The directions it draws have that density: E[p_i(ω)/p_σ(ω)] = ∫ p_i dω = 1 for
    // each volume's own (normalized) density p_i
    for (placed, _) in mix.proxies() {
        let mut sum = 0.0;
        for _ in 0..n {
            let u = [s.next_f64(), s.next_f64(), s.next_f64()];
            if let Some(d) = mix.sample_direction(x, s.next_f64(), u) {
                sum += placed.proxy.direction_pdf(x, d.direction) / d.pdf;
            }
        }
        let mean = sum / f64::from(n);
        assert!((mean - 1.0).abs() < 0.02, "E[p_i/p_σ] = {mean}");
    }
}

#[test]
fn hidden_volumes_are_hidden_from_the_camera_and_from_shadow_rays() {
    let mut members = two_slabs(([0.0; 3], 0.0), ([0.0; 3], 0.0), true);
    members[1].visible_to_camera = false;
    members[0].casts_shadows = false;
    let volumes = Volumes::new(members).unwrap();
    // Camera rays see slab A alone: L_e 2 over [0, 0.4] at μ_t 3
    let m = volumes.medium();
    let sc = scene(volumes, m, Lights::default());
    let got = along(&sc, Integrator::emission_only(Estimator::Line), normal(), 10_000, 9);
    let want = 2.0 * (1.0 - (-3.0f64 * 0.4).exp()) / 3.0;
    assert_close("camera sees A only", got[0], want);
    // Shadow rays see slab B alone
    let (od, _) = sc.field.optical_depth(1.0, &normal(), 100.0, f64::INFINITY);
    assert!((od - 2.0).abs() < 1e-9, "shadow OD {od} vs B's 2");
}

/// A rotation, non-uniform scale and shift that keeps slab B near slab A.
fn instance_map() -> DAffine3 {
    DAffine3::from_scale_rotation_translation(
        DVec3::new(1.3, 0.7, 1.1),
        glam::DQuat::from_euler(glam::EulerRot::XYZ, 0.2, -0.15, 0.4),
        DVec3::new(0.2, -0.1, 0.05),
    )
}

#[test]
fn an_instance_is_the_volume_placed_there() {
    // Slab B shared and instanced by M, against slab B's own copy placed by M: the same
    // sums along rays, the same shadows and the same FNEE densities
    let m = instance_map();
    let [a, b]: [Member<Volume>; 2] =
        two_slabs(([0.5; 3], 0.2), ([0.5; 3], 0.2), true).try_into().unwrap();
    let b_placed = Member { field: Arc::new(slab(0.2, 8, |_| (1.0, 1.5)).placed(m)), ..b };
    let b_instance = Member {
        field: Arc::new(slab(0.2, 8, |_| (1.0, 1.5))),
        instance: Some(plume_volume::instance::Instance::new(m).unwrap()),
        medium: b_placed.medium,
        visible_to_camera: true,
        casts_shadows: true,
    };
    let a2 = Member { field: Arc::clone(&a.field), ..a };
    // Trilinear copies of both, whose pieces are cubics in the distance
    let linear = |m: &Member<Volume>, v: Volume| Member {
        field: Arc::new(plume_volume::trilinear::Trilinear::new(v)),
        instance: m.instance,
        medium: m.medium,
        visible_to_camera: true,
        casts_shadows: true,
    };
    let placed_linear = Volumes::new(vec![
        linear(&a, slab(0.0, 8, |_| (1.0, 2.0))),
        linear(&b_placed, slab(0.2, 8, |_| (1.0, 1.5)).placed(m)),
    ])
    .unwrap();
    let instanced_linear = Volumes::new(vec![
        linear(&a, slab(0.0, 8, |_| (1.0, 2.0))),
        linear(&b_instance, slab(0.2, 8, |_| (1.0, 1.5))),
    ])
    .unwrap();
    let placed = Volumes::new(vec![a, b_placed]).unwrap();
    let instanced = Volumes::new(vec![a2, b_instance]).unwrap();
    let mut s = Sampler::new(11, 0, 0);
    for _ in 0..200 {
        let origin = DVec3::new(4.0 * s.next_f64() - 2.0, 4.0 * s.next_f64() - 2.0, -1.5);
        let target = DVec3::new(s.next_f64() - 0.5, s.next_f64() - 0.5, 0.3);
        let ray = Ray { origin, direction: (target - origin).normalize() };
        let (od, e) = integrals(&placed, 1.0, |_, _| Rgb::ZERO, &ray);
        let (od_i, e_i) = integrals(&instanced, 1.0, |_, _| Rgb::ZERO, &ray);
        assert!((od - od_i).abs() <= 1e-9 * od.max(1.0), "OD {od} vs instance {od_i}");
        assert!((e - e_i).abs() <= 1e-9 * e.max(1.0), "emission {e} vs instance {e_i}");
        let (od, e) = integrals(&placed_linear, 1.0, |_, _| Rgb::ZERO, &ray);
        let (od_i, e_i) = integrals(&instanced_linear, 1.0, |_, _| Rgb::ZERO, &ray);
        assert!((od - od_i).abs() <= 1e-9 * od.max(1.0), "trilinear OD {od} vs instance {od_i}");
        assert!((e - e_i).abs() <= 1e-9 * e.max(1.0), "trilinear emission {e} vs instance {e_i}");
        let (sh, _) = placed.optical_depth(1.0, &ray, 50.0, f64::INFINITY);
        let (sh_i, _) = instanced.optical_depth(1.0, &ray, 50.0, f64::INFINITY);
        assert!((sh - sh_i).abs() <= 1e-9 * sh.max(1.0), "shadow {sh} vs instance {sh_i}");
    }
    // FNEE: the instance's shared proxy, carried out, has the placed copy's density
    let build = |v: &Volume| {
        ProxyGrid::build(v, 16, light_power(&grid_emission(Convention::Cycles))).unwrap().unwrap()
    };
    let own = PlacedProxy {
        proxy: Arc::new(build(&slab(0.2, 8, |_| (1.0, 1.5)).placed(m))),
        instance: None,
    };
    let shared = PlacedProxy {
        proxy: Arc::new(build(&slab(0.2, 8, |_| (1.0, 1.5)))),
        instance: Some(plume_volume::instance::Instance::new(m).unwrap()),
    };
    let (own, shared) = (
        ProxyMixture::new(vec![(own, 1.0)]).unwrap(),
        ProxyMixture::new(vec![(shared, 1.0)]).unwrap(),
    );
    let x = DVec3::new(0.3, 0.2, -0.7);
    for k in 0..300 {
        let u = [s.next_f64(), s.next_f64(), s.next_f64()];
        let Some(d) = shared.sample_direction(x, (f64::from(k) + 0.5) / 300.0, u) else { continue };
        let p = own.direction_pdf(x, d.direction);
        assert!((p - d.pdf).abs() <= 1e-9 * p, "own {p} vs instance {}", d.pdf);
    }
}
