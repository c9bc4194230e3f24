//! `regularize`: the paper's method (`mediareg regularize`) on a loaded scene, its
//! options made by the library's `regularize::choices`, as the CLI's are.

use std::path::PathBuf;
use std::sync::Arc;

use glam::Vec3;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use mediareg::regularize::pipeline::PilotSize;
use mediareg::regularize::sequence::CameraPath;
use mediareg::regularize::{choices, ChoiceError, Choices, Method, Motion, Reproject};

use crate::images::to_numpy;
use crate::render::thread_pool;
use crate::{bad_arg, param_text, PyScene, SceneError};

/// regularize(scene, spp=None, seed=0, threads=None, medium=None, predict="difference",
/// factor=None, pilot_renders=8, pilot_spp=1, c_beta=0.5, fit_spp=4, fit_at=1.0,
/// frames=11, wa=0.1, reproject="exact", orbit=None, target=None, dolly=None,
/// camera_path=None, spatial=None, denoise=None, pick=True, oidn_check=False)
#[pyfunction]
#[pyo3(signature = (scene, spp=None, seed=0, threads=None, medium=None, predict="difference",
    factor=None, pilot_renders=8, pilot_spp=1, c_beta=None, fit_spp=4, fit_at=1.0, frames=11,
    wa=0.1, reproject="exact", orbit=None, target=None, dolly=None, camera_path=None,
    spatial=None, denoise=None, pick=true, oidn_check=false))]
#[allow(clippy::too_many_arguments)]
pub fn regularize<'py>(
    py: Python<'py>,
    scene: &Bound<'py, PyScene>,
    spp: Option<u32>,
    seed: u64,
    threads: Option<usize>,
    medium: Option<String>,
    predict: &str,
    factor: Option<&Bound<'py, PyAny>>,
    pilot_renders: usize,
    pilot_spp: u32,
    c_beta: Option<&Bound<'py, PyAny>>,
    fit_spp: u32,
    fit_at: f32,
    frames: usize,
    wa: f64,
    reproject: &str,
    orbit: Option<f32>,
    target: Option<[f32; 3]>,
    dolly: Option<f32>,
    camera_path: Option<PathBuf>,
    spatial: Option<bool>,
    denoise: Option<&str>,
    pick: bool,
    oidn_check: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let data = Arc::clone(&scene.get().inner);
    if spp == Some(0) {
        return Err(bad_arg(
            "spp must be at least 1 (None: the sampler's sample_count)",
        ));
    }
    let c_beta_text = match c_beta {
        Some(c) => param_text(c)?,
        None => "0.5".into(),
    };
    let c_beta = choices::parse_c_beta(&c_beta_text, fit_spp, fit_at).ok_or_else(|| {
        bad_arg(format!(
            "c_beta={c_beta_text}: expected a number or \"fit\""
        ))
    })?;
    let method = match predict {
        "difference" => Method::Difference,
        "plain" => Method::Radiance,
        "paper" => Method::Paper(c_beta),
        "linear" => Method::Linear,
        "loglinear" => Method::LogLinear,
        p => {
            return Err(bad_arg(format!(
                "predict=\"{p}\": one of \"difference\", \"paper\", \"linear\", \"loglinear\", \"plain\""
            )))
        }
    };
    let factor = match factor {
        None => None,
        Some(f) => {
            let text = param_text(f)?;
            Some(
                choices::parse_factor(&text)
                    .ok_or_else(|| bad_arg(format!("factor={text}: a number or \"auto\"")))?,
            )
        }
    };
    let motion = match (orbit, dolly, camera_path) {
        (None, None, None) => Motion::Static,
        (Some(degrees), None, None) => Motion::Orbit {
            degrees,
            target: target.map(Vec3::from),
        },
        (None, Some(d), None) => Motion::Dolly(d),
        (None, None, Some(file)) => {
            Motion::Path(CameraPath::read(&file).map_err(|e| SceneError::new_err(e.to_string()))?)
        }
        _ => {
            return Err(bad_arg(
                "orbit=, dolly= and camera_path= exclude one another",
            ))
        }
    };
    if target.is_some() && !matches!(motion, Motion::Orbit { .. }) {
        return Err(bad_arg("target= is the centre of orbit=; pass both"));
    }
    // As the CLI's --denoise: None picks OIDN when the library loads (difference, plain).
    let oidn = match (denoise, spatial) {
        (Some("oidn"), _) => Some(true),
        (Some("bilateral"), _) => Some(false),
        (Some(d), _) => {
            return Err(bad_arg(format!(
                "denoise=\"{d}\": one of \"oidn\", \"bilateral\" (None: oidn when the library is there)"
            )))
        }
        (None, Some(true)) => Some(false),
        (None, _) => None,
    };
    if oidn == Some(true) {
        mediareg::denoise::oidn::load().map_err(|e| crate::Error::new_err(e.to_string()))?;
    }
    let reproject = match reproject {
        "exact" => Reproject::Exact,
        "shift" => Reproject::Shift,
        "none" => Reproject::None,
        r => {
            return Err(bad_arg(format!(
                "reproject=\"{r}\": one of \"exact\", \"shift\", \"none\""
            )))
        }
    };
    let choices = Choices {
        medium,
        method,
        factor,
        pilot: PilotSize {
            chunks: pilot_renders,
            spp: pilot_spp,
        },
        frames,
        w_a: wa,
        reproject,
        motion,
        spatial,
        oidn,
        pick,
        oidn_check,
        show_progress: false,
    };
    let shot = data.shot.with(spp.unwrap_or(data.shot.spp), seed);
    let (opts, shot) = choices::options(&data, &shot, &choices).map_err(|e| match e {
        ChoiceError::Medium(_) => bad_arg(format!("medium: {e}")),
        ChoiceError::NoOrbitCentre => bad_arg(format!(
            "orbit: {e}; give the orbit's centre with target=(x, y, z)"
        )),
    })?;
    let pool = thread_pool(threads)?;
    // The method has no stop flag: Ctrl-C is seen when it returns.
    let r = py
        .detach(move || {
            let run = || mediareg::regularize::regularize(&data, &shot, &opts);
            match pool {
                Some(p) => p.install(run),
                None => run(),
            }
        })
        .map_err(|e| bad_arg(e.to_string()))?;
    let d = PyDict::new(py);
    d.set_item("predicted", to_numpy(py, r.predicted)?)?;
    d.set_item("source", to_numpy(py, r.source)?)?;
    d.set_item("dalbedo_raw", to_numpy(py, r.raw_gradient)?)?;
    d.set_item("dalbedo", to_numpy(py, r.gradient)?)?;
    d.set_item("albedo_source", r.albedos.source.to_array())?;
    d.set_item("albedo_target", r.albedos.target.to_array())?;
    d.set_item("factor", r.pilot.map(|p| p.factor))?;
    d.set_item("c_beta", r.c_beta)?;
    d.set_item("frames", r.frames_rendered)?;
    d.set_item(
        "pipeline",
        r.pipeline_check.as_ref().map(|c| c.chosen.as_str()),
    )?;
    Ok(d)
}
