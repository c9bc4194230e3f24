//! `render`: the library's render driver (what `mediareg render` runs) without the GIL,
//! on a thread of its own so that the caller's thread can watch for Ctrl-C.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::time::Duration;

use pyo3::exceptions::PyRuntimeError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};

use mediareg::denoise::AuxUse;
use mediareg::integrator::{self, volpath::Estimand, GradientError, MediumParam, RenderOptions};
use mediareg::scene::MediumChoiceError;

use crate::images::to_numpy;
use crate::{bad_arg, error, PyScene};

/// How often the caller's thread looks for signals (Ctrl-C) while a render runs.
const SIGNAL_CHECK: Duration = Duration::from_millis(100);

/// render(scene, spp=None, seed=0, sensor=None, threads=None, gradient=None, medium=None,
///        denoise=None)
#[pyfunction]
#[pyo3(signature = (scene, spp=None, seed=0, sensor=None, threads=None, gradient=None, medium=None, denoise=None))]
#[allow(clippy::too_many_arguments)]
pub fn render<'py>(
    py: Python<'py>,
    scene: &Bound<'py, PyScene>,
    spp: Option<u32>,
    seed: u64,
    sensor: Option<usize>,
    threads: Option<usize>,
    gradient: Option<&Bound<'py, PyAny>>,
    medium: Option<&str>,
    denoise: Option<&str>,
) -> PyResult<Bound<'py, PyAny>> {
    // "albedo" (the image and its derivative, as before), or a list of parameter names
    // (the image and a dict of derivatives by name).
    let (names, as_dict) = match gradient {
        None => (None, false),
        Some(g) => match g.extract::<String>() {
            Ok(one) => (Some(one), false),
            Err(_) => {
                let list: Vec<String> = g.extract().map_err(|_| {
                    bad_arg("gradient= takes a parameter name or a list of them (sigma_t, albedo, g, scale)")
                })?;
                (Some(list.join(",")), true)
            }
        },
    };
    let data = Arc::clone(&scene.get().inner);
    let built_for = scene.get().sensor;
    if let Some(sensor) = sensor.filter(|&s| s != built_for) {
        return Err(bad_arg(format!(
            "sensor={sensor}: this scene was built for sensor {built_for}; load_file(path, sensor={sensor}) builds it for sensor {sensor} (a sensor's medium is part of the built scene)"
        )));
    }
    if spp == Some(0) {
        return Err(bad_arg(
            "spp must be at least 1 (None: the sampler's sample_count)",
        ));
    }
    if medium.is_some() && names.is_none() {
        return Err(bad_arg(
            "medium= names the medium whose parameters gradient= differentiates; pass both",
        ));
    }
    let params = match &names {
        None => Vec::new(),
        Some(list) => {
            MediumParam::parse_list(list).map_err(|e| bad_arg(format!("gradient={list:?}: {e}")))?
        }
    };
    let (estimand, medium_index) = if params.is_empty() {
        (Estimand::RadianceOnly, 0)
    } else {
        integrator::medium_gradient(&data, medium, &params).map_err(|e| {
            let hint = match &e {
                GradientError::Medium(MediumChoiceError::Several { .. }) => " (medium=NAME)",
                _ => "",
            };
            bad_arg(format!(
                "gradient={:?}: {e}{hint}",
                names.as_deref().unwrap_or("")
            ))
        })?
    };
    if !as_dict && params.len() > 1 {
        return Err(bad_arg(
            "gradient= with several parameters: pass them as a list, gradient=[\"sigma_t\", \"g\"] (a dict of derivatives comes back)",
        ));
    }
    match denoise {
        None => {}
        Some("oidn") => {
            mediareg::denoise::oidn::load()
                .map_err(|e| crate::Error::new_err(format!("denoise=\"oidn\": {e}")))?;
        }
        Some(d) => {
            return Err(bad_arg(format!(
                "denoise=\"{d}\": the denoisers mediareg runs: \"oidn\""
            )))
        }
    }
    let pool = thread_pool(threads)?;
    // Mitsuba's mi.render(scene, seed=0, spp=0): the seed given, not the sampler's.
    let shot = data.shot.with(spp.unwrap_or(data.shot.spp), seed);
    let cancel = Arc::new(AtomicBool::new(false));
    let opts = RenderOptions {
        estimand,
        seen_emission: denoise.is_some(),
        cancel: Some(Arc::clone(&cancel)),
        ..Default::default()
    };
    let with_denoiser = denoise.is_some();
    let data_after = Arc::clone(&data);
    let (mut rendered, denoised) = interruptible(py, &cancel, move || {
        let run = || {
            let r = integrator::render(&data, &shot, &opts);
            let d = (with_denoiser && !r.stats.interrupted)
                .then(|| integrator::denoised::oidn(&data, &shot, &r, AuxUse::default(), None));
            (r, d)
        };
        match pool {
            Some(p) => p.install(run),
            None => run(),
        }
    })?;
    if let Some(d) = denoised {
        rendered.image = d.map_err(|e| crate::Error::new_err(format!("denoise=\"oidn\": {e}")))?;
    }
    if rendered.stats.interrupted {
        // Cancelled without a signal of this thread's (cannot happen now: the flag is
        // this render's own); never hand back a partial image as if complete.
        return Err(crate::Error::new_err("the render was interrupted"));
    }
    let derivatives = integrator::derivative_images(&data_after, medium_index, &params, &rendered);
    let image = to_numpy(py, rendered.image)?.into_any();
    if params.is_empty() {
        return Ok(image);
    }
    if !as_dict {
        let (_, g) = derivatives.into_iter().next().expect("one parameter");
        let g = g.expect("the derivative asked for is rendered");
        return Ok(PyTuple::new(py, [image, to_numpy(py, g)?.into_any()])?.into_any());
    }
    let dict = PyDict::new(py);
    for (param, img) in derivatives {
        let img = img.expect("each derivative asked for is rendered");
        dict.set_item(param.name(), to_numpy(py, img)?)?;
    }
    Ok(PyTuple::new(py, [image, dict.into_any()])?.into_any())
}

/// A pool of `threads` render threads (None: rayon's global pool, all cores).
pub(crate) fn thread_pool(threads: Option<usize>) -> PyResult<Option<rayon::ThreadPool>> {
    match threads {
        None => Ok(None),
        Some(0) => Err(bad_arg("threads must be at least 1 (None: all cores)")),
        Some(t) => rayon::ThreadPoolBuilder::new()
            .num_threads(t)
            .build()
            .map(Some)
            .map_err(|e| error(e.into())),
    }
}

/// Runs `work` on a thread of its own while this one, without the GIL, wakes every
/// `SIGNAL_CHECK` to run Python's signal handlers (on the main thread: Ctrl-C raises
/// KeyboardInterrupt there). A handler's exception sets `cancel` (the render drops the
/// pass under way), waits for the thread, and is raised.
pub(crate) fn interruptible<T: Send>(
    py: Python<'_>,
    cancel: &AtomicBool,
    work: impl FnOnce() -> T + Send,
) -> PyResult<T> {
    let done = (Mutex::new(false), Condvar::new());
    std::thread::scope(|s| {
        let handle = s.spawn(|| {
            // Marks the work done even if it panics (the join below reports it).
            struct Done<'a>(&'a (Mutex<bool>, Condvar));
            impl Drop for Done<'_> {
                fn drop(&mut self) {
                    *self.0 .0.lock().unwrap_or_else(|e| e.into_inner()) = true;
                    self.0 .1.notify_all();
                }
            }
            let _done = Done(&done);
            work()
        });
        loop {
            let finished = py.detach(|| {
                let guard = done.0.lock().unwrap_or_else(|e| e.into_inner());
                let (guard, _) = done
                    .1
                    .wait_timeout_while(guard, SIGNAL_CHECK, |d| !*d)
                    .unwrap_or_else(|e| e.into_inner());
                *guard
            });
            if finished {
                break;
            }
            if let Err(e) = py.check_signals() {
                cancel.store(true, Ordering::SeqCst);
                let _ = py.detach(|| handle.join());
                return Err(e);
            }
        }
        py.detach(|| handle.join())
            .map_err(|_| PyRuntimeError::new_err("the render panicked (a bug in mediareg)"))
    })
}
