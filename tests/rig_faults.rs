//! Attacks on the link: `mckibben control` against a scripted rig that
//! behaves until sample 5 and then sends a bad line, a value no sensor can
//! read, an impossible jump, exits, stalls or floods the link. Every case
//! runs the PI, the feedforward PID and the MPC, and checks what the rig
//! last received, the exit status and the run log's last line; every run
//! checks that each command the rig received was a number in 0–10 V.
//! (The deadline is generous, so that a loaded machine cannot make a
//! measurement miss it, except where the rig stalls on purpose.)
//!
//! The model-based controllers identify their model from one open-loop
//! record, written once by `mckibben twin` (`--design-data`): what is under
//! test is the link, and identifying on the twin's own design runs for
//! every controller would spend most of the time on the design.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

const BIN: &str = env!("CARGO_BIN_EXE_mckibben");

/// The rig: answers `U k` with `M k+1 t 0.2 25` (25 mm below the 30 mm
/// reference, so every controller raises the valve), and from sample
/// `RIG_AT` on does what `RIG_MODE` says. `RIG_LINE` is the bad line, with
/// `%k` and `%t` standing for the sample and its time. Every line it reads
/// goes to `RIG_REC`. `hangup` closes its stdin, then sends `M 5`.
const RIG: &str = r#"
read hello; echo "$hello" >> "$RIG_REC"; echo "READY 1 0.01"
k=0
while read cmd; do
  echo "$cmd" >> "$RIG_REC"
  [ "$cmd" = STOP ] && exit 0
  k=$((k+1))
  t=$(printf '%d.%02d' $((k/100)) $((k%100)))
  honest="M $k $t 0.2 25"
  if [ $k -lt "$RIG_AT" ]; then echo "$honest"; continue; fi
  bad=$(printf '%s' "$RIG_LINE" | sed "s/%k/$k/g; s/%t/$t/g")
  case $RIG_MODE in
    once) if [ $k -eq "$RIG_AT" ]; then printf '%s\n' "$bad"; else echo "$honest"; fi ;;
    from) printf '%s\n' "$bad" ;;
    exit) exit 0 ;;
    hangup) exec 0<&-; echo "$honest"; exec sleep 1 ;;
    stall) ;;
    flood) if [ $k -eq "$RIG_AT" ]; then echo "$honest"; yes "$honest" | head -n 100000 & fi ;;
  esac
done
"#;

const CONTROLLERS: [&str; 3] = ["pi", "ff-pid", "mpc"];

/// What a run left behind.
struct Seen {
    controller: &'static str,
    code: Option<i32>,
    stderr: String,
    /// Every line the rig read.
    received: Vec<String>,
    log: String,
}

impl Seen {
    /// The commands the rig received, `(k, volts)`.
    fn commands(&self) -> Vec<(u64, f64)> {
        self.received
            .iter()
            .filter_map(|l| {
                let mut f = l.strip_prefix("U ")?.split(' ');
                Some((f.next()?.parse().ok()?, f.next()?.parse().ok()?))
            })
            .collect()
    }

    /// The last command the rig received for sample `k`.
    fn volts(&self, k: u64) -> f64 {
        let c = self.commands();
        c.iter()
            .rev()
            .find(|(j, _)| *j == k)
            .unwrap_or_else(|| panic!("{}: no U {k} in {c:?}", self.controller))
            .1
    }

    fn last_log_line(&self) -> &str {
        self.log.trim_end().lines().last().unwrap_or("")
    }

    /// The run failed with `why`, the rig last received `U close 0` and
    /// `STOP`, and the log ends with the valve closed.
    fn closed(&self, close: u64, why: &str) {
        let c = self.controller;
        assert_eq!(self.code, Some(1), "{c}: {}", self.stderr);
        assert!(
            self.stderr.contains(why),
            "{c}: `{why}` not in\n{}",
            self.stderr
        );
        let tail: Vec<&str> = self
            .received
            .iter()
            .rev()
            .take(2)
            .map(|s| s.as_str())
            .collect();
        assert_eq!(tail, ["STOP", &format!("U {close} 0")], "{c}");
        assert_eq!(
            self.last_log_line(),
            format!("# valve closed: U {close} 0, STOP"),
            "{c}"
        );
    }

    /// The samples from 5 to `to` were held at the command of sample 4.
    fn held(&self, to: u64) {
        let u4 = self.volts(4);
        for k in 5..=to {
            assert_eq!(self.volts(k), u4, "{}: U {k} is not U 4", self.controller);
        }
    }
}

/// The open-loop record every design is identified from: the twin's
/// multisine at the design load, written once per test binary into the
/// folder Cargo keeps for integration tests.
fn design_record() -> &'static Path {
    static RECORD: OnceLock<PathBuf> = OnceLock::new();
    RECORD.get_or_init(|| {
        let path = Path::new(env!("CARGO_TARGET_TMPDIR")).join("rig_faults_multisine.csv");
        let out = Command::new(BIN)
            .args(["twin", "--experiment", "multisine", "--load", "4.5"])
            .args(["--seed", "1", "--out"])
            .arg(&path)
            .output()
            .expect("run mckibben twin");
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        path
    })
}

/// Runs `controller` on the rig in `mode` from sample 5 with `line`.
fn attack(controller: &'static str, mode: &str, line: &str, extra: &[&str]) -> Seen {
    let dir = tempfile::tempdir().unwrap();
    let rig = dir.path().join("rig.sh");
    std::fs::write(&rig, RIG).unwrap();
    let rec = dir.path().join("received.txt");
    let log = dir.path().join("log");
    let out = Command::new(BIN)
        .args(["control", "--controller", controller])
        .args(["--freq", "3", "--warmup", "2", "--duration", "4"])
        .args([
            "--steady-from",
            "2",
            "--tuned-gains",
            "2.2164,65.528,0.0219",
        ])
        .args(["--log", log.to_str().unwrap()])
        .arg("--design-data")
        .arg(design_record())
        .args(if extra.contains(&"--deadline") {
            &[][..]
        } else {
            &["--deadline", "5000"]
        })
        .args(extra)
        .arg("--plant")
        // `exec`: no shell in between holds the rig's pipes open after it.
        .arg(format!("cmd:exec sh {}", rig.display()))
        .env("RIG_REC", &rec)
        .env("RIG_MODE", mode)
        .env("RIG_AT", "5")
        .env("RIG_LINE", line)
        .env("XDG_RUNTIME_DIR", std::env::temp_dir())
        .output()
        .expect("run mckibben");
    let seen = Seen {
        controller,
        code: out.status.code(),
        stderr: String::from_utf8_lossy(&out.stderr).into_owned(),
        received: std::fs::read_to_string(&rec)
            .unwrap_or_default()
            .lines()
            .map(String::from)
            .collect(),
        log: std::fs::read_to_string(log.join(format!("{controller}_3rad.csv")))
            .unwrap_or_default(),
    };
    assert_eq!(seen.received.first().map(|s| s.as_str()), Some("HELLO 1"));
    for (k, v) in seen.commands() {
        assert!(
            (0.0..=10.0).contains(&v),
            "{controller}: the rig received U {k} {v}"
        );
    }
    seen
}

/// Each controller against one bad line at sample 5: the run ends there.
fn bad_line(line: &str, why: &str) {
    for c in CONTROLLERS {
        attack(c, "once", line, &[]).closed(5, why);
    }
}

#[test]
fn a_field_that_is_not_a_finite_number_ends_the_run() {
    bad_line(
        "M 5 0.05 0.2 nan",
        "line 6 `M 5 0.05 0.2 nan`: displacement_mm `nan`",
    );
    bad_line(
        "M 5 0.05 inf 25",
        "pressure_mpa `inf` is not a finite number",
    );
}

#[test]
fn a_5000_digit_number_ends_the_run() {
    bad_line(
        &format!("M 5 0.05 0.2 {}", "7".repeat(5000)),
        "longer than 4096 bytes",
    );
}

#[test]
fn a_wrong_sample_index_or_a_negative_time_ends_the_run() {
    bad_line("M 3 0.05 0.2 25", "sample 3 was already used");
    bad_line("M 5 -0.05 0.2 25", "its time stamp -0.05 s");
}

#[test]
fn missing_fields_or_non_ascii_bytes_end_the_run() {
    bad_line("M 5 0.05 0.2", "`M` takes 4 field(s)");
    bad_line("M 5 0.05 0.2 2\u{e9}5", "not a line of printable ASCII");
}

/// Each controller against measurements that cannot be, from sample 5 on:
/// samples 5 and 6 are held at U 4, the third ends the run.
fn implausible(line: &str, why: &str) {
    for c in CONTROLLERS {
        let seen = attack(c, "from", line, &[]);
        seen.held(6);
        seen.closed(7, why);
        assert!(
            seen.log
                .contains("# sample 5: implausible measurement, line 6"),
            "{c}: {}",
            seen.log
        );
    }
}

#[test]
fn huge_values_are_implausible_and_never_reach_the_controller() {
    implausible(
        "M %k %t 0.2 1e308",
        "implausible measurement (3 in a row): displacement 1e308 mm is outside the rig's range -10.5…55.5 mm",
    );
    implausible("M %k %t 0.2 -1e308", "displacement -1e308 mm is outside");
    implausible(
        "M %k %t 1e308 25",
        "pressure 1e308 MPa is outside the rig's range -0.04…0.44 MPa",
    );
}

#[test]
fn tiny_values_and_impossible_jumps_are_implausible() {
    // 25 mm to nothing in 10 ms; 25 to 45 mm, in range, but 2 m/s.
    implausible(
        "M %k %t 0.2 1e-300",
        "displacement moved 25 mm since sample 4",
    );
    implausible(
        "M %k %t 0.2 45",
        "displacement moved 20 mm since sample 4 (25 mm)",
    );
}

#[test]
fn the_ranges_given_on_the_command_line_are_the_ones_checked() {
    for c in CONTROLLERS {
        // 25 mm is a fine reading on the twin but not on a rig that reads
        // 0–20 mm: the first sample already is implausible.
        let seen = attack(
            c,
            "once",
            "M 5 0.05 0.2 25",
            &["--displacement-range", "0,20"],
        );
        seen.closed(
            3,
            "line 4 `M 3 0.03 0.2 25`: implausible measurement (3 in a row)",
        );
        assert!(seen.log.contains(
            "displacement 0…20 mm (displacement from the command line, pressure the twin's)"
        ));
    }
}

#[test]
fn a_single_glitch_is_held_and_the_run_goes_on() {
    for c in CONTROLLERS {
        let seen = attack(c, "once", "M 5 0.05 0.2 1e308", &[]);
        assert_eq!(seen.code, Some(0), "{c}: {}", seen.stderr);
        seen.held(5);
        assert_eq!(
            seen.received.last().map(|s| s.as_str()),
            Some("STOP"),
            "{c}"
        );
        assert_eq!(seen.last_log_line(), "# run complete; STOP sent", "{c}");
        assert!(
            seen.log.contains("# sample 5: implausible measurement"),
            "{c}"
        );
    }
}

#[test]
fn a_rig_that_exits_mid_run_gives_an_error_not_a_signal() {
    for c in CONTROLLERS {
        let seen = attack(c, "exit", "", &[]);
        assert_eq!(
            seen.code,
            Some(1),
            "{c}: killed by a signal? {}",
            seen.stderr
        );
        let u4 = seen.volts(4);
        assert!(
            seen.stderr.contains(&format!(
                "went away (end of stream); last exchanged: M 4 received (line 5), U 4 {u4} sent"
            )),
            "{c}: {}",
            seen.stderr
        );
        // The rig read U 4 and left; the log says so and ends on the close.
        assert_eq!(
            seen.received.last().map(|s| s.as_str()),
            Some(&*format!("U 4 {u4}"))
        );
        assert!(seen.log.contains("# error: rig"), "{c}: {}", seen.log);
        assert!(
            seen.last_log_line()
                .ends_with("the valve is as the rig left it"),
            "{c}: {}",
            seen.log
        );
    }
}

#[test]
fn a_rig_that_stalls_is_silent_and_the_valve_is_closed() {
    for c in CONTROLLERS {
        let seen = attack(c, "stall", "", &["--deadline", "300", "--max-missing", "2"]);
        // Sample 5 held; the second missing one ends the run.
        seen.held(5);
        seen.closed(6, "no measurement for 2 samples in a row");
    }
}

#[test]
fn a_flood_of_lines_ends_at_its_second_line() {
    for c in CONTROLLERS {
        let seen = attack(c, "flood", "", &[]);
        seen.closed(
            6,
            "line 7 `M 5 0.05 0.2 25`: stale measurement: sample 5 was already used",
        );
    }
}

#[test]
fn twin_serve_refuses_a_command_outside_0_to_10_volts_and_closes_the_valve() {
    use std::io::Write;
    let mut serve = Command::new(BIN)
        .args(["twin", "serve", "--load", "4.5"])
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let session = "HELLO 1\nU 0 99\nHELLO 1\nU 0 -5\nHELLO 1\nU 0 10\n";
    serve
        .stdin
        .take()
        .unwrap()
        .write_all(session.as_bytes())
        .unwrap();
    let out = serve.wait_with_output().unwrap();
    assert!(out.status.success());
    let stdout = String::from_utf8_lossy(&out.stdout);
    let lines: Vec<&str> = stdout.lines().collect();
    let ready = "READY 1 0.01 -0.04 0.44 -10.5 55.5";
    assert_eq!(lines.len(), 6, "{stdout}");
    assert_eq!(lines[0], ready);
    assert_eq!(
        lines[1],
        "ERR `U 0 99`: volts `99` is outside 0–10 V; input valve closed"
    );
    assert_eq!(lines[2], ready);
    assert_eq!(
        lines[3],
        "ERR `U 0 -5`: volts `-5` is outside 0–10 V; input valve closed"
    );
    // 10 V is in range: the twin advances a sample.
    assert!(lines[5].starts_with("M 1 0.01 "), "{stdout}");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(
        stderr
            .matches("session ended after 0 samples (`U 0 ")
            .count(),
        2,
        "{stderr}"
    );
    assert_eq!(
        stderr.matches("input valve closed (0 V)").count(),
        3,
        "{stderr}"
    );
}

/// A ringing large enough to leave the muscle slack takes the twin outside
/// its physics: `twin serve` ends the session with an error line, as a
/// rig's own fault would, instead of sending displacements no muscle
/// makes. At the documented scale the same session runs to the end.
#[test]
fn twin_serve_ends_a_session_whose_muscle_goes_slack() {
    use std::io::Write;
    let session = |ringing: &str| {
        let mut serve = Command::new(BIN)
            .args(["twin", "serve", "--load", "4.5", "--effect", ringing])
            .stdin(std::process::Stdio::piped())
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        // The valve full open for 3 s, then a STOP.
        let mut lines = String::from("HELLO 1\n");
        for k in 0..300 {
            lines += &format!("U {k} 10\n");
        }
        lines += "STOP\n";
        serve
            .stdin
            .take()
            .unwrap()
            .write_all(lines.as_bytes())
            .unwrap();
        let out = serve.wait_with_output().unwrap();
        assert!(out.status.success());
        let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
        let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
        (stdout, stderr)
    };
    let (stdout, stderr) = session("ringing=20");
    let lines: Vec<&str> = stdout.lines().collect();
    let end = lines
        .iter()
        .position(|l| l.starts_with("ERR the load's ringing left the muscle slack at sample "))
        .unwrap_or_else(|| panic!("{stdout}"));
    assert!(
        lines[end].ends_with("; input valve closed"),
        "{}",
        lines[end]
    );
    // Measurements up to there, none after: the session is over, and the
    // commands still coming are refused until a new HELLO.
    assert!(
        lines[1..end].iter().all(|l| l.starts_with("M ")),
        "{stdout}"
    );
    assert!(end > 1 && end < 300, "{end}");
    assert!(lines[end + 1..].iter().all(|l| *l == "ERR say HELLO first"));
    assert!(stderr.contains("slack"), "{stderr}");

    let (stdout, _) = session("ringing=1");
    assert!(!stdout.contains("ERR"), "{stdout}");
    assert_eq!(stdout.lines().filter(|l| l.starts_with("M ")).count(), 300);
}

#[test]
fn a_rig_that_hangs_up_gives_an_error_not_a_signal() {
    for c in CONTROLLERS {
        let seen = attack(c, "hangup", "", &[]);
        assert_eq!(
            seen.code,
            Some(1),
            "{c}: killed by a signal? {}",
            seen.stderr
        );
        let u4 = seen.volts(4);
        assert!(
            seen.stderr.contains(&format!(
                "went away (Broken pipe (os error 32)); last exchanged: M 5 received (line 6), U 4 {u4} sent"
            )),
            "{c}: {}",
            seen.stderr
        );
        assert_eq!(
            seen.received.last().map(|s| s.as_str()),
            Some(&*format!("U 4 {u4}"))
        );
        assert_eq!(
            seen.last_log_line(),
            "# U 5 0, STOP not delivered (Broken pipe (os error 32)): the valve is as the rig left it",
            "{c}"
        );
    }
}
