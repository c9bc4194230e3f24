//! Reading an XML file into a plain element tree that remembers where each element and
//! attribute came from. No Mitsuba semantics here: that is `xml::load`'s job.

use std::path::Path;
use std::sync::Arc;

use quick_xml::events::{BytesStart, Event};
use quick_xml::Reader;

use crate::error::{Loc, Result, SceneError};

/// One XML element: tag name, attributes in document order, children, and position.
#[derive(Debug, Clone)]
pub struct Element {
    pub tag: String,
    pub attrs: Vec<(String, String)>,
    pub children: Vec<Element>,
    pub loc: Loc,
}

impl Element {
    pub fn attr(&self, name: &str) -> Option<&str> {
        self.attrs
            .iter()
            .find(|(k, _)| k == name)
            .map(|(_, v)| v.as_str())
    }
}

/// Maps byte offsets to 1-based (line, column).
struct LineIndex {
    starts: Vec<usize>,
}

impl LineIndex {
    fn new(text: &str) -> Self {
        let mut starts = vec![0];
        starts.extend(text.match_indices('\n').map(|(i, _)| i + 1));
        LineIndex { starts }
    }

    fn line_col(&self, offset: usize) -> (u32, u32) {
        let line = self.starts.partition_point(|&s| s <= offset).max(1);
        let col = offset - self.starts[line - 1] + 1;
        (line as u32, col as u32)
    }
}

/// Reads and parses `path` into its root element.
pub fn read_file(path: &Path) -> Result<Element> {
    let bytes = std::fs::read(path).map_err(|e| {
        SceneError::new(
            Some(Loc::file_only(path)),
            format!("cannot read scene file: {e}"),
        )
    })?;
    let text = String::from_utf8(bytes).map_err(|e| {
        // Name the line of the first byte that is not UTF-8 (the text before it is).
        let valid = &e.as_bytes()[..e.utf8_error().valid_up_to()];
        let valid = std::str::from_utf8(valid).unwrap_or_default();
        let (line, col) = LineIndex::new(valid).line_col(valid.len());
        SceneError::at(
            &Loc::new(&Arc::new(path.to_path_buf()), line, col),
            "the scene file is not UTF-8 text",
        )
        .with_hint("save the file as UTF-8 (Mitsuba scene files are XML text)")
    })?;
    parse_str(&text, path)
}

/// How deep elements may nest. Real scenes nest a handful of levels (a shape, its
/// twosided bsdf, the inner bsdf, a texture, a transform); the loader and the tree's
/// destructor recurse once a level, so input-driven depth must be bounded before a
/// crafted file can exhaust the stack.
pub const MAX_DEPTH: usize = 64;

/// Parses XML text; `path` is used only for error locations.
pub fn parse_str(text: &str, path: &Path) -> Result<Element> {
    let file = Arc::new(path.to_path_buf());
    let index = LineIndex::new(text);
    let loc_at = |offset: u64| {
        let (l, c) = index.line_col(offset as usize);
        Loc::new(&file, l, c)
    };

    let mut reader = Reader::from_str(text);
    reader.config_mut().trim_text(true);
    reader.config_mut().check_end_names = true;

    let mut stack: Vec<Element> = Vec::new();
    let mut root: Option<Element> = None;
    loop {
        let start_offset = reader.buffer_position();
        let event = reader.read_event().map_err(|e| {
            SceneError::at(
                &loc_at(reader.error_position()),
                format!("malformed XML: {e}"),
            )
            .with_hint("check that every tag is closed and attributes are quoted")
        })?;
        match event {
            Event::Start(e) | Event::Empty(e) if root.is_some() => {
                let _ = e;
                return Err(SceneError::at(
                    &loc_at(start_offset),
                    "content after the root element",
                ));
            }
            Event::Start(e) => {
                let loc = loc_at(start_offset + leading_ws(text, start_offset));
                if stack.len() >= MAX_DEPTH {
                    return Err(SceneError::at(
                        &loc,
                        format!("elements are nested more than {MAX_DEPTH} deep"),
                    )
                    .with_hint(
                        "a Mitsuba scene nests a few levels (scene, shape, bsdf, texture); \
                         check for unclosed tags or a generated file gone wrong",
                    ));
                }
                stack.push(element_from(&e, loc)?);
            }
            Event::Empty(e) => {
                let el = element_from(&e, loc_at(start_offset + leading_ws(text, start_offset)))?;
                push_child(&mut stack, &mut root, el);
            }
            Event::End(_) => {
                let el = stack.pop().expect("quick-xml checks end names");
                push_child(&mut stack, &mut root, el);
            }
            Event::Text(t) => {
                let s = t.decode().unwrap_or_default();
                if !s.trim().is_empty() {
                    let loc = loc_at(start_offset);
                    return Err(SceneError::at(
                        &loc,
                        format!("unexpected text '{}' in scene file", s.trim()),
                    ));
                }
            }
            Event::Eof => break,
            // Comments, declarations, processing instructions, CDATA, doctype: ignored.
            _ => {}
        }
    }
    if let Some(open) = stack.last() {
        return Err(SceneError::at(
            &open.loc,
            format!("malformed XML: <{}> is never closed", open.tag),
        ));
    }
    root.ok_or_else(|| {
        SceneError::new(
            Some(Loc::new(&file, 1, 1)),
            "malformed XML: the file has no root element",
        )
    })
}

/// With trimming on, the reported start offset may sit before whitespace; step over it.
fn leading_ws(text: &str, offset: u64) -> u64 {
    text[offset as usize..]
        .bytes()
        .take_while(|b| b.is_ascii_whitespace())
        .count() as u64
}

fn push_child(stack: &mut [Element], root: &mut Option<Element>, el: Element) {
    match stack.last_mut() {
        Some(parent) => parent.children.push(el),
        None => *root = Some(el),
    }
}

fn element_from(e: &BytesStart<'_>, loc: Loc) -> Result<Element> {
    let tag = String::from_utf8_lossy(e.name().as_ref()).into_owned();
    let mut attrs = Vec::new();
    for a in e.attributes() {
        let a = a.map_err(|err| SceneError::at(&loc, format!("malformed attribute: {err}")))?;
        let key = String::from_utf8_lossy(a.key.as_ref()).into_owned();
        let value = a
            .unescape_value()
            .map_err(|err| SceneError::at(&loc, format!("malformed attribute value: {err}")))?
            .into_owned();
        attrs.push((key, value));
    }
    Ok(Element {
        tag,
        attrs,
        children: Vec::new(),
        loc,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn positions_are_one_based() {
        let el = parse_str(
            "<scene>\n  <float name=\"a\" value=\"1\"/>\n</scene>",
            Path::new("t.xml"),
        )
        .unwrap();
        assert_eq!((el.loc.line, el.loc.col), (1, 1));
        assert_eq!((el.children[0].loc.line, el.children[0].loc.col), (2, 3));
    }

    #[test]
    fn unclosed_tag_is_an_error_with_position() {
        let e = parse_str(
            "<scene>\n<shape type=\"sphere\">\n</scene>",
            Path::new("t.xml"),
        )
        .unwrap_err();
        assert!(e.to_string().contains("t.xml:"), "{e}");
        assert!(e.to_string().contains("malformed XML"), "{e}");
    }
}
