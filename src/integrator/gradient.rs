//! Which derivatives a render estimates beside the radiance, chosen from what a caller
//! asked for (the CLI's `--gradient sigma_t,albedo,g --medium ID`, the Python module's
//! `gradient=[...]`, `mediareg fit`): one check, worded by each caller for its flags,
//! and the derivative images named as the scene file names the parameters.

use super::render::Rendered;
use super::volpath::{Differentiated, Estimand};
use crate::image::Image;
use crate::medium::Phase;
use crate::scene::{IntegratorKind, MediumChoiceError, Scene};

/// A parameter of a medium, as Mitsuba's scene file and `mi.traverse` name it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum MediumParam {
    /// The extinction `sigma_t` of a homogeneous medium (per channel; the albedo held,
    /// as Mitsuba parameterizes: σ_s = albedo · σ_t), before `scale`.
    SigmaT,
    /// The single-scattering albedo (per channel); of a heterogeneous medium, a global
    /// factor on its albedo volume.
    Albedo,
    /// The Henyey–Greenstein phase function's asymmetry g.
    G,
    /// The medium's `scale` (σ_t = scale · sigma_t; of a grid medium, its density's).
    Scale,
}

impl MediumParam {
    pub const ALL: [MediumParam; 4] = [
        MediumParam::SigmaT,
        MediumParam::Albedo,
        MediumParam::G,
        MediumParam::Scale,
    ];

    /// The scene file's name of the parameter.
    pub fn name(self) -> &'static str {
        match self {
            MediumParam::SigmaT => "sigma_t",
            MediumParam::Albedo => "albedo",
            MediumParam::G => "g",
            MediumParam::Scale => "scale",
        }
    }

    /// Whether it has a value per colour channel (else one for all).
    pub fn is_chromatic(self) -> bool {
        matches!(self, MediumParam::SigmaT | MediumParam::Albedo)
    }

    /// A comma-separated list of names (`sigma_t,albedo,g`), in the order given,
    /// without repeats.
    pub fn parse_list(list: &str) -> Result<Vec<MediumParam>, String> {
        let mut out = Vec::new();
        for name in list.split(',').map(str::trim).filter(|n| !n.is_empty()) {
            let p = MediumParam::ALL
                .into_iter()
                .find(|p| p.name() == name)
                .ok_or_else(|| {
                    format!("unknown medium parameter {name:?}: sigma_t, albedo, g or scale")
                })?;
            if !out.contains(&p) {
                out.push(p);
            }
        }
        if out.is_empty() {
            return Err("no medium parameter named: give sigma_t, albedo, g or scale".into());
        }
        Ok(out)
    }
}

/// Why a derivative cannot be rendered for a scene.
#[derive(Clone, Debug)]
pub enum GradientError {
    /// The scene's integrator ignores media (only volpath estimates the derivative).
    NeedsVolpath,
    /// The medium asked for is not there, or several are and none was named.
    Medium(MediumChoiceError),
    /// The medium has no such parameter to differentiate (e.g. g of an isotropic one).
    Unsupported(String),
}

impl std::fmt::Display for GradientError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            GradientError::NeedsVolpath => write!(
                f,
                "derivatives need the volpath integrator (the scene's integrator ignores media)"
            ),
            GradientError::Medium(e) => write!(f, "{e}"),
            GradientError::Unsupported(why) => write!(f, "{why}"),
        }
    }
}

impl std::error::Error for GradientError {}

/// d(radiance)/d(albedo) of the medium with XML id `medium` (or the scene's only one).
pub fn albedo_gradient(scene: &Scene, medium: Option<&str>) -> Result<Estimand, GradientError> {
    medium_gradient(scene, medium, &[MediumParam::Albedo]).map(|(g, _)| g)
}

/// The derivatives in `params` of the medium with XML id `medium` (or the scene's only
/// one), and its index. The albedo alone is `Estimand::AlbedoDerivative`. The lane path
/// (`integrator::packet`) renders either, as the scalar one does.
pub fn medium_gradient(
    scene: &Scene,
    medium: Option<&str>,
    params: &[MediumParam],
) -> Result<(Estimand, u32), GradientError> {
    if scene.integrator.kind != IntegratorKind::Volpath {
        return Err(GradientError::NeedsVolpath);
    }
    let mi = scene.medium_index(medium).map_err(GradientError::Medium)?;
    let m = &scene.media[mi as usize];
    let label = m.id.as_deref().unwrap_or("the medium");
    for &p in params {
        match p {
            MediumParam::SigmaT if m.heterogeneous.is_some() => {
                return Err(GradientError::Unsupported(format!(
                    "{label}: sigma_t of a heterogeneous medium is a volume; differentiate its scale instead (--gradient scale)"
                )))
            }
            MediumParam::G if !matches!(m.phase, Phase::HenyeyGreenstein { .. }) => {
                return Err(GradientError::Unsupported(format!(
                    "{label}: its phase function ({:?}) has no g; give it an <phase type=\"hg\">",
                    m.phase
                )))
            }
            _ => {}
        }
    }
    if params == [MediumParam::Albedo] {
        return Ok((Estimand::AlbedoDerivative(mi), mi));
    }
    let params = Differentiated {
        albedo: params.contains(&MediumParam::Albedo),
        extinction: params.contains(&MediumParam::SigmaT) || params.contains(&MediumParam::Scale),
        g: params.contains(&MediumParam::G),
        without_shadow_term: false,
    };
    Ok((Estimand::MediumDerivatives { medium: mi, params }, mi))
}

/// The derivative images of `rendered` in `params` of medium `mi`, in the order asked:
/// d/dsigma_t = scale · d/dσ_t, d/dscale = sigma_t,c · d/dσ_t,c per channel (a
/// heterogeneous medium's is rendered as it is), d/dalbedo and d/dg as rendered.
/// None for a parameter the render did not estimate.
pub fn derivative_images(
    scene: &Scene,
    mi: u32,
    params: &[MediumParam],
    rendered: &Rendered,
) -> Vec<(MediumParam, Option<Image>)> {
    let Some(m) = scene.media.get(mi as usize) else {
        return Vec::new();
    };
    let scaled = |img: &Option<Image>, f: [f32; 3]| {
        img.as_ref().map(|img| Image {
            width: img.width,
            height: img.height,
            pixels: img
                .pixels
                .iter()
                .map(|p| [p[0] * f[0], p[1] * f[1], p[2] * f[2]])
                .collect(),
        })
    };
    params
        .iter()
        .map(|&p| {
            let img = match p {
                MediumParam::Albedo => rendered.gradient.clone(),
                MediumParam::G => rendered.d_g.clone(),
                MediumParam::SigmaT => scaled(&rendered.d_sigma, [m.scale; 3]),
                MediumParam::Scale if m.heterogeneous.is_some() => rendered.d_sigma.clone(),
                MediumParam::Scale => {
                    let raw = m.sigma_t / m.scale;
                    scaled(&rendered.d_sigma, raw.to_array())
                }
            };
            (p, img)
        })
        .collect()
}
