//! Images between numpy and the library: (H, W, 3) float32 arrays, EXR files written as
//! the CLI writes them, chunk merging (`mediareg merge`).

use std::path::{Path, PathBuf};

use numpy::{PyArray1, PyArray3, PyArrayMethods, PyReadonlyArray3, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use mediareg::denoise::{oidn, Aux, OidnError};
use mediareg::image::{self, merge as merging, Image};

use crate::{bad_arg, error};

/// An image as a float32 numpy array (H, W, 3), row 0 at the top.
pub(crate) fn to_numpy(py: Python<'_>, img: Image) -> PyResult<Bound<'_, PyArray3<f32>>> {
    let (w, h) = (img.width, img.height);
    PyArray1::from_vec(py, img.pixels.into_flattened()).reshape([h, w, 3])
}

pub(crate) fn from_numpy(array: &PyReadonlyArray3<'_, f32>) -> PyResult<Image> {
    let [height, width, c] = array.shape() else {
        unreachable!("a 3-d array")
    };
    if *c != 3 {
        return Err(bad_arg(format!(
            "the array's shape is ({height}, {width}, {c}); expected (H, W, 3): RGB"
        )));
    }
    let a = array.as_array();
    let pixels = (0..*height)
        .flat_map(|y| (0..*width).map(move |x| (y, x)))
        .map(|(y, x)| [a[[y, x, 0]], a[[y, x, 1]], a[[y, x, 2]]])
        .collect();
    Ok(Image {
        width: *width,
        height: *height,
        pixels,
    })
}

fn check_exr(path: &Path) -> PyResult<()> {
    if path.extension().and_then(|e| e.to_str()) != Some("exr") {
        return Err(bad_arg(format!("{} must end in .exr", path.display())));
    }
    Ok(())
}

/// write_exr(path, array, spp=None): float32 (H, W, 3) → linear RGB EXR, with the spp in
/// the header when given (as `mediareg render` writes it; `merge` weights by it).
#[pyfunction]
#[pyo3(signature = (path, array, spp=None))]
pub fn write_exr(
    path: PathBuf,
    array: PyReadonlyArray3<'_, f32>,
    spp: Option<u64>,
) -> PyResult<()> {
    check_exr(&path)?;
    let img = from_numpy(&array)?;
    image::write_render_exr(&path, &img, spp).map_err(error)
}

/// read_exr(path) → float32 (H, W, 3).
#[pyfunction]
pub fn read_exr(py: Python<'_>, path: PathBuf) -> PyResult<Bound<'_, PyArray3<f32>>> {
    let img = image::read_exr(&path).map_err(error)?;
    to_numpy(py, img)
}

/// merge(paths, out=None) → dict(image, variance, spp, chunks), as `mediareg merge`.
#[pyfunction]
#[pyo3(signature = (paths, out=None))]
pub fn merge<'py>(
    py: Python<'py>,
    paths: Vec<PathBuf>,
    out: Option<PathBuf>,
) -> PyResult<Bound<'py, PyDict>> {
    if let Some(out) = &out {
        check_exr(out)?;
    }
    let merged = py
        .detach(|| -> anyhow::Result<_> {
            let merged = merging::merge_files(&paths)?;
            if let Some(out) = &out {
                merging::write_merged(out, &merged)?;
            }
            Ok(merged)
        })
        .map_err(error)?;
    let d = PyDict::new(py);
    d.set_item("spp", merged.spp)?;
    d.set_item("chunks", merged.chunks)?;
    d.set_item("image", to_numpy(py, merged.mean)?)?;
    match merged.var {
        Some(v) => d.set_item("variance", to_numpy(py, v)?)?,
        None => d.set_item("variance", py.None())?,
    }
    Ok(d)
}

/// denoise(color, albedo=None, normal=None, clean_aux=True): Intel Open Image Denoise's
/// `RT` filter on (H, W, 3) float32 arrays (HDR colour; normal only with albedo).
#[pyfunction]
#[pyo3(signature = (color, albedo=None, normal=None, clean_aux=true))]
pub fn denoise<'py>(
    py: Python<'py>,
    color: PyReadonlyArray3<'py, f32>,
    albedo: Option<PyReadonlyArray3<'py, f32>>,
    normal: Option<PyReadonlyArray3<'py, f32>>,
    clean_aux: bool,
) -> PyResult<Bound<'py, PyArray3<f32>>> {
    let color = from_numpy(&color)?;
    let albedo = albedo.as_ref().map(from_numpy).transpose()?;
    let normal = normal.as_ref().map(from_numpy).transpose()?;
    if normal.is_some() && albedo.is_none() {
        return Err(bad_arg(
            "normal= needs albedo= too (Open Image Denoise takes albedo alone, or both)",
        ));
    }
    for (name, img) in [("albedo", &albedo), ("normal", &normal)] {
        if let Some(i) = img {
            if (i.width, i.height) != (color.width, color.height) {
                return Err(bad_arg(format!(
                    "{name} is {}x{}, color {}x{}: one size",
                    i.height, i.width, color.height, color.width
                )));
            }
        }
    }
    let aux = albedo.as_ref().map(|a| Aux {
        albedo: &a.pixels,
        normal: normal.as_ref().map(|n| &n.pixels[..]),
        clean: clean_aux,
    });
    let lib = oidn::load().map_err(|e| crate::Error::new_err(e.to_string()))?;
    let (w, h) = (color.width, color.height);
    let out = py
        .detach(|| lib.denoise_rt(w, h, &color.pixels, aux))
        .map_err(|e| match e {
            OidnError::BadInput(m) => bad_arg(m),
            e => crate::Error::new_err(e.to_string()),
        })?;
    to_numpy(
        py,
        Image {
            width: w,
            height: h,
            pixels: out,
        },
    )
}
