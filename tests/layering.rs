//! The source layout's rules (issue 28): no import runs up the layers, no circle of
//! imports among the files of one module, no source file over 800 lines; and (issue 54)
//! no function over 200 lines or with 8 or more parameters.
//!
//! The check reads `src/**/*.rs` as text and follows every `crate::…` and `super::…`
//! path, in code and in `#[cfg(test)]` modules alike (a test that reaches up ties the
//! layers together as much as code does); comment lines are skipped.

use std::collections::{BTreeMap, BTreeSet};
use std::fs;
use std::path::{Path, PathBuf};

/// The library's top-level modules, lowest first. A module may use only those before it.
const LAYERS: &[&str] = &[
    "error",      // Loc, SceneError
    "simd",       // f32 lanes in a register
    "sampling",   // Pcg32, warps, MIS weight
    "image",      // Image, EXR/PNG, statistics
    "denoise",    // denoisers on images (OIDN)
    "xml",        // file → SceneDescription
    "geometry",   // rays, shapes, meshes, BVH
    "texture",    // constant, checkerboard, bitmap
    "medium",     // homogeneous media, phase functions
    "bsdf",       // BSDFs, Fresnel
    "emitter",    // lights and their selection
    "scene",      // the render state, built from plain objects
    "load",       // SceneDescription → Scene (one file per plugin kind)
    "integrator", // path, volpath, the render driver
    "fit",        // a medium's parameters from images
    "optimize",   // a grid medium's voxels from images
    "regularize", // the paper's method
    "report",     // mediareg table
];

const MAX_LINES: usize = 800;

/// Files allowed over `MAX_LINES`, with why (none now).
const LONG_FILES: &[(&str, &str)] = &[];

fn src() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("src")
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let mut entries: Vec<_> = fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    entries.sort();
    for p in entries {
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|e| e == "rs") {
            out.push(p);
        }
    }
}

/// A source file of the library: its module path and its text without comment lines.
struct SourceFile {
    rel: String,
    module: Vec<String>,
    lines: Vec<String>,
}

fn module_path(rel: &Path) -> Vec<String> {
    let mut parts: Vec<String> = rel
        .iter()
        .map(|s| s.to_string_lossy().into_owned())
        .collect();
    let last = parts.pop().unwrap();
    let stem = last.trim_end_matches(".rs");
    if stem != "mod" && stem != "lib" {
        parts.push(stem.to_string());
    }
    parts
}

fn library_files() -> Vec<SourceFile> {
    let root = src();
    let mut paths = Vec::new();
    rust_files(&root, &mut paths);
    paths
        .into_iter()
        // The command line (src/bin) sits above every layer and uses the library by
        // its crate name, not `crate::`.
        .filter(|p| !p.starts_with(root.join("bin")))
        .map(|p| {
            let rel = p.strip_prefix(&root).unwrap();
            let module = module_path(rel);
            let text = fs::read_to_string(&p).unwrap();
            let lines = text
                .lines()
                .filter(|l| !l.trim_start().starts_with("//"))
                .map(str::to_string)
                .collect();
            SourceFile {
                rel: format!("src/{}", rel.display()),
                module,
                lines,
            }
        })
        .collect()
}

fn ident_at(s: &str) -> (&str, &str) {
    let end = s
        .find(|c: char| !(c.is_alphanumeric() || c == '_'))
        .unwrap_or(s.len());
    (&s[..end], &s[end..])
}

/// The paths after a `crate::` or `super::` prefix: `a::b::C` → [a, b, C]; a group
/// `{a, b::c}` → [a], [b, c] (its first two segments are all the check needs).
fn paths_after(s: &str) -> Vec<Vec<String>> {
    let mut segs = Vec::new();
    let mut rest = s;
    loop {
        if let Some(group) = rest.strip_prefix('{') {
            let mut depth = 1;
            let mut end = group.len();
            for (i, c) in group.char_indices() {
                match c {
                    '{' => depth += 1,
                    '}' => {
                        depth -= 1;
                        if depth == 0 {
                            end = i;
                            break;
                        }
                    }
                    _ => {}
                }
            }
            let inner = &group[..end];
            let mut out = Vec::new();
            let mut depth = 0;
            let mut start = 0;
            for (i, c) in inner.char_indices() {
                match c {
                    '{' => depth += 1,
                    '}' => depth -= 1,
                    ',' if depth == 0 => {
                        out.push(&inner[start..i]);
                        start = i + 1;
                    }
                    _ => {}
                }
            }
            out.push(&inner[start..]);
            return out
                .into_iter()
                .map(str::trim)
                .filter(|p| !p.is_empty() && *p != "self")
                .flat_map(|p| {
                    paths_after(p).into_iter().map(|tail| {
                        let mut v = segs.clone();
                        v.extend(tail);
                        v
                    })
                })
                .collect();
        }
        let (id, after) = ident_at(rest);
        if id.is_empty() {
            break;
        }
        segs.push(id.to_string());
        match after.strip_prefix("::") {
            Some(a) => rest = a,
            None => break,
        }
    }
    vec![segs]
}

/// Every absolute module path a file names: `crate::x::…` as is, `super::…` resolved
/// from the module the line sits in (a test module is one level below its file).
fn references(f: &SourceFile) -> Vec<Vec<String>> {
    // Everything after an inline `#[cfg(test)] mod name {` is taken as inside it: the
    // project keeps test modules last in their file.
    let text_of = |lines: &[String]| lines.join("\n");
    let test_start = (1..f.lines.len())
        .find(|&i| {
            let l = f.lines[i].trim();
            f.lines[i - 1].trim() == "#[cfg(test)]" && l.starts_with("mod ") && l.ends_with('{')
        })
        .unwrap_or(f.lines.len());
    let mut refs = Vec::new();
    for (text, in_tests) in [
        (text_of(&f.lines[..test_start]), false),
        (text_of(&f.lines[test_start..]), true),
    ] {
        let mut scope = f.module.clone();
        if in_tests {
            scope.push("(test module)".into());
        }
        let bytes = text.as_bytes();
        let mut i = 0;
        while i < text.len() {
            let boundary =
                i == 0 || !(bytes[i - 1].is_ascii_alphanumeric() || bytes[i - 1] == b'_');
            let rest = &text[i..];
            if boundary && rest.starts_with("crate::") {
                for p in paths_after(&rest["crate::".len()..]) {
                    refs.push(p);
                }
                i += "crate::".len();
            } else if boundary && rest.starts_with("super::") {
                let mut up = 0;
                let mut r = rest;
                while let Some(a) = r.strip_prefix("super::") {
                    up += 1;
                    r = a;
                }
                let base = &scope[..scope.len().saturating_sub(up)];
                for p in paths_after(r) {
                    let mut abs = base.to_vec();
                    abs.extend(p);
                    refs.push(abs);
                }
                i += up * "super::".len();
            } else {
                i += rest.chars().next().unwrap().len_utf8();
            }
        }
    }
    refs.retain(|r| !r.is_empty());
    refs
}

/// `pub use child::{A, B};` in a mod.rs (or lib.rs): item name → child module.
fn reexports(f: &SourceFile) -> BTreeMap<String, String> {
    let mut map = BTreeMap::new();
    for l in &f.lines {
        let t = l.trim();
        let Some(u) = t
            .strip_prefix("pub use ")
            .or_else(|| t.strip_prefix("pub(crate) use "))
        else {
            continue;
        };
        let u = u.strip_prefix("self::").unwrap_or(u).trim_end_matches(';');
        for p in paths_after(u) {
            if p.len() >= 2 {
                map.insert(p.last().unwrap().clone(), p[0].clone());
            }
        }
    }
    map
}

fn layer_violations(files: &[SourceFile]) -> Vec<String> {
    let lib = files.iter().find(|f| f.rel == "src/lib.rs").unwrap();
    let root_items = reexports(lib);
    let mut out = Vec::new();
    for f in files.iter().filter(|f| !f.module.is_empty()) {
        let own = f.module[0].as_str();
        let Some(own_layer) = LAYERS.iter().position(|l| *l == own) else {
            continue;
        };
        let mut seen = BTreeSet::new();
        for r in references(f) {
            let target = if LAYERS.contains(&r[0].as_str()) {
                r[0].clone()
            } else if let Some(m) = root_items.get(&r[0]) {
                m.clone()
            } else {
                format!("(crate root: {})", r[0])
            };
            if target == own {
                continue;
            }
            let ok = LAYERS
                .iter()
                .position(|l| *l == target)
                .is_some_and(|t| t < own_layer);
            if !ok && seen.insert(target.clone()) {
                out.push(format!(
                    "{} ({own}) uses {} ({target})",
                    f.rel,
                    r.join("::")
                ));
            }
        }
    }
    out
}

/// For each module with children: the graph among its children (files or folders;
/// the module's own file (mod.rs), which declares and re-exports them and holds what
/// they share, is no node: an item re-exported from a child counts as that child's),
/// and its circles.
fn circles(files: &[SourceFile]) -> Vec<String> {
    let all_modules: BTreeSet<Vec<String>> = files.iter().map(|f| f.module.clone()).collect();
    // The file of each module with children: its mod.rs, or a `name.rs` beside `name/`.
    let mods: BTreeMap<Vec<String>, &SourceFile> = files
        .iter()
        .filter(|f| {
            !f.module.is_empty()
                && all_modules
                    .iter()
                    .any(|m| m.len() > f.module.len() && m.starts_with(&f.module))
        })
        .map(|f| (f.module.clone(), f))
        .collect();
    let mut out = Vec::new();
    for (dir, mod_rs) in &mods {
        let n = dir.len();
        let children: BTreeSet<String> = all_modules
            .iter()
            .filter(|m| m.len() > n && m.starts_with(dir))
            .map(|m| m[n].clone())
            .collect();
        let re = reexports(mod_rs);
        let mut edges: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
        for f in files
            .iter()
            .filter(|f| f.module.len() > n && f.module.starts_with(dir))
        {
            let from = f.module[n].clone();
            for r in references(f) {
                if r.len() <= n || !r.starts_with(dir) {
                    continue;
                }
                let to = if children.contains(&r[n]) {
                    r[n].clone()
                } else if let Some(c) = re.get(&r[n]) {
                    c.clone()
                } else {
                    continue; // an item of the module's mod.rs
                };
                if to != from {
                    edges.entry(from.clone()).or_default().insert(to);
                }
            }
        }
        // Depth-first search for a back edge; report each circle once.
        fn visit(
            node: &str,
            edges: &BTreeMap<String, BTreeSet<String>>,
            stack: &mut Vec<String>,
            done: &mut BTreeSet<String>,
            found: &mut BTreeSet<String>,
        ) {
            if done.contains(node) {
                return;
            }
            if let Some(i) = stack.iter().position(|s| s == node) {
                let mut cyc: Vec<String> = stack[i..].to_vec();
                cyc.push(node.to_string());
                found.insert(cyc.join(" → "));
                return;
            }
            stack.push(node.to_string());
            for next in edges.get(node).into_iter().flatten() {
                visit(next, edges, stack, done, found);
            }
            stack.pop();
            done.insert(node.to_string());
        }
        let mut found = BTreeSet::new();
        let mut done = BTreeSet::new();
        for c in &children {
            visit(c, &edges, &mut Vec::new(), &mut done, &mut found);
        }
        for c in found {
            out.push(format!("src/{}: {c}", dir.join("/")));
        }
    }
    out
}

#[test]
fn every_top_level_module_has_a_layer() {
    let files = library_files();
    let tops: BTreeSet<&str> = files
        .iter()
        .filter(|f| !f.module.is_empty())
        .map(|f| f.module[0].as_str())
        .collect();
    let missing: Vec<_> = tops.iter().filter(|t| !LAYERS.contains(t)).collect();
    assert!(missing.is_empty(), "modules not in LAYERS: {missing:?}");
    let absent: Vec<_> = LAYERS.iter().filter(|l| !tops.contains(*l)).collect();
    assert!(
        absent.is_empty(),
        "LAYERS names modules that do not exist: {absent:?}"
    );
}

#[test]
fn no_import_runs_up_the_layers() {
    let v = layer_violations(&library_files());
    assert!(v.is_empty(), "upward imports:\n  {}", v.join("\n  "));
}

#[test]
fn no_circle_among_a_modules_files() {
    let v = circles(&library_files());
    assert!(v.is_empty(), "import circles:\n  {}", v.join("\n  "));
}

#[test]
fn no_source_file_over_800_lines() {
    let root = src();
    let mut paths = Vec::new();
    rust_files(&root, &mut paths);
    let mut long = Vec::new();
    for p in paths {
        let rel = format!("src/{}", p.strip_prefix(&root).unwrap().display());
        let n = fs::read_to_string(&p).unwrap().lines().count();
        if n > MAX_LINES && !LONG_FILES.iter().any(|(f, _)| *f == rel) {
            long.push(format!("{rel}: {n} lines"));
        }
    }
    assert!(
        long.is_empty(),
        "files over {MAX_LINES} lines:\n  {}",
        long.join("\n  ")
    );
}

/// The checker itself: it sees a circle and an upward import when there is one.
#[test]
fn the_checker_sees_what_it_should() {
    let file = |rel: &str, text: &str| {
        let module = module_path(Path::new(rel));
        SourceFile {
            rel: format!("src/{rel}"),
            module,
            lines: text.lines().map(str::to_string).collect(),
        }
    };
    let files = vec![
        file("lib.rs", "pub mod bsdf;\npub use scene::Scene;"),
        file("bsdf/mod.rs", "mod a;\nmod b;\npub use b::Thing;"),
        file(
            "bsdf/a.rs",
            "use super::Thing;\nuse crate::{error::Loc, Scene};",
        ),
        file("bsdf/b.rs", "use super::a::f;"),
        file(
            "bsdf/c.rs",
            "#[cfg(test)]\nmod tests {\n    use super::*;\n    use super::super::b::g;\n}",
        ),
    ];
    assert_eq!(circles(&files), vec!["src/bsdf: a → b → a".to_string()]);
    assert_eq!(
        layer_violations(&files),
        vec!["src/bsdf/a.rs (bsdf) uses Scene (scene)".to_string()]
    );
}

// ---- Functions small enough to read (issue 54) ----
// None in `src/` over 200 lines, none with 8 or more parameters (a request struct
// instead), and no `too_many_arguments` allowed there. A function starts at a line
// declaring `fn name(`, its signature runs to the `{` that opens its body, and the body
// ends at the first `}` alone on a line at the declaration's indentation (rustfmt's
// layout).

const MAX_FN_LINES: usize = 200;
const MAX_PARAMS: usize = 7;

/// A function found in a source text: name, first line (1-based), lines, parameters.
#[derive(Debug, PartialEq)]
struct Function {
    name: String,
    line: usize,
    lines: usize,
    params: usize,
}

/// The name after `fn ` where a line declares a function (`pub`, `const`, `unsafe`,
/// `extern` qualifiers allowed), with the line's indentation.
fn declared(line: &str) -> Option<(usize, String)> {
    let indent = line.len() - line.trim_start().len();
    let mut rest = line.trim_start();
    if rest.starts_with("//") {
        return None;
    }
    if let Some(r) = rest.strip_prefix("pub") {
        rest = match r.strip_prefix('(') {
            Some(r) => r.split_once(')')?.1,
            None => r,
        }
        .trim_start();
    }
    for q in ["const ", "unsafe ", "async ", "extern \"C\" "] {
        rest = rest.strip_prefix(q).unwrap_or(rest);
    }
    let name: String = rest
        .strip_prefix("fn ")?
        .chars()
        .take_while(|c| c.is_alphanumeric() || *c == '_')
        .collect();
    (!name.is_empty()).then_some((indent, name))
}

/// Top-level parameters of the signature of `name` (the text from its declaration to
/// the body's `{`), `self` not counted.
fn count_params(sig: &str, name: &str) -> usize {
    let Some(at) = sig.find(&format!("fn {name}")) else {
        return 0;
    };
    // Past the name and its generic parameters (which may hold `Fn(…)`), the list.
    let mut angle = 0i32;
    let mut open = None;
    for (k, c) in sig[at + 3 + name.len()..].char_indices() {
        match c {
            '<' => angle += 1,
            '>' => angle -= 1,
            '(' if angle == 0 => {
                open = Some(at + 3 + name.len() + k);
                break;
            }
            _ => {}
        }
    }
    let Some(open) = open else { return 0 };
    let (mut depth, mut parts, mut current) = (0i32, Vec::new(), String::new());
    let mut prev = ' ';
    for c in sig[open..].chars() {
        match c {
            '(' | '[' | '{' | '<' => depth += 1,
            // (The `>` of an `->` in a closure's type closes nothing.)
            '>' if prev == '-' => {}
            ')' | ']' | '}' | '>' => depth -= 1,
            _ => {}
        }
        prev = c;
        if depth == 0 {
            break;
        }
        if c == ',' && depth == 1 {
            parts.push(std::mem::take(&mut current));
        } else {
            current.push(c);
        }
    }
    parts.push(current);
    parts
        .iter()
        .map(|p| p.trim().trim_start_matches('(').trim())
        .filter(|p| !p.is_empty())
        .filter(|p| !matches!(*p, "self" | "&self" | "&mut self" | "mut self"))
        .count()
}

fn functions(text: &str) -> Vec<Function> {
    let lines: Vec<&str> = text.lines().collect();
    let mut out = Vec::new();
    let mut i = 0;
    while i < lines.len() {
        let Some((indent, name)) = declared(lines[i]) else {
            i += 1;
            continue;
        };
        let mut sig = String::new();
        let mut j = i;
        // The signature ends at the body's `{` (or a `;`: a declaration only).
        let body = loop {
            sig.push_str(lines[j]);
            sig.push('\n');
            let t = lines[j].trim_end();
            if t.ends_with('{') {
                break true;
            }
            if t.ends_with(';') || j + 1 == lines.len() {
                break false;
            }
            j += 1;
        };
        let params = count_params(&sig, &name);
        if !body || lines[j].trim_end().ends_with("{}") {
            out.push(Function {
                name,
                line: i + 1,
                lines: j - i + 1,
                params,
            });
            i = j + 1;
            continue;
        }
        let close = format!("{}}}", " ".repeat(indent));
        let end = (j + 1..lines.len())
            .find(|&k| lines[k].trim_end() == close)
            .unwrap_or(lines.len() - 1);
        out.push(Function {
            name,
            line: i + 1,
            lines: end - i + 1,
            params,
        });
        // Nested functions are counted inside their parent and on their own.
        i = j + 1;
    }
    out
}

fn too_large(text: &str) -> Vec<String> {
    functions(text)
        .into_iter()
        .filter(|f| f.lines > MAX_FN_LINES || f.params > MAX_PARAMS)
        .map(|f| {
            format!(
                "{} (line {}): {} lines, {} parameters",
                f.name, f.line, f.lines, f.params
            )
        })
        .collect()
}

#[test]
fn no_function_in_src_is_over_200_lines_or_takes_8_parameters() {
    let root = src();
    let mut paths = Vec::new();
    rust_files(&root, &mut paths);
    let mut found = Vec::new();
    let mut scanned = 0;
    for p in paths {
        let rel = p.strip_prefix(&root).unwrap().display().to_string();
        let text = fs::read_to_string(&p).unwrap();
        scanned += functions(&text).len();
        found.extend(
            too_large(&text)
                .into_iter()
                .map(|f| format!("src/{rel}: {f}")),
        );
        if text.contains("clippy::too_many_arguments") {
            found.push(format!("src/{rel}: allows clippy::too_many_arguments"));
        }
    }
    assert!(
        scanned > 1000,
        "only {scanned} functions found: the scanner is broken"
    );
    assert!(
        found.is_empty(),
        "functions too large:\n  {}",
        found.join("\n  ")
    );
}

/// The scanner itself: it finds a long function and one of 8 parameters (tuples and
/// generics counted as one each, `self` not at all), and nothing in small ones.
#[test]
fn the_scanner_sees_long_functions_and_long_argument_lists() {
    let long_body = "    let x = 1;\n".repeat(MAX_FN_LINES);
    let text = format!(
        "fn small(a: u32) -> u32 {{\n    a\n}}\n\
         pub(crate) fn long() {{\n{long_body}}}\n\
         impl A {{\n    pub fn many(\n        &self,\n        a: u32,\n        (b, c): (u32, u32),\n        \
         d: Vec<(u32, u32)>,\n        e: u32,\n        f: u32,\n        g: u32,\n        h: u32,\n        \
         i: impl Fn(u32) -> u32,\n    ) {{\n    }}\n\n    fn seven(&mut self, a: u8, b: u8, c: u8, d: u8, e: u8, f: u8, g: u8) {{}}\n}}\n"
    );
    let f = functions(&text);
    let names: Vec<_> = f.iter().map(|f| (f.name.as_str(), f.params)).collect();
    assert_eq!(
        names,
        [("small", 1), ("long", 0), ("many", 8), ("seven", 7)]
    );
    assert_eq!(f[1].lines, MAX_FN_LINES + 2);
    let flagged = too_large(&text);
    assert_eq!(flagged.len(), 2, "{flagged:?}");
    assert!(flagged[0].starts_with("long") && flagged[1].starts_with("many"));
}
