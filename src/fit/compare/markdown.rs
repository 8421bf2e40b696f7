//! The comparison's report as Markdown (`compare.md`).

use std::fmt::Write as _;

use super::{Report, Settings};
use crate::fit::objective::{GENERATIONS, POPULATION};
use crate::model::Flow;
use crate::report::number::significant;

/// `v` with `digits` decimals, more where a small figure needs them
/// (an SSE in metres: [`significant`]), or `diverged`.
fn opt(v: Option<f64>, digits: usize) -> String {
    v.map_or("diverged".into(), |v| significant(v, digits))
}

/// The report as Markdown tables, headed by the settings that made it.
pub fn markdown(r: &Report, settings: &Settings) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "# Optimizer comparison on {} [{}]\n", r.data, r.backend);
    // What the SSEs and RMSEs below are in, where the column says.
    if let Some(unit) = &r.columns.output.unit {
        let _ = writeln!(
            s,
            "Output `{}` in {unit}: SSEs in {unit}², RMSEs in {unit}.\n",
            r.columns.output.column
        );
    }
    if !r.table21.is_empty() {
        let _ = writeln!(
            s,
            "## Table 21 redone (G = {}, seed 1, thesis settings on the joint flow: a, b, c, x0 fitted in the data's box, the thesis' own flow is in Flows below; `mfa*`: 10 brightest attractors above N = {})\n",
            settings.gens, settings.mfa_all_pairs_max
        );
        let _ = writeln!(
            s,
            "| N | algorithm | model | total (s) | per generation (s) | SSE (estimation) | validation fit % |\n|---:|---|---|---:|---:|---:|---:|"
        );
        for row in &r.table21 {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {} | {} | {} |",
                row.population,
                row.algo,
                row.model,
                // Three decimals, and the figures a run of under a
                // millisecond needs (three decimals printed it as 0.000).
                significant(row.seconds, 3),
                significant(row.seconds_per_generation, 4),
                opt(row.sse, 3),
                opt(row.val_fit_percent, 2)
            );
        }
    }
    if !r.budget.is_empty() {
        let _ = writeln!(
            s,
            "\n## Equal population budgets (N = {}, G = {}), seeds 1..={}: median [min, max]\n\nThe staged fits add a free-run stage (N/5 for G/4) and a polish to the same global stage: their evaluations (the mean over the seeds) are not the plain searches'. A diverged seed counts as the worst.\n",
            settings.budget_pop, settings.budget_gens, settings.seeds
        );
        let _ = writeln!(
            s,
            "| model | variant | evaluations | diverged | SSE | validation fit % |\n|---|---|---:|---:|---|---|"
        );
        for b in &r.budget {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {} [{}, {}] | {} [{}, {}] |",
                b.model,
                b.variant,
                b.evaluations,
                b.diverged,
                opt(b.sse_median, 3),
                opt(b.sse_min, 3),
                opt(b.sse_max, 3),
                opt(b.fit_median, 2),
                opt(b.fit_min, 2),
                opt(b.fit_max, 2)
            );
        }
    }
    let _ = writeln!(
        s,
        "\n## Flows (staged fit, DE, N = {POPULATION}, G = {GENERATIONS}, seed 1)\n\n| model | flow | SSE | validation fit % | validation RMSE |\n|---|---|---:|---:|---:|"
    );
    for f in &r.flows {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} |",
            f.model,
            match f.flow {
                Flow::Joint => "joint (a, b, c, x0 fitted)",
                Flow::Thesis => "thesis (a, b = ARX, c = 0)",
            },
            opt(f.sse, 3),
            opt(f.val_fit_percent, 2),
            opt(f.val_rmse, 4)
        );
    }
    if !r.cross_load.is_empty() {
        let _ = writeln!(
            s,
            "\n## Cross-load check (§4.10; staged fit, DE, joint flow; fit % on the scored record's second half, the free run from its first sample)\n\n| model | fitted on | scored on | fit % |\n|---|---|---|---:|"
        );
        for c in &r.cross_load {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} |",
                c.model,
                c.fitted_on,
                c.scored_on,
                opt(c.fit_percent, 2)
            );
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::{Report, Settings, markdown, opt};

    #[test]
    fn an_sse_in_metres_keeps_its_digits_in_the_tables() {
        // The stair in metres: SSE 0.002952, where three decimals read 0.003.
        assert_eq!(opt(Some(0.0029515), 3), "0.002952");
        assert_eq!(opt(Some(2948.5012), 3), "2948.501");
        assert_eq!(opt(None, 3), "diverged");
    }

    /// A run of under a millisecond keeps its figures in Table 21 (it read
    /// 0.000 s, and 0.0000 s a generation).
    #[test]
    fn a_fast_run_keeps_its_time_in_table_21() {
        use crate::fit::compare::Row;
        use crate::model::Family;
        let report = Report {
            data: "x.csv".into(),
            columns: crate::data::Columns::of("pressure", "displacement"),
            backend: "cpu".into(),
            table21: vec![Row {
                model: Family::Classic,
                algo: "de".into(),
                population: 10,
                generations: 5,
                evaluations: 50,
                seconds: 0.00042,
                seconds_per_generation: 0.000084,
                sse: Some(1.0),
                val_fit_percent: Some(90.0),
            }],
            budget: Vec::new(),
            flows: Vec::new(),
            cross_load: Vec::new(),
        };
        let settings = Settings {
            thesis_sizes: vec![10],
            sizes: Vec::new(),
            gens: 5,
            seeds: 0,
            budget_pop: 10,
            budget_gens: 1,
            mfa_all_pairs_max: 10,
        };
        let table = markdown(&report, &settings);
        assert!(table.contains("| 0.0004200 | 0.00008400 |"), "{table}");
        // The figures' unit, from the output column's name.
        assert!(
            table.contains("Output `displacement` in mm: SSEs in mm², RMSEs in mm."),
            "{table}"
        );
    }
}
