//! No import cycles among the modules of `src/` (issue 33, point 5), nor
//! among those of the Python bindings' crate, `python/src/`.
//!
//! Every file under `src/` is read and every path it names through `crate::`,
//! `super::`, `self::` or `mckibben::` (in `use` lines, grouped or not, and
//! written out in code), or through a child module in a `use` line, is
//! resolved to the module it reaches (`tests/imports`, which
//! `tests/layering.rs` reads the crate with too). The graph is drawn at two grains: the
//! top-level modules of each crate (`src/lib.rs`'s, and `src/main.rs`'s), and
//! the sibling files and folders inside each module folder. A `mod.rs` (or
//! `lib.rs`) is the folder's namespace, not a node: a path through one of its
//! `pub use` lines counts as an import of the sibling it re-exports, and a
//! path to an item it defines itself draws no edge. Comments, strings and
//! character literals are skipped. A cycle at either grain fails the test,
//! named node by node.

mod imports;

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

use imports::{ModPath, parse_crate, read_tree};

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
    let (parsed, modules) = parse_crate(files);
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
