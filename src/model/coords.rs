//! The coordinates a fit searches in: the data's own scale.
//!
//! The canonical vector (`A, α, β, γ, n, a, b, c, x0`, or `β1…β6` for the
//! generalized family) is what a model *is*; it is a poor space to search.
//! Its numbers carry the data's units (`b` in output per input unit, `β` in
//! 1/output unit), so a box that suits MPa→mm binds on psi→mm or kPa→m; and
//! its linear part is steep and correlated (`b` and `a` trade along a ridge
//! of constant static gain). The search coordinates fix both:
//!
//! | coordinate | meaning | canonical |
//! |---|---|---|
//! | `A`, `alpha`, `n`, `a` | as in the canonical vector | the same |
//! | `gain` | small-signal static gain over the ARX static gain | `b = gain·K_ARX·(1 − λ)` |
//! | `offset` | steady output shift over the output range | `c = offset·R·(1 − λ)` |
//! | `x0_range` | start offset over the output range | `x0 = x0_range·R` |
//! | `x_s` (generalized) | the switching level itself, output units | the same |
//! | loop shape | below | `β…` times `A/Rⁿ` |
//!
//! `λ = a·(α + (1 − α)·A)` is the small-signal pole (for small loops
//! `w ≈ A·x`), `K_ARX` the ARX static gain and `R` the output range, both of
//! the estimation data. Every coordinate but one is a pure number: the same
//! record in other units gives the same coordinates, the same search and the
//! same fit. The exception is the generalized switching level `x_s`, kept in
//! the output's units so that its two natural values, the sensor's zero and
//! the estimation mean, are held exactly (`--fix x_s=0`; a scaled coordinate
//! would round them). Its search does not depend on the units either: its
//! box is the output's span, and the optimizers move a coordinate by
//! fractions of its box (DE, PSO, MFA) or of its value (the GA).
//!
//! **Loop shape.** `w` saturates where its slope on a loading branch
//! vanishes, at `|w|ⁿ = A/ψ` (`ψ = β + γ` for the classic state): the
//! normalised `ψ·Rⁿ/A` is `(R/w_sat)ⁿ`, the output range over the loop's
//! saturation level, whatever the units. In [`Loop::Bounded`] coordinates the
//! box itself is the bounded class:
//!
//! - classic (Ikhouane, Mañosa & Rodellar, "Dynamic properties of the
//!   hysteretic Bouc-Wen model", Systems & Control Letters 56, 2007, classes
//!   I and II for `A > 0`): `β + γ ≥ 0` and `β ≥ 0`. The coordinates are
//!   `loading = (β + γ)·Rⁿ/A ≥ 0` and `beta_range = β·Rⁿ/A ≥ 0`. With
//!   `β < 0` the unloading slope `A − (γ − β)|w|ⁿ` is steeper than the
//!   loading one, and each small back-and-forth of the input ratchets `|w|`
//!   up by `(ψ_unload − ψ_load)·|w|ⁿ·|Δ|`: no bound holds.
//! - generalized (Song & Der Kiureghian, "Generalized Bouc-Wen model for
//!   highly asymmetric hysteresis", J. Eng. Mech. 132, 2006): on a loading
//!   branch (`sgn Δ = sgn w = s`, `t = sgn x`)
//!   `ψ(s, t) = β1 + s·t·(β2 + β3) + s·(β4 + β5) + t·β6`, and the model is
//!   bounded when all four are `≥ 0` — the condition the paper states — *and*
//!   no unloading branch is steeper than the loading one at the same signs of
//!   `w` and `x`, the generalized form of the classic `β ≥ 0` above:
//!   `ψ_load − ψ_unload = 2·(β1 + s·t·β2 + s·β4) ≥ 0` for all four, that is
//!   `|β2| + |β4| ≤ β1`. The coordinates are the four loading slopes
//!   `psi_pp, psi_pn, psi_np, psi_nn` (`s, t` = +/−) normalised as above,
//!   and `unload_u, unload_v ∈ [−1, 1]`, which place `(β2, β4)` in that
//!   diamond: `β2 = β1·(u + v)/2`, `β4 = β1·(u − v)/2`.
//!
//! [`Loop::Free`] keeps the unconstrained shapes (`beta_range = β·Rⁿ/A`,
//! `gamma_range`, or `beta1_range…beta6_range`), for hysteresis outside the
//! bounded class such as the Bouc-Wen benchmark's.

use serde::{Deserialize, Serialize};

use super::family::Family;

/// Which loop shapes a fit may take (`--loop`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Loop {
    /// The bounded (BIBO-stable) class: the loop's state stays bounded for
    /// every bounded input (the default).
    #[default]
    Bounded,
    /// Any signs of the loop-shape parameters, as in the thesis' boxes.
    Free,
}

/// What the data say about scale: the constants of the coordinate map.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Scale {
    /// Output range `R` of the estimation data (output units).
    pub range: f64,
    /// ARX static gain `K_ARX = b/(1 − a)` (output per input unit); never 0.
    pub gain: f64,
}

/// How the loop-shape parameters are searched.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ShapeCoords {
    /// The bounded class as a box (see the module's doc).
    Bounded,
    /// The canonical parameters times `Rⁿ/A`, any sign.
    Free,
    /// The canonical parameters themselves (a bound set on one of them).
    Native,
}

/// How the linear part `b, c, x0` is searched.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum LinearCoords {
    /// `gain`, `offset`, `x0_range`.
    Scaled,
    /// `b`, `c`, `x0` themselves (a bound set on `b` or `c`).
    Native,
}

/// The map between a family's canonical vectors and search coordinates
/// of the same length, entry for entry.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum Coordinates {
    /// The canonical vector itself (the thesis' flow, the diagnosis).
    Native,
    /// The data's own scale.
    Scaled {
        shape: ShapeCoords,
        linear: LinearCoords,
        scale: Scale,
    },
}

impl Coordinates {
    /// The names of the coordinates of `family` (the canonical names where
    /// the coordinates are the canonical parameters).
    pub fn names(&self, family: Family) -> Vec<String> {
        let mut names: Vec<String> = family.params().iter().map(|p| p.name.into()).collect();
        let Coordinates::Scaled { shape, linear, .. } = *self else {
            return names;
        };
        let shapes = shape_range(family);
        let shape_names: Vec<&str> = match (family, shape) {
            (_, ShapeCoords::Native) => Vec::new(),
            (Family::Classic, ShapeCoords::Bounded) => vec!["loading", "beta_range"],
            (Family::Classic, ShapeCoords::Free) => vec!["beta_range", "gamma_range"],
            (Family::Generalized, ShapeCoords::Bounded) => vec![
                "psi_pp", "psi_pn", "psi_np", "psi_nn", "unload_u", "unload_v",
            ],
            (Family::Generalized, ShapeCoords::Free) => vec![
                "beta1_range",
                "beta2_range",
                "beta3_range",
                "beta4_range",
                "beta5_range",
                "beta6_range",
            ],
            (Family::Linear, _) => Vec::new(),
        };
        for (i, name) in shapes.zip(shape_names) {
            names[i] = name.into();
        }
        if linear == LinearCoords::Scaled {
            let [_, ib, ic] = family.linear_indices();
            names[ib] = "gain".into();
            names[ic] = "offset".into();
            names[family.start_index()] = "x0_range".into();
        }
        names
    }

    /// Why `name`, a coordinate of a scaled box of `family` that these
    /// coordinates lack, is not among them (none where no box has it): a
    /// bound on a canonical parameter switches its part of the box to the
    /// canonical parameters, and the other bounds must then name those.
    pub fn switched_away(&self, family: Family, name: &str) -> Option<&'static str> {
        let scaled = |shape| Coordinates::Scaled {
            shape,
            linear: LinearCoords::Scaled,
            scale: Scale {
                range: 1.0,
                gain: 1.0,
            },
        };
        let in_a_scaled_box = [ShapeCoords::Bounded, ShapeCoords::Free]
            .into_iter()
            .any(|shape| scaled(shape).names(family).iter().any(|n| n == name));
        if !in_a_scaled_box || self.names(family).iter().any(|n| n == name) {
            return None;
        }
        let Coordinates::Scaled { shape, linear, .. } = *self else {
            return Some("this fit searches the canonical parameters themselves");
        };
        let linear_name = ["gain", "offset", "x0_range"].contains(&name);
        Some(match (linear_name, linear, shape) {
            (true, LinearCoords::Native, _) => {
                "a bound on b or c searches the linear part in b, c and x0 themselves"
            }
            (false, _, ShapeCoords::Native) => {
                "a bound on a loop-shape parameter searches the loop shape in its own parameters"
            }
            _ => "it belongs to the other loop class's box",
        })
    }

    /// The canonical vector of coordinates `z`.
    pub fn to_native(&self, family: Family, z: &[f64]) -> Vec<f64> {
        let mut theta = vec![0.0; z.len()];
        self.to_native_into(family, z, &mut theta);
        theta
    }

    /// [`Coordinates::to_native`] written into `theta` (as long as `z`): no
    /// allocation, for the engine, which maps every row of every generation.
    pub fn to_native_into(&self, family: Family, z: &[f64], theta: &mut [f64]) {
        theta.copy_from_slice(z);
        let Coordinates::Scaled {
            shape,
            linear,
            scale,
            ..
        } = *self
        else {
            return;
        };
        if family == Family::Linear {
            return;
        }
        let per = shape_factor(family, z, scale).recip();
        let s = shape_range(family).start;
        match (family, shape) {
            (_, ShapeCoords::Native) | (Family::Linear, _) => {}
            (_, ShapeCoords::Free) => {
                for i in shape_range(family) {
                    theta[i] = z[i] * per;
                }
            }
            (Family::Classic, ShapeCoords::Bounded) => {
                let (loading, beta) = (z[s], z[s + 1]);
                theta[s] = beta * per;
                theta[s + 1] = (loading - beta) * per;
            }
            (Family::Generalized, ShapeCoords::Bounded) => {
                let loading = [z[s], z[s + 1], z[s + 2], z[s + 3]];
                let betas = bounded_betas(loading, z[s + 4], z[s + 5]);
                for (k, b) in betas.iter().enumerate() {
                    theta[s + k] = b * per;
                }
            }
        }
        if linear == LinearCoords::Scaled {
            let [ia, ib, ic] = family.linear_indices();
            let slack = 1.0 - small_signal_pole(family, theta, theta[ia]);
            theta[ib] = z[ib] * scale.gain * slack;
            theta[ic] = z[ic] * scale.range * slack;
            theta[family.start_index()] = z[family.start_index()] * scale.range;
        }
    }

    /// The coordinates of the canonical vector `theta` (the inverse of
    /// [`Coordinates::to_native`]; a generalized vector outside the bounded
    /// class maps to coordinates outside its box).
    pub fn from_native(&self, family: Family, theta: &[f64]) -> Vec<f64> {
        let mut z = theta.to_vec();
        let Coordinates::Scaled {
            shape,
            linear,
            scale,
            ..
        } = *self
        else {
            return z;
        };
        if family == Family::Linear {
            return z;
        }
        let per = shape_factor(family, theta, scale);
        let s = shape_range(family).start;
        match (family, shape) {
            (_, ShapeCoords::Native) | (Family::Linear, _) => {}
            (_, ShapeCoords::Free) => {
                for i in shape_range(family) {
                    z[i] = theta[i] * per;
                }
            }
            (Family::Classic, ShapeCoords::Bounded) => {
                let (beta, gamma) = (theta[s], theta[s + 1]);
                z[s] = (beta + gamma) * per;
                z[s + 1] = beta * per;
            }
            (Family::Generalized, ShapeCoords::Bounded) => {
                let b = &theta[s..s + 6];
                for (k, (sign_w, sign_x)) in LOADING_SIGNS.iter().enumerate() {
                    z[s + k] = loading_psi(b, *sign_w, *sign_x) * per;
                }
                let (share2, share4) = if b[0] > 0.0 {
                    (b[1] / b[0], b[3] / b[0])
                } else {
                    (0.0, 0.0)
                };
                z[s + 4] = share2 + share4;
                z[s + 5] = share2 - share4;
            }
        }
        if linear == LinearCoords::Scaled {
            let [ia, ib, ic] = family.linear_indices();
            let slack = 1.0 - small_signal_pole(family, theta, theta[ia]);
            let slack = if slack.abs() < 1e-12 { 1e-12 } else { slack };
            z[ib] = theta[ib] / (scale.gain * slack);
            z[ic] = theta[ic] / (scale.range * slack);
            z[family.start_index()] = theta[family.start_index()] / scale.range;
        }
        z
    }
}

/// The signs `(sgn w, sgn x)` of the four loading branches, in the order of
/// the coordinates `psi_pp, psi_pn, psi_np, psi_nn`.
pub const LOADING_SIGNS: [(f64, f64); 4] = [(1.0, 1.0), (1.0, -1.0), (-1.0, 1.0), (-1.0, -1.0)];

/// The generalized state's `ψ` on the loading branch with `sgn Δ = sgn w =
/// sign_w` and `sgn x = sign_x` (`betas` = β1…β6).
pub fn loading_psi(betas: &[f64], sign_w: f64, sign_x: f64) -> f64 {
    let (s, t) = (sign_w, sign_x);
    betas[0] + s * t * (betas[1] + betas[2]) + s * (betas[3] + betas[4]) + t * betas[5]
}

/// The generalized loop's `β1…β6` whose loading slopes are `loading`
/// (`ψ` for the signs of [`LOADING_SIGNS`]) and whose `(β2, β4)` sit at
/// `(u, v)` of the diamond `|β2| + |β4| ≤ β1` (`u, v ∈ [−1, 1]` fill it).
pub fn bounded_betas(loading: [f64; 4], u: f64, v: f64) -> [f64; 6] {
    let [pp, pn, np, nn] = loading;
    let beta1 = (pp + pn + np + nn) / 4.0;
    let beta23 = (pp - pn - np + nn) / 4.0;
    let beta45 = (pp + pn - np - nn) / 4.0;
    let beta6 = (pp - pn + np - nn) / 4.0;
    let beta2 = beta1 * (u + v) / 2.0;
    let beta4 = beta1 * (u - v) / 2.0;
    [beta1, beta2, beta23 - beta2, beta4, beta45 - beta4, beta6]
}

/// Whether the canonical `theta` lies in the bounded class of its family
/// (see the module's doc); the linear family always does.
pub fn in_bounded_class(family: Family, theta: &[f64]) -> bool {
    match family {
        Family::Linear => true,
        Family::Classic => theta[2] >= 0.0 && theta[2] + theta[3] >= 0.0,
        Family::Generalized => {
            let b = &theta[2..8];
            LOADING_SIGNS
                .iter()
                .all(|&(s, t)| loading_psi(b, s, t) >= 0.0)
                && b[1].abs() + b[3].abs() <= b[0]
        }
    }
}

/// The same model in the gauge `A = 1` ([`crate::model::SearchSpace::scaled`]):
/// the loop state scaled by `1/A`, its weight `a·(1 − α)` by `A` and the
/// loop-shape parameters by `A^(n−1)`, so that every output is the same. A
/// model without a loop (`A = 0`) becomes `α = 1`, `a` its linear pole. A
/// negative `A` has no such twin and is returned as it is.
pub fn gauge_fixed(family: Family, theta: &[f64]) -> Vec<f64> {
    let mut g = theta.to_vec();
    if family == Family::Linear || theta[0] < 0.0 {
        return g;
    }
    let (big_a, alpha) = (theta[0], theta[1]);
    let ia = family.linear_indices()[0];
    let a = theta[ia];
    let pole = small_signal_pole(family, theta, a);
    g[0] = 1.0;
    if big_a == 0.0 || pole == 0.0 {
        g[1] = 1.0;
        g[ia] = a * alpha;
        return g;
    }
    g[ia] = pole;
    g[1] = a * alpha / pole;
    let n = family.exponent_index().map_or(1.0, |i| theta[i]);
    for i in shape_range(family) {
        g[i] = theta[i] * big_a.powf(n - 1.0);
    }
    g
}

/// The small-signal pole `λ = a·(α + (1 − α)·A)` of a canonical vector
/// whose pole parameter is `a` (for small loops `w ≈ A·x`).
pub fn small_signal_pole(family: Family, theta: &[f64], a: f64) -> f64 {
    match family {
        Family::Linear => a,
        _ => a * (theta[1] + (1.0 - theta[1]) * theta[0]),
    }
}

/// Indices of the loop-shape parameters (between `α` and `n`).
pub fn shape_range(family: Family) -> std::ops::Range<usize> {
    2..family.exponent_index().unwrap_or(2)
}

/// `Rⁿ/A`: canonical loop-shape parameters times this are the normalised
/// coordinates. `A` and `n` are entries 0 and the exponent's of either
/// vector (they are their own coordinates); a vanishing `A` (no loop, so no
/// shape to speak of) is taken as 10⁻¹² so that the map stays finite.
fn shape_factor(family: Family, v: &[f64], scale: Scale) -> f64 {
    let n = family.exponent_index().map_or(1.0, |i| v[i]);
    // `powf(r, 1)` is `r` exactly (a correctly rounded power of an exact
    // result), and the fit maps every row of every generation through here
    // with n = 1: skipping the call keeps the bits and most of the cost.
    let range_n = if n == 1.0 {
        scale.range
    } else {
        scale.range.powf(n)
    };
    range_n / v[0].abs().max(1e-12)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scaled(shape: ShapeCoords) -> Coordinates {
        Coordinates::Scaled {
            shape,
            linear: LinearCoords::Scaled,
            scale: Scale {
                range: 23.0,
                gain: 61.0,
            },
        }
    }

    fn close(a: &[f64], b: &[f64]) -> bool {
        a.iter()
            .zip(b)
            .all(|(x, y)| (x - y).abs() <= 1e-9 * (1.0 + x.abs().max(y.abs())))
    }

    #[test]
    fn coordinates_round_trip() {
        let classic = [0.8, 0.6, 0.01, 0.02, 1.3, 0.95, 3.0, -0.4, 0.05];
        let generalized = [
            1.2, 0.5, 0.05, 0.01, 0.02, -0.015, 0.01, 0.003, 1.0, 3.5, 0.97, 2.0, 0.3, -0.02,
        ];
        for (family, theta) in [
            (Family::Classic, &classic[..]),
            (Family::Generalized, &generalized[..]),
        ] {
            assert!(in_bounded_class(family, theta), "{family}");
            for shape in [ShapeCoords::Bounded, ShapeCoords::Free, ShapeCoords::Native] {
                let c = scaled(shape);
                let z = c.from_native(family, theta);
                assert!(close(&c.to_native(family, &z), theta), "{family} {shape:?}");
                assert_eq!(c.names(family).len(), family.dim());
            }
        }
    }

    #[test]
    fn the_gauge_twin_gives_the_same_output() {
        use crate::model::simulate;
        let u: Vec<f32> = (0..600)
            .map(|k| 0.2 * (k as f32 * 0.05).sin() + 0.1 * ((k / 70) % 3) as f32)
            .collect();
        let classic = vec![0.7, 0.6, 0.03, 0.01, 1.4, 0.93, 20.0, 0.1, 0.05];
        let generalized = vec![
            1.6, 0.5, 0.05, 0.01, 0.02, -0.015, 0.01, 0.003, 1.0, 0.1, 0.95, 20.0, 0.3, -0.02,
        ];
        for (family, theta) in [
            (Family::Classic, classic),
            (Family::Generalized, generalized),
        ] {
            let twin = gauge_fixed(family, &theta);
            assert_eq!(twin[0], 1.0);
            let f = |t: &[f64]| t.iter().map(|&v| v as f32).collect::<Vec<f32>>();
            let x = simulate(family, &f(&theta), 0.0, &u, 0.5).x;
            let y = simulate(family, &f(&twin), 0.0, &u, 0.5).x;
            let worst = x
                .iter()
                .zip(&y)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0f32, f32::max);
            let swing = x.iter().fold(0.0f32, |m, v| m.max(v.abs()));
            assert!(worst <= 1e-4 * swing, "{family}: {worst} of {swing}");
        }
    }

    #[test]
    fn the_same_record_in_other_units_has_the_same_coordinates() {
        // Output in metres instead of mm (÷1000), input in kPa instead of MPa
        // (×1000): b scales by 10⁻⁶, c and x0 by 10⁻³, β and γ by 10³.
        let mm = [1.0, 0.6, 0.01, 0.02, 1.0, 0.95, 3.0, -0.4, 0.05];
        let m = [1.0, 0.6, 10.0, 20.0, 1.0, 0.95, 3e-6, -4e-4, 5e-5];
        let c = |range: f64, gain: f64| Coordinates::Scaled {
            shape: ShapeCoords::Bounded,
            linear: LinearCoords::Scaled,
            scale: Scale { range, gain },
        };
        let z_mm = c(23.0, 61.0).from_native(Family::Classic, &mm);
        let z_m = c(0.023, 61e-6).from_native(Family::Classic, &m);
        assert!(close(&z_mm, &z_m), "{z_mm:?} {z_m:?}");
    }

    #[test]
    fn every_point_of_the_bounded_box_is_in_the_bounded_class() {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        for family in [Family::Classic, Family::Generalized] {
            let c = scaled(ShapeCoords::Bounded);
            let generalized = family == Family::Generalized;
            for _ in 0..2000 {
                let mut z = vec![1.0; family.dim()];
                for (k, i) in shape_range(family).enumerate() {
                    z[i] = if generalized && k >= 4 {
                        rng.random_range(-1.0..=1.0)
                    } else {
                        rng.random_range(0.0..100.0)
                    };
                }
                let theta = c.to_native(family, &z);
                assert!(in_bounded_class(family, &theta), "{family}: {theta:?}");
            }
        }
    }

    /// The largest `|w|` of the loop of `theta` (n = 1) driven by `x`,
    /// from `w = 0`, with the production step functions.
    fn largest_state(family: Family, theta: &[f64], x: &[f64]) -> f64 {
        use crate::model::sim::{classic_w, generalized_w};
        let t: Vec<f32> = theta.iter().map(|&v| v as f32).collect();
        let (mut w, mut largest) = (0.0f32, 0.0f64);
        for k in 1..x.len() {
            let (xk, delta) = (x[k] as f32, (x[k] - x[k - 1]) as f32);
            w = match family {
                Family::Classic => classic_w(t[0], t[2], t[3], 1.0, w, delta),
                _ => {
                    let betas = [t[2], t[3], t[4], t[5], t[6], t[7]];
                    generalized_w(t[0], &betas, 1.0, w, xk, delta, 0.0)
                }
            };
            largest = largest.max((w as f64).abs());
        }
        largest
    }

    /// A bounded input for the loop: a ramp out to `reach`, then a random
    /// walk within ±`reach` whose steps (at most `step`) reverse often, so
    /// that it dithers as a noisy pressure does.
    fn dithered_input(reach: f64, step: f64, rng: &mut rand_chacha::ChaCha8Rng) -> Vec<f64> {
        use rand::RngExt;
        let mut x: Vec<f64> = (0..=((reach / step) as usize))
            .map(|k| k as f64 * step)
            .collect();
        let mut v = *x.last().unwrap();
        for _ in 0..4000 {
            v = (v + rng.random_range(-step..step)).clamp(-reach, reach);
            x.push(v);
        }
        x
    }

    /// The analytic bound of the loop of `theta` (n = 1) for inputs within
    /// ±`reach` from `w = 0`. On a loading branch `|w|` relaxes towards
    /// `A/ψ_load`, so it never passes `A/min ψ_load`; an unloading branch
    /// can raise `|w|` only while `|w|·ψ_unload > A`, at a rate `ψ_unload` per
    /// unit of motion, over one excursion of at most `2·reach`, and a cycle
    /// that returns takes back at least as much (`ψ_unload ≤ ψ_load` at the
    /// same signs of `w` and `x`). For the classic loop the second factor is
    /// 1: `ψ_unload = γ − β ≤ β + γ` already keeps `|w| ≤ A/(β + γ)`.
    fn analytic_bound(family: Family, theta: &[f64], reach: f64) -> f64 {
        let big_a = theta[0];
        match family {
            Family::Classic => big_a / (theta[2] + theta[3]),
            _ => {
                let b = &theta[2..8];
                let least = LOADING_SIGNS
                    .iter()
                    .map(|&(s, t)| loading_psi(b, s, t))
                    .fold(f64::INFINITY, f64::min);
                let steepest_unloading = LOADING_SIGNS
                    .iter()
                    .map(|&(s, t)| loading_psi(b, s, t) - 2.0 * (b[0] + s * t * b[1] + s * b[3]))
                    .fold(0.0f64, f64::max);
                big_a / least * (2.0 * reach * steepest_unloading).exp()
            }
        }
    }

    #[test]
    fn a_loop_from_the_bounded_box_stays_under_its_analytic_bound() {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(17);
        for family in [Family::Classic, Family::Generalized] {
            let c = scaled(ShapeCoords::Bounded);
            for case in 0..300 {
                let mut z = vec![1.0; family.dim()];
                z[0] = rng.random_range(0.2..2.0);
                for (k, i) in shape_range(family).enumerate() {
                    z[i] = if family == Family::Generalized && k >= 4 {
                        rng.random_range(-1.0..=1.0)
                    } else {
                        // Normalised slopes from 0.01 to 100, log-uniform.
                        10f64.powf(rng.random_range(-2.0..2.0))
                    };
                }
                let theta = c.to_native(family, &z);
                let shapes = &theta[shape_range(family)];
                let steepest = shapes.iter().fold(0.0f64, |m, v| m.max(v.abs())) * 4.0;
                // Steps small against the loop's saturation (the explicit
                // step's overshoot stays within 1 %), reach within a few
                // saturation lengths.
                let step = 0.01 / steepest;
                let reach = rng.random_range(0.2..2.0) / steepest;
                let x = dithered_input(reach, step, &mut rng);
                let largest = largest_state(family, &theta, &x);
                let bound = analytic_bound(family, &theta, reach);
                assert!(
                    largest <= 1.02 * bound,
                    "{family} case {case}: |w| reached {largest:e} over the bound {bound:e} \
                     ({theta:?})"
                );
            }
        }
    }

    #[test]
    fn a_steeper_unloading_branch_ratchets_past_the_bound() {
        // The same input outside the class: β < 0 (classic), |β2| + |β4| > β1
        // (generalized, every loading ψ still positive). Dithering pumps |w|
        // far past where the class would hold it.
        use rand::SeedableRng;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let classic = [1.0, 0.5, -0.01, 0.03, 1.0, 0.9, 1.0, 0.0, 0.0];
        let mut generalized = [0.0; 14];
        generalized[0] = 1.0;
        generalized[2..8].copy_from_slice(&[0.02, 0.02, -0.02, 0.02, -0.02, 0.0]);
        for (family, theta) in [
            (Family::Classic, &classic[..]),
            (Family::Generalized, &generalized[..]),
        ] {
            assert!(!in_bounded_class(family, theta));
            let x = dithered_input(60.0, 0.5, &mut rng);
            let largest = largest_state(family, theta, &x);
            // Every loading slope is 0.02: the class would hold |w| ≤ A/0.02.
            let least = LOADING_SIGNS
                .iter()
                .map(|&(s, t)| match family {
                    Family::Classic => theta[2] + theta[3],
                    _ => loading_psi(&theta[2..8], s, t),
                })
                .fold(f64::INFINITY, f64::min);
            assert!((least - 0.02).abs() < 1e-12);
            assert!(largest > 100.0 * theta[0] / least, "{family}: {largest:e}");
        }
    }

    #[test]
    fn the_class_excludes_a_steeper_unloading_branch() {
        // Classic β < 0 with β + γ > 0; generalized |β2| + |β4| > β1.
        assert!(!in_bounded_class(
            Family::Classic,
            &[1.0, 0.5, -0.01, 0.03, 1.0, 0.9, 1.0, 0.0, 0.0]
        ));
        let mut g = [0.0; 14];
        g[0] = 1.0;
        g[2..8].copy_from_slice(&[0.05, 0.04, 0.0, 0.02, 0.0, 0.0]);
        assert!(!in_bounded_class(Family::Generalized, &g));
        g[3] = 0.02;
        assert!(in_bounded_class(Family::Generalized, &g));
    }
}
