//! Differential evolution: the modern baseline none of the thesis' methods
//! is.
//!
//! Default variant: *current-to-pbest/1/bin* mutation (Zhang & Sanderson,
//! JADE, 2009, without the archive), `v = x_i + F·(x_pbest − x_i) + F·(x_r1 − x_r2)`
//! with `x_pbest` drawn from the best `p·N`, binomial crossover, greedy
//! one-to-one selection, and the self-adaptation of `F` and `CR` of jDE
//! (Brest et al., 2006: each individual carries its own `F`, `CR`; with
//! probability 0.1 a trial redraws `F ∈ [0.1, 1]`, resp. `CR ∈ [0, 1]`, and
//! keeps them if the trial wins). A coordinate that leaves the box is put
//! half-way between the parent and the bound it crossed (JADE's repair), so
//! the boundary is reachable but not over-sampled. `DE/rand/1/bin` (Storn &
//! Price, 1997) is selectable.

use rand::RngExt;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::{Bounds, Optimizer, RowRng, Streams};
use crate::search::{Coords, Population, ROWS_PER_TASK, Rows};

/// The mutation strategy.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "kebab-case")]
pub enum Strategy {
    /// `v = x_r0 + F·(x_r1 − x_r2)`: slow, robust exploration.
    Rand1,
    /// `v = x_i + F·(x_pbest − x_i) + F·(x_r1 − x_r2)`: greedier, converges
    /// in tens of generations on this problem.
    CurrentToPbest1,
}

/// DE settings; the thesis has no DE, so the defaults are its papers': jDE's
/// `F = 0.5`, `CR = 0.9`, `τ = 0.1` (Brest et al., 2006) and JADE's
/// `p = 0.1` (Zhang & Sanderson, 2009).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DeSettings {
    pub strategy: Strategy,
    /// Share of the population `x_pbest` is drawn from (JADE: 0.05–0.2).
    pub p_best: f64,
    /// Initial `F` and `CR` of every individual (jDE: 0.5, 0.9).
    pub f_init: f64,
    pub cr_init: f64,
    /// Probabilities of redrawing `F` and `CR` per trial (jDE: 0.1, 0.1).
    pub tau_f: f64,
    pub tau_cr: f64,
}

impl Default for DeSettings {
    fn default() -> Self {
        DeSettings {
            strategy: Strategy::CurrentToPbest1,
            p_best: 0.1,
            f_init: 0.5,
            cr_init: 0.9,
            tau_f: 0.1,
            tau_cr: 0.1,
        }
    }
}

/// DE state between generations.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct De {
    pub settings: DeSettings,
    bounds: Bounds,
    n: usize,
    pop: Vec<f64>,
    #[serde(with = "super::inf_serde")]
    costs: Vec<f32>,
    f: Vec<f64>,
    cr: Vec<f64>,
    /// Trials last asked for, with the `F`, `CR` they were made with.
    trials: Vec<f64>,
    trial_f: Vec<f64>,
    trial_cr: Vec<f64>,
}

impl Optimizer for De {
    type Settings = DeSettings;

    const HELP: &'static str =
        "Differential evolution (jDE-adapted current-to-pbest/1/bin), the baseline";

    /// rand/1 draws three partners distinct from the individual
    /// (current-to-pbest/1 two): one minimum for both strategies, so that a
    /// population valid for one is valid for the other.
    const MIN_POPULATION: usize = 4;

    /// `generations` is unused: jDE adapts `F` and `CR` without a schedule.
    fn new(settings: DeSettings, bounds: Bounds, n: usize, _generations: usize) -> De {
        De {
            f: vec![settings.f_init; n],
            cr: vec![settings.cr_init; n],
            settings,
            bounds,
            n,
            pop: Vec::new(),
            costs: Vec::new(),
            trials: Vec::new(),
            trial_f: Vec::new(),
            trial_cr: Vec::new(),
        }
    }

    fn bounds(&self) -> &Bounds {
        &self.bounds
    }

    /// A known model among `initial` means the best member never ends worse
    /// than it (selection is greedy).
    fn init(&mut self, initial: Population<Coords>, streams: &Streams) -> Rows<'_, Coords> {
        self.pop = super::first_population(&self.bounds, self.n, initial, streams);
        Rows::new(&self.pop, self.bounds.dim())
    }

    /// One trial an individual.
    fn next(&mut self, streams: &Streams) -> Rows<'_, Coords> {
        self.make_trials(streams);
        Rows::new(&self.trials, self.bounds.dim())
    }

    /// Greedy one-to-one selection, row by row in parallel.
    fn tell(&mut self, costs: &[f32]) {
        // The first population's costs: nothing to select against yet.
        if self.costs.is_empty() {
            self.costs = costs.to_vec();
            return;
        }
        let d = self.bounds.dim();
        self.pop
            .par_chunks_mut(d)
            .zip(self.trials.par_chunks(d))
            .zip(self.costs.par_iter_mut())
            .zip(self.f.par_iter_mut().zip(self.cr.par_iter_mut()))
            .enumerate()
            .with_min_len(ROWS_PER_TASK)
            .for_each(|(i, (((row, trial), cost), (f, cr)))| {
                let c = costs[i];
                if super::cost_order(c, *cost).is_le() && c.is_finite() {
                    *cost = c;
                    row.copy_from_slice(trial);
                    *f = self.trial_f[i];
                    *cr = self.trial_cr[i];
                }
            });
    }

    fn members(&self) -> (Population<Coords>, Vec<f32>) {
        (
            Population::new(self.pop.clone(), self.bounds.dim()),
            self.costs.clone(),
        )
    }
}

impl De {
    /// Every individual's trial, in parallel: row `i` and its `F`, `CR`
    /// from `streams.row(i)` alone.
    fn make_trials(&mut self, streams: &Streams) {
        let (n, d) = (self.n, self.bounds.dim());
        // x_pbest is drawn from the best `top`: a partial selection.
        let top = ((self.settings.p_best * n as f64).round() as usize).clamp(1, n);
        let best = match self.settings.strategy {
            Strategy::CurrentToPbest1 => super::best_indices(&self.costs, top),
            Strategy::Rand1 => Vec::new(),
        };
        self.trials.resize(n * d, 0.0);
        self.trial_f.resize(n, 0.0);
        self.trial_cr.resize(n, 0.0);
        let (pop, bounds, settings) = (&self.pop, &self.bounds, &self.settings);
        let (f_now, cr_now) = (&self.f, &self.cr);
        self.trials
            .par_chunks_mut(d)
            .zip(
                self.trial_f
                    .par_iter_mut()
                    .zip(self.trial_cr.par_iter_mut()),
            )
            .enumerate()
            .with_min_len(ROWS_PER_TASK)
            .for_each(|(i, (trial, (trial_f, trial_cr)))| {
                let mut rng = streams.row(i);
                let f = if rng.random::<f64>() < settings.tau_f {
                    0.1 + 0.9 * rng.random::<f64>()
                } else {
                    f_now[i]
                };
                let cr = if rng.random::<f64>() < settings.tau_cr {
                    rng.random::<f64>()
                } else {
                    cr_now[i]
                };
                let pick = |rng: &mut RowRng, not: &[usize]| loop {
                    let r = rng.random_range(0..n);
                    if !not.contains(&r) {
                        break r;
                    }
                };
                let r1 = pick(&mut rng, &[i]);
                let r2 = pick(&mut rng, &[i, r1]);
                let row = |k: usize| &pop[k * d..(k + 1) * d];
                // The mutant's base and the row it is pulled towards:
                // `rand/1`, a third partner and none; `current-to-pbest/1`,
                // the individual itself and one of the best.
                let (base, pbest) = match settings.strategy {
                    Strategy::Rand1 => (row(pick(&mut rng, &[i, r1, r2])), None),
                    Strategy::CurrentToPbest1 => {
                        (row(i), Some(row(best[rng.random_range(0..top)])))
                    }
                };
                let (x, x1, x2) = (row(i), row(r1), row(r2));
                let jrand = rng.random_range(0..d);
                let coordinates = trial
                    .iter_mut()
                    .zip(x)
                    .zip(base.iter().zip(x1.iter().zip(x2)))
                    .zip(bounds.lower.iter().zip(&bounds.upper))
                    .enumerate();
                for (j, (((t, &parent), (&b, (&a1, &a2))), (&lower, &upper))) in coordinates {
                    let mut v = if j == jrand || rng.random::<f64>() < cr {
                        match pbest {
                            None => b + f * (a1 - a2),
                            Some(xp) => b + f * (xp[j] - b) + f * (a1 - a2),
                        }
                    } else {
                        parent
                    };
                    if v < lower {
                        v = 0.5 * (lower + parent);
                    } else if v > upper {
                        v = 0.5 * (upper + parent);
                    }
                    *t = v;
                }
                *trial_f = f;
                *trial_cr = cr;
            });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::optim::stage::Stage;

    /// Generation `g`'s streams of a run seeded by `seed`.
    fn at(seed: u64, g: usize) -> Streams {
        Streams::new(seed, Stage::Global, g)
    }

    fn sphere(rows: &[f64], d: usize) -> Vec<f32> {
        rows.chunks(d)
            .map(|r| r.iter().map(|v| (v - 0.3) * (v - 0.3)).sum::<f64>() as f32)
            .collect()
    }

    #[test]
    fn trials_stay_in_the_box_and_selection_never_worsens() {
        let bounds = Bounds {
            lower: vec![-1.0; 3],
            upper: vec![1.0; 3],
            names: vec!["x".into(), "y".into(), "z".into()],
        };
        let mut de = De::new(DeSettings::default(), bounds.clone(), 20, 60);
        let mut best = f32::INFINITY;
        let mut rows = de
            .init(Population::zeros(0, 3), &at(5, 0))
            .as_flat()
            .to_vec();
        for g in 1..=60 {
            assert!(rows.chunks(3).all(|r| {
                let mut c = r.to_vec();
                !bounds.clamp(&mut c)
            }));
            de.tell(&sphere(&rows, 3));
            let now = de.costs.iter().copied().fold(f32::INFINITY, f32::min);
            assert!(now <= best);
            best = now;
            rows = de.next(&at(5, g)).as_flat().to_vec();
        }
        assert!(best < 1e-6, "{best}");
    }

    #[test]
    fn rand1_runs_at_the_minimum_population() {
        let bounds = Bounds {
            lower: vec![-1.0; 2],
            upper: vec![1.0; 2],
            names: vec!["x".into(), "y".into()],
        };
        let settings = DeSettings {
            strategy: Strategy::Rand1,
            ..DeSettings::default()
        };
        let mut de = De::new(settings, bounds, De::MIN_POPULATION, 5);
        let mut rows = de
            .init(Population::zeros(0, 2), &at(8, 0))
            .as_flat()
            .to_vec();
        for g in 1..=5 {
            de.tell(&sphere(&rows, 2));
            rows = de.next(&at(8, g)).as_flat().to_vec();
        }
        assert_eq!(rows.len(), 2 * De::MIN_POPULATION);
    }

    #[test]
    fn initial_rows_start_the_population_clamped_into_the_box() {
        let bounds = Bounds {
            lower: vec![-1.0; 2],
            upper: vec![1.0; 2],
            names: vec!["x".into(), "y".into()],
        };
        let mut de = De::new(DeSettings::default(), bounds, 10, 6);
        let initial = Population::new(vec![0.3, 0.3, 5.0, -0.5], 2);
        let rows = de.init(initial, &at(1, 0)).as_flat().to_vec();
        assert_eq!(rows.len(), 20);
        assert_eq!(&rows[..4], &[0.3, 0.3, 1.0, -0.5]);
        // The warm start is the optimum: the best cost is 0 from the start
        // and greedy selection keeps it.
        de.tell(&sphere(&rows, 2));
        for g in 1..=5 {
            let rows = de.next(&at(1, g)).as_flat().to_vec();
            de.tell(&sphere(&rows, 2));
        }
        assert_eq!(de.costs.iter().copied().fold(f32::INFINITY, f32::min), 0.0);
    }
}
