//! `mckibben identify`: the thesis' linear identification (§4.3).

use std::path::PathBuf;

use anyhow::Context;

use super::common::{MultiDataArgs, check_distinct, default_data, records};
use mckibben::data::write_atomic;
use mckibben::ident::ArxOrders;
use mckibben::ident::arx::{Identification, IdentifyJson, identify, identify_jointly};
use mckibben::model::{Model, ModelFile};
use mckibben::report::json::Versioned;
use mckibben::report::number::significant;

/// Identify a linear ARX model from a recorded experiment, as the thesis does
/// with MATLAB's System Identification Toolbox (§4.3): the means of the
/// estimation half are removed, the model is estimated on the first half by
/// least squares and validated on the second half by free-run simulation.
/// The fit is MATLAB `compare`'s: 100·(1 − ‖y − ŷ‖ / ‖y − mean(y)‖).
///
/// With the default orders (na = nb = nk = 1) this is eq. 12,
/// `l(k) = a·l(k−1) + b·p(k−1)`; the thesis found a = 0.9618, b = 24.9366.
///
/// Several files (experiments on one muscle) give one model for all, as
/// MATLAB's `arx(merge(z1, z2), ...)`: each file is split in halves, the
/// means of all estimation halves are removed, the least squares run over
/// every estimation half (no regressor reaches from one file into the
/// next), and the report gives the pooled fit and each file's own.
///
/// Examples:
///   mckibben identify                       # the shipped 4.5 kg stair experiment
///   mckibben identify run.csv --input p_bar --output x_mm --na 2 --nb 2
///   mckibben identify stair.csv sine.csv    # one model for both
///   mckibben identify --out model.json --json
#[derive(Debug, clap::Args)]
#[command(verbatim_doc_comment)]
pub struct Args {
    #[command(flatten)]
    data: MultiDataArgs,
    /// Number of poles (past outputs).
    #[arg(long, default_value_t = 1)]
    na: usize,
    /// Number of input coefficients.
    #[arg(long, default_value_t = 1)]
    nb: usize,
    /// Input delay in samples.
    #[arg(long, default_value_t = 1)]
    nk: usize,
    /// Write the identification as JSON to this file: with the default
    /// orders (--na 1 --nb 1 --nk 1) it is also a model file that
    /// `simulate --from` and `control --from` read (unless one file's
    /// --split-gaps pieces give one report each).
    #[arg(long, value_parser = crate::cli::common::output_path, value_name = "FILE")]
    out: Option<PathBuf>,
    /// Print JSON on stdout instead of a report.
    #[arg(long)]
    json: bool,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let orders = ArxOrders {
        na: args.na,
        nb: args.nb,
        nk: args.nk,
    };
    anyhow::ensure!(args.nb >= 1, "--nb must be at least 1");
    if let Some(out) = &args.out {
        let reads = match args.data.data.as_slice() {
            [] => vec![default_data()?],
            files => files.to_vec(),
        };
        let reads: Vec<(&str, &std::path::Path)> =
            reads.iter().map(|p| ("DATA", p.as_path())).collect();
        check_distinct(&reads, &[("--out", out)])?;
    }
    let traces = args.data.load()?;
    let provenance = args.data.provenance(None)?;
    // One file: each --split-gaps piece on its own, as the thesis treats
    // one experiment. Several: one model for all, a split file giving its
    // longest piece, as `fit` takes them.
    let ids = if args.data.data.len() > 1 {
        let mut records = records(traces, args.data.columns.resample.is_some())?;
        vec![(identify_jointly(&records, orders)?, records.swap_remove(0))]
    } else {
        traces
            .into_iter()
            .map(|t| Ok((identify(&t, orders)?, t)))
            .collect::<anyhow::Result<Vec<_>>>()?
    };
    let mut outputs = Vec::new();
    for (id, trace) in ids {
        let model = id
            .first_order_model(&trace)
            .map(|m| ModelFile::new(&Model::plain(m), None, provenance.clone()));
        outputs.push((id, model));
    }
    // One document per data piece, each with its own `schema_version`.
    let json: Vec<Versioned<IdentifyJson>> = outputs
        .iter()
        .map(|(id, model)| {
            Versioned::new(IdentifyJson {
                identification: id,
                model: model.clone(),
            })
        })
        .collect();
    let text = if json.len() == 1 {
        serde_json::to_string_pretty(&json[0])?
    } else {
        serde_json::to_string_pretty(&json)?
    };
    if let Some(path) = &args.out {
        write_atomic(path, text.as_bytes())
            .with_context(|| format!("cannot write --out {}", path.display()))?;
    }
    if args.json {
        outln!("{text}")?;
        return Ok(());
    }
    for (id, model) in &outputs {
        // The thesis' figures are in MPa and mm: beside a fit in other
        // units they are no comparison, and the line says so.
        let thesis_units = model.as_ref().is_some_and(|m| {
            m.data.input.unit.as_deref() == Some("MPa")
                && m.data.output.unit.as_deref() == Some("mm")
        });
        print_report(id, thesis_units)?;
    }
    if let Some(path) = &args.out {
        match (outputs.len(), orders == ArxOrders::default()) {
            (1, true) => outln!("model written to {}", path.display())?,
            (_, true) => outln!(
                "reports of {} pieces written to {} (a model file holds one: `simulate --from` \
                 reads none of them)",
                outputs.len(),
                path.display()
            )?,
            (_, false) => outln!(
                "report written to {} (no model: only the first-order ARX, --na 1 --nb 1 --nk 1, \
                 is a model file `simulate --from` reads)",
                path.display()
            )?,
        }
    }
    Ok(())
}

/// `y(k) = a1·y(k−1) + … + b1·u(k−nk) + …`, each term with its sign, the
/// output and the input named `(y, u)`.
fn difference_equation(a: &[f64], b: &[f64], nk: usize, (y, u): (&str, &str)) -> String {
    let terms = a
        .iter()
        .enumerate()
        .map(|(i, v)| (*v, format!("{y}(k−{})", i + 1)))
        .chain(
            b.iter()
                .enumerate()
                .map(|(j, v)| (*v, format!("{u}(k−{})", nk + j))),
        );
    let mut s = format!("{y}(k) =");
    for (i, (v, term)) in terms.enumerate() {
        let sign = match (v < 0.0, i) {
            (true, _) => " −",
            (false, 0) => "",
            (false, _) => " +",
        };
        s.push_str(&format!("{sign} {}·{term}", significant(v.abs(), 4)));
    }
    s
}

/// A fit % to two decimals; `NaN` is an output constant over the half
/// scored ([`mckibben::ident::fit_percent`]), where the measure is undefined.
fn percent(v: f64) -> String {
    match v.is_nan() {
        true => "undefined (the output is constant over it)".into(),
        false => format!("{v:.2} %"),
    }
}

/// `thesis_units`: the data are in the thesis' MPa and mm, so that its
/// eq. 12 figures compare.
fn print_report(id: &Identification, thesis_units: bool) -> anyhow::Result<()> {
    let o = id.arx.orders;
    outln!(
        "ARX identification of {} ({} samples, dt = {} s)",
        id.source,
        id.samples,
        mckibben::data::tidy_step(id.dt)
    )?;
    outln!(
        "  orders        na = {}, nb = {}, nk = {}",
        o.na,
        o.nb,
        o.nk
    )?;
    outln!(
        "  means removed input {}, output {} (estimation {})",
        significant(id.input_mean, 6),
        significant(id.output_mean, 6),
        if id.records.is_empty() {
            "half"
        } else {
            "halves together"
        }
    )?;
    for (i, a) in id.arx.a.iter().enumerate() {
        outln!("  a{}            {}", i + 1, significant(*a, 6))?;
    }
    for (j, b) in id.arx.b.iter().enumerate() {
        outln!("  b{}            {}", j + 1, significant(*b, 6))?;
    }
    if o == ArxOrders::default() {
        // The thesis' eq. 12 names them l and p.
        let equation = difference_equation(&id.arx.a, &id.arx.b, o.nk, ("l", "p"));
        let thesis = match thesis_units {
            true => "thesis: 0.9618, 24.9366",
            false => "the thesis' 0.9618, 24.9366 are in MPa and mm",
        };
        outln!("  model         {equation}   (eq. 12; {thesis})")?;
    } else {
        outln!(
            "  model         {}",
            difference_equation(&id.arx.a, &id.arx.b, o.nk, ("y", "u"))
        )?;
        // MATLAB's arx writes A(q)·y = B(q)·u with A(q) = 1 + a1·q⁻¹ + …:
        // its a's are these with the opposite sign.
        let matlab: Vec<String> = id.arx.a.iter().map(|a| significant(-a, 4)).collect();
        outln!(
            "                (MATLAB's arx: A(q) = 1 + a1·q⁻¹ + … with a = [{}], the opposite sign)",
            matlab.join(", ")
        )?;
    }
    outln!(
        "  fit, estimation half   {}",
        percent(id.estimation_fit_percent)
    )?;
    outln!(
        "  fit, validation half   {}   (RMSE {}; simulated from the half's own start, \
         as MATLAB's compare)",
        percent(id.validation_fit_percent),
        significant(id.validation_rmse, 4)
    )?;
    outln!(
        "  run on from the start  {}   (the same half, simulated from the record's first \
         sample: how `fit` and `simulate` score)",
        percent(id.continued_validation_fit_percent)
    )?;
    if let Some(warning) = mckibben::ident::arx::unstable_warning(&id.arx) {
        // `fit`'s box reads the first record's first-order ARX: this one
        // only where it is that.
        let fit = match o == ArxOrders::default() && id.records.is_empty() {
            true => "; `fit` builds its box around the best stable first-order run instead",
            false => "",
        };
        errln!("mckibben: warning: {warning}{fit}");
    }
    if id.validation_fit_percent.is_nan() {
        errln!(
            "mckibben: warning: {}",
            mckibben::ident::fit::constant_validation_warning("")
        );
    }
    if !id.records.is_empty() {
        outln!(
            "  the fits above pool the records, each about its own mean; each record's own \
             (estimation / validation / run on):"
        )?;
        for r in &id.records {
            let cell = |v: f64| match v.is_nan() {
                true => "  undef".to_string(),
                false => format!("{v:>7.2}"),
            };
            outln!(
                "    {:<28} {} / {} / {} %   (validation RMSE {})",
                r.data,
                cell(r.estimation_fit_percent),
                cell(r.validation_fit_percent),
                cell(r.continued_validation_fit_percent),
                significant(r.validation_rmse, 4)
            )?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each term with its own sign and lag, the input's from nk on.
    #[test]
    fn the_difference_equation_reads_as_the_estimates_say() {
        assert_eq!(
            difference_equation(&[1.543, -0.5491], &[2.4524, -1.7993], 2, ("y", "u")),
            "y(k) = 1.5430·y(k−1) − 0.5491·y(k−2) + 2.4524·u(k−2) − 1.7993·u(k−3)"
        );
        assert_eq!(
            difference_equation(&[-0.5], &[3.0], 1, ("y", "u")),
            "y(k) = − 0.5000·y(k−1) + 3.0000·u(k−1)"
        );
    }
}
