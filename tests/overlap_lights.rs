//! Classic NEE over several volumes (`plume_engine::light::nee_mixture`): the mixture of
//! the volumes' emitter tables is a density over points (it integrates to 1, a drawn
//! point's density is the mixture's, and each table's own density has expectation 1
//! under it), and multiple scattering lit through it, with the point estimator's MIS, has the mean of one volume holding the summed coefficients.
//! Fixed seeds; means within 4 standard errors.

use std::sync::Arc;

use crate::common::image_means;
use crate::overlap::{integrator, medium, merged, scene, two_slabs};
use glam::DVec3;
use plume_core::sampling::Sampler;
use plume_engine::camera::Camera;
use plume_engine::integrator::{LightSampling, Lights};
use plume_engine::light::nee_mixture::{emitting_bounds, EmitterMixture, PlacedEmitters};
use plume_engine::light::{EmitterDistribution, LightPower};
use plume_engine::medium::Estimator;
use plume_engine::overlap::member::Member;
use plume_engine::overlap::volumes::Volumes;
use plume_volume::Volume;

/// Classic NEE over the members' tables, each chosen by its power.
fn emitter_lights(members: &[Member<Volume>]) -> Lights {
    let emitters = members
        .iter()
        .enumerate()
        .filter_map(|(i, m)| {
            let e = &m.medium.emission;
            let t = EmitterDistribution::build(&m.field, |d, s| LightPower::new(e).power(d, s))
                .unwrap()?;
            let w = t.total_power() * f64::from(e.scale) * f64::from(e.color.luminance());
            let bounds = emitting_bounds(&m.field, None);
            Some((PlacedEmitters { table: Arc::new(t), member: i, instance: None, bounds }, w))
        })
        .collect();
    Lights { nee_several: EmitterMixture::new(emitters), ..Lights::default() }
}

#[test]
fn the_mixture_of_emitter_tables_is_a_density_over_points() {
    let members = two_slabs(([0.5; 3], 0.0), ([0.5; 3], 0.0), true);
    let lights = emitter_lights(&members);
    let volumes = Volumes::new(members).unwrap();
    let mix = lights.nee_several.as_ref().unwrap();
    let mut s = Sampler::new(9, 0, 0);
    // ∫ p_V dV = 1 over the box holding both slabs (uniform points)
    let (lo, hi) = (DVec3::new(-16.0, -16.0, -0.1), DVec3::new(16.0, 16.0, 0.7));
    let n = 200_000;
    let box_volume = (hi - lo).x * (hi - lo).y * (hi - lo).z;
    let mut sum = 0.0;
    for _ in 0..n {
        let u = DVec3::new(s.next_f64(), s.next_f64(), s.next_f64());
        sum += mix.pdf(&volumes, lo + u * (hi - lo)) * box_volume;
    }
    let mean = sum / f64::from(n);
    assert!((mean - 1.0).abs() < 0.02, "∫ p_V dV = {mean}");
    // A drawn point's density is the mixture's; E[p_i(y)/p_V(y)] = 1 for each table's own
    for (k, (placed, _)) in mix.emitters().enumerate() {
        let volume = volumes.members()[placed.member].field.as_ref();
        let mut sum = 0.0;
        for _ in 0..n {
            let u = [s.next_f64(), s.next_f64(), s.next_f64()];
            let y = mix.sample(&volumes, s.next_f64(), u).expect("the slabs' voxels");
            let p = mix.pdf(&volumes, y.p_world);
            assert!((y.pdf - p).abs() <= 1e-12 * p, "drawn {} vs mixture {p}", y.pdf);
            sum += placed.table.pdf(volume, y.p_world) / y.pdf;
        }
        let mean = sum / f64::from(n);
        assert!((mean - 1.0).abs() < 0.02, "table {k}: E[p_i/p_V] = {mean}");
    }
}

#[test]
fn scattering_lit_by_classic_nee_over_overlapping_slabs_is_the_summed_medium_in_the_mean() {
    let (albedo, g) = ([0.7f32; 3], 0.4);
    let members = two_slabs((albedo, g), (albedo, g), true);
    let lights = emitter_lights(&members);
    let volumes = Volumes::new(members).unwrap();
    let cam = Camera::look_at(
        DVec3::new(0.5, -0.3, -2.0),
        DVec3::new(0.0, 0.0, 0.3),
        DVec3::Y,
        50.0,
        8,
        6,
    )
    .unwrap();
    let m = volumes.medium();
    let sc = plume_engine::integrator::Scene { camera: cam, ..scene(volumes, m, lights) };
    let one_medium = medium(1.0, albedo, g, true);
    let one_volume = merged();
    let one_lights =
        Lights::build(&one_volume, &one_medium.emission, LightSampling::Nee, 16).unwrap();
    let one = plume_engine::integrator::Scene {
        camera: cam,
        ..scene(one_volume, one_medium, one_lights)
    };
    // (Line integration with classic NEE has no MIS partner, and its variance is infinite
    // from vertices inside emitters: `tests/path.rs`; the point estimator's is finite)
    let integ = integrator(Estimator::Point, 8, LightSampling::Nee);
    let (got, want) = (image_means(&sc, integ, 300, 32), image_means(&one, integ, 350, 32));
    for c in 0..3 {
        let ((a, sa), (b, sb)) = (got[c], want[c]);
        let z = (a - b) / (sa * sa + sb * sb).sqrt();
        assert!(z.abs() < 4.0, "channel {c}: {a} ± {sa} vs one volume {b} ± {sb}");
        assert!(sa < 0.02 * a, "channel {c}: noise {sa} of {a}");
    }
}
