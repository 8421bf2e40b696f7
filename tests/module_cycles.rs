//! No import cycles among the modules of `src/` (issue 33, point 5), nor
//! among those of the Python bindings' crate, `python/src/`.
//!
//! Every file under `src/` is read and every path it names through `crate::`,
//! `super::`, `self::` or `mckibben::` (in `use` lines, grouped or not, and
//! written out in code), or through a child module in a `use` line, is
//! resolved to the module it reaches. The graph is drawn at two grains: the
//! top-level modules of each crate (`src/lib.rs`'s, and `src/main.rs`'s), and
//! the sibling files and folders inside each module folder. A `mod.rs` (or
//! `lib.rs`) is the folder's namespace, not a node: a path through one of its
//! `pub use` lines counts as an import of the sibling it re-exports, and a
//! path to an item it defines itself draws no edge. Comments, strings and
//! character literals are skipped. A cycle at either grain fails the test,
//! named node by node.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// A module path: the crate (`mckibben` for the library, `main` for the
/// binary), then the modules below it.
type ModPath = Vec<String>;

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
struct Parsed {
    module: ModPath,
    /// Every module path the file reaches (resolved, absolute).
    reaches: Vec<ModPath>,
    /// Its `pub use` lines: the bound name and the absolute path it binds.
    re_exports: BTreeMap<String, ModPath>,
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

/// Where a folder's graph lives, for a message.
fn folder_name(dir: &ModPath) -> String {
    match dir.as_slice() {
        [k] if k == "mckibben" => "src/ (src/lib.rs's modules)".into(),
        [k] => format!("src/ ({k}.rs's modules)"),
        [_, rest @ ..] => format!("src/{}/", rest.join("/")),
        [] => unreachable!(),
    }
}

/// The import graph of the files (`(path relative to src/, text)`), one
/// per folder: the folder's module path → sibling → the siblings it imports.
fn graphs(files: &[(String, String)]) -> BTreeMap<ModPath, BTreeMap<String, BTreeSet<String>>> {
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
    let parsed: Vec<Parsed> = files
        .iter()
        .map(|(rel, text)| parse(module_of(rel, &bin_mods), text, &modules))
        .collect();
    let exports: BTreeMap<&ModPath, &BTreeMap<String, ModPath>> =
        parsed.iter().map(|p| (&p.module, &p.re_exports)).collect();
    let mut out: BTreeMap<ModPath, BTreeMap<String, BTreeSet<String>>> = BTreeMap::new();
    for p in &parsed {
        let src = &p.module;
        for target in &p.reaches {
            if target[0] != src[0] {
                continue; // the binary's uses of the library cannot close a cycle
            }
            let k = src.iter().zip(target).take_while(|(a, b)| a == b).count();
            if k >= src.len() || k >= target.len() {
                continue; // itself, one of its own children, or an ancestor
            }
            let dir = &src[..k];
            let mut child = dir.to_vec();
            child.push(target[k].clone());
            let to = if modules.contains(&child) {
                Some(target[k].clone())
            } else {
                // An item of the folder's root file: through its `pub use`,
                // the sibling that defines it; its own items draw no edge.
                let dir_path: ModPath = dir.to_vec();
                exports
                    .get(&dir_path)
                    .and_then(|e| e.get(&target[k]))
                    .filter(|r| {
                        r.len() > k && r[..k] == *dir && {
                            let mut c = dir.to_vec();
                            c.push(r[k].clone());
                            modules.contains(&c)
                        }
                    })
                    .map(|r| r[k].clone())
            };
            if let Some(to) = to.filter(|to| *to != src[k]) {
                out.entry(dir.to_vec())
                    .or_default()
                    .entry(src[k].clone())
                    .or_default()
                    .insert(to);
            }
        }
    }
    out
}

/// Each cycle of each folder's graph, as `folder: a → b → … → a`: one per
/// strongly connected component of more than one node (Tarjan), through
/// all of its members where one path does.
fn cycles(files: &[(String, String)]) -> Vec<String> {
    let mut found = Vec::new();
    for (dir, graph) in graphs(files) {
        for component in components(&graph) {
            found.push(format!(
                "{}: {}",
                folder_name(&dir),
                cycle_through(&graph, &component)
            ));
        }
    }
    found
}

/// The strongly connected components of more than one node.
fn components(graph: &BTreeMap<String, BTreeSet<String>>) -> Vec<BTreeSet<String>> {
    struct Tarjan<'a> {
        graph: &'a BTreeMap<String, BTreeSet<String>>,
        index: BTreeMap<&'a str, usize>,
        low: BTreeMap<&'a str, usize>,
        stack: Vec<&'a str>,
        on_stack: BTreeSet<&'a str>,
        out: Vec<BTreeSet<String>>,
    }
    impl<'a> Tarjan<'a> {
        fn visit(&mut self, v: &'a str) {
            let n = self.index.len();
            self.index.insert(v, n);
            self.low.insert(v, n);
            self.stack.push(v);
            self.on_stack.insert(v);
            let graph = self.graph;
            for w in graph.get(v).into_iter().flatten() {
                let w = w.as_str();
                if !self.index.contains_key(w) {
                    self.visit(w);
                    let lw = self.low[w];
                    let lv = self.low.get_mut(v).unwrap();
                    *lv = (*lv).min(lw);
                } else if self.on_stack.contains(w) {
                    let iw = self.index[w];
                    let lv = self.low.get_mut(v).unwrap();
                    *lv = (*lv).min(iw);
                }
            }
            if self.low[v] == self.index[v] {
                let mut component = BTreeSet::new();
                while let Some(w) = self.stack.pop() {
                    self.on_stack.remove(w);
                    component.insert(w.to_string());
                    if w == v {
                        break;
                    }
                }
                if component.len() > 1 {
                    self.out.push(component);
                }
            }
        }
    }
    let mut t = Tarjan {
        graph,
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        stack: Vec::new(),
        on_stack: BTreeSet::new(),
        out: Vec::new(),
    };
    for v in graph.keys() {
        if !t.index.contains_key(v.as_str()) {
            t.visit(v);
        }
    }
    t.out
}

/// A closed walk inside `component` from its first node, the shortest
/// cycle back to it, then the members that walk missed in brackets.
fn cycle_through(
    graph: &BTreeMap<String, BTreeSet<String>>,
    component: &BTreeSet<String>,
) -> String {
    let start = component.first().unwrap().clone();
    // Breadth first from start's successors back to start, inside the component.
    let mut came_from: BTreeMap<String, String> = BTreeMap::new();
    let mut queue = std::collections::VecDeque::from([start.clone()]);
    'search: while let Some(v) = queue.pop_front() {
        for w in graph
            .get(&v)
            .into_iter()
            .flatten()
            .filter(|w| component.contains(*w))
        {
            if *w == start {
                came_from.insert(start.clone(), v.clone());
                break 'search;
            }
            if !came_from.contains_key(w) {
                came_from.insert(w.clone(), v.clone());
                queue.push_back(w.clone());
            }
        }
    }
    let mut walk = vec![start.clone()];
    let mut v = came_from[&start].clone();
    while v != start {
        walk.push(v.clone());
        v = came_from[&v].clone();
    }
    walk.push(start);
    walk.reverse();
    let missed: Vec<&str> = component
        .iter()
        .filter(|m| !walk.contains(m))
        .map(String::as_str)
        .collect();
    let mut text = walk.join(" → ");
    if !missed.is_empty() {
        text.push_str(&format!(
            " (and, in the same tangle, {})",
            missed.join(", ")
        ));
    }
    text
}

/// Every `.rs` file under `dir`, as `(path relative to root, text)`.
fn read_tree(root: &Path, dir: &Path, out: &mut Vec<(String, String)>) {
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

#[test]
fn src_has_no_import_cycles() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    read_tree(&src, &src, &mut files);
    // The analysis saw the crate: the library's top level imports itself.
    let g = graphs(&files);
    let top = &g[&vec!["mckibben".to_string()]];
    assert!(
        top["fit"].contains("eval") && top["diagnose"].contains("fit"),
        "{top:?}"
    );
    let found = cycles(&files);
    assert!(
        found.is_empty(),
        "import cycles in src/:\n  {}",
        found.join("\n  ")
    );
}

/// The Python bindings are a crate of their own over the library: their
/// `mckibben::` paths lead out of it, so they are renamed before the check
/// (which reads `mckibben::` as the library's own root).
#[test]
fn python_src_has_no_import_cycles() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("python/src");
    let mut files = Vec::new();
    read_tree(&src, &src, &mut files);
    for (_, text) in &mut files {
        *text = text.replace("mckibben::", "the_library::");
    }
    let g = graphs(&files);
    let top = &g[&vec!["mckibben".to_string()]];
    assert!(
        top["fit"].contains("convert") && top["diagnose"].contains("args"),
        "{top:?}"
    );
    let found = cycles(&files);
    assert!(
        found.is_empty(),
        "import cycles in python/src/ (named as if it were src/):\n  {}",
        found.join("\n  ")
    );
}

fn crate_of(files: &[(&str, &str)]) -> Vec<(String, String)> {
    files
        .iter()
        .map(|(p, t)| (p.to_string(), t.to_string()))
        .collect()
}

/// The check itself finds what it must: a top-level cycle through a path
/// written out in code, and a sibling cycle through the folder's `pub use`
/// and through a test module's `super::super`.
#[test]
fn the_check_names_the_cycles_of_a_small_crate() {
    let files = crate_of(&[
        ("lib.rs", "pub mod a;\npub mod b;\npub mod c;\n"),
        (
            "a/mod.rs",
            "mod x;\nmod y;\npub use x::{Thing, other as Other};\n",
        ),
        ("a/x.rs", "use super::y::Helper;\npub struct Thing;\n"),
        (
            "a/y.rs",
            "pub struct Helper;\nfn f() -> super::Thing { todo!() }\n",
        ),
        ("b.rs", "use crate::{a::Thing, c};\n"),
        (
            "c.rs",
            "fn g() { let _ = crate::b::G; }\n#[cfg(test)]\nmod tests {\n    use super::super::a;\n}\n",
        ),
    ]);
    assert_eq!(
        cycles(&files),
        [
            "src/ (src/lib.rs's modules): b → c → b",
            "src/a/: x → y → x"
        ],
    );
}

/// And nothing that is not an import: paths in comments, strings and
/// character literals, items the folder's root file defines itself, the
/// binary's uses of the library.
#[test]
fn the_check_ignores_what_is_not_an_import() {
    let files = crate_of(&[
        ("lib.rs", "pub mod a;\npub mod b;\n"),
        ("main.rs", "mod cli;\nuse mckibben::a;\n"),
        ("cli.rs", "use mckibben::b;\n"),
        (
            "a/mod.rs",
            "mod x;\nmod y;\npub struct Own;\nuse crate::b;\n",
        ),
        (
            "a/x.rs",
            "use super::y;\n/// see [`super::x`] and crate::b\n",
        ),
        ("a/y.rs", "fn f(_: super::Own) { let _ = '{'; }\n"),
        (
            "b.rs",
            "// crate::a::x\nconst S: &str = \"crate::a::x\";\nconst R: &str = r#\"super::a\"#;\n",
        ),
    ]);
    assert_eq!(cycles(&files), Vec::<String>::new());
    let g = graphs(&files);
    let edges = |dir: &[&str]| {
        let dir: ModPath = dir.iter().map(|s| s.to_string()).collect();
        g[&dir].clone()
    };
    let one = |to: &str| BTreeSet::from([to.to_string()]);
    assert_eq!(g.len(), 2, "{g:?}");
    assert_eq!(
        edges(&["mckibben"]),
        BTreeMap::from([("a".into(), one("b"))])
    );
    assert_eq!(
        edges(&["mckibben", "a"]),
        BTreeMap::from([("x".into(), one("y"))])
    );
}
