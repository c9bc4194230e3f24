//! The scene *description*: what the file says, and nothing more. A tree (really a DAG,
//! because of `<ref>`) of plugin objects with typed properties, each with its position in
//! the source. `load` turns it into render state.

use glam::{DMat4, DVec3};

use crate::error::Loc;

/// Index of an object in `SceneDescription::objects`.
pub type ObjId = usize;

/// The plugin kinds of Mitsuba 3, named by their XML tag.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ObjectKind {
    Scene,
    Integrator,
    Sensor,
    Film,
    Sampler,
    Shape,
    Bsdf,
    Emitter,
    Medium,
    Phase,
    Rfilter,
    Texture,
    Volume,
    Spectrum,
}

impl ObjectKind {
    pub fn from_tag(tag: &str) -> Option<Self> {
        Some(match tag {
            "scene" => Self::Scene,
            "integrator" => Self::Integrator,
            "sensor" => Self::Sensor,
            "film" => Self::Film,
            "sampler" => Self::Sampler,
            "shape" => Self::Shape,
            "bsdf" => Self::Bsdf,
            "emitter" => Self::Emitter,
            "medium" => Self::Medium,
            "phase" => Self::Phase,
            "rfilter" => Self::Rfilter,
            "texture" => Self::Texture,
            "volume" => Self::Volume,
            _ => return None,
        })
    }

    pub fn tag(self) -> &'static str {
        match self {
            Self::Scene => "scene",
            Self::Integrator => "integrator",
            Self::Sensor => "sensor",
            Self::Film => "film",
            Self::Sampler => "sampler",
            Self::Shape => "shape",
            Self::Bsdf => "bsdf",
            Self::Emitter => "emitter",
            Self::Medium => "medium",
            Self::Phase => "phase",
            Self::Rfilter => "rfilter",
            Self::Texture => "texture",
            Self::Volume => "volume",
            Self::Spectrum => "spectrum",
        }
    }
}

/// A typed property value, as written in the file (double precision until build).
#[derive(Clone, Debug, PartialEq)]
pub enum Value {
    Float(f64),
    Integer(i64),
    Boolean(bool),
    String(String),
    Point(DVec3),
    Vector(DVec3),
    Rgb(DVec3),
    /// A constant `<spectrum value="v"/>`.
    Spectrum(f64),
    /// A sampled `<spectrum value="λ₁:v₁, λ₂:v₂, …"/>`: (wavelength in nm, value) pairs,
    /// wavelengths strictly increasing.
    SampledSpectrum(Vec<(f64, f64)>),
    Transform(DMat4),
}

impl Value {
    pub fn type_name(&self) -> &'static str {
        match self {
            Value::Float(_) => "float",
            Value::Integer(_) => "integer",
            Value::Boolean(_) => "boolean",
            Value::String(_) => "string",
            Value::Point(_) => "point",
            Value::Vector(_) => "vector",
            Value::Rgb(_) => "rgb",
            Value::Spectrum(_) | Value::SampledSpectrum(_) => "spectrum",
            Value::Transform(_) => "transform",
        }
    }
}

#[derive(Clone, Debug)]
pub struct Property {
    pub name: String,
    pub value: Value,
    pub loc: Loc,
}

/// A nested object (or a `<ref>` to one) inside another object.
#[derive(Clone, Debug)]
pub struct Child {
    /// The `name` attribute (e.g. `interior`), if given.
    pub name: Option<String>,
    pub object: ObjId,
    /// Where the child (or the `<ref>`) appears.
    pub loc: Loc,
}

#[derive(Clone, Debug)]
pub struct Object {
    pub kind: ObjectKind,
    /// The `type` attribute: the plugin name (`diffuse`, `ply`, ...). "scene" for the root.
    pub plugin: String,
    pub id: Option<String>,
    pub props: Vec<Property>,
    pub children: Vec<Child>,
    pub loc: Loc,
    /// Read from a file older than 2.0 (Mitsuba 0.5/0.6): a property no plugin reads is
    /// a warning there, as in Mitsuba 0.6, unless `--strict-v3` (see `Props::finish`).
    pub legacy: bool,
}

impl Object {
    /// `<shape type="ply" id="x">` style label for messages.
    pub fn label(&self) -> String {
        match &self.id {
            Some(id) => format!("{} \"{}\" (id \"{}\")", self.kind.tag(), self.plugin, id),
            None => format!("{} \"{}\"", self.kind.tag(), self.plugin),
        }
    }
}

/// A loaded scene file: all objects, the root, and every file the scene read (for
/// provenance hashes).
#[derive(Clone, Debug)]
pub struct SceneDescription {
    pub objects: Vec<Object>,
    pub root: ObjId,
    /// The scene file and every included file, in the order read.
    pub files: Vec<std::path::PathBuf>,
    /// Directories searched for relative file names: the scene's folder, then each `-a`.
    pub search_path: Vec<std::path::PathBuf>,
    /// One line per Mitsuba 0.6 reading the loader made (`upgrade`), to be printed.
    pub notes: Vec<String>,
    /// `--strict-v3`: read files older than 2.0 as Mitsuba 3 does.
    pub strict_v3: bool,
    /// Properties of objects from files older than 2.0 that their plugin did not read:
    /// Mitsuba 0.6 logged each and went on, and so does the build (a line each, taken by
    /// `build_scene`); with `strict_v3` each is an error, as in Mitsuba 3.
    pub unread_legacy: std::cell::RefCell<Vec<String>>,
}

impl SceneDescription {
    pub fn object(&self, id: ObjId) -> &Object {
        &self.objects[id]
    }

    pub fn root(&self) -> &Object {
        &self.objects[self.root]
    }

    /// Every file the scene depends on: the scene file, its includes, and each asset
    /// named by a `filename` property that resolves on the search path.
    pub fn referenced_files(&self) -> Vec<std::path::PathBuf> {
        let mut out = self.files.clone();
        for o in &self.objects {
            for p in &o.props {
                if let (true, Value::String(name)) = (p.name == "filename", &p.value) {
                    if let Some(path) = super::resolve::resolve_path(&self.search_path, name) {
                        out.push(path);
                    }
                }
            }
        }
        out
    }
}
