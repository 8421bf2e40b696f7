//! The `--json` contract: each command's output against the field tables of
//! docs/JSON.md.
//!
//! The doc marks each command's table with `<!-- contract: NAME -->`; its
//! rows give a field's path (`a.b`, `a[].b`, `a.*`) and its JSON type
//! (`number\|null`, `absent` for a field that can be missing). Each test
//! runs one command with `--json` on small inputs and checks that every
//! documented field has its documented type, and that every member of an
//! object whose members the table lists (the top level always) is
//! documented: a field added to an output without a row fails here.
//!
//! The examples are checked too, value for value to the six significant
//! digits the doc writes, but for what measures the machine (times, rates,
//! the threads a backend names): an example that no longer reads as the
//! command's output fails here. An example the doc says is cut holds a
//! prefix of each array and some of each object's members. Not checked:
//! `diagnose`'s (12–17 s, its steps cut to the last),
//! `--self-test=catalogue`'s and `validate boucwen`'s (a search of 45 s).

mod common;

use std::collections::BTreeMap;
use std::path::Path;
use std::process::Command;

use serde_json::Value;

const BIN: &str = env!("CARGO_BIN_EXE_mckibben");
const ROOT: &str = env!("CARGO_MANIFEST_DIR");

/// Every contract docs/JSON.md must hold: one per `--json` output.
const CONTRACTS: [&str; 13] = [
    "fit",
    "model-file",
    "compare",
    "identify",
    "simulate",
    "diagnose",
    "diagnose-self-test",
    "diagnose-self-test-catalogue",
    "control",
    "bench",
    "sweep",
    "validate-boucwen",
    "static",
];

/// One row of a contract table: a field's path and its allowed types.
#[derive(Debug, Clone)]
struct Field {
    path: String,
    types: Vec<String>,
}

/// The contract tables of `doc`, by name.
fn contracts(doc: &str) -> BTreeMap<String, Vec<Field>> {
    let mut out = BTreeMap::new();
    let mut lines = doc.lines().peekable();
    while let Some(line) = lines.next() {
        let Some(name) = line
            .trim()
            .strip_prefix("<!-- contract:")
            .and_then(|r| r.strip_suffix("-->"))
        else {
            continue;
        };
        let mut fields = Vec::new();
        let mut row = 0;
        while let Some(l) = lines.next_if(|l| l.trim_start().starts_with('|')) {
            row += 1;
            if row <= 2 {
                continue; // the header and its separator
            }
            let cells = cells(l);
            assert!(
                cells.len() >= 2,
                "docs/JSON.md, contract {name}: a row without a type: {l}"
            );
            let path = cells[0].trim().trim_matches('`').to_string();
            let types: Vec<String> = cells[1].split('|').map(|t| t.trim().to_string()).collect();
            for t in &types {
                assert!(
                    [
                        "string", "number", "integer", "boolean", "object", "array", "null",
                        "absent"
                    ]
                    .contains(&t.as_str()),
                    "docs/JSON.md, contract {name}, field {path}: unknown type `{t}`"
                );
            }
            fields.push(Field { path, types });
        }
        assert!(
            !fields.is_empty(),
            "docs/JSON.md: contract {name} has no rows"
        );
        let previous = out.insert(name.trim().to_string(), fields);
        assert!(previous.is_none(), "docs/JSON.md: contract {name} twice");
    }
    out
}

/// The cells of a Markdown table row; `\|` stays inside its cell (as `|`).
fn cells(row: &str) -> Vec<String> {
    let row = row.trim().trim_start_matches('|').trim_end_matches('|');
    let mut cells = vec![String::new()];
    let mut chars = row.chars().peekable();
    while let Some(c) = chars.next() {
        match c {
            '\\' if chars.peek() == Some(&'|') => {
                chars.next();
                cells.last_mut().unwrap().push('|');
            }
            '|' => cells.push(String::new()),
            c => cells.last_mut().unwrap().push(c),
        }
    }
    cells
}

fn type_of(v: &Value) -> &'static str {
    match v {
        Value::Null => "null",
        Value::Bool(_) => "boolean",
        Value::Number(n) if n.is_f64() => "number",
        Value::Number(_) => "integer",
        Value::String(_) => "string",
        Value::Array(_) => "array",
        Value::Object(_) => "object",
    }
}

fn type_ok(v: &Value, types: &[String]) -> bool {
    let t = type_of(v);
    types
        .iter()
        .any(|d| d == t || (d == "number" && t == "integer"))
}

/// Splits a path into its steps: a member name, `[]` (every element) or
/// `*` (every member).
fn steps(path: &str) -> Vec<&str> {
    let mut out = Vec::new();
    for part in path.split('.') {
        match part.strip_suffix("[]") {
            Some(name) => {
                out.push(name);
                out.push("[]");
            }
            None => out.push(part),
        }
    }
    out
}

/// What `doc` says is wrong with `v`: documented fields that are missing
/// or of another type, and members of fully documented objects that the
/// doc does not list.
fn violations(fields: &[Field], v: &Value) -> Vec<String> {
    let mut errors = Vec::new();
    for f in fields {
        let path = steps(&f.path);
        let (last, parents) = path.split_last().expect("a path has a step");
        let mut reached = vec![v];
        for step in parents {
            reached = reached
                .into_iter()
                .flat_map(|v| children(v, step))
                .collect();
        }
        for parent in reached {
            let values: Vec<&Value> = match (*last, parent) {
                ("[]" | "*", _) => children(parent, last),
                (name, Value::Object(m)) => match m.get(name) {
                    Some(x) => vec![x],
                    None if f.types.iter().any(|t| t == "absent") => vec![],
                    None => {
                        errors.push(format!("documented field `{}` is missing", f.path));
                        vec![]
                    }
                },
                // A parent of another type (a `string|object` field that is
                // a string here): its own row checks it.
                _ => vec![],
            };
            for x in values {
                if !type_ok(x, &f.types) {
                    errors.push(format!(
                        "field `{}` is {} ({}), documented as {}",
                        f.path,
                        type_of(x),
                        x,
                        f.types.join("|")
                    ));
                }
            }
        }
    }
    undocumented(fields, v, "", &mut errors);
    errors.sort();
    errors.dedup();
    errors
}

fn children<'a>(v: &'a Value, step: &str) -> Vec<&'a Value> {
    match (step, v) {
        ("[]", Value::Array(a)) => a.iter().collect(),
        ("*", Value::Object(m)) => m.values().collect(),
        (name, Value::Object(m)) if name != "[]" && name != "*" => {
            m.get(name).into_iter().collect()
        }
        _ => vec![],
    }
}

/// Members of `v` (at `path`) that the doc does not list, where it lists
/// any member of `path` (at the top level, always).
fn undocumented(fields: &[Field], v: &Value, path: &str, errors: &mut Vec<String>) {
    let child = |name: &str| {
        if path.is_empty() {
            name.to_string()
        } else {
            format!("{path}.{name}")
        }
    };
    match v {
        Value::Object(m) => {
            let wildcard = fields.iter().any(|f| f.path == child("*"));
            let listed: Vec<&str> = fields
                .iter()
                .filter_map(|f| {
                    let rest = if path.is_empty() {
                        Some(f.path.as_str())
                    } else {
                        f.path.strip_prefix(&format!("{path}."))
                    }?;
                    let name = rest.split(['.', '[']).next()?;
                    Some(name)
                })
                .collect();
            for (k, x) in m {
                if wildcard {
                    undocumented(fields, x, &child("*"), errors);
                } else if listed.contains(&k.as_str()) {
                    undocumented(fields, x, &child(k), errors);
                } else if path.is_empty() || !listed.is_empty() {
                    errors.push(format!("field `{}` is not documented", child(k)));
                }
            }
        }
        Value::Array(a) => {
            for x in a {
                undocumented(fields, x, &format!("{path}[]"), errors);
            }
        }
        _ => {}
    }
}

fn doc_contracts() -> BTreeMap<String, Vec<Field>> {
    let doc = std::fs::read_to_string(Path::new(ROOT).join("docs/JSON.md"))
        .expect("docs/JSON.md is readable");
    contracts(&doc)
}

/// Runs `mckibben args` and checks its stdout against contract `name`.
fn check(name: &str, args: &[&str]) -> Value {
    let all = doc_contracts();
    let fields = all
        .get(name)
        .unwrap_or_else(|| panic!("docs/JSON.md has no contract `{name}`"));
    let out = Command::new(BIN)
        .args(args)
        .current_dir(ROOT)
        .output()
        .expect("run mckibben");
    assert!(
        out.status.success(),
        "mckibben {}: {}",
        args.join(" "),
        String::from_utf8_lossy(&out.stderr)
    );
    let v: Value = serde_json::from_slice(&out.stdout).unwrap_or_else(|e| {
        panic!(
            "mckibben {}: stdout is not JSON ({e}): {}",
            args.join(" "),
            String::from_utf8_lossy(&out.stdout)
        )
    });
    assert_eq!(
        v["schema_version"],
        mckibben::report::json::SCHEMA_VERSION,
        "{name}: schema_version"
    );
    assert_documented(name, fields, &v, &format!("mckibben {}", args.join(" ")));
    v
}

/// Fails naming every way `v` (from `what`) breaks contract `name`.
fn assert_documented(name: &str, fields: &[Field], v: &Value, what: &str) {
    let errors = violations(fields, v);
    assert!(
        errors.is_empty(),
        "{what} does not match docs/JSON.md's `{name}` table:\n  {}",
        errors.join("\n  ")
    );
}

/// Checks the JSON file at `path` against contract `name`.
fn check_file(name: &str, path: &Path) -> Value {
    let all = doc_contracts();
    let fields = all
        .get(name)
        .unwrap_or_else(|| panic!("docs/JSON.md has no contract `{name}`"));
    let v: Value = serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap();
    assert_documented(name, fields, &v, &path.display().to_string());
    v
}

const STAIR: &str = "data/stair_4.5kg.csv";

/// The first ```json block after docs/JSON.md's heading `heading`.
fn doc_example(heading: &str) -> Value {
    let doc = std::fs::read_to_string(Path::new(ROOT).join("docs/JSON.md")).unwrap();
    let block: Vec<&str> = doc
        .lines()
        .skip_while(|l| *l != heading)
        .skip_while(|l| *l != "```json")
        .skip(1)
        .take_while(|l| *l != "```")
        .collect();
    serde_json::from_str(&block.join("\n"))
        .unwrap_or_else(|e| panic!("docs/JSON.md, {heading}: the example is not JSON: {e}"))
}

/// How an example stands for the command's output.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Example {
    /// Every member and every element.
    Whole,
    /// Cut, as the doc says: a prefix of each array, some of each
    /// object's members.
    Cut,
}

/// Members whose values measure the machine an example ran on (wall
/// times, rates, the threads a backend names), not the command: an
/// example shows them as one run gave them, and they are not compared.
const MEASURED: [&str; 18] = [
    "seconds",
    "seconds_per_generation",
    "evaluator_seconds",
    "kernel_seconds",
    "mean_seconds",
    "min_seconds",
    "max_seconds",
    "wall_s",
    "median_s",
    "min_s",
    "max_s",
    "mean_step_time_us",
    "max_step_time_us",
    "max_step_cpu_us",
    "candidate_samples_per_s",
    "evals_per_s",
    "backend",
    "adapter",
];

/// Every way `actual` differs from the doc's `example`: the same members
/// and lengths (or, `Cut`, members and a prefix of the command's), the
/// same strings (a doc string with `…` stands for any, a hash say) and
/// flags, numbers to the example's six significant digits; the
/// [`MEASURED`] members aside.
fn example_differences(
    example: &Value,
    actual: &Value,
    kind: Example,
    path: &str,
    out: &mut Vec<String>,
) {
    match (example, actual) {
        (Value::Object(e), Value::Object(a)) => {
            let (ek, ak): (Vec<_>, Vec<_>) = (e.keys().collect(), a.keys().collect());
            let differ = match kind {
                Example::Whole => ek != ak,
                Example::Cut => ek.iter().any(|k| !a.contains_key(*k)),
            };
            if differ {
                out.push(format!("{path}: members {ek:?}, the command's {ak:?}"));
            }
            for (k, ev) in e.iter().filter(|(k, _)| !MEASURED.contains(&k.as_str())) {
                if let Some(av) = a.get(k) {
                    example_differences(ev, av, kind, &format!("{path}.{k}"), out);
                }
            }
        }
        (Value::Array(e), Value::Array(a))
            if e.len() == a.len() || (kind == Example::Cut && e.len() < a.len()) =>
        {
            for (i, (ev, av)) in e.iter().zip(a).enumerate() {
                example_differences(ev, av, kind, &format!("{path}[{i}]"), out);
            }
        }
        (Value::Number(e), Value::Number(a)) => {
            let (e, a) = (e.as_f64().unwrap(), a.as_f64().unwrap());
            if (e - a).abs() > 5e-6 * a.abs() + 1e-12 {
                out.push(format!("{path}: {e} in the doc, {a} from the command"));
            }
        }
        (Value::String(e), Value::String(_)) if e.contains('…') => {}
        (e, a) if e == a => {}
        (e, a) => out.push(format!("{path}: {e} in the doc, {a} from the command")),
    }
}

/// Fails naming every way docs/JSON.md's example under `heading` differs
/// from `actual`.
/// The command line a provenance records starts with the binary's path,
/// which the doc writes as `mckibben`.
fn assert_example(heading: &str, kind: Example, actual: &Value) {
    let mut actual = actual.clone();
    for at in ["/model/provenance/command", "/provenance/command"] {
        if let Some(Value::String(command)) = actual.pointer_mut(at) {
            *command = command.replacen(BIN, "mckibben", 1);
        }
    }
    let mut out = Vec::new();
    example_differences(&doc_example(heading), &actual, kind, "", &mut out);
    assert!(
        out.is_empty(),
        "docs/JSON.md's example under {heading} is not the command's output:\n  {}",
        out.join("\n  ")
    );
}

#[test]
fn the_doc_holds_one_contract_per_json_output() {
    let names: Vec<String> = doc_contracts().into_keys().collect();
    let mut want: Vec<String> = CONTRACTS.iter().map(|s| s.to_string()).collect();
    want.sort();
    assert_eq!(names, want);
}

#[test]
fn the_checker_catches_a_missing_a_mistyped_and_an_undocumented_field() {
    let doc = "<!-- contract: t -->\n| field | type | unit | meaning |\n|---|---|---|---|\n\
               | `a` | number\\|null | — | x |\n| `b` | object | — | x |\n| `b.c` | integer | — | x |\n\
               | `d` | array | — | x |\n| `d[].e` | string | — | x |\n| `m` | object | — | x |\n\
               | `m.*` | number | — | x |\n| `o` | object\\|absent | — | x |\n";
    let c = contracts(doc);
    let fields = &c["t"];
    assert_eq!(fields[0].types, ["number", "null"]);
    let good =
        serde_json::json!({"a": null, "b": {"c": 1}, "d": [{"e": "x"}], "m": {"p": 1.5, "q": 2}});
    assert_eq!(violations(fields, &good), Vec::<String>::new());
    let bad = serde_json::json!({"a": "1", "b": {"c": 1.5, "z": 0}, "d": [{"e": "x", "f": 1}],
                                 "m": {"p": true}, "new": 1});
    assert_eq!(
        violations(fields, &bad),
        [
            "field `a` is string (\"1\"), documented as number|null",
            "field `b.c` is number (1.5), documented as integer",
            "field `b.z` is not documented",
            "field `d[].f` is not documented",
            "field `m.*` is boolean (true), documented as number",
            "field `new` is not documented",
        ]
    );
    let missing = serde_json::json!({"a": 1});
    assert_eq!(
        violations(fields, &missing),
        [
            "documented field `b` is missing",
            "documented field `d` is missing",
            "documented field `m` is missing",
        ]
    );
}

#[test]
fn fit() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    // A bound the fit ends on, so that `on_edge` and `widened` have rows
    // (with N = 40 × 10 one seed in six stopped inside the bound, short of
    // the basin; with N = 100, seeds 1–6 all end on it).
    let v = check(
        "fit",
        &[
            "fit",
            STAIR,
            "--pop",
            "100",
            "--gens",
            "10",
            "--backend",
            "cpu",
            "--bound",
            "alpha=0.1:0.2",
            "--json",
            "--out",
            out,
        ],
    );
    assert!(!v["on_edge"].as_array().unwrap().is_empty());
    // Every stage scores on the evaluator, and that is part of its time.
    for stage in v["stages"].as_array().unwrap() {
        let (inside, all) = (
            stage["evaluator_seconds"].as_f64().unwrap(),
            stage["seconds"].as_f64().unwrap(),
        );
        assert!(inside > 0.0 && inside <= all, "{stage}");
        assert!(
            stage["kernel_seconds"].is_null(),
            "the CPU has no device clock: {stage}"
        );
    }
    // result.json is the same document.
    let file: Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("result.json")).unwrap()).unwrap();
    assert_eq!(file["schema_version"], v["schema_version"]);
    assert_eq!(file["params"], v["params"]);

    // The doc's example, written to a temporary folder that the document
    // then names as the doc's `out/fit`.
    let mut v = check(
        "fit",
        &["fit", STAIR, "--backend", "cpu", "--json", "--out", out],
    );
    if let Some(Value::String(written)) = v.pointer_mut("/out") {
        *written = written.replacen(out, "out/fit", 1);
    }
    assert_example("## `fit`", Example::Cut, &v);
}

#[test]
fn model_file() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    let run = Command::new(BIN)
        .args([
            "fit",
            STAIR,
            "--pop",
            "40",
            "--gens",
            "10",
            "--backend",
            "cpu",
            "--effects",
            "creep",
            "--fix",
            "alpha=0.5",
            "--out",
            out,
        ])
        .current_dir(ROOT)
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let v = check_file("model-file", &dir.path().join("model.json"));
    assert_eq!(v["effects"][0], "creep");
    assert_eq!(v["user_bounds"][0], "alpha=0.5");
    assert!(v["data"]["effect_context"].is_object());

    // The doc's example: `fit --effects creep --out out/fit`, written here
    // to a temporary folder that its provenance names as the doc's.
    let run = Command::new(BIN)
        .args(["fit", "--effects", "creep", "--out", out])
        .current_dir(ROOT)
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let mut v = check_file("model-file", &dir.path().join("model.json"));
    if let Some(Value::String(command)) = v.pointer_mut("/provenance/command") {
        *command = command.replacen(out, "out/fit", 1);
    }
    assert_example("## The model file", Example::Cut, &v);
}

#[test]
fn compare() {
    let dir = tempfile::tempdir().unwrap();
    // The doc's example (its tables cut to their first rows), then with the
    // cross-load check; `--out` only keeps the written copy out of the
    // repository.
    let tiny = [
        "compare",
        STAIR,
        "--thesis-sizes",
        "10",
        "--sizes",
        "0",
        "--gens",
        "2",
        "--seeds",
        "1",
        "--budget-pop",
        "20",
        "--budget-gens",
        "2",
        "--backend",
        "cpu",
        "--json",
        "--out",
        dir.path().to_str().unwrap(),
    ];
    let v = check("compare", &tiny);
    assert_example("## `compare`", Example::Cut, &v);
    check(
        "compare",
        &[&tiny[..], &["--cross", "data/stair_7kg.csv"]].concat(),
    );
}

#[test]
fn identify() {
    check("identify", &["identify", STAIR, "--json"]);
    // The doc's example: the default data, the command as the doc writes it.
    let v = check("identify", &["identify", "--json"]);
    assert_example("## `identify`", Example::Whole, &v);
    // Two files: one model, each file's own scores in `records`.
    let sine = "data/sine_2rads_4.5kg.csv";
    let v = check("identify", &["identify", STAIR, sine, "--json"]);
    let files: Vec<&str> = v["records"]
        .as_array()
        .expect("records with two files")
        .iter()
        .map(|r| r["data"].as_str().unwrap())
        .collect();
    assert_eq!(files, [STAIR, sine]);
    assert_eq!(v["samples"], 8000);
    assert_eq!(v["model"]["family"], "linear");
}

#[test]
fn simulate() {
    let v = check("simulate", &["simulate", "--json"]);
    assert_example("## `simulate`", Example::Whole, &v);
}

#[test]
fn diagnose() {
    // One effect the stair shows, few generations, one scratch seed: an
    // accepted candidate, a size interval and the refits, twice (--repeat),
    // in about 4 s.
    let v = check(
        "diagnose",
        &[
            "diagnose",
            STAIR,
            "--effects",
            "saturation:output,delay",
            "--seeds",
            "2",
            "--generations",
            "5",
            "--scratch-seeds",
            "1",
            "--repeat",
            "2",
            "--json",
        ],
    );
    assert!(v["final"]["refits"].is_object());
    let runs = v["repeats"]["runs"].as_array().unwrap();
    assert_eq!(runs.len(), 2);
    assert_eq!(
        runs[0]["verdict"], v["verdict"],
        "the first run is this one"
    );
}

#[test]
fn diagnose_self_test() {
    // The doc's example, cut.
    let v = check(
        "diagnose-self-test",
        &[
            "diagnose",
            STAIR,
            "--self-test",
            "--cases",
            "control",
            "--seeds",
            "1",
            "--generations",
            "20",
            "--scratch-seeds",
            "0",
            "--json",
        ],
    );
    assert_example("## `diagnose --self-test`", Example::Cut, &v);
}

#[test]
fn diagnose_self_test_catalogue() {
    check(
        "diagnose-self-test-catalogue",
        &[
            "diagnose",
            STAIR,
            "--self-test=catalogue",
            "--cases",
            "control",
            "--effects",
            "delay",
            "--seeds",
            "2",
            "--generations",
            "3",
            "--scratch-seeds",
            "0",
            "--json",
        ],
    );
}

#[test]
fn control() {
    // The doc's example (cut): given gains (tuning takes minutes), short
    // runs; then with the robustness table.
    let example = [
        "control",
        "--controller",
        "pi,pi-tuned,ff-pid,mpc",
        "--tuned-gains",
        "2.2,65.5,0.02",
        "--freq",
        "1",
        "--load",
        "4.5",
        "--warmup",
        "1",
        "--duration",
        "3",
        "--steady-from",
        "1",
        "--json",
    ];
    let v = check("control", &example);
    assert_example("## `control`", Example::Cut, &v);
    let v = check("control", &[&example[..], &["--robustness"]].concat());
    assert!(v["design"].is_object() && !v["robustness"].as_array().unwrap().is_empty());
}

#[test]
fn bench() {
    // The doc's example (its rates are the machine's), then timed against
    // the CPU path.
    let example = [
        "bench",
        "--synthetic",
        "300",
        "--backend",
        "cpu",
        "--pop",
        "50",
        "--repeats",
        "1",
        "--json",
    ];
    let v = check("bench", &example);
    assert_example("## `bench`", Example::Whole, &v);
    check("bench", &[&example[..], &["--time-reference"]].concat());
}

#[test]
fn sweep() {
    // The doc's example.
    let v = check(
        "sweep",
        &[
            "sweep",
            "--pop",
            "100",
            "--family",
            "classic",
            "--cases",
            "1000",
            "--backend",
            "cpu",
            "--json",
        ],
    );
    assert_example("## `sweep`", Example::Whole, &v);
}

/// On a GPU adapter the calibration and the kernels' share of it are
/// there to check; on the CPU (above) they are null.
#[test]
fn bench_on_a_gpu() {
    if common::require_any_adapter().is_none() {
        return;
    }
    let v = check(
        "bench",
        &[
            "bench",
            "--synthetic",
            "200",
            "--backend",
            "gpu",
            "--pop",
            "64",
            "--repeats",
            "1",
            "--json",
        ],
    );
    assert!(v["calibration"]["variants"].as_array().unwrap().len() == 3);
    assert!(v["rows"][0]["ceiling_share"].as_f64().unwrap() > 0.0);
}

#[test]
fn validate_boucwen() {
    let data = mckibben::benchmark::default_data_dir();
    if !data.join("train_multisine.csv").is_file() {
        common::skip_or_fail(&format!("no Bouc-Wen benchmark data in {}", data.display()));
        return;
    }
    check(
        "validate-boucwen",
        &[
            "validate",
            "boucwen",
            "--backend",
            "cpu",
            "--population",
            "20",
            "--generations",
            "2",
            "--lm-iterations",
            "0",
            "--json",
        ],
    );
    // The table says what the published rows are beside this one's
    // white-box model, and what its time covers.
    let out = Command::new(BIN)
        .args([
            "validate",
            "boucwen",
            "--backend",
            "cpu",
            "--population",
            "20",
        ])
        .args(["--generations", "2", "--lm-iterations", "0"])
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(text.contains("identified and tested in"), "{text}");
    assert!(
        text.contains("white-box: the benchmark's own Bouc-Wen oscillator, where the published rows are black-box models"),
        "{text}"
    );
}

/// `benchmark`, `validate`'s name before 0.2, still runs the command, with
/// a note that names the new one; `validate` gives no such note.
#[test]
fn the_old_benchmark_name_runs_validate_with_a_note() {
    let missing = std::env::temp_dir().join("mckibben-no-such-benchmark-dir");
    let run = |command: &str| {
        let out = Command::new(BIN)
            .args([command, "boucwen", "--data"])
            .arg(&missing)
            .output()
            .unwrap();
        assert!(
            !out.status.success(),
            "{command}: no data, yet it succeeded"
        );
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    let (old, new) = (run("benchmark"), run("validate"));
    let note =
        "`mckibben benchmark` is deprecated and will be removed; it is now `mckibben validate`";
    assert!(old.contains(note), "{old}");
    assert!(!new.contains("deprecated"), "{new}");
    // Past the note, the same command with the same error.
    assert_eq!(
        old.lines()
            .filter(|l| !l.contains(note))
            .collect::<Vec<_>>(),
        new.lines().collect::<Vec<_>>()
    );
}

#[test]
fn static_force() {
    check("static", &["static", "--points", "3", "--json"]);
    let v = check(
        "static",
        &["static", "--points", "2", "--pressures", "0.3", "--json"],
    );
    assert_example("## `static`", Example::Whole, &v);
}

#[test]
fn the_example_check_catches_a_stale_figure_a_member_and_a_string() {
    let doc = serde_json::json!({"a": 87.735, "b": [1, "x"], "c": {"d": 0.0}});
    let now = serde_json::json!({"a": 87.7352, "b": [1, "x"], "c": {"d": 0.0}});
    let mut out = Vec::new();
    example_differences(&doc, &now, Example::Whole, "", &mut out);
    assert!(out.is_empty(), "{out:?}");
    let stale = serde_json::json!({"a": -91.5286, "b": [1, "y"], "c": {"d": 0.0, "e": 1}});
    let hash = serde_json::json!({"h": "…"});
    example_differences(
        &hash,
        &serde_json::json!({"h": "da9f"}),
        Example::Whole,
        "",
        &mut out,
    );
    assert!(out.is_empty(), "{out:?}");
    example_differences(&doc, &stale, Example::Whole, "", &mut out);
    assert_eq!(
        out,
        [
            ".a: 87.735 in the doc, -91.5286 from the command",
            ".b[1]: \"x\" in the doc, \"y\" from the command",
            ".c: members [\"d\"], the command's [\"d\", \"e\"]",
        ]
    );
}

#[test]
fn a_cut_example_may_leave_out_elements_and_members_but_not_change_them() {
    let doc = serde_json::json!({"a": [1.5, 2.0], "c": {"d": 0.0}, "seconds": 4.7});
    let longer = serde_json::json!({"a": [1.5, 2.0, 3.0], "c": {"d": 0.0, "e": 1}, "f": 2,
                                    "seconds": 0.2});
    let mut out = Vec::new();
    example_differences(&doc, &longer, Example::Cut, "", &mut out);
    assert!(out.is_empty(), "{out:?}");
    // The same cut read as whole, and a cut whose values changed.
    example_differences(&doc, &longer, Example::Whole, "", &mut out);
    assert_eq!(out.len(), 3, "{out:?}");
    out.clear();
    let changed = serde_json::json!({"a": [1.6, 2.0, 3.0], "c": {"e": 1}, "seconds": 0.2});
    example_differences(&doc, &changed, Example::Cut, "", &mut out);
    assert_eq!(
        out,
        [
            ".a[0]: 1.5 in the doc, 1.6 from the command",
            ".c: members [\"d\"], the command's [\"e\"]",
        ]
    );
    let shorter = serde_json::json!({"a": [1.5], "c": {"d": 0.0}, "seconds": 4.7});
    out.clear();
    example_differences(&doc, &shorter, Example::Cut, "", &mut out);
    assert_eq!(out.len(), 1, "an example longer than the output: {out:?}");
}
