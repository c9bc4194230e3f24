//! BSDF plugins: Mitsuba's `diffuse`, `dielectric`, `thindielectric`,
//! `roughdielectric`, `conductor`, `roughconductor`, `plastic`, `roughplastic`, `null`
//! `twosided`, `principled`, `blendbsdf` and `mask`, with their indices of refraction
//! and microfacet parameters.

use glam::Vec3;

use super::conductor_ior::{self, named_conductor};
use super::props::Props;
use super::spectrum::SpectrumUse;
use super::{unsupported, Builder};
use crate::bsdf::dielectric::named_ior;
use crate::bsdf::microfacet::{Microfacet, MicrofacetType};
use crate::bsdf::principled::eta_from_specular;
use crate::bsdf::{
    Blend, Bsdf, Conductor, Dielectric, Mask, Plastic, Principled, RoughConductor, RoughDielectric,
    RoughPlastic, ThinDielectric,
};
use crate::error::{Result, SceneError};
use crate::texture::Texture;
use crate::xml::description::{ObjId, ObjectKind, Value};

impl Builder<'_> {
    pub(super) fn bsdf(&mut self, id: ObjId) -> Result<u32> {
        if let Some(&i) = self.bsdf_ids.get(&id) {
            return Ok(i);
        }
        let b = self.bsdf_value(id)?;
        self.bsdfs.push(b);
        let i = self.bsdfs.len() as u32 - 1;
        self.bsdf_ids.insert(id, i);
        Ok(i)
    }

    pub(super) fn bsdf_value(&self, id: ObjId) -> Result<Bsdf> {
        let p = Props::new(self.desc, id);
        let b = match p.obj.plugin.as_str() {
            "null" => {
                p.finish("(no parameters)")?;
                Bsdf::Null
            }
            "diffuse" => {
                let reflectance = self.reflectance(&p, "reflectance", Vec3::splat(0.5))?;
                p.finish("reflectance")?;
                Bsdf::Diffuse { reflectance }
            }
            // The same parameters, and defaults, for both.
            "dielectric" | "thindielectric" => {
                let int_ior = ior(&p, "int_ior", "bk7")?;
                let ext_ior = ior(&p, "ext_ior", "air")?;
                let eta = (int_ior / ext_ior) as f32;
                let specular_reflectance = p.color_nonneg("specular_reflectance", Vec3::ONE)?;
                let specular_transmittance = p.color_nonneg("specular_transmittance", Vec3::ONE)?;
                let thin = p.obj.plugin == "thindielectric";
                p.finish("int_ior, ext_ior, specular_reflectance, specular_transmittance")?;
                if !thin {
                    Bsdf::Dielectric(Dielectric {
                        eta,
                        specular_reflectance,
                        specular_transmittance,
                    })
                } else {
                    Bsdf::ThinDielectric(ThinDielectric {
                        eta,
                        specular_reflectance,
                        specular_transmittance,
                    })
                }
            }
            "conductor" => {
                let sr = p.color_nonneg("specular_reflectance", Vec3::ONE)?;
                let (eta, k) = conductor_ior(&p)?;
                p.finish("material, eta, k, specular_reflectance")?;
                Bsdf::Conductor(Conductor {
                    eta,
                    k,
                    specular_reflectance: sr,
                })
            }
            "roughconductor" => {
                let specular_reflectance = p.color_nonneg("specular_reflectance", Vec3::ONE)?;
                let (eta, k) = conductor_ior(&p)?;
                let distr = microfacet(&p, true)?;
                p.finish("material, eta, k, specular_reflectance, distribution, alpha, alpha_u, alpha_v, sample_visible")?;
                Bsdf::RoughConductor(RoughConductor {
                    distr,
                    eta,
                    k,
                    specular_reflectance,
                })
            }
            "roughdielectric" => {
                let eta = relative_ior(&p, "bk7")?;
                let specular_reflectance = p.color_nonneg("specular_reflectance", Vec3::ONE)?;
                let specular_transmittance = p.color_nonneg("specular_transmittance", Vec3::ONE)?;
                let distr = microfacet(&p, true)?;
                p.finish("int_ior, ext_ior, specular_reflectance, specular_transmittance, distribution, alpha, alpha_u, alpha_v, sample_visible")?;
                Bsdf::RoughDielectric(RoughDielectric {
                    eta,
                    distr,
                    specular_reflectance,
                    specular_transmittance,
                })
            }
            // The same coated-diffuse parameters; the rough one adds a microfacet coating.
            "plastic" | "roughplastic" => {
                let rough = p.obj.plugin == "roughplastic";
                let eta = if rough {
                    relative_ior(&p, "polypropylene")?
                } else {
                    (ior(&p, "int_ior", "polypropylene")? / ior(&p, "ext_ior", "air")?) as f32
                };
                let diffuse_reflectance =
                    self.reflectance(&p, "diffuse_reflectance", Vec3::splat(0.5))?;
                let specular_reflectance = if p.has("specular_reflectance") {
                    Some(p.color_nonneg("specular_reflectance", Vec3::ONE)?)
                } else {
                    None
                };
                let nonlinear = p.bool("nonlinear", false)?;
                if rough {
                    let distr = microfacet(&p, false)?;
                    p.finish("int_ior, ext_ior, diffuse_reflectance, specular_reflectance, nonlinear, distribution, alpha, sample_visible")?;
                    Bsdf::RoughPlastic(RoughPlastic::new(
                        eta,
                        distr,
                        diffuse_reflectance,
                        specular_reflectance,
                        nonlinear,
                    ))
                } else {
                    p.finish(
                        "int_ior, ext_ior, diffuse_reflectance, specular_reflectance, nonlinear",
                    )?;
                    Bsdf::Plastic(Plastic::new(
                        eta,
                        diffuse_reflectance,
                        specular_reflectance,
                        nonlinear,
                    ))
                }
            }
            "twosided" => {
                let nested = p.children_of(ObjectKind::Bsdf);
                let (front, back) = match nested.as_slice() {
                    [one] => {
                        let b = self.bsdf_value(one.object)?;
                        (b.clone(), b)
                    }
                    [a, b] => (self.bsdf_value(a.object)?, self.bsdf_value(b.object)?),
                    _ => return Err(p.error("twosided needs one or two nested <bsdf>")),
                };
                p.finish("one or two nested bsdf")?;
                Bsdf::TwoSided(Box::new([front, back]))
            }
            "principled" => self.principled(p)?,
            "blendbsdf" => {
                if !self.given(&p, "weight") {
                    return Err(p.error("blendbsdf needs a \"weight\"")
                        .with_hint("give <float name=\"weight\" value=\"0.5\"/> or a texture named weight: the share of the second nested bsdf"));
                }
                let weight = self.reflectance(&p, "weight", Vec3::ZERO)?;
                let nested = p.children_of(ObjectKind::Bsdf);
                let [a, b] = nested.as_slice() else {
                    return Err(p.error(format!(
                        "blendbsdf needs exactly two nested <bsdf>, not {}",
                        nested.len()
                    )));
                };
                let bsdfs = [self.bsdf_value(a.object)?, self.bsdf_value(b.object)?];
                p.finish("weight, two nested bsdf")?;
                Bsdf::Blend(Box::new(Blend { weight, bsdfs }))
            }
            "mask" => {
                let opacity = self.reflectance(&p, "opacity", Vec3::splat(0.5))?;
                let nested = p.children_of(ObjectKind::Bsdf);
                let [one] = nested.as_slice() else {
                    return Err(p.error(format!(
                        "mask needs exactly one nested <bsdf>, not {}",
                        nested.len()
                    )));
                };
                let nested = self.bsdf_value(one.object)?;
                p.finish("opacity, one nested bsdf")?;
                Bsdf::Mask(Box::new(Mask { opacity, nested }))
            }
            _ => {
                return Err(unsupported(
                    &p,
                    "bsdf",
                    "null, diffuse, dielectric, thindielectric, conductor, plastic, roughdielectric, roughconductor, roughplastic, twosided, principled, blendbsdf, mask",
                ))
            }
        };
        Ok(b)
    }
}

impl Builder<'_> {
    /// Whether `name` is given, as a property or a nested object.
    fn given(&self, p: &Props, name: &str) -> bool {
        p.has(name)
            || p.obj
                .children
                .iter()
                .any(|c| c.name.as_deref() == Some(name))
    }

    /// A scalar parameter of `principled` that switches its lobe's code on (Mitsuba's
    /// `get_flag`): `None` when not given or given as the float 0. A float, rgb (its
    /// mean, as `eval_1`) or texture, in [0, 1].
    fn lobe_param(&self, p: &Props, name: &str) -> Result<Option<Texture>> {
        if !self.given(p, name) {
            return Ok(None);
        }
        let zero_float = matches!(p.get(name), Some((Value::Float(v), _)) if *v == 0.0);
        let t = self.scalar_param(p, name, 0.0)?;
        Ok((!zero_float).then_some(t))
    }

    /// A scalar parameter read by `eval_1`: a texture (texels in [0, 1]), or a float or
    /// rgb, finite and nonnegative (Mitsuba bounds none of them; a sheen or clearcoat
    /// above 1 is a stronger lobe).
    fn scalar_param(&self, p: &Props, name: &str, default: f32) -> Result<Texture> {
        if p.named_child_of(name, ObjectKind::Texture)?.is_some() {
            return self.reflectance(p, name, Vec3::splat(default));
        }
        Ok(Texture::Constant(
            p.color_nonneg(name, Vec3::splat(default))?,
        ))
    }

    /// Mitsuba 3's `principled`, every parameter with its name and default.
    fn principled(&self, p: Props) -> Result<Bsdf> {
        let spec_trans = self.lobe_param(&p, "spec_trans")?;
        let eta = match (p.has("eta"), p.has("specular")) {
            (true, true) => {
                return Err(p
                    .error("give either eta or specular, not both")
                    .with_hint("specular s stands for eta = 2 / (1 − √(0.08 s)) − 1"))
            }
            (true, false) => {
                let eta = p.float("eta", 1.5)? as f32;
                if !(eta > 0.0 && eta.is_finite()) {
                    return Err(p.error(format!("eta = {eta}: must be a finite index > 0")));
                }
                // η = 1 would make the transmission lobe singular.
                if spec_trans.is_some() && eta == 1.0 {
                    1.001
                } else {
                    eta
                }
            }
            (false, _) => {
                let mut specular = p.float_in("specular", 0.5, 0.0, 12.4)? as f32;
                if spec_trans.is_some() && specular == 0.0 {
                    specular = 1e-3;
                }
                eta_from_specular(specular)
            }
        };
        let rate = |name| -> Result<f32> { Ok(p.float_in(name, 1.0, 0.0, 1e6)? as f32) };
        let anisotropic = self.lobe_param(&p, "anisotropic")?;
        // α_u = roughness² / √(1 − 0.9 anisotropic) needs anisotropic ≤ 1/0.9.
        if let Some(a) = anisotropic.as_ref().and_then(Texture::constant) {
            if a.max_element() > 1.0 {
                return Err(p.error(format!("anisotropic {a} must be in [0, 1]")));
            }
        }
        let b = Principled {
            base_color: self.reflectance(&p, "base_color", Vec3::splat(0.5))?,
            roughness: self.scalar_param(&p, "roughness", 0.5)?,
            anisotropic,
            spec_trans,
            sheen: self.lobe_param(&p, "sheen")?,
            sheen_tint: self.lobe_param(&p, "sheen_tint")?,
            flatness: self.lobe_param(&p, "flatness")?,
            spec_tint: self.lobe_param(&p, "spec_tint")?,
            metallic: self.lobe_param(&p, "metallic")?,
            clearcoat: self.lobe_param(&p, "clearcoat")?,
            clearcoat_gloss: self.scalar_param(&p, "clearcoat_gloss", 0.0)?,
            eta,
            spec_srate: rate("main_specular_sampling_rate")?,
            clearcoat_srate: rate("clearcoat_sampling_rate")?,
            diff_refl_srate: rate("diffuse_reflectance_sampling_rate")?,
        };
        p.finish("base_color, roughness, anisotropic, metallic, spec_trans, eta or specular, spec_tint, sheen, sheen_tint, flatness, clearcoat, clearcoat_gloss, main_specular_sampling_rate, clearcoat_sampling_rate, diffuse_reflectance_sampling_rate")?;
        Ok(Bsdf::Principled(Box::new(b)))
    }
}

/// A conductor's complex index η + iκ: `eta` and `k` (float, rgb or spectrum,
/// unbounded), `material` "none" (η 0, κ 1: an ideal mirror), or one of Mitsuba's named
/// materials (its spectral tables, in RGB as its RGB variants make them).
fn conductor_ior(p: &Props) -> Result<(Vec3, Vec3)> {
    let material = p.string("material", "none")?;
    if p.has("eta") || material == "none" {
        if material != "none" {
            return Err(p.error("give either eta and k, or material, not both"));
        }
        let eta = p.color_nonneg_as("eta", Vec3::ZERO, SpectrumUse::Unbounded)?;
        let k = p.color_nonneg_as("k", Vec3::ONE, SpectrumUse::Unbounded)?;
        return Ok((eta, k));
    }
    if p.has("k") {
        return Err(p.error("give either eta and k, or material, not both"));
    }
    named_conductor(&material).ok_or_else(|| {
        let loc = p
            .get("material")
            .map_or(p.obj.loc.clone(), |(_, l)| l.clone());
        SceneError::at(
            &loc,
            format!(
                "{}: unknown conductor material \"{material}\"",
                p.obj.label()
            ),
        )
        .with_hint(format!(
            "give eta and k, or one of Mitsuba's materials (names are case-sensitive): none, {}",
            conductor_ior::names().join(", ")
        ))
    })
}

/// Mitsuba's microfacet parameters: `distribution` ("beckmann" or "ggx"; Beckmann by
/// default), `alpha` (0.1) or both `alpha_u` and `alpha_v` (only where `anisotropic`),
/// and `sample_visible` (true). mediareg always samples the visible normals; `false`
/// only changes how Mitsuba samples, not what it computes, so it is read and noted.
fn microfacet(p: &Props, anisotropic: bool) -> Result<Microfacet> {
    let name = p.string("distribution", "beckmann")?;
    let kind = MicrofacetType::parse(&name).ok_or_else(|| {
        p.error(format!(
            "distribution \"{name}\" is not one of \"beckmann\", \"ggx\""
        ))
    })?;
    let (has_u, has_v) = (p.has("alpha_u"), p.has("alpha_v"));
    let (au, av) = if has_u || has_v {
        if !anisotropic {
            return Err(p.error(
                "anisotropic roughness (alpha_u, alpha_v) is not supported by this plugin, as in Mitsuba 3; give alpha",
            ));
        }
        if !(has_u && has_v) {
            return Err(p.error("give both alpha_u and alpha_v, or alpha"));
        }
        if p.has("alpha") {
            return Err(p.error("give either alpha or alpha_u and alpha_v, not both"));
        }
        (
            roughness(p, "alpha_u", anisotropic)?,
            roughness(p, "alpha_v", anisotropic)?,
        )
    } else {
        let a = roughness(p, "alpha", anisotropic)?;
        (a, a)
    };
    if !p.bool("sample_visible", true)? {
        eprintln!(
            "note: {}: sample_visible = false is read; mediareg samples visible normals (the same image in expectation)",
            p.obj.label()
        );
    }
    Ok(Microfacet::new(kind, au as f32, av as f32))
}

/// A roughness: `roughconductor` and `roughdielectric` read it as Mitsuba 3 does, as an
/// unbounded texture's `eval_1` (a float, a constant `<spectrum>`, or an `<rgb>` or
/// sampled spectrum's channel mean); `roughplastic` as a plain float (Mitsuba's
/// `MicrofacetDistribution` reads `get<float>`, which refuses a spectrum).
fn roughness(p: &Props, name: &str, texture: bool) -> Result<f64> {
    let v = match (texture, p.get(name)) {
        (true, Some((Value::Rgb(_) | Value::Spectrum(_) | Value::SampledSpectrum(_), _))) => {
            let (c, _) = p.color_opt_as(name, SpectrumUse::Unbounded)?.unwrap();
            ((c.x + c.y + c.z) / 3.0) as f64
        }
        _ => p.float(name, 0.1)?,
    };
    if !(0.0..=1e3).contains(&v) {
        let loc = p.get(name).map_or(p.obj.loc.clone(), |(_, l)| l.clone());
        return Err(SceneError::at(
            &loc,
            format!(
                "{}: \"{name}\" = {v} is out of range [0, 1000]",
                p.obj.label()
            ),
        ));
    }
    Ok(v)
}

/// int_ior / ext_ior (defaults `int_default` and "air"), which must differ, as Mitsuba's
/// rough models require.
fn relative_ior(p: &Props, int_default: &str) -> Result<f32> {
    let int_ior = ior(p, "int_ior", int_default)?;
    let ext_ior = ior(p, "ext_ior", "air")?;
    if int_ior == ext_ior {
        return Err(p.error(format!(
            "int_ior and ext_ior are both {int_ior}: they must differ (a null bsdf is an index-matched boundary)"
        )));
    }
    Ok((int_ior / ext_ior) as f32)
}

/// An index of refraction: a number, or one of Mitsuba's named materials.
fn ior(p: &Props, name: &str, default: &str) -> Result<f64> {
    let given = p.obj.props.iter().find(|q| q.name == name);
    let v = match given.map(|q| &q.value) {
        Some(Value::String(_)) | None => {
            let s = p.string(name, default)?;
            named_ior(&s).map(|v| v as f64).ok_or_else(|| {
                let names: Vec<&str> = crate::bsdf::dielectric::NAMED_IOR
                    .iter()
                    .map(|(n, _)| *n)
                    .collect();
                SceneError::at(
                    &given.map_or(p.obj.loc.clone(), |q| q.loc.clone()),
                    format!("unknown material \"{s}\" for {name}"),
                )
                .with_hint(format!("give a number or one of: {}", names.join(", ")))
            })?
        }
        Some(_) => p.float(name, 1.0)?,
    };
    if !(v > 0.0 && v.is_finite()) {
        return Err(p.error(format!("{name} = {v}: must be a finite index > 0")));
    }
    Ok(v)
}
