//! Host and device at once: where an objective's calls pay a round trip,
//! the engine scores a generation in parts and asks and tells one part's
//! islands while the next is scored. The fit must be the same, bit for bit,
//! as when every generation is scored in one go.

use mckibben::model::Measure;
use mckibben::optim::Algorithm;
use mckibben::optim::engine::{
    Engine, FreeRun, Global, Objective, Outcome, Plan, Space, StopRules, Ticket, TrySize,
};
use mckibben::search::{Params, Rows};

const DIM: usize = 3;

/// A cost that differs by measure, as a model's prediction errors do.
fn cost(row: &[f64], measure: Measure) -> f32 {
    let weight = match measure {
        Measure::FreeRun => 1.0,
        Measure::Ahead { horizon } => 1.0 / horizon as f64,
    };
    let shifted: f64 = row.iter().map(|x| (x - 0.5).powi(2)).sum();
    (weight * shifted + 0.01 * row[0].sin()) as f32
}

/// What the overlapped objective was asked, in order.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Call {
    Submit(usize),
    Collect(usize),
}

/// An objective that scores when its costs are collected, not when they
/// are submitted, as a device does; with `round_trips` false the engine
/// scores each generation in one go.
struct Deferred {
    round_trips: bool,
    calls: Vec<Call>,
}

impl Objective for Deferred {
    fn describe(&self) -> String {
        "deferred test objective".into()
    }

    fn round_trips(&self) -> bool {
        self.round_trips
    }

    fn costs(&mut self, rows: Rows<'_, Params>, measure: Measure) -> anyhow::Result<Vec<f32>> {
        Ok(rows.iter().map(|r| cost(r, measure)).collect())
    }

    fn submit(&mut self, rows: Rows<'_, Params>, measure: Measure) -> anyhow::Result<Ticket> {
        self.calls.push(Call::Submit(rows.len()));
        Ok(Ticket::new((rows.to_population(), measure)))
    }

    fn collect(
        &mut self,
        ticket: Ticket,
        rows: Rows<'_, Params>,
        measure: Measure,
    ) -> anyhow::Result<Vec<f32>> {
        let (submitted, submitted_measure): (mckibben::search::Population<Params>, Measure) =
            ticket.take()?;
        assert_eq!(
            submitted.rows().as_flat(),
            rows.as_flat(),
            "the rows submitted"
        );
        assert_eq!(submitted_measure, measure);
        self.calls.push(Call::Collect(rows.len()));
        self.costs(rows, measure)
    }
}

/// Three tries of four islands, the second smaller, then a free-run stage;
/// with `ladder` the islands measure a ladder of horizons (the last one the
/// free run), so that a generation's islands go in calls of several
/// measures.
fn plan(ladder: bool) -> Plan {
    Plan {
        global: Some(Global {
            settings: Algorithm::De.default_settings(),
            population: 48,
            generations: 12,
            measure: Measure::Ahead { horizon: 2 },
            islands: 4,
            ladder,
            longest: 1000,
        }),
        free_run: Some(FreeRun {
            population: 24,
            generations: 6,
        }),
        polish: None,
        refine: None,
        // Tries of two sizes: their islands differ in size within a part.
        tries: 3,
        sizes: [48, 16, 48]
            .map(|global| TrySize {
                global,
                free_run: (global / 2).max(16),
                refine: 0,
                polish: 0,
            })
            .to_vec(),
    }
}

fn run(ladder: bool, round_trips: bool) -> (Outcome, Vec<Call>, String) {
    let space = Space::new(
        vec![-2.0; DIM],
        vec![2.0; DIM],
        (0..DIM).map(|i| format!("x{i}")).collect(),
    );
    let mut engine = Engine::new(plan(ladder), space, 7, StopRules::default()).unwrap();
    let mut objective = Deferred {
        round_trips,
        calls: Vec::new(),
    };
    let outcome = engine.run(&mut objective, &mut [], None, None).unwrap();
    let history = serde_json::to_string(&engine.history.records).unwrap();
    (outcome, objective.calls, history)
}

/// The most calls submitted and not yet collected at any time.
fn most_in_flight(calls: &[Call]) -> i64 {
    calls
        .iter()
        .scan(0i64, |n, c| {
            *n += if matches!(c, Call::Submit(_)) { 1 } else { -1 };
            Some(*n)
        })
        .max()
        .unwrap_or(0)
}

/// The same fit, and the same record of every generation but its time.
fn assert_same_fit(a: &(Outcome, Vec<Call>, String), b: &(Outcome, Vec<Call>, String)) {
    assert_eq!(a.0.params, b.0.params);
    assert_eq!(a.0.sse.to_bits(), b.0.sse.to_bits());
    assert_eq!(a.0.evaluations, b.0.evaluations);
    let tries = |o: &Outcome| o.tries.iter().map(|t| t.sse.to_bits()).collect::<Vec<_>>();
    assert_eq!(tries(&a.0), tries(&b.0));
    let records = |h: &str| {
        let mut v: serde_json::Value = serde_json::from_str(h).unwrap();
        for r in v.as_array_mut().unwrap() {
            r.as_object_mut().unwrap().remove("seconds");
        }
        v
    };
    assert_eq!(records(&a.2), records(&b.2));
}

#[test]
fn overlapped_parts_give_the_fit_of_one_part() {
    let whole = run(false, false);
    let overlapped = run(false, true);
    assert_same_fit(&overlapped, &whole);
    // In one go a generation is one call, waited for before the next; in
    // parts the next part is submitted before the one before is collected.
    assert_eq!(most_in_flight(&whole.1), 1, "{:?}", &whole.1[..8]);
    assert_eq!(most_in_flight(&overlapped.1), 2, "{:?}", &overlapped.1[..8]);
    let submitted = |calls: &[Call]| -> usize {
        calls
            .iter()
            .map(|c| match c {
                Call::Submit(n) => *n,
                Call::Collect(_) => 0,
            })
            .sum()
    };
    assert_eq!(submitted(&overlapped.1), submitted(&whole.1));
}

#[test]
fn overlapped_parts_of_several_measures_give_the_fit_of_one_part() {
    assert_same_fit(&run(true, true), &run(true, false));
}
