//! The library's top-level modules stand in layers (docs/ARCHITECTURE.md,
//! "Layers"), and a module imports only from the layers below its own: the
//! optimizers and their engine know search coordinates, populations and an
//! objective, never a muscle model, its evaluator or a plot; the model
//! knows no fit. The binary (`src/main.rs`, `src/cli/`) sits above them
//! all, and the Python bindings are a crate over the library.
//!
//! Every file under `src/` is read as `tests/module_cycles.rs` reads it
//! (`tests/imports`: `use` lines and paths written out in code, test
//! modules included; comments and strings skipped), and every path that
//! leaves its top-level module for another of the library's must land in a
//! lower layer.

mod imports;

use std::path::Path;

use imports::{parse_crate, read_tree};

/// The library's top-level modules, bottom layer first. A module may import
/// from any layer below its own, none from its own or above.
const LAYERS: &[&[&str]] = &[
    // Terms, traces and names that know nothing of the crate.
    &["data", "names", "search"],
    // The muscle models; the optimizers and the fitting engine, apart.
    &["model", "optim"],
    // What stands on a model: identification, the twin, the evaluators,
    // the reports (which draw an engine's history too).
    &["ident", "twin", "eval", "report"],
    // Where a model meets the engine: the fit, the benchmark, the control.
    &["fit", "benchmark", "control"],
    // What runs fits and loops: the diagnosis, the rig.
    &["diagnose", "rig"],
];

/// The layer of the top-level module `name`, if it has one.
fn layer(name: &str) -> Option<usize> {
    LAYERS.iter().position(|l| l.contains(&name))
}

/// Every import of the library's files (`(path relative to src/, text)`)
/// that does not go down a layer, as `from::module → to::path`; and every
/// top-level module that has no layer.
fn violations(files: &[(String, String)]) -> Vec<String> {
    let (parsed, modules) = parse_crate(files);
    let mut found: Vec<String> = modules
        .iter()
        .filter(|m| m.len() == 2 && m[0] == "mckibben" && layer(&m[1]).is_none())
        .map(|m| format!("{} has no layer in tests/layering.rs", m[1]))
        .collect();
    for p in parsed.iter().filter(|p| p.module[0] == "mckibben") {
        let Some(from) = p.module.get(1) else {
            continue; // lib.rs declares the modules
        };
        for target in &p.reaches {
            let Some(to) = target.get(1).filter(|to| *to != from) else {
                continue;
            };
            if let (Some(a), Some(b)) = (layer(from), layer(to))
                && b < a
            {
                continue;
            }
            found.push(format!(
                "{} → {}",
                p.module[1..].join("::"),
                target[1..].join("::")
            ));
        }
    }
    found.sort();
    found.dedup();
    found
}

#[test]
fn src_imports_only_from_lower_layers() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    read_tree(&src, &src, &mut files);
    // The table names the library's modules, no more.
    let (_, modules) = parse_crate(&files);
    for name in LAYERS.iter().flat_map(|l| l.iter()) {
        assert!(
            modules.contains(&vec!["mckibben".to_string(), name.to_string()]),
            "tests/layering.rs places {name}, which src/lib.rs does not declare"
        );
    }
    let found = violations(&files);
    assert!(
        found.is_empty(),
        "imports that do not go down a layer (docs/ARCHITECTURE.md, \"Layers\"):\n  {}",
        found.join("\n  ")
    );
}

fn crate_of(files: &[(&str, &str)]) -> Vec<(String, String)> {
    files
        .iter()
        .map(|(p, t)| (p.to_string(), t.to_string()))
        .collect()
}

/// The check finds an import up or across a layer, in a `use` line, in a
/// path written out in code and in a test module, and a module with no
/// layer; it lets pass the imports that go down, a doc comment's path and
/// the binary's.
#[test]
fn the_check_names_the_imports_that_break_the_layers() {
    let files = crate_of(&[
        (
            "lib.rs",
            "pub mod data;\npub mod model;\npub mod optim;\npub mod report;\npub mod extra;\n",
        ),
        ("main.rs", "mod cli;\n"),
        ("cli.rs", "use mckibben::{model, optim, report};\n"),
        ("data.rs", "pub fn write_atomic() {}\n"),
        ("model.rs", "use crate::data::write_atomic;\n"),
        (
            "report.rs",
            "use crate::optim::History;\nuse crate::model;\n",
        ),
        ("extra.rs", ""),
        ("optim/mod.rs", "pub mod engine;\npub struct History;\n"),
        (
            "optim/engine.rs",
            "use crate::data::write_atomic;\nuse crate::model::Family;\n\
             /// see [`crate::report::Figure`]\n\
             fn f() { let _ = crate::report::figure(); }\n\
             #[cfg(test)]\nmod tests {\n    use super::super::super::model::Measure;\n}\n",
        ),
    ]);
    assert_eq!(
        violations(&files),
        [
            "extra has no layer in tests/layering.rs",
            "optim::engine → model::Family",
            "optim::engine → model::Measure",
            "optim::engine → report::figure",
        ]
    );
}
