//! Tests of the explosion generator at small resolutions (20³–64³).

use std::collections::{HashMap, HashSet};

use super::*;

fn params(resolution: u32, seed: u64) -> ExplosionParams {
    ExplosionParams { resolution, seed, ..ExplosionParams::default() }
}

/// Every stored voxel as `(index, value)`, including zeros inside leaves.
fn voxels(grid: &FloatGrid) -> impl Iterator<Item = (IVec3, f32)> + '_ {
    grid.origins.iter().enumerate().flat_map(move |(leaf, &origin)| {
        let values = grid.leaf_values(leaf);
        (0..LEAF_VOXELS as i32).map(move |o| {
            let local = IVec3::new(o >> 6, (o >> 3) & 7, o & 7);
            (origin + local, values[leaf_offset(local.x, local.y, local.z)])
        })
    })
}

fn active_count(grid: &FloatGrid) -> usize {
    grid.values.iter().filter(|&&v| v != 0.0).count()
}

/// Bitwise equality of two grids (origins, values, transform, name, background).
fn assert_identical(a: &FloatGrid, b: &FloatGrid) {
    assert_eq!(a.name, b.name);
    assert_eq!(a.world_from_index, b.world_from_index);
    assert_eq!(a.background.to_bits(), b.background.to_bits());
    assert_eq!(a.origins, b.origins);
    assert_eq!(a.values.len(), b.values.len());
    assert!(a.values.iter().zip(&b.values).all(|(x, y)| x.to_bits() == y.to_bits()));
}

#[test]
fn synth_same_seed_is_bit_identical_and_other_seed_differs() {
    let a = explosion(&params(40, 7));
    let b = explosion(&params(40, 7));
    assert_identical(&a.density, &b.density);
    assert_identical(&a.temperature, &b.temperature);
    let c = explosion(&params(40, 8));
    assert!(a.density.origins != c.density.origins || a.density.values != c.density.values);
    assert!(a.temperature.values != c.temperature.values);
}

#[test]
fn synth_is_independent_of_thread_count() {
    let run = |threads| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("pool");
        pool.install(|| explosion(&params(48, 3)))
    };
    let (one, two) = (run(1), run(2));
    assert_identical(&one.density, &two.density);
    assert_identical(&one.temperature, &two.temperature);
}

#[test]
fn synth_leaves_are_aligned_unique_in_range_and_non_empty() {
    for resolution in [32, 45] {
        let e = explosion(&params(resolution, 1));
        for grid in [&e.density, &e.temperature] {
            assert!(grid.leaf_count() > 0, "{} has no leaves", grid.name);
            assert_eq!(grid.values.len(), grid.leaf_count() * LEAF_VOXELS);
            let mut seen = HashSet::new();
            for (leaf, &origin) in grid.origins.iter().enumerate() {
                assert_eq!(origin % LEAF_DIM, IVec3::ZERO, "{origin} not leaf-aligned");
                assert!(origin.min_element() >= 0 && origin.max_element() < resolution as i32);
                assert!(seen.insert(origin), "duplicate leaf {origin}");
                assert!(grid.leaf_values(leaf).iter().any(|&v| v != 0.0), "empty leaf {origin}");
            }
            // Lexicographic (x, y, z) order, as documented.
            let key = |o: &IVec3| (o.x, o.y, o.z);
            assert!(grid.origins.windows(2).all(|w| key(&w[0]) < key(&w[1])));
        }
    }
}

#[test]
fn synth_voxels_outside_the_resolution_are_zero() {
    let resolution = 45; // not a multiple of 8
    let e = explosion(&params(resolution, 1));
    for grid in [&e.density, &e.temperature] {
        for (p, v) in voxels(grid) {
            if p.max_element() >= resolution as i32 {
                assert_eq!(v, 0.0, "{} at {p} beyond resolution", grid.name);
            }
        }
    }
}

#[test]
fn synth_is_sparse_with_a_sparser_temperature_grid() {
    let resolution = 64u32;
    let e = explosion(&params(resolution, 1));
    let cube = f64::from(resolution).powi(3);
    let density_active = active_count(&e.density);
    let temperature_active = active_count(&e.temperature);
    let fraction = density_active as f64 / cube;
    assert!(fraction > 0.03 && fraction < 0.5, "active fraction {fraction}");
    let leaf_fraction = e.density.leaf_count() as f64 * LEAF_VOXELS as f64 / cube;
    assert!(leaf_fraction < 0.6, "leaf fraction {leaf_fraction}");
    assert!(temperature_active > 0 && temperature_active < density_active / 2);
    assert!(e.temperature.leaf_count() < e.density.leaf_count());
}

#[test]
fn synth_values_are_in_range() {
    let e = explosion(&params(48, 5));
    assert!(e.density.values.iter().all(|&d| d.is_finite() && (0.0..=SMOKE_MAX).contains(&d)));
    let max = e.density.values.iter().copied().fold(0.0f32, f32::max);
    assert!(max > 0.8, "densest voxel only {max}");
    let core = ExplosionParams::default().core_temperature;
    for &t in &e.temperature.values {
        assert!(t == 0.0 || (500.0..=4000.0).contains(&t) && t <= core, "temperature {t}");
    }
    // Fire only where there is smoke.
    let density_at: HashMap<IVec3, f32> = voxels(&e.density).collect();
    for (p, t) in voxels(&e.temperature) {
        if t > 0.0 {
            assert!(density_at.get(&p).copied().unwrap_or(0.0) > 0.0, "fire without smoke at {p}");
        }
    }
}

#[test]
fn synth_has_a_hot_core_and_a_cool_shell() {
    let resolution = 64;
    let e = explosion(&params(resolution, 2));
    let world_from_index = e.temperature.world_from_index;
    let density_at: HashMap<IVec3, f32> = voxels(&e.density).collect();
    // Mean temperature (zeros included) over smoke voxels in a ball around the core and in
    // the shell of the cap beyond it.
    let (mut core, mut shell) = ((0.0f64, 0usize), (0.0f64, 0usize));
    let temperature_at: HashMap<IVec3, f32> = voxels(&e.temperature).collect();
    for p in density_at.iter().filter(|(_, &d)| d > 0.0).map(|(p, _)| *p) {
        let r = (world_from_index.transform_point3(p.as_dvec3()).as_vec3() - CORE_CENTRE).length();
        let t = f64::from(temperature_at.get(&p).copied().unwrap_or(0.0));
        if r < 0.3 {
            core = (core.0 + t, core.1 + 1);
        } else if r > 0.95 && r < 1.4 {
            shell = (shell.0 + t, shell.1 + 1);
        }
    }
    let (core_mean, shell_mean) = (core.0 / core.1 as f64, shell.0 / shell.1 as f64);
    assert!(core.1 > 50 && shell.1 > 50, "too few voxels: {core:?} {shell:?}");
    assert!(core_mean > 1800.0, "core mean {core_mean} K");
    assert!(shell_mean < 0.25 * core_mean, "shell mean {shell_mean} K, core {core_mean} K");
}

#[test]
fn synth_transform_spans_the_world_cube() {
    for resolution in [1, 32, 45, 1000] {
        let m = world_from_index(resolution);
        let lo = m.transform_point3(DVec3::splat(-0.5));
        let hi = m.transform_point3(DVec3::splat(f64::from(resolution) - 0.5));
        assert!((lo + 2.0).abs().max_element() < 1e-12, "{resolution}: {lo}");
        assert!((hi - 2.0).abs().max_element() < 1e-12, "{resolution}: {hi}");
    }
}

#[test]
fn synth_leaf_culling_is_conservative() {
    let p = params(40, 9);
    let culled = generate(&p, true);
    let full = generate(&p, false);
    assert_identical(&culled.density, &full.density);
    assert_identical(&culled.temperature, &full.temperature);
}

#[test]
fn synth_samples_the_same_volume_at_every_resolution() {
    // Voxel centres of 20³ coincide with those of 60³ at index 3i + 1.
    let coarse = explosion(&params(20, 4));
    let fine = explosion(&params(60, 4));
    let fine_density: HashMap<IVec3, f32> = voxels(&fine.density).collect();
    let mut compared = 0;
    for (p, d) in voxels(&coarse.density).filter(|(p, _)| p.max_element() < 20) {
        let f = fine_density.get(&(p * 3 + 1)).copied().unwrap_or(0.0);
        assert!((d - f).abs() < 1e-3, "{p}: {d} at 20³, {f} at 60³");
        compared += usize::from(d > 0.0);
    }
    assert!(compared > 1000);
}

#[test]
fn synth_envelope_bound_holds_for_turbulence_extremes() {
    for turbulence in [0.0, 1.5] {
        let p = ExplosionParams { resolution: 32, turbulence, ..ExplosionParams::default() };
        let culled = generate(&p, true);
        let full = generate(&p, false);
        assert_identical(&culled.density, &full.density);
        assert!(culled.density.leaf_count() > 0);
    }
}

#[test]
#[should_panic(expected = "resolution")]
fn synth_rejects_zero_resolution() {
    let _ = explosion(&params(0, 1));
}
