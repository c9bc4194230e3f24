//! A render through a denoiser, as `mediareg render --denoise` and the Python module's
//! `render(denoise=...)` run it: the directly seen emission sharpened at emitter edges
//! and kept out of the filter, the auxiliary images traced (`aovs`), then `denoise`.

use super::aovs;
use super::render::Rendered;
use crate::denoise::{self, AuxImages, AuxUse, OidnError};
use crate::image::Image;
use crate::scene::shot::Shot;
use crate::scene::Scene;

/// OIDN on `rendered` (a render of `shot` with `RenderOptions::seen_emission`), with the
/// auxiliary images `use_aux` names; `aux` reuses ones already traced for this shot.
pub fn oidn(
    scene: &Scene,
    shot: &Shot,
    rendered: &Rendered,
    use_aux: AuxUse,
    aux: Option<&AuxImages>,
) -> Result<Image, OidnError> {
    let mut seen = rendered.seen_emission.clone();
    if let Some(seen) = &mut seen {
        aovs::sharpen_seen_emission(scene, shot, seen);
    }
    let traced;
    let aux = match (use_aux, aux) {
        (AuxUse::None, _) => None,
        (_, Some(a)) => Some(a),
        (_, None) => {
            traced = aovs::first_hit_aovs(scene, shot);
            Some(&traced)
        }
    };
    denoise::oidn(&rendered.image, seen.as_ref(), aux, use_aux)
}
