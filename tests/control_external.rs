//! The loop against a rig in another process: `mckibben control --plant`
//! talking the line protocol to `mckibben twin serve`, over its stdin/stdout
//! and over UDP. The same run gives the same numbers as in process; a
//! missing measurement holds the command, a late one is set aside, and a
//! malformed or stale line ends the run with an error and the valve closed.
//! (The deadlines here are generous so that a loaded machine cannot make a
//! measurement miss one by accident; the faults are injected by the rig.)

mod common;

use std::io::{BufRead, BufReader};
use std::process::{Command, Output, Stdio};

use serde_json::Value;

const BIN: &str = env!("CARGO_BIN_EXE_mckibben");
const ROOT: &str = env!("CARGO_MANIFEST_DIR");
/// A quick fit of the shipped 4.5 kg stair (`extra` flags added) written
/// to `out`, which it returns.
fn fit_stair(out: &std::path::Path, extra: &[&str]) -> std::path::PathBuf {
    let fitted = Command::new(BIN)
        .current_dir(ROOT)
        .args(["fit", "data/stair_4.5kg.csv", "--pop", "40", "--gens", "5"])
        .args(extra)
        .arg("--out")
        .arg(out)
        .output()
        .unwrap();
    assert!(
        fitted.status.success(),
        "{}",
        String::from_utf8_lossy(&fitted.stderr)
    );
    out.to_path_buf()
}

/// A short episode: 2 s settling, 4 s of 3 rad/s sine scored from 2 s.
const SHORT: [&str; 8] = [
    "--freq",
    "3",
    "--warmup",
    "2",
    "--duration",
    "4",
    "--steady-from",
    "2",
];

fn control(extra: &[&str]) -> Output {
    Command::new(BIN)
        .arg("control")
        .args(SHORT)
        .args(extra)
        .env("XDG_RUNTIME_DIR", std::env::temp_dir())
        .output()
        .expect("run mckibben")
}

/// The error of a `control` call that must fail (exit 1).
fn refusal(extra: &[&str]) -> String {
    let out = control(extra);
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(1), "{extra:?}: {err}");
    err
}

fn runs(out: &Output) -> Vec<Value> {
    assert!(
        out.status.success(),
        "control failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: Value = serde_json::from_slice(&out.stdout).expect("JSON");
    v["runs"].as_array().unwrap().clone()
}

/// The twin's design multisine, as `mckibben twin` writes it into `dir`:
/// its path and its text.
fn twin_multisine(dir: &std::path::Path) -> (std::path::PathBuf, String) {
    let path = dir.join("multisine.csv");
    let twin = Command::new(BIN)
        .args(["twin", "--experiment", "multisine", "--out"])
        .arg(&path)
        .output()
        .unwrap();
    assert!(
        twin.status.success(),
        "{}",
        String::from_utf8_lossy(&twin.stderr)
    );
    let text = std::fs::read_to_string(&path).unwrap();
    (path, text)
}

fn serve_cmd(args: &str) -> String {
    format!("cmd:{BIN} twin serve --load 4.5 --seed 1 {args}")
}

/// The numbers a run must reproduce exactly.
fn numbers(run: &Value) -> Vec<(String, Value)> {
    [
        "controller",
        "rms_error_mm",
        "max_error_mm",
        "effort_rms_v",
        "effort_travel_v_per_s",
        "constraint_violations",
        "missing_measurements",
    ]
    .iter()
    .map(|k| (k.to_string(), run[*k].clone()))
    .collect()
}

#[test]
fn pi_and_mpc_give_the_same_numbers_in_process_over_stdio_and_over_udp() {
    let local = runs(&control(&[
        "--controller",
        "pi,mpc",
        "--load",
        "4.5",
        "--json",
    ]));
    let piped = runs(&control(&[
        "--controller",
        "pi,mpc",
        "--json",
        "--deadline",
        "5000",
        "--plant",
        &serve_cmd(""),
    ]));
    assert_eq!(local.len(), 2);
    for (a, b) in local.iter().zip(&piped) {
        assert_eq!(numbers(a), numbers(b));
    }
    // A step's CPU time lies within its wall time (it was read outside
    // it, and an interrupt in that read made it up to ten times the wall
    // time); the margin is the two clocks' own disagreement.
    for run in local.iter().chain(&piped) {
        let (wall, cpu) = (
            run["max_step_time_us"].as_f64().unwrap(),
            run["max_step_cpu_us"].as_f64().unwrap(),
        );
        assert!(cpu <= 1.001 * wall + 1.0, "{run}");
    }
    assert!(
        local[1]["rms_error_mm"].as_f64().unwrap() < local[0]["rms_error_mm"].as_f64().unwrap()
    );

    // UDP: the twin serves on a free port and prints it.
    let mut server = Command::new(BIN)
        .args([
            "twin",
            "serve",
            "--load",
            "4.5",
            "--seed",
            "1",
            "--udp",
            "127.0.0.1:0",
        ])
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut first = String::new();
    let mut stderr = BufReader::new(server.stderr.take().unwrap());
    stderr.read_line(&mut first).unwrap();
    // Keep draining the server's reports, so that its stderr stays open.
    let drain = std::thread::spawn(move || std::io::read_to_string(stderr).unwrap_or_default());
    let addr = first.trim().rsplit(' ').next().unwrap().to_string();
    assert!(first.contains("listening on udp"), "{first}");
    let udp = runs(&control(&[
        "--controller",
        "pi,mpc",
        "--json",
        "--deadline",
        "5000",
        "--plant",
        &format!("udp:{addr}"),
    ]));
    server.kill().unwrap();
    let _ = server.wait();
    let reports = drain.join().unwrap();
    assert_eq!(
        reports
            .matches("session ended after 600 samples (STOP")
            .count(),
        2,
        "{reports}"
    );
    for (a, b) in local.iter().zip(&udp) {
        assert_eq!(numbers(a), numbers(b));
    }
}

#[test]
fn a_missing_measurement_holds_and_a_late_one_is_set_aside() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().to_str().unwrap();
    let tables = dir.path().join("csv");
    let out = control(&[
        "--controller",
        "pi",
        "--json",
        "--deadline",
        "1000",
        "--log",
        log,
        "--csv",
        tables.to_str().unwrap(),
        "--plant",
        &serve_cmd("--fault drop@100 --fault delay@200=1500"),
    ]);
    let run = &runs(&out)[0];
    assert_eq!(run["missing_measurements"], 2);
    assert_eq!(run["late_measurements"], 1);
    assert_eq!(run["constraint_violations"], 0);
    let text = std::fs::read_to_string(dir.path().join("pi_3rad.csv")).unwrap();
    assert!(text.contains("# sample 100: no measurement within 1000 ms; held"));
    assert!(text.contains("# sample 200: late measurement set aside"));
    assert!(text.trim_end().ends_with("# run complete; STOP sent"));
    // The run's table keeps every sample; the two with no measurement have
    // empty measured cells.
    let table = std::fs::read_to_string(tables.join("control_pi_rig_3rad.csv")).unwrap();
    let empty = table
        .lines()
        .filter(|l| l.split(',').filter(|c| c.is_empty()).count() == 2)
        .count();
    assert_eq!(empty, 2, "{table}");
}

/// Ctrl-C in the middle of a run on a rig closes the valve before the
/// command ends: the rig (its own process group, out of the terminal's
/// reach) hears `U k 0` and `STOP`, the log says so, and the command exits
/// with 130, as a program Ctrl-C killed does.
#[cfg(unix)]
#[test]
fn ctrl_c_closes_the_valve_before_the_command_ends() {
    let dir = tempfile::tempdir().unwrap();
    let child = Command::new(BIN)
        .args([
            "control",
            "--controller",
            "pi",
            "--freq",
            "1",
            "--duration",
            "600",
        ])
        .args(["--deadline", "1000", "--log", dir.path().to_str().unwrap()])
        .args(["--plant", &serve_cmd("")])
        .env("XDG_RUNTIME_DIR", std::env::temp_dir())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run mckibben");
    let log = dir.path().join("pi_1rad.csv");
    let started = std::time::Instant::now();
    while std::fs::read_to_string(&log).map_or(0, |t| t.lines().count()) < 50 {
        assert!(started.elapsed().as_secs() < 60, "the run never started");
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    // SAFETY: kill(2) on our own child's pid, with a valid signal.
    assert_eq!(unsafe { libc::kill(child.id() as i32, libc::SIGINT) }, 0);
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(130), "{err}");
    assert!(err.contains("interrupted (Ctrl-C) before sample"), "{err}");
    assert!(err.contains("input valve closed (0 V)"), "{err}");
    let text = std::fs::read_to_string(&log).unwrap();
    let last = text.trim_end().lines().last().unwrap();
    assert!(
        last.starts_with("# valve closed: U ") && last.ends_with(" 0, STOP"),
        "{last}"
    );
}

fn failing(fault: &str, expect: &[&str]) {
    let dir = tempfile::tempdir().unwrap();
    let out = control(&[
        "--controller",
        "pi",
        "--deadline",
        "5000",
        "--log",
        dir.path().to_str().unwrap(),
        "--plant",
        &serve_cmd(&format!("--fault {fault}")),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{fault}: the run should fail");
    for e in expect {
        assert!(err.contains(e), "{fault}: `{e}` not in\n{err}");
    }
    // The rig saw the valve closed, and so does the log.
    assert!(err.contains("input valve closed (0 V)"), "{err}");
    let log = std::fs::read_to_string(dir.path().join("pi_3rad.csv")).unwrap();
    assert!(
        log.trim_end().ends_with("# valve closed: U 100 0, STOP"),
        "{log}"
    );
}

#[test]
fn a_malformed_line_ends_the_run_with_the_valve_closed() {
    failing(
        "garble@100",
        &["line 101", "pressure_mpa `0.2O` is not a finite number"],
    );
}

#[test]
fn a_stale_line_ends_the_run_with_the_valve_closed() {
    failing("stale@100", &["stale measurement: its time stamp"]);
    failing(
        "repeat@100",
        &["stale measurement: sample 99 was already used"],
    );
}

#[test]
fn a_silent_rig_is_reported() {
    let out = control(&[
        "--controller",
        "pi",
        "--deadline",
        "50",
        "--max-missing",
        "3",
        "--plant",
        "cmd:read hello; echo READY 1 0.01; sleep 10",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        err.contains("no measurement for 3 samples in a row"),
        "{err}"
    );
}

/// The link's flags on the in-process twin are an error, not flags that
/// silently hold nothing.
#[test]
fn link_flags_without_a_rig_are_refused() {
    let err = refusal(&["--controller", "pi", "--deadline", "20", "--log", "logs"]);
    assert!(
        err.contains("--deadline, --log hold(s) a run on a rig"),
        "{err}"
    );
    // The rig's guards too, though each has a default: given, they are
    // named; left out, the twin runs (every other test here).
    let err = refusal(&[
        "--controller",
        "pi",
        "--max-missing",
        "5",
        "--max-speed",
        "200",
        "--max-implausible",
        "2",
    ]);
    assert!(
        err.contains("--max-missing, --max-speed, --max-implausible hold(s) a run on a rig"),
        "{err}"
    );
}

/// A run whose moves make the load's ringing leave the muscle slack is
/// outside the twin's physics: the command says which run and stops,
/// rather than print a row that measures the slack muscle. The same
/// ringing passes the load check, and at 3 rad/s the run is kept.
#[test]
fn a_run_that_leaves_the_muscle_slack_is_an_error() {
    // The default episode: the swing builds up over its first seconds.
    let run = |controller: &str, freq: &str| {
        Command::new(BIN)
            .args(["control", "--controller", controller, "--freq", freq])
            .args(["--effect", "ringing=4"])
            .env("XDG_RUNTIME_DIR", std::env::temp_dir())
            .output()
            .expect("run mckibben")
    };
    let fast = run("mpc", "30");
    let err = String::from_utf8_lossy(&fast.stderr);
    assert_eq!(fast.status.code(), Some(1), "{err}");
    assert!(
        err.contains("mpc at 30 rad/s under 4.5 kg: the load's ringing left the muscle slack"),
        "{err}"
    );
    let slow = run("pi", "3");
    assert!(
        slow.status.success(),
        "{}",
        String::from_utf8_lossy(&slow.stderr)
    );
}

/// Ctrl-C stops the runs on the twin before the next one: nothing is
/// printed or written, and the command exits with 130, as a program Ctrl-C
/// killed does.
#[cfg(unix)]
#[test]
fn ctrl_c_stops_the_runs_on_the_twin_and_exits_as_interrupted() {
    let dir = tempfile::tempdir().unwrap();
    // The first run's line comes once the handler is in place.
    let out = common::interrupt_once(
        Command::new(BIN)
            .args([
                "control",
                "--controller",
                "pi",
                "--freq",
                "1,2,3",
                "--load",
                "4.5,7",
            ])
            .args(["--csv", "runs"])
            .current_dir(dir.path()),
        |line| line.starts_with("[1/6] pi at 1 rad/s"),
        std::time::Duration::from_millis(100),
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(130), "{err}");
    assert!(
        err.contains("mckibben: the control runs were interrupted before their table"),
        "{err}"
    );
    assert!(!err.contains("[6/6]"), "{err}");
    assert!(
        out.stdout.is_empty(),
        "{}",
        String::from_utf8_lossy(&out.stdout)
    );
    assert!(!dir.path().join("runs").exists());
}

/// A load the twin cannot carry is a flag error before any run, not a
/// panic after the runs (which lost their results): `--load` above the
/// twin's limit, and a design load whose robustness run (× 1.3) is.
#[test]
fn a_load_the_twin_cannot_carry_is_refused_before_any_run() {
    for (args, needle) in [
        (
            &["--controller", "pi", "--load", "20"][..],
            "--load 20: the twin carries at most 15 kg",
        ),
        // A negative value reaches the check, not the shell's flag parser.
        (
            &["--controller", "pi", "--freq", "-1"][..],
            "--freq: -1 is not a positive frequency (rad/s)",
        ),
        (
            &["--controller", "mpc", "--design-load", "15", "--robustness"][..],
            "--design-load 15: the twin carries at most 15 kg, and --robustness runs it at 1.3 × \
             the design load (so at most 11.54 kg)",
        ),
        // A load so light that the twin's physics leaves its range at
        // once: rows of NaN, before.
        (
            &["--controller", "pi", "--load", "0.01"][..],
            "--load: the twin's `displacement` is not finite from 0.010 s on",
        ),
        // A value named twice ran, and reported, each run twice.
        (
            &["--controller", "pi,pi"][..],
            "--controller names pi twice",
        ),
        // An infinite weight on valve moves left every QP without a
        // solution, exit 0.
        (
            &["--controller", "mpc", "--r-move", "inf"][..],
            "--r-move inf: the weight on valve moves must be a positive, finite number",
        ),
        // A family the controllers cannot use: refused before the design
        // (it was, after seconds of identification).
        (
            &[
                "--controller",
                "mpc",
                "--from",
                "tests/fixtures/generalized_before_x_s.json",
            ][..],
            "--from tests/fixtures/generalized_before_x_s.json: the controller's model must be \
             the classic or the linear family",
        ),
        // The creep's softer rubber is as much the cause as the load.
        (
            &["--controller", "pi", "--effect", "creep=9"][..],
            "--load with --effect creep=9: a 4.5 kg load stretches the muscle at rest",
        ),
        // A swing that would leave the muscle slack on the valve's full
        // step is outside the twin's physics, whatever the controller does.
        (
            &["--controller", "pi", "--effect", "ringing=5"][..],
            "--load with --effect ringing=5: the load's ringing leaves the muscle slack from",
        ),
        // A logger's own names: the flag that reads them is the fix.
        (
            &[
                "--controller",
                "mpc",
                "--design-data",
                "data/logger_example.csv",
            ][..],
            "no column \"t\" (the file has time_s, p_kPa, stroke_mm, valve_V): name the \
             file's columns with --design-columns TIME,VALVE,PRESSURE,DISPLACEMENT",
        ),
    ] {
        let out = control(args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {err}");
        assert!(err.contains(needle), "{args:?}: {err}");
    }
}

/// A model named for controllers that read none is not read, and the
/// command says so (it ran as if it had been).
#[test]
fn a_model_no_controller_reads_is_named() {
    for flag in ["--from", "--design-data"] {
        let out = control(&["--controller", "pi", flag, "no-such-file", "--json"]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{err}");
        assert!(
            err.contains(&format!(
                "warning: {flag} is not read: none of the controllers asked for (pi) uses it"
            )),
            "{err}"
        );
    }
    // So are the MPC's, the design's and the tuning's knobs, and the
    // twin's effects where the twin runs nothing.
    let rig = serve_cmd("");
    for (args, warning) in [
        (
            &["--controller", "pi", "--horizon", "5", "--r-move", "3"][..],
            "--horizon is not read: none of the controllers asked for (pi) uses it; add mpc",
        ),
        (
            &["--controller", "pi", "--design-load", "7"][..],
            "--design-load is not read: none of the controllers asked for (pi) uses it",
        ),
        (
            &["--controller", "pi", "--algo", "ga"][..],
            "--algo is not read: it sets the gain tuning, and none of the controllers asked \
             for (pi) is tuned",
        ),
        (
            &[
                "--controller",
                "pi-tuned",
                "--tuned-gains",
                "2,60,0",
                "--pop",
                "7",
            ][..],
            "--pop is not read: it sets the gain tuning, and the gains are given",
        ),
        (
            &["--controller", "pi", "--effect", "creep=1", "--plant", &rig][..],
            "--effect is not read: it sets the twin",
        ),
    ] {
        let out = control(&[args, &["--json"]].concat());
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{args:?}: {err}");
        assert!(
            err.contains(&format!("warning: {warning}")),
            "{args:?}: {err}"
        );
    }
    // Where they are read, nothing is said.
    let out = control(&["--controller", "mpc", "--horizon", "5", "--json"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success() && !err.contains("not read"), "{err}");
}

/// A folder for the figures or the traces that cannot be made is an error
/// before the runs, which it lost; and a model at another sample time than
/// the twin's is refused before any run, naming its file.
#[test]
fn what_would_fail_after_the_runs_fails_before_them() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("a-file");
    std::fs::write(&file, "not a folder").unwrap();
    for flag in ["--csv", "--plot"] {
        let out = control(&["--controller", "pi", flag, file.to_str().unwrap()]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{err}");
        assert!(err.contains(&format!("cannot create {flag}")), "{err}");
        assert!(!err.contains("[1/"), "no run started: {err}");
    }
    // The shipped stair's model, refitted on a record at 0.02 s.
    let slow = dir.path().join("slow.csv");
    let text = std::fs::read_to_string(format!("{ROOT}/data/stair_4.5kg.csv")).unwrap();
    let mut lines = text.lines().filter(|l| !l.starts_with('#'));
    let header = lines.next().unwrap();
    let mut doubled = vec![header.to_string()];
    for line in lines {
        let (t, rest) = line.split_once(',').unwrap();
        doubled.push(format!("{},{rest}", 2.0 * t.parse::<f64>().unwrap()));
    }
    std::fs::write(&slow, doubled.join("\n")).unwrap();
    let model = dir.path().join("slow");
    let fitted = Command::new(BIN)
        .args([
            "fit",
            slow.to_str().unwrap(),
            "--pop",
            "40",
            "--gens",
            "5",
            "--out",
        ])
        .arg(&model)
        .output()
        .unwrap();
    assert!(
        fitted.status.success(),
        "{}",
        String::from_utf8_lossy(&fitted.stderr)
    );
    let from = model.join("model.json");
    let err = refusal(&["--controller", "pi,mpc", "--from", from.to_str().unwrap()]);
    assert!(
        err.contains("the model steps every 0.02 s, the twin every 0.01 s")
            && err.contains("--from"),
        "{err}"
    );
    assert!(!err.contains("[1/"), "no run started: {err}");
    // The step is checked before the design: one whose prediction would
    // diverge on the twin (a pole of 1.5) still gets the step's refusal,
    // not the design's "the model's prediction diverges".
    let mut file: Value = serde_json::from_str(&std::fs::read_to_string(&from).unwrap()).unwrap();
    file["params"]["a"] = serde_json::json!(1.5);
    let unstable = dir.path().join("unstable.json");
    std::fs::write(&unstable, file.to_string()).unwrap();
    let err = refusal(&["--controller", "mpc", "--from", unstable.to_str().unwrap()]);
    assert!(
        err.contains("the model steps every 0.02 s, the twin every 0.01 s"),
        "{err}"
    );
    // Two seconds of a multisine settle no model: its pole came out at
    // −1.02 and the MPC held the valve shut, without a word.
    let (_, text) = twin_multisine(dir.path());
    let short = dir.path().join("short.csv");
    std::fs::write(
        &short,
        text.lines().take(200).collect::<Vec<_>>().join("\n"),
    )
    .unwrap();
    let err = refusal(&[
        "--controller",
        "mpc",
        "--design-data",
        short.to_str().unwrap(),
    ]);
    assert!(
        err.contains("the model identified from it has the pole a = ")
            && err.contains("outside 0 to 1"),
        "{err}"
    );
    assert!(!err.contains("[1/"), "no run started: {err}");
    // A cell of the valve column that is no number: the design reads that
    // column, so the cell is named (it was "no `valve_in` column").
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    let header = lines.iter().position(|l| l.starts_with("t,")).unwrap();
    let valve = lines[header]
        .split(',')
        .position(|c| c == "valve_in")
        .unwrap();
    let mut cells: Vec<&str> = lines[header + 100].split(',').collect();
    cells[valve] = "abc";
    lines[header + 100] = cells.join(",");
    let bad = dir.path().join("bad-valve.csv");
    std::fs::write(&bad, lines.join("\n")).unwrap();
    let err = refusal(&[
        "--controller",
        "mpc",
        "--design-data",
        bad.to_str().unwrap(),
    ]);
    assert!(
        err.contains(&format!(
            "line {}, column \"valve_in\": \"abc\" is not a number",
            header + 101
        )),
        "{err}"
    );
    // A pressure in kPa under the MPa name: the design read it as a record
    // that does not settle the model, "a stair's few steps" on a multisine.
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    let pressure = lines[header]
        .split(',')
        .position(|c| c == "pressure")
        .unwrap();
    for line in &mut lines[header + 1..] {
        let mut cells: Vec<String> = line.split(',').map(String::from).collect();
        cells[pressure] = (1000.0 * cells[pressure].parse::<f64>().unwrap()).to_string();
        *line = cells.join(",");
    }
    let kpa = dir.path().join("kpa.csv");
    std::fs::write(&kpa, lines.join("\n")).unwrap();
    let err = refusal(&[
        "--controller",
        "mpc",
        "--design-data",
        kpa.to_str().unwrap(),
    ]);
    assert!(
        err.contains("the design record's pressure is in MPa") && err.contains("convert it to MPa"),
        "{err}"
    );
    // A model whose free run diverges (a pole of 1.5 in a classic model of
    // the stair) steered the MPC without a word: refused before any run, by
    // its pole (one of 1.2, whose prediction stays finite over the horizon,
    // too: `a_model_the_controllers_cannot_use_is_refused_or_named`).
    let stair = Command::new(BIN)
        .args([
            "fit",
            &format!("{ROOT}/data/stair_4.5kg.csv"),
            "--pop",
            "40",
            "--gens",
            "5",
            "--out",
        ])
        .arg(dir.path().join("stair"))
        .output()
        .unwrap();
    assert!(stair.status.success());
    let file = dir.path().join("stair/model.json");
    let mut m: Value = serde_json::from_str(&std::fs::read_to_string(&file).unwrap()).unwrap();
    m["params"]["a"] = serde_json::json!(1.5);
    std::fs::write(&file, m.to_string()).unwrap();
    let err = refusal(&["--controller", "mpc", "--from", file.to_str().unwrap()]);
    assert!(err.contains("the model's pole a = 1.5"), "{err}");
    assert!(!err.contains("[1/"), "no run started: {err}");
}

/// An MPC whose every QP fails holds the valve: its row is no MPC's, and
/// the command says so; the row's `controller` stays the kind (the scale
/// has its own field), as the JSON contract says.
#[test]
fn an_mpc_whose_solves_fail_is_named_and_its_row_keeps_its_kind() {
    let out = control(&["--controller", "mpc", "--hysteresis-scale", "100", "--json"]);
    let rows = runs(&out);
    let scaled = rows
        .iter()
        .find(|r| r["hysteresis_scale"] == 100.0)
        .expect("the scaled run");
    assert_eq!(scaled["controller"], "mpc");
    assert!(
        scaled["solver_failures"].as_u64().unwrap() > 0,
        "{scaled:?}"
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("warning: mpc (hysteresis ×100) at 3 rad/s, 4.5 kg:")
            && err.contains("of the MPC's QP solves failed"),
        "{err}"
    );
}

/// A plan the rig's sample time cannot carry is refused at the first
/// connection, before any run drove the rig: a model identified at the
/// twin's 0.01 s on a rig at 0.02 s (the PI used to run its whole episode
/// first, then the MPC failed and both were lost), and a reference above
/// the rig's Nyquist frequency (it used to run). The rig hears HELLO and
/// STOP, no command.
#[cfg(unix)]
#[test]
fn a_plan_the_rig_cannot_carry_is_refused_before_any_run() {
    let dir = tempfile::tempdir().unwrap();
    let heard = dir.path().join("heard.txt");
    let rig = dir.path().join("rig.sh");
    std::fs::write(
        &rig,
        format!(
            "while read -r line; do echo \"$line\" >> '{}'; case \"$line\" in \
             HELLO*) echo 'READY 1 0.02';; STOP*) echo 'BYE 1'; exit 0;; esac; done\n",
            heard.display()
        ),
    )
    .unwrap();
    let plant = format!("cmd:sh {}", rig.display());
    for (args, needle) in [
        (&["--controller", "pi,mpc"][..], "mpc cannot run on cmd:"),
        (
            &["--controller", "pi", "--freq", "200"][..],
            "--freq 200: the rig samples every 0.02 s: a reference at 200 rad/s must stay below \
             Nyquist's 157.1 rad/s",
        ),
    ] {
        let _ = std::fs::remove_file(&heard);
        let out = control(&[args, &["--plant", &plant]].concat());
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {err}");
        assert!(err.contains(needle), "{args:?}: {err}");
        let heard = std::fs::read_to_string(&heard).unwrap();
        assert_eq!(
            heard.lines().collect::<Vec<_>>(),
            ["HELLO 1", "STOP"],
            "{args:?}"
        );
    }
}

/// `--hysteresis-scale` runs on a rig as on the twin (it was dropped
/// without a word), the same numbers; `--robustness`, whose runs move the
/// twin's load, is refused there (its table came from the in-process twin
/// and passed as the rig's).
#[test]
fn hysteresis_scales_run_on_a_rig_and_robustness_is_refused_there() {
    let scaled = ["--controller", "mpc", "--hysteresis-scale", "0.8", "--json"];
    let local = runs(&control(&[&scaled[..], &["--load", "4.5"]].concat()));
    let piped = runs(&control(
        &[
            &scaled[..],
            &["--deadline", "5000", "--plant", &serve_cmd("")],
        ]
        .concat(),
    ));
    assert_eq!(piped.len(), 2);
    assert_eq!(piped[1]["hysteresis_scale"], 0.8);
    for (a, b) in local.iter().zip(&piped) {
        assert_eq!(numbers(a), numbers(b));
    }
    let err = refusal(&[
        "--controller",
        "mpc",
        "--robustness",
        "--plant",
        &serve_cmd(""),
    ]);
    assert!(
        err.contains("--robustness runs the in-process twin"),
        "{err}"
    );
}

/// A steps run at ω and the sine run at ω write files of their own names
/// into one `--csv` and `--plot` folder: the second invocation overwrote
/// the first's traces and figures.
#[test]
fn steps_and_sine_runs_keep_their_own_files() {
    let dir = tempfile::tempdir().unwrap();
    let (csv, plot) = (dir.path().join("csv"), dir.path().join("plot"));
    for reference in ["sine", "steps"] {
        let out = control(&[
            "--controller",
            "pi",
            "--reference",
            reference,
            "--csv",
            csv.to_str().unwrap(),
            "--plot",
            plot.to_str().unwrap(),
        ]);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    let sine = std::fs::read_to_string(csv.join("control_pi_4.5kg_3rad.csv")).unwrap();
    let steps = std::fs::read_to_string(csv.join("control_pi_4.5kg_3rad_steps.csv")).unwrap();
    assert_ne!(sine, steps);
    // The columns in the order `control --help` gives them.
    let header = sine.lines().find(|l| !l.starts_with('#')).unwrap();
    assert_eq!(header, "t,pressure,displacement,valve_in,reference");
    assert!(plot.join("control_pi_4.5kg_3rad.svg").exists());
    assert!(plot.join("control_pi_4.5kg_3rad_steps.svg").exists());
}

/// A loop that tracks worse than a muscle held still at the reference's
/// mean is warned of, short of diverging (an MPC that weighs valve moves a
/// billion times barely moves); a loop that tracks is not. A horizon past
/// what a step can solve in time is refused.
#[test]
fn a_loop_worse_than_holding_still_is_warned_of() {
    let out = control(&[
        "--controller",
        "pi,mpc",
        "--load",
        "4.5",
        "--r-move",
        "1e9",
        "--json",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    // What the runs were scored on and with, for a script to tell them by.
    let settings = serde_json::from_slice::<Value>(&out.stdout).unwrap()["settings"].clone();
    assert_eq!(
        settings,
        serde_json::json!({"reference": "sine", "warmup_s": 2.0, "duration_s": 4.0,
            "steady_from_s": 2.0, "seed": 1, "horizon": 20, "r_move": 1e9})
    );
    let both = runs(&out);
    let rms = |r: &Value, key: &str| r[key].as_f64().unwrap();
    let (pi, mpc) = (&both[0], &both[1]);
    assert!(rms(pi, "rms_error_mm") < rms(pi, "holding_rms_mm"), "{pi}");
    assert!(
        rms(mpc, "rms_error_mm") > rms(mpc, "holding_rms_mm"),
        "{mpc}"
    );
    assert_eq!(mpc["diverged"], false, "{mpc}");
    assert!(
        err.contains("warning: mpc at 3 rad/s, 4.5 kg: its RMS error")
            && err.contains("the loop tracks worse than doing nothing"),
        "{err}"
    );
    assert!(!err.contains("warning: pi at"), "{err}");
    // On one plateau of the steps holding still is perfect: no error is
    // called worse than that (0.03 mm was, against 0).
    let plateau = Command::new(BIN)
        .args([
            "control",
            "--controller",
            "pi",
            "--reference",
            "steps",
            "--freq",
            "0.5",
            "--warmup",
            "2",
            "--duration",
            "4",
            "--steady-from",
            "2",
            "--load",
            "4.5",
            "--json",
        ])
        .env("XDG_RUNTIME_DIR", std::env::temp_dir())
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&plateau.stderr);
    assert_eq!(runs(&plateau)[0]["holding_rms_mm"], 0.0);
    assert!(!err.contains("tracks worse than doing nothing"), "{err}");
    let err = refusal(&["--controller", "mpc", "--horizon", "501"]);
    assert!(
        err.contains("--horizon 501: the MPC's horizon must be 2 to 500 samples"),
        "{err}"
    );
    // A scale of 1 is the nominal run again, under the same label.
    let err = refusal(&["--controller", "mpc", "--hysteresis-scale", "0.8,1"]);
    assert!(
        err.contains("--hysteresis-scale: 1 is the nominal model"),
        "{err}"
    );
}

/// A model file whose pole grows is refused as a design record's is; one
/// whose inverse asks for more than the valve gives (A = 0 pins the
/// feedforward at 10 V) leaves `ff-pid` a PID alone, and the command says
/// so where the row would pass for the feedforward's.
#[test]
fn a_model_the_controllers_cannot_use_is_refused_or_named() {
    let dir = tempfile::tempdir().unwrap();
    let fit = fit_stair(&dir.path().join("fit"), &[]);
    let text = std::fs::read_to_string(fit.join("model.json")).unwrap();
    let edited = |name: &str, value: f64| {
        let mut file: Value = serde_json::from_str(&text).unwrap();
        file["params"][name] = serde_json::json!(value);
        let path = dir.path().join(format!("{name}.json"));
        std::fs::write(&path, file.to_string()).unwrap();
        path.to_str().unwrap().to_string()
    };
    let err = refusal(&["--controller", "mpc", "--from", &edited("a", 1.2)]);
    assert!(err.contains("the model's pole a = 1.2"), "{err}");
    let gains = [
        "--tuned-gains",
        "2.2164,65.528,0.0219",
        "--load",
        "4.5",
        "--json",
    ];
    let out = control(
        &[
            &["--controller", "ff-pid", "--from", &edited("A", 0.0)][..],
            &gains,
        ]
        .concat(),
    );
    let err = String::from_utf8_lossy(&out.stderr);
    let pinned = runs(&out);
    assert_eq!(pinned[0]["feedforward_at_limit"], 600, "{}", pinned[0]);
    assert!(
        err.contains("the feedforward was at the valve's range on 600 of 600 samples"),
        "{err}"
    );
    let from = fit.join("model.json");
    let out = control(
        &[
            &["--controller", "ff-pid", "--from", from.to_str().unwrap()][..],
            &gains,
        ]
        .concat(),
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(runs(&out)[0]["feedforward_at_limit"].as_u64().unwrap() < 60);
    assert!(!err.contains("feedforward was at"), "{err}");
}

/// A model fitted in kPa and metres steers the controllers as the same
/// model in MPa and mm: `--from` converts its parameters, its effects'
/// too, and says so.
#[test]
fn a_model_in_other_units_steers_as_in_mpa_and_mm() {
    let dir = tempfile::tempdir().unwrap();
    let fit = fit_stair(&dir.path().join("fit"), &[]);
    let mpa = fit.join("model.json");
    // The same model written in kPa and m, through the library's
    // rescaling, which its own test checks against a simulation.
    let base = mckibben::model::ModelFile::load(&mpa)
        .unwrap()
        .model()
        .unwrap()
        .base;
    let kpa = base.rescaled(1e3, 1e-3);
    let mut file: Value = serde_json::from_str(&std::fs::read_to_string(&mpa).unwrap()).unwrap();
    for (name, value) in kpa.named_params() {
        file["params"][name] = serde_json::json!(value);
    }
    let columns = [
        ("input", "p_kPa", "kPa", kpa.input_mean),
        ("output", "x_m", "m", kpa.output_mean),
    ];
    for (side, column, unit, mean) in columns {
        file["data"][side] = serde_json::json!({"column": column, "unit": unit, "mean": mean});
    }
    let converted = dir.path().join("kpa.json");
    std::fs::write(&converted, file.to_string()).unwrap();

    let run = |from: &std::path::Path| {
        control(&[
            "--controller",
            "mpc",
            "--load",
            "4.5",
            "--json",
            "--from",
            from.to_str().unwrap(),
        ])
    };
    let (theirs, ours) = (run(&mpa), run(&converted));
    let err = String::from_utf8_lossy(&ours.stderr);
    assert!(
        err.contains("the model's input (column `p_kPa`, in kPa) is read in MPa")
            && err.contains("the model's output (column `x_m`, in m) is read in mm"),
        "{err}"
    );
    let rms = |out: &Output| runs(out)[0]["rms_error_mm"].as_f64().unwrap();
    assert!(
        (rms(&theirs) - rms(&ours)).abs() <= 1e-6 * rms(&theirs),
        "{} mm against {} mm",
        rms(&theirs),
        rms(&ours)
    );

    // With effects too: each effect parameter takes its unit's factor.
    let creep = fit_stair(&dir.path().join("creep"), &["--effects", "creep"]);
    let mpa = creep.join("model.json");
    let model = mckibben::model::ModelFile::load(&mpa)
        .unwrap()
        .model()
        .unwrap();
    assert_eq!(model.effects(), [mckibben::model::effects::Effect::Creep]);
    let mut kpa = model.rescaled(1e3, 1e-3);
    kpa.base.input_name = "p_kPa".into();
    kpa.base.output_name = "x_m".into();
    let converted = dir.path().join("creep_kpa.json");
    mckibben::model::ModelFile::new(&kpa, None, Default::default())
        .save(&converted)
        .unwrap();
    let (theirs, ours) = (run(&mpa), run(&converted));
    let err = String::from_utf8_lossy(&ours.stderr);
    assert!(
        err.contains("the model's input (column `p_kPa`, in kPa) is read in MPa")
            && err.contains("effect creep: used as states"),
        "{err}"
    );
    assert!(
        (rms(&theirs) - rms(&ours)).abs() <= 1e-6 * rms(&theirs),
        "{} mm against {} mm",
        rms(&theirs),
        rms(&ours)
    );
}

/// A rig's record names its columns its own way and in its own units:
/// `--design-columns` points the design at them, and a pressure in kPa
/// and a displacement in m are converted to the controllers' MPa and mm,
/// so the design and the run are those of the same record written as
/// `mckibben twin` writes it. Without the flag, the error says how.
#[test]
fn a_design_record_in_its_own_names_and_units_designs_as_the_twins_does() {
    let dir = tempfile::tempdir().unwrap();
    let (multisine, text) = twin_multisine(dir.path());
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    let header = lines.iter().position(|l| l.starts_with("t,")).unwrap();
    let names: Vec<String> = lines[header].split(',').map(String::from).collect();
    let at = |name: &str| names.iter().position(|c| c == name).unwrap();
    let (time, pressure, displacement) = (at("t"), at("pressure"), at("displacement"));
    lines[header] = names
        .iter()
        .map(|c| match c.as_str() {
            "t" => "time_ms",
            "valve_in" => "u_cmd",
            "pressure" => "p_kPa",
            "displacement" => "x_m",
            other => other,
        })
        .collect::<Vec<_>>()
        .join(",");
    for line in &mut lines[header + 1..] {
        let mut cells: Vec<String> = line.split(',').map(String::from).collect();
        let scaled = |cell: &str, by: f64| (cell.parse::<f64>().unwrap() * by).to_string();
        cells[time] = scaled(&cells[time], 1000.0);
        cells[pressure] = scaled(&cells[pressure], 1000.0);
        cells[displacement] = scaled(&cells[displacement], 1e-3);
        *line = cells.join(",");
    }
    let renamed = dir.path().join("rig.csv");
    std::fs::write(&renamed, lines.join("\n")).unwrap();

    let run = |extra: &[&str]| {
        control(
            &[
                &["--controller", "mpc", "--load", "4.5", "--json"][..],
                extra,
            ]
            .concat(),
        )
    };
    let twins = run(&["--design-data", multisine.to_str().unwrap()]);
    let rigs = run(&[
        "--design-data",
        renamed.to_str().unwrap(),
        "--design-columns",
        "time_ms,u_cmd,p_kPa,x_m",
    ]);
    let (a, b) = (runs(&twins), runs(&rigs));
    let err = String::from_utf8_lossy(&rigs.stderr);
    assert!(
        err.contains("column \"time_ms\" read in milliseconds and converted to seconds")
            && err.contains("column \"p_kPa\" read in kPa and converted to MPa")
            && err.contains("column \"x_m\" read in m and converted to mm"),
        "{err}"
    );
    // The same record, to the last digits the scaling rounds.
    let design = |out: &Output| -> Vec<f64> {
        let v: Value = serde_json::from_slice(&out.stdout).unwrap();
        v["design"]["prediction"]["by_step_mm"]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect()
    };
    let (da, db) = (design(&twins), design(&rigs));
    assert_eq!(da.len(), db.len());
    for (x, y) in da.iter().zip(&db) {
        assert!((x - y).abs() <= 1e-4 * x.abs(), "{da:?} against {db:?}");
    }
    let rms = |r: &Vec<Value>| r[0]["rms_error_mm"].as_f64().unwrap();
    assert!(
        (rms(&a) - rms(&b)).abs() <= 1e-3 * rms(&a),
        "{a:?} against {b:?}"
    );

    // Without the flag, the file's names are the error, and the fix; then
    // a valve column that is not there, a pressure in a length, and three
    // names for four columns.
    let rig = renamed.to_str().unwrap();
    let design = |extra: &[&str]| {
        refusal(&[&["--controller", "mpc", "--design-data", rig][..], extra].concat())
    };
    for (columns, needles) in [
        (
            &[][..],
            &[
                "no column \"t\"",
                "--design-columns TIME,VALVE,PRESSURE,DISPLACEMENT",
            ][..],
        ),
        (
            &["--design-columns", "time_ms,valve,p_kPa,x_m"],
            &["no column \"valve\"", "u_cmd"],
        ),
        (
            &["--design-columns", "time_ms,u_cmd,x_m,p_kPa"],
            &["the pressure column \"x_m\" is in m"],
        ),
        (
            &["--design-columns", "time_ms,u_cmd,p_kPa"],
            &["--design-columns: 3 names given; it takes four"],
        ),
    ] {
        let err = design(columns);
        assert!(
            needles.iter().all(|n| err.contains(n)),
            "{columns:?}: {err}"
        );
    }
}
