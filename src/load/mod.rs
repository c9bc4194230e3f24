//! Mitsuba 3 plugins → render state: [`build_scene`] translates a
//! [`SceneDescription`] into the plain objects a [`Scene`] is made of, one file per
//! plugin kind (`integrator`, `sensor`, `shape`, `bsdf`, `texture`, `emitter`,
//! `medium`), each reading its properties (Mitsuba's names and defaults, through
//! `props`; spectra through `spectrum`) and failing on anything it does not
//! understand; [`Scene::new`] then prepares them for rendering.

mod bsdf;
pub mod conductor_ior;
mod emitter;
mod heterogeneous;
mod instance;
mod integrator;
mod medium;
pub mod props;
pub mod sampler;
mod sensor;
mod shape;
pub mod spectrum;
mod texture;
mod volume;

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use glam::{DMat4, Mat4};

use crate::bsdf::Bsdf;
use crate::emitter::Emitter;
use crate::error::{Result, SceneError};
use crate::geometry::mesh::RawMesh;
use crate::geometry::shape::Geometry;
use crate::medium::Medium;
use crate::scene::shot::Shot;
use crate::scene::{IntegratorKind, IntegratorSettings, Scene, SceneParts, ShapeInfo};
use crate::xml::description::{ObjId, ObjectKind, SceneDescription};
use crate::xml::LoadOptions;
use props::Props;

pub use emitter::UNIFORM_SPECTRUM_RGB;
pub use shape::mesh_files_read;

/// The objects translated so far, in `Scene`'s order, and the ids they were declared
/// under (a `<ref>` names one); shared by the per-plugin files.
struct Builder<'a> {
    desc: &'a SceneDescription,
    bsdfs: Vec<Bsdf>,
    bsdf_ids: HashMap<ObjId, u32>,
    media: Vec<Medium>,
    medium_ids: HashMap<ObjId, u32>,
    geometries: Vec<Geometry>,
    /// Mesh files read so far, by (plugin, path, shape_index): read once, cloned per use.
    meshes: HashMap<(String, PathBuf, u32), RawMesh>,
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
    /// Which of the file's `<sensor>`s to render, in file order (`--sensor N`); None: the
    /// first, as Mitsuba's `mitsuba` renders, with a warning where there are several.
    pub sensor: Option<usize>,
    /// One of mediareg's integrators (`--integrator NAME`: path, volpath, direct) in place
    /// of the file's.
    pub integrator: Option<String>,
}

/// Loads and builds a scene.
pub fn load_scene(path: &Path, opts: &LoadOptions, overrides: &BuildOverrides) -> Result<Scene> {
    let desc = crate::xml::load_file(path, opts)?;
    build_scene(&desc, overrides)
}

pub fn build_scene(desc: &SceneDescription, overrides: &BuildOverrides) -> Result<Scene> {
    let mut b = Builder {
        desc,
        bsdfs: Vec::new(),
        bsdf_ids: HashMap::new(),
        media: Vec::new(),
        medium_ids: HashMap::new(),
        geometries: Vec::new(),
        meshes: HashMap::new(),
        shapes: Vec::new(),
        emitters: Vec::new(),
        environment: None,
        warnings: desc.notes.clone(),
    };
    let root = Props::new(desc, desc.root);

    let file_integrator = root.child_of(ObjectKind::Integrator)?;
    let integrator = match (&overrides.integrator, file_integrator) {
        (Some(name), c) => b.override_integrator(name, c.map(|c| c.object))?,
        (None, Some(c)) => b.integrator(c.object)?,
        (None, None) => IntegratorSettings {
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
        b.top_level_shape(c.object)?;
    }
    for c in root.children_of(ObjectKind::Emitter) {
        // An area light declared here with an id belongs to the shapes that refer to it.
        if !(desc.object(c.object).plugin == "area" && is_referenced(desc, c.object)) {
            b.emitter(c.object, None)?;
        }
    }
    // Top-level BSDFs, media and phase functions are declarations for <ref> (before or
    // after the <ref>): build them so they are validated even when unused.
    for c in root.children_of(ObjectKind::Bsdf) {
        b.bsdf(c.object)?;
    }
    for c in root.children_of(ObjectKind::Medium) {
        b.medium(c.object)?;
    }
    for c in root.children_of(ObjectKind::Phase) {
        b.phase(c.object)?;
    }
    // So are a sensor's parts (Mitsuba builds every top-level object).
    for c in root.children_of(ObjectKind::Sampler) {
        b.sampler(c.object)?;
    }
    for c in root.children_of(ObjectKind::Film) {
        b.film(c.object)?;
    }
    for c in root.children_of(ObjectKind::Rfilter) {
        b.rfilter(c.object)?;
    }
    let sensors = root.children_of(ObjectKind::Sensor);
    let chosen_sensor = overrides.sensor.unwrap_or(0);
    if chosen_sensor > 0 && chosen_sensor >= sensors.len() {
        return Err(root
            .error(format!(
                "--sensor {}: the scene has {} <sensor>s",
                chosen_sensor,
                sensors.len()
            ))
            .with_hint("sensors are numbered from 0 in file order"));
    }
    let (camera, camera_medium, mut film, sampler) = if sensors.is_empty() {
        let (camera, film, sampler) = b.default_sensor();
        (camera, None, film, sampler)
    } else {
        // Mitsuba builds every sensor: check them all, render the chosen one.
        let mut chosen = None;
        for (i, s) in sensors.iter().enumerate() {
            let built = b.sensor(s.object)?;
            if i == chosen_sensor {
                chosen = Some(built);
            }
        }
        // Said only where no sensor was asked for: one asked for is no surprise.
        if sensors.len() > 1 && overrides.sensor.is_none() {
            b.warnings.push(format!(
                "{}: rendering sensor 0 of the scene's {} (--sensor N picks another, 0 = the first in the file)",
                sensors[0].loc,
                sensors.len()
            ));
        }
        chosen.expect("the chosen sensor is in range")
    };
    b.warnings.extend(sampler.note.clone());
    let spp = match overrides.spp {
        Some(n) => {
            let rounded = sampler.kind.sample_count(n);
            if rounded != n {
                b.warnings.push(format!(
                    "--spp {n}: sampler \"{}\" renders {rounded} samples per pixel, as Mitsuba 3 rounds it",
                    sampler.kind.name()
                ));
            }
            rounded
        }
        None => sampler.spp,
    };
    if let Some([x, y, w, h]) = overrides.crop {
        if w == 0 || h == 0 || x + w > film.width || y + h > film.height {
            return Err(SceneError::new(
                None,
                format!(
                    "the crop window {x},{y},{w},{h} does not fit the {} x {} film",
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
    root.finish(
        "integrator, sensor, shape, emitter, bsdf, medium, phase, texture, sampler, film, rfilter",
    )?;
    b.warnings.append(&mut desc.unread_legacy.borrow_mut());
    // The mesh files' copies go before the accelerator is built, not after.
    b.meshes = HashMap::new();

    Ok(Scene::new(SceneParts {
        geometries: b.geometries,
        shapes: b.shapes,
        bsdfs: b.bsdfs,
        emitters: b.emitters,
        environment: b.environment,
        media: b.media,
        camera_medium,
        shot: Shot {
            camera,
            film,
            spp,
            seed: overrides.seed.unwrap_or(sampler.seed),
        },
        integrator,
        warnings: b.warnings,
    }))
}

fn unsupported(p: &Props, kind: &str, supported: &str) -> SceneError {
    SceneError::at(
        p.loc(),
        format!("unsupported {kind} plugin \"{}\"", p.obj.plugin),
    )
    .with_hint(format!("mediareg supports {kind} plugins: {supported}"))
}

/// Whether any object other than the root holds `id` (nested or by `<ref>`).
fn is_referenced(desc: &SceneDescription, id: ObjId) -> bool {
    desc.objects
        .iter()
        .enumerate()
        .any(|(i, o)| i != desc.root && o.children.iter().any(|c| c.object == id))
}

fn to_mat4(m: DMat4) -> Mat4 {
    m.as_mat4()
}
