//! `SceneDescription` → `Scene`: one function per plugin, each reading its properties
//! (Mitsuba's names and defaults) and failing on anything it does not understand.

use std::collections::HashMap;
use std::path::Path;
use std::sync::Arc;

use glam::{DMat4, DVec3, Mat4, Vec2, Vec3, Vec3A};

use super::camera::{fov_x_degrees, PerspectiveCamera};
use super::film::{Film, Rfilter};
use super::props::Props;
use super::shot::Shot;
use super::{IntegratorKind, IntegratorSettings, Scene, ShapeInfo};
use crate::bsdf::dielectric::named_ior;
use crate::bsdf::microfacet::{Microfacet, MicrofacetType};
use crate::bsdf::{
    Bsdf, Conductor, Dielectric, Plastic, RoughConductor, RoughDielectric, RoughPlastic,
    ThinDielectric,
};
use crate::emitter::envmap::EnvMap;
use crate::emitter::selection::EmitterSelection;
use crate::emitter::{BSphere, Emitter, Spot};
use crate::error::{err_at, Result, SceneError};
use crate::geometry::accel::{Accel, ShadowPass};
use crate::geometry::clearance::Clearance;
use crate::geometry::convex::ConvexBoundary;
use crate::geometry::cuboid::Cuboid;
use crate::geometry::mesh::{cube, read_obj, read_ply, TriangleMesh};
use crate::geometry::serialized::read_serialized;
use crate::geometry::shape::{Geometry, Planar, Sphere};
use crate::geometry::Bounds;
use crate::geometry::RAY_EPSILON;
use crate::medium::{HomogeneousMedium, Phase};
use crate::scene::spectrum::SpectrumUse;
use crate::texture::bitmap::{read_texels, Bitmap, FilterType, WrapMode};
use crate::texture::Texture;
use crate::xml::description::{ObjId, ObjectKind, SceneDescription, Value};
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

/// The largest |coordinate| a shape may reach.
const MAX_COORDINATE: f32 = 1e12;

struct Builder<'a> {
    desc: &'a SceneDescription,
    bsdfs: Vec<Bsdf>,
    bsdf_ids: HashMap<ObjId, u32>,
    media: Vec<HomogeneousMedium>,
    medium_ids: HashMap<ObjId, u32>,
    geometries: Vec<Geometry>,
    shapes: Vec<ShapeInfo>,
    emitters: Vec<Emitter>,
    environment: Option<u32>,
    warnings: Vec<String>,
}

/// Options from the command line that override the file.
#[derive(Clone, Debug, Default)]
pub struct BuildOverrides {
    pub spp: Option<u32>,
    pub seed: Option<u64>,
    /// A crop window `[x, y, width, height]` of the full film, replacing the file's
    /// (Mitsuba's `crop_offset_x/y`, `crop_width/height`).
    pub crop: Option<[usize; 4]>,
}

pub fn build_scene(desc: &SceneDescription, overrides: &BuildOverrides) -> Result<Scene> {
    let mut b = Builder {
        desc,
        bsdfs: Vec::new(),
        bsdf_ids: HashMap::new(),
        media: Vec::new(),
        medium_ids: HashMap::new(),
        geometries: Vec::new(),
        shapes: Vec::new(),
        emitters: Vec::new(),
        environment: None,
        warnings: desc.notes.clone(),
    };
    let root = Props::new(desc, desc.root);

    let integrator = match root.child_of(ObjectKind::Integrator)? {
        Some(c) => b.integrator(c.object)?,
        None => IntegratorSettings {
            kind: IntegratorKind::Path,
            max_depth: u32::MAX,
            rr_depth: 5,
            hide_emitters: false,
            moment_aovs_dropped: false,
        },
    };
    if integrator.moment_aovs_dropped {
        b.warnings.push(
            "integrator \"moment\": the image is its nested integrator's; the second-moment AOVs Mitsuba adds to the EXR are not written".into(),
        );
    }
    for c in root.children_of(ObjectKind::Shape) {
        b.shape(c.object)?;
    }
    for c in root.children_of(ObjectKind::Emitter) {
        b.emitter(c.object, None)?;
    }
    // Top-level BSDFs and media are declarations for <ref>: build them so they are
    // validated even when unused.
    for c in root.children_of(ObjectKind::Bsdf) {
        b.bsdf(c.object)?;
    }
    for c in root.children_of(ObjectKind::Medium) {
        b.medium(c.object)?;
    }
    let sensors = root.children_of(ObjectKind::Sensor);
    let sensor = match sensors.as_slice() {
        [] => {
            return Err(root
                .error("the scene has no <sensor>")
                .with_hint("add <sensor type=\"perspective\"> with a <film type=\"hdrfilm\">"))
        }
        [s] => s.object,
        [_, second, ..] => return err_at(&second.loc, "only one <sensor> per scene is supported"),
    };
    let (camera, camera_medium, mut film, spp, seed) = b.sensor(sensor)?;
    if let Some([x, y, w, h]) = overrides.crop {
        if w == 0 || h == 0 || x + w > film.width || y + h > film.height {
            return Err(SceneError::new(
                None,
                format!(
                    "--crop {x},{y},{w},{h} does not fit the {} x {} film",
                    film.width, film.height
                ),
            )
            .with_hint("give X,Y,W,H with W, H > 0 and X + W, Y + H within the film"));
        }
        film.crop_offset = (x, y);
        film.crop_size = (w, h);
    }
    // Top-level textures are used where a bsdf refers to them by id.
    root.children_of(ObjectKind::Texture);
    root.finish("integrator, sensor, shape, emitter, bsdf, medium, texture")?;

    let refs: Vec<&Geometry> = b.geometries.iter().collect();
    let accel = Accel::build(&refs);
    // The clearance saves ray casts; where a cast is a few analytic tests (no BVH), the
    // two grid lookups a scattering cost more than the cast, and the shadow roulette's
    // variance is not paid back: the furnace sphere lost 20% of its efficiency with it,
    // and the medium cube (a box and two rectangles) about 20%.
    let clearance = if b.media.is_empty()
        || integrator.kind != IntegratorKind::Volpath
        || !accel.traverses_bvh()
    {
        Clearance::none()
    } else {
        // Media lie inside the shapes that have an interior medium, unless a medium is
        // outside some shape or around the camera: then it may fill the whole scene.
        let unbounded = camera_medium.is_some() || b.shapes.iter().any(|s| s.exterior.is_some());
        let region = if unbounded {
            accel.bounds
        } else {
            b.shapes
                .iter()
                .zip(&b.geometries)
                .filter(|(s, _)| s.interior.is_some())
                .fold(Bounds::EMPTY, |r, (_, g)| r.union(&g.bounds()))
        };
        Clearance::build(&b.geometries, region, accel.bounds)
    };
    // Mitsuba's bounding sphere of the scene's bounding box, padded by RayEpsilon.
    let bsphere = if accel.bounds.is_empty() {
        BSphere {
            center: Vec3A::ZERO,
            radius: RAY_EPSILON,
        }
    } else {
        let c = (accel.bounds.min + accel.bounds.max) * 0.5;
        let r = (accel.bounds.max - c).length() * (1.0 + RAY_EPSILON);
        BSphere {
            center: c,
            radius: r.max(RAY_EPSILON),
        }
    };
    let offset_scale = if accel.bounds.is_empty() {
        1.0
    } else {
        let half = (accel.bounds.max - accel.bounds.min).max_element() * 0.5;
        if half.is_finite() && half > 0.0 {
            half
        } else {
            1.0
        }
    };
    let shadow_pass: Vec<ShadowPass> = b
        .shapes
        .iter()
        .map(|info| b.bsdfs[info.bsdf as usize].shadow_pass())
        .collect();
    // volpath and path leave a uniform sky to BSDF and phase sampling; direct keeps it (its
    // emitter samples may be all it takes). See EmitterSelection::new.
    let emitter_selection = EmitterSelection::new(
        &b.emitters,
        &b.geometries,
        matches!(
            integrator.kind,
            IntegratorKind::Volpath | IntegratorKind::Path
        ),
    );
    let area_emitter_bounds =
        area_emitters_within_media(&b.emitters, &b.geometries, &b.shapes, b.media.len());
    let emitters_unreachable = media_sealed_from_emitters(
        &b.emitters,
        &b.geometries,
        &b.shapes,
        &shadow_pass,
        b.media.len(),
    );
    let convex_media = (0..b.media.len() as u32)
        .map(|mi| convex_medium(mi, camera_medium, &b.geometries, &b.shapes, &accel))
        .collect();
    Ok(Scene {
        convex_media,
        emitters_unreachable,
        shadow_pass,
        emitter_selection,
        area_emitter_bounds,
        geometries: b.geometries,
        shapes: b.shapes,
        bsdfs: b.bsdfs,
        emitters: b.emitters,
        environment: b.environment,
        media: b.media,
        accel,
        clearance,
        bsphere,
        offset_scale,
        warnings: b.warnings,
        camera_medium,
        shot: Shot {
            camera,
            film,
            spp: overrides.spp.unwrap_or(spp),
            seed: overrides.seed.unwrap_or(seed),
        },
        integrator,
        ray_log: None,
    })
}

fn unsupported(p: &Props, kind: &str, supported: &str) -> SceneError {
    SceneError::at(
        p.loc(),
        format!("unsupported {kind} plugin \"{}\"", p.obj.plugin),
    )
    .with_hint(format!("mediareg supports {kind} plugins: {supported}"))
}

fn to_mat4(m: DMat4) -> Mat4 {
    m.as_mat4()
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
    fn moment_integrator(&self, p: Props) -> Result<IntegratorSettings> {
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

    fn integrator(&self, id: ObjId) -> Result<IntegratorSettings> {
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

    fn sensor(&mut self, id: ObjId) -> Result<(PerspectiveCamera, Option<u32>, Film, u32, u64)> {
        let p = Props::new(self.desc, id);
        if p.obj.plugin != "perspective" {
            return Err(unsupported(&p, "sensor", "perspective"));
        }
        let film = match p.child_of(ObjectKind::Film)? {
            Some(c) => self.film(c.object)?,
            None => Film {
                width: 768,
                height: 576,
                crop_offset: (0, 0),
                crop_size: (768, 576),
                rfilter: Rfilter::Gaussian { stddev: 0.5 },
            },
        };
        let (spp, seed) = match p.child_of(ObjectKind::Sampler)? {
            Some(c) => self.sampler(c.object)?,
            None => (4, 0),
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
        Ok((camera, medium, film, spp, seed))
    }

    fn film(&self, id: ObjId) -> Result<Film> {
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
        let pixel_format = p.string("pixel_format", "rgb")?.to_ascii_lowercase();
        if pixel_format != "rgb" {
            return Err(p.error(format!(
                "pixel_format \"{pixel_format}\" is not supported: mediareg writes RGB (use \"rgb\")"
            )));
        }
        // Storage precision only: mediareg always writes float32.
        let component_format = p
            .string("component_format", "float16")?
            .to_ascii_lowercase();
        if !["float16", "float32"].contains(&component_format.as_str()) {
            return Err(p.error(format!(
                "component_format \"{component_format}\": use float16 or float32"
            )));
        }
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
        })
    }

    fn rfilter(&self, id: ObjId) -> Result<Rfilter> {
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

    fn sampler(&self, id: ObjId) -> Result<(u32, u64)> {
        let p = Props::new(self.desc, id);
        if p.obj.plugin != "independent" {
            return Err(unsupported(&p, "sampler", "independent"));
        }
        let spp = p.int("sample_count", 4)?;
        if !(1..=1 << 24).contains(&spp) {
            return Err(p.error(format!("sample_count = {spp}: must be in [1, {}]", 1 << 24)));
        }
        let seed = p.int("seed", 0)?;
        if seed < 0 {
            return Err(p.error(format!("seed = {seed}: must be ≥ 0")));
        }
        p.finish("sample_count, seed")?;
        Ok((spp as u32, seed as u64))
    }

    fn shape(&mut self, id: ObjId) -> Result<()> {
        let p = Props::new(self.desc, id);
        let to_world = p.transform("to_world")?;
        let flip_normals = p.bool("flip_normals", false)?;
        let geometry = match p.obj.plugin.as_str() {
            "ply" | "obj" | "serialized" => {
                let (name, loc) = p
                    .string_opt("filename")?
                    .ok_or_else(|| p.error("missing the \"filename\" property"))?;
                let path = resolve_path(&self.desc.search_path, name).ok_or_else(|| {
                    let dirs: Vec<String> = self.desc.search_path.iter().map(|d| d.display().to_string()).collect();
                    SceneError::at(loc, format!("mesh file \"{name}\" not found"))
                        .with_hint(format!(
                            "searched: {}; add its folder with -a DIR (for the Stanford meshes run scripts/fetch_meshes)",
                            dirs.join(", ")
                        ))
                })?;
                let face_normals = p.bool("face_normals", false)?;
                let mut raw = match p.obj.plugin.as_str() {
                    "ply" => read_ply(&path),
                    "obj" => read_obj(&path),
                    _ => {
                        let index = p.int("shape_index", 0)?;
                        let index = u32::try_from(index).map_err(|_| {
                            p.error(format!("shape_index = {index}: must be 0 or more"))
                        })?;
                        read_serialized(&path, index)
                    }
                }
                // Name the scene line of the <shape> too, not only the mesh file.
                .map_err(|e| SceneError::at(p.loc(), format!("{}: {e}", p.obj.label())))?;
                // Mitsuba flips an OBJ's v (v ↦ 1 − v) unless told not to.
                if p.obj.plugin == "obj" && p.bool("flip_tex_coords", true)? {
                    if let Some(uvs) = &mut raw.uvs {
                        uvs.iter_mut().for_each(|t| t.y = 1.0 - t.y);
                    }
                }
                self.warnings
                    .extend(raw.warnings.iter().map(|w| format!("{}: {w}", p.loc())));
                Geometry::Mesh(TriangleMesh::new(
                    raw,
                    &to_mat4(to_world),
                    face_normals,
                    flip_normals,
                    Path::new(&path),
                )?)
            }
            "cube" => {
                let to_world = to_mat4(to_world);
                let mut mesh =
                    TriangleMesh::new(cube(), &to_world, true, flip_normals, Path::new("cube"))?;
                mesh.cube_to_world = Some(to_world);
                Geometry::Mesh(mesh)
            }
            "sphere" => {
                let center = p.point_opt("center")?.unwrap_or(DVec3::ZERO);
                let radius = p.float("radius", 1.0)?;
                if radius <= 0.0 {
                    return Err(p.error(format!("radius = {radius}: must be > 0")));
                }
                // Mitsuba: to_world · translate(center) · scale(radius); only similarity
                // transforms keep it a sphere.
                let c = to_world.transform_point3(center);
                let axes =
                    [DVec3::X, DVec3::Y, DVec3::Z].map(|a| to_world.transform_vector3(a).length());
                if (axes[0] - axes[1]).abs() > 1e-6 * axes[0]
                    || (axes[0] - axes[2]).abs() > 1e-6 * axes[0]
                {
                    return Err(p.error("to_world scales the sphere non-uniformly; use a ply/obj mesh for an ellipsoid"));
                }
                let linear = glam::DMat3::from_mat4(to_world) / axes[0];
                Geometry::Sphere(Sphere {
                    center: c.as_vec3().into(),
                    radius: (radius * axes[0]) as f32,
                    flip_normals,
                    axes: glam::Mat3A::from(linear.as_mat3()),
                })
            }
            "rectangle" => Geometry::Planar(Planar::new(to_mat4(to_world), flip_normals, false)),
            "disk" => Geometry::Planar(Planar::new(to_mat4(to_world), flip_normals, true)),
            _ => {
                return Err(unsupported(
                    &p,
                    "shape",
                    "ply, obj, serialized, sphere, cube, rectangle, disk",
                ))
            }
        };
        // Single-precision ray tracing needs finite coordinates of sane magnitude (at 1e12
        // one f32 step is 6e4 units; box areas overflow near 1e19 and break the BVH).
        let b = geometry.bounds();
        let mut reach = b.min.abs().max(b.max.abs()).max_element();
        if let Geometry::Mesh(m) = &geometry {
            // Bounds skip NaN; a NaN vertex (binary PLY) must not.
            if m.positions.iter().any(|p| !p.is_finite()) {
                reach = f32::NAN;
            }
        }
        if !b.is_empty() && (reach.is_nan() || reach > MAX_COORDINATE) {
            return Err(p.error(format!(
                "the shape reaches {reach:e} from the origin: coordinates must be finite and within ±{MAX_COORDINATE:e}; check its to_world, radius or the mesh's units"
            )));
        }
        let shape_index = self.geometries.len() as u32;
        let emitter = match p.child_of(ObjectKind::Emitter)? {
            Some(c) => Some(self.emitter(c.object, Some(shape_index))?),
            None => None,
        };
        let bsdf = match p.child_of(ObjectKind::Bsdf)? {
            Some(c) => self.bsdf(c.object)?,
            None => {
                // Mitsuba's default: diffuse 0.5, or black for an emitter.
                let r = if emitter.is_some() { 0.0 } else { 0.5 };
                self.bsdfs.push(Bsdf::Diffuse {
                    reflectance: Texture::Constant(Vec3::splat(r)),
                });
                self.bsdfs.len() as u32 - 1
            }
        };
        let interior = match p.named_child_of("interior", ObjectKind::Medium)? {
            Some(c) => Some(self.medium(c.object)?),
            None => None,
        };
        let exterior = match p.named_child_of("exterior", ObjectKind::Medium)? {
            Some(c) => Some(self.medium(c.object)?),
            None => None,
        };
        let names = match p.obj.plugin.as_str() {
            "ply" => "filename, to_world, face_normals, flip_normals, bsdf, emitter, interior, exterior",
            "obj" => "filename, to_world, face_normals, flip_normals, flip_tex_coords, bsdf, emitter, interior, exterior",
            "serialized" => "filename, shape_index, to_world, face_normals, flip_normals, bsdf, emitter, interior, exterior",
            "sphere" => "center, radius, to_world, flip_normals, bsdf, emitter, interior, exterior",
            _ => "to_world, flip_normals, bsdf, emitter, interior, exterior",
        };
        // Texture coordinates exist on meshes and rectangles only (Mitsuba's cube, sphere
        // and disk have their own, not implemented here).
        if self.bsdfs[bsdf as usize].is_textured()
            && matches!(p.obj.plugin.as_str(), "cube" | "sphere" | "disk")
        {
            return Err(p.error(format!(
                "a textured bsdf on a \"{}\" shape is not supported yet (texture coordinates exist on ply/obj meshes and rectangles)",
                p.obj.plugin
            )));
        }
        // Anisotropy is oriented by ∂p/∂u, which mediareg follows on meshes, rectangles,
        // disks and spheres; Mitsuba's cube has its own texture coordinates, which
        // mediareg's cube lacks.
        let tangent_frame = self.bsdfs[bsdf as usize].is_anisotropic();
        if tangent_frame && p.obj.plugin == "cube" {
            return Err(p.error(format!(
                "anisotropic roughness on a \"{}\" shape is not supported yet (it follows the surface's ∂p/∂u, which mediareg has on ply/obj/serialized meshes, rectangles, disks and spheres)",
                p.obj.plugin
            )));
        }
        // An area light is sampled with pdf 1 / area.
        if emitter.is_some() && !(geometry.area() > 0.0 && geometry.area().is_finite()) {
            return Err(p.error(format!(
                "the area light's shape has area {}: it must be finite and > 0; check its to_world scale",
                geometry.area()
            )));
        }
        p.finish(names)?;
        self.geometries.push(geometry);
        self.shapes.push(ShapeInfo {
            bsdf,
            emitter,
            interior,
            exterior,
            tangent_frame,
        });
        Ok(())
    }

    fn bsdf(&mut self, id: ObjId) -> Result<u32> {
        if let Some(&i) = self.bsdf_ids.get(&id) {
            return Ok(i);
        }
        let b = self.bsdf_value(id)?;
        self.bsdfs.push(b);
        let i = self.bsdfs.len() as u32 - 1;
        self.bsdf_ids.insert(id, i);
        Ok(i)
    }

    /// A reflectance in [0, 1]: a constant, or a nested (or referenced) `<texture>`.
    fn reflectance(&self, p: &Props, name: &str, default: Vec3) -> Result<Texture> {
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

    /// Mitsuba's `bitmap` as a reflectance: `filename` (PNG or OpenEXR), `filter_type`
    /// (bilinear), `wrap_mode` (repeat), `raw` (false), `to_uv`; `format` and `accel`
    /// only choose Mitsuba's storage and are read. Texels must lie in [0, 1].
    fn bitmap(&self, t: Props, name: &str) -> Result<Texture> {
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

    fn bsdf_value(&self, id: ObjId) -> Result<Bsdf> {
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
            _ => {
                return Err(unsupported(
                    &p,
                    "bsdf",
                    "null, diffuse, dielectric, thindielectric, conductor, plastic, roughdielectric, roughconductor, roughplastic, twosided",
                ))
            }
        };
        Ok(b)
    }

    /// `envmap`: an OpenEXR latitude-longitude image, `scale`, a rotation `to_world`;
    /// `mis_compensation` only changes Mitsuba's sampling, not the image (read, unused).
    fn envmap(&self, p: &Props) -> Result<EnvMap> {
        let Some((name, loc)) = p.string_opt("filename")? else {
            return Err(p.error("envmap needs a filename (an OpenEXR latitude-longitude image)"));
        };
        let path = resolve_path(&self.desc.search_path, name).ok_or_else(|| {
            SceneError::at(loc, format!("environment map \"{name}\" not found"))
                .with_hint("add its folder with -a DIR")
        })?;
        if path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase)
            .as_deref()
            != Some("exr")
        {
            return Err(SceneError::at(
                loc,
                format!("environment map \"{name}\": only OpenEXR (.exr) images are supported"),
            ));
        }
        let img = crate::image::read_exr(&path)
            .map_err(|e| SceneError::at(loc, format!("environment map \"{name}\": {e:#}")))?;
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

    fn emitter(&mut self, id: ObjId, shape: Option<u32>) -> Result<u32> {
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

    fn medium(&mut self, id: ObjId) -> Result<u32> {
        if let Some(&i) = self.medium_ids.get(&id) {
            return Ok(i);
        }
        let p = Props::new(self.desc, id);
        if p.obj.plugin != "homogeneous" {
            return Err(unsupported(&p, "medium", "homogeneous").with_hint(
                "heterogeneous (grid) media are out of scope; mediareg supports homogeneous media",
            ));
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
        let phase = match p.child_of(ObjectKind::Phase)? {
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
        };
        let medium_id = p.obj.id.clone();
        p.finish("albedo, sigma_t, scale, sample_emitters, has_spectral_extinction, phase")?;
        self.media.push(HomogeneousMedium {
            albedo,
            sigma_t: sigma_t * scale as f32,
            phase,
            sample_emitters,
            id: medium_id,
        });
        let i = self.media.len() as u32 - 1;
        self.medium_ids.insert(id, i);
        Ok(i)
    }
}

/// A conductor's complex index η + iκ: `eta` and `k` (float, rgb or spectrum,
/// unbounded), or `material` "none" (η 0, κ 1: an ideal mirror). Mitsuba's named
/// materials (spectral tables) are refused.
fn conductor_ior(p: &Props) -> Result<(Vec3, Vec3)> {
    let material = p.string("material", "none")?;
    if !p.has("eta") && material != "none" {
        return Err(p.error(format!(
            "conductor material \"{material}\": the named materials (spectral IOR tables) are not supported yet; give eta and k (<float> or <rgb>), or material \"none\""
        )));
    }
    if material != "none" {
        return Err(p.error("give either eta and k, or material, not both"));
    }
    let eta = p.color_nonneg_as("eta", Vec3::ZERO, SpectrumUse::Unbounded)?;
    let k = p.color_nonneg_as("k", Vec3::ONE, SpectrumUse::Unbounded)?;
    Ok((eta, k))
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
            p.float_in("alpha_u", 0.1, 0.0, 1e3)?,
            p.float_in("alpha_v", 0.1, 0.0, 1e3)?,
        )
    } else {
        let a = p.float_in("alpha", 0.1, 0.0, 1e3)?;
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

/// A texture's `to_uv`, Mitsuba's 2D affine map: the 4×4 matrix's upper-left 2×2 and its
/// translation, as rows (a, b, tx) and (c, d, ty).
fn to_uv(t: &Props) -> Result<[[f32; 3]; 2]> {
    let m = t.transform("to_uv")?;
    Ok([
        [m.x_axis.x as f32, m.y_axis.x as f32, m.w_axis.x as f32],
        [m.x_axis.y as f32, m.y_axis.y as f32, m.w_axis.y as f32],
    ])
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

/// The box of the shapes medium `mi` fills, or `None` where it is unbounded (outside
/// some shape, or inside none, as a camera's medium may be).
fn medium_region(mi: u32, geometries: &[Geometry], shapes: &[ShapeInfo]) -> Option<Bounds> {
    if shapes.iter().any(|s| s.exterior == Some(mi)) {
        return None;
    }
    let mut filled = shapes
        .iter()
        .zip(geometries)
        .filter(|(s, _)| s.interior == Some(mi))
        .peekable();
    filled.peek()?;
    Some(filled.fold(Bounds::EMPTY, |r, (_, g)| r.union(&g.bounds())))
}

/// The closed convex shape medium `mi` fills, where rays in it need test only that
/// shape (see `geometry::convex`): it fills exactly one shape, a sphere or a cube; it
/// is the exterior of none and not the camera's (so every ray in it starts inside the
/// shape); and no other shape's box meets that shape's box (so no other surface lies
/// inside it).
fn convex_medium(
    mi: u32,
    camera_medium: Option<u32>,
    geometries: &[Geometry],
    shapes: &[ShapeInfo],
    accel: &Accel,
) -> Option<ConvexBoundary> {
    if camera_medium == Some(mi) || shapes.iter().any(|s| s.exterior == Some(mi)) {
        return None;
    }
    let mut filled = (0..shapes.len()).filter(|&i| shapes[i].interior == Some(mi));
    let si = filled.next()?;
    if filled.next().is_some() {
        return None;
    }
    let own = geometries[si].bounds();
    let alone = geometries
        .iter()
        .enumerate()
        .all(|(i, g)| i == si || !g.bounds().overlaps(&own));
    if !alone {
        return None;
    }
    match &geometries[si] {
        Geometry::Sphere(_) => Some(ConvexBoundary::Sphere(si as u32)),
        // The accelerator's box when it tests the cube as one (its hits name the
        // triangles of its copy), else one of its own.
        Geometry::Mesh(m) => match accel.cuboid(si as u32) {
            Some(c) => Some(ConvexBoundary::Box {
                cuboid: Box::new(c.clone()),
                leaf_valid: true,
            }),
            None => Some(ConvexBoundary::Box {
                cuboid: Box::new(Cuboid::new(si as u32, m, m.cube_to_world.as_ref()?)?),
                leaf_valid: false,
            }),
        },
        Geometry::Planar(_) => None,
    }
}

/// Per medium: whether no emitter sample from a point inside it can arrive, so that
/// its vertices need not sample emitters. That holds for a medium that fills the
/// interior of closed shapes (spheres, Mitsuba cubes) whose surfaces all block shadow
/// rays (a glass ball of juice: Mitsuba's shadow rays stop at any non-null surface), is
/// the exterior of none, and holds no emitter (no area emitter's box meets its box, no
/// point or spot light lies in it; the other emitters lie at infinity). Every such
/// sample is 0, and no emitter can be hit from such a vertex without first meeting its
/// boundary, whose BSDF then sets the MIS weights: skipping them changes no estimate.
fn media_sealed_from_emitters(
    emitters: &[Emitter],
    geometries: &[Geometry],
    shapes: &[ShapeInfo],
    shadow_pass: &[ShadowPass],
    n_media: usize,
) -> Vec<bool> {
    let closed = |g: &Geometry| match g {
        Geometry::Sphere(_) => true,
        Geometry::Mesh(m) => m.cube_to_world.is_some(),
        Geometry::Planar(_) => false,
    };
    (0..n_media as u32)
        .map(|mi| {
            let Some(region) = medium_region(mi, geometries, shapes) else {
                return false;
            };
            let sealed = shapes
                .iter()
                .zip(geometries)
                .zip(shadow_pass)
                .filter(|((s, _), _)| s.interior == Some(mi))
                .all(|((_, g), pass)| closed(g) && *pass == ShadowPass::Blocks);
            let inside = |p: Vec3A| region.overlaps(&Bounds { min: p, max: p });
            sealed
                && emitters.iter().all(|e| match e {
                    Emitter::Area { shape, .. } => {
                        !geometries[*shape as usize].bounds().overlaps(&region)
                    }
                    Emitter::Point { position, .. } => !inside(*position),
                    Emitter::Spot(spot) => !inside(spot.position),
                    Emitter::Directional { .. } | Emitter::Constant { .. } | Emitter::EnvMap(_) => {
                        true
                    }
                })
        })
        .collect()
}

/// Per medium, a bounding sphere (centre, radius²) of each area emitter a ray in it may
/// reach without leaving it: every one where the medium is unbounded (outside some
/// shape, or bounded by none, as a camera's medium may be), else those whose box meets
/// the box of the shapes it fills.
fn area_emitters_within_media(
    emitters: &[Emitter],
    geometries: &[Geometry],
    shapes: &[ShapeInfo],
    n_media: usize,
) -> Vec<Vec<(Vec3A, f32)>> {
    let area: Vec<Bounds> = emitters
        .iter()
        .filter_map(|e| match e {
            Emitter::Area { shape, .. } => Some(geometries[*shape as usize].bounds()),
            _ => None,
        })
        .collect();
    (0..n_media as u32)
        .map(|mi| {
            let region = medium_region(mi, geometries, shapes);
            area.iter()
                .filter(|e| region.is_none_or(|r| e.overlaps(&r)))
                .map(|e| {
                    let (centre, r) = e.bounding_sphere();
                    let r = r * (1.0 + 1e-4);
                    (centre, r * r)
                })
                .collect()
        })
        .collect()
}
