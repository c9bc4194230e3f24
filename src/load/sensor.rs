//! The sensor and what it holds: Mitsuba's `perspective` sensor, `hdrfilm` film and
//! reconstruction filters (`box`, `tent`, `gaussian`); its sampler is in `sampler`.

use glam::{Mat4, Vec2, Vec3};

use super::props::Props;
use super::sampler::SamplerSpec;
use super::{to_mat4, unsupported, Builder};
use crate::error::Result;
use crate::geometry::Bounds;
use crate::scene::camera::{fov_x_degrees, PerspectiveCamera};
use crate::scene::film::{ComponentFormat, Film, PixelFormat, Rfilter};
use crate::xml::description::{ObjId, ObjectKind};

impl Builder<'_> {
    pub(super) fn sensor(
        &mut self,
        id: ObjId,
    ) -> Result<(PerspectiveCamera, Option<u32>, Film, SamplerSpec)> {
        let p = Props::new(self.desc, id);
        if p.obj.plugin != "perspective" {
            return Err(unsupported(&p, "sensor", "perspective"));
        }
        let film = match p.child_of(ObjectKind::Film)? {
            Some(c) => self.film(c.object)?,
            None => default_film(),
        };
        let sampler = match p.child_of(ObjectKind::Sampler)? {
            Some(c) => self.sampler(c.object)?,
            None => SamplerSpec::DEFAULT,
        };
        let aspect = film.width as f64 / film.height as f64;
        let fov_x = if p.has("fov") {
            if p.has("focal_length") {
                return Err(p.error("give either fov or focal_length, not both"));
            }
            let fov = p.float("fov", 0.0)?;
            if !(fov > 0.0 && fov < 180.0) {
                return Err(p.error(format!("fov = {fov}: must be in (0, 180) degrees")));
            }
            let axis = p.string("fov_axis", "x")?.to_ascii_lowercase();
            fov_x_degrees(fov, &axis, aspect).ok_or_else(|| {
                p.error(format!(
                    "fov_axis \"{axis}\": must be x, y, diagonal, smaller or larger"
                ))
            })?
        } else {
            // Mitsuba: a 35 mm-equivalent focal length (default 50mm) sets the diagonal fov.
            let f = p.string("focal_length", "50mm")?;
            let mm: f64 = f
                .strip_suffix("mm")
                .unwrap_or(&f)
                .trim()
                .parse()
                .ok()
                .filter(|v: &f64| *v > 0.0 && v.is_finite())
                .ok_or_else(|| p.error(format!("focal_length \"{f}\": expected e.g. \"50mm\"")))?;
            let fov = (2.0 * (36f64.hypot(24.0) / (2.0 * mm)).atan()).to_degrees();
            fov_x_degrees(fov, "diagonal", aspect).unwrap()
        };
        let near_clip = p.float("near_clip", 1e-2)?;
        let far_clip = p.float("far_clip", 1e4)?;
        if !(near_clip > 0.0 && far_clip > near_clip) {
            return Err(p.error(format!(
                "near_clip = {near_clip}, far_clip = {far_clip}: need 0 < near_clip < far_clip"
            )));
        }
        let ppo = Vec2::new(
            p.float("principal_point_offset_x", 0.0)? as f32,
            p.float("principal_point_offset_y", 0.0)? as f32,
        );
        let to_world = p.transform("to_world")?;
        let medium = match p.child_of(ObjectKind::Medium)? {
            Some(c) => Some(self.medium(c.object)?),
            None => None,
        };
        // Every projective camera reads the focal plane's distance (Mitsuba's
        // ProjectiveCamera); a pinhole has no use for it.
        p.float("focus_distance", far_clip)?;
        p.finish("fov, fov_axis, focal_length, near_clip, far_clip, focus_distance, principal_point_offset_x, principal_point_offset_y, to_world, film, sampler, medium")?;
        let camera = PerspectiveCamera {
            to_world: to_mat4(to_world),
            tan_half_fov_x: (0.5 * fov_x).to_radians().tan() as f32,
            aspect: aspect as f32,
            near_clip: near_clip as f32,
            far_clip: far_clip as f32,
            principal_point_offset: ppo,
            film_size: Vec2::new(film.width as f32, film.height as f32),
        };
        Ok((camera, medium, film, sampler))
    }

    /// A scene without a sensor: the perspective camera Mitsuba 2 (and Mitsuba 3 before
    /// 3.0.0, `Scene::Scene` in `src/render/scene.cpp` until commit 1279b88) added, with a
    /// warning: fov 45° (along x), looking along +z from below the scene's bounding box
    /// at the distance where its largest extent fills the fov, centred on the box in x
    /// and y; near clip distance/100, far clip 5·extent + distance; the default hdrfilm
    /// (768 × 576, gaussian) and independent sampler (4 spp). Without shapes, at the
    /// origin with the default clip planes. Computed in single precision, as Mitsuba's.
    /// Mitsuba 3.0 and later refuse such a file ("No sensor specified").
    pub(super) fn default_sensor(&mut self) -> (PerspectiveCamera, Film, SamplerSpec) {
        let film = default_film();
        let bounds = self
            .geometries
            .iter()
            .fold(Bounds::EMPTY, |b, g| b.union(&g.bounds()));
        let (to_world, near_clip, far_clip, placed) = if bounds.is_empty() {
            (
                Mat4::IDENTITY,
                1e-2,
                1e4,
                "at the origin (the scene has no shapes)".to_string(),
            )
        } else {
            let center = (bounds.min + bounds.max) * 0.5;
            let extents = bounds.max - bounds.min;
            let max_extent = extents.max_element();
            let distance = max_extent / (2.0 * (45f32 * 0.5 * std::f32::consts::PI / 180.0).tan());
            let origin = Vec3::new(center.x, center.y, bounds.min.z - distance);
            (
                Mat4::from_translation(origin),
                distance / 100.0,
                max_extent * 5.0 + distance,
                format!("at {origin}, looking along +z at the scene's bounding box"),
            )
        };
        self.warnings.push(format!(
            "the scene has no <sensor>: rendering from the camera Mitsuba 2 added (perspective, fov 45, {placed}, 768 x 576 film, 4 spp); Mitsuba 3 refuses a file without a sensor"
        ));
        let aspect = film.width as f32 / film.height as f32;
        let camera = PerspectiveCamera {
            to_world,
            tan_half_fov_x: (0.5 * 45f64).to_radians().tan() as f32,
            aspect,
            near_clip,
            far_clip,
            principal_point_offset: Vec2::ZERO,
            film_size: Vec2::new(film.width as f32, film.height as f32),
        };
        (camera, film, SamplerSpec::DEFAULT)
    }

    pub(super) fn film(&self, id: ObjId) -> Result<Film> {
        let p = Props::new(self.desc, id);
        if p.obj.plugin != "hdrfilm" {
            return Err(unsupported(&p, "film", "hdrfilm"));
        }
        let width = p.int("width", 768)?;
        let height = p.int("height", 576)?;
        // 1 << 15 per side is far beyond any render this machine can hold; refuse early.
        const MAX_SIDE: i64 = 1 << 15;
        if !(1..=MAX_SIDE).contains(&width) || !(1..=MAX_SIDE).contains(&height) {
            return Err(p.error(format!(
                "film size {width} x {height}: width and height must be in [1, {MAX_SIDE}]"
            )));
        }
        let cx = p.int("crop_offset_x", 0)?;
        let cy = p.int("crop_offset_y", 0)?;
        let cw = p.int("crop_width", width)?;
        let ch = p.int("crop_height", height)?;
        if cx < 0 || cy < 0 || cw < 1 || ch < 1 || cx + cw > width || cy + ch > height {
            return Err(p.error(format!(
                "crop window ({cx}, {cy}) + ({cw} x {ch}) does not fit the {width} x {height} film"
            )));
        }
        // The accumulation buffer holds 16 bytes per pixel (RGB sum + weight): refuse
        // up front what would not fit rather than abort on allocation.
        const MAX_PIXELS: i64 = 1 << 27;
        if cw * ch > MAX_PIXELS {
            return Err(p.error(format!(
                "film (crop) size {cw} x {ch} = {} pixels needs {:.1} GiB to accumulate; the limit is {MAX_PIXELS} pixels",
                cw * ch,
                (cw * ch * 16) as f64 / (1u64 << 30) as f64
            ))
            .with_hint("render a smaller film, or a crop window of it"));
        }
        let name = p.string("pixel_format", "rgb")?.to_ascii_lowercase();
        let pixel_format = PixelFormat::ALL
            .into_iter()
            .find(|f| f.name() == name)
            .ok_or_else(|| {
                p.error(format!("pixel_format \"{name}\" is not supported"))
                    .with_hint("use rgb, rgba, luminance or luminance_alpha (Mitsuba's xyz and xyza are not written by mediareg)")
            })?;
        let name = p
            .string("component_format", "float16")?
            .to_ascii_lowercase();
        let component_format = ComponentFormat::ALL
            .into_iter()
            .find(|f| f.name() == name)
            .ok_or_else(|| {
                p.error(format!("component_format \"{name}\" is not supported"))
                    .with_hint("use float16, float32 or uint32 (as Mitsuba 3)")
            })?;
        let file_format = p.string("file_format", "openexr")?.to_ascii_lowercase();
        if !["openexr", "exr"].contains(&file_format.as_str()) {
            return Err(p.error(format!(
                "file_format \"{file_format}\": only openexr is supported"
            )));
        }
        if p.bool("sample_border", false)? {
            return Err(p.error("sample_border = true is not supported"));
        }
        let rfilter = match p.child_of(ObjectKind::Rfilter)? {
            Some(c) => self.rfilter(c.object)?,
            None => Rfilter::Gaussian { stddev: 0.5 },
        };
        p.finish("width, height, crop_offset_x, crop_offset_y, crop_width, crop_height, pixel_format, component_format, file_format, sample_border, rfilter")?;
        Ok(Film {
            width: width as usize,
            height: height as usize,
            crop_offset: (cx as usize, cy as usize),
            crop_size: (cw as usize, ch as usize),
            rfilter,
            pixel_format,
            component_format,
        })
    }

    pub(super) fn rfilter(&self, id: ObjId) -> Result<Rfilter> {
        let p = Props::new(self.desc, id);
        let f = match p.obj.plugin.as_str() {
            "box" => Rfilter::Box,
            "tent" => Rfilter::Tent {
                radius: p.float_in("radius", 1.0, 1e-3, 16.0)? as f32,
            },
            "gaussian" => Rfilter::Gaussian {
                stddev: p.float_in("stddev", 0.5, 1e-3, 4.0)? as f32,
            },
            _ => return Err(unsupported(&p, "rfilter", "box, tent, gaussian")),
        };
        p.finish("radius (tent), stddev (gaussian)")?;
        Ok(f)
    }
}

/// Mitsuba's default `hdrfilm`: 768 × 576 with a gaussian filter.
fn default_film() -> Film {
    Film {
        width: 768,
        height: 576,
        crop_offset: (0, 0),
        crop_size: (768, 576),
        rfilter: Rfilter::Gaussian { stddev: 0.5 },
        pixel_format: PixelFormat::Rgb,
        component_format: ComponentFormat::Float16,
    }
}
