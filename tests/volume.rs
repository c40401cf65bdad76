//! Volume data tier: DDA segment invariants (proptest), pyramid bounds, voxel-centre
//! convention, constant tiles and extreme rays.

use crate::common;

use common::{grid, hash};
use glam::{DAffine3, DMat3, DVec3, IVec3};
use plume_volume::field::Ray;
use plume_volume::{Field, Volume};
use proptest::prelude::*;

/// Random volume: some dense leaves, some constant, some with zeros.
fn random_volume(seed: u32, xf: DAffine3) -> Volume {
    let mut leaves = Vec::new();
    for bx in -2..2 {
        for by in -1..2 {
            for bz in 0..3 {
                let b = IVec3::new(bx, by, bz);
                if hash(b, seed) % 3 != 0 {
                    leaves.push(b * 8);
                }
            }
        }
    }
    let d = grid("density", xf, &leaves, |p| {
        let h = hash(p, seed + 1);
        match hash(p.div_euclid(IVec3::splat(8)), seed + 2) % 4 {
            0 => 0.5, // constant leaf
            1 => 0.0, // zero leaf
            _ => {
                if h % 5 == 0 {
                    0.0
                } else {
                    (h % 1000) as f32 / 100.0
                }
            }
        }
    });
    let s =
        grid("temperature", xf, &leaves, |p| if hash(p, seed + 3) % 2 == 0 { 1000.0 } else { 0.0 });
    // Albedo: constant 0.5 in some leaves, varying in others, absent elsewhere (→ 1).
    let a_leaves: Vec<IVec3> =
        leaves.iter().copied().filter(|o| hash(*o, seed + 4) % 3 != 0).collect();
    let a = grid("albedo", xf, &a_leaves, |p| {
        if hash(p.div_euclid(IVec3::splat(8)), seed + 5) % 2 == 0 {
            0.5
        } else {
            (hash(p, seed + 6) % 100) as f32 / 99.0
        }
    });
    Volume::build_with_albedo(&d, Some(&s), |v| v, Some(&a)).unwrap()
}

fn check_segments(vol: &Volume, ray: &Ray, t_min: f64, t_max: f64) -> Result<(), TestCaseError> {
    let segs: Vec<_> = vol.segments(ray, t_min, t_max).collect();
    let plume_volume::Bounds3 { lo, hi } = vol.index_bounds();
    let o = vol.index_from_world().transform_point3(ray.origin);
    let d = vol.index_from_world().transform_vector3(ray.direction);
    let clip = plume_volume::field::clip_to_box(o, d, lo, hi, t_min, t_max);
    match clip {
        None => prop_assert!(segs.is_empty(), "ray misses but got {} segments", segs.len()),
        Some((a, b)) => {
            prop_assert!(!segs.is_empty());
            prop_assert_eq!(segs[0].t0, a, "first segment starts at the clipped entry");
            prop_assert_eq!(segs.last().unwrap().t1, b, "last segment ends at the clipped exit");
            for w in segs.windows(2) {
                prop_assert_eq!(w[0].t1, w[1].t0, "contiguous");
            }
            for s in &segs {
                prop_assert!(s.t0 < s.t1, "non-empty, increasing: {:?}", s);
                // Values at the middle match a direct nearest-voxel lookup (skip slivers,
                // whose midpoint may round onto a face).
                if s.t1 - s.t0 > 1e-6 * (1.0 + s.t1.abs()) {
                    let mid = ray.at(0.5 * (s.t0 + s.t1));
                    let plume_volume::VoxelValues { density: dv, source: sv } =
                        vol.lookup_world(mid);
                    prop_assert_eq!((dv, sv), (s.density, s.source), "segment {:?}", s);
                    if dv > 0.0 {
                        let ijk =
                            (vol.index_from_world().transform_point3(mid) + 0.5).floor().as_ivec3();
                        prop_assert_eq!(
                            vol.voxel_albedo(ijk),
                            s.albedo,
                            "albedo of segment {:?}",
                            s
                        );
                    } else {
                        prop_assert_eq!(s.albedo, 1.0, "no albedo where there is no density");
                    }
                }
            }
        }
    }
    Ok(())
}

fn axis_component() -> impl Strategy<Value = f64> {
    prop_oneof![3 => -1.0f64..1.0, 1 => Just(0.0), 1 => Just(-0.0)]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    #[test]
    fn dda_segments_are_ordered_contiguous_and_exact(
        seed in 0u32..50,
        ox in -40.0f64..40.0, oy in -30.0f64..30.0, oz in -10.0f64..40.0,
        dx in axis_component(), dy in axis_component(), dz in axis_component(),
        snap in any::<bool>(),
        t_min in 0.0f64..5.0, len in 0.1f64..200.0,
        scaled in any::<bool>(),
    ) {
        let xf = if scaled {
            DAffine3::from_mat3_translation(DMat3::from_diagonal(DVec3::new(0.7, 0.7, 0.716)) * DMat3::from_rotation_y(0.3), DVec3::new(1.0, -2.0, 3.0))
        } else {
            DAffine3::IDENTITY
        };
        let vol = random_volume(seed, xf);
        let dir = DVec3::new(dx, dy, dz);
        prop_assume!(dir.length() > 1e-3);
        // Optionally start exactly on a voxel face.
        let origin = if snap { (DVec3::new(ox, oy, oz)).round() + 0.5 } else { DVec3::new(ox, oy, oz) };
        let ray = Ray { origin, direction: dir.normalize() };
        check_segments(&vol, &ray, t_min, t_min + len)?;
    }
}

#[test]
fn pyramid_bounds_cover_every_voxel() {
    for seed in 0..5 {
        let vol = random_volume(seed, DAffine3::IDENTITY);
        let levels = vol.pyramid_levels();
        let plume_volume::Bounds3 { lo, hi } = vol.index_bounds();
        let (lo, hi) = ((lo + 0.5).as_ivec3(), (hi + 0.5).as_ivec3());
        for x in lo.x..hi.x {
            for y in lo.y..hi.y {
                for z in lo.z..hi.z {
                    let v = IVec3::new(x, y, z);
                    let plume_volume::VoxelValues { density: d, source: s } = vol.voxel(v);
                    for (k, level) in levels.iter().enumerate() {
                        let node = level.get((v - lo).div_euclid(IVec3::splat(8 << k)));
                        assert!(
                            node.density_max >= d && node.density_min <= d,
                            "level {k} density at {v}"
                        );
                        assert!(
                            node.source_max >= s && node.source_min <= s,
                            "level {k} source at {v}"
                        );
                    }
                }
            }
        }
        assert_eq!(levels.last().unwrap().nodes.len(), 1, "single root");
    }
}

#[test]
fn voxel_centres_follow_openvdb() {
    // One leaf at the origin with value = x index: voxel i covers [i-½, i+½].
    let g = grid("density", DAffine3::IDENTITY, &[IVec3::ZERO], |p| p.x as f32 + 1.0);
    let vol = Volume::build(&g, None, |v| v).unwrap();
    assert_eq!(vol.lookup_index(DVec3::new(2.49, 3.0, 3.0)).density, 3.0);
    assert_eq!(vol.lookup_index(DVec3::new(2.51, 3.0, 3.0)).density, 4.0);
    assert_eq!(vol.lookup_index(DVec3::new(-0.49, 3.0, 3.0)).density, 1.0);
    let plume_volume::Bounds3 { lo, hi } = vol.index_bounds();
    assert_eq!(lo, DVec3::splat(-0.5));
    assert_eq!(hi, DVec3::splat(7.5));
    // A ray along +x through the leaf: 8 unit-length voxels, the first from -0.5.
    let ray = Ray { origin: DVec3::new(-10.0, 3.0, 3.0), direction: DVec3::X };
    let segs: Vec<_> = vol.segments(&ray, 0.0, 100.0).collect();
    assert_eq!(segs.len(), 8);
    assert_eq!(segs[0].t0, 9.5);
    assert_eq!(segs[0].density, 1.0);
    assert_eq!(segs[7].t1, 17.5);
}

#[test]
fn constant_bricks_and_empty_space_are_single_segments() {
    // Two constant leaves far apart with empty space between: 3 segments in total.
    let g = grid("density", DAffine3::IDENTITY, &[IVec3::ZERO, IVec3::new(64, 0, 0)], |_| 2.0);
    let vol = Volume::build(&g, None, |v| v).unwrap();
    assert_eq!(vol.dense_brick_count(), 0, "constant leaves stored as constants");
    let ray = Ray { origin: DVec3::new(-1.0, 3.0, 3.0), direction: DVec3::X };
    let segs: Vec<_> = vol.segments(&ray, 0.0, 1000.0).collect();
    assert_eq!(segs.len(), 3, "{segs:?}");
    assert_eq!((segs[0].t0, segs[0].t1, segs[0].density), (0.5, 8.5, 2.0));
    assert_eq!((segs[1].t0, segs[1].t1, segs[1].density), (8.5, 64.5, 0.0));
    assert_eq!((segs[2].t0, segs[2].t1, segs[2].density), (64.5, 72.5, 2.0));
}

#[test]
fn very_long_and_grazing_rays_terminate_and_cover() {
    let vol = random_volume(7, DAffine3::IDENTITY);
    // Origin far away (1e7 voxels), nearly axis-parallel direction.
    let dir = DVec3::new(1.0, 1e-9, -1e-9).normalize();
    let ray = Ray { origin: DVec3::new(-1e7, 2.0, 5.0), direction: dir };
    let segs: Vec<_> = vol.segments(&ray, 0.0, f64::INFINITY).collect();
    assert!(!segs.is_empty());
    for w in segs.windows(2) {
        assert_eq!(w[0].t1, w[1].t0);
    }
    // A ray along a voxel face (x = 0.5 exactly) with -0.0 components.
    let ray = Ray { origin: DVec3::new(0.5, -20.0, 4.0), direction: DVec3::new(-0.0, 1.0, -0.0) };
    let segs: Vec<_> = vol.segments(&ray, 0.0, 100.0).collect();
    assert!(!segs.is_empty());
    assert_eq!(segs[0].t0, 11.5);
}

#[test]
fn nan_inf_negative_density_is_clamped_and_counted() {
    let g = grid("density", DAffine3::IDENTITY, &[IVec3::ZERO], |p| match p.x {
        0 => f32::NAN,
        1 => f32::INFINITY,
        2 => -1.0,
        _ => 1.0,
    });
    let vol = Volume::build(&g, None, |v| v).unwrap();
    assert_eq!(vol.report.density_clamped, 3 * 64);
    assert_eq!(vol.voxel(IVec3::new(0, 1, 1)).density, 0.0);
    assert_eq!(vol.voxel(IVec3::new(3, 1, 1)).density, 1.0);
}
