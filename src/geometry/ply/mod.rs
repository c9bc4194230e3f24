//! PLY reader: the header, then the payload (ASCII, binary little- or big-endian) read
//! element by element straight into a [`RawMesh`]'s arrays. ply-rs's `DefaultElement`
//! (a map of property names per vertex and per face) peaked near 730 bytes a triangle;
//! this reader holds the mesh's own arrays and a 1 MiB buffer. It accepts what ply-rs
//! accepted and refuses what it refused, with the same checks after the parse as before.

use std::path::Path;

use glam::{Vec2, Vec3A};

use super::mesh::{available_memory, check_fits, mesh_error, RawMesh, Triangulator};
use crate::error::Result;
use source::Source;

/// Why the payload could not be read: the file ends early, or its bytes are not in the
/// header's format. (A `String`, wrapped with the file's name by [`read_ply`].)
type Parse<T> = std::result::Result<T, String>;

mod source;

/// Said after every payload error: the two ways a file goes wrong that way.
const PAYLOAD_HINT: &str = "(the data ends before the element counts its header declares, \
                            or is not in the header's format: ascii vs binary)";

#[derive(Clone, Copy, PartialEq, Debug)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn from_name(s: &str) -> Option<Scalar> {
        Some(match s {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    /// The header's name for it, for messages.
    fn name(self) -> &'static str {
        match self {
            Scalar::I8 => "char",
            Scalar::U8 => "uchar",
            Scalar::I16 => "short",
            Scalar::U16 => "ushort",
            Scalar::I32 => "int",
            Scalar::U32 => "uint",
            Scalar::F32 => "float",
            Scalar::F64 => "double",
        }
    }

    fn is_integer(self) -> bool {
        !matches!(self, Scalar::F32 | Scalar::F64)
    }

    /// The value in `b` (at least `size()` bytes), widened to f64 as the ply-rs reader
    /// did (exact for every type but f64, so a float's bits come through unchanged).
    #[inline]
    fn decode(self, b: &[u8], big: bool) -> f64 {
        macro_rules! get {
            ($t:ty, $n:expr) => {{
                let a: [u8; $n] = b[..$n].try_into().unwrap();
                if big {
                    <$t>::from_be_bytes(a)
                } else {
                    <$t>::from_le_bytes(a)
                }
            }};
        }
        match self {
            Scalar::I8 => b[0] as i8 as f64,
            Scalar::U8 => b[0] as f64,
            Scalar::I16 => get!(i16, 2) as f64,
            Scalar::U16 => get!(u16, 2) as f64,
            Scalar::I32 => get!(i32, 4) as f64,
            Scalar::U32 => get!(u32, 4) as f64,
            Scalar::F32 => get!(f32, 4) as f64,
            Scalar::F64 => get!(f64, 8),
        }
    }

    /// An integer type's value (every one fits an f64 exactly).
    #[inline]
    fn decode_int(self, b: &[u8], big: bool) -> i64 {
        self.decode(b, big) as i64
    }

    /// An ASCII token as this type (Rust's parser for it, as ply-rs), widened to f64.
    fn parse(self, t: &str) -> Option<f64> {
        match self {
            Scalar::I8 => t.parse::<i8>().ok().map(f64::from),
            Scalar::U8 => t.parse::<u8>().ok().map(f64::from),
            Scalar::I16 => t.parse::<i16>().ok().map(f64::from),
            Scalar::U16 => t.parse::<u16>().ok().map(f64::from),
            Scalar::I32 => t.parse::<i32>().ok().map(f64::from),
            Scalar::U32 => t.parse::<u32>().ok().map(f64::from),
            Scalar::F32 => t.parse::<f32>().ok().map(f64::from),
            Scalar::F64 => t.parse::<f64>().ok(),
        }
    }
}

#[derive(Clone, Copy, PartialEq, Debug)]
enum Kind {
    Scalar(Scalar),
    List { count: Scalar, item: Scalar },
}

#[derive(Debug)]
struct Property {
    name: String,
    kind: Kind,
}

#[derive(Debug)]
struct Element {
    name: String,
    count: u64,
    props: Vec<Property>,
}

impl Element {
    fn prop(&self, name: &str) -> Option<&Property> {
        self.props.iter().find(|p| p.name == name)
    }

    /// The fewest bytes one element can take in the file, to bound what is reserved
    /// for it by the file's size (a header may declare far more than the file holds).
    fn min_bytes(&self, ascii: bool) -> u64 {
        let n = if ascii {
            // A value and a separator each.
            2 * self.props.len()
        } else {
            self.props
                .iter()
                .map(|p| match p.kind {
                    Kind::Scalar(s) => s.size(),
                    Kind::List { count, .. } => count.size(),
                })
                .sum()
        };
        n.max(1) as u64
    }
}

struct Header {
    /// `None` for ASCII, else whether binary data is big-endian.
    big_endian: Option<bool>,
    elements: Vec<Element>,
}

/// What the payload's values go to: per element, per property.
#[derive(Clone, Copy, PartialEq, Debug)]
enum Role {
    Skip,
    /// x y z, nx ny nz, u v: an index into the vertex's values.
    Value(usize),
    /// The face's vertex index list.
    Indices,
}

/// The header's meaning for the mesh: where each value goes, and the first error the
/// payload cannot change (ply-rs's reader checked these after the parse, in this order).
struct Plan {
    roles: Vec<Vec<Role>>,
    normals: bool,
    uvs: bool,
    error: Option<String>,
}

/// Texture coordinates under any of the names Mitsuba's PLY reader accepts.
const UV_NAMES: [(&str, &str); 4] = [
    ("u", "v"),
    ("s", "t"),
    ("texture_u", "texture_v"),
    ("texture_s", "texture_t"),
];

impl Plan {
    fn new(header: &Header) -> Plan {
        let mut roles: Vec<Vec<Role>> = header
            .elements
            .iter()
            .map(|e| vec![Role::Skip; e.props.len()])
            .collect();
        let mut plan = Plan {
            roles: roles.clone(),
            normals: false,
            uvs: false,
            error: None,
        };
        if let Err(e) = Self::fill(header, &mut roles, &mut plan) {
            // Nothing is kept: the payload is only checked.
            plan.error = Some(e);
            return plan;
        }
        plan.roles = roles;
        plan
    }

    fn fill(header: &Header, roles: &mut [Vec<Role>], plan: &mut Plan) -> Parse<()> {
        let find = |name: &str| header.elements.iter().position(|e| e.name == name);
        let vi = find("vertex").ok_or("PLY file has no \"vertex\" element")?;
        let vertex = &header.elements[vi];
        // Every vertex has the header's properties; with none, nothing is asked of them.
        let any = vertex.count > 0;
        let mut assign = |names: &[&str], first: usize, what: String| -> Parse<bool> {
            let props: Vec<Option<usize>> = names
                .iter()
                .map(|n| vertex.props.iter().position(|p| p.name == *n))
                .collect();
            if props.iter().any(Option::is_none) {
                return Ok(false);
            }
            for (k, p) in props.into_iter().flatten().enumerate() {
                if !matches!(vertex.props[p].kind, Kind::Scalar(_)) {
                    return Err(format!("PLY vertex 0 lacks numeric {what}"));
                }
                roles[vi][p] = Role::Value(first + k);
            }
            Ok(true)
        };
        if any {
            if let Some((a, b)) = UV_NAMES
                .into_iter()
                .find(|(a, b)| vertex.prop(a).is_some() && vertex.prop(b).is_some())
            {
                plan.uvs = assign(&[a, b], 6, format!("{a}, {b}"))?;
            }
            if !assign(&["x", "y", "z"], 0, "x, y, z".into())? {
                return Err("PLY vertex 0 lacks numeric x, y, z".into());
            }
            plan.normals = assign(&["nx", "ny", "nz"], 3, "nx, ny, nz".into())?;
        }
        let fi = find("face").ok_or("PLY file has no \"face\" element")?;
        let face = &header.elements[fi];
        let indices = face
            .prop("vertex_indices")
            .or_else(|| face.prop("vertex_index"));
        match indices.map(|p| (p, p.kind)) {
            Some((p, Kind::List { item, .. })) if item.is_integer() => {
                let k = face.props.iter().position(|q| q.name == p.name).unwrap();
                roles[fi][k] = Role::Indices;
            }
            _ if face.count > 0 => return Err("PLY face 0 has no vertex_indices list".into()),
            _ => {}
        }
        Ok(())
    }
}

/// Reads a PLY file (ASCII or binary): vertex x, y, z and optional nx, ny, nz and texture
/// coordinates; faces from `vertex_indices` (or `vertex_index`), polygons fan-triangulated.
pub fn read_ply(path: &Path) -> Result<RawMesh> {
    read_ply_within(path, available_memory())
}

/// [`read_ply`], refusing a mesh whose arrays would not fit in `available` bytes.
fn read_ply_within(path: &Path, available: Option<u64>) -> Result<RawMesh> {
    let mut src =
        Source::open(path).map_err(|e| mesh_error(path, format!("cannot open PLY file: {e}")))?;
    let header = read_header(&mut src).map_err(|e| mesh_error(path, e))?;
    let plan = Plan::new(&header);
    let n_vertices = header
        .elements
        .iter()
        .find(|e| e.name == "vertex")
        .map_or(0, |e| e.count);
    let n_faces = header
        .elements
        .iter()
        .find(|e| e.name == "face")
        .map_or(0, |e| e.count);
    let mut sink = Sink {
        positions: Vec::new(),
        normals: Vec::new(),
        uvs: Vec::new(),
        plan: &plan,
        faces: Triangulator::new(n_vertices),
        values: [0.0; 8],
        poly: Vec::new(),
    };
    let ascii = header.big_endian.is_none();
    // A file that can hold what its header declares has at least a triangle a face (a
    // face of fewer than 3 vertices is an error): refused here if that cannot fit. A
    // file too short for its counts fails as truncated instead.
    let declared = header.elements.iter().fold(0u64, |sum, e| {
        sum.saturating_add(e.count.saturating_mul(e.min_bytes(ascii)))
    });
    if declared <= src.remaining() {
        check_fits(path, n_faces, n_vertices, available)?;
    }
    for (e, roles) in header.elements.iter().zip(&plan.roles) {
        let keep = roles.iter().any(|r| *r != Role::Skip);
        let cap = e.count.min(src.remaining() / e.min_bytes(ascii) + 1) as usize;
        sink.reserve(keep, roles, cap);
        read_element(&mut src, e, roles, header.big_endian, &mut sink)
            .map_err(|m| mesh_error(path, format!("cannot parse PLY file: {m} {PAYLOAD_HINT}")))?;
    }
    // Data past the declared elements: Mitsuba ignores it, and so does this reader,
    // but a header count that is too small is worth a word.
    let trailing = src
        .any_non_whitespace()
        .map_err(|e| mesh_error(path, format!("cannot read PLY file: {e}")))?;
    if let Some(e) = &plan.error {
        return Err(mesh_error(path, e.clone()));
    }
    let triangles = sink.faces.finish(path)?;
    let mut warnings = Vec::new();
    if trailing {
        warnings.push(format!(
            "{}: data after the {} vertices and {} faces the header declares is ignored (as Mitsuba does); is a count in the header too small?",
            path.display(),
            n_vertices,
            n_faces
        ));
    }
    Ok(RawMesh {
        positions: sink.positions,
        normals: plan.normals.then_some(sink.normals),
        triangles,
        uvs: plan.uvs.then_some(sink.uvs),
        warnings,
    })
}

/// Where one element's values go as they are read.
struct Sink<'a> {
    positions: Vec<Vec3A>,
    normals: Vec<Vec3A>,
    uvs: Vec<Vec2>,
    plan: &'a Plan,
    faces: Triangulator,
    /// The current vertex's x y z, nx ny nz, u v.
    values: [f64; 8],
    /// The current face's vertex indices.
    poly: Vec<i64>,
}

impl Sink<'_> {
    fn reserve(&mut self, keep: bool, roles: &[Role], n: usize) {
        if !keep {
            return;
        }
        if roles.contains(&Role::Indices) {
            self.faces.triangles.reserve_exact(n);
            return;
        }
        self.positions.reserve_exact(n);
        if self.plan.normals {
            self.normals.reserve_exact(n);
        }
        if self.plan.uvs {
            self.uvs.reserve_exact(n);
        }
    }

    /// Ends an element: a vertex's values or a face's indices go to the arrays.
    #[inline]
    fn end_element(&mut self, is_face: bool) {
        if is_face {
            self.faces.add(&self.poly);
        } else {
            let v = self.values.map(|x| x as f32);
            self.positions.push(Vec3A::new(v[0], v[1], v[2]));
            if self.plan.normals {
                self.normals.push(Vec3A::new(v[3], v[4], v[5]));
            }
            if self.plan.uvs {
                self.uvs.push(Vec2::new(v[6], v[7]));
            }
        }
    }
}

/// Reads `e.count` elements, ASCII (one line each) or binary.
fn read_element(
    src: &mut Source,
    e: &Element,
    roles: &[Role],
    big_endian: Option<bool>,
    sink: &mut Sink,
) -> Parse<()> {
    let is_face = roles.contains(&Role::Indices);
    let store = roles.iter().any(|r| *r != Role::Skip);
    if e.props.is_empty() && big_endian.is_some() {
        // Elements of nothing take no bytes.
        return Ok(());
    }
    for i in 0..e.count {
        let read = match big_endian {
            Some(big) => binary_element(src, e, roles, big, sink),
            // Empty lines to the end of the file, which ply-rs read as elements of nothing.
            None if e.props.is_empty() && src.remaining() == 0 => return Ok(()),
            None => ascii_element(src, e, roles, sink),
        };
        read.map_err(|m| format!("element \"{}\" {i}: {m}", e.name))?;
        if store {
            sink.end_element(is_face);
        }
    }
    Ok(())
}

fn binary_element(
    src: &mut Source,
    e: &Element,
    roles: &[Role],
    big: bool,
    sink: &mut Sink,
) -> Parse<()> {
    for (p, role) in e.props.iter().zip(roles) {
        match p.kind {
            Kind::Scalar(s) => {
                let b = src.take(s.size())?;
                if let Role::Value(k) = role {
                    sink.values[*k] = s.decode(b, big);
                }
            }
            Kind::List { count, item } => {
                if !count.is_integer() {
                    return Err(format!("list \"{}\" has a non-integer length type", p.name));
                }
                let n = count.decode_int(src.take(count.size())?, big);
                if n < 0 {
                    return Err(format!("list \"{}\" has length {n}", p.name));
                }
                let bytes = (n as u64).saturating_mul(item.size() as u64);
                if bytes > src.remaining() {
                    return Err(format!("the file ends inside list \"{}\"", p.name));
                }
                let b = src.take(bytes as usize)?;
                if *role == Role::Indices {
                    sink.poly.clear();
                    sink.poly
                        .extend(b.chunks_exact(item.size()).map(|c| item.decode_int(c, big)));
                }
            }
        }
    }
    Ok(())
}

fn ascii_element(src: &mut Source, e: &Element, roles: &[Role], sink: &mut Sink) -> Parse<()> {
    let line = src.line()?;
    // A line ends in \n, \r\n or \r (ply-rs's grammar); values are split by spaces and tabs.
    let line = line.strip_suffix(b"\r").unwrap_or(line);
    let text = std::str::from_utf8(line).map_err(|_| "the line is not text".to_string())?;
    let mut tokens = text.split([' ', '\t']).filter(|t| !t.is_empty());
    // ply-rs checked every value on the line, the ones past the element's too.
    if let Some(bad) = tokens.clone().find(|t| !is_number(t.as_bytes())) {
        return Err(format!("\"{bad}\" is not a number"));
    }
    let mut next = |what: &str| {
        tokens
            .next()
            .ok_or_else(|| format!("the line ends before {what}"))
    };
    for (p, role) in e.props.iter().zip(roles) {
        let t = next(&p.name)?;
        match p.kind {
            Kind::Scalar(s) => {
                let v = s
                    .parse(t)
                    .ok_or_else(|| format!("{} = \"{t}\" is not a {}", p.name, s.name()))?;
                if let Role::Value(k) = role {
                    sink.values[*k] = v;
                }
            }
            Kind::List { item, .. } => {
                // ply-rs read an ASCII list's length as an unsigned integer, whatever its type.
                let n: usize = t
                    .parse()
                    .map_err(|_| format!("list \"{}\" has length \"{t}\"", p.name))?;
                if *role == Role::Indices {
                    sink.poly.clear();
                }
                for _ in 0..n {
                    let t = next(&p.name)?;
                    let v = item.parse(t).ok_or_else(|| {
                        format!("{} item \"{t}\" is not a {}", p.name, item.name())
                    })?;
                    if *role == Role::Indices {
                        sink.poly.push(v as i64);
                    }
                }
            }
        }
    }
    Ok(())
}

/// ply-rs's number grammar: [+-]digits[.digits][e[+-]digits].
fn is_number(t: &[u8]) -> bool {
    let mut i = usize::from(matches!(t.first(), Some(b'+' | b'-')));
    let digits = |i: &mut usize| {
        let start = *i;
        while t.get(*i).is_some_and(u8::is_ascii_digit) {
            *i += 1;
        }
        *i > start
    };
    if !digits(&mut i) {
        return false;
    }
    if t.get(i) == Some(&b'.') {
        i += 1;
        if !digits(&mut i) {
            return false;
        }
    }
    if t.get(i) == Some(&b'e') {
        i += 1;
        if matches!(t.get(i), Some(b'+' | b'-')) {
            i += 1;
        }
        if !digits(&mut i) {
            return false;
        }
    }
    i == t.len()
}

/// Reads the header up to and including `end_header`; an error is the whole message.
fn read_header(src: &mut Source) -> Parse<Header> {
    let at = |n: usize, m: String| format!("cannot parse PLY file: header line {n}: {m}");
    let mut format: Option<(Option<bool>, String)> = None;
    let mut elements: Vec<Element> = Vec::new();
    for n in 1.. {
        if src.remaining() == 0 {
            return Err(format!(
                "cannot parse PLY file: the header ends at line {} without \"end_header\"",
                n - 1
            ));
        }
        let line = src.line().map_err(|m| at(n, m))?;
        let line = line.strip_suffix(b"\r").unwrap_or(line);
        let text = String::from_utf8_lossy(line);
        let words: Vec<&str> = text.split([' ', '\t']).filter(|w| !w.is_empty()).collect();
        match (n, &words[..]) {
            (1, ["ply"]) => {}
            (1, _) => {
                return Err(at(
                    1,
                    format!("\"{text}\" where \"ply\" should be: this is not a PLY file"),
                ))
            }
            (_, ["end_header"]) => break,
            (_, ["comment" | "obj_info", ..]) => {}
            (_, ["format", encoding, version]) => {
                let big = match *encoding {
                    "ascii" => None,
                    "binary_little_endian" => Some(false),
                    "binary_big_endian" => Some(true),
                    _ => return Err(at(n, format!("unknown format \"{encoding}\" (ascii, binary_little_endian or binary_big_endian)"))),
                };
                if !is_version(version) {
                    return Err(format!("PLY header line {n}: format version \"{version}\" is not a version number such as 1.0"));
                }
                match &format {
                    Some(f) if *f != (big, version.to_string()) => {
                        return Err(at(n, "a second, different format line".into()))
                    }
                    _ => format = Some((big, version.to_string())),
                }
            }
            (_, ["element", name, count]) => {
                let Some(count) = digits_u32(count) else {
                    return Err(format!("PLY header line {n}: element \"{name}\" has count \"{count}\"; expected a number below 2^32"));
                };
                if elements.iter().any(|e| e.name == *name) {
                    return Err(at(n, format!("a second element \"{name}\"")));
                }
                elements.push(Element {
                    name: name.to_string(),
                    count: count.into(),
                    props: Vec::new(),
                });
            }
            (_, ["property", rest @ ..]) => {
                let Some(e) = elements.last_mut() else {
                    return Err(at(n, "a property before any element".into()));
                };
                let (kind, name) = match rest {
                    [t, name] => (Scalar::from_name(t).map(Kind::Scalar), name),
                    ["list", c, t, name] => (
                        Scalar::from_name(c)
                            .zip(Scalar::from_name(t))
                            .map(|(count, item)| Kind::List { count, item }),
                        name,
                    ),
                    _ => (None, &""),
                };
                let Some(kind) = kind else {
                    return Err(at(n, format!("cannot read \"{text}\" (a property is \"property TYPE NAME\" or \"property list TYPE TYPE NAME\", TYPE such as uchar, int, float)")));
                };
                if e.prop(name).is_some() {
                    return Err(at(
                        n,
                        format!("a second property \"{name}\" in element \"{}\"", e.name),
                    ));
                }
                e.props.push(Property {
                    name: name.to_string(),
                    kind,
                });
            }
            _ => return Err(at(n, format!("cannot read \"{text}\""))),
        }
    }
    let Some((big_endian, _)) = format else {
        return Err("cannot parse PLY file: the header has no format line".into());
    };
    Ok(Header {
        big_endian,
        elements,
    })
}

/// A run of digits (ply-rs's grammar: no sign) below 2³² (ply-rs panicked on one past
/// u64, and no mesh this renderer can hold has more).
fn digits_u32(t: &str) -> Option<u32> {
    t.bytes()
        .all(|b| b.is_ascii_digit())
        .then(|| t.parse().ok())
        .flatten()
}

/// `major.minor`, each [`digits_u32`].
fn is_version(v: &str) -> bool {
    v.split_once('.')
        .is_some_and(|(a, b)| digits_u32(a).is_some() && digits_u32(b).is_some())
}

#[cfg(test)]
mod tests;
