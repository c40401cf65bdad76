//! Every integration test, in one test binary: each `tests/<name>.rs` is the module
//! `<name>` here (run one with `cargo test --test suite <name>::`), and all share
//! [`common`].
//!
//! One binary instead of one per file: a binary per file would link the plume library and
//! OpenVDB once each, several times the build time of this one, and the tests of
//! different files share the cores instead of each binary running alone. No test sets
//! process-wide state (environment, working directory, global thread pool, signal
//! handlers), and each file's scratch directories have their own prefix.

mod common;

mod adaptive;
mod aovs;
mod batch_slurm;
mod bench;
mod cache;
mod camera_lens;
mod chromatic;
mod cli;
mod cli_lights;
mod cli_method;
mod coloured_albedo;
mod deferred_paths;
mod denoise;
mod dense_tracking;
mod environment_map;
mod estimators;
mod farm;

mod faults;
mod forced_collision;
mod fuzz_mutants;
mod instances;
mod interpolation;
mod isolation;
mod light_sampling;
mod lights;
mod mapped_faults;
mod memory_limits;
mod motion_blur;
mod nee_table;
mod null_tracking;
mod overlap;
mod overlap_lights;
mod overlap_render;
mod path;
mod placement;
mod point_lookup;
mod render;
mod sampling;
mod scene_file;
mod several_volumes;

mod split_by;
mod stream;
mod synth_flare_cli;
mod synth_sky_cli;
mod tracking;
mod vdb_hostile;
mod vdb_real;
mod vdb_write;
mod vec3_grids;
mod volume;
mod volume_groups;
mod volume_trilinear;

/// With `autotests = false` cargo no longer finds test files by itself: a file in `tests/`
/// that this root does not declare would compile into nothing and its tests never run.
#[test]
fn every_test_file_is_a_module_of_the_suite() {
    let root = include_str!("suite.rs");
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests");
    let mut files = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        let Some(name) = path.file_stem().and_then(|s| s.to_str()) else { continue };
        if path.extension().is_some_and(|e| e == "rs") && name != "suite" {
            assert!(
                root.lines().any(|l| l == format!("mod {name};")),
                "tests/{name}.rs is not declared in tests/suite.rs: add `mod {name};`"
            );
            files += 1;
        }
    }
    assert!(files >= 38, "only {files} test files found in {}", dir.display());
}
