//! CSV reading through the public library API, on files in a temporary
//! folder: every malformed file gives an error naming file, line and column
//! (never a panic); resampling and splitting behave as documented; real
//! jittery recordings from ../shared load (skipped locally without them,
//! a failure under `CI=true`). Two tests run `mckibben identify` and
//! `mckibben fit` on files cut by `--split-gaps`, as a user would.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use mckibben::data::Trace;
use mckibben::data::csv::{
    Gaps, MIN_SEGMENT, ReadOptions, read_traces, read_traces_with_notes, write_trace,
};

fn file(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

fn opts(gaps: Gaps) -> ReadOptions {
    ReadOptions {
        gaps,
        ..ReadOptions::default()
    }
}

#[test]
fn malformed_files_name_file_line_and_column() {
    let dir = tempfile::tempdir().unwrap();
    let head = "# a comment line\nt,pressure,displacement\n";
    // (file name, content, what the message must say after "<path>: ")
    let cases = [
        (
            "missing.csv",
            "t,pressure,disp_mm\n0,1,2\n1,1,2\n".to_string(),
            vec![
                "line 1: no output column \"displacement\"",
                "\"t\", \"pressure\", \"disp_mm\"",
                "--output COL",
            ],
        ),
        (
            "text.csv",
            format!("{head}0,0.3,1\n0.01,abc,1\n"),
            vec!["line 4, column \"pressure\": \"abc\" is not a number"],
        ),
        (
            "nan.csv",
            format!("{head}0,0.3,1\n0.01,0.3,1\n0.02,0.3,NaN\n"),
            vec!["line 5, column \"displacement\": \"NaN\" is not finite"],
        ),
        ("empty.csv", String::new(), vec!["the file is empty"]),
        (
            "header_only.csv",
            head.to_string(),
            vec!["line 2: a header row but 0 data rows"],
        ),
        (
            "backwards.csv",
            format!("{head}0,0,0\n0.01,0,0\n0.02,0,0\n0.015,0,0\n"),
            vec![
                "line 6, column \"t\": time 0.015 does not increase (previous row: 0.02)",
                "it runs back by 0.005 s",
                "pass --split-gaps",
            ],
        ),
        (
            "gap.csv",
            format!("{head}0,0,0\n0.01,0,0\n0.02,0,0\n0.05,0,0\n0.06,0,0\n"),
            vec![
                // The step as the rows wrote it, not 0.030000000000000002.
                "line 6, column \"t\": non-uniform time base: step 0.03 s, expected 0.01 s",
                "--resample DT",
                "--split-gaps",
            ],
        ),
        (
            "ragged.csv",
            format!("{head}0,0,0\n0.01,0\n"),
            vec!["line 4: 2 fields, but the header on line 2 has 3"],
        ),
    ];
    for (name, text, wanted) in cases {
        let path = file(dir.path(), name, &text);
        let msg = read_traces(&path, &ReadOptions::default())
            .unwrap_err()
            .to_string();
        assert!(
            msg.starts_with(&format!("{}: ", path.display())),
            "{name}: {msg}"
        );
        for w in wanted {
            assert!(msg.contains(w), "{name}: message {msg:?} lacks {w:?}");
        }
    }
}

/// 100 Hz, a 0.2 s gap after sample 29, then 30 more samples; values linear in t.
fn gappy(dir: &Path) -> PathBuf {
    let mut text = String::from("t,pressure,displacement,valve_in\n");
    let times = (0..30)
        .map(|k| k as f64 * 0.01)
        .chain((0..30).map(|k| 0.5 + k as f64 * 0.01));
    for t in times {
        text += &format!("{t},{},{},{}\n", 0.2 * t, 3.0 * t + 1.0, -t);
    }
    file(dir, "gappy.csv", &text)
}

#[test]
fn resample_interpolates_linearly_onto_the_step() {
    let dir = tempfile::tempdir().unwrap();
    let path = gappy(dir.path());
    let traces = read_traces(&path, &opts(Gaps::Resample(0.02))).unwrap();
    assert_eq!(traces.len(), 1);
    let tr = &traces[0];
    // 0 .. 0.79 s at 0.02 s: 40 samples; across the gap too.
    assert_eq!(tr.len(), 40);
    assert!((tr.dt() - 0.02).abs() < 1e-12);
    for k in 0..tr.len() {
        let t = tr.t[k];
        assert!((t - k as f64 * 0.02).abs() < 1e-12);
        assert!((tr.input[k] - 0.2 * t).abs() < 1e-9, "k = {k}");
        assert!((tr.output[k] - (3.0 * t + 1.0)).abs() < 1e-9);
        assert!((tr.column("valve_in").unwrap()[k] + t).abs() < 1e-9);
    }
}

#[test]
fn split_gives_one_trace_per_segment() {
    let dir = tempfile::tempdir().unwrap();
    let path = gappy(dir.path());
    let (traces, notes) = read_traces_with_notes(&path, &opts(Gaps::Split)).unwrap();
    assert_eq!(
        notes,
        [format!(
            "{}: line 32: --split-gaps cut here: gap of 0.21 s (from 0.29 s on line 31 to 0.5 s); piece [2] starts here",
            path.display()
        )]
    );
    assert_eq!(traces.len(), 2);
    assert_eq!(traces[0].source, format!("{}[1]", path.display()));
    assert_eq!(traces[1].source, format!("{}[2]", path.display()));
    assert_eq!((traces[0].len(), traces[1].len()), (30, 30));
    assert_eq!(traces[1].t[0], 0.5);
    assert_eq!(traces[1].column("valve_in").unwrap()[0], -0.5);
}

/// A logger's file: a comment line, then 100 Hz from t = 50 s (row k on line
/// k + 3) with a first-order response to a stair input; at row 200 a glitch
/// sends the clock back by 1.02 s and it ticks on from there for 150 rows.
fn clock_runs_back(dir: &Path) -> PathBuf {
    let mut text = String::from("# logger v2\nt,pressure,displacement\n");
    let mut x = 0.0;
    for k in 0..350 {
        let t = 50.0 + k as f64 * 0.01 - if k >= 200 { 1.03 } else { 0.0 };
        let p = [0.1, 0.4, 0.2, 0.5, 0.3][(k / 25) % 5];
        text += &format!("{t:.2},{p},{x:.6}\n");
        x = 0.9 * x + 2.0 * p;
    }
    file(dir, "glitch.csv", &text)
}

#[test]
fn split_cuts_where_the_clock_runs_back() {
    let dir = tempfile::tempdir().unwrap();
    let path = clock_runs_back(dir.path());
    let (traces, notes) = read_traces_with_notes(&path, &opts(Gaps::Split)).unwrap();
    assert_eq!(traces.len(), 2);
    assert_eq!((traces[0].len(), traces[1].len()), (200, 150));
    assert_eq!((traces[0].t[0], traces[1].t[0]), (50.0, 50.97));
    assert_eq!(traces[1].source, format!("{}[2]", path.display()));
    assert_eq!(
        notes,
        [format!(
            "{}: line 203: --split-gaps cut here: time runs back by 1.02 s (from 51.99 s on line 202 to 50.97 s); piece [2] starts here",
            path.display()
        )]
    );

    // Without --split-gaps, and with --resample: an error at that line.
    for gaps in [Gaps::Reject, Gaps::Resample(0.01)] {
        let msg = read_traces(&path, &opts(gaps)).unwrap_err().to_string();
        assert!(
            msg.starts_with(&format!(
                "{}: line 203, column \"t\": time 50.97 does not increase (previous row: 51.99): it runs back by 1.02 s; ",
                path.display()
            )),
            "{gaps:?}: {msg}"
        );
        assert!(msg.contains("--split-gaps"), "{gaps:?}: {msg}");
    }
}

#[test]
fn identify_with_split_gaps_uses_both_sides_of_a_clock_glitch() {
    let dir = tempfile::tempdir().unwrap();
    let path = clock_runs_back(dir.path());
    let run = |extra: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_mckibben"))
            .arg("identify")
            .arg(&path)
            .args(extra)
            .env("XDG_RUNTIME_DIR", std::env::temp_dir())
            .output()
            .unwrap()
    };
    let out = run(&["--split-gaps", "--json"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(
        stderr.contains(&format!(
            "mckibben: note: {}: line 203: --split-gaps cut here: time runs back by 1.02 s",
            path.display()
        )),
        "{stderr}"
    );
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let pieces = json.as_array().expect("one identification per piece");
    let sources: Vec<&str> = pieces
        .iter()
        .map(|p| p["source"].as_str().unwrap())
        .collect();
    let want = [1, 2].map(|k| format!("{}[{k}]", path.display()));
    assert_eq!(sources, want);
    assert_eq!(
        pieces
            .iter()
            .map(|p| p["samples"].as_u64().unwrap())
            .collect::<Vec<_>>(),
        [200, 150]
    );

    let out = run(&[]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        stderr.contains("line 203, column \"t\"") && stderr.contains("pass --split-gaps"),
        "{stderr}"
    );
    assert!(!stderr.contains("panicked"), "{stderr}");

    // The file given twice, under two names: its pieces passed as one
    // record's (the longest of four, reported alone, exit 0).
    let again = dir.path().join(".").join(path.file_name().unwrap());
    let out = run(&[again.to_str().unwrap(), "--split-gaps"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("DATA names one file twice") && stderr.contains("give it once"),
        "{stderr}"
    );
}

/// `fit --split-gaps` fits the longest piece and says which, with its
/// share of the samples; where the other pieces outweigh it (a logger that
/// paused every second: pieces of about equal length) it warns that the
/// fit reads a small part of the recording and names the ways to use all
/// of it. Beside `--resample`, it cuts only where the clock jumps: the
/// paused logger's file is one record again, its pauses filled in.
#[test]
fn fit_with_split_gaps_names_the_piece_and_warns_when_it_is_a_small_part() {
    let dir = tempfile::tempdir().unwrap();
    // 100 Hz pieces of `lengths` rows, each 0.5 s after the one before.
    let paused = |name: &str, lengths: &[usize]| {
        let mut text = String::from("t,pressure,displacement\n");
        let (mut t, mut x, mut k) = (0.0, 0.0, 0);
        for &n in lengths {
            for _ in 0..n {
                let p = [0.1, 0.4, 0.2, 0.5, 0.3][(k / 25) % 5];
                text += &format!("{t:.2},{p},{x:.6}\n");
                x = 0.9 * x + 2.0 * p;
                t += 0.01;
                k += 1;
            }
            t += 0.5;
        }
        file(dir.path(), name, &text)
    };
    let fit_with = |path: &Path, resample: &[&str]| {
        let out = Command::new(env!("CARGO_BIN_EXE_mckibben"))
            .arg("fit")
            .arg(path)
            .args(resample)
            .args([
                "--split-gaps",
                "--pop",
                "40",
                "--gens",
                "5",
                "--json",
                "--out",
            ])
            .arg(dir.path().join("fit"))
            .env("XDG_RUNTIME_DIR", std::env::temp_dir())
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
        assert!(out.status.success(), "{stderr}");
        let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        (stderr, json)
    };
    let fit = |path: &Path| fit_with(path, &[]).0;

    let path = paused("paused.csv", &[120, 160, 120]);
    let stderr = fit(&path);
    assert!(
        stderr.contains(&format!(
            "mckibben: note: 3 pieces after --split-gaps; fitting the longest, {}[2] (160 of \
             their 400 samples, 40 %)",
            path.display()
        )),
        "{stderr}"
    );
    assert!(
        stderr.contains(
            "mckibben: warning: the fit reads 40 % of the recording; where the cuts are gaps in \
             time, --resample DT beside --split-gaps keeps each stretch between jumps of the \
             clock as one record"
        ),
        "{stderr}"
    );
    // Both flags: no cut (the clock never jumps back), the two pauses
    // interpolated over: 4.99 s at 0.01 s, all 400 samples and 100 made up.
    let (stderr, json) = fit_with(&path, &["--resample", "0.01"]);
    assert!(!stderr.contains("pieces after --split-gaps"), "{stderr}");
    assert!(
        stderr.contains("--resample 0.01 interpolated across a gap of 0.51 s"),
        "{stderr}"
    );
    assert_eq!(json["records"][0]["samples"], 500, "{}", json["records"]);

    // Pieces of one length: the one whose input moves, not a rest before it.
    let mut text = String::from("t,pressure,displacement\n");
    let mut x = 2.0;
    for k in 0..200 {
        let t = k as f64 * 0.01 + if k >= 100 { 0.5 } else { 0.0 };
        let p = if k < 100 {
            0.1
        } else {
            [0.1, 0.4, 0.2, 0.5][(k / 25) % 4]
        };
        text += &format!("{t:.2},{p},{x:.6}\n");
        x = 0.9 * x + 2.0 * p;
    }
    let rest_first = file(dir.path(), "rest_first.csv", &text);
    let stderr = fit(&rest_first);
    assert!(
        stderr.contains(&format!(
            "fitting the longest, {}[2] (100 of",
            rest_first.display()
        )),
        "{stderr}"
    );

    // The glitch's two pieces: the longest holds most of the samples.
    let stderr = fit(&clock_runs_back(dir.path()));
    assert!(
        stderr.contains("fitting the longest, ")
            && stderr.contains("(200 of their 350 samples, 57 %)"),
        "{stderr}"
    );
    assert!(!stderr.contains("warning: the fit reads"), "{stderr}");

    // A clock that jumps back at every pause: both flags cut there alone,
    // and when the pieces outweigh the longest, the warning does not send
    // the user to the --resample they gave.
    let mut text = String::from(
        "t,pressure,displacement
",
    );
    let mut x = 0.0;
    for k in 0..300 {
        let t = (k % 100) as f64 * 0.01 + if k % 100 >= 50 { 0.3 } else { 0.0 };
        let p = [0.1, 0.4, 0.2, 0.5, 0.3][(k / 25) % 5];
        text += &format!("{t:.2},{p},{x:.6}\n");
        x = 0.9 * x + 2.0 * p;
    }
    let restarts = file(dir.path(), "restarts.csv", &text);
    let (stderr, json) = fit_with(&restarts, &["--resample", "0.01"]);
    assert!(
        stderr.contains("3 pieces after --split-gaps; fitting the longest")
            && stderr.contains("time runs back by 1.29 s"),
        "{stderr}"
    );
    assert!(
        stderr.contains(
            "mckibben: warning: the fit reads 33 % of the recording; `diagnose` fits every piece"
        ),
        "{stderr}"
    );
    // Each piece: 0 to 1.29 s with its pause filled in.
    assert_eq!(json["records"][0]["samples"], 130, "{}", json["records"]);
}

/// A time column named in milliseconds (a logger's `t_ms`) is read in
/// milliseconds and converted, with a note: read as seconds, a 10 ms step
/// became a model of 10 s a sample. Written back, the time keeps its
/// name and its unit; an error about the time quotes the file's own
/// times, and how far they run back in seconds.
#[test]
fn a_time_column_named_in_milliseconds_is_converted_and_written_back() {
    let dir = tempfile::tempdir().unwrap();
    let text = "# logger\nt_ms,pressure,displacement\n0,0.1,0\n10,0.2,0.1\n20,0.3,0.2\n";
    let path = file(dir.path(), "ms.csv", text);
    let read = ReadOptions {
        time: "t_ms".into(),
        ..ReadOptions::default()
    };
    let (traces, notes) = read_traces_with_notes(&path, &read).unwrap();
    assert_eq!(traces[0].t, [0.0, 0.01, 0.02]);
    assert_eq!(traces[0].dt(), 0.01);
    assert_eq!(
        notes[0],
        format!(
            "{}: column \"t_ms\" read in milliseconds and converted to seconds (a file \
             written from it names its time as it did, in milliseconds)",
            path.display()
        )
    );
    // The same samples in seconds read the same.
    let seconds = file(
        dir.path(),
        "s.csv",
        &text
            .replace("t_ms", "t_s")
            .replace("\n10,", "\n0.01,")
            .replace("\n20,", "\n0.02,"),
    );
    let read_s = ReadOptions {
        time: "t_s".into(),
        ..ReadOptions::default()
    };
    assert_eq!(read_traces(&seconds, &read_s).unwrap()[0].t, traces[0].t);
    // Written back: named and in milliseconds, as read.
    let out = dir.path().join("out.csv");
    write_trace(&out, &traces[0]).unwrap();
    let written = std::fs::read_to_string(&out).unwrap();
    assert!(
        written.contains("t_ms,pressure,displacement\n0,0.1,0\n10,0.2,0.1\n20,0.3,0.2\n"),
        "{written}"
    );
    // Microseconds and minutes too.
    for (name, cells, want) in [
        ("time [us]", ["0", "10000", "20000"], [0.0, 0.01, 0.02]),
        ("t (min)", ["0", "1", "2"], [0.0, 60.0, 120.0]),
    ] {
        let text = format!(
            "{name},pressure,displacement\n{},0.1,0\n{},0.2,0.1\n{},0.3,0.2\n",
            cells[0], cells[1], cells[2]
        );
        let path = file(dir.path(), "other.csv", &text);
        let read = ReadOptions {
            time: name.into(),
            ..ReadOptions::default()
        };
        assert_eq!(read_traces(&path, &read).unwrap()[0].t, want, "{name}");
    }
    // Time that runs back: the file's milliseconds, and the jump in s.
    let back = file(
        dir.path(),
        "back.csv",
        "t_ms,pressure,displacement\n0,0.1,0\n10,0.2,0.1\n20,0.3,0.2\n5,0.3,0.2\n",
    );
    let msg = read_traces(&back, &read).unwrap_err().to_string();
    assert!(
        msg.contains(
            "line 5, column \"t_ms\": time 5 does not increase (previous row: 20): it runs back \
             by 0.015 s"
        ),
        "{msg}"
    );
}

#[test]
fn written_traces_read_back_identically() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("sim.csv");
    let mut tr = Trace::uniform(
        "sim",
        0.01,
        (0..50).map(|k| (k as f64 * 0.3).sin()).collect(),
        (0..50).map(|k| k as f64 / 7.0).collect(),
    );
    tr.extra.push(("reference".into(), vec![30.0; 50]));
    write_trace(&path, &tr).unwrap();
    let back = read_traces(&path, &ReadOptions::default()).unwrap();
    assert_eq!(back[0].t, tr.t);
    assert_eq!(back[0].input, tr.input);
    assert_eq!(back[0].output, tr.output);
    assert_eq!(back[0].extra, tr.extra);
}

#[test]
fn cavatappi_recordings_load_split_or_resampled() {
    let Some(path) = common::require_external("cavatappi_muscle/sample1_100g.csv") else {
        return;
    };
    let columns = ReadOptions {
        time: "t_s".into(),
        input: "pressure_psi".into(),
        output: "disp_mm".into(),
        gaps: Gaps::Reject,
        ..ReadOptions::default()
    };
    // 12 000 samples at 1 kHz in 12 blocks of 1000, with 20 ms – 1.2 s gaps between.
    let msg = read_traces(&path, &columns).unwrap_err().to_string();
    assert!(
        msg.contains("line 1003, column \"t_s\": non-uniform"),
        "{msg}"
    );

    let split = ReadOptions {
        gaps: Gaps::Split,
        ..columns.clone()
    };
    let segments = read_traces(&path, &split).unwrap();
    assert_eq!(segments.len(), 12);
    for s in &segments {
        assert!(s.len() >= MIN_SEGMENT);
        assert!((s.dt() - 0.001).abs() < 1e-6, "{}: dt {}", s.source, s.dt());
        assert_eq!(
            (s.input_name.as_str(), s.output_name.as_str()),
            ("pressure_psi", "disp_mm")
        );
    }
    assert_eq!(segments.iter().map(Trace::len).sum::<usize>(), 12_000);

    let resampled = ReadOptions {
        gaps: Gaps::Resample(0.001),
        ..columns
    };
    let tr = &read_traces(&path, &resampled).unwrap()[0];
    let span = segments[11].t[segments[11].len() - 1] - segments[0].t[0];
    assert_eq!(tr.len(), (span / 0.001).round() as usize + 1);
    assert!(tr.input.iter().chain(&tr.output).all(|v| v.is_finite()));
    // Inside a block the grid hits the recorded samples.
    assert!((tr.output[500] - segments[0].output[500]).abs() < 1e-9);
}
