//! Emitter plugins: Mitsuba's `area`, `point`, `spot`, `constant`, `directional` and
//! `envmap`.

use glam::{DVec3, Vec3};

use super::props::Props;
use super::spectrum::SpectrumUse;
use super::{unsupported, Builder};
use crate::emitter::envmap::EnvMap;
use crate::emitter::{Emitter, Spot};
use crate::error::{Result, SceneError};
use crate::xml::description::{ObjId, Value};
use crate::xml::resolve::resolve_path;

/// Mitsuba's `xyz_to_srgb` applied to XYZ = (1, 1, 1): in RGB mode a constant
/// `<spectrum value="v"/>` given to an emitter becomes `v` times this color
/// (`src/core/properties.cpp`, "A uniform spectrum does not produce a uniform RGB
/// response in sRGB").
pub const UNIFORM_SPECTRUM_RGB: Vec3 = Vec3::new(
    3.240479 - 1.53715 - 0.498535,
    -0.969256 + 1.875991 + 0.041556,
    0.055648 - 0.204043 + 1.057311,
);

impl Builder<'_> {
    /// `envmap`: a latitude-longitude image (any `bitmap` format), `scale`, a rotation `to_world`;
    /// `mis_compensation` only changes Mitsuba's sampling, not the image (read, unused).
    pub(super) fn envmap(&self, p: &Props) -> Result<EnvMap> {
        let Some((name, loc)) = p.string_opt("filename")? else {
            return Err(p.error("envmap needs a filename (a latitude-longitude image)"));
        };
        let path = resolve_path(&self.desc.search_path, name).ok_or_else(|| {
            SceneError::at(loc, format!("environment map \"{name}\" not found"))
                .with_hint("add its folder with -a DIR")
        })?;
        // Any format Mitsuba's `Bitmap` reads, made linear RGB as Mitsuba's envmap does
        // (`convert(RGB, Float, srgb = false)`: 8/16-bit data sRGB-decoded).
        let (width, height, texels) = crate::texture::bitmap_file::read_texels(&path, false)
            .map_err(|e| SceneError::at(loc, format!("environment map \"{name}\": {e}")))?;
        let img = crate::image::Image {
            width,
            height,
            pixels: texels.iter().map(|t| t.to_array()).collect(),
        };
        if img.width < 2 || img.height < 3 {
            return Err(SceneError::at(
                loc,
                format!(
                    "environment map \"{name}\" is {}x{}: at least 2x3 pixels, as Mitsuba requires",
                    img.width, img.height
                ),
            ));
        }
        if let Some(bad) = img
            .pixels
            .iter()
            .flatten()
            .find(|v| !v.is_finite() || **v < 0.0)
        {
            return Err(SceneError::at(
                loc,
                format!("environment map \"{name}\" holds the value {bad}: radiance must be finite and ≥ 0"),
            ));
        }
        let scale = p.float("scale", 1.0)?;
        if !(scale.is_finite() && scale >= 0.0) {
            return Err(p.error(format!("scale = {scale}: must be finite and ≥ 0")));
        }
        let m = p.transform("to_world")?;
        let r = glam::DMat3::from_mat4(m);
        if (r.transpose() * r - glam::DMat3::IDENTITY)
            .to_cols_array()
            .iter()
            .any(|v| v.abs() > 1e-5)
        {
            return Err(p.error("an envmap's to_world must be a rotation (no scale or shear)"));
        }
        p.bool("mis_compensation", false)?;
        Ok(EnvMap::new(
            img.width,
            img.height,
            &img.pixels,
            scale as f32,
            r.as_mat3(),
        ))
    }

    pub(super) fn emitter(&mut self, id: ObjId, shape: Option<u32>) -> Result<u32> {
        let p = Props::new(self.desc, id);
        let e = match (p.obj.plugin.as_str(), shape) {
            ("area", Some(s)) => {
                let radiance = emissive(&p, "radiance")?;
                p.finish("radiance")?;
                Emitter::Area { shape: s, radiance }
            }
            ("area", None) => {
                return Err(p.error("an area emitter must be nested inside a <shape>"))
            }
            (_, Some(_)) => {
                return Err(p.error("only an \"area\" emitter can be attached to a shape"))
            }
            ("point", None) => {
                let intensity = emissive(&p, "intensity")?;
                let pos = p.point_opt("position")?;
                let tw = p.has("to_world");
                let position = match (pos, tw) {
                    (Some(_), true) => {
                        return Err(p.error("give either position or to_world, not both"))
                    }
                    (Some(x), false) => x,
                    (None, _) => p.transform("to_world")?.transform_point3(DVec3::ZERO),
                };
                p.finish("intensity, position, to_world")?;
                Emitter::Point {
                    position: position.as_vec3().into(),
                    intensity,
                }
            }
            ("spot", None) => {
                let intensity = emissive(&p, "intensity")?;
                if p.has("texture") {
                    return Err(p.error(
                        "a spot light's \"texture\" (a projected image) is not supported yet",
                    ));
                }
                let cutoff = p.float("cutoff_angle", 20.0)?;
                let beam = p.float("beam_width", cutoff * 0.75)?;
                if !(cutoff > 0.0 && cutoff <= 180.0 && (0.0..=cutoff).contains(&beam)) {
                    return Err(p.error(format!(
                        "cutoff_angle {cutoff} and beam_width {beam} (degrees): need 0 < cutoff_angle <= 180 and 0 <= beam_width <= cutoff_angle"
                    )));
                }
                let to_world = p.transform("to_world")?;
                let linear = glam::DMat3::from_mat4(to_world);
                if linear.determinant().abs() < 1e-12 {
                    return Err(p.error("the spot light's to_world is singular"));
                }
                p.finish("intensity, cutoff_angle, beam_width, to_world")?;
                Emitter::Spot(Spot::new(
                    to_world.transform_point3(DVec3::ZERO).as_vec3().into(),
                    glam::Mat3A::from(linear.inverse().as_mat3()),
                    intensity,
                    cutoff.to_radians() as f32,
                    beam.to_radians() as f32,
                ))
            }
            ("constant", None) => {
                let radiance = emissive(&p, "radiance")?;
                if self.environment.is_some() {
                    return Err(p.error("only one environment emitter is allowed"));
                }
                p.finish("radiance")?;
                self.environment = Some(self.emitters.len() as u32);
                Emitter::Constant { radiance }
            }
            ("envmap", None) => {
                if self.environment.is_some() {
                    return Err(p.error("only one environment emitter is allowed"));
                }
                let m = self.envmap(&p)?;
                p.finish("filename, scale, to_world, mis_compensation")?;
                self.environment = Some(self.emitters.len() as u32);
                Emitter::EnvMap(Box::new(m))
            }
            ("directional", None) => {
                let irradiance = emissive(&p, "irradiance")?;
                let dir = p.vector_opt("direction")?;
                let tw = p.has("to_world");
                let d = match (dir, tw) {
                    (Some(_), true) => {
                        return Err(p.error("give either direction or to_world, not both"))
                    }
                    (Some(d), false) => d,
                    (None, _) => p.transform("to_world")?.transform_vector3(DVec3::Z),
                };
                let d = d
                    .try_normalize()
                    .ok_or_else(|| p.error("the light direction must be a nonzero vector"))?;
                p.finish("irradiance, direction, to_world")?;
                Emitter::Directional {
                    direction: d.as_vec3().into(),
                    irradiance,
                }
            }
            _ => {
                return Err(unsupported(
                    &p,
                    "emitter",
                    "area, point, spot, constant, envmap, directional",
                ))
            }
        };
        self.emitters.push(e);
        Ok(self.emitters.len() as u32 - 1)
    }
}

/// A color for an emitter: float and rgb as given, a constant spectrum as Mitsuba's RGB
/// mode converts it (see `UNIFORM_SPECTRUM_RGB`), a sampled one without the D65 weight
/// and unclipped above (`SpectrumUse::Emission`).
fn emissive(p: &Props, name: &str) -> Result<Vec3> {
    let is_spectrum = p
        .obj
        .props
        .iter()
        .any(|q| q.name == name && matches!(q.value, Value::Spectrum(_)));
    let c = p.color_nonneg_as(name, Vec3::ONE, SpectrumUse::Emission)?;
    Ok(if is_spectrum {
        c * UNIFORM_SPECTRUM_RGB
    } else {
        c
    })
}
