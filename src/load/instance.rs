//! Geometry instancing: Mitsuba's `shapegroup` and `instance` (`src/shapes/shapegroup.cpp`,
//! `instance.cpp`, `src/render/shapegroup.cpp`).
//!
//! A shapegroup's shapes are not rendered themselves (Mitsuba's `Scene` keeps shape groups
//! out of its shape list); each `instance` places all of them under its `to_world`. Mitsuba
//! intersects the group in the instance's object space; mediareg instead bakes each
//! instance at load into copies of the group's shapes whose `to_world` is the instance's
//! times the shape's own. The surfaces are the same: a point maps by `to_world`, normals by
//! its inverse transpose, as Mitsuba's `Instance::compute_surface_interaction` maps them.
//! Each copy costs memory, which Mitsuba's shared group does not; a mesh file is read
//! once for all of them (the builder keeps what it read, `shape.rs`).
//!
//! Refused as Mitsuba refuses them: a shapegroup in a shapegroup, an instance in a
//! shapegroup, an emitter on a shape in a shapegroup ("Instancing of emitters is not
//! supported"), an instance of anything but one shapegroup. Refused because a baked copy
//! would differ: a mirroring (or singular) instance `to_world` (a baked triangle's winding,
//! hence its geometric normal, flips where Mitsuba's instance keeps the object's normal),
//! and a sphere under a non-uniform scale (an ellipsoid mediareg's sphere cannot be).

use glam::DMat4;

use super::props::Props;
use super::Builder;
use crate::error::{Loc, Result, SceneError};
use crate::xml::description::{ObjId, ObjectKind};

/// Where an instance puts a shapegroup's shape: its `to_world`, and where the instance
/// is written (for messages).
pub(super) struct Placement<'a> {
    pub to_world: DMat4,
    pub loc: &'a Loc,
}

impl Builder<'_> {
    /// A shape directly under `<scene>`: a shapegroup (built only through its instances),
    /// an instance (its group's shapes, placed), or an ordinary shape.
    pub(super) fn top_level_shape(&mut self, id: ObjId) -> Result<()> {
        match self.desc.object(id).plugin.as_str() {
            "shapegroup" => {
                let members = self.shapegroup_members(id)?;
                if !self.is_instanced(id) {
                    // Mitsuba builds a group even when nothing instances it: check its
                    // shapes the same way, then drop them.
                    let (g, s) = (self.geometries.len(), self.shapes.len());
                    let here = self.desc.object(id).loc.clone();
                    let at = Placement {
                        to_world: DMat4::IDENTITY,
                        loc: &here,
                    };
                    for m in members {
                        self.shape(m, Some(&at))?;
                    }
                    self.geometries.truncate(g);
                    self.shapes.truncate(s);
                    self.warnings.push(format!(
                        "{here}: shapegroup {}: no instance refers to it, so none of its shapes is rendered",
                        self.desc.object(id).id.as_deref().unwrap_or("(no id)")
                    ));
                }
                Ok(())
            }
            "instance" => self.instance(id),
            _ => self.shape(id, None),
        }
    }

    fn is_instanced(&self, group: ObjId) -> bool {
        self.desc.objects.iter().any(|o| {
            o.kind == ObjectKind::Shape
                && o.plugin == "instance"
                && o.children.iter().any(|c| c.object == group)
        })
    }

    /// The shapes a shapegroup holds, checked as Mitsuba's `ShapeGroup` constructor
    /// checks them.
    fn shapegroup_members(&self, id: ObjId) -> Result<Vec<ObjId>> {
        let p = Props::new(self.desc, id);
        let mut members = Vec::new();
        for c in &p.obj.children {
            let o = self.desc.object(c.object);
            let refuse = |what: &str| {
                Err(SceneError::at(
                    &c.loc,
                    format!("{}: {what} (as in Mitsuba 3)", p.obj.label()),
                ))
            };
            match (o.kind, o.plugin.as_str()) {
                (ObjectKind::Shape, "shapegroup") => {
                    return refuse("a shapegroup inside a shapegroup is not permitted")
                }
                (ObjectKind::Shape, "instance") => {
                    return refuse("an instance inside a shapegroup is not permitted")
                }
                (ObjectKind::Shape, _) => members.push(c.object),
                (kind, plugin) => {
                    return refuse(&format!(
                        "a shapegroup holds only shapes, not a <{} type=\"{plugin}\">",
                        kind.tag()
                    ))
                }
            }
        }
        p.children_of(ObjectKind::Shape);
        p.finish("nested shapes only")?;
        Ok(members)
    }

    /// Mitsuba's `instance`: `to_world` and exactly one shapegroup (nested or by `<ref>`).
    fn instance(&mut self, id: ObjId) -> Result<()> {
        let p = Props::new(self.desc, id);
        let to_world = p.transform("to_world")?;
        let groups = p.children_of(ObjectKind::Shape);
        let group = match groups.as_slice() {
            [g] if self.desc.object(g.object).plugin == "shapegroup" => g.object,
            [] => {
                return Err(p
                    .error("a reference to a shapegroup must be given (as in Mitsuba 3)")
                    .with_hint("add <ref id=\"GROUP\"/> naming a <shape type=\"shapegroup\" id=\"GROUP\">"))
            }
            [g] => {
                return Err(SceneError::at(
                    &g.loc,
                    format!(
                        "{}: only a shapegroup can be given in an instance, not a shape \"{}\" (as in Mitsuba 3)",
                        p.obj.label(),
                        self.desc.object(g.object).plugin
                    ),
                ))
            }
            [_, second, ..] => {
                return Err(SceneError::at(
                    &second.loc,
                    format!(
                        "{}: only one shapegroup per instance (as in Mitsuba 3)",
                        p.obj.label()
                    ),
                ))
            }
        };
        let det = to_world.determinant();
        if det <= 0.0 || det.is_nan() {
            return Err(p
                .error(format!(
                    "the instance's to_world {} (determinant {det:.3}): mediareg bakes instances into copies of the group's shapes, which a mirroring or singular transform would turn inside out",
                    if det < 0.0 { "mirrors" } else { "is singular" }
                ))
                .with_hint("use a to_world with positive determinant (no negative scale), or mirror the shapes inside the group"));
        }
        let members = self.shapegroup_members(group)?;
        let loc = p.loc().clone();
        p.finish("to_world, one shapegroup")?;
        let at = Placement {
            to_world,
            loc: &loc,
        };
        for m in members {
            self.shape(m, Some(&at))?;
        }
        Ok(())
    }
}
