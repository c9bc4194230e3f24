//! `mediareg._mediareg`: the native part of the `mediareg` Python package. Bindings
//! only: loading, rendering, writing and merging are the library's functions, the ones
//! the command line calls, so the module's images (and EXR files) are the CLI's bit for
//! bit. `python/mediareg/__init__.py` documents the API users see.

mod backward;
mod fit;
mod images;
mod regularize;
mod render;

use std::path::PathBuf;
use std::sync::Arc;

use pyo3::create_exception;
use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyString};

use mediareg::{load_scene, xml, BuildOverrides};

create_exception!(
    _mediareg,
    Error,
    PyRuntimeError,
    "An error of mediareg (a file that cannot be read or written, a render refused)."
);
create_exception!(
    _mediareg,
    SceneError,
    Error,
    "A scene file mediareg cannot load: the message starts with file:line:col, as the CLI's."
);

/// A library error as a Python exception, with the CLI's message (causes included).
pub(crate) fn error(e: anyhow::Error) -> PyErr {
    Error::new_err(format!("{e:#}"))
}

/// A loaded scene (Mitsuba's `mi.load_file` result): the render state and the shot its
/// file describes.
#[pyclass(frozen, name = "Scene", module = "mediareg")]
pub struct PyScene {
    pub(crate) inner: Arc<mediareg::scene::Scene>,
    path: PathBuf,
    /// The sensor the scene was built for (its medium is part of the built scene).
    pub(crate) sensor: usize,
}

#[pymethods]
impl PyScene {
    /// The scene file.
    #[getter]
    fn path(&self) -> PathBuf {
        self.path.clone()
    }
    /// The rendered image's width in pixels (the film's crop window).
    #[getter]
    fn width(&self) -> usize {
        self.inner.shot.film.crop_size.0
    }
    #[getter]
    fn height(&self) -> usize {
        self.inner.shot.film.crop_size.1
    }
    /// The sampler's sample_count (what `render(spp=None)` uses).
    #[getter]
    fn spp(&self) -> u32 {
        self.inner.shot.spp
    }
    /// The media as `render(medium=...)` takes them: the XML id, else the
    /// `mi.traverse` key (`<shape id>.interior_medium`), else the slot and its shape's line.
    #[getter]
    fn media(&self) -> Vec<String> {
        (0..self.inner.media.len() as u32)
            .map(|m| self.inner.medium_name(m))
            .collect()
    }
    /// What the loader accepted but the user should hear about (one line each).
    #[getter]
    fn warnings(&self) -> Vec<String> {
        self.inner.warnings.clone()
    }
    fn __repr__(&self) -> String {
        let (w, h) = self.inner.shot.film.crop_size;
        format!(
            "mediareg.Scene('{}', {w}x{h}, {} spp)",
            self.path.display(),
            self.inner.shot.spp
        )
    }
}

/// A scene parameter's value as the XML would spell it (`-D name=value`).
pub(crate) fn param_text(value: &Bound<'_, PyAny>) -> PyResult<String> {
    if let Ok(b) = value.cast::<PyBool>() {
        return Ok(if b.is_true() { "true" } else { "false" }.into());
    }
    if let Ok(s) = value.cast::<PyString>() {
        return Ok(s.to_str()?.to_owned());
    }
    Ok(value.str()?.to_str()?.to_owned())
}

/// load_file(path, search_path=None, strict_v3=False, sensor=None, **params)
#[pyfunction]
#[pyo3(signature = (path, search_path=None, strict_v3=false, sensor=None, **params))]
fn load_file(
    py: Python<'_>,
    path: PathBuf,
    search_path: Option<Vec<PathBuf>>,
    strict_v3: bool,
    sensor: Option<usize>,
    params: Option<&Bound<'_, PyDict>>,
) -> PyResult<PyScene> {
    let mut defines = Vec::new();
    for (k, v) in params.into_iter().flat_map(|d| d.iter()) {
        defines.push((k.extract::<String>()?, param_text(&v)?));
    }
    let opts = xml::LoadOptions {
        params: defines,
        search_dirs: search_path.unwrap_or_default(),
        strict_v3,
    };
    // Loading builds the BVH (seconds for a large mesh): without the GIL.
    let scene = py
        .detach(|| {
            let overrides = BuildOverrides {
                sensor,
                ..Default::default()
            };
            load_scene(&path, &opts, &overrides)
        })
        .map_err(|e| SceneError::new_err(e.to_string()))?;
    Ok(PyScene {
        inner: Arc::new(scene),
        path,
        sensor: sensor.unwrap_or(0),
    })
}

#[pymodule]
fn _mediareg(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("Error", m.py().get_type::<Error>())?;
    m.add("SceneError", m.py().get_type::<SceneError>())?;
    m.add_class::<PyScene>()?;
    m.add_function(wrap_pyfunction!(load_file, m)?)?;
    m.add_function(wrap_pyfunction!(render::render, m)?)?;
    m.add_function(wrap_pyfunction!(regularize::regularize, m)?)?;
    m.add_function(wrap_pyfunction!(fit::fit, m)?)?;
    m.add_function(wrap_pyfunction!(backward::backward, m)?)?;
    m.add_function(wrap_pyfunction!(backward::write_vol, m)?)?;
    m.add_function(wrap_pyfunction!(images::write_exr, m)?)?;
    m.add_function(wrap_pyfunction!(images::read_exr, m)?)?;
    m.add_function(wrap_pyfunction!(images::merge, m)?)?;
    m.add_function(wrap_pyfunction!(images::denoise, m)?)?;
    Ok(())
}

/// A keyword argument the caller got wrong.
pub(crate) fn bad_arg(msg: impl Into<String>) -> PyErr {
    PyValueError::new_err(msg.into())
}
