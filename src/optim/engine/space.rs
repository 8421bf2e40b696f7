//! The box a fit searches, and the coordinates the optimizers move in.

use serde::{Deserialize, Serialize};

use super::super::Bounds;
use crate::model::SearchSpace;

/// The box of a fit over canonical vectors; a coordinate whose bounds are
/// equal is held there and never shown to the optimizers.
///
/// The optimizers see the free coordinates as they are. A log scale for the
/// loop-shape parameters (β, γ are often 10⁻³ in a box of ±0.5) was tried
/// and measured worse on the generated cases (docs/RESULTS.md): the
/// prediction-error stage finds their size without help.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Space {
    pub lower: Vec<f64>,
    pub upper: Vec<f64>,
    pub names: Vec<String>,
}

impl Space {
    pub fn new(lower: Vec<f64>, upper: Vec<f64>, names: Vec<String>) -> Space {
        Space {
            lower,
            upper,
            names,
        }
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
    fn from(s: &SearchSpace) -> Space {
        Space::new(
            s.lower.clone(),
            s.upper.clone(),
            s.family.params().iter().map(|p| p.name.into()).collect(),
        )
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
}
