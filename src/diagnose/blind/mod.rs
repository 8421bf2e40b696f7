//! The independent self-test (issue 17, point 3): cases made by a generator
//! with its own equations ([`generator`]), which never calls into the
//! catalogue, so the diagnosis cannot pass it by matching its own equations.
//!
//! Every physical effect in two or three realisations, on two excitations
//! (the data's own input and a multisine with rate content), at two sizes
//! calibrated to the mark they leave on the nominal output (6 σ and 15 σ,
//! σ the noise); a control on each excitation; two pairs; and a sensor's
//! cross-talk, which no catalogued effect realises. Each case is
//! diagnosed blind and judged:
//!
//! - a single effect: the first effect named is one the physical effect
//!   counts as ([`accepted`]), at least 80 % of the gap is closed, and the
//!   size is within 20 % wherever it is identifiable: the catalogue has a
//!   parameter that means the realisation's size ([`found_size`]) and the
//!   diagnosis' 95 % profile interval of it is within ±20 %; otherwise the
//!   size is reported and the reason it is not judged;
//! - the control: nothing named;
//! - a pair: both physical effects named;
//! - an effect outside the catalogue (a sensor's cross-talk): the verdict
//!   "not explained by the catalogue", hence no name.

pub mod generator;
pub mod mechanism;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

use self::generator::{Excitation, Plant};
use self::mechanism::{Mechanism, Physical};
use super::selftest::{MARKS, Nominal, SizeCheck, unpinned};
use super::{Diagnosis, Effect, Settings, diagnose};
use crate::model::Family;

/// The catalogue names that count as naming a physical effect.
///
/// - lag: `delay` or `inertia`. A first-order lag is between the two: at
///   low frequencies it is a delay of its mean delay, and it is an extra
///   real pole, which is what `inertia` adds; a pure delay named `inertia`
///   is the same approximation the other way round.
/// - inertia: `inertia` only. A delay has no overshoot and no ringing, so
///   naming it for a load mode would be a wrong physical reading.
/// - every other effect: its catalogue namesake (end stop: `saturation`,
///   threshold: `deadzone`). A hysteretic threshold is not accepted as
///   `backlash`: play moves the whole input, a threshold only its bottom.
///
/// The names are physical effects ([`Effect::PHYSICAL`]): any realisation
/// of an accepted physical effect counts ([`Effect::physical`]).
pub fn accepted(p: Physical) -> &'static [Effect] {
    match p {
        Physical::Lag => &[Effect::Delay, Effect::Inertia],
        Physical::Inertia => &[Effect::Inertia],
        Physical::Asymmetry => &[Effect::Asymmetry],
        Physical::EndStop => &[Effect::Saturation],
        Physical::Creep => &[Effect::Creep],
        Physical::Threshold => &[Effect::Deadzone],
        Physical::Rate => &[Effect::Rate],
        Physical::Backlash => &[Effect::Backlash],
        Physical::Load => &[Effect::Load],
        Physical::Softening => &[Effect::Softening],
        Physical::Set => &[Effect::Set],
        Physical::Outside => &[],
    }
}

/// Why a realisation's size has no counterpart in the catalogue, or `None`
/// where [`found_size`] maps the catalogue's parameter onto it.
pub fn not_comparable(r: Mechanism) -> Option<&'static str> {
    use Mechanism::*;
    match r {
        LoadMode => Some("a lightly damped mode has two parameters (period, damping)"),
        SoftLimit => Some("a smooth knee has no hard stop level"),
        HystereticThreshold => Some("an on/off pair is no single dead-zone width"),
        MullinsSoftening | CyclicSoftening => {
            Some("a saturating growth has no single counterpart in the catalogue's gain")
        }
        _ => None,
    }
}

/// Where a case sits, for reading the catalogue's absolute levels as sizes:
/// the nominal output's peak on the case's excitation (absolute), on the
/// side the input drives it to, whether that side is up, the excitation's
/// lowest input, and the nominal output's range on it.
#[derive(Debug, Clone, Copy)]
pub struct Frame {
    pub peak: f64,
    pub up: bool,
    pub p_lo: f64,
    pub range: f64,
}

/// The realisation's size implied by the catalogue's fitted parameters of
/// effect `e` (`params` from the effect's offset on), `None` where they do
/// not mean the same thing.
///
/// A lag's size is its mean delay in samples: `delay`'s `d` is one, and an
/// extra pole `a2` delays by `a2/(1 − a2)` (a moment match, not an identity).
/// The catalogue's dead zone `max(p − p0, 0)` is this one's
/// `p_lo + max(p − p_lo − s, 0)` with `p0 = p_lo + s` (the offset `p_lo`
/// goes into the intercept), so its size is `p0 − p_lo`. A first-order lag
/// of pole `ρ` delays by `ρ/(1 − ρ)` samples, as a time constant does in
/// samples; the drain lag's size is that of its slow branch. The
/// catalogue's set keeps a share of the way back toward the drive, the
/// generator's a share `s/range` away from it: its size is `−share·range`.
/// The generator's ratchet is sized by its walk after four loadings, away
/// from the drive: the catalogue's offset after four, its sign turned.
pub fn found_size(r: Mechanism, e: Effect, params: &[f64], at: Frame) -> Option<f64> {
    use Mechanism::*;
    if not_comparable(r).is_some() {
        return None;
    }
    match (r, e) {
        (PureDelay | InputLag | OutputLag, Effect::Delay) => Some(params[0]),
        (
            PureDelay | InputLag | OutputLag,
            Effect::Inertia | Effect::InputLag | Effect::OutputLag,
        ) => Some(params[0] / (1.0 - params[0])),
        (DrainLag, Effect::DrainLag) => Some(params[0] / (1.0 - params[0])),
        (ExtraPole, Effect::Inertia) => Some(params[0]),
        (GainAsymmetry, Effect::Asymmetry) => Some(params[0]),
        (StateClip | OutputClip, Effect::Saturation | Effect::OutputClip) => Some(if at.up {
            at.peak - params[0]
        } else {
            params[0] - at.peak
        }),
        (CreepInput | CreepTwo, Effect::Creep) => Some(params[1]),
        (CreepInput | CreepTwo, Effect::TwoPoleCreep) => Some(params[2]),
        // Three terms of gain κ each.
        (CreepInput | CreepTwo, Effect::LogCreep) => Some(3.0 * params[1]),
        (CreepOutput, Effect::OutputCreep) => Some(params[1]),
        (DeadZone, Effect::Deadzone) => Some(params[0] - at.p_lo),
        (ViscousRate, Effect::Rate) => Some(params[0]),
        (Play, Effect::Backlash) => Some(params[0]),
        (LoadGain, Effect::Load) => Some(params[0]),
        (PermanentSet, Effect::Set) => Some(-params[0] * at.range),
        (Ratchet, Effect::Ratchet) => {
            let walk = ratchet_walk(params[0], params[1], 4);
            Some(if at.up { -walk } else { walk })
        }
        _ => None,
    }
}

/// The catalogue ratchet's offset after `loadings` loadings: a first step
/// `a`, then each the one before times `1 − q/n`.
fn ratchet_walk(a: f64, q: f64, loadings: u32) -> f64 {
    let (mut step, mut walk) = (a, 0.0);
    for n in 1..=loadings {
        if n > 1 {
            step *= 1.0 - q / n as f64;
        }
        walk += step;
    }
    walk
}

/// The nominal model as the generator's plant, the two excitations and
/// their noise levels.
#[derive(Debug, Clone)]
pub struct Setup {
    pub plant: Plant,
    pub excitations: Vec<Excitation>,
    /// Noise σ on each excitation (0.5 % of its nominal output range).
    pub sigmas: Vec<f64>,
    /// The nominal output's peak on each excitation (absolute), on the side
    /// the input drives it to, and its range there.
    pub peaks: Vec<f64>,
    pub ranges: Vec<f64>,
}

impl Setup {
    /// The plant from the nominal model fitted to the data, the data's
    /// input and a multisine over the data's input range and length (its
    /// phases drawn from `seed`).
    pub fn new(nominal: &Nominal, seed: u64) -> anyhow::Result<Setup> {
        anyhow::ensure!(
            nominal.family == Family::Classic,
            "the independent self-test's generator implements the classic model only \
             (--baseline classic); `--self-test=catalogue` checks the generalized one"
        );
        let w = &nominal.data.records.whole[0];
        let trace = &nominal.trace;
        let plant = Plant::classic(&nominal.params, w.u_mean, w.y_mean, trace.dt());
        let (lo, hi) = generator::extremes(&trace.input);
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let (len, dt) = (trace.len(), trace.dt());
        let excitations = vec![
            Excitation::stair(trace, &plant),
            Excitation::multisine(len, dt, (lo, hi), &plant, &mut rng),
            Excitation::pulses(
                "rising pulses",
                &[0.6, 0.8, 1.0, 1.0],
                len,
                dt,
                (lo, hi),
                &plant,
            ),
            Excitation::pulses("equal pulses", &[1.0; 4], len, dt, (lo, hi), &plant),
        ];
        let sigmas = excitations
            .iter()
            .map(|e| generator::noise_sigma(&plant, e))
            .collect();
        let (peaks, ranges) = excitations
            .iter()
            .map(|e| {
                let (lo, hi) = generator::extremes(&generator::simulate(&plant, e, &[], 0));
                (if plant.drives_up() { hi } else { lo }, hi - lo)
            })
            .unzip();
        Ok(Setup {
            plant,
            excitations,
            sigmas,
            peaks,
            ranges,
        })
    }
}

/// The excitations' places in [`Setup::excitations`]: the data's own
/// input, the multisine, and the two pulse trains the softening and the set
/// are tried on (pulses of 0.6, 0.8, 1 and 1 of the input's range, which
/// tell the largest input so far from the number of loadings, and four
/// equal pulses, which tell the number of loadings from a creep).
const MULTISINE: usize = 1;
const RISING: usize = 2;
const EQUAL: usize = 3;

/// One case of the independent self-test.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BlindCase {
    pub name: String,
    /// Index into [`Setup::excitations`].
    pub excitation: usize,
    /// `small` or `large` (empty for the control).
    pub size_label: String,
    pub effects: Vec<(Mechanism, f64)>,
    /// Seed of the case's noise.
    pub seed: u64,
}

/// Every case: on the stair and the multisine the control and every
/// catalogued realisation at the two sizes of [`MARKS`]; then two pairs on
/// the data's input, each effect at its small size; then the cross-talk
/// outside the catalogue on both at both sizes; then the softening and the
/// set on the pulse trains (rising pulses for the largest-input drivers,
/// equal ones for the loading-count drivers), each train with its control,
/// and a creep alone on equal pulses, which must not be named a softening
/// or a set. Case `i`'s noise is drawn from `seed + 1 + i`, so a case keeps
/// its data when others are filtered out.
pub fn cases(setup: &Setup, seed: u64) -> Vec<BlindCase> {
    let mut out = Vec::new();
    let mut push = |name: String, excitation: usize, size_label: &str, effects| {
        let seed = seed + 1 + out.len() as u64;
        out.push(BlindCase {
            name,
            excitation,
            size_label: size_label.into(),
            effects,
            seed,
        });
    };
    let size = |r: Mechanism, i: usize, k: f64| {
        generator::calibrate(&setup.plant, &setup.excitations[i], r, k * setup.sigmas[i])
    };
    for (i, exc) in setup.excitations[..=MULTISINE].iter().enumerate() {
        push(format!("control ({})", exc.name), i, "", Vec::new());
        for r in Mechanism::ALL
            .into_iter()
            .filter(|r| r.physical() != Physical::Outside && !r.on_pulses())
        {
            for (k, label) in MARKS {
                push(
                    format!("{} ({label} on {})", r.label(), exc.name),
                    i,
                    label,
                    vec![(r, size(r, i, k))],
                );
            }
        }
    }
    let small = MARKS[0].0;
    for (a, b) in PAIRS {
        push(
            format!("{} + {} (small on stair)", a.label(), b.label()),
            0,
            "small",
            vec![(a, size(a, 0, small)), (b, size(b, 0, small))],
        );
    }
    // Last, so that the other cases' seeds do not depend on it.
    let r = Mechanism::CrossTalk;
    for (i, exc) in setup.excitations[..=MULTISINE].iter().enumerate() {
        for (k, label) in MARKS {
            push(
                format!("{} ({label} on {})", r.label(), exc.name),
                i,
                label,
                vec![(r, size(r, i, k))],
            );
        }
    }
    for (i, drivers) in [
        (
            RISING,
            [Mechanism::MullinsSoftening, Mechanism::PermanentSet],
        ),
        (EQUAL, [Mechanism::CyclicSoftening, Mechanism::Ratchet]),
    ] {
        let exc = &setup.excitations[i];
        push(format!("control ({})", exc.name), i, "", Vec::new());
        for r in drivers {
            for (k, label) in MARKS {
                push(
                    format!("{} ({label} on {})", r.label(), exc.name),
                    i,
                    label,
                    vec![(r, size(r, i, k))],
                );
            }
        }
    }
    let r = Mechanism::CreepInput;
    push(
        format!("{} (small on {})", r.label(), setup.excitations[EQUAL].name),
        EQUAL,
        "small",
        vec![(r, size(r, EQUAL, small))],
    );
    out
}

/// The realisation a case must name first where the physical effect is
/// not enough: the softening's driver, which the pulse trains tell apart.
fn driver(r: Mechanism) -> Option<Effect> {
    match r {
        Mechanism::MullinsSoftening => Some(Effect::Softening),
        Mechanism::CyclicSoftening => Some(Effect::CyclicSoftening),
        _ => None,
    }
}

/// On the pulse trains, every softening or set named that the case does
/// not have: what repeated loading tempts the diagnosis to name.
fn named_beyond_the_case(case: &BlindCase, named: &[Effect]) -> Vec<Effect> {
    if case.excitation < RISING {
        return Vec::new();
    }
    let own: Vec<Physical> = case.effects.iter().map(|(r, _)| r.physical()).collect();
    named
        .iter()
        .copied()
        .filter(|e| {
            [Physical::Softening, Physical::Set]
                .into_iter()
                .any(|p| accepted(p).contains(&e.physical()) && !own.contains(&p))
        })
        .collect()
}

/// The two pairs: realisations unlike the catalogue's equations, one on the
/// input side and one on the output side each.
pub const PAIRS: [(Mechanism, Mechanism); 2] = [
    (Mechanism::InputLag, Mechanism::OutputClip),
    (Mechanism::DeadZone, Mechanism::CreepTwo),
];

/// The outcome of one case.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BlindOutcome {
    pub case: String,
    /// `physical: realisation` of each effect in the case.
    pub truth: Vec<String>,
    pub excitation: String,
    pub size_label: String,
    pub named: Vec<Effect>,
    pub size_true: Option<f64>,
    pub size_found: Option<f64>,
    pub size_error: Option<f64>,
    /// The 95 % profile interval of the size found, in the same units.
    pub size_interval: Option<(f64, f64)>,
    pub size_check: SizeCheck,
    /// The baseline's and the final model's RMSE on the test part, and the
    /// share of the baseline's gap above the floor closed there.
    pub baseline_rmse: f64,
    pub final_rmse: f64,
    pub noise_floor: f64,
    pub gap_closed: f64,
    /// The explainable bound's share of the gap, and whether the diagnosis
    /// said "not explained by the catalogue".
    pub gap_closable: f64,
    pub not_explained: bool,
    pub pass: bool,
    pub note: String,
}

/// Generates a case's traces (noise from the case's own seed).
pub fn synthesize(setup: &Setup, case: &BlindCase) -> Vec<crate::data::Trace> {
    let mut rng = ChaCha8Rng::seed_from_u64(case.seed);
    generator::traces(
        &setup.plant,
        &setup.excitations[case.excitation],
        &case.effects,
        setup.sigmas[case.excitation],
        &case.name,
        &mut rng,
    )
}

/// Generates, diagnoses blind and judges one case.
pub fn run_case(
    setup: &Setup,
    case: &BlindCase,
    effects: &[Effect],
    settings: &Settings,
) -> anyhow::Result<BlindOutcome> {
    let traces = synthesize(setup, case);
    let d = diagnose(&traces, Family::Classic, effects, settings)?;
    Ok(judge(setup, case, &d))
}

/// Judges a diagnosis of a case by the rules of the module's documentation.
pub fn judge(setup: &Setup, case: &BlindCase, d: &Diagnosis) -> BlindOutcome {
    let named = d.named().to_vec();
    // Scored on the test part, which none of the diagnosis' choices read.
    let gap = d.last().test_gap_closed;
    let mut notes = Vec::new();
    let (mut size_true, mut size_found, mut size_error, mut size_interval) =
        (None, None, None, None);
    let mut size_check = SizeCheck::NotApplicable;
    match case.effects.as_slice() {
        [] => {
            if !named.is_empty() {
                notes.push("control: named an effect".to_string());
            }
        }
        [(r, _)] if r.physical() == Physical::Outside => {
            if !d.explainable.not_explained {
                notes.push(format!(
                    "wanted \"not explained by the catalogue\", named {}",
                    names_or_nothing(&named)
                ));
            }
        }
        [(r, s)] => {
            size_true = Some(*s);
            let ok = accepted(r.physical());
            match named.first() {
                Some(e) if driver(*r).is_some_and(|want| want != *e) => {
                    size_check = SizeCheck::NotNamed;
                    notes.push(format!(
                        "named {e} first, wanted the driver {}",
                        driver(*r).map_or("", |d| d.name())
                    ));
                }
                Some(e) if ok.contains(&e.physical()) => {
                    (size_check, size_found, size_interval) = size_of(setup, case, d, (*r, *e), *s);
                    if let Some(f) = size_found {
                        size_error = Some((f - s).abs() / s.abs());
                    }
                    if size_check == SizeCheck::Judged && size_error.is_some_and(|e| e > 0.2) {
                        notes.push(format!(
                            "size off by {:.0} %",
                            100.0 * size_error.unwrap_or(0.0)
                        ));
                    }
                }
                first => {
                    size_check = SizeCheck::NotNamed;
                    notes.push(format!(
                        "named {} first, wanted {}",
                        first.map_or("nothing", |e| e.name()),
                        ok.iter().map(|e| e.name()).collect::<Vec<_>>().join(" or ")
                    ));
                }
            }
            if gap < 0.8 {
                notes.push(format!("closed only {:.0} % of the gap", 100.0 * gap));
            }
        }
        pair => {
            for (r, _) in pair {
                let physical = accepted(r.physical());
                if !named.iter().any(|e| physical.contains(&e.physical())) {
                    notes.push(format!("{} not named", r.physical().name()));
                }
            }
        }
    }
    let beyond = named_beyond_the_case(case, &named);
    if !beyond.is_empty() && !case.effects.is_empty() {
        notes.push(format!(
            "named {}, which the case does not have",
            names_or_nothing(&beyond)
        ));
    }
    BlindOutcome {
        case: case.name.clone(),
        truth: case.effects.iter().map(|(r, _)| r.label()).collect(),
        excitation: setup.excitations[case.excitation].name.clone(),
        size_label: case.size_label.clone(),
        named,
        size_true,
        size_found,
        size_error,
        size_interval,
        size_check,
        baseline_rmse: d.baseline().test_rmse,
        final_rmse: d.last().test_rmse,
        noise_floor: d.noise_floor_rmse,
        gap_closed: gap,
        gap_closable: d.explainable.bound.gap_closable,
        not_explained: d.explainable.not_explained,
        pass: notes.is_empty(),
        note: notes.join("; "),
    }
}

fn names_or_nothing(named: &[Effect]) -> String {
    if named.is_empty() {
        "nothing".into()
    } else {
        named
            .iter()
            .map(|e| e.name())
            .collect::<Vec<_>>()
            .join(", ")
    }
}

/// The size the diagnosis found for realisation `r` named as `e`, its
/// interval, and whether it can be judged.
fn size_of(
    setup: &Setup,
    case: &BlindCase,
    d: &Diagnosis,
    (r, e): (Mechanism, Effect),
    truth: f64,
) -> (SizeCheck, Option<f64>, Option<(f64, f64)>) {
    let (mut found, mut interval) = (None, None);
    let check = size_check(setup, case, d, (r, e), truth, &mut found, &mut interval);
    (check, found, interval)
}

fn size_check(
    setup: &Setup,
    case: &BlindCase,
    d: &Diagnosis,
    (r, e): (Mechanism, Effect),
    truth: f64,
    found: &mut Option<f64>,
    interval: &mut Option<(f64, f64)>,
) -> SizeCheck {
    if let Some(why) = not_comparable(r) {
        return SizeCheck::NotComparable(why.into());
    }
    let sel = &d.selection;
    let Some(offset) = sel.final_model.offset_of(e) else {
        return SizeCheck::NotNamed;
    };
    let exc = &setup.excitations[case.excitation];
    let frame = Frame {
        peak: setup.peaks[case.excitation],
        up: setup.plant.drives_up(),
        p_lo: exc.input.iter().copied().fold(f64::INFINITY, f64::min),
        range: setup.ranges[case.excitation],
    };
    let params = &sel.final_fit.params[offset..];
    let Some(f) = found_size(r, e, params, frame) else {
        return SizeCheck::NotComparable(format!("{e}'s parameter does not mean {}", r.name()));
    };
    *found = Some(f);
    let Some(iv) = d.size_intervals.iter().find(|s| s.effect == e) else {
        return SizeCheck::NotIdentifiable("no profile interval".into());
    };
    let ends = iv.mapped(params, |p| found_size(r, e, p, frame).unwrap_or(f64::NAN));
    *interval = Some(ends);
    match unpinned(ends, f, iv.at_edge()) {
        Some(why) => SizeCheck::NotIdentifiable(format!("{why} (truth {truth:.4})")),
        None => SizeCheck::Judged,
    }
}

/// Rows (`physical: realisation`, `control`) × columns (the first effect
/// named, or `none`) of the single-effect cases and the controls, summed
/// over excitations and sizes.
pub fn confusion(outcomes: &[BlindOutcome]) -> Vec<(String, Vec<usize>)> {
    let mut rows: Vec<(String, Vec<usize>)> = Vec::new();
    let cols = Effect::PHYSICAL.len() + 1;
    for o in outcomes.iter().filter(|o| o.truth.len() <= 1) {
        let label = o.truth.first().cloned().unwrap_or_else(|| "control".into());
        let ci = o
            .named
            .first()
            .and_then(|e| Effect::PHYSICAL.iter().position(|&x| x == e.physical()))
            .unwrap_or(cols - 1);
        match rows.iter_mut().find(|(l, _)| *l == label) {
            Some((_, v)) => v[ci] += 1,
            None => {
                let mut v = vec![0; cols];
                v[ci] += 1;
                rows.push((label, v));
            }
        }
    }
    rows
}

/// The confusion table and one line per case, as text.
pub fn table(outcomes: &[BlindOutcome]) -> String {
    use std::fmt::Write as _;
    let mut o = String::new();
    let _ = write!(o, "{:<32}", "true \\ named first");
    for e in Effect::PHYSICAL {
        let _ = write!(o, " {:>5}", &e.name()[..e.name().len().min(5)]);
    }
    let _ = writeln!(o, "  none");
    for (label, counts) in confusion(outcomes) {
        let _ = write!(o, "{label:<32}");
        for n in counts {
            let _ = write!(o, " {n:>5}");
        }
        let _ = writeln!(o);
    }
    let _ = writeln!(o);
    let _ = writeln!(
        o,
        "{:<58} {:<24} {:>9} {:>9} {:>6} {:>6} {:>6}  result",
        "case", "named", "size true", "found", "error", "gap", "×floor"
    );
    for r in outcomes {
        let named: Vec<_> = r.named.iter().map(|e| e.name()).collect();
        let f = |v: Option<f64>| v.map_or("—".to_string(), |x| format!("{x:.4}"));
        let size_note = match &r.size_check {
            SizeCheck::NotComparable(why) => format!(" [size not comparable: {why}]"),
            SizeCheck::NotIdentifiable(why) => format!(" [size not identifiable: {why}]"),
            _ => String::new(),
        };
        let _ = writeln!(
            o,
            "{:<58} {:<24} {:>9} {:>9} {:>6} {:>5.0}% {:>6.2}  {}{}",
            r.case,
            if named.is_empty() {
                "none".to_string()
            } else {
                named.join("+")
            },
            f(r.size_true),
            f(r.size_found),
            r.size_error
                .map_or("—".to_string(), |e| format!("{:.0}%", 100.0 * e)),
            100.0 * r.gap_closed,
            r.baseline_rmse / r.noise_floor,
            if r.pass {
                "pass".to_string()
            } else {
                format!("FAIL: {}", r.note)
            },
            size_note
        );
    }
    o
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The catalogue's ratchet sized as the generator sizes its own: the
    /// walk after four loadings, away from the drive.
    #[test]
    fn a_ratchet_is_sized_by_its_walk_after_four_loadings() {
        let at = |up| Frame {
            peak: 0.0,
            up,
            p_lo: 0.0,
            range: 1.0,
        };
        let size =
            |a, q, up| found_size(Mechanism::Ratchet, Effect::Ratchet, &[a, q], at(up)).unwrap();
        // A steady walk: four equal steps.
        assert!((size(-0.5, 0.0, true) - 2.0).abs() < 1e-12);
        // As the log of the count: 1 + 1/2 + 1/3 + 1/4 of the first step.
        assert!((size(-1.0, 1.0, true) - 25.0 / 12.0).abs() < 1e-12);
        // A muscle driven down walks up, away from its drive.
        assert!((size(1.0, 1.0, false) - 25.0 / 12.0).abs() < 1e-12);
        // At q = 2 the first step is all.
        assert!((size(-1.0, 2.0, true) - 1.0).abs() < 1e-12);
    }
}
