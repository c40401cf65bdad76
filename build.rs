//! Builds the OpenVDB shim (`cpp/*.cc`, one concept per file, listed in `SHIM_SOURCES`
//! and described in `cpp/shim_internal.h`) and its cxx bridge (`src/vdb/ffi.rs`).
//!
//! Why `cxx_build` rather than the `cmake` crate: the shim is a handful of C++ files with
//! nothing to configure (one compiler invocation each), and Debian's `libopenvdb-dev`
//! installs plain headers and shared libraries that link directly. With cmake we would
//! need the cmake package plus OpenVDB's `FindOpenVDB.cmake` and the find-modules of its
//! dependencies (TBB, Blosc, Imath), which are not all packaged.
//!
//! OpenVDB discovery: the system include path, or `OPENVDB_INCLUDE_DIR` /
//! `OPENVDB_LIB_DIR` for a custom install.

use std::env;
use std::path::PathBuf;

/// The shim's C++ sources, one concept each (see `cpp/shim_internal.h`); a new file must be
/// added here to be compiled. Longest compile first (`write.cc` takes about twice as long
/// as any other), so that the parallel compile does not end on the longest one alone.
const SHIM_SOURCES: [&str; 6] =
    ["cpp/write.cc", "cpp/read.cc", "cpp/stream.cc", "cpp/list.cc", "cpp/scan.cc", "cpp/common.cc"];
/// `vdb_shim.h` is the header the bridge includes; `shim_internal.h` is shared by the sources.
const SHIM_HEADERS: [&str; 2] = ["cpp/vdb_shim.h", "cpp/shim_internal.h"];

fn main() {
    for file in ["build.rs", "src/vdb/ffi.rs"].iter().chain(&SHIM_SOURCES).chain(&SHIM_HEADERS) {
        println!("cargo:rerun-if-changed={file}");
    }
    println!("cargo:rerun-if-env-changed=OPENVDB_INCLUDE_DIR");
    println!("cargo:rerun-if-env-changed=OPENVDB_LIB_DIR");

    let include_dir = env::var_os("OPENVDB_INCLUDE_DIR").map(PathBuf::from);
    let search = include_dir
        .iter()
        .cloned()
        .chain(["/usr/include", "/usr/local/include"].map(PathBuf::from));
    let found = search.clone().any(|dir| dir.join("openvdb/openvdb.h").is_file());
    if !found {
        panic!(
            "OpenVDB headers not found (looked for openvdb/openvdb.h in {:?}); install \
             libopenvdb-dev or set OPENVDB_INCLUDE_DIR",
            search.collect::<Vec<_>>()
        );
    }

    let mut build = cxx_build::bridge("src/vdb/ffi.rs");
    // No C++ debug info, in every profile: with `-g` the OpenVDB templates take much longer
    // to compile and make objects an order of magnitude larger, for a shim whose bugs show
    // up as the Rust-side errors it returns.
    build.files(SHIM_SOURCES).std("c++17").opt_level(2).debug(false);
    if let Some(dir) = &include_dir {
        build.include(dir);
    }
    if checked_only() {
        // `cargo clippy` checks the Rust code and links nothing, so the shim's objects
        // would go unused; compiling them (about 1.5 minutes on 2 cores) doubled the C++
        // work of `scripts/test.sh`, whose clippy step runs its own build script.
        return;
    }
    build.compile("plume_vdb_shim");

    if let Some(dir) = env::var_os("OPENVDB_LIB_DIR") {
        println!("cargo:rustc-link-search=native={}", PathBuf::from(dir).display());
    }
    // OpenVDB's own dependencies (blosc, zlib, boost_iostreams, log4cplus) come in through
    // libopenvdb.so's DT_NEEDED entries; the shim's inline header code calls TBB and
    // Imath (half) directly.
    for lib in ["openvdb", "tbb", "Imath-3_1"] {
        println!("cargo:rustc-link-lib=dylib={lib}");
    }
}

/// True when this build script runs for `cargo clippy`: cargo names clippy's driver in
/// `RUSTC_WORKSPACE_WRAPPER` (an environment variable it documents for build scripts),
/// and clippy only checks, so nothing the script compiles is ever linked.
fn checked_only() -> bool {
    env::var_os("RUSTC_WORKSPACE_WRAPPER").is_some_and(|w| {
        PathBuf::from(w)
            .file_stem()
            .is_some_and(|s| s.to_string_lossy().starts_with("clippy-driver"))
    })
}
