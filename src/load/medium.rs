//! Medium plugins: Mitsuba's `homogeneous`, with its phase function (`isotropic`,
//! `hg`, `rayleigh`).

use glam::Vec3;

use super::props::Props;
use super::spectrum::SpectrumUse;
use super::{unsupported, Builder};
use crate::error::{Result, SceneError};
use crate::medium::{Medium, Phase};
use crate::xml::description::{ObjId, ObjectKind, Value};

impl Builder<'_> {
    /// A medium's volume parameter `name`: a constant property (which Mitsuba 3 wraps in
    /// a `constvolume` itself), or a nested `<volume type="constvolume">` whose `value`
    /// (an unbounded texture in Mitsuba 3's `src/volumes/const.cpp`, default 1; a float,
    /// rgb or spectrum) is that constant: the medium stays homogeneous. Any other volume
    /// plugin varies in space and is refused.
    fn volume_constant(&self, p: &Props, name: &str, default: Vec3) -> Result<Vec3> {
        let Some(child) = p.named_child_of(name, ObjectKind::Volume)? else {
            return p.color_nonneg_as(name, default, SpectrumUse::Unbounded);
        };
        let v = Props::new(self.desc, child.object);
        if v.obj.plugin != "constvolume" {
            return Err(SceneError::at(
                &child.loc,
                format!(
                    "{}: \"{name}\" given as a nested volume plugin \"{}\"; only a constant (or a constvolume) is supported",
                    p.obj.label(),
                    v.obj.plugin
                ),
            )
            .with_hint(
                "for a sigma_t that varies in space use <medium type=\"heterogeneous\"> (its sigma_t and albedo take volumes); a homogeneous medium takes a <float>, <rgb>, <spectrum> or constvolume",
            ));
        }
        let value = v.color_nonneg_as("value", Vec3::ONE, SpectrumUse::Unbounded)?;
        // The volume's placement does not change a constant.
        v.transform("to_world")?;
        v.finish("value, to_world")?;
        Ok(value)
    }

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
        let albedo = self.volume_constant(&p, "albedo", Vec3::splat(0.75))?;
        if albedo.max_element() > 1.0 {
            return Err(p.error(format!("albedo {albedo} must be in [0, 1]")));
        }
        let sigma_t = self.volume_constant(&p, "sigma_t", Vec3::ONE)?;
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
        let phase = self.medium_phase(&p)?;
        let medium_id = p.obj.id.clone();
        p.finish("albedo, sigma_t, scale, sample_emitters, has_spectral_extinction, phase")?;
        self.media.push(Medium {
            albedo,
            sigma_t: sigma_t * scale as f32,
            scale: scale as f32,
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
    pub(super) fn medium_phase(&self, p: &Props) -> Result<Phase> {
        match p.child_of(ObjectKind::Phase)? {
            Some(c) => self.phase(c.object),
            None => Ok(Phase::Isotropic),
        }
    }

    /// Mitsuba's `isotropic` and `hg` phase functions (nested in a medium, or declared
    /// at the top level with an `id` and referred to).
    pub(super) fn phase(&self, id: ObjId) -> Result<Phase> {
        let q = Props::new(self.desc, id);
        let ph = match q.obj.plugin.as_str() {
            "isotropic" => Phase::Isotropic,
            "rayleigh" => Phase::Rayleigh,
            "hg" => {
                let g = q.float("g", 0.8)?;
                if !(g > -1.0 && g < 1.0) {
                    return Err(q.error(format!("g = {g}: the asymmetry must lie in (-1, 1)")));
                }
                Phase::HenyeyGreenstein { g: g as f32 }
            }
            _ => return Err(unsupported(&q, "phase", "isotropic, hg, rayleigh")),
        };
        q.finish("g (hg)")?;
        Ok(ph)
    }
}
