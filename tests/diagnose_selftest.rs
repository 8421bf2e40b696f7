//! The withheld-effect check on a small synthetic rig trace: a
//! representative subset of the self-test cases (the full table is
//! `mckibben diagnose --self-test`).

use mckibben::data::Trace;
use mckibben::diagnose::selftest::{Case, Nominal, cases, run_case};
use mckibben::diagnose::{Effect, Settings};
use mckibben::model::presets::thesis_params;
use mckibben::model::{Family, simulate};

/// A stair of gauge pressures up and down (MPa), the valve smoothing each
/// step with a pole of 0.6, and the thesis' classic model's response (mm).
fn rig_trace(len: usize) -> Trace {
    let levels = [0.05, 0.2, 0.35, 0.5, 0.3, 0.1, 0.25, 0.45, 0.15];
    let mut p = vec![levels[0]; len];
    for k in 1..len {
        let target = levels[(k / 60) % levels.len()];
        p[k] = 0.6 * p[k - 1] + 0.4 * target;
    }
    let mut theta: Vec<f32> = thesis_params(Family::Classic)
        .iter()
        .map(|&v| v as f32)
        .collect();
    theta[7] = 0.5;
    let u: Vec<f32> = p.iter().map(|&v| v as f32).collect();
    let x = simulate(Family::Classic, &theta, &u, 0.0).x;
    Trace::uniform("rig", 0.1, p, x.iter().map(|&v| v as f64).collect())
}

fn fast() -> Settings {
    Settings {
        seeds: 2,
        baseline_population: 30,
        baseline_generations: 150,
        population: 30,
        generations: 150,
        ..Settings::default()
    }
}

fn nominal() -> Nominal {
    Nominal::fit(&rig_trace(1080), Family::Classic, &fast()).unwrap()
}

fn case_of(nominal: &Nominal, name: &str) -> Case {
    cases(nominal, &Effect::ALL)
        .into_iter()
        .find(|c| c.name == name)
        .unwrap_or_else(|| panic!("no case {name}"))
}

#[test]
#[ignore = "exploration: prints the whole table"]
fn explore() {
    let t0 = std::time::Instant::now();
    let nom = nominal();
    eprintln!("nominal {:?} in {:?}", nom.params, t0.elapsed());
    let mut outs = Vec::new();
    for c in cases(&nom, &Effect::ALL) {
        let t = std::time::Instant::now();
        let o = run_case(&nom, &c, &Effect::ALL, &fast(), 7).unwrap();
        eprintln!("{} {:?} {:?}", c.name, t.elapsed(), o);
        outs.push(o);
    }
    eprintln!(
        "{}",
        mckibben::diagnose::selftest::table(&outs, &Effect::ALL)
    );
}

#[test]
#[ignore = "exploration: baseline budget"]
fn explore_budget() {
    let nom = nominal();
    let c = case_of(&nom, "control");
    let traces = mckibben::diagnose::selftest::synthesize(&nom, &c, 7);
    let data = mckibben::diagnose::Data::new(&traces).unwrap();
    let model = mckibben::diagnose::Augmented::new(Family::Classic, vec![], 1);
    for (pop, gens) in [(30, 150), (40, 400), (60, 800), (100, 1500)] {
        let t = std::time::Instant::now();
        for seed in 0..3 {
            let f = mckibben::diagnose::select::fit_candidate(&data, &model, None, seed, pop, gens);
            eprintln!(
                "{pop}x{gens} seed {seed}: val {:.4} est {:.2} {:?} {:?}",
                f.val_rmse,
                f.est_sse,
                t.elapsed(),
                f.params
            );
        }
    }
}

#[test]
#[ignore = "exploration: truth"]
fn explore_truth() {
    let nom = nominal();
    let c = case_of(&nom, "control");
    let traces = mckibben::diagnose::selftest::synthesize(&nom, &c, 7);
    let data = mckibben::diagnose::Data::new(&traces).unwrap();
    let model = mckibben::diagnose::Augmented::new(Family::Classic, vec![], 1);
    let mut th = nom.params.clone();
    let delta = data.whole[0].y_mean - nom.data.whole[0].y_mean;
    th[7] += (th[5] * th[1] - 1.0) * delta;
    eprintln!(
        "delta {delta} du {}",
        data.whole[0].u_mean - nom.data.whole[0].u_mean
    );
    eprintln!(
        "truth est {} val {}",
        data.est_sse(&model, &th),
        data.val_rmse(&model, &th)
    );
    let r = &data.val_residuals(&model, &th)[0];
    let pred = &data.predict(&model, &th)[0];
    let e: Vec<f64> = (0..540)
        .map(|k| data.whole[0].y[k] as f64 - pred[k] as f64)
        .collect();
    eprintln!("est resid head {:?}", &e[..12]);
    eprintln!(
        "est rms {}",
        (e.iter().map(|v| v * v).sum::<f64>() / 540.0).sqrt()
    );
    eprintln!("val resid head {:?}", &r[..5]);
    let t32: Vec<f32> = nom.params.iter().map(|&v| v as f32).collect();
    let clean = model.simulate(&t32, 0, &nom.data.ctx[0], &nom.data.whole[0]);
    let mism: Vec<f64> = (0..1080)
        .map(|k| {
            (clean[k] as f64 + nom.data.whole[0].y_mean) - (pred[k] as f64 + data.whole[0].y_mean)
        })
        .collect();
    eprintln!("mismatch head {:?}", &mism[..8]);
    eprintln!(
        "mismatch rms est {} val {}",
        (mism[..540].iter().map(|v| v * v).sum::<f64>() / 540.0).sqrt(),
        (mism[540..].iter().map(|v| v * v).sum::<f64>() / 540.0).sqrt()
    );
    let nz: Vec<f64> = (0..1080)
        .map(|k| traces[0].output[k] - (clean[k] as f64 + nom.data.whole[0].y_mean))
        .collect();
    eprintln!(
        "noise rms est {} val {}",
        (nz[..540].iter().map(|v| v * v).sum::<f64>() / 540.0).sqrt(),
        (nz[540..].iter().map(|v| v * v).sum::<f64>() / 540.0).sqrt()
    );
    let (_, lo, hi) = data.space(&model);
    eprintln!("lo {lo:?}\nhi {hi:?}\nth {th:?}");
}

#[test]
#[ignore = "exploration: baseline budget on a CSV named by DG_CSV"]
fn explore_budget_csv() {
    let path = std::env::var("DG_CSV").unwrap();
    let traces = mckibben::data::csv::read_traces(std::path::Path::new(&path), &Default::default()).unwrap();
    let data = mckibben::diagnose::Data::new(&traces).unwrap();
    let model = mckibben::diagnose::Augmented::new(Family::Classic, vec![], 1);
    for (pop, gens) in [(40, 300), (60, 600), (40, 1000)] {
        let t = std::time::Instant::now();
        for seed in 0..4 {
            let f = mckibben::diagnose::select::fit_candidate(&data, &model, None, seed, pop, gens);
            eprintln!("{pop}x{gens} seed {seed}: val {:.4} est {:.2} {:?}", f.val_rmse, f.est_sse, t.elapsed());
        }
    }
}

#[test]
#[ignore = "exploration: saturation"]
fn explore_saturation() {
    let nom = nominal();
    let c = case_of(&nom, "saturation (small)");
    let traces = mckibben::diagnose::selftest::synthesize(&nom, &c, 7);
    let data = mckibben::diagnose::Data::new(&traces).unwrap();
    let model = mckibben::diagnose::Augmented::new(Family::Classic, vec![Effect::Saturation], 1);
    let mut th = nom.params.clone();
    let delta = data.whole[0].y_mean - nom.data.whole[0].y_mean;
    th[7] += (th[5] * th[1] - 1.0) * delta;
    th.push(c.effects[0].1[0]);
    eprintln!("truth est {} val {} ctx {:?}", data.est_sse(&model, &th), data.val_rmse(&model, &th), data.ctx[0]);
    let (_, lo, hi) = data.space(&model);
    eprintln!("lo {lo:?}\nhi {hi:?}\nth {th:?}");
}
