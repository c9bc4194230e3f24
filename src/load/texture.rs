//! Texture plugins a BSDF parameter may be: a color, Mitsuba's `checkerboard` and
//! `bitmap`.

use std::sync::Arc;

use glam::Vec3;

use super::props::Props;
use super::{unsupported, Builder};
use crate::error::{Result, SceneError};
use crate::texture::bitmap::{Bitmap, FilterType, WrapMode};
use crate::texture::bitmap_file::read_texels;
use crate::texture::Texture;
use crate::xml::description::ObjectKind;
use crate::xml::resolve::resolve_path;

impl Builder<'_> {
    /// A reflectance in [0, 1]: a constant, or a nested (or referenced) `<texture>`.
    pub(super) fn reflectance(&self, p: &Props, name: &str, default: Vec3) -> Result<Texture> {
        let in_unit = |c: Vec3, p: &Props| -> Result<Vec3> {
            if c.max_element() > 1.0 {
                return Err(p.error(format!("{name} {c} must be in [0, 1]")));
            }
            Ok(c)
        };
        let Some(child) = p.named_child_of(name, ObjectKind::Texture)? else {
            return Ok(Texture::Constant(in_unit(
                p.color_nonneg(name, default)?,
                p,
            )?));
        };
        let t = Props::new(self.desc, child.object);
        if t.obj.plugin == "bitmap" {
            return self.bitmap(t, name);
        }
        if t.obj.plugin != "checkerboard" {
            return Err(unsupported(&t, "texture", "checkerboard, bitmap"));
        }
        let color0 = in_unit(t.color_nonneg("color0", Vec3::splat(0.4))?, &t)?;
        let color1 = in_unit(t.color_nonneg("color1", Vec3::splat(0.2))?, &t)?;
        // Mitsuba's to_uv is a 2D affine map: the 4x4 matrix's upper-left 2x2 and its
        // translation.
        let to_uv = to_uv(&t)?;
        t.finish("color0, color1, to_uv")?;
        Ok(Texture::Checkerboard {
            color0,
            color1,
            to_uv,
        })
    }

    /// Mitsuba's `bitmap` as a reflectance: `filename` (any format Mitsuba reads:
    /// `bitmap_file`), `filter_type`
    /// (bilinear), `wrap_mode` (repeat), `raw` (false), `to_uv`; `format` and `accel`
    /// only choose Mitsuba's storage and are read. Texels must lie in [0, 1].
    pub(super) fn bitmap(&self, t: Props, name: &str) -> Result<Texture> {
        let file = t.string("filename", "")?;
        if file.is_empty() {
            return Err(t.error("bitmap needs a filename"));
        }
        let loc = t
            .get("filename")
            .map_or(t.obj.loc.clone(), |(_, l)| l.clone());
        let path = resolve_path(&self.desc.search_path, &file).ok_or_else(|| {
            SceneError::at(&loc, format!("bitmap \"{file}\" not found"))
                .with_hint("give a path relative to the scene, or add its folder with -a DIR")
        })?;
        let filter = match t.string("filter_type", "bilinear")?.as_str() {
            "bilinear" => FilterType::Bilinear,
            "nearest" => FilterType::Nearest,
            f => {
                return Err(t.error(format!(
                    "filter_type \"{f}\" is not one of \"bilinear\", \"nearest\""
                )))
            }
        };
        let wrap = match t.string("wrap_mode", "repeat")?.as_str() {
            "repeat" => WrapMode::Repeat,
            "mirror" => WrapMode::Mirror,
            "clamp" => WrapMode::Clamp,
            w => {
                return Err(t.error(format!(
                    "wrap_mode \"{w}\" is not one of \"repeat\", \"mirror\", \"clamp\""
                )))
            }
        };
        let raw = t.bool("raw", false)?;
        let format = t.string("format", "auto")?;
        if !["auto", "variant", "float16", "fp16", "uint8"].contains(&format.as_str()) {
            return Err(t.error(format!(
                "format \"{format}\" is not one of \"auto\", \"variant\", \"float16\", \"uint8\""
            )));
        }
        t.bool("accel", true)?;
        let to_uv = to_uv(&t)?;
        let (width, height, texels) =
            read_texels(&path, raw).map_err(|e| SceneError::at(&loc, e))?;
        if width == 0 || height == 0 {
            return Err(SceneError::at(&loc, format!("bitmap \"{file}\" is empty")));
        }
        let b = Bitmap {
            width,
            height,
            texels,
            filter,
            wrap,
            to_uv,
        };
        let outside = |c: &Vec3| !c.is_finite() || c.min_element() < 0.0 || c.max_element() > 1.0;
        if b.texels.iter().any(outside) {
            return Err(SceneError::at(
                &loc,
                format!(
                    "bitmap \"{file}\" used as {name} has values outside [0, 1] (largest {})",
                    b.max_value()
                ),
            ));
        }
        t.finish("filename, filter_type, wrap_mode, raw, format, accel, to_uv")?;
        Ok(Texture::Bitmap(Arc::new(b)))
    }
}

/// A texture's `to_uv`, Mitsuba's 2D affine map: the 4×4 matrix's upper-left 2×2 and its
/// translation, as rows (a, b, tx) and (c, d, ty).
fn to_uv(t: &Props) -> Result<[[f32; 3]; 2]> {
    let m = t.transform("to_uv")?;
    Ok([
        [m.x_axis.x as f32, m.y_axis.x as f32, m.w_axis.x as f32],
        [m.x_axis.y as f32, m.y_axis.y as f32, m.w_axis.y as f32],
    ])
}
