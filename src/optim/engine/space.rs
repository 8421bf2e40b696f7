//! The box a fit searches, and the coordinates the optimizers move in.

use rand::RngExt;
use rayon::prelude::*;
use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};

use super::super::{Bounds, Streams};
use crate::search::{Coords, Params, Population, Rows, Side};

/// The map between the coordinates a box is set in and the canonical
/// vectors the objective scores, entry for entry (as long as each other).
/// The engine knows no model: a model's own coordinates come as a chart
/// (the data's scale of a model family: `fit::chart`). A checkpoint holds
/// it with the rest of the engine.
pub trait Chart:
    Clone + std::fmt::Debug + PartialEq + Send + Sync + Serialize + DeserializeOwned
{
    /// The canonical vector of coordinates `z`, written into `theta`: no
    /// allocation, for the engine maps every row of every generation.
    fn to_canonical_into(&self, z: &[f64], theta: &mut [f64]);

    /// The coordinates of the canonical vector `theta`.
    fn coordinates_of(&self, theta: &[f64]) -> Vec<f64>;

    /// The names of the canonical parameters of the coordinates `names`.
    fn canonical_names(&self, names: &[String]) -> Vec<String>;
}

/// No chart: a box set in the canonical vectors themselves. It has no
/// value, so a [`Space`] of it never holds a chart.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Canonical {}

impl Chart for Canonical {
    fn to_canonical_into(&self, _: &[f64], _: &mut [f64]) {
        match *self {}
    }

    fn coordinates_of(&self, _: &[f64]) -> Vec<f64> {
        match *self {}
    }

    fn canonical_names(&self, _: &[String]) -> Vec<String> {
        match *self {}
    }
}

/// The box of a fit over search coordinates (the canonical parameters, or
/// others through a [`Chart`]); a coordinate whose bounds are equal is held
/// there and never shown to the optimizers. What the engine scores, keeps
/// and reports are canonical vectors ([`Space::embed`]).
///
/// The optimizers see the free coordinates as they are. For a coordinate
/// whose values span decades near zero, a log scale as the coordinate does
/// worse (docs/ARCHITECTURE.md, "Decisions of the fitting engine"); what
/// helps is drawing half the first population's values of such coordinates
/// log-uniformly ([`Space::draw`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Space<C = Canonical> {
    pub lower: Vec<f64>,
    pub upper: Vec<f64>,
    pub names: Vec<String>,
    /// Coordinates whose plausible values span decades below the box's
    /// edge (canonical indices).
    #[serde(default)]
    pub decades: Vec<bool>,
    /// Decades below the box's edge that a log-uniform draw spans.
    #[serde(default = "thesis_decades")]
    pub drawn_decades: f64,
    /// The map from coordinates to canonical vectors (none: the
    /// coordinates are the canonical vector).
    #[serde(default = "Option::default")]
    pub coords: Option<C>,
    /// Coordinates in which the objective is piecewise constant: the polish
    /// holds them and a scan of levels in one batch moves them
    /// ([`Stepwise`]).
    #[serde(default)]
    pub stepwise: Vec<Stepwise>,
}

/// A coordinate in which the objective is piecewise constant, as in a level
/// where a model's state switches: the cost changes only where the level
/// passes a sample, so its difference quotients are zero or noise and no
/// gradient step moves it. The polish holds it; after each polish, the
/// engine scores a grid of its levels around each try's best in one call
/// and keeps the lowest ([`super::Engine`]'s scan).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Stepwise {
    /// Its index in the canonical vector (free coordinates only matter).
    pub index: usize,
    /// Values kept among those that score alike: the scan keeps one of
    /// these where it scores within `tolerance` of the lowest, and a third
    /// of a first population draws them ([`Space::draw`]).
    pub preferred: Vec<f64>,
    /// Relative: a preferred value whose cost is at most `1 + tolerance`
    /// times the lowest scores alike.
    pub tolerance: f64,
}

/// Decades a log-uniform draw spans below the edge of a box (a box of ±0.5:
/// down to 5·10⁻⁵).
const THESIS_DECADES: f64 = 4.0;
fn thesis_decades() -> f64 {
    THESIS_DECADES
}

impl Space {
    /// A box set in the canonical vectors.
    pub fn new(lower: Vec<f64>, upper: Vec<f64>, names: Vec<String>) -> Space {
        let decades = vec![false; lower.len()];
        Space {
            lower,
            upper,
            names,
            decades,
            drawn_decades: THESIS_DECADES,
            coords: None,
            stepwise: Vec::new(),
        }
    }

    /// The same box set in the coordinates of `chart` (none: the canonical
    /// vectors still).
    pub fn with_chart<C: Chart>(self, chart: Option<C>) -> Space<C> {
        let Space {
            lower,
            upper,
            names,
            decades,
            drawn_decades,
            stepwise,
            ..
        } = self;
        Space {
            lower,
            upper,
            names,
            decades,
            drawn_decades,
            coords: chart,
            stepwise,
        }
    }
}

impl<C: Chart> Space<C> {
    /// Marks the coordinates `indices` as spanning decades (see [`Space::draw`]).
    pub fn with_decades(mut self, indices: impl IntoIterator<Item = usize>) -> Space<C> {
        for i in indices {
            self.decades[i] = true;
        }
        self
    }

    /// `count` random rows of free coordinates, row `r` from
    /// `streams.row(r)`: uniform over the box, except that every other row
    /// (the odd `r`) draws the coordinates marked as spanning decades
    /// log-uniformly in magnitude over four decades below the box's larger
    /// edge (either sign where the box has both), and every third row (`r`
    /// of 1 modulo 3) takes a [`Stepwise`] coordinate's preferred values in
    /// turn. A uniform draw almost never visits the sliver near zero where
    /// such a coordinate's value often lies (docs/ARCHITECTURE.md, "Decisions of the
    /// fitting engine"), and neither do the differences of uniform draws
    /// that DE steps by; nor does it hit a level exactly, and a level held
    /// exactly (DE's crossover keeps a parent's coordinate as it is)
    /// survives as long as it scores.
    pub fn draw(&self, count: usize, streams: &Streams) -> Population<Coords> {
        let free = self.free();
        let mut rows = Population::zeros(count, self.free_dim());
        rows.par_iter_mut().enumerate().for_each(|(r, row)| {
            let mut rng = streams.row(r);
            for (v, &i) in row.iter_mut().zip(&free) {
                let (lo, hi) = (self.lower[i], self.upper[i]);
                let uniform = lo + rng.random::<f64>() * (hi - lo);
                let preferred = self
                    .stepwise
                    .iter()
                    .find(|s| s.index == i)
                    .map(|s| s.preferred.as_slice())
                    .filter(|p| !p.is_empty() && r % 3 == 1);
                *v = if let Some(p) = preferred {
                    p[(r / 3) % p.len()].clamp(lo, hi)
                } else if r % 2 == 1 && self.decades[i] {
                    let magnitude = hi.abs().max(lo.abs())
                        * 10f64.powf(-self.drawn_decades * rng.random::<f64>());
                    let sign = if lo < 0.0 && (hi <= 0.0 || rng.random::<bool>()) {
                        -1.0
                    } else {
                        1.0
                    };
                    (sign * magnitude).clamp(lo, hi)
                } else {
                    uniform
                };
            }
        });
        rows
    }

    /// `count` canonical rows around the canonical `center`: the center
    /// itself, then draws within 2 % of the box's width of it on each free
    /// coordinate (within a factor 10^±0.2 on those that span decades),
    /// clamped into the box, row `r` from `streams.row(r)`. A warm start's
    /// first population: the basin it starts in, not the whole box.
    pub fn cloud(&self, center: &[f64], count: usize, streams: &Streams) -> Population<Params> {
        self.embed(self.cloud_rows(center, count, streams).rows())
    }

    /// [`Space::cloud`]'s rows in free coordinates, as the optimizers see
    /// them.
    pub fn cloud_rows(
        &self,
        center: &[f64],
        count: usize,
        streams: &Streams,
    ) -> Population<Coords> {
        let free = self.free();
        let z0 = self.project_one(center);
        let mut rows = Population::zeros(count, self.free_dim());
        rows.par_iter_mut().enumerate().for_each(|(r, row)| {
            let mut rng = streams.row(r);
            for ((v, &i), &c) in row.iter_mut().zip(&free).zip(&z0) {
                let (lo, hi) = (self.lower[i], self.upper[i]);
                let step = 2.0 * rng.random::<f64>() - 1.0;
                let v_new = match (r, self.decades[i] && c != 0.0) {
                    (0, _) => c,
                    (_, true) => c * 10f64.powf(0.2 * step),
                    (_, false) => c + 0.02 * (hi - lo) * step,
                };
                *v = v_new.clamp(lo, hi);
            }
        });
        rows
    }

    pub fn dim(&self) -> usize {
        self.lower.len()
    }

    /// Entries of a row of the optimizers' coordinates: the free ones, or a
    /// placeholder where every coordinate is held.
    pub fn free_dim(&self) -> usize {
        self.free().len().max(1)
    }

    /// Indices of the coordinates the optimizers move.
    pub fn free(&self) -> Vec<usize> {
        (0..self.dim())
            .filter(|&i| self.lower[i] != self.upper[i])
            .collect()
    }

    /// The box of the free coordinates, in the optimizers' coordinates.
    pub fn bounds(&self) -> Bounds {
        let free = self.free();
        Bounds {
            lower: free.iter().map(|&i| self.lower[i]).collect(),
            upper: free.iter().map(|&i| self.upper[i]).collect(),
            names: free.iter().map(|&i| self.names[i].clone()).collect(),
        }
    }

    /// Canonical rows from rows of the optimizers' coordinates (the held
    /// coordinates at their value).
    pub fn embed(&self, rows: Rows<'_, Coords>) -> Population<Params> {
        let mut out = Population::zeros(rows.len(), self.dim());
        self.embed_into(rows, &mut out);
        out
    }

    /// [`Space::embed`] written into `out` (as many rows), row by row in
    /// parallel, with no allocation a row: what the engine scores every
    /// generation.
    pub fn embed_into(&self, rows: Rows<'_, Coords>, out: &mut Population<Params>) {
        assert_eq!(rows.len(), out.len());
        self.embed_at(rows, out, 0);
    }

    /// [`Space::embed_into`] into `out`'s rows from `at` on: a part of a
    /// generation's buffer.
    pub fn embed_at(&self, rows: Rows<'_, Coords>, out: &mut Population<Params>, at: usize) {
        let free = self.free();
        assert_eq!(
            (rows.dim(), out.dim()),
            (self.free_dim(), self.dim()),
            "rows of another box"
        );
        let dim = out.dim();
        out.span_mut(at, rows.len())
            .par_chunks_exact_mut(dim)
            .zip(rows.par_iter())
            .for_each_init(
                || self.lower.clone(),
                |z, (theta, row)| {
                    for (&v, &i) in row.iter().zip(&free) {
                        z[i] = v.clamp(self.lower[i], self.upper[i]);
                    }
                    match &self.coords {
                        Some(chart) => chart.to_canonical_into(z, theta),
                        None => theta.copy_from_slice(z),
                    }
                },
            );
    }

    /// The names of the canonical parameters the engine reports (what
    /// [`Space::embed`] returns): the chart's where there is one, else the
    /// coordinates' own names.
    pub fn canonical_names(&self) -> Vec<String> {
        match &self.coords {
            Some(chart) => chart.canonical_names(&self.names),
            None => self.names.clone(),
        }
    }

    /// The full search coordinates of a canonical vector.
    fn coordinates(&self, canonical: &[f64]) -> Vec<f64> {
        match &self.coords {
            Some(chart) => chart.coordinates_of(canonical),
            None => canonical.to_vec(),
        }
    }

    /// The optimizers' coordinates of canonical rows.
    pub fn project(&self, canonical: Rows<'_, Params>) -> Population<Coords> {
        let flat = canonical
            .iter()
            .flat_map(|row| self.project_one(row))
            .collect();
        Population::new(flat, self.free_dim())
    }

    /// The optimizers' coordinates of one canonical vector.
    pub fn project_one(&self, theta: &[f64]) -> Vec<f64> {
        let z = self.coordinates(theta);
        let free = self.free();
        if free.is_empty() {
            // The placeholder entry of a box with nothing free.
            return vec![0.0];
        }
        free.iter().map(|&i| z[i]).collect()
    }

    /// The first held coordinate (its bounds equal) at which the canonical
    /// `theta` lies elsewhere than where the box holds it, with its value
    /// there: [`Space::project_one`] leaves it out, so the coordinates it
    /// returns stand for `theta` with the hold in its place. Within a
    /// relative 10⁻⁹, the rounding of a chart's round trip.
    pub fn off_hold(&self, theta: &[f64]) -> Option<(usize, f64)> {
        let z = self.coordinates(theta);
        (0..self.dim())
            .filter(|&i| self.lower[i] == self.upper[i])
            .find(|&i| {
                let hold = self.lower[i];
                let off = (z[i] - hold).abs();
                // NaN is elsewhere too.
                off.is_nan() || off > 1e-9 * hold.abs().max(1.0)
            })
            .map(|i| (i, z[i]))
    }

    /// The free coordinates of the canonical `theta` that sit on a bound of
    /// the box, with the coordinate's index and the bound: a fit that ends
    /// there was stopped by the box, not by the data.
    pub fn on_edge(&self, theta: &[f64]) -> Vec<(usize, Side)> {
        self.near_edge(theta, 1e-6)
    }

    /// The free coordinates of the canonical `theta` within `share` of the
    /// box's width of one of its bounds, with the coordinate's index and the
    /// bound. A coordinate that spans decades is near its lower edge only
    /// on the scale of its smallest drawn values, and near its upper edge
    /// within `share` of that edge's value.
    pub fn near_edge(&self, theta: &[f64], share: f64) -> Vec<(usize, Side)> {
        let theta = self.coordinates(theta);
        self.free()
            .into_iter()
            .filter_map(|i| {
                let width = self.upper[i] - self.lower[i];
                let (below, above) = if self.decades[i] {
                    (
                        share * 10f64.powf(-self.drawn_decades) * width,
                        share * self.upper[i].abs().max(self.lower[i].abs()),
                    )
                } else {
                    (share * width, share * width)
                };
                if theta[i] - self.lower[i] <= below {
                    Some((i, Side::Lower))
                } else if self.upper[i] - theta[i] <= above {
                    Some((i, Side::Upper))
                } else {
                    None
                }
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn embed_and_project_hold_fixed_coordinates() {
        let space = Space::new(
            vec![0.0, 1.0, -0.5],
            vec![2.0, 1.0, 0.5],
            vec!["A".into(), "n".into(), "beta".into()],
        );
        assert_eq!(space.free(), vec![0, 2]);
        let theta = [0.7, 1.0, -0.003];
        let z = space.project(Rows::new(&theta, 3));
        assert_eq!((z.len(), z.dim()), (1, 2));
        let back = space.embed(z.rows());
        assert_eq!(back.rows().row(0), theta);
        assert_eq!(space.bounds().lower, vec![0.0, -0.5]);
        // Only a held coordinate's own value is off its hold; a free one
        // anywhere, and rounding of the hold, are not.
        assert_eq!(space.off_hold(&theta), None);
        assert_eq!(space.off_hold(&[9.0, 1.0 + 1e-12, 0.4]), None);
        assert_eq!(space.off_hold(&[0.7, 1.5, -0.003]), Some((1, 1.5)));
        let nan = space.off_hold(&[0.7, f64::NAN, -0.003]);
        assert!(nan.is_some_and(|(i, v)| i == 1 && v.is_nan()));
    }

    #[test]
    fn a_warm_start_cloud_starts_at_its_center_and_stays_near_it() {
        use crate::optim::stage::Stage;
        let space = Space::new(
            vec![0.0, 1.0, 0.0],
            vec![10.0, 1.0, 1000.0],
            vec!["x".into(), "n".into(), "shape".into()],
        )
        .with_decades([2]);
        let center = [4.0, 1.0, 0.5];
        let rows = space.cloud(&center, 50, &Streams::new(7, Stage::FreeRun, 0));
        let rows = rows.rows();
        assert_eq!((rows.len(), rows.dim()), (50, 3));
        assert_eq!(rows.row(0), &center);
        for row in rows.iter() {
            assert!((row[0] - 4.0).abs() <= 0.2, "{row:?}");
            assert_eq!(row[1], 1.0);
            assert!((0.5 / 1.6..=0.5 * 1.6).contains(&row[2]), "{row:?}");
        }
        assert!(rows.iter().skip(1).all(|r| r != center));
    }

    #[test]
    fn draws_stay_in_the_box_and_half_reach_the_decades_near_zero() {
        use crate::optim::stage::Stage;
        let space = Space::new(
            vec![0.0, -0.5],
            vec![2.0, 0.5],
            vec!["A".into(), "beta".into()],
        )
        .with_decades([1]);
        let draw = |seed| space.draw(1000, &Streams::new(seed, Stage::Global, 0));
        let rows = draw(3);
        assert_eq!(rows, draw(3));
        assert_eq!((rows.len(), rows.dim()), (1000, 2));
        let (mut small_a, mut small_beta) = (0, 0);
        for row in rows.rows().iter() {
            assert!((0.0..=2.0).contains(&row[0]) && (-0.5..=0.5).contains(&row[1]));
            small_a += usize::from(row[0] < 2e-3);
            small_beta += usize::from(row[1].abs() < 5e-3);
        }
        // Uniform: about 1 in 1000 below 1e-3 of the box. Half the rows draw
        // coordinate 1 over four decades, a quarter of them within the lowest two.
        assert!(small_a < 10, "{small_a}");
        assert!(small_beta > 200, "{small_beta}");
    }
}
