//! Integrator plugins: Mitsuba's `path`, `volpath`, `direct` and `moment` (around one
//! of them).

use super::props::Props;
use super::{unsupported, Builder};
use crate::error::Result;
use crate::scene::{IntegratorKind, IntegratorSettings};
use crate::xml::description::{ObjId, ObjectKind};

/// Mitsuba's `direct`: `shading_samples` (1) sets both counts unless `emitter_samples`
/// or `bsdf_samples` is given (giving both kinds is an error, as in Mitsuba).
fn direct_integrator(p: Props) -> Result<IntegratorSettings> {
    let count = |name: &str, default: i64| -> Result<u32> {
        let v = p.int(name, default)?;
        if !(0..=1 << 20).contains(&v) {
            return Err(p.error(format!("{name} = {v}: must be in [0, 2^20]")));
        }
        Ok(v as u32)
    };
    if p.has("shading_samples") && (p.has("emitter_samples") || p.has("bsdf_samples")) {
        return Err(p.error(
            "give either shading_samples or emitter_samples/bsdf_samples, not both (as Mitsuba requires)",
        ));
    }
    let shading = count("shading_samples", 1)?;
    let emitter_samples = count("emitter_samples", shading as i64)?;
    let bsdf_samples = count("bsdf_samples", shading as i64)?;
    if emitter_samples + bsdf_samples == 0 {
        return Err(p.error("emitter_samples + bsdf_samples must be at least 1"));
    }
    if p.bool("hide_emitters", false)? {
        return Err(p.error(
            "hide_emitters = true is not supported with the direct integrator yet; use path with max_depth 2",
        ));
    }
    p.finish("shading_samples, emitter_samples, bsdf_samples, hide_emitters")?;
    Ok(IntegratorSettings {
        kind: IntegratorKind::Direct {
            emitter_samples,
            bsdf_samples,
        },
        max_depth: 2,
        rr_depth: u32::MAX,
        hide_emitters: false,
        moment_aovs_dropped: false,
    })
}

impl Builder<'_> {
    /// Mitsuba's `moment`: the image is its nested integrator's (Mitsuba returns the
    /// first nested integrator's radiance); the moment AOVs it adds to the EXR are not
    /// written here (a warning says so).
    pub(super) fn moment_integrator(&self, p: Props) -> Result<IntegratorSettings> {
        let nested = p.children_of(ObjectKind::Integrator);
        let [inner] = nested.as_slice() else {
            return Err(p.error(format!(
                "moment with {} nested integrators: exactly one is supported",
                nested.len()
            )));
        };
        let mut settings = self.integrator(inner.object)?;
        p.finish("(one nested integrator)")?;
        settings.moment_aovs_dropped = true;
        Ok(settings)
    }

    pub(super) fn integrator(&self, id: ObjId) -> Result<IntegratorSettings> {
        let p = Props::new(self.desc, id);
        let kind = match p.obj.plugin.as_str() {
            "path" => IntegratorKind::Path,
            // Mitsuba's `volpathmis` estimates the same radiance as `volpath` (it only
            // samples chromatic media differently; `use_spectral_mis` picks how), so it
            // renders the same image in expectation: mediareg's volpath renders it.
            "volpath" | "volpathmis" => IntegratorKind::Volpath,
            "direct" => return direct_integrator(p),
            "moment" => return self.moment_integrator(p),
            _ => {
                return Err(unsupported(
                    &p,
                    "integrator",
                    "path, volpath, volpathmis, direct, moment",
                ))
            }
        };
        if p.obj.plugin == "volpathmis" {
            p.bool("use_spectral_mis", true)?;
        }
        let max_depth = p.int("max_depth", -1)?;
        if max_depth < -1 {
            return Err(p.error(format!(
                "max_depth = {max_depth}: must be -1 (unbounded) or ≥ 0"
            )));
        }
        let rr_depth = p.int("rr_depth", 5)?;
        if rr_depth <= 0 {
            return Err(p.error(format!("rr_depth = {rr_depth}: must be > 0")));
        }
        let hide_emitters = p.bool("hide_emitters", false)?;
        p.finish("max_depth, rr_depth, hide_emitters (volpathmis: use_spectral_mis)")?;
        Ok(IntegratorSettings {
            kind,
            max_depth: if max_depth == -1 {
                u32::MAX
            } else {
                max_depth.min(u32::MAX as i64 - 1) as u32
            },
            rr_depth: rr_depth.min(u32::MAX as i64) as u32,
            hide_emitters,
            moment_aovs_dropped: false,
        })
    }
}
