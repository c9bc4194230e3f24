//! Medium plugins: Mitsuba's `homogeneous`, with its phase function (`isotropic`,
//! `hg`).

use glam::Vec3;

use super::props::Props;
use super::spectrum::SpectrumUse;
use super::{unsupported, Builder};
use crate::error::{Result, SceneError};
use crate::medium::{HomogeneousMedium, Phase};
use crate::xml::description::{ObjId, ObjectKind, Value};

impl Builder<'_> {
    pub(super) fn medium(&mut self, id: ObjId) -> Result<u32> {
        if let Some(&i) = self.medium_ids.get(&id) {
            return Ok(i);
        }
        let p = Props::new(self.desc, id);
        // A medium that varies in space: `heterogeneous`, or a grid albedo.
        if p.obj.plugin == "heterogeneous"
            || (p.obj.plugin == "homogeneous" && super::volume::is_grid(&p, "albedo"))
        {
            return self.heterogeneous_medium(id, p);
        }
        if p.obj.plugin != "homogeneous" {
            return Err(unsupported(&p, "medium", "homogeneous, heterogeneous"));
        }
        // Both are Mitsuba volumes (`constvolume`), whose values are unbounded textures.
        let albedo = p.color_nonneg_as("albedo", Vec3::splat(0.75), SpectrumUse::Unbounded)?;
        if albedo.max_element() > 1.0 {
            return Err(p.error(format!("albedo {albedo} must be in [0, 1]")));
        }
        let sigma_t = p.color_nonneg_as("sigma_t", Vec3::ONE, SpectrumUse::Unbounded)?;
        // Mitsuba 3 turns an `<rgb>` sigma_t into a bounded sRGB texture, which refuses
        // components above 1; give the same file the same meaning (an error).
        if let Some((Value::Rgb(c), loc)) = p.get("sigma_t") {
            if c.max_element() > 1.0 {
                return Err(SceneError::at(
                    loc,
                    format!("homogeneous medium: <rgb name=\"sigma_t\"> = {c} has a component above 1, which Mitsuba 3 refuses (it reads <rgb> here as a reflectance)"),
                )
                .with_hint("write the colour with components in [0, 1] and put the magnitude in <float name=\"scale\">, or use a <float> sigma_t"));
            }
        }
        let scale = p.float("scale", 1.0)?;
        if scale <= 0.0 {
            return Err(p.error(format!("scale = {scale}: must be > 0")));
        }
        let sample_emitters = p.bool("sample_emitters", true)?;
        // Mitsuba's flag for RGB sigma_t. With `false` Mitsuba weights scattering by the
        // albedo alone, which is exact only for grey extinction: for a chromatic sigma_t
        // it renders a biased image, which mediareg will not reproduce silently.
        if !p.bool("has_spectral_extinction", true)?
            && sigma_t.min_element() != sigma_t.max_element()
        {
            let loc = p
                .get("has_spectral_extinction")
                .map_or(p.obj.loc.clone(), |(_, l)| l.clone());
            return Err(SceneError::at(
                &loc,
                format!("homogeneous medium: has_spectral_extinction = false with a chromatic sigma_t {sigma_t} is not supported (Mitsuba 3 renders it with a biased estimator)"),
            )
            .with_hint("remove has_spectral_extinction (default true), or give a grey sigma_t"));
        }
        let phase = self.phase(&p)?;
        let medium_id = p.obj.id.clone();
        p.finish("albedo, sigma_t, scale, sample_emitters, has_spectral_extinction, phase")?;
        self.media.push(HomogeneousMedium {
            albedo,
            sigma_t: sigma_t * scale as f32,
            phase,
            sample_emitters,
            id: medium_id,
            heterogeneous: None,
        });
        let i = self.media.len() as u32 - 1;
        self.medium_ids.insert(id, i);
        Ok(i)
    }

    /// The medium's nested phase function (`isotropic` when none is given).
    pub(super) fn phase(&self, p: &Props) -> Result<Phase> {
        Ok(match p.child_of(ObjectKind::Phase)? {
            Some(c) => {
                let q = Props::new(self.desc, c.object);
                let ph = match q.obj.plugin.as_str() {
                    "isotropic" => Phase::Isotropic,
                    "hg" => {
                        let g = q.float("g", 0.8)?;
                        if !(g > -1.0 && g < 1.0) {
                            return Err(
                                q.error(format!("g = {g}: the asymmetry must lie in (-1, 1)"))
                            );
                        }
                        Phase::HenyeyGreenstein { g: g as f32 }
                    }
                    _ => return Err(unsupported(&q, "phase", "isotropic, hg")),
                };
                q.finish("g (hg)")?;
                ph
            }
            None => Phase::Isotropic,
        })
    }
}
