//! The terms a search and the model it searches share, below both: what a
//! candidate's cost measures, which bound of a box, and populations whose
//! type says what their entries are. The model's
//! simulation runs under a [`Measure`] and its search box has sides; the
//! fitting engine plans its stages on measures and finds the sides a
//! result ends on, without knowing the model.

use std::fmt;
use std::marker::PhantomData;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Rows one rayon task of a row-by-row update takes at least: an
/// optimizer's step, a draw, rows embedded into the model's parameters.
/// Such a row costs well under a microsecond, and handing a task to
/// another thread costs tens of microseconds in wake-ups, so a generation
/// of a few dozen rows (the diagnosis' fits) runs on one thread while
/// 10⁵ rows still split into hundreds of tasks. Each row draws from its
/// own stream, so where the rows split never moves a bit.
pub const ROWS_PER_TASK: usize = 256;

/// What a score sums: the error of the free run (the thesis' fitness, eq. 29)
/// or of the `h`-step-ahead prediction.
///
/// The `h`-step-ahead predictor is the free run with its output state set
/// back to the measurement after every `h`-th sample (a state that is never
/// measured follows that jump as it follows any motion of the output:
/// `model::sim`'s `Stepper::restart`). Its error cannot pile up through a
/// slow pole for longer than `h` samples, so its cost surface has no needle along the pole
/// and the static gain where the free run's has one (Ribeiro, Tiels,
/// Umenberger, Schön and Aguirre, "On the smoothness of nonlinear system
/// identification", Automatica 2020: the Lipschitz constant of a simulation
/// error can grow exponentially with the simulated length; short predictions
/// restore smoothness). `h = 1` is the equation error; `h` past the data is
/// the free run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Measure {
    /// `Σ_{k≥1} (x(k) − y(k))²` of the free run.
    #[default]
    FreeRun,
    /// The same sum with the output state restarted from `y(k)` after every
    /// `horizon`-th sample (`horizon ≥ 1`).
    Ahead { horizon: usize },
}

impl Measure {
    /// Samples between restarts (`usize::MAX`: never).
    pub fn restart_every(self) -> usize {
        match self {
            Measure::FreeRun => usize::MAX,
            Measure::Ahead { horizon } => horizon.max(1),
        }
    }
}

impl fmt::Display for Measure {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Measure::FreeRun => f.write_str("free run"),
            Measure::Ahead { horizon } => write!(f, "{horizon}-step-ahead prediction"),
        }
    }
}

/// Which bound of a coordinate's box.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Side {
    Lower,
    Upper,
}

impl Side {
    pub const BOTH: [Side; 2] = [Side::Lower, Side::Upper];

    /// Its place in a `[lower, upper]` pair (as a model's search box keeps
    /// its bounds' origins).
    pub fn index(self) -> usize {
        match self {
            Side::Lower => 0,
            Side::Upper => 1,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Side::Lower => "lower",
            Side::Upper => "upper",
        }
    }
}

impl fmt::Display for Side {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Rows whose entries are a search box's coordinates: the free
/// coordinates the optimizers move (a model's parameters seen through its
/// chart, the held ones left out). A marker for [`Rows`] and [`Population`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Coords {}

/// Rows whose entries are a model's canonical parameters, every one of
/// them: what a simulation runs on and an evaluator scores. A marker for
/// [`Rows`] and [`Population`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Params {}

/// Row-major vectors of one length, borrowed: a population of
/// [`Rows::len`] candidates of [`Rows::dim`] entries each. `K` says what the
/// entries are ([`Coords`] or [`Params`]), so that a population of one kind
/// cannot be handed where the other is asked for, and the dimension
/// travels with the values instead of beside them.
pub struct Rows<'a, K> {
    flat: &'a [f64],
    dim: usize,
    kind: PhantomData<fn() -> K>,
}

impl<K> Clone for Rows<'_, K> {
    fn clone(&self) -> Self {
        *self
    }
}

impl<K> Copy for Rows<'_, K> {}

impl<K> fmt::Debug for Rows<'_, K> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Rows")
            .field("dim", &self.dim)
            .field("flat", &self.flat)
            .finish()
    }
}

impl<'a, K> Rows<'a, K> {
    /// The rows of `flat`, `dim` values each. Panics unless `dim ≥ 1` and
    /// `flat` holds whole rows: a caller's slip, not a user's input.
    pub fn new(flat: &'a [f64], dim: usize) -> Rows<'a, K> {
        assert!(
            dim > 0 && flat.len().is_multiple_of(dim),
            "{} values are not whole rows of {dim}",
            flat.len()
        );
        Rows {
            flat,
            dim,
            kind: PhantomData,
        }
    }

    /// One row of `row.len()` entries (panics on an empty one).
    pub fn one(row: &'a [f64]) -> Rows<'a, K> {
        Rows::new(row, row.len())
    }

    /// The `count` rows from row `at` on.
    pub fn span(self, at: usize, count: usize) -> Rows<'a, K> {
        Rows::new(&self.flat[at * self.dim..(at + count) * self.dim], self.dim)
    }

    /// Entries a row.
    pub fn dim(self) -> usize {
        self.dim
    }

    /// Rows.
    pub fn len(self) -> usize {
        self.flat.len() / self.dim
    }

    pub fn is_empty(self) -> bool {
        self.flat.is_empty()
    }

    /// Row `i`.
    pub fn row(self, i: usize) -> &'a [f64] {
        &self.flat[i * self.dim..(i + 1) * self.dim]
    }

    /// The rows in order.
    pub fn iter(self) -> std::slice::ChunksExact<'a, f64> {
        self.flat.chunks_exact(self.dim)
    }

    /// The rows, for rayon, [`ROWS_PER_TASK`] or more to a task.
    pub fn par_iter(self) -> rayon::iter::MinLen<rayon::slice::ChunksExact<'a, f64>> {
        self.flat
            .par_chunks_exact(self.dim)
            .with_min_len(ROWS_PER_TASK)
    }

    /// Every value, row after row: what a device buffer is filled from.
    pub fn as_flat(self) -> &'a [f64] {
        self.flat
    }

    pub fn to_population(self) -> Population<K> {
        Population::new(self.flat.to_vec(), self.dim)
    }
}

/// Row-major vectors of one length, owned: [`Rows`] that a caller keeps or
/// fills.
pub struct Population<K> {
    flat: Vec<f64>,
    dim: usize,
    kind: PhantomData<fn() -> K>,
}

impl<K> Clone for Population<K> {
    fn clone(&self) -> Self {
        Population::new(self.flat.clone(), self.dim)
    }
}

impl<K> PartialEq for Population<K> {
    fn eq(&self, other: &Self) -> bool {
        self.dim == other.dim && self.flat == other.flat
    }
}

impl<K> fmt::Debug for Population<K> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        self.rows().fmt(f)
    }
}

impl<K> Population<K> {
    /// The rows of `flat`, `dim` values each (panics as [`Rows::new`]).
    pub fn new(flat: Vec<f64>, dim: usize) -> Population<K> {
        Rows::<K>::new(&flat, dim);
        Population {
            flat,
            dim,
            kind: PhantomData,
        }
    }

    /// `len` rows of zeros, to be filled.
    pub fn zeros(len: usize, dim: usize) -> Population<K> {
        Population::new(vec![0.0; len * dim], dim)
    }

    pub fn rows(&self) -> Rows<'_, K> {
        Rows::new(&self.flat, self.dim)
    }

    pub fn dim(&self) -> usize {
        self.dim
    }

    pub fn len(&self) -> usize {
        self.flat.len() / self.dim
    }

    pub fn is_empty(&self) -> bool {
        self.flat.is_empty()
    }

    /// `len` rows: cut, or grown with rows of zeros.
    pub fn resize(&mut self, len: usize) {
        self.flat.resize(len * self.dim, 0.0);
    }

    /// Rows `at..at + count`, every value row after row, to fill in place.
    pub fn span_mut(&mut self, at: usize, count: usize) -> &mut [f64] {
        &mut self.flat[at * self.dim..(at + count) * self.dim]
    }

    /// Row `i`, to change in place.
    pub fn row_mut(&mut self, i: usize) -> &mut [f64] {
        &mut self.flat[i * self.dim..(i + 1) * self.dim]
    }

    /// The rows in order, to change in place.
    pub fn iter_mut(&mut self) -> std::slice::ChunksExactMut<'_, f64> {
        self.flat.chunks_exact_mut(self.dim)
    }

    /// The rows, to change in place with rayon, [`ROWS_PER_TASK`] or more
    /// to a task.
    pub fn par_iter_mut(&mut self) -> rayon::iter::MinLen<rayon::slice::ChunksExactMut<'_, f64>> {
        self.flat
            .par_chunks_exact_mut(self.dim)
            .with_min_len(ROWS_PER_TASK)
    }

    /// The rows of `other` appended (panics where the dimensions differ).
    pub fn extend(&mut self, other: Rows<'_, K>) {
        assert_eq!(self.dim, other.dim, "rows of another dimension");
        self.flat.extend_from_slice(other.flat);
    }

    /// Every value, row after row.
    pub fn into_flat(self) -> Vec<f64> {
        self.flat
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The threads that ran `count` rows (on a pool of four), each row
    /// long enough (0.2 ms) for an idle thread to steal work if allowed.
    fn threads_of_rows(count: usize) -> std::collections::BTreeSet<Option<usize>> {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(4)
            .build()
            .unwrap();
        let mut rows = Population::<Coords>::zeros(count, 3);
        let seen = std::sync::Mutex::new(std::collections::BTreeSet::new());
        pool.install(|| {
            let note = || {
                std::thread::sleep(std::time::Duration::from_micros(200));
                seen.lock().unwrap().insert(rayon::current_thread_index());
            };
            rows.par_iter_mut().for_each(|_| note());
            rows.rows().par_iter().for_each(|_| note());
        });
        seen.into_inner().unwrap()
    }

    #[test]
    fn a_generation_of_fewer_rows_than_a_task_takes_runs_on_one_thread() {
        assert_eq!(threads_of_rows(ROWS_PER_TASK).len(), 1);
        assert_eq!(threads_of_rows(40).len(), 1);
    }

    #[test]
    fn rows_keep_their_dimension() {
        let flat = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0];
        let rows = Rows::<Params>::new(&flat, 3);
        assert_eq!((rows.len(), rows.dim()), (2, 3));
        assert_eq!(rows.row(1), &[4.0, 5.0, 6.0]);
        assert_eq!(rows.iter().count(), 2);
        assert_eq!(rows.span(1, 1).as_flat(), rows.row(1));
        assert_eq!(Rows::<Params>::one(rows.row(1)).dim(), 3);
        let mut population = rows.to_population();
        population.row_mut(0)[0] = 9.0;
        population.extend(rows);
        assert_eq!(population.len(), 4);
        population.resize(5);
        assert_eq!(population.rows().row(4), &[0.0; 3]);
        population.resize(4);
        assert_eq!(population.rows().row(0), &[9.0, 2.0, 3.0]);
        assert_eq!(population.rows().row(3), &[4.0, 5.0, 6.0]);
    }

    #[test]
    #[should_panic(expected = "not whole rows")]
    fn a_partial_row_is_refused() {
        Rows::<Coords>::new(&[1.0, 2.0, 3.0], 2);
    }

    #[test]
    #[should_panic(expected = "not whole rows")]
    fn rows_of_no_entries_are_refused() {
        Population::<Coords>::zeros(3, 0);
    }
}
