//! Functions small enough to read (issue 54): none in `src/` over 200 lines, none with 8
//! or more parameters (a request struct instead), and no `too_many_arguments` allowed
//! there. The check reads the sources as text: a function starts at a line declaring
//! `fn name(`, its signature runs to the `{` that opens its body, and the body ends at
//! the first `}` alone on a line at the declaration's indentation (rustfmt's layout).

use std::fs;
use std::path::{Path, PathBuf};

const MAX_FN_LINES: usize = 200;
const MAX_PARAMS: usize = 7;

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
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
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
