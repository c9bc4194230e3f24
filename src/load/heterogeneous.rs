//! Media that vary in space: Mitsuba's `heterogeneous` (`src/media/heterogeneous.cpp`),
//! and a `homogeneous` medium whose albedo is a grid (`src/media/homogeneous.cpp`
//! evaluates its albedo volume at each collision). Both become a
//! [`HeterogeneousMedium`], rendered by delta and ratio tracking.

use glam::Vec3;

use super::props::Props;
use super::Builder;
use crate::error::{Result, SceneError};
use crate::medium::grid::Source;
use crate::medium::{HeterogeneousMedium, Medium};
use crate::xml::description::ObjId;

impl Builder<'_> {
    pub(super) fn heterogeneous_medium(&mut self, id: ObjId, p: Props) -> Result<u32> {
        let bounded = p.obj.plugin == "heterogeneous";
        let (albedo, albedo_loc) = self.volume(&p, "albedo", Vec3::splat(0.75))?;
        if albedo.max > 1.0 {
            return Err(SceneError::at(
                &albedo_loc,
                format!("{}: albedo reaches {}, above 1", p.obj.label(), albedo.max),
            )
            .with_hint("an albedo (σ_s / σ_t) lies in [0, 1]"));
        }
        let (sigma_t, sigma_loc) = self.volume(&p, "sigma_t", Vec3::ONE)?;
        if !bounded && !matches!(sigma_t.source, Source::Const(_)) {
            return Err(SceneError::at(
                &sigma_loc,
                "homogeneous medium: a grid sigma_t makes the medium heterogeneous",
            )
            .with_hint("use <medium type=\"heterogeneous\"> for a sigma_t that varies in space"));
        }
        let scale = p.float("scale", 1.0)?;
        if !(scale > 0.0 && scale.is_finite()) {
            return Err(p.error(format!("scale = {scale}: must be > 0")));
        }
        let medium = HeterogeneousMedium::new(sigma_t, albedo, scale as f32, bounded);
        let majorant = medium.majorant;
        if !(majorant > 0.0 && majorant.is_finite()) {
            return Err(SceneError::at(
                &sigma_loc,
                format!(
                    "{}: sigma_t × scale has maximum {majorant}: the medium is empty (no majorant to track it with)",
                    p.obj.label()
                ),
            )
            .with_hint("give a positive sigma_t somewhere, or remove the medium"));
        }
        let sample_emitters = p.bool("sample_emitters", true)?;
        // With `false`, Mitsuba weights real collisions by the albedo alone and null
        // ones by nothing, exact only for grey extinction (see load/medium.rs).
        if !p.bool("has_spectral_extinction", true)? && !medium.sigma_t.is_grey() {
            let loc = p
                .get("has_spectral_extinction")
                .map_or(p.obj.loc.clone(), |(_, l)| l.clone());
            return Err(SceneError::at(
                &loc,
                format!("{}: has_spectral_extinction = false with a chromatic sigma_t is not supported (Mitsuba 3 renders it with a biased estimator)", p.obj.label()),
            )
            .with_hint("remove has_spectral_extinction (default true), or give a grey sigma_t"));
        }
        let phase = self.medium_phase(&p)?;
        let medium_id = p.obj.id.clone();
        p.finish("albedo, sigma_t, scale, sample_emitters, has_spectral_extinction, phase")?;
        self.media.push(Medium {
            albedo: Vec3::ONE,
            sigma_t: Vec3::splat(majorant),
            scale: scale as f32,
            phase,
            sample_emitters,
            id: medium_id,
            heterogeneous: Some(Box::new(medium)),
        });
        let i = self.media.len() as u32 - 1;
        self.medium_ids.insert(id, i);
        Ok(i)
    }
}
