//! Light-sampling tier: every sample/pdf pair the integrator's NEE and FNEE rely on.
//!
//! - Proxy grid: cell powers against a brute-force sum, cell selection chi², the
//!   direction pdf against an independent brute-force ray walk, `∫ p_σ dω = 1` inside and
//!   outside under identity and non-uniform (scaled, rotated, sheared) transforms, and FNEE
//!   direction chi² against `p_σ` integrated per bin.
//! - Volume NEE: pdfs sum to 1, voxel chi², `pdf(p)` equals the sampled pdf bit for bit.
//!
//! The phase function and alias table they build on are tested in `sampling.rs`.
//! Fixed seeds; these chi² tests and those of `sampling.rs` are one family of [`TESTS`]
//! tests at family-wise false-failure rate [`ALPHA`] (Šidák).
//! `cargo test --test light_sampling -- --nocapture` prints p-values.

use crate::common;

use std::f64::consts::PI;

use common::{
    chi2_test, direction_bin, frame, grid, hash, mean_stderr, rng, SAMPLING_ALPHA as ALPHA,
    SAMPLING_TESTS as TESTS,
};
use glam::{DAffine3, DMat3, DVec3, IVec3};
use plume::Error;
use plume_core::sampling::phase::sample_uniform_sphere;
use plume_engine::light::fnee::ProxySampling;
use plume_engine::light::EmitterDistribution;
use plume_volume::proxy::ProxyGrid;
use plume_volume::Volume;

/// Luminance of the test emission: depends on both channels, non-zero where density is 0.
fn power(density: f32, source: f32) -> f64 {
    f64::from(source) * (0.25 + f64::from(density))
}

/// 3×2×2 bricks (voxels x ∈ [−8, 16), y, z ∈ [0, 16)) with one brick missing, one constant
/// emitting brick, one cold brick, scattered non-emitting voxels and a hot blob, so that
/// cell powers differ by orders of magnitude.
fn emitter_volume(xf: DAffine3) -> Volume {
    let mut leaves = Vec::new();
    for bx in -1..2 {
        for by in 0..2 {
            for bz in 0..2 {
                if (bx, by, bz) != (1, 1, 0) {
                    leaves.push(IVec3::new(bx, by, bz) * 8);
                }
            }
        }
    }
    let constant = IVec3::new(0, 1, 1);
    let cold = IVec3::new(-1, 0, 1);
    let brick = |p: IVec3| p.div_euclid(IVec3::splat(8));
    let density = grid("density", xf, &leaves, |p| {
        if brick(p) == constant {
            0.5
        } else {
            (hash(p, 1) % 100) as f32 / 50.0
        }
    });
    let source = grid("emission", xf, &leaves, |p| {
        if brick(p) == constant {
            2.0
        } else if brick(p) == cold || hash(p, 2) % 4 == 0 {
            0.0
        } else {
            let c = p.as_dvec3() - DVec3::new(4.0, 6.0, 9.0);
            (10.0 * (-c.length_squared() / 30.0).exp() + f64::from(hash(p, 3) % 100) / 100.0) as f32
        }
    });
    Volume::build(&density, Some(&source), |v| v).expect("test volume builds")
}

/// Non-uniform scale, shear, rotation and translation.
fn skewed_transform() -> DAffine3 {
    let shear = DMat3::from_cols(DVec3::X, DVec3::new(0.3, 1.0, 0.0), DVec3::new(0.0, -0.2, 1.0));
    let m = DMat3::from_rotation_z(0.4)
        * DMat3::from_rotation_x(-0.3)
        * DMat3::from_diagonal(DVec3::new(0.5, 1.3, 2.0))
        * shear;
    DAffine3::from_mat3_translation(m, DVec3::new(1.0, -2.0, 3.0))
}

/// Index → world of the centre of the volume's index bounds.
fn world_centre(volume: &Volume) -> DVec3 {
    let plume_volume::Bounds3 { lo, hi } = volume.index_bounds();
    volume.world_from_index().transform_point3(0.5 * (lo + hi))
}

// ---------------------------------------------------------------------------------------
// Proxy grid

/// Brute-force `P_j` of every proxy cell from `volume.voxel`, and `ΣΦ`.
fn brute_cell_probabilities(volume: &Volume, proxy: &ProxyGrid) -> (Vec<f64>, f64) {
    let plume_volume::Bounds3 { lo, hi } = volume.index_bounds();
    let (vlo, vhi) = ((lo + 0.5).as_ivec3(), (hi + 0.5).as_ivec3());
    let e = proxy.cell_edge_voxels();
    let dims = proxy.dims();
    let mut phi = vec![0.0; proxy.cell_count()];
    for z in vlo.z..vhi.z {
        for y in vlo.y..vhi.y {
            for x in vlo.x..vhi.x {
                let v = IVec3::new(x, y, z);
                let plume_volume::VoxelValues { density: d, source: s } = volume.voxel(v);
                let c = (v - vlo) / e;
                phi[(c.x + dims.x * (c.y + dims.y * c.z)) as usize] +=
                    volume.voxel_volume() * power(d, s);
            }
        }
    }
    let total: f64 = phi.iter().sum();
    (phi.iter().map(|p| p / total).collect(), total)
}

#[test]
fn proxy_cell_powers_and_selection_chi2() {
    let volume = emitter_volume(skewed_transform());
    for (resolution, edge, seed) in [(8u32, 3, 11u64), (16, 2, 12)] {
        let proxy = ProxyGrid::build(&volume, resolution, power).unwrap().expect("emits");
        assert_eq!(proxy.resolution(), resolution);
        assert_eq!(proxy.cell_edge_voxels(), edge);
        let (brute, total) = brute_cell_probabilities(&volume, &proxy);
        assert!((proxy.total_power() - total).abs() < 1e-12 * total);
        for (j, &p) in brute.iter().enumerate() {
            // Alias tables realise P_j to within ~2⁻³² absolute (sampling::alias docs)
            let pmf = proxy.cell_probability(j);
            assert_eq!(pmf == 0.0, p == 0.0, "cell {j}: {pmf} vs {p}");
            assert!((pmf - p).abs() <= 1e-12 * p + 2f64.powi(-32), "cell {j}: {pmf} vs {p}");
        }
        let n = 400_000;
        let mut observed = vec![0.0; proxy.cell_count()];
        let mut sampler = rng(seed);
        let inverse = volume.index_from_world();
        for _ in 0..n {
            let s = proxy.sample_point(
                sampler.next_f64(),
                [sampler.next_f64(), sampler.next_f64(), sampler.next_f64()],
            );
            assert_eq!(s.pmf.to_bits(), proxy.cell_probability(s.cell).to_bits());
            let (lo, hi) = proxy.cell_index_bounds(s.cell);
            let p = inverse.transform_point3(s.p_world);
            assert!(
                p.cmpge(lo - 1e-9).all() && p.cmple(hi + 1e-9).all(),
                "point {p} outside cell [{lo}, {hi}]"
            );
            observed[s.cell] += 1.0;
        }
        let expected: Vec<f64> = brute.iter().map(|p| n as f64 * p).collect();
        chi2_test(&format!("proxy_cells_r{resolution}"), &observed, &expected, ALPHA, TESTS);
    }
}

#[test]
fn proxy_resolution_is_validated() {
    let volume = emitter_volume(DAffine3::IDENTITY); // 24 voxels along x: up to 32
    for bad in [0u32, 4, 12, 64, 1 << 20] {
        match ProxyGrid::build(&volume, bad, power) {
            Err(Error::InvalidArgument { flag, message }) => {
                // The library names the scene key; the binary shows --proxy-resolution (tests/cli_method.rs)
                assert_eq!(flag, "integrator.proxy_resolution");
                assert!(message.contains(&bad.to_string()) && message.contains("32"), "{message}");
            }
            other => panic!("resolution {bad}: expected InvalidArgument, got {other:?}"),
        }
    }
    let full = ProxyGrid::build(&volume, 32, power).unwrap().unwrap();
    assert_eq!((full.cell_edge_voxels(), full.dims()), (1, IVec3::new(24, 16, 16)));
    // An empty volume has no data resolution: any power of two ≥ 8, and nothing emits
    let empty =
        Volume::build(&grid("density", DAffine3::IDENTITY, &[], |_| 0.0), None, |v| v).unwrap();
    assert!(ProxyGrid::build(&empty, 64, power).unwrap().is_none());
    assert!(matches!(ProxyGrid::build(&empty, 12, power), Err(Error::InvalidArgument { .. })));
    assert!(EmitterDistribution::build(&empty, power).unwrap().is_none());
    // Nothing emits: None; invalid power: a clear error
    assert!(ProxyGrid::build(&volume, 8, |_, _| 0.0).unwrap().is_none());
    assert!(matches!(ProxyGrid::build(&volume, 8, |_, _| f64::NAN), Err(Error::Scene(_))));
    assert!(EmitterDistribution::build(&volume, |_, _| 0.0).unwrap().is_none());
    assert!(matches!(
        EmitterDistribution::build(&volume, |_, s| if s > 5.0 { -1.0 } else { 1.0 }),
        Err(Error::Scene(_))
    ));
    eprintln!(
        "proxy memory: r8 {} B for {} cells ({} emitting); r32 {} B for {} cells ({} emitting)",
        ProxyGrid::build(&volume, 8, power).unwrap().unwrap().memory_bytes(),
        ProxyGrid::build(&volume, 8, power).unwrap().unwrap().cell_count(),
        ProxyGrid::build(&volume, 8, power).unwrap().unwrap().emitting_cell_count(),
        full.memory_bytes(),
        full.cell_count(),
        full.emitting_cell_count()
    );
}

/// `p_σ` by an independent walk: all cell-boundary crossings `t > 0` of each axis, merged;
/// along each axis a piece lies in the cell of the last boundary crossed before its
/// midpoint, judged by the crossing *times* (a position lookup would round onto the wrong
/// side of a face for rays within 10⁻¹⁶ of one).
fn brute_direction_pdf(proxy: &ProxyGrid, index_from_world: DAffine3, x: DVec3, w: DVec3) -> f64 {
    let o = index_from_world.transform_point3(x);
    let d = index_from_world.transform_vector3(w);
    let (origin, _) = proxy.cell_index_bounds(0);
    let e = f64::from(proxy.cell_edge_voxels());
    let dims = proxy.dims();
    // Per axis: (boundary k, crossing t) for every boundary from beyond the origin to
    // beyond the grid
    let mut crossings: [Vec<(i64, f64)>; 3] = Default::default();
    for a in 0..3 {
        if d[a] != 0.0 {
            let g = ((o[a] - origin[a]) / e).floor() as i64;
            for k in g.min(0) - 2..=g.max(i64::from(dims[a])) + 2 {
                crossings[a].push((k, (origin[a] + k as f64 * e - o[a]) / d[a]));
            }
        }
    }
    // No boundary crossed yet (or all passed): the piece lies outside the grid, cell −1
    let cell_at = |a: usize, t: f64| -> i64 {
        if d[a] == 0.0 {
            ((o[a] - origin[a]) / e).floor() as i64
        } else if d[a] > 0.0 {
            crossings[a].iter().filter(|c| c.1 <= t).map(|c| c.0).max().unwrap_or(-1)
        } else {
            crossings[a].iter().filter(|c| c.1 >= t).map(|c| c.0).max().unwrap_or(-1)
        }
    };
    let mut ts: Vec<f64> = std::iter::once(0.0)
        .chain(crossings.iter().flatten().map(|c| c.1).filter(|&t| t > 0.0))
        .collect();
    ts.sort_by(f64::total_cmp);
    let mut sum = 0.0;
    for pair in ts.windows(2) {
        let (t0, t1) = (pair[0], pair[1]);
        if t1 <= t0 {
            continue;
        }
        let c: Vec<i64> = (0..3).map(|a| cell_at(a, 0.5 * (t0 + t1))).collect();
        if (0..3).all(|a| c[a] >= 0 && c[a] < i64::from(dims[a])) {
            let cell =
                c[0] as usize + dims.x as usize * (c[1] as usize + dims.y as usize * c[2] as usize);
            sum += proxy.cell_probability(cell) * (t1 - t0) * (t1 * t1 + t1 * t0 + t0 * t0) / 3.0;
        }
    }
    sum / proxy.cell_volume()
}

#[test]
fn direction_pdf_matches_an_independent_walk() {
    for xf in [DAffine3::IDENTITY, skewed_transform()] {
        let volume = emitter_volume(xf);
        let inverse = volume.index_from_world();
        for resolution in [8, 16, 32] {
            let proxy = ProxyGrid::build(&volume, resolution, power).unwrap().unwrap();
            let mut sampler = rng(u64::from(resolution));
            let mut checked = 0;
            for k in 0..3000 {
                // Origins inside and outside, some on cell faces; directions some axis-aligned
                let mut o = DVec3::new(
                    -14.0 + 36.0 * sampler.next_f64(),
                    -6.0 + 28.0 * sampler.next_f64(),
                    -6.0 + 28.0 * sampler.next_f64(),
                );
                if k % 3 == 0 {
                    o = (o / 3.0).round() * 3.0 - 0.5; // on r8 faces (x from −8.5 in steps of 3)
                }
                let mut d_index = sample_uniform_sphere([sampler.next_f64(), sampler.next_f64()]);
                if k % 4 == 1 {
                    let axis = (k / 4) % 3;
                    let sign = if k % 8 == 1 { 1.0 } else { -1.0 };
                    d_index = DVec3::ZERO;
                    d_index[axis] = sign;
                    d_index[(axis + 1) % 3] = -0.0;
                }
                let x = volume.world_from_index().transform_point3(o);
                let w = volume.world_from_index().transform_vector3(d_index).normalize();
                let fast = proxy.direction_pdf(x, w);
                let brute = brute_direction_pdf(&proxy, inverse, x, w);
                assert!(fast.is_finite() && fast >= 0.0);
                assert!(
                    (fast - brute).abs() <= 1e-9 * brute.max(1e-12),
                    "r{resolution} x={x} w={w}: {fast} vs {brute}"
                );
                checked += usize::from(brute > 0.0);
            }
            assert!(checked > 500, "too few rays hit emission: {checked}");
        }
    }
}

/// `∫ p_σ dω` as the mean of `4π p_σ(ω)` over `replicates` independent jittered-stratified
/// sets of `strata²` uniform directions, with the standard error of that mean taken from
/// the spread of the replicates (honest for the stratified estimator, which the i.i.d.
/// formula would overstate several-fold).
fn sphere_integral(
    proxy: &ProxyGrid,
    x: DVec3,
    strata: usize,
    replicates: usize,
    seed: u64,
) -> (f64, f64) {
    let estimates: Vec<f64> = (0..replicates)
        .map(|r| {
            let mut sampler = rng(seed * 1000 + r as u64);
            let mut sum = 0.0f64;
            for i in 0..strata {
                for j in 0..strata {
                    let u = [
                        (i as f64 + sampler.next_f64()) / strata as f64,
                        (j as f64 + sampler.next_f64()) / strata as f64,
                    ];
                    sum += 4.0 * PI * proxy.direction_pdf(x, sample_uniform_sphere(u));
                }
            }
            sum / (strata * strata) as f64
        })
        .collect();
    mean_stderr(&estimates)
}

#[test]
fn p_sigma_integrates_to_one_over_the_sphere() {
    // 16 replicates: |mean − 1| > 5 s.e. has probability ≈ 1.6·10⁻⁴ (Student t, 15 dof)
    // per check, ≈ 2·10⁻³ over the 12 checks
    for (name, xf) in [("identity", DAffine3::IDENTITY), ("skewed", skewed_transform())] {
        let volume = emitter_volume(xf);
        let centre = world_centre(&volume);
        let plume_volume::Bounds3 { lo, hi } = volume.index_bounds();
        // Inside: near the hot blob; outside: beyond a corner, looking in
        let inside = volume.world_from_index().transform_point3(DVec3::new(3.3, 6.2, 8.7));
        let outside = volume.world_from_index().transform_point3(hi + 0.25 * (hi - lo));
        for resolution in [8, 32] {
            let proxy = ProxyGrid::build(&volume, resolution, power).unwrap().unwrap();
            for (place, x) in [("inside", inside), ("outside", outside), ("centre", centre)] {
                let (mean, se) = sphere_integral(&proxy, x, 128, 16, 40 + u64::from(resolution));
                println!("∫p_σ dω {name} r{resolution} {place}: {mean:.6} ± {se:.6} (1 s.e.)");
                assert!(
                    se > 0.0 && (mean - 1.0).abs() <= 5.0 * se,
                    "{name} r{resolution} {place}: {mean} ± {se}"
                );
            }
        }
    }
}

/// FNEE chi²: directions from `sample_direction` binned in (cos θ, φ) around `pole` over
/// `cos θ ∈ [c_min, 1]`, expected counts from `direction_pdf` integrated per bin by the
/// midpoint rule on `k × k` sub-cells (`4k × 4k` where p_σ vanishes somewhere in the bin).
/// p_σ is continuous for `x` off cell faces (chords shrink to 0 at silhouettes), so the
/// rule converges as O(1/k²).
#[allow(clippy::too_many_arguments)] // a test driver: every knob named at the call site
fn fnee_chi2(
    name: &str,
    proxy: &ProxyGrid,
    x: DVec3,
    pole: DVec3,
    c_min: f64,
    bins: (usize, usize),
    k: usize,
    n: usize,
    seed: u64,
) {
    let (nc, nphi) = bins;
    let basis = frame(pole);
    let mut observed = vec![0.0; nc * nphi];
    let mut sampler = rng(seed);
    let (mut below, mut dropped) = (0usize, 0usize);
    for _ in 0..n {
        let u_cell = sampler.next_f64();
        let u_pos = [sampler.next_f64(), sampler.next_f64(), sampler.next_f64()];
        let Some(s) = proxy.sample_direction(x, u_cell, u_pos) else {
            dropped += 1;
            continue;
        };
        assert_eq!(
            s.pdf.to_bits(),
            proxy.direction_pdf(x, s.direction).to_bits(),
            "sample and pdf paths differ"
        );
        match direction_bin(s.direction, pole, basis, c_min, nc, nphi) {
            Some(b) => observed[b] += 1.0,
            None => below += 1,
        }
    }
    assert_eq!((below, dropped), (0, 0), "{name}: samples below cos θ = {c_min} or dropped");
    let (dc, dphi) = ((1.0 - c_min) / nc as f64, 2.0 * PI / nphi as f64);
    // Midpoint rule on k × k sub-cells; also whether some sub-cell saw p_σ = 0
    let integrate = |b: usize, k: usize| -> (f64, bool) {
        let (ic, ip) = (b / nphi, b % nphi);
        let (mut integral, mut zero) = (0.0, false);
        for a in 0..k {
            let c = c_min + (ic as f64 + (a as f64 + 0.5) / k as f64) * dc;
            let s = (1.0 - c * c).max(0.0).sqrt();
            for q in 0..k {
                let phi = (ip as f64 + (q as f64 + 0.5) / k as f64) * dphi;
                let w =
                    (basis.0 * (s * phi.cos()) + basis.1 * (s * phi.sin()) + pole * c).normalize();
                let p = proxy.direction_pdf(x, w);
                integral += p;
                zero |= p == 0.0;
            }
        }
        (integral * dc * dphi / (k * k) as f64, zero)
    };
    let expected: Vec<f64> = (0..nc * nphi)
        .map(|b| {
            // Bins on or near the silhouette of the emission get a 4× finer grid, so that
            // slivers the coarse grid misses still get their (small) expected count
            let (coarse, touches_zero) = integrate(b, k);
            n as f64 * if touches_zero { integrate(b, 4 * k).0 } else { coarse }
        })
        .collect();
    let mass: f64 = expected.iter().sum::<f64>() / n as f64;
    println!("fnee {name}: integrated mass in the binned range {mass:.5}");
    chi2_test(name, &observed, &expected, ALPHA, TESTS);
}

/// Smallest cos θ around `pole` from `x` over the corners of the proxy grid (the grid lies
/// in that cone, since a convex body lies in a cone iff its vertices do).
fn cone_of_grid(proxy: &ProxyGrid, xf: DAffine3, x: DVec3, pole: DVec3) -> f64 {
    let (lo, _) = proxy.cell_index_bounds(0);
    let (_, hi) = proxy.cell_index_bounds(proxy.cell_count() - 1);
    (0..8)
        .map(|i| {
            let c = DVec3::new(
                if i & 1 == 0 { lo.x } else { hi.x },
                if i & 2 == 0 { lo.y } else { hi.y },
                if i & 4 == 0 { lo.z } else { hi.z },
            );
            (xf.transform_point3(c) - x).normalize().dot(pole)
        })
        .fold(1.0, f64::min)
}

#[test]
fn fnee_directions_match_p_sigma_chi2() {
    // Inside, identity transform, r8: the whole sphere
    let volume = emitter_volume(DAffine3::IDENTITY);
    let proxy = ProxyGrid::build(&volume, 8, power).unwrap().unwrap();
    let inside = DVec3::new(3.3, 6.2, 8.7);
    fnee_chi2(
        "fnee_inside_r8",
        &proxy,
        inside,
        DVec3::new(0.2, 0.3, 0.9).normalize(),
        -1.0,
        (16, 32),
        8,
        400_000,
        21,
    );
    // Outside, identity, r8: bins over the cone that holds the grid
    let outside = DVec3::new(-20.0, 25.0, 30.0);
    let pole = (world_centre(&volume) - outside).normalize();
    let c_min = cone_of_grid(&proxy, volume.world_from_index(), outside, pole) - 1e-3;
    fnee_chi2("fnee_outside_r8", &proxy, outside, pole, c_min, (16, 32), 8, 400_000, 22);
    // Outside, skewed transform, r16
    let volume = emitter_volume(skewed_transform());
    let proxy = ProxyGrid::build(&volume, 16, power).unwrap().unwrap();
    let outside = volume.world_from_index().transform_point3(DVec3::new(30.0, -10.0, 25.0));
    let pole = (world_centre(&volume) - outside).normalize();
    let c_min = cone_of_grid(&proxy, volume.world_from_index(), outside, pole) - 1e-3;
    fnee_chi2("fnee_outside_skewed_r16", &proxy, outside, pole, c_min, (16, 32), 8, 400_000, 23);
}

// ---------------------------------------------------------------------------------------
// Volume NEE

/// Under trilinear reconstruction NEE draws `y − i` from the hat around the chosen voxel
/// (`light/nee.rs`): the pdf is the trilinear interpolation of `P_i/V`, it integrates to 1,
/// `sample` and `pdf` agree, and the share of samples in each voxel box is exactly
/// `Σ_i P_i Π_k w(v_k − i_k)` with `w(0) = 3/4`, `w(±1) = 1/8` (the hat's mass in the box).
///
/// For both tables: one entry per voxel, or per brick with the voxel drawn from the brick.
#[test]
fn nee_hat_samples_match_the_trilinear_pdf_chi2() {
    let volume = emitter_volume(skewed_transform());
    for (table, nee) in nee_tables(&volume) {
        nee_hat_chi2(&volume, table, &nee.for_interpolation(plume_volume::Interpolation::Linear));
    }
}

/// The voxel table and the brick table of `volume`, by name.
fn nee_tables(volume: &Volume) -> [(&'static str, EmitterDistribution); 2] {
    [
        ("voxel", EmitterDistribution::build(volume, power).unwrap().expect("emits")),
        ("brick", EmitterDistribution::build_bricks(volume, power).unwrap().expect("emits")),
    ]
}

fn nee_hat_chi2(volume: &Volume, table: &str, nee: &EmitterDistribution) {
    let plume_volume::Bounds3 { lo, hi } = volume.index_bounds();
    // Voxel boxes that can receive samples: the volume's grown by one voxel
    let (vlo, vhi) = ((lo + 0.5).as_ivec3() - 1, (hi + 0.5).as_ivec3() + 1);
    let extent = vhi - vlo;
    let slot = |v: IVec3| {
        let r = v - vlo;
        (r.x + extent.x * (r.y + extent.y * r.z)) as usize
    };
    let mut weights = vec![0.0; (extent.x * extent.y * extent.z) as usize];
    for z in vlo.z + 1..vhi.z - 1 {
        for y in vlo.y + 1..vhi.y - 1 {
            for x in vlo.x + 1..vhi.x - 1 {
                let v = IVec3::new(x, y, z);
                let plume_volume::VoxelValues { density: d, source: s } = volume.voxel(v);
                let p = power(d, s);
                if p == 0.0 {
                    continue;
                }
                for k in 0..27 {
                    let o = IVec3::new(k % 3 - 1, (k / 3) % 3 - 1, k / 9 - 1);
                    let w: f64 = (0..3).map(|a| if o[a] == 0 { 0.75 } else { 0.125 }).product();
                    weights[slot(v + o)] += p * w;
                }
            }
        }
    }
    let total: f64 = weights.iter().sum();
    // ∫ p_V = 1: the pdf is trilinear on every dual cell, so the midpoint rule on 2³
    // sub-cells of each dual cell is exact
    let (inverse, forward, vv) =
        (volume.index_from_world(), volume.world_from_index(), volume.voxel_volume());
    let mut integral = 0.0;
    for z in 2 * vlo.z..2 * vhi.z {
        for y in 2 * vlo.y..2 * vhi.y {
            for x in 2 * vlo.x..2 * vhi.x {
                let p = (IVec3::new(x, y, z).as_dvec3() + 0.5) * 0.5;
                integral += nee.pdf(volume, forward.transform_point3(p)) * vv / 8.0;
            }
        }
    }
    assert!((integral - 1.0).abs() < 1e-9, "{table}: ∫ p_V = {integral}");
    let n = 1_000_000;
    let mut observed = vec![0.0; weights.len()];
    let mut sampler = rng(37);
    for _ in 0..n {
        let s = nee.sample(
            volume,
            sampler.next_f64(),
            [sampler.next_f64(), sampler.next_f64(), sampler.next_f64()],
        );
        let p = inverse.transform_point3(s.p_world);
        assert!(
            (p - s.voxel.as_dvec3()).abs().max_element() < 1.0 + 1e-9,
            "{p} outside the hat of {}",
            s.voxel
        );
        let again = nee.pdf(volume, s.p_world);
        assert!(
            s.pdf > 0.0 && (again - s.pdf).abs() <= 1e-9 * s.pdf,
            "sample pdf {} vs pdf {again}",
            s.pdf
        );
        observed[slot((p + 0.5).floor().as_ivec3())] += 1.0;
    }
    let expected: Vec<f64> = weights.iter().map(|w| n as f64 * w / total).collect();
    chi2_test(&format!("nee_hat_voxels_{table}_table"), &observed, &expected, ALPHA, TESTS);
}

/// Both tables: pdfs sum to 1 and match the brute-force power share, sample and pdf agree
/// bit for bit, and samples follow the pdf (chi²).
#[test]
fn nee_voxel_pdfs_chi2_and_bitwise_agreement() {
    let volume = emitter_volume(skewed_transform());
    let [(_, voxels), (_, bricks)] = nee_tables(&volume);
    nee_voxel_chi2(&volume, "voxel", &voxels);
    nee_voxel_chi2(&volume, "brick", &bricks);
    // The same law: each voxel's pdf agrees between the tables, to the alias tables' 32-bit
    // thresholds (each reports the exact pmf of its own quantized table, `sampling::alias`)
    let plume_volume::Bounds3 { lo, hi } = volume.index_bounds();
    let (vlo, vhi) = ((lo + 0.5).as_ivec3(), (hi + 0.5).as_ivec3());
    let mut worst = 0.0f64;
    for z in vlo.z..vhi.z {
        for y in vlo.y..vhi.y {
            for x in vlo.x..vhi.x {
                let v = IVec3::new(x, y, z);
                let (a, b) = (voxels.pdf_voxel(&volume, v), bricks.pdf_voxel(&volume, v));
                assert_eq!(a > 0.0, b > 0.0, "voxel {v}: {a} vs {b}");
                if a > 0.0 {
                    worst = worst.max((b / a - 1.0).abs());
                }
            }
        }
    }
    assert!(worst < 1e-6, "voxel and brick tables differ by {worst:e} (relative)");
    assert!(
        bricks.memory_bytes() < voxels.memory_bytes() / 8,
        "{} vs {} bytes",
        bricks.memory_bytes(),
        voxels.memory_bytes()
    );
}

fn nee_voxel_chi2(volume: &Volume, table: &str, nee: &EmitterDistribution) {
    let plume_volume::Bounds3 { lo, hi } = volume.index_bounds();
    let (vlo, vhi) = ((lo + 0.5).as_ivec3(), (hi + 0.5).as_ivec3());
    let extent = vhi - vlo;
    let slot = |v: IVec3| {
        let r = v - vlo;
        (r.x + extent.x * (r.y + extent.y * r.z)) as usize
    };
    let vv = volume.voxel_volume();
    let mut brute = vec![0.0; (extent.x * extent.y * extent.z) as usize];
    let (mut pdf_sum, mut emissive) = (0.0f64, 0usize);
    for z in vlo.z..vhi.z {
        for y in vlo.y..vhi.y {
            for x in vlo.x..vhi.x {
                let v = IVec3::new(x, y, z);
                let plume_volume::VoxelValues { density: d, source: s } = volume.voxel(v);
                let p = power(d, s);
                brute[slot(v)] = p;
                let pdf = nee.pdf_voxel(volume, v);
                assert_eq!(pdf > 0.0, p > 0.0, "voxel {v}: pdf {pdf}, power {p}");
                emissive += usize::from(p > 0.0);
                pdf_sum += pdf * vv;
                // pdf at the voxel centre goes through the world → index lookup
                assert_eq!(
                    nee.pdf(volume, volume.world_from_index().transform_point3(v.as_dvec3()))
                        .to_bits(),
                    pdf.to_bits()
                );
            }
        }
    }
    let emitting_bricks = (vlo.z..vhi.z)
        .flat_map(|z| {
            (vlo.y..vhi.y).flat_map(move |y| (vlo.x..vhi.x).map(move |x| IVec3::new(x, y, z)))
        })
        .filter(|&v| brute[slot(v)] > 0.0)
        .map(|v| v.div_euclid(IVec3::splat(8)))
        .collect::<std::collections::HashSet<_>>()
        .len();
    assert_eq!(
        nee.entry_count(),
        if table == "voxel" { emissive } else { emitting_bricks },
        "{table}"
    );
    assert!((pdf_sum - 1.0).abs() < 1e-12, "Σ pdf V = {pdf_sum}");
    let total: f64 = brute.iter().sum();
    assert!((nee.total_power() - vv * total).abs() < 1e-12 * vv * total);
    assert_eq!(nee.pdf_voxel(volume, IVec3::new(1000, 0, 0)), 0.0);
    assert_eq!(nee.pdf(volume, DVec3::splat(f64::NAN)), 0.0);

    let n = 1_000_000;
    let mut observed = vec![0.0; brute.len()];
    let mut sampler = rng(31);
    let inverse = volume.index_from_world();
    let mut face_rounding = 0usize;
    for _ in 0..n {
        let s = nee.sample(
            volume,
            sampler.next_f64(),
            [sampler.next_f64(), sampler.next_f64(), sampler.next_f64()],
        );
        assert_eq!(s.pdf.to_bits(), nee.pdf_voxel(volume, s.voxel).to_bits());
        let p = inverse.transform_point3(s.p_world);
        assert!(
            (p - s.voxel.as_dvec3()).abs().max_element() <= 0.5 + 1e-9,
            "{p} not in voxel {}",
            s.voxel
        );
        if (p + 0.5).floor().as_ivec3() == s.voxel {
            assert_eq!(nee.pdf(volume, s.p_world).to_bits(), s.pdf.to_bits());
        } else {
            face_rounding += 1; // the round trip landed on the neighbour's side of a face
        }
        observed[slot(s.voxel)] += 1.0;
    }
    assert!(face_rounding < 100, "{face_rounding} samples rounded out of their voxel");
    let expected: Vec<f64> = brute.iter().map(|p| n as f64 * p / total).collect();
    chi2_test(&format!("nee_voxels_{table}_table"), &observed, &expected, ALPHA, TESTS);
    println!(
        "nee, {table} table: {} entries for {emissive} emissive voxels, {} bytes ({:.2} B/voxel), {face_rounding} face round-trips",
        nee.entry_count(),
        nee.memory_bytes(),
        nee.memory_bytes() as f64 / emissive as f64
    );
}
