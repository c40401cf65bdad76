//! Tests of the flare generator at small resolutions (40³–1024³ listings, ≤ 256³ fills).
//! Fixed seeds; no timing asserts (figures come from the ignored `synth_flare_report`).

use std::collections::HashSet;
use std::time::Instant;

use super::*;
use plume_volume::grid::{leaf_offset, FloatGrid};

fn flare(resolution: u32, seed: u64) -> Flare {
    Flare::new(&FlareParams { resolution, seed, ..FlareParams::default() })
}

/// Every brick in `[0, brick_dims)³`, z slowest.
fn all_bricks(f: &Flare) -> impl Iterator<Item = IVec3> {
    let d = f.brick_dims();
    (0..d.z)
        .flat_map(move |z| (0..d.y).flat_map(move |y| (0..d.x).map(move |x| IVec3::new(x, y, z))))
}

/// `fill_brick` into fresh arrays.
fn fill(f: &Flare, b: IVec3) -> (bool, [f32; 512], [f32; 512]) {
    let (mut density, mut temperature) = ([f32::NAN; 512], [f32::NAN; 512]);
    let occupied = f.fill_brick(b, &mut density, &mut temperature);
    (occupied, density, temperature)
}

fn bits(values: &[f32]) -> Vec<u32> {
    values.iter().map(|v| v.to_bits()).collect()
}

fn assert_identical(a: &FloatGrid, b: &FloatGrid) {
    assert_eq!(a.name, b.name);
    assert_eq!(a.world_from_index, b.world_from_index);
    assert_eq!(a.origins, b.origins);
    assert_eq!(bits(&a.values), bits(&b.values));
}

#[test]
fn synth_flare_listing_never_misses_an_occupied_brick() {
    // 100 is not a multiple of 8: the last bricks are partial
    for (resolution, seed) in [(64, 1), (128, 1), (100, 7)] {
        let f = flare(resolution, seed);
        let listed: HashSet<IVec3> =
            (0..f.brick_dims().z).flat_map(|bz| f.bricks_in_slab(bz)).collect();
        let mut occupied = 0;
        for b in all_bricks(&f) {
            if fill(&f, b).0 {
                occupied += 1;
                assert!(
                    listed.contains(&b),
                    "{resolution}³ seed {seed}: occupied brick {b} not listed"
                );
            }
        }
        assert!(occupied > 20, "{resolution}³: only {occupied} occupied bricks");
        // Conservative, but not grossly so
        assert!(
            listed.len() < 2 * occupied,
            "{resolution}³: {} listed, {occupied} occupied",
            listed.len()
        );
    }
}

#[test]
fn synth_flare_listing_is_sorted_unique_and_in_range() {
    let f = flare(100, 2);
    let dims = f.brick_dims();
    assert_eq!(dims, IVec3::splat(13));
    for bz in 0..dims.z {
        let bricks = f.bricks_in_slab(bz);
        let key = |b: &IVec3| (b.y, b.x);
        assert!(
            bricks.windows(2).all(|w| key(&w[0]) < key(&w[1])),
            "slab {bz} not sorted by (y, x)"
        );
        for b in bricks {
            assert_eq!(b.z, bz);
            assert!(b.cmpge(IVec3::ZERO).all() && b.cmplt(dims).all(), "{b} outside {dims}");
        }
    }
    assert!(f.bricks_in_slab(-1).is_empty() && f.bricks_in_slab(dims.z).is_empty());
    assert!(!fill(&f, IVec3::new(0, 0, dims.z)).0 && !fill(&f, IVec3::new(-1, 0, 0)).0);
}

#[test]
fn synth_flare_values_are_finite_and_in_range() {
    let resolution = 100;
    let f = flare(resolution, 3);
    let (mut hottest, mut coolest, mut densest) = (0.0f32, f32::INFINITY, 0.0f32);
    for b in all_bricks(&f) {
        let (occupied, density, temperature) = fill(&f, b);
        assert_eq!(occupied, density.iter().any(|&d| d > 0.0), "{b}: return value");
        for o in 0..512 {
            let (d, t) = (density[o], temperature[o]);
            let p = b * 8 + IVec3::new(o as i32 >> 6, (o as i32 >> 3) & 7, o as i32 & 7);
            assert_eq!(leaf_offset(p.x, p.y, p.z), o);
            assert!(
                d.is_finite() && d >= 0.0 && t.is_finite(),
                "{p}: density {d}, temperature {t}"
            );
            if p.max_element() >= resolution as i32 {
                assert!(d == 0.0 && t == 0.0, "{p} beyond the resolution has {d}, {t}");
            }
            if d > 0.0 {
                assert!((FOOT_TEMPERATURE..=PEAK_TEMPERATURE).contains(&t), "{p}: {t} K");
                (hottest, coolest, densest) = (hottest.max(t), coolest.min(t), densest.max(d));
            } else {
                assert_eq!(t, 0.0, "{p}: temperature without density");
            }
        }
    }
    assert!(hottest > 1.2e7 && coolest < 1.5e6, "temperatures span only {coolest}–{hottest} K");
    assert!(densest > 0.1 && densest < 10.0, "densest voxel {densest}");
}

#[test]
fn synth_flare_is_deterministic_across_threads_slab_order_and_instances() {
    let params = FlareParams { resolution: 96, seed: 5, ..FlareParams::default() };
    let run = |threads| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("pool");
        pool.install(|| Flare::new(&params).to_float_grids())
    };
    let (one, two) = (run(1), run(2));
    assert_identical(&one.0, &two.0);
    assert_identical(&one.1, &two.1);
    // Bricks filled in reverse order by another instance give the same bits
    let f = Flare::new(&params);
    for (i, origin) in one.0.origins.iter().enumerate().rev() {
        let (occupied, density, temperature) = fill(&f, *origin / 8);
        assert!(occupied);
        assert_eq!(bits(&density), bits(one.0.leaf_values(i)), "density at {origin}");
        assert_eq!(bits(&temperature), bits(one.1.leaf_values(i)), "temperature at {origin}");
    }
    let other = Flare::new(&FlareParams { seed: 6, ..params }).to_float_grids();
    assert!(other.0.origins != one.0.origins || other.0.values != one.0.values);
}

#[test]
fn synth_flare_grids_hold_exactly_the_occupied_bricks() {
    let f = flare(72, 4);
    let (density, temperature) = f.to_float_grids();
    assert_eq!((density.name.as_str(), temperature.name.as_str()), ("density", "temperature"));
    assert_eq!(density.origins, temperature.origins);
    assert_eq!(density.values.len(), density.leaf_count() * 512);
    assert_eq!((density.background, temperature.background), (0.0, 0.0));
    let occupied: Vec<IVec3> = all_bricks(&f).filter(|&b| fill(&f, b).0).map(|b| b * 8).collect();
    // Leaves in (z, y, x) order of their bricks, like all_bricks
    assert_eq!(density.origins, occupied);
    for (i, origin) in density.origins.iter().enumerate() {
        let (_, d, t) = fill(&f, *origin / 8);
        assert_eq!(bits(&d), bits(density.leaf_values(i)));
        assert_eq!(bits(&t), bits(temperature.leaf_values(i)));
    }
}

#[test]
fn synth_flare_occupied_fraction_is_in_band() {
    // Documented on FlareParams: 11–16 % of bricks occupied at 256³ with the defaults
    // (13.7 % for seed 1; 5.87 % at 4096³, see synth_flare_full_4096); listed bricks are
    // at most 1.3× the occupied ones.
    let f = flare(256, 1);
    let listed: Vec<IVec3> = (0..f.brick_dims().z).flat_map(|bz| f.bricks_in_slab(bz)).collect();
    let occupied = listed.iter().filter(|&&b| fill(&f, b).0).count();
    let total = f.brick_dims().as_dvec3().element_product();
    let fraction = occupied as f64 / total;
    assert!((0.11..=0.16).contains(&fraction), "occupied fraction {fraction}");
    assert!(
        listed.len() as f64 <= 1.3 * occupied as f64,
        "{} listed, {occupied} occupied",
        listed.len()
    );
    assert_eq!(f.estimated_bytes(), listed.len() as u64 * BYTES_PER_BRICK, "exact below 64 slabs");
}

#[test]
fn synth_flare_estimate_from_sampled_slabs_is_close() {
    let f = flare(1024, 1);
    let listed: usize =
        (0..f.brick_dims().z).into_par_iter().map(|bz| f.bricks_in_slab(bz).len()).sum();
    let exact = listed as f64 * BYTES_PER_BRICK as f64;
    let estimate = f.estimated_bytes() as f64;
    assert!((estimate / exact - 1.0).abs() < 0.05, "estimate {estimate}, exact {exact}");
}

#[test]
fn synth_flare_is_a_flare() {
    // Footpoints on the photosphere, an empty top, and hot plasma low down
    let resolution = 128;
    let f = flare(resolution, 1);
    let (density, temperature) = f.to_float_grids();
    let (mut on_floor, mut high, mut hot_height, mut hot_count) = (0usize, 0usize, 0.0f64, 0usize);
    for (i, origin) in density.origins.iter().enumerate() {
        for o in 0..512 {
            let (d, t) = (density.leaf_values(i)[o], temperature.leaf_values(i)[o]);
            let y = origin.y + ((o as i32 >> 3) & 7);
            if d > 0.0 {
                on_floor += usize::from(y == 0);
                high += usize::from(y as f64 > 0.85 * f64::from(resolution));
                if t > 1.0e7 {
                    hot_height += f64::from(y) / f64::from(resolution);
                    hot_count += 1;
                }
            }
        }
    }
    assert!(on_floor > 100, "only {on_floor} voxels at the photosphere");
    assert_eq!(high, 0, "the top of the box should be empty");
    assert!(
        hot_count > 100 && hot_height / (hot_count as f64) < 0.3,
        "hot plasma: {hot_count} voxels"
    );
    // Index −½ is the photosphere corner, resolution − ½ the opposite corner
    let m = f.world_from_index();
    let lo = m.transform_point3(DVec3::splat(-0.5));
    let hi = m.transform_point3(DVec3::splat(f64::from(resolution) - 0.5));
    assert!((lo - DVec3::new(-50.0, 0.0, -50.0)).abs().max_element() < 1e-9, "{lo}");
    assert!((hi - DVec3::new(50.0, 100.0, 50.0)).abs().max_element() < 1e-9, "{hi}");
}

#[test]
fn synth_flare_fast_atan2_is_accurate() {
    for i in -2000..=2000 {
        let y = i as f32 * 0.013;
        for x in [-7.0f32, -1.0, -0.01, 0.0, 0.01, 1.0, 7.0] {
            let error = (tube::fast_atan2(y, x) - y.atan2(x)).abs();
            assert!(error < 3e-5 || (y == 0.0 && x < 0.0), "atan2({y}, {x}) off by {error}");
        }
    }
}

#[test]
#[should_panic(expected = "resolution")]
fn synth_flare_rejects_zero_resolution() {
    let _ = flare(0, 1);
}

/// Size and speed figures (`cargo test --lib synth_flare_report -- --ignored --nocapture`):
/// listed and occupied bricks at 256³–1024³, all listings at 4096³ (wall time, all
/// threads), occupancy and fill speed (thread CPU time, one thread) on 8 sampled 4096³ slabs.
#[test]
#[ignore]
fn synth_flare_report() {
    let gb = |bricks: usize| bricks as f64 * BYTES_PER_BRICK as f64 / 1e9;
    for resolution in [256u32, 512, 1024] {
        let f = flare(resolution, 1);
        let listed: Vec<IVec3> =
            (0..f.brick_dims().z).into_par_iter().flat_map(|bz| f.bricks_in_slab(bz)).collect();
        let occupied = listed.par_iter().filter(|&&b| fill(&f, b).0).count();
        let total = f.brick_dims().as_dvec3().element_product();
        println!(
            "{resolution}³: {} listed ({:.2} %, {:.3} GB), {occupied} occupied ({:.2} %, {:.3} GB)",
            listed.len(),
            100.0 * listed.len() as f64 / total,
            gb(listed.len()),
            100.0 * occupied as f64 / total,
            gb(occupied)
        );
    }
    // Largest resolution whose estimate fits the CLI's 8 GiB .vdb limit
    let (mut fits, mut too_big) = (1024u32, 4096u32);
    while too_big - fits > 16 {
        let middle = (fits + too_big) / 2;
        if flare(middle, 1).estimated_bytes() <= 8 << 30 {
            fits = middle
        } else {
            too_big = middle
        }
    }
    println!("largest resolution under an 8 GiB estimate: ≈ {fits}");
    let t = Instant::now();
    let f = flare(4096, 1);
    let built = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let listed: usize =
        (0..f.brick_dims().z).into_par_iter().map(|bz| f.bricks_in_slab(bz).len()).sum();
    let listing = t.elapsed().as_secs_f64();
    let total = f.brick_dims().as_dvec3().element_product();
    println!(
        "4096³: new {built:.2} s; all 512 slabs listed in {listing:.2} s ({} threads): {listed} bricks ({:.2} %, {:.1} GB); estimated_bytes {:.1} GB",
        rayon::current_num_threads(),
        100.0 * listed as f64 / total,
        gb(listed),
        f.estimated_bytes() as f64 / 1e9
    );
    let (mut filled, mut occupied, mut seconds) = (0usize, 0usize, 0.0);
    let (mut density, mut temperature) = ([0.0; 512], [0.0; 512]);
    for i in 0..8 {
        let bricks = f.bricks_in_slab((2 * i + 1) * 512 / 16);
        let start = thread_cpu_seconds();
        for &b in &bricks {
            occupied += usize::from(f.fill_brick(b, &mut density, &mut temperature));
        }
        seconds += thread_cpu_seconds() - start;
        filled += bricks.len();
    }
    let ratio = occupied as f64 / filled as f64;
    println!(
        "4096³ sampled slabs: {filled} listed bricks filled, {:.1} % occupied ⇒ ≈ {:.0} occupied bricks ({:.2} %, {:.1} GB); {:.0} listed bricks/s per core ({:.0} MB/s of output)",
        100.0 * ratio,
        ratio * listed as f64,
        100.0 * ratio * listed as f64 / total,
        gb((ratio * listed as f64) as usize),
        filled as f64 / seconds,
        occupied as f64 * BYTES_PER_BRICK as f64 / seconds / 1e6
    );
}

/// CPU time of the calling thread, seconds (wall time means little on a shared machine).
fn thread_cpu_seconds() -> f64 {
    let mut t = libc::timespec { tv_sec: 0, tv_nsec: 0 };
    // SAFETY: `t` is a valid, writable timespec for the duration of the call.
    unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut t) };
    t.tv_sec as f64 + 1e-9 * t.tv_nsec as f64
}

#[test]
fn synth_flare_listing_is_conservative_on_sampled_high_resolution_slabs() {
    // Every brick of a few slabs, at resolutions where tubes are many voxels thick
    for (resolution, slabs) in [(512u32, vec![18, 30, 44]), (4096, vec![150])] {
        let f = flare(resolution, 1);
        let dims = f.brick_dims();
        for bz in slabs {
            let listed: HashSet<IVec3> = f.bricks_in_slab(bz).into_iter().collect();
            let occupied: Vec<IVec3> = (0..dims.y)
                .into_par_iter()
                .flat_map_iter(|y| (0..dims.x).map(move |x| IVec3::new(x, y, bz)))
                .filter(|&b| fill(&f, b).0)
                .collect();
            assert!(occupied.len() > 50, "{resolution}³ slab {bz}: {} occupied", occupied.len());
            for b in occupied {
                assert!(listed.contains(&b), "{resolution}³: occupied brick {b} not listed");
            }
        }
    }
}

/// Costs at the largest resolution: `new`, one slab's listing, `estimated_bytes`
/// (`cargo test --lib synth_flare_huge -- --ignored --nocapture`).
#[test]
#[ignore]
fn synth_flare_huge_resolution_costs() {
    let t = Instant::now();
    let f = flare(65536, 1);
    println!("65536³: new {:.2} s", t.elapsed().as_secs_f64());
    let t = Instant::now();
    let n = f.bricks_in_slab(2000).len();
    println!("one slab: {n} bricks in {:.2} s", t.elapsed().as_secs_f64());
    let t = Instant::now();
    println!(
        "estimate {:.1} TB in {:.2} s",
        f.estimated_bytes() as f64 / 1e12,
        t.elapsed().as_secs_f64()
    );
}

/// The whole 4096³ dataset, filled and dropped, in parallel over slabs like a writer:
/// exact occupied bricks, wall time (`cargo test --lib synth_flare_full_4096 -- --ignored
/// --nocapture`; minutes).
#[test]
#[ignore]
fn synth_flare_full_4096() {
    let t = Instant::now();
    let f = flare(4096, 1);
    let (listed, occupied, cpu) = (0..f.brick_dims().z)
        .into_par_iter()
        .map(|bz| {
            let start = thread_cpu_seconds();
            let bricks = f.bricks_in_slab(bz);
            let (mut density, mut temperature) = ([0.0; 512], [0.0; 512]);
            let occupied =
                bricks.iter().filter(|&&b| f.fill_brick(b, &mut density, &mut temperature)).count();
            (bricks.len(), occupied, thread_cpu_seconds() - start)
        })
        .reduce(|| (0, 0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1, a.2 + b.2));
    let total = f.brick_dims().as_dvec3().element_product();
    println!(
        "4096³ full: {listed} listed, {occupied} occupied ({:.2} %, {:.2} GB = {:.2} GiB) in {:.0} s wall on {} threads, {:.0} s CPU ({:.0} MB/s per CPU second)",
        100.0 * occupied as f64 / total,
        occupied as f64 * BYTES_PER_BRICK as f64 / 1e9,
        occupied as f64 * BYTES_PER_BRICK as f64 / f64::from(1u32 << 30),
        t.elapsed().as_secs_f64(),
        rayon::current_num_threads(),
        cpu,
        occupied as f64 * BYTES_PER_BRICK as f64 / cpu / 1e6
    );
}

/// Size across seeds: bricks listed at 4096³ and occupied at 256³ for seeds 1–5
/// (`cargo test --lib synth_flare_seed_spread -- --ignored --nocapture`).
#[test]
#[ignore]
fn synth_flare_seed_spread() {
    for seed in 1..=5 {
        let f = flare(4096, seed);
        let listed: usize =
            (0..f.brick_dims().z).into_par_iter().map(|bz| f.bricks_in_slab(bz).len()).sum();
        let small = flare(256, seed);
        let occupied = (0..small.brick_dims().z)
            .flat_map(|bz| small.bricks_in_slab(bz))
            .filter(|&b| fill(&small, b).0)
            .count();
        println!(
            "seed {seed}: 4096³ {:.2} % listed, 256³ {:.2} % occupied",
            100.0 * listed as f64 / 512f64.powi(3),
            100.0 * occupied as f64 / 32f64.powi(3)
        );
    }
}
