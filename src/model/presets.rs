//! The thesis' numbers: the identified linear model (eq. 10–12), the
//! trial-and-error parameters (tables 1 and 2) and the bounds of the
//! optimizer runs (tables 5, 9, 11, 13, 17, 19).

use super::family::Family;

/// Eq. 10–12: the first-order ARX model the thesis identified.
pub const THESIS_A: f64 = 0.9618;
pub const THESIS_B: f64 = 24.9366;

/// The thesis' trial-and-error parameters (Table 1 classic, Table 2
/// generalized) with the linear part of eq. 12, no intercept and no start
/// offset, as a canonical vector of `family`. The thesis writes its model in
/// deviation coordinates, so its generalized sign terms switch at the
/// output mean: `x_s = 0` for data whose output mean is 0 (`simulate`
/// without a model file).
pub fn thesis_params(family: Family) -> Vec<f64> {
    match family {
        Family::Linear => vec![THESIS_A, THESIS_B, 0.0, 0.0],
        // Table 1: α 0.5, A 0.9, β 0.002, γ −0.001, n 1.
        Family::Classic => vec![0.9, 0.5, 0.002, -0.001, 1.0, THESIS_A, THESIS_B, 0.0, 0.0],
        // Table 2: α 0.9, A 1, n 1, β1..β6 = 0.01, 0.005, 0.1, −0.01, −0.1, 0.001.
        Family::Generalized => {
            vec![
                1.0, 0.9, 0.01, 0.005, 0.1, -0.01, -0.1, 0.001, 1.0, 0.0, THESIS_A, THESIS_B, 0.0,
                0.0,
            ]
        }
    }
}

/// Which of the thesis' optimizer runs a set of bounds belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ThesisRun {
    Ga,
    Mfa,
    Pso,
}

/// Bounds on the hysteresis parameters (the thesis' `d`-vector: classic
/// `[A, α, β, γ]`, generalized `[A, α, β1..β6]`) of one thesis run.
#[derive(Debug, Clone, PartialEq)]
pub struct ThesisBounds {
    /// The table the numbers come from.
    pub table: u8,
    pub lower: Vec<f64>,
    pub upper: Vec<f64>,
}

/// The bounds of tables 5, 9, 11 (classic) and 13, 17, 19 (generalized).
/// `None` for the linear family, which the thesis fits by least squares.
pub fn thesis_bounds(family: Family, run: ThesisRun) -> Option<ThesisBounds> {
    let b = |table, lower: &[f64], upper: &[f64]| {
        Some(ThesisBounds {
            table,
            lower: lower.to_vec(),
            upper: upper.to_vec(),
        })
    };
    let m = -0.1;
    match (family, run) {
        (Family::Linear, _) => None,
        (Family::Classic, ThesisRun::Ga) => b(5, &[0.5, 0.5, -0.5, -0.1], &[1.0, 0.99, 0.5, 0.1]),
        (Family::Classic, ThesisRun::Mfa) => b(9, &[0.0, 0.5, -0.5, -0.5], &[2.0, 0.99, 0.5, 0.5]),
        (Family::Classic, ThesisRun::Pso) => b(11, &[0.0, 0.0, -0.5, -0.5], &[2.0, 0.9, 0.5, 0.5]),
        (Family::Generalized, ThesisRun::Ga) => b(
            13,
            &[0.0, 0.5, m, m, m, m, m, m],
            &[2.0, 0.99, 0.5, 0.5, 0.5, 0.5, 0.5, 1.0],
        ),
        (Family::Generalized, ThesisRun::Mfa) => b(
            17,
            &[0.0, 0.7, m, m, m, m, m, m],
            &[1.5, 1.0, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5],
        ),
        (Family::Generalized, ThesisRun::Pso) => b(
            19,
            &[0.0, 0.0, m, m, m, m, m, m],
            &[2.0, 0.9, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0],
        ),
    }
}

/// The hull of the three thesis runs' bounds: the default hysteresis box when
/// no thesis run is asked for.
pub fn hysteresis_hull(family: Family) -> Option<ThesisBounds> {
    let runs = [ThesisRun::Ga, ThesisRun::Mfa, ThesisRun::Pso];
    let all: Vec<ThesisBounds> = runs
        .iter()
        .filter_map(|&r| thesis_bounds(family, r))
        .collect();
    let first = all.first()?;
    let d = first.lower.len();
    let lower = (0..d)
        .map(|i| all.iter().map(|b| b.lower[i]).fold(f64::INFINITY, f64::min))
        .collect();
    let upper = (0..d)
        .map(|i| {
            all.iter()
                .map(|b| b.upper[i])
                .fold(f64::NEG_INFINITY, f64::max)
        })
        .collect();
    Some(ThesisBounds {
        table: 0,
        lower,
        upper,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_have_canonical_length() {
        for f in Family::ALL {
            assert_eq!(thesis_params(f).len(), f.dim());
        }
    }

    #[test]
    fn bounds_are_ordered_and_sized() {
        for f in [Family::Classic, Family::Generalized] {
            for r in [ThesisRun::Ga, ThesisRun::Mfa, ThesisRun::Pso] {
                let b = thesis_bounds(f, r).unwrap();
                assert_eq!(b.lower.len(), f.exponent_index().unwrap(), "{f} {r:?}");
                assert!(
                    b.lower.iter().zip(&b.upper).all(|(l, u)| l < u),
                    "{f} {r:?}"
                );
            }
        }
        let hull = hysteresis_hull(Family::Classic).unwrap();
        assert_eq!(hull.lower, vec![0.0, 0.0, -0.5, -0.5]);
        assert_eq!(hull.upper, vec![2.0, 0.99, 0.5, 0.5]);
    }
}
