//! Volume plugins (Mitsuba's `gridvolume`, `constvolume`, and a plain `<float>`/`<rgb>`
//! read as a `constvolume`), for the properties of media that may vary in space.

use glam::{Affine3A, DMat4, Vec3};

use super::props::Props;
use super::spectrum::SpectrumUse;
use super::{to_mat4, unsupported, Builder};
use crate::error::{Loc, Result, SceneError};
use crate::medium::grid::{parse_vol, Filter, Source, Volume, Wrap};
use crate::xml::description::ObjectKind;
use crate::xml::resolve::resolve_path;

/// Whether property `name` of `p` is a nested `gridvolume` (looked at without
/// marking it used).
pub(super) fn is_grid(p: &Props, name: &str) -> bool {
    p.obj.children.iter().any(|c| {
        c.name.as_deref() == Some(name) && {
            let o = p.desc.object(c.object);
            o.kind == ObjectKind::Volume && o.plugin == "gridvolume"
        }
    })
}

impl Builder<'_> {
    /// Property `name` of `p` as a volume, and where it is given: a nested
    /// `gridvolume` or `constvolume`, or a constant (a `constvolume` over the unit
    /// cube, as Mitsuba's `get_volume` makes it); `default` when absent.
    pub(super) fn volume(&self, p: &Props, name: &str, default: Vec3) -> Result<(Volume, Loc)> {
        let Some(c) = p.named_child_of(name, ObjectKind::Volume)? else {
            let (v, loc) = match p.color_opt_as(name, SpectrumUse::Unbounded)? {
                Some(x) => x,
                None => (default, p.obj.loc.clone()),
            };
            if !v.is_finite() || v.min_element() < 0.0 {
                return Err(SceneError::at(
                    &loc,
                    format!(
                        "{}: \"{name}\" = {v} must be finite and nonnegative",
                        p.obj.label()
                    ),
                ));
            }
            return Ok((Volume::new(Source::Const(v), Affine3A::IDENTITY), loc));
        };
        let q = Props::new(self.desc, c.object);
        let to_world = q.transform("to_world")?;
        let volume = match q.obj.plugin.as_str() {
            "constvolume" => {
                let v = q.color_nonneg_as("value", Vec3::ONE, SpectrumUse::Unbounded)?;
                let a = affine(&q, to_world)?;
                q.finish("value, to_world")?;
                Volume::new(Source::Const(v), a)
            }
            "gridvolume" => self.grid_volume(q, to_world)?,
            _ => return Err(unsupported(&q, "volume", "gridvolume, constvolume")),
        };
        Ok((volume, c.loc.clone()))
    }

    /// Mitsuba's `gridvolume`: `filename` (a `.vol`), `filter_type`, `wrap_mode`,
    /// `use_grid_bbox`, `max_value`, `to_world`; `raw` and `accel` only change
    /// Mitsuba's spectral conversion and storage, and are read.
    fn grid_volume(&self, q: Props, to_world: DMat4) -> Result<Volume> {
        let Some((file, floc)) = q.string_opt("filename")? else {
            return Err(q.error("gridvolume needs a filename (a Mitsuba .vol file)"));
        };
        let path = resolve_path(&self.desc.search_path, file).ok_or_else(|| {
            SceneError::at(floc, format!("volume file \"{file}\" not found"))
                .with_hint("give a path relative to the scene, or add its folder with -a DIR")
        })?;
        let bytes = std::fs::read(&path)
            .map_err(|e| SceneError::at(floc, format!("volume file {}: {e}", path.display())))?;
        let grid = parse_vol(&bytes).map_err(|e| {
            SceneError::at(floc, format!("volume file {}: {e}", path.display())).with_hint(
                "write it in Mitsuba's .vol format: \"VOL\", version 3, encoding 1, xres yres zres channels (i32), bbox (6 f32), then float32 values x fastest",
            )
        })?;
        let filter = match q.string("filter_type", "trilinear")?.as_str() {
            "trilinear" => Filter::Trilinear,
            "nearest" => Filter::Nearest,
            f => {
                return Err(q.error(format!(
                    "filter_type \"{f}\" is not one of \"trilinear\", \"nearest\""
                )))
            }
        };
        let wrap = match q.string("wrap_mode", "clamp")?.as_str() {
            "clamp" => Wrap::Clamp,
            "repeat" => Wrap::Repeat,
            "mirror" => Wrap::Mirror,
            w => {
                return Err(q.error(format!(
                    "wrap_mode \"{w}\" is not one of \"clamp\", \"repeat\", \"mirror\""
                )))
            }
        };
        q.bool("raw", false)?;
        q.bool("accel", true)?;
        let mut to_world = to_world;
        if q.bool("use_grid_bbox", false)? {
            // The file's box is the unit cube's image before to_world.
            let [lo, hi] = grid.file_bbox;
            let (lo, hi) = (lo.as_dvec3(), hi.as_dvec3());
            if (hi - lo).min_element() <= 0.0 {
                return Err(q.error(format!(
                    "use_grid_bbox: the file's bounding box {lo} – {hi} is empty"
                )));
            }
            to_world = to_world * DMat4::from_translation(lo) * DMat4::from_scale(hi - lo);
        }
        let max_value = q.float_opt("max_value")?;
        let a = affine(&q, to_world)?;
        let label = q.obj.label();
        q.finish(
            "filename, filter_type, wrap_mode, use_grid_bbox, max_value, raw, accel, to_world",
        )?;
        let mut v = Volume::new(Source::Grid { grid, filter, wrap }, a);
        if let Some(m) = max_value {
            // Mitsuba takes it as the majorant unchecked; one below the data would bias
            // the render.
            if (m as f32) < v.max || m.is_nan() {
                return Err(SceneError::at(floc, format!(
                    "{label}: max_value = {m} is below the grid's largest value {}: as a majorant it would bias the image",
                    v.max
                )));
            }
            v.max = m as f32;
        }
        Ok(v)
    }
}

/// A volume's `to_world`, which must be invertible.
fn affine(q: &Props, m: DMat4) -> Result<Affine3A> {
    let a = Affine3A::from_mat4(to_mat4(m));
    let det = a.matrix3.determinant();
    if !(det.is_finite() && det.abs() > 1e-12) || m.row(3) != glam::DVec4::new(0.0, 0.0, 0.0, 1.0) {
        return Err(q.error("to_world must be an invertible affine transform"));
    }
    Ok(a)
}
