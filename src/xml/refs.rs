//! `<ref id>` to an object declared later in the file. Mitsuba 3 parses the whole file
//! first and resolves every reference afterwards (`transform_resolve`, `parser.cpp`), so
//! a reference may come before its target; a circular reference is an error there too.
//!
//! While the file is read, a reference whose id is not yet known becomes a child whose
//! object index is a placeholder (`UNRESOLVED + k`, k indexing the pending list); once
//! the file is read, [`resolve`] puts the target in its place.

use std::collections::HashMap;

use super::description::{ObjId, Object};
use crate::error::{Loc, Result, SceneError};

/// Object indices from here on are placeholders for pending references.
pub const UNRESOLVED: ObjId = ObjId::MAX / 2;

/// A `<ref id>` met before its target: the id and where the `<ref>` is.
pub struct Pending {
    pub id: String,
    pub loc: Loc,
}

/// Replaces each placeholder by the object its id names (an id never declared is an
/// error at the `<ref>`), then refuses circular references.
pub fn resolve(
    objects: &mut [Object],
    ids: &HashMap<String, ObjId>,
    pending: &[Pending],
) -> Result<()> {
    if pending.is_empty() {
        // Every reference named an object already read: no cycle is possible.
        return Ok(());
    }
    for obj in objects.iter_mut() {
        for c in obj.children.iter_mut().filter(|c| c.object >= UNRESOLVED) {
            let p = &pending[c.object - UNRESOLVED];
            c.object = *ids.get(&p.id).ok_or_else(|| {
                SceneError::at(
                    &p.loc,
                    format!(
                        "<ref id=\"{}\"> refers to an unknown id: no object in the scene declares it",
                        p.id
                    ),
                )
                .with_hint(format!(
                    "declare an object with id=\"{}\" (anywhere in the file), or fix the spelling",
                    p.id
                ))
            })?;
        }
    }
    check_cycles(objects)
}

/// Depth-first search over the children; a child on the current path closes a cycle.
fn check_cycles(objects: &[Object]) -> Result<()> {
    #[derive(Clone, Copy, PartialEq)]
    enum Mark {
        New,
        OnPath,
        Done,
    }
    let mut mark = vec![Mark::New; objects.len()];
    for start in 0..objects.len() {
        if mark[start] != Mark::New {
            continue;
        }
        // Explicit stack of (object, next child) so deep files cannot overflow it.
        let mut stack = vec![(start, 0usize)];
        mark[start] = Mark::OnPath;
        while let Some(&mut (o, ref mut next)) = stack.last_mut() {
            match objects[o].children.get(*next) {
                None => {
                    mark[o] = Mark::Done;
                    stack.pop();
                }
                Some(c) => {
                    *next += 1;
                    match mark[c.object] {
                        Mark::New => {
                            mark[c.object] = Mark::OnPath;
                            stack.push((c.object, 0));
                        }
                        Mark::OnPath => {
                            return Err(SceneError::at(
                                &c.loc,
                                format!(
                                    "circular reference: {} contains itself through this <ref>",
                                    objects[c.object].label()
                                ),
                            )
                            .with_hint("an object cannot contain (or refer to) an object that refers back to it"));
                        }
                        Mark::Done => {}
                    }
                }
            }
        }
    }
    Ok(())
}
