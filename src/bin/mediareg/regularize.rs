//! `mediareg regularize`: the paper's method on a scene file.

use std::io::IsTerminal;
use std::path::PathBuf;

use anyhow::{anyhow, Result};
use clap::Args;

use mediareg::image::{self, Image};
use mediareg::regularize::pipeline::PilotSize;
use mediareg::regularize::sequence::CameraPath;
use mediareg::regularize::{self, ChoiceError, Choices, Method, Motion, OidnUse, Reproject};

use crate::common::{
    fmt3, medium_error, parse_point, prepare, regularize_error, sibling, warn_invalid_samples,
    SceneArgs,
};

/// The paper's method: render at source albedo factor × the scene's, denoise the
/// albedo gradient over a camera sequence, predict the image at the scene's albedo.
/// Writes OUT.exr (the prediction), OUT_source.exr, OUT_dalbedo_raw.exr and
/// OUT_dalbedo.exr (denoised), each with a PNG preview.
#[derive(Args)]
pub struct RegularizeArgs {
    #[command(flatten)]
    pub args: SceneArgs,
    /// The medium to extrapolate: its XML id, its slot (interior, exterior) or its
    /// mi.traverse key (SHAPE_ID.interior_medium); needed when the scene has several.
    #[arg(long, value_name = "NAME")]
    pub medium: Option<String>,
    /// Source albedo = factor × the scene's albedo (per channel), or `auto` (the
    /// difference predictor: chosen by a pilot). Default: auto with `--predict
    /// difference`, 0.95 with the others.
    #[arg(long, value_name = "F|auto")]
    pub factor: Option<String>,
    /// The pilot of `--factor auto`: renders per candidate factor, and their spp.
    #[arg(long, default_value_t = 8)]
    pub pilot_renders: usize,
    #[arg(long, default_value_t = 1)]
    pub pilot_spp: u32,
    /// c_β of the paper's predictor (0 < c_β ≤ σ_t α_s), or `fit` to fit it to a
    /// cheap render (--fit-spp, --fit-at).
    #[arg(long = "c-beta", default_value = "0.5", value_name = "C|fit")]
    pub c_beta: String,
    /// Samples per pixel of the render c_β is fitted to.
    #[arg(long, default_value_t = 4)]
    pub fit_spp: u32,
    /// The fit's albedo: source + at × (target − source).
    #[arg(long, default_value_t = 1.0)]
    pub fit_at: f32,
    /// N: the target frame and N − 1 earlier frames.
    #[arg(long, default_value_t = 11)]
    pub frames: usize,
    /// The blending weight w_a of Eq. 10.
    #[arg(long, default_value_t = 0.1)]
    pub wa: f64,
    /// How earlier frames are reprojected into the target frame.
    #[arg(long, value_enum, default_value = "exact")]
    pub reproject: ReprojectArg,
    /// The camera moved this many degrees per frame about the --target point, around
    /// its up vector.
    #[arg(long, value_name = "DEGREES", conflicts_with_all = ["dolly", "camera_path"])]
    pub orbit: Option<f32>,
    /// The camera moved this far per frame along its view direction.
    #[arg(long, value_name = "DISTANCE", conflicts_with = "camera_path")]
    pub dolly: Option<f32>,
    /// A file of sensor transforms, one per line in time order, the last the target
    /// frame: 16 numbers (4x4 row-major) or 9 (origin target up).
    #[arg(long, value_name = "FILE")]
    pub camera_path: Option<PathBuf>,
    /// The orbit's centre "x,y,z" (default: the first visible point at the image centre).
    #[arg(long, value_name = "X,Y,Z")]
    pub target: Option<String>,
    /// Also filter the gradient spatially (joint bilateral, guided by the first hit);
    /// the default with `--predict difference`.
    #[arg(long, conflicts_with = "no_spatial")]
    pub spatial: bool,
    /// Filter the gradient over frames only (the default with the paper's predictors).
    #[arg(long)]
    pub no_spatial: bool,
    /// The difference's filter: `oidn` (Intel Open Image Denoise on every frame's
    /// difference and the target frame's R_s; needs the library: scripts/fetch_oidn) or
    /// `bilateral` (the joint bilateral filter after the blend). Default: oidn with the
    /// difference predictor when the library is there, else bilateral.
    #[arg(long, value_enum, value_name = "FILTER", conflicts_with = "spatial")]
    pub denoise: Option<FilterArg>,
    /// The prediction function.
    #[arg(long, value_enum, default_value = "difference")]
    pub predict: PredictArg,
    /// Keep the method's pipeline: do not let the check on held-out samples pick the
    /// control, plain + OIDN or plain volpath instead (with the difference predictor
    /// through OIDN and more than one frame; see docs/regularize.md).
    #[arg(long)]
    pub no_pick: bool,
    /// With --frames 1 through OIDN: check on the render's own samples whether OIDN
    /// lowers the error, and keep plain volpath where it does not (one more OIDN run;
    /// see docs/regularize.md). Without it the frame is `render --denoise oidn`'s.
    #[arg(long)]
    pub oidn_check: bool,
}

#[derive(Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum FilterArg {
    Oidn,
    Bilateral,
}

#[derive(Clone, Copy, clap::ValueEnum)]
pub enum ReprojectArg {
    Exact,
    Shift,
    None,
}

#[derive(Clone, Copy, clap::ValueEnum)]
pub enum PredictArg {
    Paper,
    Linear,
    Loglinear,
    /// R_s + the denoised difference R(α_t) − R(α_s) rendered in the same paths
    Difference,
    /// No extrapolation: plain volpath frames at the scene's albedo through the same
    /// reprojection, blend and filter (the table's `volpath_filtered`)
    Plain,
}

pub fn run(cmd: RegularizeArgs) -> Result<()> {
    let RegularizeArgs {
        args,
        medium,
        factor,
        c_beta,
        fit_spp,
        fit_at,
        frames,
        wa,
        reproject,
        orbit,
        dolly,
        camera_path,
        target,
        spatial,
        no_spatial,
        denoise,
        predict,
        no_pick,
        oidn_check,
        pilot_renders,
        pilot_spp,
    } = cmd;
    if denoise == Some(FilterArg::Oidn) {
        mediareg::denoise::oidn::load().map_err(|e| anyhow!("--denoise oidn: {e}"))?;
    }
    let (scene_data, out_exr) = prepare(&args)?;
    let c_beta = regularize::choices::parse_c_beta(&c_beta, fit_spp, fit_at)
        .ok_or_else(|| anyhow!("--c-beta {c_beta}: expected a number or `fit`"))?;
    let method = match predict {
        PredictArg::Paper => Method::Paper(c_beta),
        PredictArg::Linear => Method::Linear,
        PredictArg::Loglinear => Method::LogLinear,
        PredictArg::Difference => Method::Difference,
        PredictArg::Plain => Method::Radiance,
    };
    let motion = match (orbit, dolly, camera_path) {
        (Some(degrees), _, _) => Motion::Orbit {
            degrees,
            target: target.as_deref().map(parse_point).transpose()?,
        },
        (_, Some(distance), _) => Motion::Dolly(distance),
        (_, _, Some(file)) => Motion::Path(CameraPath::read(&file).map_err(|e| anyhow!("{e}"))?),
        _ => Motion::Static,
    };
    if frames > 1 && motion == Motion::Static {
        eprintln!(
            "note: no --orbit, --dolly or --camera-path: the {frames} frames share the sensor and differ only in their noise"
        );
    }
    let factor = factor
        .map(|f| {
            regularize::choices::parse_factor(&f)
                .ok_or_else(|| anyhow!("--factor {f}: expected a number or `auto`"))
        })
        .transpose()?;
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
        reproject: match reproject {
            ReprojectArg::Exact => Reproject::Exact,
            ReprojectArg::Shift => Reproject::Shift,
            ReprojectArg::None => Reproject::None,
        },
        motion,
        spatial: match (spatial, no_spatial) {
            (true, _) => Some(true),
            (_, true) => Some(false),
            _ => None,
        },
        oidn: match (denoise, spatial) {
            (Some(f), _) => Some(f == FilterArg::Oidn),
            (None, true) => Some(false),
            (None, false) => None,
        },
        pick: !no_pick,
        oidn_check,
        show_progress: std::io::stderr().is_terminal(),
    };
    let (opts, shot) = regularize::choices::options(&scene_data, &scene_data.shot, &choices)
        .map_err(|e| match e {
            ChoiceError::Medium(m) => medium_error(m),
            ChoiceError::NoOrbitCentre => {
                anyhow!("--orbit: {e}; give the orbit's centre with --target x,y,z")
            }
        })?;
    let r = regularize::regularize(&scene_data, &shot, &opts).map_err(regularize_error)?;

    let outputs: [(PathBuf, &Image, bool); 4] = [
        (out_exr.clone(), &r.predicted, false),
        (sibling(&out_exr, "_source"), &r.source, false),
        (sibling(&out_exr, "_dalbedo_raw"), &r.raw_gradient, true),
        (sibling(&out_exr, "_dalbedo"), &r.gradient, true),
    ];
    // Both gradient previews on the raw gradient's scale, so they compare.
    let scale = image::signed_scale(&r.raw_gradient);
    let mut written = Vec::new();
    for (path, img, signed) in &outputs {
        image::write_exr(path, img)?;
        written.push(path.display().to_string());
        if !args.no_png {
            let png = path.with_extension("png");
            if *signed {
                image::write_png_signed(&png, img, scale)?;
            } else {
                image::write_png(&png, img)?;
            }
            written.push(png.display().to_string());
        }
    }
    warn_invalid_samples(r.invalid_samples);
    if r.fallbacks > 0 {
        eprintln!(
            "warning: {} channel values could not be predicted (negative or not finite) and keep the source radiance",
            r.fallbacks
        );
    }
    if let Some(p) = &r.pilot {
        let costs: Vec<String> = p
            .candidates
            .iter()
            .map(|c| format!("{}: {:.3e}", c.factor, c.error.iter().sum::<f64>()))
            .collect();
        println!(
            "factor {:?} (R, G, B) chosen by the pilot in {:.2} s (predicted squared error at equal time, summed over pixels and channels: {})",
            p.factor,
            p.seconds,
            costs.join(", ")
        );
    }
    if let Some(c) = &r.oidn_check {
        println!(
            "one frame: plain volpath{} (OIDN's squared error {:.3e} ± {:.1e} against plain volpath's variance {:.3e}, measured with 2 × {} of the {} spp)",
            match c.chose_oidn {
                true => " through OIDN",
                false => ", not denoised",
            },
            c.oidn_error,
            c.oidn_error_se,
            c.plain_variance,
            c.spp_each,
            shot.spp
        );
    }
    if let Some(c) = &r.pipeline_check {
        println!(
            "pipeline: {} (squared error, from 2 x {} held-out spp: {}; the check took {:.2} s)",
            c.chosen.as_str(),
            c.spp_each,
            c.errors_by_name(),
            c.seconds
        );
    }
    if r.pilot_unaffordable {
        println!(
            "factor 1 (plain volpath): the pilot would cost more than {:.0}% of the render ({} frames of {} spp)",
            100.0 * mediareg::regularize::pilot::MAX_SHARE,
            r.frames_rendered,
            shot.spp
        );
    }
    println!(
        "filter: {}",
        match (opts.oidn, &opts.spatial) {
            _ if r.oidn_check.is_some() => "see above (one plain frame)",
            (OidnUse::None, Some(_)) => "joint bilateral after the blend",
            (OidnUse::None, None) => "the blend over frames only",
            _ => "Open Image Denoise on every frame (and R_s)",
        }
    );
    let a = &r.albedos;
    let t = &r.timings;
    println!(
        "albedo {} -> {}; {} frames ({:.2} blended per pixel), {} spp each; c_beta {}",
        fmt3(a.source),
        fmt3(a.target),
        r.frames_rendered,
        r.mean_frames,
        shot.spp,
        r.c_beta.map_or("-".into(), |c| format!("{c:.4}")),
    );
    println!(
        "seconds: target frame {:.2}, all frames {:.2}, c_beta fit {:.2}, denoise+predict {:.2}",
        t.target_frame, t.frames, t.fit, t.denoise_and_predict
    );
    println!("wrote {}", written.join(", "));
    Ok(())
}
