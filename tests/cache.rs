//! Brick cache files (`plume prepare`, `.plume` inputs, automatic caches): bit-identical
//! renders to in-core ones, and damaged, truncated, stale or mismatched caches detected.

use crate::common;

use std::path::{Path, PathBuf};

use common::{explosion, exr_pixels, grid, hash, plume, plume_exits, s, stderr, tmpdir, PLUME};
use glam::{DAffine3, DVec3, IVec3};
use plume_volume::field::{Ray, RayGrid};
use plume_volume::out_of_core::format::{Header, PAGE};
use plume_volume::out_of_core::{write_volume, Cache, CacheInfo};
use plume_volume::{Field, Volume};

/// Render `input` with `extra` flags; returns the pixels.
fn render(input: &Path, out: &Path, extra: &[&str]) -> Vec<[f32; 4]> {
    let mut args = vec![
        "render",
        s(input),
        "-o",
        s(out),
        "--spp",
        "3",
        "--width",
        "40",
        "--height",
        "30",
        "--seed",
        "11",
        "-q",
    ];
    args.extend_from_slice(extra);
    let o = plume(&args);
    assert!(o.status.success(), "render {}: {}", input.display(), stderr(&o));
    exr_pixels(out)
}

fn assert_bitwise(a: &[[f32; 4]], b: &[[f32; 4]], what: &str) {
    assert_eq!(a.len(), b.len());
    let same =
        a.iter().zip(b).all(|(p, q)| p.iter().zip(q).all(|(x, y)| x.to_bits() == y.to_bits()));
    assert!(same, "{what}: pixels differ");
    assert!(
        a.iter().any(|p| p[0] > 0.0 || p[3] > 0.0),
        "{what}: the image is empty, the test proves nothing"
    );
}

#[test]
fn cached_renders_are_bit_identical_to_in_core_renders() {
    let dir = tmpdir("cache", "roundtrip");
    let vdb = explosion(&dir, 64, Some(5));
    let cache = dir.join("ex.plume");
    // The temporary a killed conversion left (a process that has exited) is removed
    let dead = std::process::Command::new("true").spawn().unwrap();
    let pid = dead.id();
    let _ = dead.wait_with_output();
    let host = std::fs::read_to_string("/proc/sys/kernel/hostname")
        .unwrap()
        .trim()
        .replace(['/', '.'], "_");
    let stale = dir.join(format!(".ex.plume.{host}.{pid}.tmp"));
    std::fs::write(&stale, b"half a cache").unwrap();
    let o = plume(&["prepare", s(&vdb), "-o", s(&cache)]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!stale.exists(), "a dead conversion's temporary is removed");
    // Every estimator and light sampling; FNEE uses the stored proxy power. Trilinear
    // reconstruction (the default) unless a case says nearest.
    for (name, flags) in [
        ("line-fnee", &["--albedo", "0.8", "--g", "0.3"][..]),
        ("point-nee", &["--method", "point-nee", "--albedo", "0.8"]),
        ("ray-march", &["--method", "ray-march"]),
        ("fnee proxy 16 (rebuilt from bricks)", &["--albedo", "0.5", "--proxy-resolution", "16"]),
        (
            "scaled and tinted",
            &[
                "--albedo",
                "0.7",
                "--emission-scale",
                "3",
                "--emission-color",
                "1,0.5,0.25",
                "--density-scale",
                "4",
            ],
        ),
        ("line-fnee, nearest", &["--albedo", "0.8", "--interpolation", "nearest"]),
    ] {
        let a = render(&vdb, &dir.join("a.exr"), flags);
        let b = render(&cache, &dir.join("b.exr"), flags);
        assert_bitwise(&a, &b, name);
        let scene = plume::output::read_exr_contents(&dir.join("b.exr"))
            .unwrap()
            .metadata
            .remove("plume:scene")
            .unwrap_or_default();
        let expected = if flags.contains(&"nearest") {
            "interpolation = \"nearest\""
        } else {
            "interpolation = \"linear\""
        };
        assert!(scene.contains(expected), "{name}: rendered with {expected}? {scene}");
    }
    // Tile-major order with read-ahead from the mapped cache, against progressive in core
    let flags = ["--albedo", "0.8", "--g", "0.3"];
    let a = render(&vdb, &dir.join("a.exr"), &flags);
    let b = render(
        &cache,
        &dir.join("b.exr"),
        &[&flags[..], &["--sample-order", "tile-major"]].concat(),
    );
    assert_bitwise(&a, &b, "tile-major from the cache");
}

#[test]
fn real_files_convert_by_streaming_and_render_identically() {
    let dir = tmpdir("cache", "real");
    for (file, flags) in [
        // Active tiles (voxelized as constant bricks), one grid, no emission
        ("../shared/data/cloud/wdas_cloud_sixteenth.vdb", &["--density-scale", "20"][..]),
        // Blender's own grid names; emission from flame_noise
        (
            "../shared/data/explosion/blender_fluid_noise_0040.vdb",
            &["--density-grid", "density_noise", "--albedo", "0.7"],
        ),
        // Kelvin temperature, blackbody
        ("../shared/data/explosion/mantaflow_explosion_kelvin_0020.vdb", &["--albedo", "0.5"]),
    ] {
        let vdb = Path::new(file);
        let cache = dir.join("real.plume");
        let mut args = vec!["prepare", file, "-o", s(&cache)];
        args.extend(
            flags.iter().filter(|f| f.starts_with("--density-grid") || f.starts_with("density_")),
        );
        let o = plume(&args);
        assert!(o.status.success(), "{file}: {}", stderr(&o));
        let a = render(vdb, &dir.join("a.exr"), flags);
        let b = render(&cache, &dir.join("b.exr"), flags);
        assert_bitwise(&a, &b, file);
    }
}

#[test]
fn a_flare_generated_straight_to_a_cache_renders_like_its_vdb() {
    let dir = tmpdir("cache", "flare");
    let (vdb, cache) = (dir.join("f.vdb"), dir.join("f.plume"));
    for out in [&vdb, &cache] {
        let o = plume(&["synth", "flare", "--resolution", "160", "--seed", "4", "-o", s(out)]);
        assert!(o.status.success(), "{}", stderr(&o));
    }
    let flags = ["--albedo", "0.6"];
    let a = render(&vdb, &dir.join("a.exr"), &flags);
    let b = render(&cache, &dir.join("b.exr"), &flags);
    assert_bitwise(&a, &b, "flare streamed to a cache vs its .vdb");
}

/// A volume with dense, constant, albedo and empty bricks, built in memory.
fn test_volume() -> Volume {
    let xf = DAffine3::from_scale_rotation_translation(
        DVec3::new(0.1, 0.12, 0.09),
        glam::DQuat::from_rotation_y(0.3),
        DVec3::new(1.0, -2.0, 0.5),
    );
    let leaves: Vec<IVec3> = (0..5)
        .flat_map(|x| (0..4).map(move |y| IVec3::new(8 * x, 8 * y, 8 * ((x + y) % 3))))
        .collect();
    let density =
        grid(
            "density",
            xf,
            &leaves,
            |p| if p.x < 16 { 0.5 } else { (hash(p, 1) % 100) as f32 * 0.03 },
        );
    let temp = grid("temperature", xf, &leaves[3..], |p| {
        if (hash(p, 2) % 4) == 0 {
            0.0
        } else {
            1500.0 + (hash(p, 3) % 2000) as f32
        }
    });
    let albedo = grid("albedo", xf, &leaves[..7], |p| (hash(p, 4) % 100) as f32 * 0.011);
    Volume::build_with_albedo(&density, Some(&temp), |v| v, Some(&albedo)).unwrap()
}

fn info() -> CacheInfo {
    CacheInfo {
        density_grid: "density".into(),
        source_grid: Some("temperature".into()),
        albedo_grid: Some("albedo".into()),
        source_key: "grid".into(),
        emission_kind: "grid".into(),
        input: None,
        backgrounds: [Some(0.0), Some(0.0), Some(1.0)],
    }
}

/// [`test_volume`] in memory, and written to a cache (in a directory named after `test`)
/// and opened from it.
fn test_cache(test: &str) -> (Volume, Cache) {
    let volume = test_volume();
    let path =
        write_volume(&tmpdir("cache", test).join("v.plume"), &volume, &info(), None).unwrap();
    let cache = Cache::open(&path).unwrap();
    (volume, cache)
}

/// A grid of `n × n` parallel rays along +z through the world-space box `lo..hi` (in x, y).
fn parallel_grid(lo: DVec3, hi: DVec3, n: usize) -> RayGrid {
    let mut rays = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            let f = DVec3::new(i as f64 / n as f64, j as f64 / n as f64, 0.0);
            let origin =
                DVec3::new(lo.x + (hi.x - lo.x) * f.x, lo.y + (hi.y - lo.y) * f.y, lo.z - 1.0);
            rays.push(Ray { origin, direction: DVec3::Z });
        }
    }
    RayGrid { rays, cells_x: n, cells_y: n }
}

/// The read-ahead reports the bytes it asked for, which the tile-major render bounds by
/// its read-ahead window: every value block once for rays through the whole volume, whole
/// blocks through part of it, none for rays that miss it or for a volume in memory.
#[test]
fn read_ahead_reports_the_bytes_it_asks_for() {
    let (volume, cache) = test_cache("read_ahead");
    let mapped = &cache.volume;
    let all = cache.meta.value_blocks * 512 * 4;
    let b = mapped.world_bounds();
    let pad = DVec3::splat(0.5);
    assert_eq!(
        mapped.read_ahead(&parallel_grid(b.lo - pad, b.hi + pad, 2)),
        all,
        "every block, once"
    );
    let mid = DVec3::new((b.lo.x + b.hi.x) / 2.0, b.hi.y, b.hi.z);
    let part = mapped.read_ahead(&parallel_grid(b.lo - pad, mid, 2));
    // (Blocks less than 16 apart are read as one run, so a part may come to all 36 here)
    assert!(part > 0 && part <= all && part % 2048 == 0, "whole blocks: {part} of {all}");
    let away = DVec3::new(b.hi.x + 10.0, b.lo.y, b.lo.z);
    assert_eq!(mapped.read_ahead(&parallel_grid(away, away + DVec3::ONE, 2)), 0, "rays that miss");
    assert_eq!(volume.read_ahead(&parallel_grid(b.lo - pad, b.hi + pad, 2)), 0, "in memory");
}

#[test]
fn a_mapped_volume_gives_the_same_segments_bit_for_bit() {
    let (volume, cache) = test_cache("segments");
    cache.check.verified().unwrap();
    let mapped = &cache.volume;
    assert!(mapped.is_mapped() && mapped.heap_bytes() < volume.heap_bytes() / 4);
    assert_eq!(mapped.brick_count(), volume.brick_count());
    assert_eq!(mapped.report, volume.report);
    let plume_volume::Bounds3 { lo, hi } = volume.world_bounds();
    let mut rays = 0;
    for i in 0..2000u32 {
        let h = |k| f64::from(hash(IVec3::new(i as i32, k, 7), 9) % 10_000) / 10_000.0;
        let o = lo - (hi - lo) * 0.2 + (hi - lo) * 1.4 * DVec3::new(h(0), h(1), h(2));
        let d = DVec3::new(h(3) - 0.5, h(4) - 0.5, h(5) - 0.5).normalize();
        let ray = Ray { origin: o, direction: d };
        let a: Vec<_> = volume.segments(&ray, 0.0, 100.0).collect();
        let b: Vec<_> = mapped.segments(&ray, 0.0, 100.0).collect();
        assert_eq!(a.len(), b.len());
        for (x, y) in a.iter().zip(&b) {
            assert_eq!(
                [
                    x.t0.to_bits(),
                    x.t1.to_bits(),
                    u64::from(x.density.to_bits()),
                    u64::from(x.source.to_bits()),
                    u64::from(x.albedo.to_bits())
                ],
                [
                    y.t0.to_bits(),
                    y.t1.to_bits(),
                    u64::from(y.density.to_bits()),
                    u64::from(y.source.to_bits()),
                    u64::from(y.albedo.to_bits())
                ]
            );
        }
        rays += usize::from(a.len() > 1);
    }
    assert!(rays > 500, "only {rays} rays hit the volume");
}

/// Prepare a small cache; returns (vdb, cache).
fn prepared(dir: &Path) -> (PathBuf, PathBuf) {
    let vdb = explosion(dir, 48, Some(5));
    let cache = dir.join("ex.plume");
    let o = plume(&["prepare", s(&vdb), "-o", s(&cache)]);
    assert!(o.status.success(), "{}", stderr(&o));
    (vdb, cache)
}

/// Render `input`, expecting failure with exit `code`, a one-line message containing
/// every one of `needles`, and no output file.
fn refused(input: &Path, dir: &Path, code: i32, needles: &[&str], extra: &[&str]) {
    let out = dir.join("refused.exr");
    let mut args = vec![
        "render",
        s(input),
        "-o",
        s(&out),
        "--spp",
        "1",
        "--width",
        "8",
        "--height",
        "8",
        "-q",
    ];
    args.extend_from_slice(extra);
    let err = plume_exits(&args, code, needles);
    assert_eq!(err.lines().filter(|l| l.starts_with("plume: error")).count(), 1, "{err}");
    assert!(!out.exists(), "an output was written from a bad cache");
}

fn section(cache: &Path, kind: plume_volume::out_of_core::format::SectionKind) -> (u64, u64) {
    let bytes = std::fs::read(cache).unwrap();
    let header: Header = bytemuck::pod_read_unaligned(&bytes[..std::mem::size_of::<Header>()]);
    let e = header.section(kind).unwrap();
    (e.offset, e.len)
}

fn flip(path: &Path, at: u64) {
    let mut bytes = std::fs::read(path).unwrap();
    bytes[at as usize] ^= 0x20;
    std::fs::write(path, bytes).unwrap();
}

#[test]
fn damaged_truncated_and_foreign_caches_are_refused() {
    use plume_volume::out_of_core::format::SectionKind;
    let dir = tmpdir("cache", "damaged");
    let (_, good) = prepared(&dir);
    let copy = |name: &str| {
        let p = dir.join(name);
        std::fs::copy(&good, &p).unwrap();
        p
    };
    // A bit flipped in each section, in the header, and the section table
    for kind in [
        SectionKind::Values,
        SectionKind::Table,
        SectionKind::Bricks,
        SectionKind::Pyramid,
        SectionKind::Proxy,
        SectionKind::Meta,
        SectionKind::Chunks,
    ] {
        let p = copy(&format!("flip-{}.plume", kind as u32));
        let (offset, len) = section(&p, kind);
        flip(&p, offset + len / 2);
        refused(&p, &dir, 3, &["brick cache", s(&p), "checksum"], &["--albedo", "0.5"]);
    }
    let p = copy("flip-header.plume");
    flip(&p, 20);
    refused(&p, &dir, 3, &["brick cache", "header"], &[]);
    // Truncated: at a section boundary, mid-values, and to less than a header
    let len = std::fs::metadata(&good).unwrap().len();
    for (i, keep) in [len - 1, len / 2, PAGE + 100, 100, 0].into_iter().enumerate() {
        let p = copy(&format!("trunc-{i}.plume"));
        std::fs::OpenOptions::new().write(true).open(&p).unwrap().set_len(keep).unwrap();
        refused(&p, &dir, 3, &["brick cache", s(&p)], &[]);
    }
    // Not a cache at all
    let p = dir.join("text.plume");
    std::fs::write(&p, vec![b'x'; 10_000]).unwrap();
    refused(&p, &dir, 3, &["brick cache", "magic"], &[]);
    // Another format version: refused as stale, with the fix
    let p = copy("old.plume");
    let mut bytes = std::fs::read(&p).unwrap();
    let mut header: Header = bytemuck::pod_read_unaligned(&bytes[..std::mem::size_of::<Header>()]);
    header.version += 1;
    header.checksum = header.compute_checksum();
    bytes[..std::mem::size_of::<Header>()].copy_from_slice(bytemuck::bytes_of(&header));
    std::fs::write(&p, bytes).unwrap();
    refused(&p, &dir, 3, &["brick cache", "version", "stale", "plume prepare"], &[]);
}

#[test]
fn stale_and_mismatched_caches_are_refused_and_automatic_caches_rebuilt() {
    let dir = tmpdir("cache", "stale");
    let (vdb, cache) = prepared(&dir);
    // Flags that map the source differently, or select other grids
    refused(
        &cache,
        &dir,
        2,
        &["--temperature-map/--temperature-cutoff/--convention", "prepare"],
        &["--temperature-cutoff", "900"],
    );
    refused(&cache, &dir, 2, &["--density-grid"], &["--density-grid", "smoke"]);
    refused(&cache, &dir, 2, &["--emission"], &["--emission", "grid"]);
    // The source changed after prepare: stale
    let bytes = std::fs::read(&vdb).unwrap();
    std::thread::sleep(std::time::Duration::from_millis(20));
    std::fs::write(&vdb, &bytes).unwrap();
    let later = std::time::SystemTime::now() + std::time::Duration::from_secs(5);
    std::fs::File::options().write(true).open(&vdb).unwrap().set_modified(later).unwrap();
    refused(&cache, &dir, 3, &["stale", "plume prepare"], &[]);

    // Automatic cache: a .vdb above a quarter of --memory-budget renders through one,
    // bit-identically; a damaged one is rebuilt
    let cache_dir = dir.join("auto");
    let flags = ["--albedo", "0.6", "--memory-budget", "64KiB", "--cache-dir", s(&cache_dir)];
    let in_core = render(&vdb, &dir.join("core.exr"), &["--albedo", "0.6"]);
    let auto = render(&vdb, &dir.join("auto.exr"), &flags);
    assert_bitwise(&in_core, &auto, "automatic cache");
    // The cache, and the lock file of its conversion (`.NAME.lock`)
    let made: Vec<_> = std::fs::read_dir(&cache_dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| plume::cache::is_cache_path(p))
        .collect();
    assert_eq!(made.len(), 1, "{made:?}");
    let (offset, len) = section(&made[0], plume_volume::out_of_core::format::SectionKind::Meta);
    flip(&made[0], offset + len / 3);
    let again = dir.join("again.exr");
    let mut args = vec![
        "render",
        s(&vdb),
        "-o",
        s(&again),
        "--spp",
        "3",
        "--width",
        "40",
        "--height",
        "30",
        "--seed",
        "11",
        "-q",
    ];
    args.extend_from_slice(&flags);
    let o = plume(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("rebuilding the automatic cache"), "{}", stderr(&o));
    assert_bitwise(&in_core, &exr_pixels(&dir.join("again.exr")), "rebuilt automatic cache");
}

/// `(RssAnon, RssFile)` of process `pid` in bytes, from /proc.
fn rss(pid: u32) -> Option<(u64, u64)> {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    let field = |name: &str| -> Option<u64> {
        let line = status.lines().find(|l| l.starts_with(name))?;
        Some(line.split_whitespace().nth(1)?.parse::<u64>().ok()? * 1024)
    };
    Some((field("RssAnon:")?, field("RssFile:")?))
}

#[test]
fn a_1_gib_cache_renders_within_a_256_mib_budget() {
    const BUDGET: u64 = 256 << 20;
    let dir = tmpdir("cache", "budget");
    let cache = dir.join("flare.plume");
    // ≈1.2 GB of bricks, written by streaming (never in memory)
    let o = plume(&["synth", "flare", "--resolution", "1152", "--seed", "2", "-o", s(&cache)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let bytes = std::fs::metadata(&cache).unwrap().len();
    assert!(bytes > 4 * BUDGET, "the dataset ({bytes} bytes) must dwarf the budget");
    let out = dir.join("flare.exr");
    let mut child = std::process::Command::new(PLUME)
        .args([
            "render",
            s(&cache),
            "-o",
            s(&out),
            "--spp",
            "2",
            "--width",
            "96",
            "--height",
            "72",
            "--albedo",
            "0.5",
        ])
        .args(["--memory-budget", "256MiB", "--threads", "2", "--sample-order", "tile-major", "-q"])
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let (mut peak_anon, mut peak_file) = (0, 0);
    while child.try_wait().unwrap().is_none() {
        if let Some((anon, file)) = rss(child.id()) {
            peak_anon = peak_anon.max(anon);
            peak_file = peak_file.max(file);
        }
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    let o = child.wait_with_output().unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    eprintln!(
        "dataset {:.2} GiB, peak RssAnon {:.1} MiB, peak RssFile {:.1} MiB",
        bytes as f64 / 1073741824.0,
        peak_anon as f64 / 1048576.0,
        peak_file as f64 / 1048576.0
    );
    assert!(peak_anon > 0, "never sampled the render's memory");
    assert!(peak_anon < BUDGET, "peak anonymous RSS {peak_anon} exceeds the 256 MiB budget");
    let pixels = exr_pixels(&out);
    assert!(pixels.iter().any(|p| p[0] > 0.0), "the flare rendered black");
    let _ = std::fs::remove_dir_all(&dir);
}

/// A cache of 34 × 32 × 32 dense bricks written from memory: 68 MiB of values, more than
/// the 64 MiB checked at open, so its values are checked in the background.
fn background_checked_cache(path: &Path) -> PathBuf {
    let leaves: Vec<IVec3> = (0..34)
        .flat_map(|x| (0..32).flat_map(move |y| (0..32).map(move |z| 8 * IVec3::new(x, y, z))))
        .collect();
    let density = grid("density", DAffine3::from_scale(DVec3::splat(0.1)), &leaves, |p| {
        0.001 + (hash(p, 5) % 1000) as f32 * 1e-3
    });
    let volume = Volume::build(&density, None, |v| v).unwrap();
    let info = CacheInfo {
        density_grid: "density".into(),
        source_grid: None,
        albedo_grid: None,
        source_key: String::new(),
        emission_kind: "none".into(),
        input: None,
        backgrounds: [Some(0.0), Some(0.0), None],
    };
    write_volume(path, &volume, &info, None).unwrap()
}

/// An automatic cache found damaged only by the background check is removed
/// (so the next run rebuilds it) only if the file at its path is still the one checked.
/// Another process may have renamed a new cache over it meanwhile, with the same size and
/// header, or hold the conversion lock while it makes one; either is left alone. Library
/// level, no timing: the file is replaced, or the lock taken, between the open and the
/// check's end, as another process would.
#[test]
fn a_damaged_automatic_cache_is_removed_only_while_it_is_the_file_checked() {
    use plume_volume::out_of_core::format::SectionKind;
    use std::os::fd::AsRawFd;
    use std::os::unix::fs::MetadataExt;
    let dir = tmpdir("cache", "remove-damaged");
    let good = background_checked_cache(&dir.join("good.plume"));
    let (offset, len) = section(&good, SectionKind::Values);
    assert!(
        len > plume_volume::out_of_core::reader::EAGER_BYTES,
        "the values must be checked in the background"
    );
    let path = dir.join("auto.plume");
    let damaged_cache = || {
        std::fs::copy(&good, &path).unwrap();
        flip(&path, offset + len / 2);
        let mut cache =
            Cache::open(&path).expect("damage in the values is found only in the background");
        cache.check.remove_on_failure();
        cache
    };
    let checked = |cache: Cache| {
        let err = cache.check.verified().expect_err("the values fail their checksum").to_string();
        assert!(
            err.contains(s(&path)) && err.contains("values section fails its checksum"),
            "{err}"
        );
        err
    };
    // Nobody else: removed
    let err = checked(damaged_cache());
    assert!(err.contains("removed this automatic cache"), "{err}");
    assert!(!path.exists(), "a damaged automatic cache is removed");
    // A good cache renamed over it while in use (another process rebuilt it): kept
    let cache = damaged_cache();
    let staged = dir.join(".auto.plume.other.tmp");
    std::fs::copy(&good, &staged).unwrap();
    std::fs::rename(&staged, &path).unwrap();
    let new_ino = std::fs::metadata(&path).unwrap().ino();
    let err = checked(cache);
    assert!(err.contains("already replaced"), "{err}");
    assert_eq!(
        std::fs::metadata(&path).map(|m| m.ino()).ok(),
        Some(new_ino),
        "the new cache was removed"
    );
    Cache::open(&path).unwrap().check.verified().expect("the new cache is whole");
    // Another process holds the conversion lock (it is making a new one): left to it
    let cache = damaged_cache();
    let lock = std::fs::File::create(dir.join(".auto.plume.lock")).unwrap();
    // SAFETY: flock on a descriptor `lock` owns; a lock of another open file conflicts
    // with the one plume takes, as another process's would.
    assert_eq!(unsafe { libc::flock(lock.as_raw_fd(), libc::LOCK_EX | libc::LOCK_NB) }, 0);
    let err = checked(cache);
    assert!(err.contains("holds its lock") && err.contains(".auto.plume.lock"), "{err}");
    assert!(path.exists(), "a cache whose lock another process holds was removed");
    drop(lock);
    let _ = std::fs::remove_dir_all(&dir);
}
