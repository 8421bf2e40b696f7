//! One extractor per argument, for `#[pyo3(from_py_with = named::dt)]`:
//! each converts its argument with [`crate::args`]' checks, and its
//! errors name the argument (`dt must be a number (an int or a float), got
//! str '0.1'`). PyO3 names an argument it failed to convert only in a note
//! on the exception (`while processing 'dt'`), which the message
//! (`str(e)`) leaves out. An extractor keeps the argument's Rust type, so
//! that a literal default (`seed = 1`) still shows in the signature.

use std::path::PathBuf;

use pyo3::prelude::*;

use mckibben::model::UserBound;
use mckibben::model::effects::Effect;

use crate::args::{at_least, effects_arg, flag, optional, path, real, seed, text, user_bounds};

/// `name: T = conv("arg", extra...)` defines `fn name(obj) -> PyResult<T>`
/// calling `conv(obj, "arg", extra...)`; `optional(conv(...))` takes
/// Python's `None` as `None`.
macro_rules! named {
    () => {};
    ($f:ident: $t:ty = optional($conv:ident($what:literal $(, $x:expr)*)); $($rest:tt)*) => {
        // `'a` is the borrow a `&'a str` argument's type names.
        #[allow(clippy::needless_lifetimes)]
        pub fn $f<'a>(obj: &'a Bound<'_, PyAny>) -> PyResult<Option<$t>> {
            optional(obj, |o| $conv(o, $what $(, $x)*))
        }
        named!($($rest)*);
    };
    ($f:ident: $t:ty = $conv:ident($what:literal $(, $x:expr)*); $($rest:tt)*) => {
        #[allow(clippy::needless_lifetimes)]
        pub fn $f<'a>(obj: &'a Bound<'_, PyAny>) -> PyResult<$t> {
            $conv(obj, $what $(, $x)*)
        }
        named!($($rest)*);
    };
}

named! {
    // Trace, fit, Evaluator.
    dt: f64 = real("dt");
    dt_opt: f64 = optional(real("dt"));
    input_name: &'a str = text("input_name");
    output_name: &'a str = text("output_name");
    source: &'a str = text("source");
    time_name: &'a str = text("time_name");
    // read_csv.
    csv_path: PathBuf = path("path");
    input: &'a str = text("input");
    output: &'a str = text("output");
    time: &'a str = optional(text("time"));
    resample: f64 = optional(real("resample"));
    split_gaps: bool = flag("split_gaps");
    // Model.
    model_path: PathBuf = path("path");
    x0: f64 = optional(real("x0"));
    // fit and Evaluator.
    family_opt: &'a str = optional(text("model"));
    family: &'a str = text("model");
    effects: Vec<Effect> = optional(effects_arg("effects"));
    algo: &'a str = text("algo");
    pop: usize = optional(at_least("pop", 1));
    gens: usize = optional(at_least("gens", 1));
    backend: &'a str = text("backend");
    bounds: Vec<UserBound> = optional(user_bounds("bounds"));
    free_n: bool = flag("free_n");
    loop_shape: &'a str = text("loop");
    switch: &'a str = optional(text("switch"));
    overshoot: &'a str = optional(text("overshoot"));
    thesis_flow: bool = flag("thesis_flow");
    target_sse: f64 = optional(real("target_sse"));
    time_budget: f64 = optional(real("time_budget"));
    stall: usize = optional(at_least("stall", 1));
    refine_rounds: usize = optional(at_least("refine_rounds", 0));
    checked: bool = flag("checked");
    // fit and diagnose.
    seed_arg: u64 = seed("seed");
    // diagnose.
    baseline: &'a str = optional(text("baseline"));
    seeds: usize = optional(at_least("seeds", 1));
    generations: usize = optional(at_least("generations", 1));
    scratch_seeds: usize = optional(at_least("scratch_seeds", 0));
    max_effects: usize = optional(at_least("max_effects", 0));
    blocks: usize = optional(at_least("blocks", 2));
    repeat: usize = at_least("repeat", 1);
    // twin.
    experiment: &'a str = text("experiment");
    load: f64 = real("load");
    freq: f64 = optional(real("freq"));
    // identify.
    na: usize = at_least("na", 0);
    nb: usize = at_least("nb", 1);
    nk: usize = at_least("nk", 0);
    // control.
    design_load: f64 = optional(real("design_load"));
    robustness: bool = flag("robustness");
    algo_opt: &'a str = optional(text("algo"));
    horizon: usize = optional(at_least("horizon", 0));
    r_move: f64 = optional(real("r_move"));
    reference: &'a str = text("reference");
    warmup: f64 = optional(real("warmup"));
    duration: f64 = optional(real("duration"));
    steady_from: f64 = optional(real("steady_from"));
}
