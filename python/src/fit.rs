//! `fit`: a medium's parameters from target images (`mediareg::fit`, what `mediareg
//! fit` runs), on a thread of its own so that Ctrl-C stops it.

use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

use numpy::PyReadonlyArray3;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};

use mediareg::fit::{FitSettings, FitTarget};
use mediareg::integrator::MediumParam;
use mediareg::{load_scene, xml, BuildOverrides};

use crate::images::from_numpy;
use crate::render::interruptible;
use crate::{bad_arg, param_text, SceneError};

/// fit(path, targets, params=["sigma_t", "albedo", "g"], medium=None, spp=32,
///     iterations=None, seed=0, search_path=None, **params)
#[pyfunction]
#[pyo3(signature = (path, targets, params=None, medium=None, spp=32, iterations=None, seed=0, search_path=None, **defines))]
#[allow(clippy::too_many_arguments)]
pub fn fit<'py>(
    py: Python<'py>,
    path: PathBuf,
    targets: Vec<Bound<'py, PyAny>>,
    params: Option<Vec<String>>,
    medium: Option<String>,
    spp: u32,
    iterations: Option<u32>,
    seed: u64,
    search_path: Option<Vec<PathBuf>>,
    defines: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyDict>> {
    if spp == 0 || iterations == Some(0) {
        return Err(bad_arg("spp and iterations must be at least 1"));
    }
    let names = params.unwrap_or_else(|| vec!["sigma_t".into(), "albedo".into(), "g".into()]);
    let params = MediumParam::parse_list(&names.join(","))
        .map_err(|e| bad_arg(format!("params={names:?}: {e}")))?;
    let mut global = Vec::new();
    for (k, v) in defines.into_iter().flat_map(|d| d.iter()) {
        global.push((k.extract::<String>()?, param_text(&v)?));
    }
    let mut fit_targets = Vec::new();
    for (i, t) in targets.iter().enumerate() {
        // An image, or (image, {name: value}) for a target rendered with other parameters.
        let (image, own) = match t.cast::<PyTuple>() {
            Ok(pair) if pair.len() == 2 => (pair.get_item(0)?, Some(pair.get_item(1)?)),
            _ => (t.clone(), None),
        };
        let array: PyReadonlyArray3<f32> = image.extract().map_err(|_| {
            bad_arg(format!(
                "targets[{i}]: a float32 array (H, W, 3), or (array, {{name: value}})"
            ))
        })?;
        let mut all = global.clone();
        if let Some(own) = own {
            let own = own
                .cast::<PyDict>()
                .map_err(|_| bad_arg(format!("targets[{i}]: the parameters are a dict")))?;
            for (k, v) in own.iter() {
                all.push((k.extract::<String>()?, param_text(&v)?));
            }
        }
        let opts = xml::LoadOptions {
            params: all,
            search_dirs: search_path.clone().unwrap_or_default(),
            strict_v3: false,
        };
        let scene = py
            .detach(|| load_scene(&path, &opts, &BuildOverrides::default()))
            .map_err(|e| SceneError::new_err(e.to_string()))?;
        fit_targets.push(FitTarget {
            scene,
            image: from_numpy(&array)?,
        });
    }
    let cancel = Arc::new(AtomicBool::new(false));
    let settings = FitSettings {
        medium,
        params,
        spp,
        iterations: iterations.unwrap_or(mediareg::fit::DEFAULT_ITERATIONS),
        max_iterations: iterations.unwrap_or(mediareg::fit::MAX_ITERATIONS),
        seed,
        cancel: Some(Arc::clone(&cancel)),
    };
    let result = interruptible(py, &cancel, move || {
        mediareg::fit::fit(&mut fit_targets, &settings, |_| {})
    })?
    .map_err(|e| bad_arg(e.to_string()))?;
    let out = PyDict::new(py);
    let values = PyDict::new(py);
    let ci = PyDict::new(py);
    for ((u, v), c) in result.unknowns.iter().zip(&result.values).zip(&result.ci) {
        values.set_item(u.label(), v)?;
        ci.set_item(u.label(), (c[0], c[1]))?;
    }
    out.set_item("params", values)?;
    out.set_item("ci", ci)?;
    out.set_item("loss", result.loss)?;
    out.set_item("iterations", result.iterations)?;
    out.set_item("converged", result.converged)?;
    out.set_item("seconds", result.seconds)?;
    Ok(out)
}
