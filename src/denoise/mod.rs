//! Denoisers on rendered images: Intel Open Image Denoise's `RT` filter (`oidn`, loaded
//! at run time), as `mediareg render --denoise oidn`, `regularize --denoise oidn` and
//! the Python module's `denoise` run it.
//!
//! What goes through the filter: the radiance without the emission the camera sees
//! directly (an emitting surface at the camera ray's first hit, through no medium),
//! which is added back afterwards (sharpened at the emitters' edges: `integrator::aovs`),
//!
//!   out = OIDN(L − E, albedo, normal) + E,                                     (D1)
//!
//! as production renderers keep bright visible lights out of their denoisers: a
//! directly visible emitter many times brighter than what it lights (the Candle's flame)
//! is sharp-edged and noise-free but for its pixels' coverage, and a network that
//! smooths it bleeds its edges into the neighbours, which costs more than all the noise
//! it removes. E comes from the same paths as L (`integrator::PathSample`), so L − E is
//! the radiance of the light that scattered at least once.

pub mod oidn;

pub use oidn::{Aux, Oidn, OidnError};

use crate::image::Image;

/// The auxiliary images OIDN takes: per pixel, the albedo and the normal of what the
/// camera sees first (`integrator::aovs`), noise-free when averaged over enough rays.
#[derive(Clone, Debug)]
pub struct AuxImages {
    pub albedo: Image,
    pub normal: Image,
}

/// Which auxiliary images to give OIDN (its `RT` filter takes albedo alone, or albedo
/// and normal). None by default: on the Table 1 scenes, media seen through null
/// boundaries, the first hit's albedo and normal made the output worse (docs/denoise.md).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum AuxUse {
    #[default]
    None,
    Albedo,
    AlbedoNormal,
}

/// Denoises `color` with OIDN by (D1): `seen`, the part of `color` that is directly
/// seen emission, is kept out of the filter and added back. L − E is clamped at 0,
/// where the two images' sums of the same samples round apart.
pub fn oidn(
    color: &Image,
    seen: Option<&Image>,
    aux: Option<&AuxImages>,
    use_aux: AuxUse,
) -> Result<Image, OidnError> {
    let lib = oidn::load()?;
    let scattered: Vec<[f32; 3]> = match seen {
        Some(e) => {
            same_size(color, e, "seen-emission")?;
            color
                .pixels
                .iter()
                .zip(&e.pixels)
                .map(|(l, e)| std::array::from_fn(|c| (l[c] - e[c]).max(0.0)))
                .collect()
        }
        None => color.pixels.clone(),
    };
    let aux = match (aux, use_aux) {
        (Some(a), AuxUse::Albedo | AuxUse::AlbedoNormal) => {
            same_size(color, &a.albedo, "albedo")?;
            same_size(color, &a.normal, "normal")?;
            Some(Aux {
                albedo: &a.albedo.pixels,
                normal: (use_aux == AuxUse::AlbedoNormal).then_some(&a.normal.pixels[..]),
                clean: true,
            })
        }
        _ => None,
    };
    let mut out = lib.denoise_rt(color.width, color.height, &scattered, aux)?;
    if let Some(e) = seen {
        for (o, e) in out.iter_mut().zip(&e.pixels) {
            for c in 0..3 {
                o[c] += e[c];
            }
        }
    }
    Ok(Image {
        width: color.width,
        height: color.height,
        pixels: out,
    })
}

/// OIDN on a signed image (a derivative, a difference), with the auxiliary images
/// `use_aux` names: its positive and negative parts each through the filter (the HDR
/// filter takes non-negative values), the second only where there is one. An image of
/// zeros stays zero.
pub fn oidn_signed(
    img: &Image,
    aux: Option<&AuxImages>,
    use_aux: AuxUse,
) -> Result<Image, OidnError> {
    let part = |sign: f32| Image {
        pixels: img
            .pixels
            .iter()
            .map(|p| p.map(|v| (sign * v).max(0.0)))
            .collect(),
        ..img.clone()
    };
    let filtered = |part: &Image| -> Result<Option<Image>, OidnError> {
        if part.pixels.iter().flatten().all(|&v| v == 0.0) {
            return Ok(None);
        }
        oidn(part, None, aux, use_aux).map(Some)
    };
    let positive = filtered(&part(1.0))?;
    let negative = filtered(&part(-1.0))?;
    let mut out = positive.unwrap_or_else(|| part(0.0));
    if let Some(n) = negative {
        for (o, n) in out.pixels.iter_mut().zip(&n.pixels) {
            for c in 0..3 {
                o[c] -= n[c];
            }
        }
    }
    Ok(out)
}

fn same_size(color: &Image, other: &Image, name: &str) -> Result<(), OidnError> {
    if (other.width, other.height) != (color.width, color.height) {
        return Err(OidnError::BadInput(format!(
            "the {name} image is {}×{}, the colour {}×{}",
            other.width, other.height, color.width, color.height
        )));
    }
    Ok(())
}
