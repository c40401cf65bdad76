//! Volume data tier, trilinear reconstruction (METHOD.md §12): the dual-cell walk's piece
//! invariants (proptest), density cubics against point interpolation, skipping at node
//! faces (the dual pyramid's dilation), constant volumes, dual pyramid bounds and memory.

use crate::common;

use common::{grid, hash};
use glam::{DAffine3, DMat3, DVec3, IVec3};
use plume_volume::field::{clip_to_box, optical_depth_along, Piece, Ray};
use plume_volume::trilinear::{poly, CubicSegment, Trilinear};
use plume_volume::{Bounds3, Field, Volume};
use proptest::prelude::*;

/// Sparse volume over bricks `[-2, 2) × [-1, 2) × [0, 2)`, about two in three present:
/// dense bricks (varied values, some zeros), constant non-zero bricks and constant zero
/// bricks; a source in some voxels, an albedo grid over some bricks.
fn sparse_volume(seed: u32, xf: DAffine3) -> Trilinear {
    let mut leaves = Vec::new();
    for bx in -2..2 {
        for by in -1..2 {
            for bz in 0..2 {
                let b = IVec3::new(bx, by, bz);
                if hash(b, seed) % 3 != 0 {
                    leaves.push(b * 8);
                }
            }
        }
    }
    let kind = move |p: IVec3| hash(p.div_euclid(IVec3::splat(8)), seed + 2) % 4;
    let d = grid("density", xf, &leaves, |p| match kind(p) {
        0 => 0.5,
        1 => 0.0,
        _ => {
            let h = hash(p, seed + 1);
            if h % 5 == 0 {
                0.0
            } else {
                (h % 1000) as f32 / 100.0
            }
        }
    });
    let s = grid("temperature", xf, &leaves, |p| {
        if kind(p) == 0 || hash(p, seed + 3) % 2 == 0 {
            1000.0
        } else {
            0.0
        }
    });
    let a_leaves: Vec<IVec3> =
        leaves.iter().copied().filter(|o| hash(*o, seed + 4) % 3 != 0).collect();
    let a = grid("albedo", xf, &a_leaves, |p| {
        if kind(p) == 0 {
            0.5
        } else {
            (hash(p, seed + 6) % 100) as f32 / 99.0
        }
    });
    Trilinear::new(Volume::build_with_albedo(&d, Some(&s), |v| v, Some(&a)).unwrap())
}

/// Sparse volume over bricks `[-2, 2) × [-1, 2) × [0, 2)` whose dense bricks are empty in
/// most blocks of 2³ voxels (each block empty or filled as a whole, some filled blocks
/// with a source): what the walk's empty-block masks (`volume::trilinear::dual`, "Empty
/// cells") skip, next to blocks it must not skip, also across brick faces.
fn blocky_volume(seed: u32, xf: DAffine3) -> Trilinear {
    let leaves: Vec<IVec3> = (-2..2)
        .flat_map(|x| (-1..2).flat_map(move |y| (0..2).map(move |z| IVec3::new(x, y, z))))
        .filter(|b| hash(*b, seed) % 4 != 0)
        .map(|b| b * 8)
        .collect();
    let block = move |p: IVec3, salt: u32| hash(p.div_euclid(IVec3::splat(2)), seed + salt);
    let d = grid("density", xf, &leaves, |p| {
        if block(p, 1) % 5 < 2 {
            0.1 + (hash(p, seed + 2) % 100) as f32 / 20.0
        } else {
            0.0
        }
    });
    let s = grid("temperature", xf, &leaves, |p| {
        if block(p, 1) % 5 < 2 && block(p, 3) % 2 == 0 {
            1500.0
        } else {
            0.0
        }
    });
    Trilinear::new(Volume::build(&d, Some(&s), |v| v).unwrap())
}

fn scaled() -> DAffine3 {
    DAffine3::from_mat3_translation(
        DMat3::from_diagonal(DVec3::new(0.7, 0.7, 0.716)) * DMat3::from_rotation_y(0.3),
        DVec3::new(1.0, -2.0, 3.0),
    )
}

/// The ray's parameter range clipped to the field's dilated index box.
fn clipped(tri: &Trilinear, ray: &Ray, t_min: f64, t_max: f64) -> Option<(f64, f64)> {
    let xf = tri.volume().index_from_world();
    let Bounds3 { lo, hi } = tri.index_bounds();
    clip_to_box(
        xf.transform_point3(ray.origin),
        xf.transform_vector3(ray.direction),
        lo,
        hi,
        t_min,
        t_max,
    )
}

/// `∫₀ᴸ ρ(u) du` of a piece's density cubic.
fn density_integral(p: &CubicSegment) -> f64 {
    let (a, l) = (p.density_cubic(), p.t1 - p.t0);
    l * (a[0] + l * (a[1] / 2.0 + l * (a[2] / 3.0 + l * a[3] / 4.0)))
}

fn same_constant(a: &CubicSegment, b: &CubicSegment) -> bool {
    a.constant
        && b.constant
        && a.corners[0].density.to_bits() == b.corners[0].density.to_bits()
        && a.corners[0].source.to_bits() == b.corners[0].source.to_bits()
        && a.albedo[0].to_bits() == b.albedo[0].to_bits()
}

fn check_pieces(tri: &Trilinear, ray: &Ray, t_min: f64, t_max: f64) -> Result<(), TestCaseError> {
    let pieces: Vec<CubicSegment> = tri.segments(ray, t_min, t_max).collect();
    let Some((a, b)) = clipped(tri, ray, t_min, t_max) else {
        prop_assert!(pieces.is_empty(), "ray misses but got {} pieces", pieces.len());
        return Ok(());
    };
    prop_assert!(!pieces.is_empty());
    prop_assert_eq!(pieces[0].t0, a, "first piece starts at the clipped entry");
    prop_assert_eq!(pieces.last().unwrap().t1, b, "last piece ends at the clipped exit");
    for w in pieces.windows(2) {
        prop_assert_eq!(w[0].t1, w[1].t0, "contiguous");
        prop_assert!(!same_constant(&w[0], &w[1]), "equal constant neighbours are merged: {:?}", w);
    }
    for p in &pieces {
        prop_assert!(p.t0 < p.t1, "non-empty, increasing: {:?}", p);
        if p.constant {
            prop_assert_eq!(p.density_cubic(), [f64::from(p.corners[0].density), 0.0, 0.0, 0.0]);
            prop_assert!(
                p.corners.iter().all(|c| *c == p.corners[0])
                    && p.albedo.iter().all(|&x| x == p.albedo[0])
            );
        } else {
            prop_assert!(
                p.f0.cmpge(DVec3::ZERO).all() && p.f0.cmple(DVec3::ONE).all(),
                "f0 in the cell: {:?}",
                p
            );
        }
    }
    Ok(())
}

/// Every dense piece carries its cell's 8 corner albedo factors (the voxel's where its
/// density is positive, else 1), whether its dual brick reads the albedo channel or knows
/// all of it is 1 (`DualBricks::albedo_one`: the sparse volume's albedo grid covers some
/// bricks only).
fn check_albedo(tri: &Trilinear, ray: &Ray, t_min: f64, t_max: f64) -> Result<(), TestCaseError> {
    let vol = tri.volume();
    let xf = vol.index_from_world();
    for p in tri.segments(ray, t_min, t_max).filter(|p| !p.constant) {
        // The cell: the corner voxel the piece's local origin is measured from
        let mid = xf.transform_point3(ray.at(0.5 * (p.t0 + p.t1)));
        let cell = mid.floor().as_ivec3();
        for (c, (&albedo, corner)) in p.albedo.iter().zip(&p.corners).enumerate() {
            let v = cell + IVec3::new((c & 1) as i32, ((c >> 1) & 1) as i32, ((c >> 2) & 1) as i32);
            let want = if corner.density > 0.0 { vol.voxel_albedo(v) } else { 1.0 };
            prop_assert_eq!(
                albedo.to_bits(),
                want.to_bits(),
                "corner {} (voxel {}) of {:?}",
                c,
                v,
                p
            );
        }
    }
    Ok(())
}

/// `n` deterministic uniforms in `[0, 1)` (splitmix64).
fn uniforms(seed: u64, n: usize) -> Vec<f64> {
    let mut s = seed;
    (0..n)
        .map(|_| {
            s = s.wrapping_add(0x9e37_79b9_7f4a_7c15);
            let mut z = s;
            z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
            (z ^ (z >> 31)) as f64 / 2f64.powi(64)
        })
        .collect()
}

fn check_cubics(
    tri: &Trilinear,
    ray: &Ray,
    t_min: f64,
    t_max: f64,
    u_seed: u64,
) -> Result<(), TestCaseError> {
    for (k, p) in tri.segments(ray, t_min, t_max).enumerate() {
        let len = p.t1 - p.t0;
        for f in uniforms(u_seed + k as u64, 4) {
            let u = f * len;
            let got = poly::eval(&p.density_cubic(), u);
            let want = f64::from(tri.values_at(ray.at(p.t0 + u)).density);
            prop_assert!(
                (got - want).abs() <= 1e-5 * want.abs() + 1e-6,
                "ρ(u = {u}) = {got}, interpolated {want}, piece {:?}",
                p
            );
        }
    }
    Ok(())
}

fn axis_component() -> impl Strategy<Value = f64> {
    prop_oneof![3 => -1.0f64..1.0, 1 => Just(0.0), 1 => Just(-0.0)]
}

/// How a ray origin's coordinate is placed: anywhere, on a dual-cell face (an integer:
/// a voxel centre plane) or on a voxel face (a half integer).
fn snap_mode() -> impl Strategy<Value = u8> {
    prop_oneof![2 => Just(0u8), 1 => Just(1u8), 1 => Just(2u8)]
}

fn snap(v: f64, mode: u8) -> f64 {
    match mode {
        1 => v.round(),
        2 => v.round() + 0.5,
        _ => v,
    }
}

/// A random ray: origin in index space (possibly on integer or half-integer planes),
/// mapped to world space; `None` for a (near) zero direction.
fn make_ray(xf: DAffine3, o: DVec3, snaps: [u8; 3], dir: DVec3) -> Option<Ray> {
    let o_index = DVec3::new(snap(o.x, snaps[0]), snap(o.y, snaps[1]), snap(o.z, snaps[2]));
    (dir.length() > 1e-3)
        .then(|| Ray { origin: xf.transform_point3(o_index), direction: dir.normalize() })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    #[test]
    fn dual_pieces_are_ordered_contiguous_and_cover_the_clipped_range(
        seed in 0u32..40,
        ox in -30.0f64..30.0, oy in -20.0f64..25.0, oz in -10.0f64..25.0,
        sx in snap_mode(), sy in snap_mode(), sz in snap_mode(),
        dx in axis_component(), dy in axis_component(), dz in axis_component(),
        t_min in 0.0f64..5.0, len in 0.1f64..200.0,
        is_scaled in any::<bool>(),
    ) {
        let xf = if is_scaled { scaled() } else { DAffine3::IDENTITY };
        let tri = sparse_volume(seed, xf);
        let ray = make_ray(xf, DVec3::new(ox, oy, oz), [sx, sy, sz], DVec3::new(dx, dy, dz));
        prop_assume!(ray.is_some());
        check_pieces(&tri, &ray.unwrap(), t_min, t_min + len)?;
    }

    #[test]
    fn dual_density_cubics_match_point_interpolation(
        seed in 0u32..40,
        ox in -30.0f64..30.0, oy in -20.0f64..25.0, oz in -10.0f64..25.0,
        sx in snap_mode(), sy in snap_mode(), sz in snap_mode(),
        dx in axis_component(), dy in axis_component(), dz in axis_component(),
        t_min in 0.0f64..5.0, len in 0.1f64..200.0,
        is_scaled in any::<bool>(),
        u_seed in any::<u64>(),
    ) {
        let xf = if is_scaled { scaled() } else { DAffine3::IDENTITY };
        let tri = sparse_volume(seed, xf);
        let ray = make_ray(xf, DVec3::new(ox, oy, oz), [sx, sy, sz], DVec3::new(dx, dy, dz));
        prop_assume!(ray.is_some());
        check_cubics(&tri, &ray.unwrap(), t_min, t_min + len, u_seed)?;
    }

    /// Pieces from cells the empty-block masks skip are what reading their corners gives:
    /// density and source along every piece equal point interpolation, and the density
    /// walk's optical depth the full walk's.
    #[test]
    fn empty_blocks_are_skipped_exactly(
        seed in 0u32..40,
        ox in -30.0f64..30.0, oy in -20.0f64..25.0, oz in -10.0f64..25.0,
        dx in axis_component(), dy in axis_component(), dz in axis_component(),
        len in 0.1f64..200.0,
        is_scaled in any::<bool>(),
        u_seed in any::<u64>(),
    ) {
        let xf = if is_scaled { scaled() } else { DAffine3::IDENTITY };
        let tri = blocky_volume(seed, xf);
        let ray = make_ray(xf, DVec3::new(ox, oy, oz), [0, 0, 0], DVec3::new(dx, dy, dz));
        prop_assume!(ray.is_some());
        let ray = ray.unwrap();
        check_pieces(&tri, &ray, 0.0, len)?;
        check_cubics(&tri, &ray, 0.0, len, u_seed)?;
        for (k, p) in tri.segments(&ray, 0.0, len).enumerate() {
            for f in uniforms(u_seed ^ (k as u64 + 1), 4) {
                let u = f * (p.t1 - p.t0);
                let want = f64::from(tri.values_at(ray.at(p.t0 + u)).source);
                let got = f64::from(p.source_at(u));
                prop_assert!((got - want).abs() <= 1e-4 * want.abs() + 1e-6, "source at u = {u}: {got}, interpolated {want}, piece {:?}", p);
            }
        }
        let (od, _) = tri.optical_depth(0.7, &ray, len, f64::INFINITY);
        let (want, _) = optical_depth_along(tri.segments(&ray, 0.0, len), 0.7, f64::INFINITY);
        prop_assert!((od - want).abs() <= 1e-12 * (1.0 + want), "density walk {od} against {want}");
    }

    #[test]
    fn dual_pieces_carry_their_corners_albedo(
        seed in 0u32..40,
        ox in -30.0f64..30.0, oy in -20.0f64..25.0, oz in -10.0f64..25.0,
        dx in axis_component(), dy in axis_component(), dz in axis_component(),
        len in 0.1f64..200.0,
        is_scaled in any::<bool>(),
    ) {
        let xf = if is_scaled { scaled() } else { DAffine3::IDENTITY };
        let tri = sparse_volume(seed, xf);
        let ray = make_ray(xf, DVec3::new(ox, oy, oz), [0, 0, 0], DVec3::new(dx, dy, dz));
        prop_assume!(ray.is_some());
        check_albedo(&tri, &ray.unwrap(), 0.0, len)?;
    }

    /// Shadow rays walk the dual cells reading density alone
    /// (`volume::trilinear::density`): the same optical depth as the sum over the full
    /// walk's pieces (equal up to rounding where 8 corners agree in density but not in
    /// source or albedo, which the density walk merges into a constant piece), the same
    /// voxel steps, and the same early stop.
    #[test]
    fn density_walk_optical_depth_matches_the_full_walk(
        seed in 0u32..40,
        ox in -30.0f64..30.0, oy in -20.0f64..25.0, oz in -10.0f64..25.0,
        sx in snap_mode(), sy in snap_mode(), sz in snap_mode(),
        dx in axis_component(), dy in axis_component(), dz in axis_component(),
        len in 0.1f64..200.0,
        is_scaled in any::<bool>(),
        stop in prop_oneof![Just(f64::INFINITY), 0.5f64..20.0],
    ) {
        let xf = if is_scaled { scaled() } else { DAffine3::IDENTITY };
        let tri = sparse_volume(seed, xf);
        let ray = make_ray(xf, DVec3::new(ox, oy, oz), [sx, sy, sz], DVec3::new(dx, dy, dz));
        prop_assume!(ray.is_some());
        let ray = ray.unwrap();
        let sigma_t = 0.7;
        let (od, steps) = tri.optical_depth(sigma_t, &ray, len, stop);
        let (want, want_steps) = optical_depth_along(tri.segments(&ray, 0.0, len), sigma_t, stop);
        if stop.is_infinite() {
            prop_assert!((od - want).abs() <= 1e-12 * (1.0 + want), "density walk {od} against {want}");
            prop_assert_eq!(steps, want_steps);
        } else {
            // Both stop in the piece that passes `stop` (or run to the end below it)
            prop_assert_eq!(od > stop, want > stop, "density walk {} against {} (stop {})", od, want, stop);
            if want <= stop {
                prop_assert!((od - want).abs() <= 1e-12 * (1.0 + want), "density walk {od} against {want}");
            }
        }
    }
}

#[test]
fn point_values_follow_box_sampler() {
    let tri = sparse_volume(3, DAffine3::IDENTITY);
    let vol = tri.volume();
    for (k, f) in uniforms(11, 60).chunks(3).enumerate() {
        // At a voxel centre: that voxel's values
        let v = IVec3::new(-17, -9, -1)
            + (DVec3::new(f[0], f[1], f[2]) * DVec3::new(34.0, 26.0, 18.0)).as_ivec3();
        let at = tri.values_at(v.as_dvec3());
        assert_eq!(
            (at.density, at.source),
            (vol.voxel(v).density, vol.voxel(v).source),
            "centre {v}"
        );
        // Half-way along +x: the mean of the two voxels
        let mid = tri.interpolate_index(v.as_dvec3() + DVec3::new(0.5, 0.0, 0.0));
        let want =
            0.5 * (f64::from(vol.voxel(v).density) + f64::from(vol.voxel(v + IVec3::X).density));
        assert!(
            (mid.density() - want).abs() <= 1e-12 * (1.0 + want),
            "{k}: {} vs {want}",
            mid.density()
        );
        assert!((mid.weights.iter().sum::<f64>() - 1.0).abs() < 1e-15);
    }
}

/// Volume with two non-zero voxels at the corners of brick (1,1,1): (8,8,8) and
/// (15,15,15). `neighbours`: also store the 26 bricks around it (all zero), so the
/// neighbours are uniform zero pyramid nodes rather than missing bricks.
fn corner_voxels(neighbours: bool) -> Trilinear {
    let leaves: Vec<IVec3> = if neighbours {
        (0..27).map(|i| IVec3::new(i % 3, (i / 3) % 3, i / 9) * 8).collect()
    } else {
        vec![IVec3::splat(8)]
    };
    let hot = |p: IVec3| p == IVec3::splat(8) || p == IVec3::splat(15);
    let d = grid("density", DAffine3::IDENTITY, &leaves, |p| if hot(p) { 3.0 } else { 0.0 });
    let s = grid("temperature", DAffine3::IDENTITY, &leaves, |p| if hot(p) { 2000.0 } else { 0.0 });
    Trilinear::new(Volume::build(&d, Some(&s), |v| v).unwrap())
}

/// `∫ρ` along `ray` by a 10⁵-step midpoint march of [`Field::values_at`] over the part of
/// the ray inside `[lo, hi]` (index space = world space here), where all density lies.
fn marched_integral(tri: &Trilinear, ray: &Ray, lo: DVec3, hi: DVec3) -> f64 {
    let Some((a, b)) = clip_to_box(ray.origin, ray.direction, lo, hi, 0.0, f64::INFINITY) else {
        return 0.0;
    };
    let n = 100_000;
    let h = (b - a) / f64::from(n);
    (0..n)
        .map(|k| f64::from(tri.values_at(ray.at(a + (f64::from(k) + 0.5) * h)).density))
        .sum::<f64>()
        * h
}

/// Rays that cross only the bricks next to a hot voxel's brick (in nearest terms) within
/// one voxel of it still see its density: the dual pyramid covers each node's support
/// dilated by one voxel, and the clip box is grown by ½ voxel.
#[test]
fn skipping_sees_density_across_node_faces() {
    for neighbours in [false, true] {
        let tri = corner_voxels(neighbours);
        let us = uniforms(7, 400);
        for (k, u) in us.chunks(4).enumerate() {
            // Low corner (8,8,8): a plane z ∈ (7, 7.5), below brick (1,1,1)'s first voxel
            // face; high corner (15,15,15): z ∈ (15.5, 16), above its last.
            let (hot, z) =
                if k % 2 == 0 { (8.0, 7.0 + 0.5 * u[0]) } else { (15.0, 15.5 + 0.5 * u[0]) };
            let through = DVec3::new(hot - 1.0 + 2.0 * u[1], hot - 1.0 + 2.0 * u[2], z);
            let phi = std::f64::consts::TAU * u[3];
            let direction = match k % 8 {
                0 | 1 => DVec3::X,
                2 | 3 => DVec3::new(-0.0, -1.0, 0.0),
                _ => DVec3::new(phi.cos(), phi.sin(), 0.0),
            };
            let ray = Ray { origin: through - 40.0 * direction, direction };
            let pieces: Vec<CubicSegment> = tri.segments(&ray, 0.0, f64::INFINITY).collect();
            let got: f64 = pieces.iter().map(density_integral).sum();
            let want =
                marched_integral(&tri, &ray, DVec3::splat(hot - 1.0), DVec3::splat(hot + 1.0));
            assert!(want > 0.0, "ray {k} passes through the support");
            assert!((got - want).abs() <= 1e-6 * want, "neighbours {neighbours}, ray {k} {ray:?}: ∫ρ = {got}, marched {want}; pieces {pieces:?}");
        }
    }
}

/// A volume constant inside its bricks: inside the voxel centres' box every piece is
/// constant (one merged piece), and ∫ρ equals the nearest reconstruction's.
#[test]
fn constant_volume_gives_constant_pieces() {
    let leaves: Vec<IVec3> = (0..12).map(|i| IVec3::new(i % 3, (i / 3) % 2, i / 6) * 8).collect();
    let xf = scaled();
    let d = grid("density", xf, &leaves, |_| 2.0);
    let s = grid("temperature", xf, &leaves, |_| 1500.0);
    let tri = Trilinear::new(Volume::build(&d, Some(&s), |v| v).unwrap());
    let nearest = tri.volume();
    // Voxel centres span [0, 23] × [0, 15] × [0, 15]; keep clear of its faces by 10⁻⁶
    let (lo, hi) = (DVec3::splat(1e-6), DVec3::new(23.0, 15.0, 15.0) - 1e-6);
    let ifw = nearest.index_from_world();
    for (k, u) in uniforms(5, 600).chunks(6).enumerate() {
        let a = xf.transform_point3(lo + (hi - lo) * DVec3::new(u[0], u[1], u[2]));
        let b = xf.transform_point3(lo + (hi - lo) * DVec3::new(u[3], u[4], u[5]));
        let ray = Ray { origin: a, direction: (b - a).normalize() };
        let (t0, t1) = clip_to_box(
            ifw.transform_point3(a),
            ifw.transform_vector3(ray.direction),
            lo,
            hi,
            -1e9,
            1e9,
        )
        .expect("origin inside");
        let pieces: Vec<CubicSegment> = tri.segments(&ray, t0, t1).collect();
        assert_eq!(pieces.len(), 1, "ray {k}: {pieces:?}");
        assert!(
            pieces[0].constant && pieces[0].density_cubic() == [2.0, 0.0, 0.0, 0.0],
            "ray {k}: {:?}",
            pieces[0]
        );
        let near: f64 =
            nearest.segments(&ray, t0, t1).map(|s| f64::from(s.density) * s.length()).sum();
        assert!((density_integral(&pieces[0]) - near).abs() <= 1e-12 * near, "ray {k}");
    }
    // Whole axis-parallel rays through the interior: the ramps at the faces integrate to
    // what the nearest voxels' half-voxel overhang does.
    for (k, u) in uniforms(6, 40).chunks(2).enumerate() {
        let ray = Ray {
            origin: xf.transform_point3(DVec3::new(-5.0, 15.0 * u[0], 15.0 * u[1])),
            direction: xf.transform_vector3(DVec3::X).normalize(),
        };
        let got: f64 = tri.segments(&ray, 0.0, f64::INFINITY).map(|p| density_integral(&p)).sum();
        let near: f64 = nearest
            .segments(&ray, 0.0, f64::INFINITY)
            .map(|s| f64::from(s.density) * s.length())
            .sum();
        assert!((got - near).abs() <= 1e-12 * near, "axis ray {k}: {got} vs {near}");
    }
}

/// Every dual pyramid node bounds every voxel that any dual cell beneath it reads.
#[test]
fn dual_pyramid_bounds_cover_every_corner() {
    for seed in 0..4 {
        let tri = sparse_volume(seed, DAffine3::IDENTITY);
        let vol = tri.volume();
        let levels = tri.dual_pyramid_levels();
        let Bounds3 { lo, hi } = vol.index_bounds();
        // Dual table: one brick more on the low side
        let (first, end) = ((lo + 0.5).as_ivec3() - 8, (hi + 0.5).as_ivec3());
        assert_eq!(levels[0].dims, (end - first) / 8);
        for x in first.x..end.x {
            for y in first.y..end.y {
                for z in first.z..end.z {
                    let i = IVec3::new(x, y, z);
                    for c in 0..8 {
                        let v = vol.voxel(i + IVec3::new(c & 1, (c >> 1) & 1, c >> 2));
                        for (k, level) in levels.iter().enumerate() {
                            let node = level.get((i - first).div_euclid(IVec3::splat(8 << k)));
                            assert!(
                                node.density_min <= v.density && v.density <= node.density_max,
                                "level {k} density, cell {i}"
                            );
                            assert!(
                                node.source_min <= v.source && v.source <= node.source_max,
                                "level {k} source, cell {i}"
                            );
                        }
                    }
                }
            }
        }
        assert_eq!(levels.last().unwrap().nodes.len(), 1, "single root");
    }
}

/// The dual pyramid and the block masks cost a few per cent of the volume (one pyramid
/// more, on a table one brick larger per axis, and 8 bytes per brick).
#[test]
fn dual_pyramid_is_small_next_to_the_volume() {
    let ex = plume_synth::explosion(&plume_synth::ExplosionParams {
        resolution: 128,
        ..Default::default()
    });
    let tri = Trilinear::new(Volume::build(&ex.density, Some(&ex.temperature), |v| v).unwrap());
    let (dual, volume) = (tri.dual_bytes(), tri.volume().memory_bytes());
    let ratio = dual as f64 / volume as f64;
    println!(
        "128³ explosion: dual pyramid and block masks {dual} B, volume {volume} B: {:.2} %",
        100.0 * ratio
    );
    assert!(
        ratio <= 0.10,
        "dual pyramid and block masks {dual} B is {:.1} % of the volume's {volume} B",
        100.0 * ratio
    );
    assert_eq!(tri.data_bytes(), dual + volume);
}

/// `Volume::voxel_block` (each brick the corners lie in found once, the corners placed by
/// the 9³ window's table) gives what 8 `Volume::voxel` lookups give, for every cell of the sparse volume and a layer around
/// it: inside bricks, on their high faces (where the corners span 2–8 bricks), at missing
/// and constant bricks, and outside the table (negative coordinates included).
#[test]
fn voxel_block_matches_eight_voxel_lookups() {
    let tri = sparse_volume(11, DAffine3::IDENTITY);
    let volume = tri.volume();
    let mut checked = 0;
    for z in -2..18 {
        for y in -10..18 {
            for x in -18..18 {
                let cell = IVec3::new(x, y, z);
                let block = volume.voxel_block(cell);
                for (c, got) in block.iter().enumerate() {
                    let want = volume.voxel(
                        cell + IVec3::new((c & 1) as i32, ((c >> 1) & 1) as i32, (c >> 2) as i32),
                    );
                    assert_eq!(
                        (got.density.to_bits(), got.source.to_bits()),
                        (want.density.to_bits(), want.source.to_bits()),
                        "cell {cell}, corner {c}"
                    );
                }
                checked += 1;
            }
        }
    }
    assert_eq!(checked, 20 * 28 * 36);
}

/// [`Volume::brick_block`] gives what 8 calls of [`Volume::brick`] give (the same brick
/// records, or none), for every dual brick of a sparse generated explosion and two
/// layers of bricks around its table, where some corners fall outside it.
#[test]
fn brick_block_finds_the_bricks_brick_finds() {
    let ex = plume_synth::explosion(&plume_synth::ExplosionParams {
        resolution: 40,
        seed: 3,
        ..Default::default()
    });
    let volume = Volume::build(&ex.density, Some(&ex.temperature), |v| v).unwrap();
    let (lo, hi) = (volume.brick_lo - 2, volume.brick_lo + volume.dims + 1);
    let (mut found, mut missing) = (0, 0);
    for z in lo.z..=hi.z {
        for y in lo.y..=hi.y {
            for x in lo.x..=hi.x {
                let b = IVec3::new(x, y, z);
                for (c, got) in volume.brick_block(b).into_iter().enumerate() {
                    let want = volume.brick(b + plume_volume::trilinear::window::corner_offset(c));
                    match (got.map(|(_, b)| b), want) {
                        (Some(g), Some(w)) => {
                            assert!(std::ptr::eq(g, w), "dual brick {b}, corner {c}")
                        }
                        (None, None) => {}
                        _ => panic!(
                            "dual brick {b}, corner {c}: {} against {}",
                            got.is_some(),
                            want.is_some()
                        ),
                    }
                    if want.is_some() {
                        found += 1;
                    } else {
                        missing += 1;
                    }
                }
            }
        }
    }
    // Not vacuous: both kinds occur, inside the table too
    assert!(found > 0 && missing > 0, "{found} found, {missing} missing");
    assert!(
        volume.dims.cmpgt(IVec3::splat(1)).all()
            && volume.brick_count() < (volume.dims.x * volume.dims.y * volume.dims.z) as usize
    );
}
