//! The streaming read (`vdb::stream`) against the whole-grid read, in both isolation modes:
//! the same blocks in the same order with the same bits, the same errors, memory bounded
//! by the topology, hostile files and broken replies refused cleanly, visitor errors
//! returned.

use crate::common;

use std::ffi::OsString;
use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use common::{data, fixture, retry_while_busy, scratch_dir, shell_script, PLUME};
use glam::{DAffine3, DVec3, IVec3};
use plume::vdb::{
    leaf_offset, list_grids, read_float_grid, read_grids_isolated, write_float_grids, FloatGrid,
    GridRequest, GridSelector, IsolationLimits, LeafData, ReadIsolation, ReadLimits, StreamedGrid,
    LEAF_VOXELS,
};
use plume::Error;

fn child(limits: IsolationLimits) -> ReadIsolation {
    ReadIsolation::Child { reader_exe: PathBuf::from(PLUME).into(), limits }
}

/// In-process, then in a child with the CLI's default limits.
fn modes() -> [ReadIsolation; 2] {
    let limits = IsolationLimits::new(&ReadLimits::default(), Duration::from_secs(60));
    [ReadIsolation::InProcess, child(limits)]
}

/// Everything one stream delivered.
#[derive(Debug, Default)]
struct Collected {
    header: Option<StreamedGrid>,
    /// Block origins in visiting order, and 512 values per block (constants expanded).
    origins: Vec<IVec3>,
    values: Vec<f32>,
    leaves: u64,
    constants: u64,
}

fn stream(
    mode: &ReadIsolation,
    path: &Path,
    selector: &GridSelector,
    limits: &ReadLimits,
) -> plume::Result<(StreamedGrid, Collected)> {
    let mut got = Collected::default();
    let mut header = |g: &StreamedGrid| {
        assert!(got.header.is_none(), "header visited twice");
        got.header = Some(g.clone());
        Ok(())
    };
    let mut origins = Vec::new();
    let mut values = Vec::new();
    let (mut leaves, mut constants) = (0, 0);
    let mut leaf = |origin: IVec3, data: LeafData<'_>| {
        origins.push(origin);
        match data {
            LeafData::Values(block) => {
                values.extend_from_slice(block);
                leaves += 1;
            }
            LeafData::Constant(v) => {
                values.extend(std::iter::repeat_n(v, LEAF_VOXELS));
                constants += 1;
            }
        }
        Ok(())
    };
    let grid = mode.stream_float_grid(path, selector, limits, &mut header, &mut leaf)?;
    got.origins = origins;
    got.values = values;
    got.leaves = leaves;
    got.constants = constants;
    Ok((grid, got))
}

/// The stream equals the whole-grid read: header, block order, every bit.
#[track_caller]
fn assert_same(what: &str, whole: &FloatGrid, grid: &StreamedGrid, got: &Collected) {
    assert_eq!(got.header.as_ref(), Some(grid), "{what}: header differs from the result");
    assert_eq!(grid.name, whole.name, "{what}");
    assert_eq!(grid.world_from_index, whole.world_from_index, "{what}");
    assert_eq!(grid.background.to_bits(), whole.background.to_bits(), "{what}");
    assert_eq!((got.leaves, got.constants), (grid.leaf_count, grid.tile_blocks), "{what}");
    assert_eq!(got.origins, whole.origins, "{what}: blocks or their order differ");
    assert_eq!(got.values.len(), whole.values.len(), "{what}");
    let differing =
        got.values.iter().zip(&whole.values).filter(|(a, b)| a.to_bits() != b.to_bits());
    assert_eq!(differing.count(), 0, "{what}: values differ");
    let bbox = (!whole.origins.is_empty()).then(|| {
        let lo = whole.origins.iter().fold(IVec3::MAX, |m, &o| m.min(o));
        let hi = whole.origins.iter().fold(IVec3::MIN, |m, &o| m.max(o + 7));
        (lo, hi)
    });
    assert_eq!(grid.index_bbox, bbox, "{what}: bounds");
}

/// Every grid of several real files and the fixture with tiles: scalar grids stream to
/// exactly what `read_float_grid` gives, others fail the same way.
#[test]
fn streams_equal_whole_grid_reads() {
    let files = [
        data("smoke/openvdb_org_smoke1.vdb"),
        data("fire/openusd_densityAndHeat.vdb"),
        data("explosion/blender_fluid_noise_0040.vdb"),
        data("explosion/mantaflow_explosion_kelvin_0020.vdb"),
        data("cloud/wdas_cloud_sixteenth.vdb"),
        data("edge_cases/arnold_usd_grids_3x_density.vdb"),
        data("edge_cases/oiio_sphereCd.vdb"),
        data("sequence/openusd_smoke_000001.vdb"),
        fixture("affine_tiles.vdb"),
    ];
    let limits = ReadLimits::default();
    let mut streamed = 0;
    for path in &files {
        for info in list_grids(path).unwrap() {
            let selector: GridSelector = info.selector.parse().unwrap();
            if info.selector == "root_tile" {
                continue; // 2^27 blocks: `a_root_tile_is_announced_before_any_block`
            }
            let whole = read_float_grid(path, &selector, &limits);
            for mode in modes() {
                let what = format!("{} {} {mode:?}", path.display(), info.selector);
                match (&whole, stream(&mode, path, &selector, &limits)) {
                    (Ok(whole), Ok((grid, got))) => {
                        assert_same(&what, whole, &grid, &got);
                        streamed += 1;
                    }
                    (Err(w), Err(s)) => {
                        assert_eq!(w.to_string(), s.to_string(), "{what}");
                        assert!(matches!(s, Error::UnsupportedGrid { .. }), "{what}: {s:?}");
                    }
                    (w, s) => panic!("{what}: whole read {w:?}, stream {:?}", s.map(|r| r.0)),
                }
            }
        }
    }
    assert!(streamed >= 2 * 12, "{streamed} streams compared");
}

/// Both of the fixture's tile levels, a double grid and an affine map, spelled out.
#[test]
fn tiles_come_as_constant_blocks_after_the_leaves() {
    let path = fixture("affine_tiles.vdb");
    for mode in modes() {
        let (grid, got) =
            stream(&mode, &path, &GridSelector::first("heat_double"), &ReadLimits::default())
                .unwrap();
        assert_eq!((grid.leaf_count, grid.tile_blocks), (1, 1 + 4096), "{mode:?}");
        assert_eq!(grid.background, 0.5);
        assert_eq!(grid.index_bbox, Some((IVec3::new(-8, 0, 0), IVec3::new(255, 127, 127))));
        assert_eq!(got.origins[0], IVec3::new(-8, 0, 0), "the leaf first");
        assert_eq!(got.values[leaf_offset(-3, 5, 7)], 1.25);
        assert_eq!(got.origins[1], IVec3::new(64, 0, 0), "then the 8³ tile");
        assert!(got.values[LEAF_VOXELS..2 * LEAF_VOXELS].iter().all(|&v| v == 2.0));
        assert_eq!(got.origins[2], IVec3::new(128, 0, 0), "then the 128³ tile, x slowest");
        assert_eq!(got.origins[3], IVec3::new(128, 0, 8));
        assert_eq!(got.origins.last(), Some(&IVec3::new(248, 120, 120)));
        assert!(got.values[2 * LEAF_VOXELS..].iter().all(|&v| v == 3.0));
        let p_world = grid.world_from_index.transform_point3(DVec3::new(1.0, 2.0, 3.0));
        assert!(p_world.abs_diff_eq(DVec3::new(0.887861, -1.37757, 4.2), 1e-5), "{p_world}");
    }
}

/// A 4096³ root tile in a 20 KB file: 2^27 constant blocks, known from the header, which a
/// visitor can refuse before any block; or it can stop midway through the tile.
#[test]
fn a_root_tile_is_announced_before_any_block() {
    let path = fixture("affine_tiles.vdb");
    let selector = GridSelector::first("root_tile");
    for mode in modes() {
        let mut announced = None;
        let mut blocks = 0u64;
        let result = mode.stream_float_grid(
            &path,
            &selector,
            &ReadLimits::default(),
            &mut |g| {
                announced = Some(g.clone());
                Err(Error::invalid("test", "too many blocks"))
            },
            &mut |_, _| {
                blocks += 1;
                Ok(())
            },
        );
        let error = result.unwrap_err();
        assert!(error.to_string().contains("too many blocks"), "{mode:?}: {error}");
        let announced = announced.unwrap();
        assert_eq!((announced.leaf_count, announced.tile_blocks), (0, 1 << 27));
        assert_eq!(announced.index_bbox, Some((IVec3::ZERO, IVec3::splat(4095))));
        assert_eq!(blocks, 0);

        let mut seen = Vec::new();
        let result = mode.stream_float_grid(
            &path,
            &selector,
            &ReadLimits::default(),
            &mut |_| Ok(()),
            &mut |origin, data| {
                assert_eq!(data, LeafData::Constant(1.0));
                seen.push(origin);
                if seen.len() == 1000 {
                    return Err(Error::invalid("test", "enough"));
                }
                Ok(())
            },
        );
        assert!(result.unwrap_err().to_string().contains("enough"), "{mode:?}");
        assert_eq!(seen.len(), 1000);
        assert_eq!(seen[999], IVec3::new(0, 8, 8 * (999 - 512)));
    }
}

/// An error from the leaf visitor stops the stream at once and is what it returns.
#[test]
fn a_visitor_error_aborts_the_stream() {
    let path = data("smoke/openvdb_org_smoke1.vdb");
    for mode in modes() {
        let mut visits = 0;
        let result = mode.stream_float_grid(
            &path,
            &GridSelector::first("density"),
            &ReadLimits::default(),
            &mut |_| Ok(()),
            &mut |_, _| {
                visits += 1;
                if visits == 300 {
                    // past the first batch of 256
                    return Err(Error::invalid("--visitor", "leaf 300 refused"));
                }
                Ok(())
            },
        );
        match result {
            Err(Error::InvalidArgument { flag, message }) => {
                assert_eq!((flag.as_str(), message.as_str()), ("--visitor", "leaf 300 refused"));
            }
            other => panic!("{mode:?}: {other:?}"),
        }
        assert_eq!(visits, 300, "{mode:?}");
    }
}

/// Clean failures are the whole-grid read's errors, word for word (the limit excepted: the
/// stream's memory is its topology, not the voxelized grid).
#[test]
fn clean_errors_are_the_whole_grid_errors() {
    let cases = [
        (data("smoke/openvdb_org_smoke1.vdb"), "smoke"),
        (data("edge_cases/oiio_sphereCd.vdb"), "Cd"),
        (data("edge_cases/malformed/oiio_truncated.vdb"), "huge"),
        (data("missing.vdb"), "density"),
        (data("nanovdb/openvdb_fvdb_smoke-blosc.nvdb"), "density"),
        (fixture("frustum.vdb"), "fog"),
        (fixture("affine_tiles.vdb"), "heat_double[1]"),
    ];
    for (path, selector) in &cases {
        let selector: GridSelector = selector.parse().unwrap();
        let whole = read_float_grid(path, &selector, &ReadLimits::default()).unwrap_err();
        for mode in modes() {
            let error = stream(&mode, path, &selector, &ReadLimits::default()).unwrap_err();
            assert_eq!(error.to_string(), whole.to_string(), "{mode:?}");
            assert_eq!(error.exit_code(), 3);
        }
    }
    for mode in modes() {
        let tiny = ReadLimits { max_bytes: 1024 };
        let path = data("smoke/openvdb_org_smoke1.vdb");
        match stream(&mode, &path, &GridSelector::first("density"), &tiny) {
            Err(Error::TooLarge { needed, limit: 1024, .. }) => {
                // the topology of 3117 leaves plus one batch of 256
                assert!(needed > 256 * 2048 && needed < 3117 * 2048, "{needed}");
            }
            other => panic!("{mode:?}: {:?}", other.map(|r| r.0)),
        }
    }
}

/// A grid of 40³ = 64,000 leaves (131 MB voxelized, an 8 MB file: one value per leaf).
fn big_grid(dir: &Path) -> PathBuf {
    let n = 40;
    let mut origins = Vec::with_capacity(n * n * n);
    let mut values = Vec::with_capacity(n * n * n * LEAF_VOXELS);
    for i in 0..n as i32 {
        for j in 0..n as i32 {
            for k in 0..n as i32 {
                origins.push(IVec3::new(8 * i, 8 * j, 8 * k));
                let value = 1.0 + ((7 * i + 3 * j + k) % 11) as f32 * 0.25;
                values.extend(std::iter::repeat_n(value, LEAF_VOXELS));
            }
        }
    }
    let grid = FloatGrid {
        name: "density".into(),
        world_from_index: DAffine3::from_scale(DVec3::splat(0.01)),
        background: 0.0,
        origins,
        values,
    };
    let path = dir.join("big.vdb");
    write_float_grids(&path, &[&grid]).unwrap();
    path
}

/// Runs the reader subcommand directly (reply to /dev/null) under GNU time and returns
/// its peak resident set in KiB, or `None` without `/usr/bin/time`.
///
/// Not `wait4` on a child of this process: exec records the spawning process's peak RSS
/// in the child's `ru_maxrss` (posix_spawn shares this test's memory), whereas `time`
/// forks from its own small image.
fn reader_peak_rss_kib(args: &[OsString]) -> Option<u64> {
    let time = Path::new("/usr/bin/time");
    if !time.is_file() {
        return None;
    }
    let output = Command::new(time)
        .args(["-f", "%M"])
        .arg(PLUME)
        .arg("__read-grids")
        .args(args)
        .stdin(Stdio::null())
        .stdout(fs::File::create("/dev/null").unwrap())
        .stderr(Stdio::piped())
        .output()
        .unwrap();
    assert!(output.status.success(), "{output:?}");
    let text = String::from_utf8_lossy(&output.stderr);
    text.lines().last()?.trim().parse().ok()
}

/// The stream succeeds where the whole-grid read cannot: under a `--max-input-memory` far
/// below the grid's size (the whole read refuses with the limit error), and in a child
/// whose memory limit is below the grid's size (the whole read runs out of memory).
#[test]
fn streaming_memory_is_bounded_by_the_topology() {
    let dir = scratch_dir("stream", "big");
    let path = big_grid(&dir);
    let selector = GridSelector::first("density");
    let leaves = 64_000u64;
    let voxelized = leaves * (LEAF_VOXELS as u64 * 4 + 12);
    let small = ReadLimits { max_bytes: 32 << 20 };
    match read_float_grid(&path, &selector, &small) {
        Err(Error::TooLarge { needed, .. }) => assert_eq!(needed, voxelized),
        other => panic!("{:?}", other.map(|g| g.leaf_count())),
    }
    // RLIMIT_DATA of 96 MiB: less than the values alone (125 MiB)
    let tight = IsolationLimits {
        memory_bytes: 96 << 20,
        cpu_seconds: 60,
        timeout: Duration::from_secs(60),
    };
    let whole = read_grids_isolated(
        &PLUME.into(),
        &path,
        &[GridRequest::required(selector.clone())],
        &ReadLimits::default(),
        &tight,
    );
    match whole {
        // Out of memory, or a crash on it: blosc does not check every allocation
        Err(Error::ReaderFailed { what, grid, .. }) => {
            assert!(what.contains("memory"), "{what}");
            assert_eq!(grid.as_deref(), Some("density"));
        }
        other => panic!("{:?}", other.map(|g| g.len())),
    }
    for (mode, limits) in [(ReadIsolation::InProcess, small), (child(tight.clone()), small)] {
        let start = Instant::now();
        let mut count = 0u64;
        let mut leaf = |origin: IVec3, data: LeafData<'_>| {
            let i = origin / 8;
            let value = 1.0 + ((7 * i.x + 3 * i.y + i.z) % 11) as f32 * 0.25;
            match data {
                LeafData::Values(block) => assert!(block.iter().all(|&v| v == value), "{origin}"),
                LeafData::Constant(_) => panic!("no tiles in this grid"),
            }
            count += 1;
            Ok(())
        };
        let grid =
            mode.stream_float_grid(&path, &selector, &limits, &mut |_| Ok(()), &mut leaf).unwrap();
        let seconds = start.elapsed().as_secs_f64();
        assert_eq!((grid.leaf_count, count), (leaves, leaves));
        println!(
            "{mode:?}: {leaves} leaves in {seconds:.2} s, {:.0} leaves/s",
            leaves as f64 / seconds
        );
    }

    // Peak RSS of the reader, whole grid vs stream (no rlimits here)
    let path_arg = OsString::from(&path);
    let max = OsString::from(ReadLimits::default().max_bytes.to_string());
    let read_args = ["read".into(), path_arg.clone(), max.clone(), "need".into(), "1".into()];
    let whole = reader_peak_rss_kib(&[&read_args[..], &["density".into()]].concat());
    let streamed = reader_peak_rss_kib(&["stream".into(), path_arg, max, "density".into()]);
    let (Some(whole), Some(streamed)) = (whole, streamed) else {
        println!("no /usr/bin/time: peak RSS not measured");
        return;
    };
    println!(
        "peak RSS of the reader for {leaves} leaves ({} MiB voxelized): whole grid {} MiB, \
         stream {} MiB",
        voxelized >> 20,
        whole >> 10,
        streamed >> 10
    );
    assert!(streamed * 3 < whole, "stream {streamed} KiB, whole {whole} KiB");
}

/// The damaged files of `../shared/data/edge_cases/malformed` and the crash/hang/alloc
/// mutants of `data/regressions`, streamed in a child: each ends in a clean one-line error
/// (exit code 3) or, where the whole-grid read succeeds, in the same blocks.
#[test]
fn hostile_files_stream_to_clean_errors() {
    let limits = IsolationLimits::new(&ReadLimits::default(), Duration::from_secs(30));
    let isolated = child(limits.clone());
    let mut files = Vec::new();
    for dir in [
        data("edge_cases/malformed"),
        Path::new(env!("CARGO_MANIFEST_DIR")).join("data/regressions"),
    ] {
        for entry in fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            if path.extension().is_some_and(|e| e == "vdb") {
                files.push(path);
            }
        }
    }
    files.sort();
    assert!(files.len() >= 13, "{files:?}");
    let (mut ok, mut refused) = (0, 0);
    for path in &files {
        let stem = path.file_stem().unwrap().to_str().unwrap();
        let own = stem.rsplit(['-', '_']).next().unwrap();
        for selector in ["density", "heat", own] {
            let what = format!("{} {selector}", path.display());
            let selector: GridSelector = selector.parse().unwrap();
            let whole = read_grids_isolated(
                &PLUME.into(),
                path,
                &[GridRequest::required(selector.clone())],
                &ReadLimits::default(),
                &limits,
            );
            match (whole, stream(&isolated, path, &selector, &ReadLimits::default())) {
                (Ok(mut found), Ok((grid, got))) => {
                    let whole = found.remove(0).expect("required").grid;
                    assert_same(&what, &whole, &grid, &got);
                    ok += 1;
                }
                (whole, Err(error)) => {
                    let message = error.to_string();
                    assert_eq!(error.exit_code(), 3, "{what}: {message}");
                    assert!(!message.contains('\n'), "{what}: {message:?}");
                    assert!(message.contains(stem), "{what}: {message}");
                    if let Ok(found) = whole {
                        panic!(
                            "{what}: stream failed ({message}), whole read gave {} grid",
                            found.len()
                        );
                    }
                    if stem.starts_with("crash_") && stem.ends_with(selector.name.as_str()) {
                        assert!(message.contains("reader crashed with SIG"), "{what}: {message}");
                        assert!(
                            message.contains(&format!("grid \"{}\"", selector.name)),
                            "{message}"
                        );
                    }
                    if stem.starts_with("scan_") {
                        assert!(message.contains("truncated or corrupt"), "{what}: {message}");
                    }
                    refused += 1;
                }
                (Err(w), Ok(_)) => {
                    panic!("{what}: the whole read failed ({w}), the stream did not")
                }
            }
        }
    }
    println!("{ok} streams equal to the whole read, {refused} refused cleanly");
    assert!(ok >= 6 && refused >= 20, "{ok} ok, {refused} refused");
}

/// A stand-in reader that replays `reply` (bytes a real reader wrote, then damaged) and
/// exits with `exit`.
fn replaying_reader(name: &str, reply: &[u8], exit: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("stream_replies");
    fs::create_dir_all(&dir).unwrap();
    let data = dir.join(format!("{name}.bin"));
    fs::write(&data, reply).unwrap();
    shell_script(
        "stream_replies",
        &format!("{name}.sh"),
        &format!("cat '{}'\n{exit}", data.display()),
    )
}

/// Streams SMOKE through `reader`, retrying while another test thread's fork still holds
/// the fresh script open for writing (ETXTBSY). Returns the result and the leaves visited.
fn stream_with(reader: &Path) -> (plume::Result<StreamedGrid>, u64) {
    let path = data("smoke/openvdb_org_smoke1.vdb");
    let limits = IsolationLimits::new(&ReadLimits::default(), Duration::from_secs(30));
    let mut visited = 0u64;
    let result = retry_while_busy(reader, || {
        visited = 0;
        plume::vdb::stream_float_grid_isolated(
            &reader.to_path_buf().into(),
            &path,
            &GridSelector::first("density"),
            &ReadLimits::default(),
            &limits,
            &mut |_| Ok(()),
            &mut |_, _| {
                visited += 1;
                Ok(())
            },
        )
    });
    (result, visited)
}

/// Broken replies after some good batches: cut short, a batch sent twice, a smashed batch
/// count, a crash. Each is a ReaderFailed naming the file and grid; the batches before the
/// damage have been visited.
#[test]
fn broken_stream_replies_are_refused() {
    let path = data("smoke/openvdb_org_smoke1.vdb");
    let output = Command::new(PLUME)
        .args(["__read-grids", "stream"])
        .arg(&path)
        .args([&ReadLimits::default().max_bytes.to_string(), "density"])
        .output()
        .unwrap();
    assert!(output.status.success());
    let reply = output.stdout;
    // magic + version, BEGIN, STREAM (name "density", no tiles), then LEAVES of 256
    let first = 12 + 9 + (1 + 4 + 7 + 12 * 8 + 4 + 8 + 8 + 1 + 24);
    let batch = 1 + 4 + 256 * (12 + 4 * LEAF_VOXELS);
    assert_eq!((reply[first], reply[first + batch]), (0x08, 0x08), "layout changed");

    let (result, visited) = stream_with(&replaying_reader("good", &reply, "exit 0"));
    assert_eq!((result.unwrap().leaf_count, visited), (3117, 3117), "the replay itself is good");

    let failed =
        |(result, visited): (plume::Result<StreamedGrid>, u64), needle: &str, seen: u64| {
            let error = result.unwrap_err();
            let message = error.to_string();
            assert!(matches!(error, Error::ReaderFailed { .. }), "{error:?}");
            assert!(message.contains("openvdb_org_smoke1.vdb"), "{message}");
            assert!(message.contains("grid \"density\""), "{message}");
            assert!(message.contains(needle), "{message:?} lacks {needle:?}");
            assert_eq!(visited, seen, "{message}");
        };
    let cut = &reply[..first + 2 * batch + 1000];
    failed(stream_with(&replaying_reader("cut", cut, "exit 0")), "before finishing", 512);

    let mut twice = reply[..first + batch].to_vec();
    twice.extend_from_slice(&reply[first..]);
    failed(stream_with(&replaying_reader("twice", &twice, "exit 0")), "out of tree order", 256);

    let mut smashed = reply.clone();
    smashed[first + batch + 1..first + batch + 5].copy_from_slice(&u32::MAX.to_le_bytes());
    failed(
        stream_with(&replaying_reader("smashed", &smashed, "exit 0")),
        "batch of 4294967295",
        256,
    );

    let crash = replaying_reader("crash", &reply[..first + batch], "kill -SEGV $$");
    failed(stream_with(&crash), "crashed with SIGSEGV", 256);
}
