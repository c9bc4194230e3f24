//! Typed access to an object's properties while building it, in the manner of Mitsuba 3's
//! `Properties`: every property and nested object must be queried by the plugin that
//! owns it, or the build fails ("unreferenced property"), so a misspelled name is never
//! silently ignored.

use std::cell::RefCell;

use glam::{DMat4, DVec3, Vec3};

use super::spectrum::{spectrum_to_srgb, SpectrumUse};
use crate::error::{err_at, Loc, Result, SceneError};
use crate::xml::description::{Child, ObjId, Object, ObjectKind, SceneDescription, Value};

pub struct Props<'a> {
    pub desc: &'a SceneDescription,
    pub obj: &'a Object,
    used_props: RefCell<Vec<bool>>,
    used_children: RefCell<Vec<bool>>,
}

impl<'a> Props<'a> {
    pub fn new(desc: &'a SceneDescription, id: ObjId) -> Self {
        let obj = desc.object(id);
        Props {
            desc,
            obj,
            used_props: RefCell::new(vec![false; obj.props.len()]),
            used_children: RefCell::new(vec![false; obj.children.len()]),
        }
    }

    pub fn loc(&self) -> &Loc {
        &self.obj.loc
    }

    /// An error located at this object, naming it.
    pub fn error(&self, message: impl Into<String>) -> SceneError {
        SceneError::at(
            &self.obj.loc,
            format!("{}: {}", self.obj.label(), message.into()),
        )
    }

    pub(crate) fn get(&self, name: &str) -> Option<(&'a Value, &'a Loc)> {
        let i = self.obj.props.iter().position(|p| p.name == name)?;
        self.used_props.borrow_mut()[i] = true;
        let p = &self.obj.props[i];
        Some((&p.value, &p.loc))
    }

    fn wrong_type<T>(&self, name: &str, loc: &Loc, v: &Value, expected: &str) -> Result<T> {
        err_at(
            loc,
            format!(
                "property \"{name}\" of {} must be {expected}, but the file gives <{}>",
                self.obj.label(),
                v.type_name()
            ),
        )
    }

    pub fn has(&self, name: &str) -> bool {
        self.obj.props.iter().any(|p| p.name == name)
    }

    pub fn float_opt(&self, name: &str) -> Result<Option<f64>> {
        match self.get(name) {
            None => Ok(None),
            Some((Value::Float(v), _)) => Ok(Some(*v)),
            Some((Value::Integer(v), _)) => Ok(Some(*v as f64)),
            Some((v, loc)) => self.wrong_type(name, loc, v, "a <float>"),
        }
    }

    pub fn float(&self, name: &str, default: f64) -> Result<f64> {
        Ok(self.float_opt(name)?.unwrap_or(default))
    }

    /// A float that must be in `[lo, hi]`.
    pub fn float_in(&self, name: &str, default: f64, lo: f64, hi: f64) -> Result<f64> {
        let v = self.float(name, default)?;
        if !(lo..=hi).contains(&v) {
            let loc = self
                .get(name)
                .map(|(_, l)| l.clone())
                .unwrap_or(self.obj.loc.clone());
            return err_at(
                &loc,
                format!(
                    "{}: \"{name}\" = {v} is out of range [{lo}, {hi}]",
                    self.obj.label()
                ),
            );
        }
        Ok(v)
    }

    pub fn int(&self, name: &str, default: i64) -> Result<i64> {
        match self.get(name) {
            None => Ok(default),
            Some((Value::Integer(v), _)) => Ok(*v),
            Some((v, loc)) => self.wrong_type(name, loc, v, "an <integer>"),
        }
    }

    pub fn bool(&self, name: &str, default: bool) -> Result<bool> {
        match self.get(name) {
            None => Ok(default),
            Some((Value::Boolean(v), _)) => Ok(*v),
            Some((v, loc)) => self.wrong_type(name, loc, v, "a <boolean>"),
        }
    }

    pub fn string_opt(&self, name: &str) -> Result<Option<(&'a str, &'a Loc)>> {
        match self.get(name) {
            None => Ok(None),
            Some((Value::String(v), loc)) => Ok(Some((v.as_str(), loc))),
            Some((v, loc)) => self.wrong_type(name, loc, v, "a <string>"),
        }
    }

    pub fn string(&self, name: &str, default: &str) -> Result<String> {
        Ok(self
            .string_opt(name)?
            .map_or(default.to_string(), |(s, _)| s.to_string()))
    }

    pub fn point_opt(&self, name: &str) -> Result<Option<DVec3>> {
        match self.get(name) {
            None => Ok(None),
            Some((Value::Point(v), _)) | Some((Value::Vector(v), _)) => Ok(Some(*v)),
            Some((v, loc)) => self.wrong_type(name, loc, v, "a <point>"),
        }
    }

    pub fn vector_opt(&self, name: &str) -> Result<Option<DVec3>> {
        self.point_opt(name)
    }

    pub fn transform(&self, name: &str) -> Result<DMat4> {
        match self.get(name) {
            None => Ok(DMat4::IDENTITY),
            Some((Value::Transform(m), _)) => Ok(*m),
            Some((v, loc)) => self.wrong_type(name, loc, v, "a <transform>"),
        }
    }

    /// A reflectance-like color: `<float>`, `<rgb>`, a constant `<spectrum>` (all the
    /// same in RGB mode) or a sampled spectrum (converted as a reflectance). Returns the
    /// value and where it was given.
    pub fn color_opt(&self, name: &str) -> Result<Option<(Vec3, Loc)>> {
        self.color_opt_as(name, SpectrumUse::Reflectance)
    }

    /// A color whose sampled spectrum, if it is one, converts to RGB as `usage` says.
    pub fn color_opt_as(&self, name: &str, usage: SpectrumUse) -> Result<Option<(Vec3, Loc)>> {
        if let Some(c) = self.child_named(name) {
            let o = self.desc.object(c.object);
            let e = SceneError::at(
                &c.loc,
                format!(
                    "{}: \"{name}\" given as a nested {} plugin \"{}\"; only a constant <float>, <rgb> or <spectrum> is supported here",
                    self.obj.label(),
                    o.kind.tag(),
                    o.plugin
                ),
            );
            return Err(if o.kind == ObjectKind::Volume {
                e.with_hint("for a property that varies in space use <medium type=\"heterogeneous\"> (its sigma_t and albedo take volumes)")
            } else {
                e
            });
        }
        match self.get(name) {
            None => Ok(None),
            Some((Value::Float(v), loc)) | Some((Value::Spectrum(v), loc)) => {
                Ok(Some((Vec3::splat(*v as f32), loc.clone())))
            }
            Some((Value::Integer(v), loc)) => Ok(Some((Vec3::splat(*v as f32), loc.clone()))),
            Some((Value::Rgb(v), loc)) => Ok(Some((v.as_vec3(), loc.clone()))),
            Some((Value::SampledSpectrum(s), loc)) => {
                Ok(Some((spectrum_to_srgb(s, usage), loc.clone())))
            }
            Some((v, loc)) => self.wrong_type(name, loc, v, "a <float>, <rgb> or <spectrum>"),
        }
    }

    /// A reflectance-like color that must be finite and nonnegative.
    pub fn color_nonneg(&self, name: &str, default: Vec3) -> Result<Vec3> {
        self.color_nonneg_as(name, default, SpectrumUse::Reflectance)
    }

    /// A color that must be finite and nonnegative; a sampled spectrum converts as
    /// `usage` says.
    pub fn color_nonneg_as(&self, name: &str, default: Vec3, usage: SpectrumUse) -> Result<Vec3> {
        match self.color_opt_as(name, usage)? {
            None => Ok(default),
            Some((c, loc)) => {
                if !c.is_finite() || c.min_element() < 0.0 {
                    return err_at(
                        &loc,
                        format!(
                            "{}: \"{name}\" = {c} must be finite and nonnegative",
                            self.obj.label()
                        ),
                    );
                }
                Ok(c)
            }
        }
    }

    fn child_named(&self, name: &str) -> Option<&'a Child> {
        let i = self
            .obj
            .children
            .iter()
            .position(|c| c.name.as_deref() == Some(name))?;
        self.used_children.borrow_mut()[i] = true;
        Some(&self.obj.children[i])
    }

    /// All nested objects of one kind (named or not), marked as used.
    pub fn children_of(&self, kind: ObjectKind) -> Vec<&'a Child> {
        let mut out = Vec::new();
        for (i, c) in self.obj.children.iter().enumerate() {
            if self.desc.object(c.object).kind == kind {
                self.used_children.borrow_mut()[i] = true;
                out.push(c);
            }
        }
        out
    }

    /// At most one nested object of `kind`; more is an error.
    pub fn child_of(&self, kind: ObjectKind) -> Result<Option<&'a Child>> {
        let all = self.children_of(kind);
        if all.len() > 1 {
            return err_at(
                &all[1].loc,
                format!(
                    "{} takes at most one nested <{}>",
                    self.obj.label(),
                    kind.tag()
                ),
            );
        }
        Ok(all.first().copied())
    }

    /// A nested object by its `name` attribute (e.g. `interior`), which must be `kind`.
    pub fn named_child_of(&self, name: &str, kind: ObjectKind) -> Result<Option<&'a Child>> {
        match self.child_named(name) {
            None => Ok(None),
            Some(c) => {
                let o = self.desc.object(c.object);
                if o.kind != kind {
                    return err_at(
                        &c.loc,
                        format!(
                            "\"{name}\" must be a <{}>, not a <{}>",
                            kind.tag(),
                            o.kind.tag()
                        ),
                    );
                }
                Ok(Some(c))
            }
        }
    }

    /// Fails on any property or nested object the plugin did not ask for, as Mitsuba 3
    /// does ("Unreferenced property"). A property of an object from a file older than 2.0
    /// is noted instead (Mitsuba 0.6 logged it and went on), unless `--strict-v3`.
    pub fn finish(self, supported: &str) -> Result<()> {
        for (p, used) in self.obj.props.iter().zip(self.used_props.borrow().iter()) {
            if !used && self.obj.legacy && !self.desc.strict_v3 {
                let line = format!(
                    "{}: property \"{}\" of {} is not read by mediareg (nor by Mitsuba 3): ignored, as Mitsuba 0.6 ignored it (--strict-v3 makes it an error); {} reads: {supported}",
                    p.loc,
                    p.name,
                    self.obj.label(),
                    self.obj.plugin
                );
                let mut unread = self.desc.unread_legacy.borrow_mut();
                if !unread.contains(&line) {
                    unread.push(line);
                }
            } else if !used {
                return Err(SceneError::at(
                    &p.loc,
                    format!(
                        "unreferenced property \"{}\" in {}",
                        p.name,
                        self.obj.label()
                    ),
                )
                .with_hint(format!("{} accepts: {supported}", self.obj.plugin)));
            }
        }
        for (c, used) in self
            .obj
            .children
            .iter()
            .zip(self.used_children.borrow().iter())
        {
            if !used {
                let o = self.desc.object(c.object);
                return Err(SceneError::at(
                    &c.loc,
                    format!(
                        "unreferenced nested {} \"{}\" in {}",
                        o.kind.tag(),
                        o.plugin,
                        self.obj.label()
                    ),
                )
                .with_hint(format!("{} accepts: {supported}", self.obj.plugin)));
            }
        }
        Ok(())
    }
}
