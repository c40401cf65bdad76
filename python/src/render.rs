//! `render_shot`: a render through the same frame pipeline as `plume render`
//! (`plume::farm::job::render_command`), into a private temporary directory, handing back
//! every channel of the EXR it wrote, the file itself and the statistics record. The
//! Python API's arrays are those channels, and `Render.write_exr` writes those bytes: the
//! same file the command line writes, bit for bit in its pixels.
//!
//! **Threads and signals.** The render runs on a thread of its own while the calling
//! thread waits without holding the interpreter, waking every 50 ms to let Python run its
//! signal handlers (Ctrl-C). A `KeyboardInterrupt`, or an exception raised by the progress
//! callback, asks the render to stop at the end of the pass (`JobObserver::stop_requested`);
//! the partial frame is discarded and the exception is raised. Progress callbacks run on
//! the render thread, holding the interpreter only while they run.
//!
//! **Arrays in.** A `VolumeData` is written as a `.vdb` into the temporary directory and
//! the scene's volume file set to it, so the render reads exactly what the command line
//! would read from that file.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Mutex;
use std::time::Duration;

use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict};

use crate::arrays::VolumeData;
use crate::scene::Shot;
use crate::{to_py, RenderError};
use plume::farm::observer::{JobObserver, Pass, RunContext};
use plume::farm::part::Completion;
use plume_core::error::Error;

/// What a render produced: the EXR's channels, the file, the statistics record.
#[pyclass(module = "plume._plume", name = "RenderData", frozen)]
pub struct RenderData {
    /// Width of the image's data window.
    #[pyo3(get)]
    width: usize,
    /// Height of the image's data window.
    #[pyo3(get)]
    height: usize,
    /// Every float channel, in the file's order, row-major (`output::read_exr_channels`).
    channels: Vec<(String, Vec<f32>)>,
    /// The statistics record as JSON (the `--stats` line).
    #[pyo3(get)]
    stats_json: String,
    /// The EXR file as written.
    exr: Vec<u8>,
}

#[pymethods]
impl RenderData {
    /// The channel names, in the file's order.
    #[getter]
    fn channel_names(&self) -> Vec<String> {
        self.channels.iter().map(|(n, _)| n.clone()).collect()
    }

    /// Channel `name` as little-endian float32 bytes, row-major.
    fn channel<'py>(&self, py: Python<'py>, name: &str) -> PyResult<Bound<'py, PyBytes>> {
        let (_, values) = self
            .channels
            .iter()
            .find(|(n, _)| n == name)
            .ok_or_else(|| RenderError::new_err(format!("no channel {name:?} in the image")))?;
        let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
        Ok(PyBytes::new(py, &bytes))
    }

    /// Write the beauty as an 8-bit sRGB PNG to `path`, as `plume render`'s preview: scaled
    /// by `2^exposure` stops, or by the automatic exposure when `exposure` is None.
    #[pyo3(signature = (path, exposure=None))]
    fn write_png(&self, py: Python<'_>, path: PathBuf, exposure: Option<f32>) -> PyResult<()> {
        let pixels = self.rgba()?;
        let scale =
            exposure.map_or_else(|| plume::output::auto_exposure(&pixels), |ev| 2f32.powf(ev));
        let (w, h) = (self.width as u32, self.height as u32);
        py.detach(|| plume::output::write_png(&path, w, h, &pixels, scale)).map_err(|e| to_py(&e))
    }

    /// Write the EXR file as rendered to `path`, atomically.
    fn write_exr(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        py.detach(|| {
            plume_core::fs::write_atomic(&path, |w| std::io::Write::write_all(w, &self.exr))
        })
        .map_err(|e| to_py(&e))
    }
}

impl RenderData {
    /// The beauty as RGBA pixels.
    fn rgba(&self) -> PyResult<Vec<[f32; 4]>> {
        let find = |c: &str| {
            self.channels
                .iter()
                .find(|(n, _)| n == c)
                .map(|(_, v)| v)
                .ok_or_else(|| RenderError::new_err(format!("no channel {c:?} in the image")))
        };
        let (r, g, b, a) = (find("R")?, find("G")?, find("B")?, find("A")?);
        Ok((0..r.len()).map(|i| [r[i], g[i], b[i], a[i]]).collect())
    }
}

/// Every channel of the EXR file `path` (one `plume render` wrote, say), with an empty
/// statistics record.
#[pyfunction]
pub fn read_exr(py: Python<'_>, path: PathBuf) -> PyResult<RenderData> {
    py.detach(|| read_render(&path, "{}".into())).map_err(|e| to_py(&e))
}

/// The render's observer: calls the progress callback, keeps the statistics record, and
/// holds the first Python exception that asks the render to stop.
struct PyObserver {
    progress: Option<Py<PyAny>>,
    failure: Mutex<Option<PyErr>>,
    stop: AtomicBool,
    record: Mutex<Option<String>>,
}

impl PyObserver {
    fn fail(&self, e: PyErr) {
        let mut failure = locked(&self.failure);
        failure.get_or_insert(e);
        self.stop.store(true, Ordering::SeqCst);
    }
}

impl JobObserver for PyObserver {
    fn pass_done(&self, pass: &Pass) {
        let Some(progress) = &self.progress else { return };
        Python::attach(|py| {
            let call = || -> PyResult<()> {
                let d = PyDict::new(py);
                d.set_item("done", pass.done)?;
                d.set_item("target", pass.target)?;
                d.set_item("resumed", pass.resumed)?;
                d.set_item("fraction", pass.fraction)?;
                d.set_item("frame", pass.frame)?;
                progress.call1(py, (d,))?;
                Ok(())
            };
            if let Err(e) = call() {
                self.fail(e);
            }
        });
    }

    fn frame_done(
        &self,
        _index: usize,
        _frame: Option<i64>,
        _status: Completion,
        record: &plume_engine::stats::RenderStats,
    ) {
        if let Ok(json) = serde_json::to_string(record) {
            *locked(&self.record) = Some(json);
        }
    }

    fn stop_requested(&self) -> bool {
        self.stop.load(Ordering::SeqCst)
    }
}

/// `mutex`'s value, also after a panic elsewhere held it (the values here are plain data).
fn locked<T>(mutex: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    mutex.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// A private temporary directory, removed on drop.
struct TempDir(PathBuf);

impl TempDir {
    fn new() -> PyResult<TempDir> {
        static COUNT: AtomicU64 = AtomicU64::new(0);
        let n = COUNT.fetch_add(1, Ordering::SeqCst);
        let dir = std::env::temp_dir().join(format!("plume-python-{}-{n}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir)
            .map_err(|e| RenderError::new_err(format!("cannot create {}: {e}", dir.display())))?;
        Ok(TempDir(dir))
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// Render `shot` (with `volume`'s grids as its volume, when given), calling `progress`
/// with a dict after each pass; relative paths are relative to `working_dir`.
#[pyfunction]
#[pyo3(signature = (shot, working_dir, volume=None, progress=None))]
pub fn render_shot(
    py: Python<'_>,
    shot: &Shot,
    working_dir: PathBuf,
    volume: Option<PyRef<'_, VolumeData>>,
    progress: Option<Py<PyAny>>,
) -> PyResult<RenderData> {
    let dir = TempDir::new()?;
    let mut shot = shot.shot.clone();
    if let Some(volume) = &volume {
        let path = dir.0.join("volume.vdb");
        let data: &VolumeData = volume;
        py.detach(|| data.write_to(&path)).map_err(|e| to_py(&e))?;
        shot.scene.volume.file = path;
    }
    let output = dir.0.join("render.exr");
    shot.settings.output.image = output.clone();
    shot.settings.output.preview = None;
    shot.settings.output.stats = None;
    // The command line's "written" line would name the private temporary file
    shot.settings.render.quiet = true;
    let frames = match &shot.settings.farm.frames {
        Some(list) => plume_scene::frames::parse_frames(list)
            .map_err(|m| to_py(&Error::invalid("farm.frames", m)))?
            .len(),
        None => 1,
    };
    if frames != 1 {
        return Err(crate::SceneError::new_err(format!(
            "farm.frames: plume.render renders one frame, and {frames} are given; render each frame in its own call (farm.frames = \"N\")"
        )));
    }
    if shot.settings.render.debug_pixel.is_some() {
        return Err(crate::SceneError::new_err(
            "render.debug_pixel: replaying one sample is the command line's (plume render --debug-pixel); plume.render renders images",
        ));
    }
    let valid = shot.validate().map_err(|e| to_py(&e))?;
    let observer = PyObserver {
        progress,
        failure: Mutex::new(None),
        stop: AtomicBool::new(false),
        record: Mutex::new(None),
    };
    let result = run_watched(py, &observer, || {
        let context = RunContext {
            command_line: "python: plume.render",
            working_dir: &working_dir,
            observer: &observer,
        };
        plume::farm::job::render_command(&valid, &context)
    });
    if let Some(e) = locked(&observer.failure).take() {
        return Err(e);
    }
    match result {
        // `farm.time_limit` ran out: the frame reached was written, and its record says so
        Ok(()) | Err(Error::TimeLimit { .. }) => {}
        Err(e) => return Err(to_py(&e)),
    }
    let stats_json = locked(&observer.record).take().unwrap_or_else(|| "{}".into());
    py.detach(|| read_render(&output, stats_json)).map_err(|e| to_py(&e))
}

/// Run `render` on a thread of its own while this thread, not holding the interpreter,
/// wakes every 50 ms to let Python handle signals; an exception from a handler
/// (`KeyboardInterrupt`) goes to `observer`, which stops the render.
fn run_watched(
    py: Python<'_>,
    observer: &PyObserver,
    render: impl FnOnce() -> plume::Result<()> + Send,
) -> plume::Result<()> {
    std::thread::scope(|scope| {
        let handle = scope.spawn(render);
        loop {
            let finished = py.detach(|| {
                let deadline = std::time::Instant::now() + Duration::from_millis(50);
                while !handle.is_finished() && std::time::Instant::now() < deadline {
                    std::thread::sleep(Duration::from_millis(2));
                }
                handle.is_finished()
            });
            if finished {
                break;
            }
            if let Err(e) = py.check_signals() {
                observer.fail(e);
            }
        }
        handle.join().unwrap_or_else(|_| {
            Err(Error::Scene("the render thread panicked; nothing was written".into()))
        })
    })
}

/// The EXR at `path`: every float channel of its first layer, and the file's bytes.
fn read_render(path: &Path, stats_json: String) -> plume::Result<RenderData> {
    let exr =
        std::fs::read(path).map_err(|source| Error::Open { path: path.to_path_buf(), source })?;
    let image = plume::output::read_exr_channels(path)?;
    Ok(RenderData {
        width: image.width,
        height: image.height,
        channels: image.channels,
        stats_json,
        exr,
    })
}
