//! The box a fit searches, and the coordinates the optimizers move in.

use rand::RngExt;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use super::super::Bounds;
use crate::model::SearchSpace;

/// The box of a fit over canonical vectors; a coordinate whose bounds are
/// equal is held there and never shown to the optimizers.
///
/// The optimizers see the free coordinates as they are. A log scale for the
/// loop-shape parameters (β, γ are often 10⁻³ in a box of ±0.5) as
/// coordinates does worse (docs/ARCHITECTURE.md, "Half the first population
/// draws β, γ log-uniformly"); what helps is drawing half the first
/// population's values of those parameters log-uniformly ([`Space::draw`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Space {
    pub lower: Vec<f64>,
    pub upper: Vec<f64>,
    pub names: Vec<String>,
    /// Coordinates whose plausible values span decades below the box's
    /// edge (canonical indices).
    #[serde(default)]
    pub decades: Vec<bool>,
}

/// Decades below the box's edge that a log-uniform draw spans.
const DRAWN_DECADES: f64 = 4.0;

impl Space {
    pub fn new(lower: Vec<f64>, upper: Vec<f64>, names: Vec<String>) -> Space {
        let decades = vec![false; lower.len()];
        Space {
            lower,
            upper,
            names,
            decades,
        }
    }

    /// Marks the coordinates `indices` as spanning decades (see [`Space::draw`]).
    pub fn with_decades(mut self, indices: impl IntoIterator<Item = usize>) -> Space {
        for i in indices {
            self.decades[i] = true;
        }
        self
    }

    /// `count` random rows of free coordinates: uniform over the box, except
    /// that every other row draws the coordinates marked as spanning decades
    /// log-uniformly in magnitude over four decades below the box's larger
    /// edge (either sign where the box has both). A uniform draw almost never
    /// visits the sliver near zero where a muscle's β and γ often lie (as
    /// the shipped stair's hysteretic fits do: docs/RESULTS.md, "The shipped
    /// stair"), and neither do the differences of uniform draws that DE
    /// steps by.
    pub fn draw(&self, count: usize, rng: &mut ChaCha8Rng) -> Vec<f64> {
        let free = self.free();
        let mut rows = Vec::with_capacity(count * free.len());
        for r in 0..count {
            for &i in &free {
                let (lo, hi) = (self.lower[i], self.upper[i]);
                let uniform = lo + rng.random::<f64>() * (hi - lo);
                rows.push(if r % 2 == 1 && self.decades[i] {
                    let magnitude =
                        hi.abs().max(lo.abs()) * 10f64.powf(-DRAWN_DECADES * rng.random::<f64>());
                    let sign = if lo < 0.0 && (hi <= 0.0 || rng.random::<bool>()) {
                        -1.0
                    } else {
                        1.0
                    };
                    (sign * magnitude).clamp(lo, hi)
                } else {
                    uniform
                });
            }
        }
        rows
    }

    pub fn dim(&self) -> usize {
        self.lower.len()
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
    pub fn embed(&self, rows: &[f64]) -> Vec<f64> {
        let free = self.free();
        let nf = free.len().max(1);
        let mut out = Vec::with_capacity(rows.len() / nf * self.dim());
        for row in rows.chunks_exact(nf) {
            let start = out.len();
            out.extend_from_slice(&self.lower);
            for (k, &i) in free.iter().enumerate() {
                out[start + i] = row[k].clamp(self.lower[i], self.upper[i]);
            }
        }
        out
    }

    /// The optimizers' coordinates of canonical rows.
    pub fn project(&self, canonical: &[f64]) -> Vec<f64> {
        let free = self.free();
        canonical
            .chunks_exact(self.dim().max(1))
            .flat_map(|row| free.iter().map(|&i| row[i]).collect::<Vec<_>>())
            .collect()
    }

    /// The free coordinates of `theta` that sit on a bound of the box,
    /// with the bound (`"lower"` or `"upper"`): a fit that ends there was
    /// stopped by the box, not by the data.
    pub fn on_edge(&self, theta: &[f64]) -> Vec<(String, &'static str)> {
        self.free()
            .into_iter()
            .filter_map(|i| {
                let width = self.upper[i] - self.lower[i];
                let near = |b: f64| (theta[i] - b).abs() <= 1e-6 * width;
                if near(self.lower[i]) {
                    Some((self.names[i].clone(), "lower"))
                } else if near(self.upper[i]) {
                    Some((self.names[i].clone(), "upper"))
                } else {
                    None
                }
            })
            .collect()
    }
}

impl From<&SearchSpace> for Space {
    /// The loop-shape parameters (β, γ or β1…β6, between α and n) span decades.
    fn from(s: &SearchSpace) -> Space {
        let shape = 2..s.family.exponent_index().unwrap_or(2);
        Space::new(
            s.lower.clone(),
            s.upper.clone(),
            s.family.params().iter().map(|p| p.name.into()).collect(),
        )
        .with_decades(shape)
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
        let z = space.project(&theta);
        assert_eq!(z.len(), 2);
        let back = space.embed(&z);
        assert_eq!(back[1], 1.0);
        assert_eq!(back, theta);
        assert_eq!(space.bounds().lower, vec![0.0, -0.5]);
    }

    #[test]
    fn draws_stay_in_the_box_and_half_reach_the_decades_near_zero() {
        use rand::SeedableRng;
        let space = Space::new(
            vec![0.0, -0.5],
            vec![2.0, 0.5],
            vec!["A".into(), "beta".into()],
        )
        .with_decades([1]);
        let draw = |seed| space.draw(1000, &mut ChaCha8Rng::seed_from_u64(seed));
        let rows = draw(3);
        assert_eq!(rows, draw(3));
        assert_eq!(rows.len(), 2000);
        let (mut small_a, mut small_beta) = (0, 0);
        for row in rows.chunks(2) {
            assert!((0.0..=2.0).contains(&row[0]) && (-0.5..=0.5).contains(&row[1]));
            small_a += usize::from(row[0] < 2e-3);
            small_beta += usize::from(row[1].abs() < 5e-3);
        }
        // Uniform: about 1 in 1000 below 1e-3 of the box. Half the rows draw
        // β over four decades, a quarter of them within the lowest two.
        assert!(small_a < 10, "{small_a}");
        assert!(small_beta > 200, "{small_beta}");
    }
}
