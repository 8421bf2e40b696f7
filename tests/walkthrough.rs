//! `docs/GUIDE.md`, run as written: every ```` ```sh ```` block of the guide,
//! in order, in a scratch folder holding a copy of the shipped `data/` (less
//! `logger_example.csv`, which the guide's first block remakes from the
//! stair), with `mckibben` on the `PATH`. A ```` ```sh fails ```` block must
//! exit non-zero, any other must succeed; the ```` ```text ```` block right
//! after a run block must match its real output (see [`check_shown`]); every
//! file a block names after `>`, `--out`, `--plot` or `--report` must exist
//! afterwards; and the guide's claims are checked on the numbers themselves
//! (the fits, the control runs), so a guide edited into a wrong statement
//! fails too.
//!
//! It runs the commands through `sh` (with `awk` and `head`), so it is Unix
//! only. About 40 s on two cores, most of it `diagnose`.

#![cfg(unix)]

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

/// One run block of the guide.
#[derive(Debug)]
struct Step {
    /// The block's text, run with `sh -c`.
    script: String,
    /// A `sh fails` block: the command must exit non-zero.
    fails: bool,
    /// The output the guide shows for it, if a `text` block follows.
    shown: Option<String>,
    /// Line of the guide where the block starts (1-based), for messages.
    line: usize,
}

/// The guide's run blocks, in order, each with the output block after it.
fn steps(guide: &str) -> Vec<Step> {
    let mut steps: Vec<Step> = Vec::new();
    let mut lines = guide.lines().enumerate();
    // Whether the fenced block just closed was a run block (so a `text`
    // block now is its output).
    let mut after_step = false;
    while let Some((i, line)) = lines.next() {
        let Some(info) = line.strip_prefix("```") else {
            if !line.trim().is_empty() {
                after_step = false;
            }
            continue;
        };
        let info = info.trim();
        let mut body = String::new();
        for (_, l) in lines.by_ref() {
            if l.trim_end() == "```" {
                break;
            }
            body.push_str(l);
            body.push('\n');
        }
        match info {
            "sh" | "sh fails" => {
                steps.push(Step {
                    script: body,
                    fails: info == "sh fails",
                    shown: None,
                    line: i + 1,
                });
                after_step = true;
            }
            "text" if after_step => {
                steps.last_mut().unwrap().shown = Some(body);
                after_step = false;
            }
            _ => after_step = false,
        }
    }
    steps
}

/// Every line of the shown output must be in the real one, in the order
/// printed (whitespace at either end ignored), and the lines between two
/// shown ones must be the real lines between them unless a line `…` stands
/// there (rows left out); a line ending in `…` must begin a real line.
/// What differs, or `None`.
fn shown_differs(step: &Step, real: &str) -> Option<String> {
    let shown = step.shown.as_ref()?;
    // Blank lines are layout, on either side.
    let real: Vec<&str> = real
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty())
        .collect();
    let matches = |shown: &str, real: &str| match shown.strip_suffix('…') {
        Some(prefix) => real.starts_with(prefix.trim_end()),
        None => real == shown,
    };
    // The real line after the last one matched, and whether a `…` came since.
    let (mut next, mut skipping, mut first) = (0, false, true);
    for l in shown.lines().map(str::trim) {
        if l == "…" {
            skipping = true;
            continue;
        }
        if l.is_empty() {
            continue;
        }
        let Some(found) = real[next..].iter().position(|r| matches(l, r)) else {
            return Some(format!(
                "docs/GUIDE.md line {}: the output shown has\n  {l}\nwhich the command did not \
                 print after the lines shown before it; it printed\n{}",
                step.line,
                real.join("\n")
            ));
        };
        let at = next + found;
        if !(first || skipping || at == next) {
            return Some(format!(
                "docs/GUIDE.md line {}: the output shown leaves out\n  {}\nbefore\n  {l}\n\
                 without a `…` line",
                step.line,
                real[next..at].join("\n  ")
            ));
        }
        (next, skipping, first) = (at + 1, false, false);
    }
    None
}

/// The files a block writes: the word after `>`, `--out`, `--plot` or
/// `--report`.
fn written(script: &str) -> Vec<String> {
    let words: Vec<&str> = script.split_whitespace().collect();
    words
        .windows(2)
        .filter(|w| matches!(w[0], ">" | "--out" | "--plot" | "--report"))
        // `--out -` writes to standard output, which the block shows.
        .filter(|w| w[1] != "-")
        .map(|w| w[1].to_string())
        .collect()
}

/// The number after `key` on the first line of `out` holding it.
fn number_after(out: &str, key: &str) -> f64 {
    let line = out
        .lines()
        .find(|l| l.contains(key))
        .unwrap_or_else(|| panic!("no `{key}` in\n{out}"));
    let rest = &line[line.find(key).unwrap() + key.len()..];
    let token: String = rest
        .trim_start()
        .chars()
        .take_while(|c| c.is_ascii_digit() || matches!(c, '.' | '-'))
        .collect();
    token
        .parse()
        .unwrap_or_else(|_| panic!("no number after `{key}` in\n{line}"))
}

/// The RMS tracking error (mm) of `controller`'s row in `control`'s table.
fn rms_of(out: &str, controller: &str) -> f64 {
    let row = out
        .lines()
        .find(|l| l.split_whitespace().next() == Some(controller))
        .unwrap_or_else(|| panic!("no `{controller}` row in\n{out}"));
    row.split_whitespace().nth(3).unwrap().parse().unwrap()
}

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// A scratch folder laid out as the repository root for the guide: the
/// shipped data (less the file the guide remakes) and `bin/mckibben`.
fn scratch() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data");
    std::fs::create_dir(&data).unwrap();
    for entry in std::fs::read_dir(repo().join("data")).unwrap() {
        let path = entry.unwrap().path();
        let name = path.file_name().unwrap().to_owned();
        if name != "logger_example.csv" {
            std::fs::copy(&path, data.join(name)).unwrap();
        }
    }
    let bin = dir.path().join("bin");
    std::fs::create_dir(&bin).unwrap();
    std::os::unix::fs::symlink(env!("CARGO_BIN_EXE_mckibben"), bin.join("mckibben")).unwrap();
    dir
}

fn run(step: &Step, root: &Path) -> String {
    let path = format!(
        "{}:{}",
        root.join("bin").display(),
        std::env::var("PATH").unwrap_or_default()
    );
    let started = Instant::now();
    // One stream, as a terminal shows it: notes on stderr between the
    // lines of stdout, in the order printed.
    let out = Command::new("sh")
        .arg("-c")
        .arg(format!("{{\n{}\n}} 2>&1", step.script))
        .current_dir(root)
        .env("PATH", path)
        .output()
        .expect("sh runs");
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    eprintln!(
        "docs/GUIDE.md line {}: {:.1} s: {}",
        step.line,
        started.elapsed().as_secs_f64(),
        step.script.lines().next().unwrap_or("")
    );
    assert_eq!(
        out.status.success(),
        !step.fails,
        "docs/GUIDE.md line {}: the block {} but it exited with {}:\n{}\n{text}",
        step.line,
        if step.fails {
            "is marked `sh fails`"
        } else {
            "must succeed"
        },
        out.status,
        step.script
    );
    text
}

#[test]
fn the_guide_runs_as_written() {
    let guide = std::fs::read_to_string(repo().join("docs/GUIDE.md")).unwrap();
    let steps = steps(&guide);
    let dir = scratch();
    let root = dir.path();
    let started = Instant::now();

    // What the guide must keep covering, counted as the blocks run.
    let mut seen: Vec<&str> = Vec::new();
    // Every block's output differences, reported together at the end.
    let mut differs = Vec::new();
    for step in &steps {
        let out = run(step, root);
        differs.extend(shown_differs(step, &out));
        if !step.fails {
            for file in written(&step.script) {
                assert!(
                    root.join(&file).exists(),
                    "docs/GUIDE.md line {}: {file} was not written",
                    step.line
                );
            }
        }
        let s = step.script.as_str();
        if s.contains("> data/logger_example.csv") {
            // The recipe remakes the shipped file, byte for byte.
            let made = std::fs::read(root.join("data/logger_example.csv")).unwrap();
            let shipped = std::fs::read(repo().join("data/logger_example.csv")).unwrap();
            assert!(
                made == shipped,
                "the guide's recipe no longer makes data/logger_example.csv"
            );
            seen.push("recipe");
        } else if s.starts_with("mckibben identify data/logger_example.csv") && step.fails {
            assert!(out.contains("line 3623, column \"time_s\""), "{out}");
            seen.push("glitch error");
        } else if s.contains("identify") && s.contains("--split-gaps") && s.contains("--resample") {
            // Cut at the glitch alone, the gap before it filled in.
            assert!(!out.contains("--split-gaps cut here: gap"), "{out}");
            assert!(out.contains("line 3623: --split-gaps cut here: time runs back"));
            assert!(out.contains("csv[1] (3650 samples, dt = 0.01 s)"), "{out}");
            assert_eq!(out.matches("ARX identification").count(), 2, "{out}");
            seen.push("split and resample");
        } else if s.contains("identify") && s.contains("--split-gaps") {
            assert!(
                out.contains("line 3303: --split-gaps cut here: gap"),
                "{out}"
            );
            assert!(out.contains("line 3623: --split-gaps cut here: time runs back"));
            assert_eq!(out.matches("ARX identification").count(), 3, "{out}");
            seen.push("split");
        } else if s.contains("before_glitch.csv") && step.fails {
            assert!(out.contains("line 3303") && out.contains("non-uniform"));
            seen.push("gap error");
        } else if s.contains("identify") && s.contains("--resample") && !step.fails {
            assert!(out.contains("(3628 samples, dt = 0.01 s)"), "{out}");
            seen.push("resample");
        } else if s.starts_with("mckibben fit") && s.contains("sine_2rads") {
            // One model for the stair and the sine: it holds on each
            // record's second half, not only on the pool.
            for record in ["data/stair_4.5kg.csv", "data/sine_2rads_4.5kg.csv"] {
                let line = out
                    .lines()
                    .find(|l| l.trim_start().starts_with(record))
                    .unwrap_or_else(|| panic!("no line for {record} in\n{out}"));
                let fit = number_after(line, record);
                assert!(fit > 89.0, "{record}: {fit} %");
            }
            let folder = root.join(written(s)[0].clone());
            for f in ["loop.svg", "loop-2.svg", "trace-2.svg", "model.json"] {
                assert!(folder.join(f).exists(), "{f}");
            }
            seen.push("fit of two records");
        } else if s.starts_with("mckibben fit") {
            let fit = number_after(&out, "validation fit");
            assert!(fit > 85.0, "validation fit {fit} %");
            let model = written(s)[0].clone() + "/model.json";
            let model = std::fs::read_to_string(root.join(model)).unwrap();
            let units = if s.contains("p_kPa") {
                "p_kPa"
            } else {
                "p_MPa"
            };
            assert!(model.contains(&format!("\"column\": \"{units}\"")));
            for f in ["loop.svg", "trace.svg", "result.json"] {
                assert!(root.join(written(s)[0].clone()).join(f).exists(), "{f}");
            }
            seen.push("fit");
        } else if s.starts_with("mckibben diagnose") {
            assert!(out.contains("on data/logger_example.csv[1], data/logger_example.csv[2]"));
            let baseline = out.lines().find(|l| l.starts_with("Baseline:")).unwrap();
            assert!(number_after(baseline, "test fit") > 80.0, "{baseline}");
            // The chosen effects lift the fit on the test part, which no
            // choice saw, not only on the selection part that chose them.
            let last = out
                .lines()
                .take_while(|l| !l.starts_with("HOW SURE"))
                .filter(|l| l.trim_start().starts_with('+'))
                .last()
                .unwrap_or_else(|| panic!("no effect in HOW FAR:\n{out}"));
            assert!(
                number_after(last, "test") > number_after(baseline, "test fit"),
                "{last}\n{baseline}"
            );
            for f in ["diagnose_fit.svg", "diagnose_residual.svg"] {
                assert!(root.join("out/guide/diagnose").join(f).exists(), "{f}");
            }
            for f in ["baseline.json", "model.json"] {
                assert!(root.join("out/guide/diagnosis").join(f).exists(), "{f}");
            }
            seen.push("diagnose");
        } else if s.starts_with("mckibben simulate --from") {
            assert!(out.contains("output range"), "{out}");
            assert!(number_after(&out, "its second half alone:") > 85.0, "{out}");
            seen.push("simulate");
        } else if s.starts_with("mckibben control --from") {
            if s.contains("fit_MPa") {
                // The model in the twin's units predicts it to under 1.5 mm
                // and the MPC with it tracks better than the thesis' PI.
                let rmse = number_after(&out, "steps ahead on the validation record:");
                assert!(rmse < 1.5, "prediction RMSE {rmse} mm");
                assert!(rms_of(&out, "mpc") < rms_of(&out, "pi"), "{out}");
                assert!(root.join("out/guide/control/control_model.svg").exists());
                seen.push("control");
            } else {
                // The kPa model is read in MPa, saying so, and its gain is
                // the kPa fit's times 1000.
                assert!(!step.fails, "{out}");
                assert!(
                    out.contains("(column `p_kPa`, in kPa) is read in MPa"),
                    "{out}"
                );
                let file = std::fs::read_to_string(root.join("out/guide/fit/model.json")).unwrap();
                let file: serde_json::Value = serde_json::from_str(&file).unwrap();
                let kpa = file["params"]["b"].as_f64().unwrap();
                let b = number_after(&out, " b ");
                assert!(
                    (b - 1000.0 * kpa).abs() < 1e-4 * b,
                    "b = {b} mm/MPa, {kpa} mm/kPa\n{out}"
                );
                seen.push("control, other units");
            }
        }
    }
    for want in [
        "recipe",
        "glitch error",
        "split",
        "gap error",
        "resample",
        "split and resample",
        "fit",
        "fit of two records",
        "diagnose",
        "simulate",
        "control",
        "control, other units",
    ] {
        assert!(
            seen.contains(&want),
            "docs/GUIDE.md no longer has the step `{want}` (seen: {seen:?})"
        );
    }

    // The figures the guide shows are in docs/figures, and README links the
    // guide.
    for (i, _) in guide.match_indices("](figures/") {
        let rest = &guide[i + 2..];
        let link = &rest[..rest.find(')').unwrap()];
        assert!(repo().join("docs").join(link).exists(), "{link} is missing");
    }
    let readme = std::fs::read_to_string(repo().join("README.md")).unwrap();
    assert!(readme.contains("docs/GUIDE.md"));
    assert!(differs.is_empty(), "{}", differs.join("\n\n"));
    eprintln!("the guide ran in {:.1} s", started.elapsed().as_secs_f64());
}

#[test]
fn steps_are_read_from_the_fenced_blocks() {
    let md = "text\n\n```sh\nmckibben a\n```\n\n```text\nout a\n```\n\n```bash\nnot run\n```\n\n\
              ```text\nnot attached\n```\n\n```sh fails\nmckibben b \\\n  --x\n```\nprose\n\n```text\nlate\n```\n";
    let s = steps(md);
    assert_eq!(s.len(), 2);
    assert_eq!(s[0].script, "mckibben a\n");
    assert_eq!(s[0].shown.as_deref(), Some("out a\n"));
    assert!(!s[0].fails);
    assert_eq!(s[1].script, "mckibben b \\\n  --x\n");
    assert!(s[1].fails);
    // Prose between a run block and a text block detaches it.
    assert_eq!(s[1].shown, None);
    assert_eq!(
        written("mckibben fit x --out out/a > log.txt"),
        ["out/a", "log.txt"]
    );
}
