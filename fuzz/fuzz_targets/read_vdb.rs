//! The in-process reader (shim + OpenVDB) on arbitrary bytes written to a temp file: list
//! every grid, then read each scalar grid and each vector grid. Crashes found here are crashes of OpenVDB that
//! the isolated reader (`plume::vdb::isolate`) turns into clean errors; keep small ones in
//! `data/regressions/`. Only the Rust side is coverage-instrumented (OpenVDB is the
//! system library), so seed the corpus with real files (ARCHITECTURE.md, "Untrusted input").
#![no_main]

use std::io::Write;
use std::path::PathBuf;
use std::sync::OnceLock;

use libfuzzer_sys::fuzz_target;
use plume::vdb::{list_grids, read_float_grid, read_vec3_grid, GridSelector, ReadLimits};

fn scratch() -> &'static PathBuf {
    static PATH: OnceLock<PathBuf> = OnceLock::new();
    PATH.get_or_init(|| std::env::temp_dir().join(format!("plume-fuzz-{}.vdb", std::process::id())))
}

fuzz_target!(|data: &[u8]| {
    let path = scratch();
    let mut file = std::fs::File::create(path).expect("scratch file");
    file.write_all(data).expect("write scratch file");
    drop(file);
    // Well below libFuzzer's 2 GiB RSS limit: only a lie that escapes this check is a bug
    let limits = ReadLimits { max_bytes: 256 << 20 };
    if let Ok(infos) = list_grids(path) {
        for info in &infos {
            let selector: GridSelector = info.selector.parse().expect("selectors round-trip");
            match info.value_type.as_str() {
                "float" | "double" => drop(read_float_grid(path, &selector, &limits)),
                "vec3s" | "vec3d" => drop(read_vec3_grid(path, &selector, &limits)),
                _ => {}
            }
        }
    }
});
