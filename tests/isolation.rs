//! The isolated VDB reader (`vdb::isolate`): the real `plume` child gives the same grids
//! and errors as in-process reading, and every way a child can fail (crash, hang, CPU
//! burn, garbage, a lying length, an early exit) becomes one clean
//! [`Error::ReaderFailed`]. The failing children are small shell scripts standing in for
//! a reader that OpenVDB has derailed.

use crate::common;

use std::fs;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use common::{retry_while_busy, shell_script, PLUME, SMOKE};
use plume::vdb::{
    list_grids, list_grids_isolated, read_float_grid, read_float_grids_isolated, read_grids,
    read_grids_isolated, GridRequest, GridSelector, IsolationLimits, ReadLimits,
};
use plume::Error;

const FIRE: &str = "../shared/data/fire/openusd_densityAndHeat.vdb";

fn limits(timeout: Duration) -> IsolationLimits {
    IsolationLimits::new(&ReadLimits::default(), timeout)
}

fn density() -> Vec<GridSelector> {
    vec![GridSelector::first("density")]
}

/// A stand-in reader: a shell script in the test's scratch directory.
fn script(name: &str, body: &str) -> PathBuf {
    shell_script("isolation", name, body)
}

/// Reads SMOKE's density through `reader`, retrying the spawn while another test thread's
/// fork still holds the freshly written script open for writing (ETXTBSY).
fn read_with(
    reader: &Path,
    limits: &IsolationLimits,
) -> plume::Result<Vec<plume_volume::grid::FloatGrid>> {
    retry_while_busy(reader, || {
        read_float_grids_isolated(
            &reader.to_path_buf().into(),
            Path::new(SMOKE),
            &density(),
            &ReadLimits::default(),
            limits,
        )
    })
}

/// The reply header and a BEGIN record for request 0, alternative 0, as `printf` text.
const HEADER_AND_BEGIN: &str =
    r"printf 'plumeRD\n\001\000\000\000\001\000\000\000\000\000\000\000\000'";

/// Asserts a ReaderFailed naming SMOKE, with `needle` in its one-line message.
fn assert_reader_failed(
    result: plume::Result<Vec<plume_volume::grid::FloatGrid>>,
    needle: &str,
) -> String {
    let error = result.expect_err("the reader failed");
    let message = error.to_string();
    assert!(matches!(error, Error::ReaderFailed { .. }), "{error:?}");
    assert_eq!(error.exit_code(), 3);
    assert!(message.starts_with(&format!("corrupt or hostile VDB {SMOKE}: ")), "{message}");
    assert!(message.contains(needle), "{message:?} lacks {needle:?}");
    assert!(!message.contains('\n'), "{message:?}");
    message
}

#[test]
fn isolated_reads_equal_in_process_reads() {
    let isolated = read_float_grids_isolated(
        &PLUME.into(),
        Path::new(FIRE),
        &[GridSelector::first("heat"), GridSelector::first("density")],
        &ReadLimits::default(),
        &limits(Duration::from_secs(60)),
    )
    .unwrap();
    for (grid, name) in isolated.iter().zip(["heat", "density"]) {
        let local =
            read_float_grid(Path::new(FIRE), &GridSelector::first(name), &ReadLimits::default())
                .unwrap();
        assert_eq!(grid.name, local.name);
        assert_eq!(grid.world_from_index, local.world_from_index);
        assert_eq!(grid.background, local.background);
        assert_eq!(grid.origins, local.origins);
        assert_eq!(grid.values.len(), local.values.len());
        assert!(grid.values.iter().zip(&local.values).all(|(a, b)| a.to_bits() == b.to_bits()));
    }
    let json = |infos: &[plume::vdb::GridInfo]| serde_json::to_string(infos).unwrap();
    for file in [SMOKE, FIRE, "../shared/data/sequence/openusd_smoke_000001.vdb"] {
        let isolated =
            list_grids_isolated(&PLUME.into(), Path::new(file), &limits(Duration::from_secs(60)))
                .unwrap();
        assert_eq!(json(&isolated), json(&list_grids(Path::new(file)).unwrap()), "{file}");
    }
}

#[test]
fn alternatives_and_optional_requests_match_in_process() {
    let sel = |s: &str| s.parse::<GridSelector>().unwrap();
    let requests = [
        GridRequest::required(sel("density")),
        GridRequest {
            alternatives: vec![sel("temperature"), sel("emission"), sel("heat")],
            required: false,
        },
        GridRequest { alternatives: vec![sel("temperature"), sel("flame")], required: false },
        GridRequest { alternatives: vec![sel("density[1]"), sel("density")], required: true },
    ];
    let path = Path::new(FIRE);
    let isolated = read_grids_isolated(
        &PLUME.into(),
        path,
        &requests,
        &ReadLimits::default(),
        &limits(Duration::from_secs(60)),
    )
    .unwrap();
    let local = read_grids(path, &requests, &ReadLimits::default()).unwrap();
    let summary = |found: &[Option<plume::vdb::FoundGrid>]| -> Vec<Option<(usize, String, usize)>> {
        found
            .iter()
            .map(|f| f.as_ref().map(|f| (f.alternative, f.grid.name.clone(), f.grid.leaf_count())))
            .collect()
    };
    assert_eq!(summary(&isolated), summary(&local));
    assert_eq!(
        summary(&isolated),
        vec![
            Some((0, "density".into(), 46)),
            Some((2, "heat".into(), 37)),
            None,
            Some((1, "density".into(), 46))
        ]
    );
}

#[test]
fn clean_errors_in_the_child_are_the_in_process_errors() {
    let reader = &PLUME.into();
    let iso = limits(Duration::from_secs(60));
    let read = |file: &str, selector: &str, read_limits: ReadLimits| {
        let selector: GridSelector = selector.parse().unwrap();
        let isolated = read_float_grids_isolated(
            reader,
            Path::new(file),
            std::slice::from_ref(&selector),
            &read_limits,
            &iso,
        )
        .unwrap_err();
        let local = read_float_grid(Path::new(file), &selector, &read_limits).unwrap_err();
        assert_eq!(isolated.to_string(), local.to_string());
        assert_eq!(isolated.exit_code(), local.exit_code());
        isolated
    };
    assert!(matches!(read(SMOKE, "smoke", ReadLimits::default()), Error::GridNotFound { .. }));
    assert!(matches!(
        read("../shared/data/edge_cases/oiio_sphereCd.vdb", "Cd", ReadLimits::default()),
        Error::UnsupportedGrid { .. }
    ));
    assert!(matches!(
        read(SMOKE, "density", ReadLimits { max_bytes: 1024 }),
        Error::TooLarge { .. }
    ));
    assert!(matches!(
        read(
            "../shared/data/edge_cases/malformed/oiio_truncated.vdb",
            "huge",
            ReadLimits::default()
        ),
        Error::Vdb { .. }
    ));
    assert!(matches!(
        read("../shared/data/missing.vdb", "density", ReadLimits::default()),
        Error::Open { .. }
    ));
    assert!(matches!(
        read(
            "../shared/data/nanovdb/openvdb_fvdb_smoke-blosc.nvdb",
            "density",
            ReadLimits::default()
        ),
        Error::Vdb { .. }
    ));
}

#[test]
fn a_crashing_reader_is_reported_with_the_grid_it_was_reading() {
    let reader = script("segv.sh", &format!("{HEADER_AND_BEGIN}\nkill -SEGV $$"));
    let message = assert_reader_failed(
        read_with(&reader, &limits(Duration::from_secs(30))),
        "reader crashed with SIGSEGV",
    );
    assert!(message.ends_with(r#" while reading grid "density""#), "{message}");
    let reader = script(
        "abort.sh",
        "echo 'terminate called after throwing an instance of X' >&2\nkill -ABRT $$",
    );
    let message =
        assert_reader_failed(read_with(&reader, &limits(Duration::from_secs(30))), "SIGABRT");
    assert!(message.contains("reader said: terminate called"), "{message}");
    assert!(message.ends_with(" while listing grids"), "{message}");
}

#[test]
fn a_hanging_reader_is_killed_at_the_timeout() {
    let reader = script("hang.sh", &format!("{HEADER_AND_BEGIN}\nexec sleep 60"));
    let start = Instant::now();
    let message = assert_reader_failed(
        read_with(&reader, &limits(Duration::from_millis(500))),
        "reader did not finish within 0.5 s (reading.read_timeout); killed",
    );
    assert!(start.elapsed() < Duration::from_secs(10), "{:?}", start.elapsed());
    assert!(message.contains(r#"while reading grid "density""#), "{message}");
    // A grandchild that keeps the pipes open cannot hold plume either
    let reader = script("hang_in_child.sh", "sleep 60 &\nsleep 60");
    let start = Instant::now();
    assert_reader_failed(read_with(&reader, &limits(Duration::from_millis(500))), "did not finish");
    assert!(start.elapsed() < Duration::from_secs(10), "{:?}", start.elapsed());
}

#[test]
fn a_reader_burning_cpu_hits_its_cpu_limit() {
    let reader = script("spin.sh", "while :; do :; done");
    let limits = IsolationLimits { cpu_seconds: 1, ..limits(Duration::from_secs(30)) };
    let start = Instant::now();
    assert_reader_failed(read_with(&reader, &limits), "CPU time limit of 1 s");
    assert!(start.elapsed() < Duration::from_secs(20), "{:?}", start.elapsed());
}

#[test]
fn garbage_and_lies_on_the_pipe_are_refused() {
    let l = limits(Duration::from_secs(30));
    let random = script("random.sh", "head -c 100000 /dev/urandom");
    assert_reader_failed(read_with(&random, &l), "malformed reply (bad magic");
    // A GRID record for 2^40 leaves: refused from the count, before any allocation
    let liar = script(
        "liar.sh",
        &format!(
            r"{HEADER_AND_BEGIN}
printf '\002\000\000\000\000\000\000\000\000\007\000\000\000density'
head -c 100 /dev/zero
printf '\000\000\000\000\000\001\000\000'
exec sleep 60"
        ),
    );
    let start = Instant::now();
    assert_reader_failed(read_with(&liar, &l), "exceed the input memory limit");
    assert!(start.elapsed() < Duration::from_secs(10));
    let wrong_grid =
        script("wrong.sh", r"printf 'plumeRD\n\001\000\000\000\003\000\000\000\000\006'");
    assert_reader_failed(read_with(&wrong_grid, &l), "ABSENT out of order");
    let version = script("version.sh", r"printf 'plumeRD\n\377\000\000\000\006'");
    assert_reader_failed(read_with(&version, &l), "format version 255");
}

#[test]
fn early_and_unhappy_exits_are_reported() {
    let l = limits(Duration::from_secs(30));
    let short = script("short.sh", HEADER_AND_BEGIN);
    assert_reader_failed(read_with(&short, &l), "reader exited before finishing its reply");
    let status = script("status.sh", "echo 'something broke' >&2\nexit 7");
    assert_reader_failed(
        read_with(&status, &l),
        "reader exited with status 7 (reader said: something broke)",
    );
    let oom = script(
        "oom.sh",
        "echo 'memory allocation of 1099511627776 bytes failed' >&2\nkill -ABRT $$",
    );
    assert_reader_failed(read_with(&oom, &l), "reader ran out of memory at its limit of");
    let missing = Path::new("/nonexistent/plume");
    let error = read_with(missing, &l).unwrap_err();
    assert!(matches!(error, Error::ReaderSpawn { .. }), "{error:?}");
    assert_eq!(error.exit_code(), 4);
}

/// Every input kept in `data/regressions/` (mutants that made OpenVDB crash, hang or
/// allocate gigabytes; see its README) is refused with one clean line by `plume info` and
/// `plume render`; `plume info` for the reason its name gives.
#[test]
fn regression_inputs_give_clean_errors() {
    let dir = Path::new("data/regressions");
    let mut files: Vec<PathBuf> = fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "vdb"))
        .collect();
    files.sort();
    assert!(files.len() >= 6, "{files:?}");
    let out = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("regression.exr");
    for file in files {
        let f = file.to_str().unwrap();
        let name = file.file_name().unwrap().to_str().unwrap();
        let expected = match name.split('_').next().unwrap() {
            "crash" => "reader crashed with",
            "hang" => "reader did not finish within 3 s",
            // Refused by the shim's bounded scan before OpenVDB parses the file
            "scan" => "truncated or corrupt file: ",
            other => panic!("{name}: unknown class {other:?}"),
        };
        // The two mutants of oiio_bad-bbox-bomb.vdb call their grid "bomb"
        let grid = if name.contains("bomb") || name.contains("root_topology") {
            "bomb"
        } else {
            "density"
        };
        for args in [
            vec!["info", f, "--read-timeout", "3"],
            vec![
                "render",
                f,
                "-o",
                out.to_str().unwrap(),
                "--spp",
                "1",
                "--width",
                "8",
                "--height",
                "8",
                "--read-timeout",
                "3",
                "--density-grid",
                grid,
            ],
        ] {
            let start = Instant::now();
            let o = std::process::Command::new(PLUME).args(&args).output().unwrap();
            let err = String::from_utf8_lossy(&o.stderr);
            assert_eq!(o.status.code(), Some(3), "{args:?}: {err}");
            let lines: Vec<&str> = err.lines().collect();
            assert_eq!(lines.len(), 1, "{args:?}: {err}");
            assert!(lines[0].starts_with("plume: error: ") && lines[0].contains(f), "{err}");
            // (render reads one grid, not the whole file: its failure may come elsewhere)
            if args[0] == "info" {
                assert!(lines[0].contains(expected), "{args:?}: {err} lacks {expected:?}");
            }
            assert!(
                start.elapsed() < Duration::from_secs(30),
                "{args:?} took {:?}",
                start.elapsed()
            );
        }
    }
}
