//! `fit --effects auto` ([`selected_fit`]): the diagnosis' own selection,
//! its final model reported as a fit's, with what weakens its verdict.

use super::Effect;
use super::report::verdict_cautions;
use super::settings::Settings;
use crate::data::Trace;
use crate::eval::Backend;
use crate::fit::objective::TryGroup;
use crate::fit::problem::Overshoot;
use crate::fit::records::Records;
use crate::fit::report::{DiagnosisParts, FitReport, Note, RecordScore};
use crate::ident::{fit_percent, rmse};
use crate::model::experiment::halves;
use crate::model::file::SearchBox;
use crate::model::{Family, Flow, Model};
use crate::optim::Algorithm;
use crate::optim::engine::StopReason;
use crate::report::json::Named;

/// `fit --effects auto`: the diagnosis' forward selection over its whole
/// catalogue on `trace` (the diagnosis' settings with `seed` and
/// `backend`), its final model reported as a fit's: scored on the second
/// half from one free run over the whole record, against the first-order
/// ARX model on the same halves.
pub fn selected_fit(
    trace: &Trace,
    family: Family,
    seed: u64,
    backend: Backend,
) -> anyhow::Result<(Model, FitReport)> {
    let settings = Settings {
        seed,
        backend,
        ..Settings::default()
    };
    let started = std::time::Instant::now();
    let d = super::diagnose(
        std::slice::from_ref(trace),
        family,
        &Effect::by_default(),
        &settings,
    )?;
    let model = d.final_model.clone();
    let run = model.simulate_absolute(&trace.input, trace.output[0]);
    let from = halves(trace.len()).1.start;
    let (y, yhat) = (&trace.output[from..], &run.output[from..]);
    let finite = |v: f64| v.is_finite().then_some(v);
    let (val_rmse, val_fit_percent) = (finite(rmse(y, yhat)), finite(fit_percent(y, yhat)));
    let linear = Records::of(std::slice::from_ref(trace), None)?.linear_yardstick();
    let linear_val_fit_percent = linear.as_ref().and_then(|l| finite(l.0.pooled.fit_percent));
    let linear_largest_pole = linear.as_ref().and_then(|l| l.1.first().copied());
    let report = FitReport {
        model: family,
        effects: model
            .effects()
            .iter()
            .map(|e| e.name().to_string())
            .collect(),
        algo: Algorithm::De,
        params: model.named_params().into_iter().collect(),
        std_errors: model
            .named_params()
            .into_iter()
            .map(|(name, _)| (name, None))
            .collect(),
        undetermined: Vec::new(),
        diverging_probes: Vec::new(),
        held_at_bounds: Vec::new(),
        units: Named(model.units()),
        sse: finite(d.selection.final_fit.est_sse),
        val_rmse,
        val_fit_percent,
        linear_val_fit_percent,
        linear_largest_pole,
        diagnosis_parts: Some(DiagnosisParts {
            selection_fit_percent: finite(d.last().selection_fit_percent),
            test_rmse: finite(d.last().test_rmse),
            test_fit_percent: finite(d.last().test_fit_percent),
        }),
        // The effect stages move the output off the state the update steps on.
        stable_step: None,
        largest_step: None,
        simulated_largest_step: None,
        start_sse: None,
        start_val_fit_percent: None,
        built: None,
        switching: None,
        evaluations: 0,
        generations: 0,
        seconds: started.elapsed().as_secs_f64(),
        backend: format!("{backend:?} (the diagnosis' searches)").to_lowercase(),
        flow: Flow::Joint,
        // The diagnosis admits every bounded loop.
        overshoot: Overshoot::Allow,
        seed,
        population: settings.population,
        tries: 1,
        try_population: settings.population,
        try_sizes: vec![TryGroup {
            population: settings.population,
            tries: 1,
        }],
        agreement: None,
        refining: None,
        stop: StopReason::Completed,
        stages: Vec::new(),
        on_edge: Vec::new(),
        widened: Vec::new(),
        search_box: SearchBox {
            names: Vec::new(),
            lower: Vec::new(),
            upper: Vec::new(),
            origin: Vec::new(),
        },
        data: trace.source.clone(),
        columns: Some(trace.columns()),
        records: vec![RecordScore {
            data: trace.source.clone(),
            samples: trace.len(),
            val_rmse,
            val_fit_percent,
            linear_val_fit_percent,
            linear_largest_pole,
        }],
        // What weakens the verdict weakens the model built on it; `fit`
        // prints these where `diagnose` would have.
        notes: verdict_cautions(&d)
            .into_iter()
            .map(|caution| Note {
                level: "warning",
                text: format!(
                    "the diagnosis' verdict may not hold: {caution} (`mckibben diagnose` gives \
                     its report)"
                ),
            })
            .collect(),
        out: None,
    };
    Ok((model, report))
}
