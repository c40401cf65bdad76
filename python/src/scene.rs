//! `Shot`: a scene as the scene file holds it, read from a TOML file or built from nested
//! Python dicts, and written back as TOML. Both ways in go through the scene-file parser
//! (`plume_scene::file::SceneFile::parse`), so keys, defaults and messages are the scene
//! file's.

use std::path::{Path, PathBuf};

use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple};

use crate::to_py;
use plume::Error;
use plume_scene::file::{to_toml, SceneFile};

/// A scene and its job settings, as a scene file holds them.
#[pyclass(module = "plume._plume", name = "Shot", frozen)]
#[derive(Clone)]
pub struct Shot {
    pub(crate) shot: plume_scene::Shot,
}

/// What errors call a scene built from keyword arguments.
const KEYS_NAME: &str = "plume.Scene(...)";

#[pymethods]
impl Shot {
    /// Read a scene file; its relative paths are relative to the file's directory.
    #[staticmethod]
    fn from_toml(path: PathBuf) -> PyResult<Shot> {
        let (shot, _) = SceneFile::read(&path).map_err(|e| to_py(&e))?;
        Ok(Shot { shot })
    }

    /// A scene from nested dicts of scene-file keys (`{"camera": {"width": 64}}`); relative
    /// paths are relative to `working_dir`.
    #[staticmethod]
    fn from_keys(keys: &Bound<'_, PyDict>, working_dir: PathBuf) -> PyResult<Shot> {
        let table = table_of(keys, "")?;
        let text = toml::to_string(&table)
            .map_err(|e| crate::SceneError::new_err(format!("{KEYS_NAME}: {e}")))?;
        let (shot, _) =
            SceneFile::parse(Path::new(KEYS_NAME), text, &working_dir).map_err(|e| {
                // The generated text's line numbers mean nothing to the caller: the key does
                let e = match e {
                    Error::SceneFile { path, key, message, .. } => {
                        Error::SceneFile { path, line: None, key, message }
                    }
                    other => other,
                };
                to_py(&e)
            })?;
        Ok(Shot { shot })
    }

    /// The scene as a TOML scene file, every path absolute (relative ones made so against
    /// `working_dir`), so that it renders the same from anywhere.
    fn to_toml(&self, working_dir: PathBuf) -> PyResult<String> {
        to_toml(&self.shot, &working_dir).map_err(|e| to_py(&e))
    }

    /// The volume file the scene names.
    #[getter]
    fn volume_file(&self) -> PathBuf {
        self.shot.scene.volume.file.clone()
    }
}

/// A Python dict of scene-file keys as a TOML table; `at` is the dotted key of the dict,
/// for messages.
fn table_of(dict: &Bound<'_, PyDict>, at: &str) -> PyResult<toml::Table> {
    let mut table = toml::Table::new();
    for (k, v) in dict.iter() {
        let key: String = k.extract().map_err(|_| {
            PyTypeError::new_err(format!("{KEYS_NAME}: key {k} of {at:?} is not a string"))
        })?;
        let path = if at.is_empty() { key.clone() } else { format!("{at}.{key}") };
        table.insert(key, value_of(&v, &path)?);
    }
    Ok(table)
}

/// A Python value as a TOML value: bool, int, float, str, path, list or tuple, dict.
fn value_of(v: &Bound<'_, PyAny>, at: &str) -> PyResult<toml::Value> {
    if v.is_instance_of::<PyBool>() {
        return Ok(toml::Value::Boolean(v.extract()?));
    }
    if v.is_instance_of::<PyInt>() {
        return Ok(toml::Value::Integer(v.extract()?));
    }
    if v.is_instance_of::<PyFloat>() {
        return Ok(toml::Value::Float(v.extract()?));
    }
    if v.is_instance_of::<PyString>() {
        return Ok(toml::Value::String(v.extract()?));
    }
    if let Ok(d) = v.cast::<PyDict>() {
        return Ok(toml::Value::Table(table_of(d, at)?));
    }
    if v.is_instance_of::<PyList>() || v.is_instance_of::<PyTuple>() {
        let items: Vec<Bound<'_, PyAny>> = v.try_iter()?.collect::<PyResult<_>>()?;
        return items
            .iter()
            .enumerate()
            .map(|(i, item)| value_of(item, &format!("{at}[{i}]")))
            .collect::<PyResult<Vec<_>>>()
            .map(toml::Value::Array);
    }
    // os.PathLike, then NumPy scalars and anything else with __index__ or __float__
    let py = v.py();
    if let Ok(path) = py.import("os")?.call_method1("fspath", (v,)) {
        return Ok(toml::Value::String(path.extract()?));
    }
    if v.hasattr("__index__")? {
        return Ok(toml::Value::Integer(v.call_method0("__index__")?.extract()?));
    }
    if v.hasattr("__float__")? {
        return Ok(toml::Value::Float(v.call_method0("__float__")?.extract()?));
    }
    Err(PyTypeError::new_err(format!(
        "{KEYS_NAME}: key {at}: a {} is not a scene value (bool, int, float, str, path, list or dict; leave a key out for its default)",
        v.get_type().name()?
    )))
}
