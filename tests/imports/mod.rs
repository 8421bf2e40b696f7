//! How the import checks (`tests/module_cycles.rs`, `tests/layering.rs`)
//! read a crate's source: every path a file names through `crate::`,
//! `super::`, `self::` or `mckibben::` (in `use` lines, grouped or not, and
//! written out in code), or through a child module in a `use` line,
//! resolved to the module it reaches. Comments, strings and character
//! literals are skipped.

// Each test binary compiles its own copy and uses what it needs.
#![allow(dead_code)]

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// A module path: the crate (`mckibben` for the library, `main` for the
/// binary), then the modules below it.
pub type ModPath = Vec<String>;

#[derive(Debug, Clone, PartialEq)]
enum Tok {
    Ident(String),
    /// `::`
    Sep,
    Punct(char),
}

/// The tokens of `text` that paths are made of: identifiers, `::` and single
/// punctuation. Comments, string literals (plain, byte and raw), character
/// literals and lifetimes leave nothing, so a path quoted in a doc comment or
/// a message draws no edge, and a `'{'` does not upset the brace count.
fn tokens(text: &str) -> Vec<Tok> {
    let c: Vec<char> = text.chars().collect();
    let mut out = Vec::new();
    let mut i = 0;
    while i < c.len() {
        let ch = c[i];
        let next = c.get(i + 1).copied();
        if ch == '/' && next == Some('/') {
            while i < c.len() && c[i] != '\n' {
                i += 1;
            }
        } else if ch == '/' && next == Some('*') {
            // Block comments nest in Rust.
            let mut depth = 0;
            while i < c.len() {
                if c[i] == '/' && c.get(i + 1) == Some(&'*') {
                    depth += 1;
                    i += 2;
                } else if c[i] == '*' && c.get(i + 1) == Some(&'/') {
                    depth -= 1;
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    i += 1;
                }
            }
        } else if ch == '"' {
            i = skip_string(&c, i + 1);
        } else if ch == 'r' && matches!(next, Some('#') | Some('"')) && raw_string_at(&c, i + 1) {
            i = skip_raw_string(&c, i + 1);
        } else if ch == 'b' && next == Some('r') && raw_string_at(&c, i + 2) {
            i = skip_raw_string(&c, i + 2);
        } else if ch == 'b' && next == Some('"') {
            i = skip_string(&c, i + 2);
        } else if ch == '\'' {
            i = skip_char_or_lifetime(&c, i);
        } else if ch.is_alphanumeric() || ch == '_' {
            let start = i;
            while i < c.len() && (c[i].is_alphanumeric() || c[i] == '_') {
                i += 1;
            }
            out.push(Tok::Ident(c[start..i].iter().collect()));
        } else if ch == ':' && next == Some(':') {
            out.push(Tok::Sep);
            i += 2;
        } else {
            if !ch.is_whitespace() {
                out.push(Tok::Punct(ch));
            }
            i += 1;
        }
    }
    out
}

/// Past the closing quote of a string whose body starts at `i`.
fn skip_string(c: &[char], mut i: usize) -> usize {
    while i < c.len() {
        match c[i] {
            '\\' => i += 2,
            '"' => return i + 1,
            _ => i += 1,
        }
    }
    i
}

/// Whether `#…#"` (or a bare `"`) starts at `i`: the body of a raw string.
fn raw_string_at(c: &[char], mut i: usize) -> bool {
    while c.get(i) == Some(&'#') {
        i += 1;
    }
    c.get(i) == Some(&'"')
}

/// Past the end of a raw string whose hashes start at `i`.
fn skip_raw_string(c: &[char], mut i: usize) -> usize {
    let mut hashes = 0;
    while c[i] == '#' {
        hashes += 1;
        i += 1;
    }
    i += 1;
    while i < c.len() {
        if c[i] == '"' && (1..=hashes).all(|h| c.get(i + h) == Some(&'#')) {
            return i + 1 + hashes;
        }
        i += 1;
    }
    i
}

/// Past a character literal (`'x'`, `'\n'`, `'\u{7b}'`) or a lifetime
/// (`'a`) starting at the quote `i`.
fn skip_char_or_lifetime(c: &[char], i: usize) -> usize {
    if c.get(i + 1) == Some(&'\\') {
        let mut j = i + 2;
        while j < c.len() && c[j] != '\'' {
            j += 1;
        }
        return j + 1;
    }
    if c.get(i + 2) == Some(&'\'') {
        return i + 3;
    }
    // A lifetime: the identifier that follows is harmless.
    i + 1
}

/// The paths of a `use` tree starting at `i` (after `use`), each as written,
/// with the name it is bound to (its last segment, or the `as` name), and
/// the index past the tree.
fn use_tree(
    t: &[Tok],
    mut i: usize,
    prefix: Vec<String>,
    out: &mut Vec<(Vec<String>, String)>,
) -> usize {
    let mut path = prefix;
    loop {
        match t.get(i) {
            Some(Tok::Sep) if path.is_empty() => i += 1, // `use ::std::…`
            Some(Tok::Ident(s)) => {
                path.push(s.clone());
                i += 1;
                if t.get(i) == Some(&Tok::Sep) {
                    i += 1;
                    continue;
                }
                let mut name = path.last().cloned().unwrap_or_default();
                if t.get(i) == Some(&Tok::Ident("as".into())) {
                    if let Some(Tok::Ident(alias)) = t.get(i + 1) {
                        name = alias.clone();
                    }
                    i += 2;
                }
                if name == "self" {
                    path.pop();
                    name = path.last().cloned().unwrap_or_default();
                }
                out.push((path, name));
                return i;
            }
            Some(Tok::Punct('{')) => {
                i += 1;
                while i < t.len() && t[i] != Tok::Punct('}') {
                    i = use_tree(t, i, path.clone(), out);
                    while i < t.len() && !matches!(t[i], Tok::Punct(',') | Tok::Punct('}')) {
                        i += 1;
                    }
                    if t.get(i) == Some(&Tok::Punct(',')) {
                        i += 1;
                    }
                }
                return i + 1;
            }
            Some(Tok::Punct('*')) => {
                out.push((path, "*".into()));
                return i + 1;
            }
            _ => {
                out.push((path.clone(), path.last().cloned().unwrap_or_default()));
                return i;
            }
        }
    }
}

/// A path written out in code from `i` (`crate::a::b::f(…)`): its segments
/// up to the first thing that is not `ident ::`, and the index past them.
fn code_path(t: &[Tok], mut i: usize) -> (Vec<String>, usize) {
    let mut path = Vec::new();
    while let Some(Tok::Ident(s)) = t.get(i) {
        path.push(s.clone());
        i += 1;
        if t.get(i) != Some(&Tok::Sep) {
            break;
        }
        i += 1;
    }
    (path, i)
}

/// One file's module and what it names.
pub struct Parsed {
    pub module: ModPath,
    /// Every module path the file reaches (resolved, absolute).
    pub reaches: Vec<ModPath>,
    /// Its `pub use` lines: the bound name and the absolute path it binds.
    pub re_exports: BTreeMap<String, ModPath>,
}

/// `path` as written in module `at` (the file's module and any inline
/// `mod` it sits in), made absolute; `None` for another crate's path (std,
/// serde) or a path that is not one.
fn resolve(path: &[String], at: &ModPath, children: &BTreeSet<ModPath>) -> Option<ModPath> {
    let first = path.first()?;
    let (mut abs, rest) = match first.as_str() {
        "crate" => (vec![at[0].clone()], &path[1..]),
        "mckibben" => (vec!["mckibben".to_string()], &path[1..]),
        "self" => (at.clone(), &path[1..]),
        "super" => {
            let mut abs = at.clone();
            let mut k = 0;
            while path.get(k).map(String::as_str) == Some("super") {
                abs.pop();
                k += 1;
            }
            (abs, &path[k..])
        }
        _ => {
            // A `use` relative to the current module: only its children.
            let mut child = at.clone();
            child.push(first.clone());
            if !children.contains(&child) {
                return None;
            }
            (at.clone(), path)
        }
    };
    if abs.is_empty() {
        return None;
    }
    abs.extend(rest.iter().filter(|s| *s != "self").cloned());
    Some(abs)
}

fn parse(module: ModPath, text: &str, modules: &BTreeSet<ModPath>) -> Parsed {
    let t = tokens(text);
    let mut reaches = Vec::new();
    let mut re_exports = BTreeMap::new();
    // Inline modules (`mod tests { … }`) with the brace depth they opened at.
    let mut inline: Vec<(String, usize)> = Vec::new();
    let mut depth = 0usize;
    let mut i = 0;
    while i < t.len() {
        let at: ModPath = module
            .iter()
            .cloned()
            .chain(inline.iter().map(|(m, _)| m.clone()))
            .collect();
        match &t[i] {
            Tok::Punct('{') => {
                depth += 1;
                i += 1;
            }
            Tok::Punct('}') => {
                if inline.last().is_some_and(|&(_, d)| d == depth) {
                    inline.pop();
                }
                depth = depth.saturating_sub(1);
                i += 1;
            }
            Tok::Ident(k) if k == "mod" => {
                if let (Some(Tok::Ident(name)), Some(Tok::Punct('{'))) =
                    (t.get(i + 1), t.get(i + 2))
                {
                    inline.push((name.clone(), depth + 1));
                    depth += 1;
                    i += 3;
                } else {
                    i += 1;
                }
            }
            Tok::Ident(k) if k == "use" => {
                let public =
                    i > 0 && (t[i - 1] == Tok::Ident("pub".into()) || t[i - 1] == Tok::Punct(')'));
                let mut paths = Vec::new();
                i = use_tree(&t, i + 1, Vec::new(), &mut paths);
                for (path, name) in paths {
                    if let Some(abs) = resolve(&path, &at, modules) {
                        if public && inline.is_empty() {
                            re_exports.insert(name, abs.clone());
                        }
                        reaches.push(abs);
                    }
                }
            }
            Tok::Ident(k)
                if matches!(k.as_str(), "crate" | "super" | "self" | "mckibben")
                    && t.get(i + 1) == Some(&Tok::Sep)
                    && (i == 0 || t[i - 1] != Tok::Sep) =>
            {
                let (path, next) = code_path(&t, i);
                if let Some(abs) = resolve(&path, &at, modules) {
                    reaches.push(abs);
                }
                i = next;
            }
            _ => i += 1,
        }
    }
    Parsed {
        module,
        reaches,
        re_exports,
    }
}

/// The module path of the file at `rel` (relative to `src/`); `bin_mods`
/// are the modules `src/main.rs` declares (they belong to the binary).
fn module_of(rel: &str, bin_mods: &BTreeSet<String>) -> ModPath {
    let parts: Vec<&str> = rel.trim_end_matches(".rs").split('/').collect();
    match parts.as_slice() {
        ["lib"] => return vec!["mckibben".into()],
        ["main"] => return vec!["main".into()],
        _ => {}
    }
    let krate = if bin_mods.contains(parts[0]) {
        "main"
    } else {
        "mckibben"
    };
    std::iter::once(krate)
        .chain(parts.iter().copied().filter(|p| *p != "mod"))
        .map(String::from)
        .collect()
}

/// Every file of a crate (`(path relative to src/, text)`) parsed: the
/// modules `src/main.rs` declares belong to the binary (`main`), the others
/// to the library (`mckibben`); and the set of every module there is.
pub fn parse_crate(files: &[(String, String)]) -> (Vec<Parsed>, BTreeSet<ModPath>) {
    let bin_mods: BTreeSet<String> = files
        .iter()
        .find(|(rel, _)| rel == "main.rs")
        .map(|(_, text)| {
            let t = tokens(text);
            t.windows(3)
                .filter_map(|w| match w {
                    [Tok::Ident(m), Tok::Ident(name), Tok::Punct(';')] if m == "mod" => {
                        Some(name.clone())
                    }
                    _ => None,
                })
                .collect()
        })
        .unwrap_or_default();
    let modules: BTreeSet<ModPath> = files
        .iter()
        .map(|(rel, _)| module_of(rel, &bin_mods))
        .collect();
    let parsed = files
        .iter()
        .map(|(rel, text)| parse(module_of(rel, &bin_mods), text, &modules))
        .collect();
    (parsed, modules)
}

/// Every `.rs` file under `dir`, as `(path relative to root, text)`.
pub fn read_tree(root: &Path, dir: &Path, out: &mut Vec<(String, String)>) {
    let mut entries: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    entries.sort();
    for path in entries {
        if path.is_dir() {
            read_tree(root, &path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            let rel = path
                .strip_prefix(root)
                .unwrap()
                .to_string_lossy()
                .replace('\\', "/");
            out.push((rel, std::fs::read_to_string(&path).unwrap()));
        }
    }
}
