//! Integrator plugins: Mitsuba's `path`, `volpath`, `direct`, `moment` and `aov` (around
//! one of them), the integrators that estimate the same image as one of these (rendered by
//! it, with a warning: `volpathmis`, `prb`, `prb_basic`, `prbvolpath`, `ptracer`, and
//! Mitsuba 0.6's `volpath_simple` and `bdpt` in files older than 2.0), and the command
//! line's `--integrator NAME`, which replaces the file's.

use super::props::Props;
use super::{unsupported, Builder};
use crate::error::{Result, SceneError};
use crate::scene::{IntegratorKind, IntegratorSettings};
use crate::xml::description::{ObjId, ObjectKind};

/// What `--integrator` may name.
pub const OVERRIDE_NAMES: &str = "path, volpath, direct";

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
    pub(super) fn moment_integrator(&mut self, p: Props) -> Result<IntegratorSettings> {
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

    /// Mitsuba's `aov`: the `aovs` it lists (depth, normals, …) become extra EXR channels
    /// beside the nested integrator's image; mediareg renders that image and writes no
    /// AOV (a warning says so).
    fn aov_integrator(&mut self, p: Props) -> Result<IntegratorSettings> {
        let aovs = p.string("aovs", "")?;
        let nested = p.children_of(ObjectKind::Integrator);
        let [inner] = nested.as_slice() else {
            return Err(p
                .error(format!(
                    "aov with {} nested integrators: mediareg renders the image of exactly one",
                    nested.len()
                ))
                .with_hint(
                    "nest one integrator (e.g. <integrator type=\"path\"/>) in the aov integrator",
                ));
        };
        let settings = self.integrator(inner.object)?;
        self.warnings.push(format!(
            "{}: integrator \"aov\": the image is its nested integrator's; the AOVs \"{aovs}\" are not written",
            p.loc()
        ));
        p.finish("aovs, (one nested integrator)")?;
        Ok(settings)
    }

    pub(super) fn integrator(&mut self, id: ObjId) -> Result<IntegratorSettings> {
        let p = Props::new(self.desc, id);
        let legacy = p.obj.legacy;
        let plugin = p.obj.plugin.as_str();
        // Integrators that estimate the same image (in expectation) as one of mediareg's,
        // which renders them.
        let (kind, alias_of) = match plugin {
            "path" => (IntegratorKind::Path, None),
            "volpath" => (IntegratorKind::Volpath, None),
            // Spectral MIS only changes how chromatic media are sampled.
            "volpathmis" => (IntegratorKind::Volpath, Some("volpath")),
            // Path replay backpropagation: the primal image is a path tracer's (media
            // ignored, as by `path`).
            "prb" | "prb_basic" => (IntegratorKind::Path, Some("path")),
            "prbvolpath" => (IntegratorKind::Volpath, Some("volpath")),
            // The particle tracer: light paths splatted to the film, surfaces only.
            "ptracer" => (IntegratorKind::Path, Some("path")),
            // Mitsuba 0.6: volpath_simple is volpath without MIS; bdpt handles media.
            "volpath_simple" if legacy => (IntegratorKind::Volpath, Some("volpath")),
            "bdpt" if legacy => {
                let media = self.desc.objects.iter().any(|o| o.kind == ObjectKind::Medium);
                if media {
                    (IntegratorKind::Volpath, Some("volpath"))
                } else {
                    (IntegratorKind::Path, Some("path"))
                }
            }
            "direct" => return direct_integrator(p),
            "moment" => return self.moment_integrator(p),
            "aov" => return self.aov_integrator(p),
            _ => {
                return Err(unsupported(
                    &p,
                    "integrator",
                    "path, volpath, direct, moment, aov; rendered by path or volpath: volpathmis, prb, prb_basic, prbvolpath, ptracer (and 0.6's volpath_simple, bdpt)",
                )
                .with_hint(format!(
                    "render it with one of mediareg's integrators instead: --integrator NAME ({OVERRIDE_NAMES})"
                )))
            }
        };
        if plugin == "volpathmis" {
            p.bool("use_spectral_mis", true)?;
        }
        let mut names = "max_depth, rr_depth, hide_emitters";
        match plugin {
            "volpathmis" => names = "max_depth, rr_depth, hide_emitters, use_spectral_mis",
            "ptracer" => {
                // How many samples go to the film per pass: no effect on the image.
                p.int("samples_per_pass", -1)?;
                names = "max_depth, rr_depth, hide_emitters, samples_per_pass";
            }
            "bdpt" => {
                // 0.6: whether light paths are splatted to the film, and direct light
                // sampled; both only change the noise.
                p.bool("light_image", true)?;
                p.bool("sample_direct", true)?;
                names = "max_depth, rr_depth, light_image, sample_direct";
            }
            _ => {}
        }
        // The differentiable integrators (Mitsuba's ADIntegrator) default to depth 6.
        let default_depth = if plugin.starts_with("prb") { 6 } else { -1 };
        let settings = depth_settings(&p, kind, default_depth)?;
        let loc = p.loc().clone();
        p.finish(names)?;
        if let Some(ours) = alias_of {
            self.warnings.push(format!(
                "{loc}: integrator \"{plugin}\" is rendered by mediareg's {ours} (the same image in expectation)"
            ));
        }
        Ok(settings)
    }

    /// `--integrator NAME`: mediareg's integrator NAME replaces the file's; the file's
    /// `max_depth`, `rr_depth` and `hide_emitters` (of the innermost integrator, under
    /// `moment` or `aov`) are kept where it gives them.
    pub(super) fn override_integrator(
        &mut self,
        name: &str,
        file: Option<ObjId>,
    ) -> Result<IntegratorSettings> {
        // The innermost integrator the file nests.
        let mut inner = file;
        while let Some(i) = inner {
            let o = self.desc.object(i);
            match o
                .children
                .iter()
                .find(|c| self.desc.object(c.object).kind == ObjectKind::Integrator)
            {
                Some(c) if matches!(o.plugin.as_str(), "moment" | "aov") => inner = Some(c.object),
                _ => break,
            }
        }
        let settings = match (name, inner) {
            ("direct", _) => IntegratorSettings {
                kind: IntegratorKind::Direct {
                    emitter_samples: 1,
                    bsdf_samples: 1,
                },
                max_depth: 2,
                rr_depth: u32::MAX,
                hide_emitters: false,
                moment_aovs_dropped: false,
            },
            ("path" | "volpath", i) => {
                let kind = if name == "path" {
                    IntegratorKind::Path
                } else {
                    IntegratorKind::Volpath
                };
                match i {
                    // Read only what this integrator takes; the rest of the file's
                    // integrator is not used.
                    Some(i) => depth_settings(&Props::new(self.desc, i), kind, -1)?,
                    None => IntegratorSettings {
                        kind,
                        max_depth: u32::MAX,
                        rr_depth: 5,
                        hide_emitters: false,
                        moment_aovs_dropped: false,
                    },
                }
            }
            _ => {
                return Err(SceneError::new(
                    None,
                    format!("--integrator {name}: not one of mediareg's integrators"),
                )
                .with_hint(format!("use one of: {OVERRIDE_NAMES}")))
            }
        };
        let what = match file {
            Some(f) => format!(
                "{}: the file's integrator \"{}\"",
                self.desc.object(f).loc,
                self.desc.object(f).plugin
            ),
            None => "the default integrator".into(),
        };
        self.warnings.push(format!(
            "--integrator {name}: rendered with mediareg's {name} instead of {what}"
        ));
        Ok(settings)
    }
}

/// `max_depth` (−1 = unbounded), `rr_depth` (5) and `hide_emitters` (false), as Mitsuba's
/// `MonteCarloIntegrator` reads them.
fn depth_settings(
    p: &Props,
    kind: IntegratorKind,
    default_depth: i64,
) -> Result<IntegratorSettings> {
    let max_depth = p.int("max_depth", default_depth)?;
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
