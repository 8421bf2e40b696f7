//! The search box of a fit: bounds on every canonical parameter, where a
//! parameter whose lower and upper bounds are equal is held fixed.

use serde::{Deserialize, Serialize};

use super::family::Family;
use super::presets::{ThesisBounds, hysteresis_hull};

/// How the linear part is treated during a fit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Flow {
    /// `a`, `b` and the intercept `c` are fitted with the hysteresis
    /// parameters (the default: least squares on hysteretic data does not
    /// return the hysteretic model's `a`, `b`, and mean removal leaves an offset).
    #[default]
    Joint,
    /// The thesis' flow: `a`, `b` fixed at the ARX estimate, no intercept.
    Thesis,
}

/// Bounds on a canonical parameter vector.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SearchSpace {
    pub family: Family,
    pub lower: Vec<f64>,
    pub upper: Vec<f64>,
}

/// What the data say about scale, for the bounds of the linear part.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinearPrior {
    /// ARX pole and gain (eq. 12) on the estimation data.
    pub a: f64,
    pub b: f64,
    /// Largest absolute input and output in the data's own units (before mean
    /// removal): the intercept can be no larger than what they can produce.
    pub max_abs_input: f64,
    pub max_abs_output: f64,
    /// Range (max − min) of the output: the scale of the start offset's box.
    pub output_range: f64,
}

impl SearchSpace {
    /// The default box: the thesis' hysteresis bounds (hull of its runs, or
    /// the given table), `n` fixed at 1 unless `free_n` (then `[1, 3]`), and
    /// the linear part per `flow` around the ARX estimate.
    ///
    /// Joint flow: with `s = 1 − a_ARX`, `a` from `min(a_ARX − 10 s, 0.8)`
    /// to `max(a_ARX + 3 s, 1.05)`, within `[0, 1.2]` (the ARX pole is the
    /// hysteretic model's *effective* pole `a·(α + (1 − α)·A)`, which a fast
    /// `a·α` with a slow hysteretic feedback gives as well as a slow `a·α`:
    /// the thesis' own Table 1 has α = 0.5), `b` within a factor 5 of the
    /// ARX gain, `|c| ≤ |b_ARX|·max|p| + max|l|`, and the start offset
    /// `x0` within 5 % of the output range (many times the noise of any
    /// usable record; the thesis' flow holds it at 0).
    pub fn around(
        family: Family,
        hysteresis: Option<&ThesisBounds>,
        prior: LinearPrior,
        flow: Flow,
        free_n: bool,
    ) -> SearchSpace {
        let d = family.dim();
        let mut lower = vec![0.0; d];
        let mut upper = vec![0.0; d];
        if family != Family::Linear {
            let hull = hysteresis_hull(family).expect("hysteretic family");
            let h = hysteresis.unwrap_or(&hull);
            let nh = h.lower.len();
            lower[..nh].copy_from_slice(&h.lower);
            upper[..nh].copy_from_slice(&h.upper);
            let ni = family.exponent_index().expect("hysteretic family has n");
            lower[ni] = 1.0;
            upper[ni] = if free_n { 3.0 } else { 1.0 };
        }
        let [ia, ib, ic] = family.linear_indices();
        let ix = family.start_index();
        match flow {
            Flow::Thesis => {
                (lower[ia], upper[ia]) = (prior.a, prior.a);
                (lower[ib], upper[ib]) = (prior.b, prior.b);
                (lower[ic], upper[ic]) = (0.0, 0.0);
                (lower[ix], upper[ix]) = (0.0, 0.0);
            }
            Flow::Joint => {
                let s = (1.0 - prior.a).abs().max(1e-3);
                lower[ia] = (prior.a - 10.0 * s).clamp(0.0, 0.8);
                upper[ia] = (prior.a + 3.0 * s).clamp(1.05, 1.2);
                let (b1, b2) = (prior.b / 5.0, prior.b * 5.0);
                (lower[ib], upper[ib]) = (b1.min(b2), b1.max(b2));
                let cmax = prior.b.abs() * prior.max_abs_input + prior.max_abs_output;
                (lower[ic], upper[ic]) = (-cmax, cmax);
                let xmax = 0.05 * prior.output_range;
                (lower[ix], upper[ix]) = (-xmax, xmax);
            }
        }
        SearchSpace {
            family,
            lower,
            upper,
        }
    }

    pub fn dim(&self) -> usize {
        self.lower.len()
    }

    /// Indices of the parameters the optimizer moves.
    pub fn free(&self) -> Vec<usize> {
        (0..self.dim())
            .filter(|&i| self.lower[i] != self.upper[i])
            .collect()
    }

    /// Whether `theta` lies inside the box.
    pub fn contains(&self, theta: &[f64]) -> bool {
        theta.len() == self.dim()
            && theta
                .iter()
                .zip(self.lower.iter().zip(&self.upper))
                .all(|(v, (l, u))| l <= v && v <= u)
    }

    /// Clamps `theta` into the box; returns whether anything moved.
    pub fn clamp(&self, theta: &mut [f64]) -> bool {
        let mut moved = false;
        for (v, (l, u)) in theta.iter_mut().zip(self.lower.iter().zip(&self.upper)) {
            let c = v.clamp(*l, *u);
            moved |= c != *v;
            *v = c;
        }
        moved
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn prior() -> LinearPrior {
        LinearPrior {
            a: 0.9618,
            b: 24.9366,
            max_abs_input: 0.4,
            max_abs_output: 40.0,
            output_range: 30.0,
        }
    }

    #[test]
    fn thesis_flow_fixes_the_linear_part() {
        let s = SearchSpace::around(Family::Classic, None, prior(), Flow::Thesis, false);
        assert_eq!(s.free(), vec![0, 1, 2, 3]);
        assert_eq!(s.lower[5], 0.9618);
        assert_eq!(s.upper[7], 0.0);
        assert_eq!(s.upper[8], 0.0);
    }

    #[test]
    fn joint_flow_frees_a_b_c_around_the_arx_estimate() {
        let s = SearchSpace::around(Family::Generalized, None, prior(), Flow::Joint, true);
        assert_eq!(s.free(), (0..13).collect::<Vec<_>>());
        let [ia, ib, ic] = Family::Generalized.linear_indices();
        assert!(s.lower[ia] < 0.9618 && 0.9618 < s.upper[ia]);
        assert!(s.lower[ib] < 24.9366 && 24.9366 < s.upper[ib]);
        assert!(s.lower[ic] < 0.0 && 0.0 < s.upper[ic]);
        let mut theta = s.upper.clone();
        theta[0] += 1.0;
        assert!(!s.contains(&theta));
        assert!(s.clamp(&mut theta));
        assert!(s.contains(&theta));
    }
}
