//! `plume._plume`: the extension module under the Python package `plume`
//! (`python/plume/__init__.py` is the API users import; this module is its engine).
//!
//! - [`scene`]: `Shot`, a scene as the scene file holds it (from a file or from nested
//!   Python dicts, back to TOML);
//! - [`arrays`]: `VolumeData`, dense arrays turned into the sparse 8³ bricks of a grid,
//!   and `write_vdb`;
//! - [`render`]: `render_shot`, which renders through the same frame pipeline as
//!   `plume render` and hands back the image, its layers and the statistics record;
//! - `info_json`: what `plume info --json` prints;
//! - [`logger`]: the renderer's warnings as records of Python's `logging` logger `plume`.
//!
//! Errors are the library's one-line messages, raised as `plume.SceneError` (bad keys and
//! values: the command line's exit code 2), `plume.InputError` (files that cannot be read:
//! 3) or `plume.RenderError` (anything else), all subclasses of `plume.Error`.

mod arrays;
mod logger;
mod render;
mod scene;

use std::path::PathBuf;

use pyo3::create_exception;
use pyo3::exceptions::PyException;
use pyo3::prelude::*;

create_exception!(_plume, Error, PyException, "Any error plume reports.");
create_exception!(
    _plume,
    SceneError,
    Error,
    "A scene key or value is invalid (the command line's exit code 2)."
);
create_exception!(
    _plume,
    InputError,
    Error,
    "An input file cannot be read, or an input array is invalid (exit code 3)."
);
create_exception!(
    _plume,
    RenderError,
    Error,
    "Rendering or writing an output failed (exit codes 4 and above)."
);

/// The Python exception for a library error: its class by the command line's exit code,
/// its message the command line's one line.
pub(crate) fn to_py(e: &plume::Error) -> PyErr {
    let message = e.to_string();
    match e.exit_code() {
        2 => SceneError::new_err(message),
        3 => InputError::new_err(message),
        _ => RenderError::new_err(message),
    }
}

/// The grids of a `.vdb` file, or the summary of a `.plume` brick cache, as the JSON text
/// `plume info --json` prints.
#[pyfunction]
fn info_json(py: Python<'_>, path: PathBuf) -> PyResult<String> {
    py.detach(|| {
        if plume::cache::is_cache_path(&path) {
            let cache = plume::cache::Cache::open(&path)?;
            cache.check.verified()?;
            return Ok(format!("{:#}", plume::info::cache_json(&path, &cache)));
        }
        let reading = plume_scene::ReadSettings::default();
        let isolation = plume::load::bind::reader(&reading)?.isolation;
        Ok(plume::info::to_json(&isolation.list_grids(&path)?))
    })
    .map_err(|e: plume::Error| to_py(&e))
}

/// Read VDB files in child processes of `exe` run with `prefix` before the reader's
/// arguments (the interpreter, running [`reader_main`]), as the command line reads them in
/// children of itself: a damaged or hostile file fails the read, never this process. The
/// first registration holds.
#[pyfunction]
fn use_isolated_reader(exe: PathBuf, prefix: Vec<std::ffi::OsString>) {
    plume::vdb::isolate::set_reader_command(plume::vdb::isolate::ReaderCommand { exe, prefix });
}

/// The isolated reader's child: serve `args` (the reader subcommand and its arguments) and
/// end the process with its exit status, skipping every destructor (after a hostile file
/// the heap may be damaged). Never returns.
#[pyfunction]
fn reader_main(args: Vec<std::ffi::OsString>) -> PyResult<()> {
    use plume::vdb::isolate::{reader_main, READER_SUBCOMMAND};
    let Some((_, rest)) = args.split_first().filter(|(f, _)| *f == READER_SUBCOMMAND) else {
        return Err(pyo3::exceptions::PyValueError::new_err(format!(
            "reader_main: the arguments must start with {READER_SUBCOMMAND}"
        )));
    };
    let code = match reader_main(rest) {
        Ok(()) => 0,
        Err(failure) => {
            let line = format!("plume {READER_SUBCOMMAND}: {failure}\n");
            let _ = std::io::Write::write_all(&mut std::io::stderr(), line.as_bytes());
            failure.exit_code()
        }
    };
    let _ = std::io::Write::flush(&mut std::io::stderr());
    // SAFETY: _exit ends the process without running atexit handlers or destructors; the
    // reply was flushed by the reader, stderr above.
    unsafe { libc::_exit(code) }
}

#[pymodule]
fn _plume(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    logger::install();
    m.add("Error", py.get_type::<Error>())?;
    m.add("SceneError", py.get_type::<SceneError>())?;
    m.add("InputError", py.get_type::<InputError>())?;
    m.add("RenderError", py.get_type::<RenderError>())?;
    m.add_class::<scene::Shot>()?;
    m.add_class::<arrays::VolumeData>()?;
    m.add_class::<render::RenderData>()?;
    m.add_function(wrap_pyfunction!(info_json, m)?)?;
    m.add_function(wrap_pyfunction!(use_isolated_reader, m)?)?;
    m.add_function(wrap_pyfunction!(reader_main, m)?)?;
    m.add_function(wrap_pyfunction!(arrays::write_vdb, m)?)?;
    m.add_function(wrap_pyfunction!(render::render_shot, m)?)?;
    m.add_function(wrap_pyfunction!(render::read_exr, m)?)?;
    Ok(())
}
