//! The experiments of the thesis run on the twin: the identification stair
//! (§4.3.1, appendix A.1.1), the PI-controlled sine tracking (§6.2, A.1.2),
//! and a seeded multisine. Each returns a [`Trace`] with input `pressure`
//! (MPa), output `displacement` (mm) and the columns `valve_in`, `valve_out`,
//! `load_kg` (and `reference` for the sine).

use crate::data::csv::{DataError, write_trace_with_comments};
use crate::data::signals::{Multisine, SineReference, Stair, nyquist_rad_s};
use crate::data::{Trace, readable};

use super::{Rig, Sample, TwinConfig, TwinError};

/// The thesis' PI controller (Table 22, used for both loads): `Kp = 0.06875`
/// V/mm, `Ki = 0.05` V/(mm·sample).
///
/// The thesis prints the gains but not the discretisation. Read as a
/// continuous `Ki = 0.05 V/(mm·s)` the integral action would be far too slow
/// to give the precise 1 rad/s tracking of figure 27 (the loop gain of the
/// twin is about 10 mm/V), so the integral is taken per sample:
/// `u(k) = Kp·e(k) + Ki·Σ_{j≤k} e(j)`, the form of a hand-written MATLAB loop.
/// The integral stops accumulating while the command is saturated (anti-windup).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ThesisPi {
    pub kp: f64,
    pub ki: f64,
}

impl Default for ThesisPi {
    fn default() -> Self {
        ThesisPi {
            kp: 0.06875,
            ki: 0.05,
        }
    }
}

/// What to run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum TwinExperiment {
    /// The identification staircase on the input valve (open loop).
    Stair(Stair),
    /// The sine reference tracked by the thesis' PI on the displacement.
    Sine(SineReference, ThesisPi),
    /// A multisine on the input valve (open loop); the phases come from the seed.
    Multisine(Multisine),
}

impl TwinExperiment {
    /// A short name for the trace's `source`.
    pub fn name(&self) -> String {
        match self {
            TwinExperiment::Stair(_) => "stair".into(),
            TwinExperiment::Sine(r, _) => format!("sine {} rad/s", r.omega_rad_s),
            TwinExperiment::Multisine(_) => "multisine".into(),
        }
    }
}

/// Runs `experiment` on a fresh rig and returns the recorded trace. Row `k`
/// holds the sensors read at `t = k·dt` and the valve commands applied from
/// that instant on (for the sine, computed from that very reading).
pub fn run(config: &TwinConfig, load_kg: f64, seed: u64, experiment: &TwinExperiment) -> Trace {
    run_rig(config, load_kg, seed, experiment).0
}

/// [`run`], with the sample from which the load's ringing left the muscle
/// slack ([`Rig::slack_from`]).
fn run_rig(
    config: &TwinConfig,
    load_kg: f64,
    seed: u64,
    experiment: &TwinExperiment,
) -> (Trace, Option<u64>) {
    let mut rig = Rig::new(config, load_kg, seed);
    let dt = rig.dt();
    let mut rows: Vec<Sample> = Vec::new();
    let mut reference = Vec::new();
    match experiment {
        TwinExperiment::Stair(s) => open_loop(&mut rig, &s.generate(dt), &mut rows),
        TwinExperiment::Multisine(m) => open_loop(&mut rig, &m.generate(dt, seed), &mut rows),
        TwinExperiment::Sine(r, pi) => {
            reference = r.generate(dt);
            let full = config.valve.full_scale_v;
            let mut integral = 0.0;
            for &r_k in &reference {
                let mut s = rig.measure();
                let e = r_k - s.displacement_mm;
                let trial = integral + pi.ki * e;
                let u_raw = pi.kp * e + trial;
                if (0.0..=full).contains(&u_raw) {
                    integral = trial;
                }
                let u = u_raw.clamp(0.0, full);
                s.valve_in = u;
                s.valve_out = config.valve.output_command(u);
                rows.push(s);
                rig.advance(u);
            }
        }
    }
    let source = format!(
        "twin {} {} kg seed {}",
        experiment.name(),
        readable(load_kg),
        seed
    );
    let mut trace = Trace::uniform(
        source,
        dt,
        rows.iter().map(|s| s.pressure_mpa).collect(),
        rows.iter().map(|s| s.displacement_mm).collect(),
    );
    trace
        .extra
        .push(("valve_in".into(), rows.iter().map(|s| s.valve_in).collect()));
    trace.extra.push((
        "valve_out".into(),
        rows.iter().map(|s| s.valve_out).collect(),
    ));
    trace
        .extra
        .push(("load_kg".into(), vec![load_kg; rows.len()]));
    if !reference.is_empty() {
        trace.extra.push(("reference".into(), reference));
    }
    (trace, rig.slack_from())
}

fn open_loop(rig: &mut Rig, command: &[f64], rows: &mut Vec<Sample>) {
    let valve = rig.config().valve;
    for &u in command {
        let mut s = rig.measure();
        let u = u.clamp(0.0, valve.full_scale_v);
        s.valve_in = u;
        s.valve_out = valve.output_command(u);
        rows.push(s);
        rig.advance(u);
    }
}

/// The experiment kinds of `mckibben twin --experiment`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    Stair,
    Sine,
    Multisine,
}

impl Kind {
    pub const ALL: [Kind; 3] = [Kind::Stair, Kind::Sine, Kind::Multisine];

    pub fn as_str(&self) -> &'static str {
        match self {
            Kind::Stair => "stair",
            Kind::Sine => "sine",
            Kind::Multisine => "multisine",
        }
    }
}

/// An experiment's name in any case (`Stair`, `SINE`), as `--experiment`
/// reads it.
impl std::str::FromStr for Kind {
    type Err = crate::names::UnknownName;

    fn from_str(s: &str) -> Result<Kind, Self::Err> {
        crate::names::one_of("experiment", s, &Kind::ALL, |k| k.as_str())
    }
}

/// The sine reference's ω (rad/s) unless one is given: the thesis' slowest.
pub const DEFAULT_FREQ_RAD_S: f64 = 1.0;

/// Everything that decides a twin run, as given on the command line; the
/// CLI and the tests that regenerate the shipped files both go through it.
#[derive(Debug, Clone, PartialEq)]
pub struct RunSpec {
    pub kind: Kind,
    /// Hanging load (kg).
    pub load_kg: f64,
    /// Seed of the sensor noise (and the multisine's phases).
    pub seed: u64,
    /// ω of the sine reference (rad/s).
    pub freq_rad_s: f64,
    /// `--effect NAME=VALUE` settings, in the order given.
    pub effects: Vec<String>,
}

impl RunSpec {
    /// The default configuration with this spec's effect settings applied.
    pub fn config(&self) -> Result<TwinConfig, TwinError> {
        let mut config = TwinConfig::default();
        config.effects.apply_args(&self.effects)?;
        config.validate()?;
        Ok(config)
    }

    /// The experiment with the thesis' settings (appendix A.1).
    pub fn experiment(&self) -> TwinExperiment {
        match self.kind {
            Kind::Stair => TwinExperiment::Stair(Stair::default()),
            Kind::Sine => TwinExperiment::Sine(
                SineReference {
                    omega_rad_s: self.freq_rad_s,
                    ..SineReference::default()
                },
                ThesisPi::default(),
            ),
            Kind::Multisine => TwinExperiment::Multisine(Multisine::default()),
        }
    }

    /// The command that reproduces this run (without `--out`), written as
    /// the CSV's comment line.
    pub fn command(&self) -> String {
        let mut c = format!(
            "mckibben twin --experiment {} --load {} --seed {}",
            self.kind.as_str(),
            readable(self.load_kg),
            self.seed
        );
        if self.kind == Kind::Sine {
            c.push_str(&format!(" --freq {}", readable(self.freq_rad_s)));
        }
        for e in &self.effects {
            c.push_str(&format!(" --effect {e}"));
        }
        c
    }

    /// The comment lines written above the CSV header.
    pub fn comments(&self) -> Vec<String> {
        vec![format!("generated by: {}", self.command())]
    }

    /// Writes `trace` (from [`RunSpec::run`]) as CSV with the command as a
    /// comment, atomically, in `data::csv`'s deterministic format.
    pub fn write_csv(&self, path: &std::path::Path, trace: &Trace) -> Result<(), DataError> {
        write_trace_with_comments(path, trace, &self.comments())
    }

    /// The configuration ([`RunSpec::config`]) once it is checked to carry
    /// the load ([`Rig::check_load`]).
    pub fn checked_config(&self) -> Result<TwinConfig, TwinError> {
        let config = self.config()?;
        Rig::check_load(&config, self.load_kg)?;
        Ok(config)
    }

    /// Runs the experiment; an error names a bad load, frequency or effect.
    pub fn run(&self) -> Result<Trace, TwinError> {
        let config = self.checked_config()?;
        if self.kind == Kind::Sine && !(self.freq_rad_s.is_finite() && self.freq_rad_s > 0.0) {
            return Err(TwinError::BadFrequency(self.freq_rad_s));
        }
        let dt = config.sample_time_s;
        if self.kind == Kind::Sine && self.freq_rad_s >= nyquist_rad_s(dt) {
            return Err(TwinError::AboveNyquist {
                freq: self.freq_rad_s,
                dt,
                nyquist: nyquist_rad_s(dt),
            });
        }
        let (mut trace, slack_from) = run_rig(&config, self.load_kg, self.seed, &self.experiment());
        if let Some(k) = slack_from {
            return Err(TwinError::Slack {
                k: k as usize,
                t_s: k as f64 * dt,
                command: self.command(),
            });
        }
        trace.source = self.command();
        let columns = [
            (trace.input_name.as_str(), trace.input.as_slice()),
            (trace.output_name.as_str(), trace.output.as_slice()),
        ];
        let extra = trace.extra.iter().map(|(n, v)| (n.as_str(), v.as_slice()));
        for (column, values) in columns.into_iter().chain(extra) {
            if let Some(k) = values.iter().position(|v| !v.is_finite()) {
                return Err(TwinError::NotFinite {
                    column: column.to_string(),
                    k,
                    t_s: trace.t[k],
                    command: self.command(),
                });
            }
        }
        Ok(trace)
    }
}
