//! The withheld-effect check: data generated from the fitted nominal model
//! with one catalogued effect added (each effect at two magnitudes, with
//! noise), a control with no effect and a case with two effects. The
//! diagnosis, not told what was added, must name the effect first, recover
//! its size within 20 %, and close at least half of the gap; on the control it
//! must name nothing; on the two-effect case it must name both.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use serde::Serialize;

use super::effects::{Augmented, Context, Effect};
use super::select::{Data, Settings, fit_seeds};
use super::{Diagnosis, diagnose};
use crate::data::Trace;
use crate::model::Family;

/// The nominal model the cases are generated from: the baseline fitted to
/// real (or twin) data.
#[derive(Debug, Clone)]
pub struct Nominal {
    pub family: Family,
    pub trace: Trace,
    pub data: Data,
    pub params: Vec<f64>,
    /// Nominal simulated output, absolute units.
    pub output: Vec<f64>,
}

impl Nominal {
    /// Fits `family` to `trace` with the diagnosis' baseline budget.
    pub fn fit(trace: &Trace, family: Family, settings: &Settings) -> anyhow::Result<Nominal> {
        let data = Data::new(std::slice::from_ref(trace))?;
        let model = Augmented::new(family, Vec::new(), 1);
        let fit = fit_seeds(&data, &model, None, settings, 0);
        let pred = data.predict(&model, &fit.best.params);
        let ym = data.whole[0].y_mean;
        let output = pred[0].iter().map(|&v| v as f64 + ym).collect();
        Ok(Nominal {
            family,
            trace: trace.clone(),
            data,
            params: fit.best.params,
            output,
        })
    }

    fn ctx(&self) -> &Context {
        &self.data.ctx[0]
    }

    fn output_range(&self) -> (f64, f64) {
        self.output
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
                (a.min(v), b.max(v))
            })
    }
}

/// One withheld-effect case.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Case {
    pub name: String,
    /// Effects added with their full parameter vectors.
    pub effects: Vec<(Effect, Vec<f64>)>,
}

/// The standard cases: every effect at a small and a large magnitude, scaled
/// to the nominal data; the control; `delay` with `saturation`.
pub fn cases(nominal: &Nominal, effects: &[Effect]) -> Vec<Case> {
    let c = nominal.ctx();
    let ru = c.input_max - c.input_min;
    let (omin, omax) = nominal.output_range();
    let ry = omax - omin;
    let v = (c.max_step / c.dt).max(f64::MIN_POSITIVE);
    let peak = if c.drives_up { omax } else { omin };
    let toward = if c.drives_up { -1.0 } else { 1.0 };
    let size = |e: Effect, big: bool| -> Vec<f64> {
        let f = |small: f64, large: f64| if big { large } else { small };
        match e {
            Effect::Delay => vec![f(3.0, 8.0)],
            Effect::Deadzone => vec![c.input_min.max(0.0) + f(0.15, 0.3) * ru],
            Effect::Saturation => vec![peak + toward * f(0.1, 0.25) * ry],
            Effect::Asymmetry => vec![f(0.1, 0.25)],
            Effect::Inertia => vec![f(0.4, 0.7)],
            Effect::Backlash => vec![f(0.08, 0.2) * ru],
            Effect::Creep => vec![0.995, f(0.2, 0.35) * ry / ru],
            Effect::Rate => vec![f(0.3, 0.8) / v],
            Effect::Load => vec![f(0.1, 0.25)],
        }
    };
    let mut out = vec![Case {
        name: "control".into(),
        effects: Vec::new(),
    }];
    for &e in effects {
        for (big, label) in [(false, "small"), (true, "large")] {
            out.push(Case {
                name: format!("{e} ({label})"),
                effects: vec![(e, size(e, big))],
            });
        }
    }
    if effects.contains(&Effect::Delay) && effects.contains(&Effect::Saturation) {
        out.push(Case {
            name: "delay + saturation".into(),
            effects: vec![
                (Effect::Delay, size(Effect::Delay, false)),
                (Effect::Saturation, size(Effect::Saturation, false)),
            ],
        });
    }
    out
}

/// Standard deviation of the added measurement noise: 0.5 % of the nominal
/// output range.
pub fn noise_sigma(nominal: &Nominal) -> f64 {
    let (lo, hi) = nominal.output_range();
    0.005 * (hi - lo)
}

/// The traces of a case: the nominal input, the nominal model with the case's
/// effects, plus white noise (seeded). The `load` effect needs two datasets:
/// the second is the same input under a different load.
pub fn synthesize(nominal: &Nominal, case: &Case, seed: u64) -> Vec<Trace> {
    let datasets = if case.effects.iter().any(|(e, _)| *e == Effect::Load) {
        2
    } else {
        1
    };
    let model = Augmented::new(
        nominal.family,
        case.effects.iter().map(|(e, _)| *e).collect(),
        datasets,
    );
    let mut theta = nominal.params.clone();
    for (_, p) in &case.effects {
        theta.extend_from_slice(p);
    }
    let theta32: Vec<f32> = theta.iter().map(|&v| v as f32).collect();
    let whole = &nominal.data.whole[0];
    let sigma = noise_sigma(nominal);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let noise = Normal::new(0.0, sigma).expect("finite sigma");
    (0..datasets)
        .map(|i| {
            let y = model.simulate(&theta32, i, nominal.ctx(), whole);
            let mut t = nominal.trace.clone();
            t.source = format!("self-test {}#{i}", case.name);
            // The first sample is left clean: the free run starts from it, and
            // the Bouc-Wen state remembers a noisy start for hundreds of
            // samples, which would blur every case alike.
            t.output = y
                .iter()
                .enumerate()
                .map(|(k, &v)| {
                    let e = noise.sample(&mut rng);
                    v as f64 + whole.y_mean + if k == 0 { 0.0 } else { e }
                })
                .collect();
            t
        })
        .collect()
}

/// The size of an effect the self-test recovers: its primary parameter, or
/// for `deadzone` and `saturation` the distance of the threshold from the
/// data's edge (an absolute level would make 20 % meaningless).
fn size_of(nominal: &Nominal, e: Effect, params: &[f64]) -> f64 {
    let c = nominal.ctx();
    let (omin, omax) = nominal.output_range();
    match e {
        Effect::Deadzone => params[0] - c.input_min.max(0.0),
        Effect::Saturation => {
            if c.drives_up {
                omax - params[0]
            } else {
                params[0] - omin
            }
        }
        _ => params[e.primary()],
    }
}

/// The outcome of one case.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Outcome {
    pub case: String,
    pub truth: Vec<Effect>,
    pub named: Vec<Effect>,
    /// Size of the (first) true effect and what the diagnosis recovered.
    pub size_true: Option<f64>,
    pub size_found: Option<f64>,
    pub size_error: Option<f64>,
    pub baseline_rmse: f64,
    pub final_rmse: f64,
    pub noise_floor: f64,
    pub gap_closed: f64,
    pub pass: bool,
    /// What failed, if anything.
    pub note: String,
}

/// Judges a diagnosis of a case.
pub fn judge(nominal: &Nominal, case: &Case, d: &Diagnosis) -> Outcome {
    let truth: Vec<Effect> = case.effects.iter().map(|(e, _)| *e).collect();
    let named = d.selection.verdict.clone();
    let mut notes = Vec::new();
    let (mut size_true, mut size_found, mut size_error) = (None, None, None);
    let gap = d.last().gap_closed;
    match truth.len() {
        0 => {
            if !named.is_empty() {
                notes.push("control: named an effect".to_string());
            }
        }
        _ => {
            let (e, p) = &case.effects[0];
            if truth.len() == 1 && named.first() != Some(e) {
                notes.push(format!("named {:?} first", named.first().map(|x| x.name())));
            }
            if truth.iter().any(|t| !named.contains(t)) {
                notes.push("missed a true effect".into());
            }
            let st = size_of(nominal, *e, p);
            size_true = Some(st);
            // The recovered parameters: from the round the effect was accepted in.
            let found = d
                .selection
                .rounds
                .iter()
                .filter(|r| r.accepted == Some(*e))
                .flat_map(|r| r.candidates.iter().filter(|c| c.effect == *e))
                .next();
            if let Some(c) = found {
                let at = c.model.offset_of(*e).expect("effect in model");
                let sf = size_of(nominal, *e, &c.fit.best.params[at..]);
                let err = (sf - st).abs() / st.abs();
                size_found = Some(sf);
                size_error = Some(err);
                if err > 0.2 {
                    notes.push(format!("size off by {:.0} %", 100.0 * err));
                }
            }
            if gap < 0.5 {
                notes.push(format!("closed only {:.0} % of the gap", 100.0 * gap));
            }
        }
    }
    Outcome {
        case: case.name.clone(),
        truth,
        named,
        size_true,
        size_found,
        size_error,
        baseline_rmse: d.baseline().val_rmse,
        final_rmse: d.last().val_rmse,
        noise_floor: d.noise_floor_rmse,
        gap_closed: gap,
        pass: notes.is_empty(),
        note: notes.join("; "),
    }
}

/// Generates and diagnoses one case.
pub fn run_case(
    nominal: &Nominal,
    case: &Case,
    effects: &[Effect],
    settings: &Settings,
    seed: u64,
) -> anyhow::Result<Outcome> {
    let traces = synthesize(nominal, case, seed);
    if traces
        .iter()
        .any(|t| t.output.iter().any(|v| !v.is_finite()))
    {
        // The nominal model with this effect explodes: there is no data to
        // diagnose, and the case counts as failed rather than hidden.
        return Ok(Outcome {
            case: case.name.clone(),
            truth: case.effects.iter().map(|(e, _)| *e).collect(),
            named: Vec::new(),
            size_true: None,
            size_found: None,
            size_error: None,
            baseline_rmse: f64::NAN,
            final_rmse: f64::NAN,
            noise_floor: f64::NAN,
            gap_closed: 0.0,
            pass: false,
            note: "the nominal model with this effect diverges: no data generated".into(),
        });
    }
    let d = diagnose(&traces, nominal.family, effects, settings)?;
    Ok(judge(nominal, case, &d))
}

/// Rows (truth) × columns (first effect named, or `none`) of the single-effect
/// cases and the control.
pub fn confusion(outcomes: &[Outcome], effects: &[Effect]) -> Vec<(String, Vec<usize>)> {
    let mut cols: Vec<String> = effects.iter().map(|e| e.name().to_string()).collect();
    cols.push("none".into());
    let mut rows: Vec<(String, Vec<usize>)> = Vec::new();
    for o in outcomes.iter().filter(|o| o.truth.len() <= 1) {
        let label = o
            .truth
            .first()
            .map_or("none".to_string(), |e| e.name().to_string());
        let col = o
            .named
            .first()
            .map_or("none".to_string(), |e| e.name().to_string());
        let ci = cols
            .iter()
            .position(|c| *c == col)
            .unwrap_or(cols.len() - 1);
        match rows.iter_mut().find(|(l, _)| *l == label) {
            Some((_, v)) => v[ci] += 1,
            None => {
                let mut v = vec![0; cols.len()];
                v[ci] += 1;
                rows.push((label, v));
            }
        }
    }
    rows
}

/// The confusion table and the per-case lines, as text.
pub fn table(outcomes: &[Outcome], effects: &[Effect]) -> String {
    use std::fmt::Write as _;
    let mut o = String::new();
    let mut cols: Vec<&str> = effects.iter().map(|e| e.name()).collect();
    cols.push("none");
    let _ = write!(o, "{:<12}", "true \\ named");
    for c in &cols {
        let _ = write!(o, " {:>5}", &c[..c.len().min(5)]);
    }
    let _ = writeln!(o);
    for (label, counts) in confusion(outcomes, effects) {
        let _ = write!(o, "{label:<12}");
        for n in counts {
            let _ = write!(o, " {n:>5}");
        }
        let _ = writeln!(o);
    }
    let _ = writeln!(o);
    let _ = writeln!(
        o,
        "{:<24} {:<22} {:>10} {:>10} {:>7} {:>8} {:>8} {:>7}  result",
        "case", "named", "size true", "found", "error", "RMSE 0", "RMSE 1", "gap"
    );
    for r in outcomes {
        let named: Vec<_> = r.named.iter().map(|e| e.name()).collect();
        let f = |v: Option<f64>| v.map_or("—".to_string(), |x| format!("{x:.4}"));
        let _ = writeln!(
            o,
            "{:<24} {:<22} {:>10} {:>10} {:>7} {:>8.4} {:>8.4} {:>6.0}%  {}",
            r.case,
            if named.is_empty() {
                "none".to_string()
            } else {
                named.join("+")
            },
            f(r.size_true),
            f(r.size_found),
            r.size_error
                .map_or("—".to_string(), |e| format!("{:.1}%", 100.0 * e)),
            r.baseline_rmse,
            r.final_rmse,
            100.0 * r.gap_closed,
            if r.pass {
                "pass".to_string()
            } else {
                format!("FAIL: {}", r.note)
            }
        );
    }
    o
}

/// One twin check: the gap the diagnosis explains on twin data with one
/// non-ideal effect on, against the gap that disappears when the twin runs
/// without it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TwinOutcome {
    /// The twin's effect name (`mckibben twin --effect`).
    pub twin_effect: String,
    pub verdict_on: Vec<Effect>,
    pub verdict_off: Vec<Effect>,
    /// Baseline validation RMSE with the effect on and off.
    pub baseline_on: f64,
    pub baseline_off: f64,
    /// `(R_b² − R_f²)_on − (R_b² − R_f²)_off`: what the diagnosis explains
    /// on top of what it explains without the effect (residual energy, mm²).
    pub attributed: f64,
    /// `R_b,on² − R_b,off²`: the baseline's gap that disappears with the effect.
    pub disappears: f64,
    pub ratio: f64,
    /// Within 20 %, and the effect makes a gap at all (≥ 5 % of the baseline's energy).
    pub pass: bool,
}

/// The twin effects checked: the ones that leave a mark on a stair.
pub const TWIN_EFFECTS: [&str; 4] = ["friction", "deadband", "spool_lag", "compliance"];

/// Runs the twin's stair (4.5 kg, seed 1) with every non-ideal effect of
/// [`TWIN_EFFECTS`] off except one, and with all off, diagnoses both and
/// compares the gap attributed with the gap that disappears.
pub fn twin_check(
    family: Family,
    effects: &[Effect],
    settings: &Settings,
) -> anyhow::Result<Vec<TwinOutcome>> {
    use crate::twin::experiment::{Kind, RunSpec};
    let run = |keep: Option<&str>| -> anyhow::Result<Trace> {
        let spec = RunSpec {
            kind: Kind::Stair,
            load_kg: 4.5,
            seed: 1,
            freq_rad_s: 1.0,
            effects: TWIN_EFFECTS
                .iter()
                .chain(&["endstop"])
                .filter(|e| Some(**e) != keep)
                .map(|e| format!("{e}=0"))
                .collect(),
        };
        spec.run().map_err(|e| anyhow::anyhow!("twin: {e}"))
    };
    let explained = |d: &Diagnosis| d.baseline().val_rmse.powi(2) - d.last().val_rmse.powi(2);
    let off = diagnose(&[run(None)?], family, effects, settings)?;
    let mut out = Vec::new();
    for name in TWIN_EFFECTS {
        let on = diagnose(&[run(Some(name))?], family, effects, settings)?;
        let attributed = explained(&on) - explained(&off);
        let disappears = on.baseline().val_rmse.powi(2) - off.baseline().val_rmse.powi(2);
        let ratio = attributed / disappears;
        let pass =
            (ratio - 1.0).abs() <= 0.2 && disappears >= 0.05 * on.baseline().val_rmse.powi(2);
        out.push(TwinOutcome {
            twin_effect: name.into(),
            verdict_on: on.selection.verdict.clone(),
            verdict_off: off.selection.verdict.clone(),
            baseline_on: on.baseline().val_rmse,
            baseline_off: off.baseline().val_rmse,
            attributed,
            disappears,
            ratio,
            pass,
        });
    }
    Ok(out)
}
