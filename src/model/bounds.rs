//! The search box of a fit: bounds on every canonical parameter, where a
//! parameter whose lower and upper bounds are equal is held fixed.

use serde::{Deserialize, Serialize};

use super::coords::{Coordinates, LinearCoords, Loop, Scale, ShapeCoords, shape_range};
use super::family::Family;
use super::presets::{ThesisBounds, hysteresis_hull};
use super::user_bound::UserBound;
use crate::search::Side;

/// A user bound (`--bound`, `--fix`) that names no parameter of the fit.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum BoundError {
    /// A name that is neither the family's nor its search coordinates'.
    #[error(
        "{given}: no parameter `{name}` in the {family} model{}: the names are {}",
        switched.map(|why| format!(" here ({why})")).unwrap_or_default(),
        known.join(", ")
    )]
    UnknownParameter {
        name: String,
        /// The bound as its flag gave it (`--bound foo=0:1`).
        given: String,
        family: Family,
        /// The names a bound may use.
        known: Vec<String>,
        /// Why `name`, a coordinate of another box of the family, is not
        /// one of this box's: `--bound gain=… --fix b=3` asks for the
        /// scaled linear part and the native one at once.
        switched: Option<&'static str>,
    },
    /// A box for the Bouc-Wen exponent that reaches `n ≤ 0`
    /// ([`Family::exponent_refused`]).
    #[error("{given}: {why}")]
    Exponent { given: String, why: String },
    /// An effect parameter's name (`effect.param`) that no effect of the
    /// fit has.
    #[error(
        "{given}: no effect parameter `{name}` in this fit: {}",
        effects_hint(known)
    )]
    UnknownEffectParameter {
        name: String,
        /// The bound as its flag gave it (`--fix creep.x=1`).
        given: String,
        /// The fit's effect parameters (none: the fit has no effects).
        known: Vec<String>,
    },
}

/// What [`BoundError::UnknownEffectParameter`] suggests.
fn effects_hint(known: &[String]) -> String {
    if known.is_empty() {
        "it has no effects (add them with --effects)".to_string()
    } else {
        format!("its effects' parameters are {}", known.join(", "))
    }
}

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

/// The box of a fit: bounds on every search coordinate ([`Coordinates`]:
/// the canonical parameters themselves, or the data's own scale).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SearchSpace {
    pub family: Family,
    /// How the box's coordinates map to canonical vectors.
    #[serde(default = "native")]
    pub coords: Coordinates,
    pub lower: Vec<f64>,
    pub upper: Vec<f64>,
    /// Where each bound (`[lower, upper]` of each coordinate) comes from:
    /// only the data's may be widened when a fit ends on them
    /// ([`SearchSpace::widen`]).
    #[serde(default)]
    pub origin: Vec<[Origin; 2]>,
    /// Names of the coordinates after the family's: the effects' own
    /// parameters (`creep.kappa`), searched as they are.
    #[serde(default)]
    pub extra_names: Vec<String>,
    /// Where the generalized switching level is searched as a level
    /// ([`SearchSpace::scaled`] with [`Switching::Search`]): the levels to
    /// keep among those the estimation data cannot tell apart (the sensor's
    /// zero and the estimation mean, where the box holds them). `None`: the
    /// level is held, or searched as any other coordinate (the diagnosis'
    /// box).
    #[serde(default)]
    pub switch_levels: Option<Vec<f64>>,
}

/// Where a bound of the box comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Origin {
    /// A rule on the data (ARX, ranges): widened when a fit ends on it.
    Data,
    /// The parameter's own range or the bounded class's edge, or the
    /// thesis' tables: never widened.
    #[default]
    Class,
    /// `--bound` or `--fix`.
    User,
}

fn native() -> Coordinates {
    Coordinates::Native
}

/// Where a generalized fit lets its sign terms in `x` switch (`--switch`):
/// the switching level `x_s` held at one value per start, or searched.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Switching {
    /// `x_s` searched over the estimation output's span as a level (the
    /// default): a third of the first population starts at the sensor's
    /// zero and at the estimation mean, the polish holds it, a scan of
    /// levels moves it, and where the estimation data cannot tell the
    /// best level from one of those two, that one is kept
    /// (docs/ARCHITECTURE.md, "Where the generalized loop switches").
    #[default]
    Search,
    /// Two starts, `x_s` held at the estimation mean in one and at the
    /// sensor's zero in the other; the lower estimation SSE is kept.
    Starts,
    /// `x_s` held at the estimation mean (where the thesis' model, written
    /// in deviation coordinates, switches).
    Mean,
    /// `x_s` held at the sensor's zero (its rest length).
    Zero,
}

/// The data-scale box's loop-shape reach: a normalised loop-shape
/// coordinate `ψ·Rⁿ/A` is `(R/w_sat)ⁿ`, so this admits loops that saturate at
/// a thousandth of the output range, far below any record's noise.
pub const SHAPE_REACH: f64 = 1000.0;
/// How far the data-scale box lets the pole's time constant `1/(1 − a)`
/// stray from the ARX one, either way. ARX on hysteretic data finds it
/// within tens of per cent; a hysteretic model's small-signal pole can
/// still sit several times slower or faster than ARX's average one.
pub const POLE_REACH: f64 = 10.0;
/// How far the data-scale box lets the static gain stray from the ARX one,
/// either way (ARX finds it within a factor 1.5 on hysteretic records).
pub const GAIN_REACH: f64 = 5.0;
/// The data-scale box of the start offset, as a share of the output range.
pub const START_REACH: f64 = 0.2;
/// How far the switching level's box reaches past the estimation output's
/// smallest and largest sample, as a share of their span: a free run strays
/// a little past the measured output, so a level just beyond it still
/// switches somewhere. Further out every level gives the same model.
pub const SWITCH_MARGIN: f64 = 0.05;

/// How many times its span a column's largest absolute value may count in
/// a box ([`LinearPrior`]'s `max_abs_*`, from `ident::arx::linear_prior`).
/// The fit works in deviations from the mean, so a constant level (an
/// absolute position, an encoder's counts, a gauge reading atmospheric
/// pressure) changes nothing the model must reach, yet the intercept's box
/// grew with it without end; past this many spans a level no longer widens
/// the box. Every record that starts near its zero lies well inside it and
/// keeps its box exactly.
pub const LEVEL_REACH: f64 = 10.0;

/// The largest absolute value of `v`, at most [`LEVEL_REACH`] times its
/// span (a constant column keeps its largest absolute value).
pub fn level_reach(v: &[f64]) -> f64 {
    let largest = v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let span = crate::data::range(v);
    if span > 0.0 {
        largest.min(LEVEL_REACH * span)
    } else {
        largest
    }
}

/// What the data say about scale, for the bounds of the linear part.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinearPrior {
    /// ARX pole and gain (eq. 12) on the estimation data; where ARX's pole
    /// is not in [0, 1), those of the best stable first-order free run
    /// (`ident::arx::stable_output_error`).
    pub a: f64,
    pub b: f64,
    /// Largest absolute input and output in the data's own units (before
    /// mean removal), each at most [`LEVEL_REACH`] times its span: the
    /// intercept can be no larger than what they can produce, and a
    /// constant level far past the swing changes nothing the model must
    /// reach.
    pub max_abs_input: f64,
    pub max_abs_output: f64,
    /// Range (max − min) of the output: the scale of the start offset's box.
    pub output_range: f64,
    /// Smallest and largest output over the estimation halves (absolute
    /// units): the switching level's box (only the estimation part, which
    /// the fit chooses on).
    pub est_output_min: f64,
    pub est_output_max: f64,
    /// The output mean `ȳ` the fit's deviation coordinates remove (absolute
    /// units): where a model that switches at its estimation mean switches.
    pub output_mean: f64,
}

impl LinearPrior {
    /// The box of the switching level `x_s` (absolute units): the
    /// estimation output's span with [`SWITCH_MARGIN`] either side.
    pub fn switch_box(&self) -> (f64, f64) {
        let margin = SWITCH_MARGIN * (self.est_output_max - self.est_output_min);
        (self.est_output_min - margin, self.est_output_max + margin)
    }
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
    /// ARX gain, `|c| ≤ |b_ARX|·max|p| + max|l|` (each `max` at most
    /// [`LEVEL_REACH`] spans), and the start offset
    /// `x0` within 5 % of the output range (many times the noise of any
    /// usable record; the thesis' flow holds it at 0). The generalized
    /// switching level `x_s` spans the estimation output
    /// ([`LinearPrior::switch_box`]); the thesis' flow holds it at the
    /// estimation mean, where the thesis' model, written in deviation
    /// coordinates, switches.
    pub fn from_prior(
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
        if let Some(is) = family.switch_index() {
            (lower[is], upper[is]) = match flow {
                Flow::Thesis => (prior.output_mean, prior.output_mean),
                Flow::Joint => prior.switch_box(),
            };
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
            coords: Coordinates::Native,
            origin: vec![[Origin::Class; 2]; d],
            lower,
            upper,
            extra_names: Vec::new(),
            switch_levels: None,
        }
    }

    /// The default box of the joint flow, in the data's own scale
    /// ([`crate::model::coords`]); every bound is set by a rule on what the
    /// data determine, wide enough that no plausible truth lies outside:
    ///
    /// - `A = 1`: the gauge. Scaling `w` by `k` while `A` and the weight
    ///   `a·(1 − α)` of `w` scale by `1/k` and `k` gives the same output
    ///   (for `n = 1`; `β, γ` then scale by `k^(n−1)`), so only the
    ///   product is determined, and the box fixes `A` (Ma, Zhang & Xu,
    ///   "Parameter analysis of the differential model of hysteresis",
    ///   J. Appl. Mech. 71, 2004). `a` is then the small-signal pole and
    ///   `1 − α` the share of it carried by the loop.
    /// - `α ∈ [0, 1]`: its whole range.
    /// - `a`: time constant `1/(1 − a)` within [`POLE_REACH`] of the ARX
    ///   one either way (at least 0).
    /// - `gain`: the static gain within [`GAIN_REACH`] of ARX's either way.
    /// - `offset`: as far as the largest input through the largest gain,
    ///   plus the largest output, can shift the output (each largest value
    ///   at most [`LEVEL_REACH`] times its column's span).
    /// - `x0_range`: [`START_REACH`] of the output range either way.
    /// - `x_s` (generalized, in output units), by `switching`: held at the
    ///   estimation mean ([`Switching::Starts`]'s first start, and
    ///   [`Switching::Mean`]), held at 0 ([`Switching::Zero`]), or searched
    ///   over the estimation output's span with [`SWITCH_MARGIN`]
    ///   ([`Switching::Search`], [`LinearPrior::switch_box`]). Every one of
    ///   these bounds is the class's, never widened: past the span every
    ///   level gives the same model, so a search that ends on its edge has
    ///   found that the loop does not switch within the record (a rest
    ///   length below every sample).
    /// - loop shape: `[0, SHAPE_REACH]` for the bounded class's slopes
    ///   (`unload_u, unload_v` over their whole `[−1, 1]`), `±SHAPE_REACH`
    ///   free ([`SHAPE_REACH`]).
    ///
    /// `bounds` are then applied in order: each names a coordinate or a
    /// canonical parameter. Bounding `b` or `c` searches the linear part in
    /// `b, c, x0` themselves, bounding a loop-shape parameter (`beta`…)
    /// the loop shape in its canonical parameters; their default boxes are
    /// the images of the data-scale ones. A bound on a parameter that is
    /// neither gives an error naming the names there are.
    pub fn scaled(
        family: Family,
        prior: LinearPrior,
        (shape_class, switching): (Loop, Switching),
        free_n: bool,
        bounds: &[UserBound],
    ) -> Result<SearchSpace, BoundError> {
        let canonical: Vec<&str> = family.params().iter().map(|p| p.name).collect();
        let shape_names: Vec<&str> = shape_range(family).map(|i| canonical[i]).collect();
        let [_, ib, ic] = family.linear_indices();
        let linear = if bounds
            .iter()
            .any(|b| b.name == canonical[ib] || b.name == canonical[ic])
        {
            LinearCoords::Native
        } else {
            LinearCoords::Scaled
        };
        let shape = if bounds
            .iter()
            .any(|b| shape_names.contains(&b.name.as_str()))
        {
            ShapeCoords::Native
        } else {
            match shape_class {
                Loop::Bounded => ShapeCoords::Bounded,
                Loop::Free => ShapeCoords::Free,
            }
        };
        let range = if prior.output_range > 0.0 {
            prior.output_range
        } else {
            1.0
        };
        let s = (1.0 - prior.a).abs().max(1e-3);
        let arx_gain = prior.b / s;
        // A record whose output barely follows its input: ARX's gain is
        // noise; give the gain coordinate the scale of the output range
        // over the input's.
        let floor = 1e-3 * range / prior.max_abs_input.max(f64::MIN_POSITIVE);
        let gain = if arx_gain.abs() >= floor {
            arx_gain
        } else {
            floor.copysign(if arx_gain == 0.0 { 1.0 } else { arx_gain })
        };
        let coords = Coordinates::Scaled {
            shape,
            linear,
            scale: Scale { range, gain },
        };
        let d = family.dim();
        let mut lower = vec![0.0; d];
        let mut upper = vec![0.0; d];
        let mut origin = vec![[Origin::Class; 2]; d];
        // A (the gauge) and α.
        (lower[0], upper[0]) = (1.0, 1.0);
        (lower[1], upper[1]) = (0.0, 1.0);
        let ni = family.exponent_index().expect("hysteretic family has n");
        (lower[ni], upper[ni]) = (1.0, if free_n { 3.0 } else { 1.0 });
        if let Some(is) = family.switch_index() {
            (lower[is], upper[is]) = match switching {
                Switching::Starts | Switching::Mean => (prior.output_mean, prior.output_mean),
                Switching::Zero => (0.0, 0.0),
                Switching::Search => prior.switch_box(),
            };
        }
        let native_shape = SHAPE_REACH / range;
        for (k, i) in shape_range(family).enumerate() {
            let unload_share = family == Family::Generalized && k >= 4;
            let (class, data) = (Origin::Class, Origin::Data);
            (lower[i], upper[i], origin[i]) = match shape {
                ShapeCoords::Bounded if unload_share => (-1.0, 1.0, [class, class]),
                ShapeCoords::Bounded => (0.0, SHAPE_REACH, [class, data]),
                ShapeCoords::Free => (-SHAPE_REACH, SHAPE_REACH, [data, data]),
                ShapeCoords::Native => (-native_shape, native_shape, [data, data]),
            };
        }
        let ia = family.linear_indices()[0];
        lower[ia] = (1.0 - POLE_REACH * s).max(0.0);
        upper[ia] = 1.0 - s / POLE_REACH;
        let pole_floor = if lower[ia] > 0.0 {
            Origin::Data
        } else {
            Origin::Class
        };
        origin[ia] = [pole_floor, Origin::Data];
        let ix = family.start_index();
        let offset = (GAIN_REACH * gain.abs() * prior.max_abs_input + prior.max_abs_output) / range;
        match linear {
            LinearCoords::Scaled => {
                (lower[ib], upper[ib]) = (1.0 / GAIN_REACH, GAIN_REACH);
                (lower[ic], upper[ic]) = (-offset, offset);
                (lower[ix], upper[ix]) = (-START_REACH, START_REACH);
            }
            LinearCoords::Native => {
                // b = gain·K·(1 − a) over the corners of the scaled box.
                let corners = [
                    gain / GAIN_REACH * (1.0 - upper[ia]),
                    gain * GAIN_REACH * (1.0 - lower[ia]),
                ];
                lower[ib] = corners[0].min(corners[1]);
                upper[ib] = corners[0].max(corners[1]);
                let c = offset * range * (1.0 - lower[ia]);
                (lower[ic], upper[ic]) = (-c, c);
                (lower[ix], upper[ix]) = (-START_REACH * range, START_REACH * range);
            }
        }
        for i in [ib, ic, ix] {
            origin[i] = [Origin::Data; 2];
        }
        // A searched level keeps, among levels the estimation data cannot
        // tell apart, the sensor's zero or the estimation mean where one
        // of them is among them: a muscle's loop commonly switches at its
        // rest length, and the generalized state's jumps make the
        // validation error hang on the exact level while the estimation
        // error stays flat across a sample's width of it.
        let switch_levels = match (family.switch_index(), switching) {
            (Some(is), Switching::Search) => Some(
                [0.0, prior.output_mean]
                    .into_iter()
                    .filter(|v| (lower[is]..=upper[is]).contains(v))
                    .collect(),
            ),
            _ => None,
        };
        let mut space = SearchSpace {
            family,
            coords,
            lower,
            upper,
            origin,
            extra_names: Vec::new(),
            switch_levels,
        };
        // An effect's parameter (`creep.kappa`) is bounded once its
        // effect joins the box ([`SearchSpace::with_extra`]).
        for b in bounds.iter().filter(|b| !b.name.contains('.')) {
            space.set_bound(b)?;
        }
        Ok(space)
    }

    /// The box with more coordinates after the family's (the effects'
    /// parameters, in their own units: their ranges are the class's, never
    /// widened), then the user `bounds` that name them.
    pub fn with_extra(
        mut self,
        names: Vec<String>,
        lower: Vec<f64>,
        upper: Vec<f64>,
        bounds: &[UserBound],
    ) -> Result<SearchSpace, BoundError> {
        let first = self.extra_names.len() + self.family.dim();
        self.origin.extend(vec![[Origin::Class; 2]; names.len()]);
        self.lower.extend(lower);
        self.upper.extend(upper);
        self.extra_names.extend(names);
        let ours = self.names()[first..].to_vec();
        for b in bounds.iter().filter(|b| b.name.contains('.')) {
            if !ours.contains(&b.name) {
                return Err(BoundError::UnknownEffectParameter {
                    name: b.name.clone(),
                    given: b.as_given(),
                    known: ours,
                });
            }
            self.set_bound(b)?;
        }
        Ok(self)
    }

    /// Sets one user bound (see [`SearchSpace::scaled`]).
    fn set_bound(&mut self, b: &UserBound) -> Result<(), BoundError> {
        let names = self.names();
        let canonical: Vec<&str> = self.family.params().iter().map(|p| p.name).collect();
        let (i, factor) = if let Some(i) = names.iter().position(|n| *n == b.name) {
            (i, 1.0)
        } else if b.name == "x0" {
            // Searched as x0_range = x0/R.
            let range = match self.coords {
                Coordinates::Scaled { scale, .. } => scale.range,
                Coordinates::Native => 1.0,
            };
            (self.family.start_index(), 1.0 / range)
        } else {
            let mut known: Vec<String> = names.clone();
            for c in &canonical {
                if !known.iter().any(|k| k == c) {
                    known.push((*c).to_string());
                }
            }
            return Err(BoundError::UnknownParameter {
                name: b.name.clone(),
                given: b.as_given(),
                family: self.family,
                known,
                switched: self.coords.switched_away(self.family, &b.name),
            });
        };
        if b.name == "n"
            && let Some(why) = Family::exponent_refused(b.lower)
        {
            return Err(BoundError::Exponent {
                given: b.as_given(),
                why,
            });
        }
        self.lower[i] = b.lower * factor;
        self.upper[i] = b.upper * factor;
        self.origin[i] = [Origin::User; 2];
        Ok(())
    }

    pub fn dim(&self) -> usize {
        self.lower.len()
    }

    /// Indices of the coordinates the optimizer moves.
    pub fn free(&self) -> Vec<usize> {
        (0..self.dim())
            .filter(|&i| self.lower[i] != self.upper[i])
            .collect()
    }

    /// The names of the search coordinates.
    pub fn names(&self) -> Vec<String> {
        let mut names = self.coords.names(self.family);
        names.extend(self.extra_names.iter().cloned());
        names
    }

    /// The canonical vector of search coordinates `z`.
    pub fn to_native(&self, z: &[f64]) -> Vec<f64> {
        self.coords.to_native(self.family, z)
    }

    /// The search coordinates of the canonical vector `theta`.
    pub fn from_native(&self, theta: &[f64]) -> Vec<f64> {
        self.coords.from_native(self.family, theta)
    }

    /// Whether the canonical `theta` lies inside the box (within rounding of
    /// the coordinate map: 10⁻⁹ of each coordinate's width).
    pub fn contains(&self, theta: &[f64]) -> bool {
        theta.len() == self.dim()
            && self
                .from_native(theta)
                .iter()
                .zip(self.lower.iter().zip(&self.upper))
                .all(|(v, (l, u))| {
                    let slack = 1e-9 * (u - l);
                    l - slack <= *v && *v <= u + slack
                })
    }

    /// Clamps the canonical `theta` into the box; returns whether anything
    /// moved.
    pub fn clamp(&self, theta: &mut [f64]) -> bool {
        let mut z = self.from_native(theta);
        let mut moved = false;
        for (v, (l, u)) in z.iter_mut().zip(self.lower.iter().zip(&self.upper)) {
            let c = v.clamp(*l, *u);
            moved |= c != *v;
            *v = c;
        }
        if moved {
            theta.copy_from_slice(&self.to_native(&z));
        }
        moved
    }

    /// Widens every bound the data set (as [`SearchSpace::widen`] does, step
    /// by step) until the box holds the canonical `theta`: a warm start
    /// from a model fitted in another box (the diagnosis') then starts from
    /// that model, not from its clamped image. Bounds of the class and the
    /// user's are left, and so is a data bound the steps cannot carry past
    /// `theta` (the time constant's towards a pole of 1, a bound that
    /// shrinks towards zero while `theta` has the other sign): `theta` is
    /// clamped to those. Returns what moved, as [`SearchSpace::widen`]
    /// words it, one entry per bound.
    pub fn widen_to_hold(&mut self, theta: &[f64]) -> Vec<String> {
        let z = self.from_native(theta);
        let mut said = Vec::new();
        for (i, &v) in z.iter().enumerate() {
            for side in Side::BOTH {
                let upper = side == Side::Upper;
                let beyond = |s: &SearchSpace| {
                    if upper {
                        v > s.upper[i]
                    } else {
                        v < s.lower[i]
                    }
                };
                let old = if upper { self.upper[i] } else { self.lower[i] };
                if self.origin[i][side.index()] != Origin::Data || !beyond(self) {
                    continue;
                }
                // Each step widens by a factor of 2.5 or more, so 16 steps
                // reach any start a bound can reach at all.
                let before = self.clone();
                for _ in 0..16 {
                    self.widen(&[(i, side)]);
                    if !beyond(self) {
                        break;
                    }
                }
                if beyond(self) {
                    *self = before;
                    continue;
                }
                let new = if upper { self.upper[i] } else { self.lower[i] };
                if new != old {
                    said.push(format!(
                        "{} {side} bound {old:.6} -> {new:.6}",
                        self.names()[i]
                    ));
                }
            }
        }
        said
    }

    /// Widens the data-set bounds named by `edges` (coordinate index and
    /// side): the time constant's and the gain's
    /// reach by a factor 4, the offset's by 4, the start's by 2.5, the loop
    /// shape's by 10. Returns one line
    /// per bound widened, naming it with its old and new value; bounds that
    /// are not data-set (the class's edges, user bounds) are left alone.
    pub fn widen(&mut self, edges: &[(usize, Side)]) -> Vec<String> {
        let names = self.names();
        let ia = self.family.linear_indices()[0];
        let shapes = shape_range(self.family);
        let mut said = Vec::new();
        for &(i, side) in edges {
            let upper = side == Side::Upper;
            if self.origin[i][side.index()] != Origin::Data {
                continue;
            }
            let old = if upper { self.upper[i] } else { self.lower[i] };
            let new = if i == ia {
                // Time constant 1/(1 − a): four times further from the ARX one.
                if upper {
                    1.0 - (1.0 - old) / 4.0
                } else {
                    (1.0 - 4.0 * (1.0 - old)).max(0.0)
                }
            } else {
                let factor = if shapes.contains(&i) {
                    10.0
                } else if names[i] == "x0_range" || names[i] == "x0" {
                    2.5
                } else {
                    4.0
                };
                // Away from the box's inside: outward from zero, or towards
                // it for a bound on the far side (a positive lower bound).
                if (old > 0.0) == upper {
                    old * factor
                } else {
                    old / factor
                }
            };
            if upper {
                self.upper[i] = new;
            } else {
                self.lower[i] = new;
                if i == ia && new == 0.0 {
                    self.origin[i][0] = Origin::Class;
                }
            }
            said.push(format!("{} {side} bound {old:.6} -> {new:.6}", names[i]));
        }
        said
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
            est_output_min: 5.0,
            est_output_max: 35.0,
            output_mean: 18.0,
        }
    }

    #[test]
    fn thesis_flow_fixes_the_linear_part() {
        let s = SearchSpace::from_prior(Family::Classic, None, prior(), Flow::Thesis, false);
        assert_eq!(s.free(), vec![0, 1, 2, 3]);
        assert_eq!(s.lower[5], 0.9618);
        assert_eq!(s.upper[7], 0.0);
        assert_eq!(s.upper[8], 0.0);
    }

    #[test]
    fn joint_flow_frees_a_b_c_around_the_arx_estimate() {
        let s = SearchSpace::from_prior(Family::Generalized, None, prior(), Flow::Joint, true);
        assert_eq!(s.free(), (0..14).collect::<Vec<_>>());
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

    #[test]
    fn the_switching_level_spans_the_estimation_output_and_takes_user_bounds() {
        let g = Family::Generalized;
        let is = g.switch_index().unwrap();
        // The estimation output spans 5..35 mm: 5 % of 30 mm either side.
        let joint = SearchSpace::from_prior(g, None, prior(), Flow::Joint, false);
        assert_eq!((joint.lower[is], joint.upper[is]), (3.5, 36.5));
        // The thesis' model switches at the estimation mean.
        let thesis = SearchSpace::from_prior(g, None, prior(), Flow::Thesis, false);
        assert_eq!((thesis.lower[is], thesis.upper[is]), (18.0, 18.0));
        let scaled = |switching| {
            SearchSpace::scaled(g, prior(), (Loop::Bounded, switching), false, &[]).unwrap()
        };
        let held = |s: &SearchSpace| (s.lower[is], s.upper[is]);
        assert_eq!(held(&scaled(Switching::Starts)), (18.0, 18.0));
        assert_eq!(held(&scaled(Switching::Mean)), (18.0, 18.0));
        assert_eq!(held(&scaled(Switching::Zero)), (0.0, 0.0));
        let searched = scaled(Switching::Search);
        assert_eq!(searched.names()[is], "x_s");
        assert_eq!(held(&searched), (3.5, 36.5));
        // Class edges: past them every level is the same model, so a fit
        // that ends there is a finding, never a bound to widen.
        assert_eq!(searched.origin[is], [Origin::Class; 2]);
        let mut widened = searched.clone();
        assert!(
            widened
                .widen(&[(is, Side::Lower), (is, Side::Upper)])
                .is_empty()
        );
        assert_eq!(widened, searched);
        // `--fix x_s=0` (a sensor zero at rest) and `--bound` hold exactly.
        let zero: UserBound = "x_s=0".parse().unwrap();
        let s = SearchSpace::scaled(
            g,
            prior(),
            (Loop::Bounded, Switching::Search),
            false,
            std::slice::from_ref(&zero),
        )
        .unwrap();
        assert_eq!((s.lower[is], s.upper[is]), (0.0, 0.0));
        assert_eq!(s.origin[is], [Origin::User; 2]);
        assert_eq!(s.to_native(&middle(&s))[is], 0.0);
        let bound: UserBound = "x_s=-2:40".parse().unwrap();
        let s = SearchSpace::scaled(
            g,
            prior(),
            (Loop::Bounded, Switching::Starts),
            false,
            &[bound],
        )
        .unwrap();
        assert_eq!((s.lower[is], s.upper[is]), (-2.0, 40.0));
        // The classic model has no switching level.
        let e = SearchSpace::scaled(
            Family::Classic,
            prior(),
            (Loop::Bounded, Switching::Starts),
            false,
            &[zero],
        )
        .unwrap_err();
        assert!(
            matches!(&e, BoundError::UnknownParameter { name, .. } if name == "x_s"),
            "{e:?}"
        );
        assert!(
            e.to_string()
                .contains("no parameter `x_s` in the classic model"),
            "{e}"
        );
    }

    /// A bound on a canonical parameter switches its part of the box to
    /// the canonical parameters; a bound on that part's scaled coordinate
    /// then names nothing, and the error says why rather than only that.
    #[test]
    fn a_scaled_name_after_a_switch_says_what_switched() {
        let cases = [
            (["b=1:2", "gain=0:10"], "a bound on b or c"),
            (
                ["beta=0:1", "loading=0:1"],
                "a bound on a loop-shape parameter",
            ),
        ];
        for (given, why) in cases {
            let bounds: Vec<UserBound> = given.iter().map(|b| b.parse().unwrap()).collect();
            let e = SearchSpace::scaled(
                Family::Classic,
                prior(),
                (Loop::Bounded, Switching::Starts),
                false,
                &bounds,
            )
            .unwrap_err();
            assert!(e.to_string().contains(why), "{given:?}: {e}");
        }
        // The other loop class's coordinate, and a name of no box.
        for (loop_class, name, why) in [
            (Loop::Free, "loading", Some("the other loop class's box")),
            (Loop::Bounded, "foo", None),
        ] {
            let bound: UserBound = format!("{name}=0:1").parse().unwrap();
            let e = SearchSpace::scaled(
                Family::Classic,
                prior(),
                (loop_class, Switching::Starts),
                false,
                &[bound],
            )
            .unwrap_err();
            let BoundError::UnknownParameter { switched, .. } = &e else {
                panic!("{e:?}")
            };
            match why {
                Some(why) => assert!(switched.is_some_and(|s| s.contains(why)), "{e}"),
                None => assert!(switched.is_none(), "{e}"),
            }
        }
    }

    /// The middle of `s`'s box, in its coordinates.
    fn middle(s: &SearchSpace) -> Vec<f64> {
        s.lower
            .iter()
            .zip(&s.upper)
            .map(|(l, u)| 0.5 * (l + u))
            .collect()
    }

    #[test]
    fn a_start_outside_the_data_box_widens_it_until_it_holds() {
        let mut s = SearchSpace::scaled(
            Family::Classic,
            prior(),
            (Loop::Bounded, Switching::Starts),
            false,
            &[],
        )
        .unwrap();
        let names = s.names();
        let gain = names.iter().position(|n| n == "gain").unwrap();
        // A start whose gain is ten times the box's top, as the diagnosis'
        // own box allows.
        let mut z = middle(&s);
        z[gain] = 10.0 * s.upper[gain];
        let theta = s.to_native(&z);
        assert!(!s.contains(&theta));
        let said = s.widen_to_hold(&theta);
        assert!(s.contains(&theta), "{said:?}");
        assert_eq!(said.len(), 1, "{said:?}");
        assert!(said[0].starts_with("gain upper bound"), "{said:?}");
        // Inside already: nothing moves.
        assert!(s.clone().widen_to_hold(&theta).is_empty());
        // A user's bound stays where the user put it.
        let user: UserBound = "gain=0.5:2".parse().unwrap();
        let mut s = SearchSpace::scaled(
            Family::Classic,
            prior(),
            (Loop::Bounded, Switching::Starts),
            false,
            &[user],
        )
        .unwrap();
        assert!(s.widen_to_hold(&theta).is_empty());
        assert!(!s.contains(&theta));
        // A bound the steps cannot carry past the start stays as it was:
        // the time constant's towards a small-signal pole above 1.
        let mut s = SearchSpace::scaled(
            Family::Classic,
            prior(),
            (Loop::Bounded, Switching::Starts),
            false,
            &[],
        )
        .unwrap();
        let a = names.iter().position(|n| n == "a").unwrap();
        let mut z = middle(&s);
        z[a] = s.upper[a] + 0.01;
        let before = s.upper[a];
        assert!(s.widen_to_hold(&s.to_native(&z)).is_empty());
        assert_eq!(s.upper[a], before);
    }
}
