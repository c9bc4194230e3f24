//! The source layout's rules (issue 28): no import runs up the layers, no circle of
//! imports among the files of one module, no source file over 800 lines.
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
