//! Naming a medium as a Mitsuba 3 user would: by its XML `id`, by the slot a shape
//! binds it to (`interior`, `exterior`), or by the key `mi.traverse` gives it
//! (`<shape id>.interior_medium`, `<shape id>.exterior_medium`). Mitsuba 3 keys a medium
//! declared at the top level by its id, and one nested in a shape by the shape's id and
//! its slot; a shape without an id gets an address-based key nobody can type, so such a
//! medium is named here by its slot, or listed by the shape's line in the file.

use super::Scene;

/// A shape's medium slot, as `mi.traverse` spells it after the shape's id.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MediumSlot {
    Interior,
    Exterior,
}

impl MediumSlot {
    /// The name the XML binds it by (`<medium name="interior">`).
    pub fn xml_name(self) -> &'static str {
        match self {
            MediumSlot::Interior => "interior",
            MediumSlot::Exterior => "exterior",
        }
    }

    /// The name `mi.traverse` keys it by after the shape's id.
    pub fn traverse_name(self) -> &'static str {
        match self {
            MediumSlot::Interior => "interior_medium",
            MediumSlot::Exterior => "exterior_medium",
        }
    }
}

impl Scene {
    /// Every (shape, slot, medium) binding, in file order.
    fn medium_bindings(&self) -> impl Iterator<Item = (usize, MediumSlot, u32)> + '_ {
        self.shapes.iter().enumerate().flat_map(|(s, info)| {
            [
                info.interior.map(|m| (s, MediumSlot::Interior, m)),
                info.exterior.map(|m| (s, MediumSlot::Exterior, m)),
            ]
            .into_iter()
            .flatten()
        })
    }

    /// The `mi.traverse` key of shape `s`'s medium in `slot`, where the shape has an id.
    fn traverse_key(&self, s: usize, slot: MediumSlot) -> Option<String> {
        let id = self.shapes[s].id.as_ref()?;
        Some(format!("{id}.{}", slot.traverse_name()))
    }

    /// How messages name medium `m`: its id, else its first `mi.traverse` key, else its
    /// slot and the line of the shape that holds it.
    pub fn medium_name(&self, m: u32) -> String {
        if let Some(id) = &self.media[m as usize].id {
            return id.clone();
        }
        let Some((s, slot, _)) = self.medium_bindings().find(|b| b.2 == m) else {
            return match self.camera_medium == Some(m) {
                true => "the sensor's medium".to_string(),
                false => format!("medium #{m} (bound to no shape)"),
            };
        };
        self.traverse_key(s, slot)
            .unwrap_or_else(|| format!("{} of {}", slot.xml_name(), self.shapes[s].origin))
    }

    /// The medium a derivative (or a method) refers to: `name` as an XML id, a slot
    /// (`interior`/`exterior`, where the shapes bind one medium to it) or a
    /// `<shape id>.interior_medium` key; with no name, the only medium. The error lists
    /// the choices by the names this accepts.
    pub fn medium_index(&self, name: Option<&str>) -> Result<u32, MediumChoiceError> {
        let names = |ms: &mut dyn Iterator<Item = u32>| -> Vec<String> {
            ms.map(|m| self.medium_name(m)).collect()
        };
        let Some(n) = name else {
            return match self.media.len() {
                0 => Err(MediumChoiceError::NoMedium),
                1 => Ok(0),
                k => Err(MediumChoiceError::Several {
                    media: names(&mut (0..k as u32)),
                }),
            };
        };
        if let Some(i) = self.media.iter().position(|m| m.id.as_deref() == Some(n)) {
            return Ok(i as u32);
        }
        let mut found: Vec<u32> = Vec::new();
        for (s, slot, m) in self.medium_bindings() {
            let key = self.traverse_key(s, slot);
            if (n == slot.xml_name() || key.as_deref() == Some(n)) && !found.contains(&m) {
                found.push(m);
            }
        }
        match found[..] {
            [m] => Ok(m),
            [] => Err(MediumChoiceError::NoSuch {
                name: n.to_string(),
                media: names(&mut (0..self.media.len() as u32)),
            }),
            _ => Err(MediumChoiceError::Ambiguous {
                name: n.to_string(),
                candidates: names(&mut found.into_iter()),
            }),
        }
    }
}

/// Why `Scene::medium_index` could not choose a medium (the command line names its
/// `--medium` flag).
#[derive(Clone, Debug, PartialEq)]
pub enum MediumChoiceError {
    NoSuch {
        name: String,
        media: Vec<String>,
    },
    /// A slot that several shapes fill with different media.
    Ambiguous {
        name: String,
        candidates: Vec<String>,
    },
    NoMedium,
    /// Several media and no name given.
    Several {
        media: Vec<String>,
    },
}

impl std::fmt::Display for MediumChoiceError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            MediumChoiceError::NoSuch { name, media } => write!(
                f,
                "no medium is named {name} (by id, slot or <shape id>.interior_medium); the scene's media: {}",
                media.join(", ")
            ),
            MediumChoiceError::Ambiguous { name, candidates } => write!(
                f,
                "{name} names {} media; name one of: {}",
                candidates.len(),
                candidates.join(", ")
            ),
            MediumChoiceError::NoMedium => write!(f, "the scene has no medium"),
            MediumChoiceError::Several { media } => write!(
                f,
                "the scene has {} media, name one: {}",
                media.len(),
                media.join(", ")
            ),
        }
    }
}

impl std::error::Error for MediumChoiceError {}
