//! `backward`: reverse-mode gradients of a grid medium's voxels (what `mediareg
//! backward` runs) as numpy arrays, and `write_vol` to hand a volume back to a scene.

use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

use numpy::{
    PyArray1, PyArrayMethods, PyReadonlyArray3, PyReadonlyArrayDyn, PyUntypedArrayMethods,
};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use mediareg::integrator::backward::{backward as reverse_mode, BackwardOptions};
use mediareg::medium::grid::{write_vol_like, GridData, Source, Volume};

use crate::images::from_numpy;
use crate::render::{interruptible, thread_pool};
use crate::{bad_arg, PyScene};

/// The (z, y, x[, 3]) shape of a grid's data.
fn shape(volume: &Volume) -> Option<Vec<usize>> {
    let Source::Grid { grid, .. } = &volume.source else {
        return None;
    };
    let mut s = vec![grid.res[2], grid.res[1], grid.res[0]];
    if grid.channels == 3 {
        s.push(3);
    }
    Some(s)
}

/// backward(scene, adjoint, params=["sigma_t"], medium=None, spp=None, seed=0,
///          threads=None) → dict of float32 arrays shaped as the grids' data (z, y, x).
#[pyfunction]
#[pyo3(signature = (scene, adjoint, params=None, medium=None, spp=None, seed=0, threads=None))]
#[allow(clippy::too_many_arguments)]
pub fn backward<'py>(
    py: Python<'py>,
    scene: &Bound<'py, PyScene>,
    adjoint: PyReadonlyArray3<'py, f32>,
    params: Option<Vec<String>>,
    medium: Option<&str>,
    spp: Option<u32>,
    seed: u64,
    threads: Option<usize>,
) -> PyResult<Bound<'py, PyDict>> {
    let params = params.unwrap_or_else(|| vec!["sigma_t".into()]);
    let (mut sigma_t, mut albedo) = (false, false);
    for p in &params {
        match p.as_str() {
            "sigma_t" => sigma_t = true,
            "albedo" => albedo = true,
            o => {
                return Err(bad_arg(format!(
                    "params: unknown volume {o:?} (sigma_t, albedo)"
                )))
            }
        }
    }
    if spp == Some(0) {
        return Err(bad_arg(
            "spp must be at least 1 (None: the sampler's sample_count)",
        ));
    }
    let adjoint = from_numpy(&adjoint)?;
    let data = Arc::clone(&scene.get().inner);
    let mi = data
        .medium_index(medium)
        .map_err(|e| bad_arg(format!("medium={medium:?}: {e}")))?;
    let shot = data.shot.with(spp.unwrap_or(data.shot.spp), seed);
    let cancel = Arc::new(AtomicBool::new(false));
    let opts = BackwardOptions {
        medium: mi,
        sigma_t,
        albedo,
        cancel: Some(Arc::clone(&cancel)),
        ..Default::default()
    };
    let pool = thread_pool(threads)?;
    let scene_ref = Arc::clone(&data);
    let grads = interruptible(py, &cancel, move || {
        let run = || reverse_mode(&scene_ref, &shot, &adjoint, &opts);
        match pool {
            Some(p) => p.install(run),
            None => run(),
        }
    })?
    .map_err(|e| bad_arg(e.to_string()))?;
    if grads.interrupted {
        return Err(crate::Error::new_err("the gradient was interrupted"));
    }
    let het = data.media[mi as usize]
        .heterogeneous
        .as_deref()
        .expect("checked by backward");
    let dict = PyDict::new(py);
    for (name, values, volume) in [
        ("sigma_t", grads.sigma_t, &het.sigma_t),
        ("albedo", grads.albedo, &het.albedo),
    ] {
        if let (Some(v), Some(s)) = (values, shape(volume)) {
            let a = PyArray1::from_vec(py, v).reshape(s)?;
            dict.set_item(name, a)?;
        }
    }
    Ok(dict)
}

/// write_vol(path, array): a (z, y, x) or (z, y, x, 3) float32 array as a Mitsuba
/// .vol file (bounding box the unit cube), for a scene that reads its grid from `path`.
#[pyfunction]
pub fn write_vol(path: PathBuf, array: PyReadonlyArrayDyn<'_, f32>) -> PyResult<()> {
    let s = array.shape().to_vec();
    let channels = match s.len() {
        3 => 1,
        4 if s[3] == 3 => 3,
        _ => {
            return Err(bad_arg(
                "write_vol: a (z, y, x) or (z, y, x, 3) float32 array",
            ))
        }
    };
    let data: Vec<f32> = array.as_array().iter().copied().collect();
    let grid = GridData {
        res: [s[2], s[1], s[0]],
        channels,
        data: Vec::new(),
        file_bbox: [glam::Vec3::ZERO, glam::Vec3::ONE],
    };
    std::fs::write(&path, write_vol_like(&grid, &data))
        .map_err(|e| crate::Error::new_err(format!("{}: {e}", path.display())))
}
