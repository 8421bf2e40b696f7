//! Model families and their canonical parameter vectors.
//!
//! Every family has one fixed layout that the CPU simulation, the WGSL shaders
//! and the optimizers share. The hysteresis parameters come first in the
//! thesis' order, then the Bouc-Wen exponent `n` (and, for the generalized
//! family, the switching level `x_s` of its sign terms in `x`), then the
//! linear part `a, b`, the intercept `c` (see `docs/ARCHITECTURE.md`, "the
//! intercept") and the start offset `x0` ("the initial state").

use serde::{Deserialize, Serialize};
use std::fmt;
use std::str::FromStr;

use crate::names::UnknownName;

/// A dynamic model family of the thesis.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Family {
    /// First-order ARX, eq. 12 plus an intercept: x(k) = a·x(k−1) + b·u(k−1) + c.
    Linear,
    /// Eq. 13 with the classic Bouc-Wen state (eq. 20, corrected).
    Classic,
    /// Eq. 13 with the generalized (Song & Der Kiureghian) state (eq. 23, corrected).
    Generalized,
}

/// Name, symbol and meaning of one parameter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParamInfo {
    /// ASCII name used in flags, JSON and CSV headers.
    pub name: &'static str,
    /// Symbol as the thesis writes it.
    pub symbol: &'static str,
    pub meaning: &'static str,
}

const fn p(name: &'static str, symbol: &'static str, meaning: &'static str) -> ParamInfo {
    ParamInfo {
        name,
        symbol,
        meaning,
    }
}

/// The start offset, last in every layout.
const START: ParamInfo = p(
    "x0",
    "x₀",
    "start of the free run less the first measured output (output units): that sample's noise",
);

const LINEAR: [ParamInfo; 4] = [
    p("a", "a", "pole of the linear part"),
    p(
        "b",
        "b",
        "input gain of the linear part (output units per input unit)",
    ),
    p(
        "c",
        "c",
        "intercept: the offset that mean removal leaves (output units)",
    ),
    START,
];

const CLASSIC: [ParamInfo; 9] = [
    p("A", "A", "Bouc-Wen stiffness of the hysteretic state"),
    p(
        "alpha",
        "α",
        "share of the linear feedback, 1 − α goes to the hysteretic state",
    ),
    p("beta", "β", "Bouc-Wen loop-shape parameter"),
    p("gamma", "γ", "Bouc-Wen loop-shape parameter"),
    p("n", "n", "Bouc-Wen exponent (1 in the thesis)"),
    LINEAR[0],
    LINEAR[1],
    LINEAR[2],
    START,
];

const GENERALIZED: [ParamInfo; 14] = [
    p("A", "A", "Bouc-Wen stiffness of the hysteretic state"),
    p(
        "alpha",
        "α",
        "share of the linear feedback, 1 − α goes to the hysteretic state",
    ),
    p("beta1", "β1", "weight of sgn(Δ·w)"),
    p("beta2", "β2", "weight of sgn(Δ·(x − x_s))"),
    p("beta3", "β3", "weight of sgn((x − x_s)·w)"),
    p("beta4", "β4", "weight of sgn(Δ)"),
    p("beta5", "β5", "weight of sgn(w)"),
    p("beta6", "β6", "weight of sgn(x − x_s)"),
    p("n", "n", "Bouc-Wen exponent (1 in the thesis)"),
    p(
        "x_s",
        "x_s",
        "output level where the sign terms in x switch, in the output's own units (the model's \
         x is the output less its estimation mean ȳ: they switch at x = x_s − ȳ)",
    ),
    LINEAR[0],
    LINEAR[1],
    LINEAR[2],
    START,
];

impl Family {
    pub const ALL: [Family; 3] = [Family::Linear, Family::Classic, Family::Generalized];

    /// The canonical parameter vector's entries, in order.
    pub fn params(self) -> &'static [ParamInfo] {
        match self {
            Family::Linear => &LINEAR,
            Family::Classic => &CLASSIC,
            Family::Generalized => &GENERALIZED,
        }
    }

    /// Length of the canonical parameter vector.
    pub fn dim(self) -> usize {
        self.params().len()
    }

    /// Position of a parameter in the canonical vector.
    pub fn index_of(self, name: &str) -> Option<usize> {
        self.params().iter().position(|p| p.name == name)
    }

    /// Positions of the linear part `a`, `b`, `c` (before the start offset).
    pub fn linear_indices(self) -> [usize; 3] {
        let d = self.dim();
        [d - 4, d - 3, d - 2]
    }

    /// Position of the start offset `x0` (the last entry).
    pub fn start_index(self) -> usize {
        self.dim() - 1
    }

    /// Position of the Bouc-Wen exponent `n`, if the family has one.
    pub fn exponent_index(self) -> Option<usize> {
        self.index_of("n")
    }

    /// Why `n` cannot be this family's Bouc-Wen exponent, if it cannot: at
    /// `n ≤ 0` the term `|w|ⁿ` no longer vanishes with `w` (it jumps at
    /// zero, or grows without bound near it), which is no hysteresis loop;
    /// `--free-n` searches `[1, 3]`.
    pub fn exponent_refused(n: f64) -> Option<String> {
        (n.is_nan() || n <= 0.0).then(|| {
            format!(
                "the Bouc-Wen exponent n must be positive (got {n}): at n ≤ 0 the term |w|^n \
                 does not vanish with w; fits search n in [1, 3] (--free-n)"
            )
        })
    }

    /// Position of the switching level `x_s` of the sign terms in `x`, if
    /// the family has them (the generalized one: right after `n`).
    pub fn switch_index(self) -> Option<usize> {
        self.index_of("x_s")
    }

    /// Whether the Bouc-Wen loop of `theta` stays bounded under every input.
    /// Classic: `β + γ ≥ 0` (for A > 0; n = 1 or not), the condition of
    /// Ikhouane, Mañosa and Rodellar ("Dynamic properties of the hysteretic
    /// Bouc-Wen model", Systems & Control Letters 56, 2007) under which `w`
    /// cannot grow past `(A/(β+γ))^(1/n)`; with `β + γ < 0` it grows without
    /// bound once the motion keeps one direction long enough. Without a loop
    /// (`A = 0`) nothing grows. The generalized model's sign terms admit
    /// truths outside any such simple condition (the generated cases draw
    /// them), so it is always admitted here and checked by simulation
    /// instead ([`crate::fit::problem::FitProblem::stress`]).
    pub fn loop_bounded(self, theta: &[f64]) -> bool {
        match self {
            Family::Classic => theta[0] == 0.0 || theta[2] + theta[3] >= 0.0,
            Family::Linear | Family::Generalized => true,
        }
    }

    /// The largest step of the output in one sample (output units) within
    /// which the discrete hysteresis update of `theta` neither overshoots
    /// its saturation nor flips past it, or `None` where no branch of the
    /// loop bends toward a bound or away from one (the linear family,
    /// `A ≤ 0`, `n ≤ 0`).
    ///
    /// The update is an explicit step, `w' = w + Δ·(A − Ψ·|w|^n)`
    /// ([`crate::model::sim::classic_w`], [`crate::model::sim::generalized_w`]),
    /// whose factor on `w` is `1 − |Δ|·n·κ·|w|^(n−1)` along a branch with
    /// `κ|w|^n` the pull on `|w|`:
    ///
    /// - on a loading branch (`Δ` and `w` of one sign) `κ = Ψ > 0` moves
    ///   `w` toward its saturation `w* = (A/Ψ)^(1/n)`;
    /// - on an unloading branch `κ = −Ψ > 0` (a branch steeper than `A`,
    ///   as the bounded class's `β ≥ 0` makes the classic one) drives `w`
    ///   back through zero, from at most the loading saturation of its
    ///   sign (`w*`; at `n = 1` the factor is the same at every `|w|`).
    ///
    /// Past `|Δ| = 2/(n·κ·w*^(n−1))` (`2/κ` at `n = 1`) the factor is below
    /// −1: each step throws `w` further past where the continuous model
    /// would take it than the last, and a record that turns back and forth
    /// at such steps pumps it without bound, though the continuous model's
    /// loop is bounded. A model fitted on a record that moves a little each
    /// sample can hold this close to the steps it saw; another record, or
    /// a start far from its own rest, may step further.
    ///
    /// The classic loading branch has `Ψ = β + γ`, its unloading one
    /// `γ − β`; the generalized loading one
    /// `β1 + (β2 + β3)·d·q + (β4 + β5)·d + β6·q` for each sign `d` of `w`
    /// and side `q` of the switching level, its unloading one that less
    /// `2·(β1 + β2·d·q + β4·d)`. The smallest step binds.
    pub fn stable_step(self, theta: &[f64]) -> Option<f64> {
        // (sign of w, loading Ψ, unloading Ψ) of each branch pair.
        let branches: Vec<(f64, f64, f64)> = match self {
            Family::Linear => return None,
            Family::Classic => {
                let (beta, gamma) = (theta[2], theta[3]);
                [1.0, -1.0]
                    .map(|d| (d, beta + gamma, gamma - beta))
                    .to_vec()
            }
            Family::Generalized => {
                let b = &theta[2..8];
                [(1.0, 1.0), (1.0, -1.0), (-1.0, 1.0), (-1.0, -1.0)]
                    .map(|(d, q)| {
                        let loading = b[0] + (b[1] + b[2]) * d * q + (b[3] + b[4]) * d + b[5] * q;
                        (d, loading, loading - 2.0 * (b[0] + b[1] * d * q + b[3] * d))
                    })
                    .to_vec()
            }
        };
        let (big_a, n) = (theta[0], theta[self.exponent_index()?]);
        if !(big_a > 0.0 && n > 0.0) {
            return None;
        }
        let saturation = |psi: f64| (big_a / psi).powf(1.0 / n);
        // The largest |w| of each sign: its loading branches' saturation,
        // unbounded where one of them does not saturate.
        let reach = |d: f64| {
            branches
                .iter()
                .filter(|b| b.0 == d)
                .map(|&(_, psi, _)| {
                    if psi > 0.0 {
                        saturation(psi)
                    } else {
                        f64::INFINITY
                    }
                })
                .fold(0.0, f64::max)
        };
        let step = |pull: f64, w_max: f64| 2.0 / (n * pull * w_max.powf(n - 1.0));
        branches
            .iter()
            .flat_map(|&(d, loading, unloading)| {
                let settling = (loading > 0.0).then(|| step(loading, saturation(loading)));
                let returning = (unloading < 0.0).then(|| step(-unloading, reach(d)));
                [settling, returning]
            })
            .flatten()
            .filter(|s| s.is_finite() && *s > 0.0)
            .reduce(f64::min)
    }

    pub fn name(self) -> &'static str {
        match self {
            Family::Linear => "linear",
            Family::Classic => "classic",
            Family::Generalized => "generalized",
        }
    }
}

impl fmt::Display for Family {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Family {
    type Err = UnknownName;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.to_ascii_lowercase().as_str() {
            "linear" | "arx" => Ok(Family::Linear),
            "classic" => Ok(Family::Classic),
            "generalized" | "generalised" => Ok(Family::Generalized),
            other => Err(UnknownName {
                what: "model family",
                got: other.to_string(),
                expected: "linear, classic or generalized".into(),
            }),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layouts_end_with_the_linear_part() {
        for f in Family::ALL {
            let names: Vec<_> = f
                .linear_indices()
                .iter()
                .map(|&i| f.params()[i].name)
                .collect();
            assert_eq!(names, ["a", "b", "c"], "{f}");
            assert_eq!(f.params()[f.start_index()].name, "x0", "{f}");
        }
        assert_eq!(Family::Classic.exponent_index(), Some(4));
        assert_eq!(Family::Generalized.exponent_index(), Some(8));
        assert_eq!(Family::Linear.exponent_index(), None);
        assert_eq!(Family::Generalized.switch_index(), Some(9));
        assert_eq!(Family::Classic.switch_index(), None);
    }

    #[test]
    fn the_classic_loop_is_bounded_when_beta_plus_gamma_is_not_negative() {
        // A, α, β, γ, n, a, b, c, x0.
        let theta =
            |big_a: f64, beta: f64, gamma: f64| [big_a, 0.5, beta, gamma, 1.0, 0.9, 1.0, 0.0, 0.0];
        assert!(Family::Classic.loop_bounded(&theta(1.0, 0.1, -0.09)));
        assert!(Family::Classic.loop_bounded(&theta(1.0, 0.0, 0.0)));
        assert!(!Family::Classic.loop_bounded(&theta(1.0, 0.08, -0.29)));
        assert!(Family::Classic.loop_bounded(&theta(0.0, 0.08, -0.29)));
        assert!(Family::Generalized.loop_bounded(&[0.0; 14]));
    }

    #[test]
    fn names_round_trip() {
        for f in Family::ALL {
            assert_eq!(f.name().parse::<Family>().unwrap(), f);
        }
        assert!(
            "bogus"
                .parse::<Family>()
                .unwrap_err()
                .to_string()
                .contains("linear, classic or generalized")
        );
    }
}
