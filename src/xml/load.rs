//! From XML elements to a `SceneDescription`, with Mitsuba 3's semantics
//! (`src/core/parser.cpp`): `<default>` and `$name` parameters, `<include>`, `id` and
//! `<ref>`, typed properties, `<transform>`, and the upgrade of pre-2.0 files.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use glam::{DMat4, DVec3};

use super::description::{Child, ObjId, Object, ObjectKind, Property, SceneDescription, Value};
use super::element::{read_file, Element};
use super::refs::{Pending, UNRESOLVED};
use super::resolve::resolve_path;
use super::transform;
use crate::error::{err_at, Loc, Result, SceneError};

/// What the caller adds to the file: `-D name=value` parameters and `-a DIR` folders.
#[derive(Clone, Debug, Default)]
pub struct LoadOptions {
    pub params: Vec<(String, String)>,
    pub search_dirs: Vec<PathBuf>,
    /// Refuse the 0.6 readings `upgrade` would otherwise make (`--strict-v3`).
    pub strict_v3: bool,
}

/// A scene parameter (`$name`): its value, and whether anything used it.
struct Param {
    value: String,
    from_caller: bool,
    used: bool,
}

struct Loader {
    objects: Vec<Object>,
    ids: HashMap<String, ObjId>,
    params: HashMap<String, Param>,
    files: Vec<PathBuf>,
    include_stack: Vec<PathBuf>,
    search_path: Vec<PathBuf>,
    /// One line per 0.6 reading made (see `upgrade`).
    notes: Vec<String>,
    strict_v3: bool,
    /// `<ref>`s met before their target (see `refs`).
    pending: Vec<Pending>,
    /// Shapes read from files older than 2.0 (see `upgrade::index_matched_boundary`).
    v1_shapes: Vec<ObjId>,
}

/// How many files deep `<include>`s may chain: each level's elements nest inside the
/// including element, so the chain is bounded like the nesting within one file.
const MAX_INCLUDE_DEPTH: usize = 16;

/// Mitsuba 3 upgrades files whose `version` is below 2.0.0.
#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Debug)]
struct Version(u32, u32, u32);

/// Loads a Mitsuba 3 scene file into its description.
pub fn load_file(path: &Path, opts: &LoadOptions) -> Result<SceneDescription> {
    let mut search_path = Vec::new();
    let scene_dir = path
        .parent()
        .map(|p| {
            if p.as_os_str().is_empty() {
                Path::new(".")
            } else {
                p
            }
        })
        .unwrap_or(Path::new("."));
    search_path.push(scene_dir.to_path_buf());
    search_path.extend(opts.search_dirs.iter().cloned());

    let mut loader = Loader {
        objects: Vec::new(),
        ids: HashMap::new(),
        params: HashMap::new(),
        files: Vec::new(),
        include_stack: Vec::new(),
        search_path,
        notes: Vec::new(),
        strict_v3: opts.strict_v3,
        pending: Vec::new(),
        v1_shapes: Vec::new(),
    };
    for (name, value) in &opts.params {
        loader.params.insert(
            name.clone(),
            Param {
                value: value.clone(),
                from_caller: true,
                used: false,
            },
        );
    }

    let root_el = read_file(path)?;
    loader.files.push(path.to_path_buf());
    loader.include_stack.push(canonical(path));
    let version = loader.root_version(&root_el)?;
    let root = loader.object(&root_el, ObjectKind::Scene, version)?;
    super::refs::resolve(&mut loader.objects, &loader.ids, &loader.pending)?;
    for shape in std::mem::take(&mut loader.v1_shapes) {
        super::upgrade::index_matched_boundary(
            shape,
            &mut loader.objects,
            &mut loader.notes,
            loader.strict_v3,
        )?;
    }

    // Mitsuba 3 rejects parameters passed by the caller that the scene never uses.
    let mut unused: Vec<&String> = loader
        .params
        .iter()
        .filter(|(_, p)| p.from_caller && !p.used)
        .map(|(k, _)| k)
        .collect();
    unused.sort();
    if let Some(name) = unused.first() {
        return Err(SceneError::new(
            Some(Loc::file_only(path)),
            format!(
                "parameter \"{name}\" was given (-D {name}=...) but the scene never uses ${name}"
            ),
        )
        .with_hint("check the spelling, or remove the -D option"));
    }

    Ok(SceneDescription {
        objects: loader.objects,
        root,
        files: loader.files,
        search_path: loader.search_path,
        notes: loader.notes,
        strict_v3: opts.strict_v3,
        unread_legacy: Default::default(),
    })
}

fn canonical(p: &Path) -> PathBuf {
    std::fs::canonicalize(p).unwrap_or_else(|_| p.to_path_buf())
}

/// Mitsuba 3's upgrade of pre-2.0 property names: `camelCase` → `camel_case`
/// (`intIOR` → `int_ior`, `toWorld` → `to_world`).
pub fn camel_to_snake(name: &str) -> String {
    let mut out = String::with_capacity(name.len() + 4);
    let mut prev_lower = false;
    for ch in name.chars() {
        if ch.is_ascii_uppercase() {
            if prev_lower {
                out.push('_');
            }
            out.push(ch.to_ascii_lowercase());
            prev_lower = false;
        } else {
            out.push(ch);
            prev_lower = ch.is_ascii_lowercase() || ch.is_ascii_digit();
        }
    }
    out
}

const PROPERTY_TAGS: &[&str] = &[
    "float",
    "integer",
    "boolean",
    "string",
    "point",
    "vector",
    "rgb",
    "spectrum",
    "transform",
];

impl Loader {
    fn root_version(&self, root: &Element) -> Result<Version> {
        if root.tag != "scene" {
            return err_at(
                &root.loc,
                format!("the root element must be <scene>, not <{}>", root.tag),
            );
        }
        let Some(v) = root.attr("version") else {
            return Err(
                SceneError::at(&root.loc, "<scene> is missing its version attribute")
                    .with_hint("write <scene version=\"3.0.0\">"),
            );
        };
        parse_version(v).ok_or_else(|| {
            SceneError::at(
                &root.loc,
                format!("invalid version \"{v}\": expected MAJOR.MINOR.PATCH, e.g. 3.0.0"),
            )
        })
    }

    /// Replaces every `$name` in an attribute value by the parameter's value.
    fn substitute(&mut self, value: &str, loc: &Loc) -> Result<String> {
        if !value.contains('$') {
            return Ok(value.to_string());
        }
        let mut out = String::with_capacity(value.len());
        let mut rest = value;
        while let Some(pos) = rest.find('$') {
            out.push_str(&rest[..pos]);
            let after = &rest[pos + 1..];
            let len = after
                .find(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
                .unwrap_or(after.len());
            let name = &after[..len];
            if name.is_empty() {
                return err_at(loc, format!("lone '$' in attribute value \"{value}\""));
            }
            match self.params.get_mut(name) {
                Some(p) => {
                    p.used = true;
                    out.push_str(&p.value);
                }
                None => {
                    return Err(SceneError::at(
                        loc,
                        format!("undefined parameter ${name}"),
                    )
                    .with_hint(format!(
                        "declare it with <default name=\"{name}\" value=\"...\"/> or pass -D {name}=..."
                    )))
                }
            }
            rest = &after[len..];
        }
        out.push_str(rest);
        Ok(out)
    }

    /// The element's attributes after `$name` substitution.
    fn attrs(&mut self, el: &Element) -> Result<Vec<(String, String)>> {
        el.attrs
            .iter()
            .map(|(k, v)| Ok((k.clone(), self.substitute(v, &el.loc)?)))
            .collect()
    }

    /// Parses an object element (`<shape type=...>`, or the root `<scene>`).
    fn object(&mut self, el: &Element, kind: ObjectKind, version: Version) -> Result<ObjId> {
        let attrs = self.attrs(el)?;
        let get = |k: &str| attrs.iter().find(|(a, _)| a == k).map(|(_, v)| v.clone());
        let allowed: &[&str] = if kind == ObjectKind::Scene {
            &["version", "type", "id", "name"]
        } else {
            &["type", "id", "name"]
        };
        check_attrs(el, &attrs, allowed)?;
        let plugin = match kind {
            ObjectKind::Scene => "scene".to_string(),
            _ => get("type").ok_or_else(|| {
                SceneError::at(
                    &el.loc,
                    format!("<{}> is missing its type attribute", el.tag),
                )
            })?,
        };
        let id = get("id");
        let mut obj = Object {
            kind,
            plugin,
            id: id.clone(),
            props: Vec::new(),
            children: Vec::new(),
            loc: el.loc.clone(),
            legacy: version < Version(2, 0, 0),
        };
        self.children(&el.children, &mut obj, version)?;
        if obj.legacy {
            super::upgrade::from_v1(&mut obj, &mut self.notes, self.strict_v3)?;
        }
        let oid = self.objects.len();
        if obj.legacy && kind == ObjectKind::Shape {
            self.v1_shapes.push(oid);
        }
        self.objects.push(obj);
        if let Some(id) = id {
            if let Some(&prev) = self.ids.get(&id) {
                return Err(SceneError::at(
                    &el.loc,
                    format!(
                        "id \"{id}\" is used twice (first at {})",
                        self.objects[prev].loc
                    ),
                ));
            }
            self.ids.insert(id, oid);
        }
        Ok(oid)
    }

    fn children(&mut self, elements: &[Element], obj: &mut Object, version: Version) -> Result<()> {
        for child in elements {
            self.child(child, obj, version)?;
        }
        Ok(())
    }

    fn child(&mut self, el: &Element, obj: &mut Object, version: Version) -> Result<()> {
        let tag = el.tag.as_str();
        match tag {
            "default" => {
                let attrs = self.attrs(el)?;
                check_attrs(el, &attrs, &["name", "value"])?;
                let name = required(el, &attrs, "name")?;
                let value = required(el, &attrs, "value")?;
                if name.is_empty() || !name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') {
                    return err_at(&el.loc, format!("invalid parameter name \"{name}\""));
                }
                // A parameter given by the caller (-D) wins over the file's default.
                self.params.entry(name).or_insert(Param {
                    value,
                    from_caller: false,
                    used: false,
                });
                Ok(())
            }
            "include" => self.include(el, obj),
            "path" => self.resource_path(el, obj),
            "ref" => {
                let attrs = self.attrs(el)?;
                check_attrs(el, &attrs, &["id", "name"])?;
                let id = required(el, &attrs, "id")?;
                // A target declared later is filled in once the file is read (`refs`).
                let target = match self.ids.get(&id) {
                    Some(&t) => t,
                    None => {
                        self.pending.push(Pending {
                            id,
                            loc: el.loc.clone(),
                        });
                        UNRESOLVED + self.pending.len() - 1
                    }
                };
                let name = attrs.iter().find(|(k, _)| k == "name").map(|(_, v)| v.clone());
                obj.children.push(Child {
                    name,
                    object: target,
                    loc: el.loc.clone(),
                });
                Ok(())
            }
            _ if PROPERTY_TAGS.contains(&tag) => {
                let prop = self.property(el, version)?;
                if let Some(prev) = obj.props.iter().find(|p| p.name == prop.name) {
                    return err_at(
                        &el.loc,
                        format!(
                            "property \"{}\" is specified twice in {} (first at {})",
                            prop.name,
                            obj.label(),
                            prev.loc
                        ),
                    );
                }
                obj.props.push(prop);
                Ok(())
            }
            _ => match ObjectKind::from_tag(tag) {
                Some(ObjectKind::Scene) => err_at(&el.loc, "<scene> may only be the root element"),
                Some(kind) => {
                    let name = match el.attr("name") {
                        Some(n) => Some(self.substitute(n, &el.loc)?),
                        None => None,
                    };
                    let id = self.object(el, kind, version)?;
                    obj.children.push(Child {
                        name,
                        object: id,
                        loc: el.loc.clone(),
                    });
                    Ok(())
                }
                None => Err(SceneError::at(&el.loc, format!("unknown tag <{tag}>")).with_hint(
                    "expected an object (shape, bsdf, emitter, medium, phase, sensor, film, sampler, \
                     rfilter, integrator), a property (float, integer, boolean, string, point, \
                     vector, rgb, spectrum, transform), default, include, path or ref",
                )),
            },
        }
    }

    fn include(&mut self, el: &Element, obj: &mut Object) -> Result<()> {
        let attrs = self.attrs(el)?;
        check_attrs(el, &attrs, &["filename"])?;
        let name = required(el, &attrs, "filename")?;
        let Some(path) = resolve_path(&self.search_path, &name) else {
            return Err(
                SceneError::at(&el.loc, format!("included file \"{name}\" not found"))
                    .with_hint(self.search_hint()),
            );
        };
        let canon = canonical(&path);
        if self.include_stack.contains(&canon) {
            return err_at(
                &el.loc,
                format!("cyclic include: \"{}\" includes itself", path.display()),
            );
        }
        if self.include_stack.len() >= MAX_INCLUDE_DEPTH {
            return Err(SceneError::at(
                &el.loc,
                format!("includes are nested more than {MAX_INCLUDE_DEPTH} files deep"),
            )
            .with_hint("include the files from one top-level file instead of a chain"));
        }
        let root = read_file(&path)?;
        let version = self.root_version(&root)?;
        self.files.push(path);
        self.include_stack.push(canon);
        // The included <scene>'s children become children of the including element.
        let r = self.children(&root.children, obj, version);
        self.include_stack.pop();
        r
    }

    /// `<path value="DIR"/>` (Mitsuba 3's `Tag::Resource`): a folder put in front of the
    /// search path, for the files named after it is read. A relative DIR is taken from
    /// the folder of the file it is written in, else looked up on the search path.
    fn resource_path(&mut self, el: &Element, obj: &Object) -> Result<()> {
        let attrs = self.attrs(el)?;
        check_attrs(el, &attrs, &["value"])?;
        let value = required(el, &attrs, "value")?;
        if obj.kind != ObjectKind::Scene {
            return err_at(&el.loc, "<path> may only be a child of <scene>");
        }
        let dir = Path::new(&value);
        let here = self
            .include_stack
            .last()
            .and_then(|f| f.parent())
            .map(|d| d.join(dir));
        let found = if dir.is_absolute() {
            dir.exists().then(|| dir.to_path_buf())
        } else {
            here.filter(|d| d.exists())
                .or_else(|| resolve_path(&self.search_path, &value))
        };
        match found {
            Some(d) if d.is_dir() => {
                self.search_path.insert(0, d);
                Ok(())
            }
            _ => Err(
                SceneError::at(&el.loc, format!("<path>: folder \"{value}\" not found"))
                    .with_hint(self.search_hint()),
            ),
        }
    }

    fn search_hint(&self) -> String {
        let dirs: Vec<String> = self
            .search_path
            .iter()
            .map(|d| d.display().to_string())
            .collect();
        format!("searched: {}; add a folder with -a DIR", dirs.join(", "))
    }

    fn property(&mut self, el: &Element, version: Version) -> Result<Property> {
        let attrs = self.attrs(el)?;
        let raw_name = required(el, &attrs, "name")?;
        let name = if version < Version(2, 0, 0) {
            camel_to_snake(&raw_name)
        } else {
            raw_name
        };
        let loc = &el.loc;
        let value_attr = || required(el, &attrs, "value");
        if el.tag != "transform" {
            if let Some(c) = el.children.first() {
                return err_at(&c.loc, format!("<{}> cannot have child elements", el.tag));
            }
        }
        let value = match el.tag.as_str() {
            "float" => {
                check_attrs(el, &attrs, &["name", "value"])?;
                Value::Float(parse_float(&value_attr()?, loc)?)
            }
            "integer" => {
                check_attrs(el, &attrs, &["name", "value"])?;
                let v = value_attr()?;
                Value::Integer(v.trim().parse::<i64>().map_err(|_| {
                    SceneError::at(loc, format!("could not parse integer value \"{v}\""))
                })?)
            }
            "boolean" => {
                check_attrs(el, &attrs, &["name", "value"])?;
                let v = value_attr()?;
                Value::Boolean(match v.trim().to_ascii_lowercase().as_str() {
                    "true" => true,
                    "false" => false,
                    _ => {
                        return err_at(
                            loc,
                            format!(
                                "could not parse boolean value \"{v}\": expected true or false"
                            ),
                        )
                    }
                })
            }
            "string" => {
                check_attrs(el, &attrs, &["name", "value"])?;
                Value::String(value_attr()?)
            }
            "point" | "vector" => {
                check_attrs(el, &attrs, &["name", "value", "x", "y", "z"])?;
                let v = parse_vec3(&attrs, loc, 0.0)?;
                if el.tag == "point" {
                    Value::Point(v)
                } else {
                    Value::Vector(v)
                }
            }
            "rgb" => {
                check_attrs(el, &attrs, &["name", "value"])?;
                let v = value_attr()?;
                let list = parse_list(&v, loc)?;
                match list.as_slice() {
                    [x] => Value::Rgb(DVec3::splat(*x)),
                    [r, g, b] => Value::Rgb(DVec3::new(*r, *g, *b)),
                    _ => {
                        return err_at(
                            loc,
                            format!("<rgb> needs 1 or 3 values, got {} in \"{v}\"", list.len()),
                        )
                    }
                }
            }
            "spectrum" => {
                check_attrs(el, &attrs, &["name", "value", "filename"])?;
                if attrs.iter().any(|(k, _)| k == "filename") {
                    return err_at(
                        loc,
                        "<spectrum filename=...> is not supported: only a constant <spectrum value=\"v\"/>",
                    );
                }
                let v = value_attr()?;
                if v.contains(':') {
                    Value::SampledSpectrum(parse_sampled_spectrum(&v, loc)?)
                } else {
                    let list = parse_list(&v, loc)?;
                    match list.as_slice() {
                        [x] => Value::Spectrum(*x),
                        [r, g, b] if version < Version(2, 0, 0) => super::upgrade::rgb_spectrum(
                            loc,
                            &name,
                            DVec3::new(*r, *g, *b),
                            &mut self.notes,
                            self.strict_v3,
                        )?,
                        _ => return err_at(loc, format!("could not parse spectrum value \"{v}\"")),
                    }
                }
            }
            "transform" => {
                check_attrs(el, &attrs, &["name"])?;
                Value::Transform(self.transform(el, version)?)
            }
            _ => unreachable!("property() called on a property tag"),
        };
        Ok(Property {
            name,
            value,
            loc: loc.clone(),
        })
    }

    /// Composes the operations of a `<transform>`: each one left-multiplies.
    fn transform(&mut self, el: &Element, version: Version) -> Result<DMat4> {
        let mut m = DMat4::IDENTITY;
        for op in &el.children {
            let attrs = self.attrs(op)?;
            let loc = &op.loc;
            let tag = if version < Version(2, 0, 0) && op.tag == "lookAt" {
                "lookat"
            } else {
                op.tag.as_str()
            };
            let t = match tag {
                "translate" => {
                    check_attrs(op, &attrs, &["value", "x", "y", "z"])?;
                    transform::translate(parse_vec3(&attrs, loc, 0.0)?)
                }
                "scale" => {
                    check_attrs(op, &attrs, &["value", "x", "y", "z"])?;
                    transform::scale(parse_vec3(&attrs, loc, 1.0)?)
                }
                "rotate" => {
                    check_attrs(op, &attrs, &["value", "x", "y", "z", "angle"])?;
                    let axis = parse_vec3(&attrs, loc, 0.0)?;
                    let angle = parse_float(&required(op, &attrs, "angle")?, loc)?;
                    if axis == DVec3::ZERO {
                        return err_at(
                            loc,
                            "<rotate> needs a nonzero axis (value=\"x,y,z\" or x/y/z)",
                        );
                    }
                    transform::rotate(axis, angle)
                }
                "matrix" => {
                    check_attrs(op, &attrs, &["value"])?;
                    let v = required(op, &attrs, "value")?;
                    let list = parse_list(&v, loc)?;
                    if let Ok(arr) = <[f64; 9]>::try_from(list.as_slice()) {
                        transform::matrix3_row_major(&arr)
                    } else {
                        let arr: [f64; 16] = list.as_slice().try_into().map_err(|_| {
                            SceneError::at(
                                loc,
                                format!("<matrix> needs 16 (or 9) values, got {}", list.len()),
                            )
                        })?;
                        transform::matrix_row_major(&arr)
                    }
                }
                "lookat" => {
                    check_attrs(op, &attrs, &["origin", "target", "up"])?;
                    let get = |k: &str| -> Result<DVec3> {
                        let v = required(op, &attrs, k)?;
                        vec3_from_list(&parse_list(&v, loc)?, loc, k)
                    };
                    let origin = get("origin")?;
                    let target = get("target")?;
                    // Mitsuba: a missing or zero up is generated from the view direction.
                    let up = match attrs.iter().find(|(k, _)| k == "up") {
                        Some(_) => get("up")?,
                        None => DVec3::ZERO,
                    };
                    let up = match (up == DVec3::ZERO, (target - origin).try_normalize()) {
                        (true, Some(dir)) => transform::default_up(dir),
                        _ => up,
                    };
                    transform::look_at(origin, target, up).ok_or_else(|| {
                        SceneError::at(
                            loc,
                            "degenerate <lookat>: origin equals target, or up is parallel to the view direction",
                        )
                    })?
                }
                other => {
                    return Err(SceneError::at(
                        loc,
                        format!("unknown transform operation <{other}>"),
                    )
                    .with_hint("expected translate, rotate, scale, matrix or lookat"))
                }
            };
            m = t * m;
        }
        Ok(m)
    }
}

fn parse_version(v: &str) -> Option<Version> {
    let parts: Vec<&str> = v.trim().split('.').collect();
    if parts.is_empty() || parts.len() > 3 {
        return None;
    }
    let n = |i: usize| -> Option<u32> { parts.get(i).map_or(Some(0), |s| s.parse().ok()) };
    Some(Version(n(0)?, n(1)?, n(2)?))
}

fn required(el: &Element, attrs: &[(String, String)], key: &str) -> Result<String> {
    attrs
        .iter()
        .find(|(k, _)| k == key)
        .map(|(_, v)| v.clone())
        .ok_or_else(|| {
            SceneError::at(
                &el.loc,
                format!("<{}> is missing its {key} attribute", el.tag),
            )
        })
}

fn check_attrs(el: &Element, attrs: &[(String, String)], allowed: &[&str]) -> Result<()> {
    for (k, _) in attrs {
        if !allowed.contains(&k.as_str()) {
            return Err(SceneError::at(
                &el.loc,
                format!("unexpected attribute \"{k}\" in <{}>", el.tag),
            )
            .with_hint(format!("allowed: {}", allowed.join(", "))));
        }
    }
    Ok(())
}

pub fn parse_float(s: &str, loc: &Loc) -> Result<f64> {
    let v: f64 = s.trim().parse().map_err(|_| {
        SceneError::at(loc, format!("could not parse floating point value \"{s}\""))
    })?;
    if !v.is_finite() {
        return err_at(loc, format!("value \"{s}\" is not a finite number"));
    }
    Ok(v)
}

/// `"λ₁:v₁, λ₂:v₂, …"`: at least two pairs, wavelengths (nm) strictly increasing, values
/// finite and nonnegative (Mitsuba turns the list into RGB by integrating it; see
/// `load::spectrum`).
fn parse_sampled_spectrum(s: &str, loc: &Loc) -> Result<Vec<(f64, f64)>> {
    let mut pairs = Vec::new();
    for item in s.split(',').map(str::trim).filter(|t| !t.is_empty()) {
        let Some((w, v)) = item.split_once(':') else {
            return err_at(
                loc,
                format!("sampled spectrum \"{s}\": \"{item}\" is not a wavelength:value pair"),
            );
        };
        let (w, v) = (parse_float(w.trim(), loc)?, parse_float(v.trim(), loc)?);
        if !w.is_finite() || w <= 0.0 || !v.is_finite() || v < 0.0 {
            return err_at(
                loc,
                format!("sampled spectrum: \"{item}\" needs a positive wavelength (nm) and a finite value >= 0"),
            );
        }
        if let Some(&(prev, _)) = pairs.last() {
            if w <= prev {
                return err_at(
                    loc,
                    format!("sampled spectrum: wavelengths must increase, but {w} follows {prev}"),
                );
            }
        }
        pairs.push((w, v));
    }
    if pairs.len() < 2 {
        return err_at(
            loc,
            format!("sampled spectrum \"{s}\" needs at least two wavelength:value pairs"),
        );
    }
    Ok(pairs)
}

/// Numbers separated by commas and/or whitespace, as Mitsuba's tokenizer accepts.
fn parse_list(s: &str, loc: &Loc) -> Result<Vec<f64>> {
    s.split(|c: char| c == ',' || c.is_whitespace())
        .filter(|t| !t.is_empty())
        .map(|t| parse_float(t, loc))
        .collect()
}

fn vec3_from_list(list: &[f64], loc: &Loc, what: &str) -> Result<DVec3> {
    match list {
        [x, y, z] => Ok(DVec3::new(*x, *y, *z)),
        _ => err_at(loc, format!("{what} needs 3 values, got {}", list.len())),
    }
}

/// `value="x, y, z"` (one value broadcasts) or separate `x`, `y`, `z` attributes, each
/// defaulting to `default`.
fn parse_vec3(attrs: &[(String, String)], loc: &Loc, default: f64) -> Result<DVec3> {
    let get = |k: &str| attrs.iter().find(|(a, _)| a == k).map(|(_, v)| v.as_str());
    if let Some(v) = get("value") {
        if get("x").or(get("y")).or(get("z")).is_some() {
            return err_at(
                loc,
                "give either value=\"...\" or x/y/z attributes, not both",
            );
        }
        let list = parse_list(v, loc)?;
        return match list.as_slice() {
            [s] => Ok(DVec3::splat(*s)),
            _ => vec3_from_list(&list, loc, "value"),
        };
    }
    let c = |k: &str| get(k).map_or(Ok(default), |v| parse_float(v, loc));
    Ok(DVec3::new(c("x")?, c("y")?, c("z")?))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn camel_case_upgrade() {
        assert_eq!(camel_to_snake("intIOR"), "int_ior");
        assert_eq!(camel_to_snake("toWorld"), "to_world");
        assert_eq!(camel_to_snake("sampleCount"), "sample_count");
        assert_eq!(camel_to_snake("max_depth"), "max_depth");
    }
}
