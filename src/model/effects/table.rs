//! The shape of one entry of the catalogue ([`Realisation`]) and the
//! `catalogue!` macro that turns the entries of `catalogue.rs` into the
//! [`super::Effect`] enum, its `ALL`, `PHYSICAL` and the lookup `entry`:
//! every other question about a realisation (its name, parameters, box,
//! size, signature, admission rule, start hint, WGSL parameter names) is
//! answered from its entry, so a realisation is declared once.

use serde::Serialize;

use super::Context;

/// A realisation's box: its neutral value (which gives the baseline's
/// bits), its lower and its upper bounds, one entry per parameter.
#[derive(Debug, Clone, PartialEq)]
pub struct EffectBox {
    pub neutral: Vec<f64>,
    pub lower: Vec<f64>,
    pub upper: Vec<f64>,
}

impl EffectBox {
    pub fn new(neutral: Vec<f64>, lower: Vec<f64>, upper: Vec<f64>) -> EffectBox {
        EffectBox {
            neutral,
            lower,
            upper,
        }
    }
}

/// One realisation of the catalogue: everything the diagnosis, the reports
/// and the backends know about it besides its step (its stage in
/// `stages/` on the CPU, placed by the step order in `catalogue.rs`;
/// `shaders/effects.wgsl` on the GPU). `E` is the catalogue's enum
/// ([`super::Realisation`] names it), which the entries generate, so this
/// schema does not import it back.
#[derive(Debug, Clone, Copy)]
pub struct Realisation<E> {
    /// Its flag and JSON name: the physical effect's (`delay`) for its
    /// first realisation, `physical:realisation` for the others.
    pub name: &'static str,
    /// The physical effect it realises; `None` for a physical effect's
    /// first realisation, which is the physical effect itself.
    pub physical: Option<E>,
    /// How the physical effect is realised, for reports.
    pub realisation: &'static str,
    /// The residual signature that points to it, for reports.
    pub signature: &'static str,
    /// Its parameters, in vector order.
    pub params: Params,
    /// Those of its parameters that say how it evolves in time, not how
    /// large it is: poles, delays, how fast a count's growth or steps fall.
    /// A chain carried to another record of the same muscle holds these at
    /// the diagnosed values and refits the rest, which are in the record's
    /// own scale (`fit --carry`, `diagnose --transfer`).
    pub dynamics: &'static [&'static str],
    /// Index (within its parameters) of the one that measures its size,
    /// which the self-test recovers and the interval is drawn for.
    pub primary: usize,
    /// Its box from the first dataset's context and the number of datasets:
    /// the neutral value always lies in it (an augmented fit can always
    /// fall back on the baseline).
    pub bounds: fn(&Context, usize) -> EffectBox,
    /// Its size in words a person reads (`params`: its own, `dt`: the
    /// sample time), where its parameters do not say it directly.
    pub size_text: Option<fn(&[f64], f64) -> String>,
    /// Datasets it needs to be fitted at all.
    pub min_datasets: usize,
    /// Which of its parameter values the diagnosis admits (`params`: its
    /// own); `None` admits every one in the box.
    pub admits: Option<fn(&[f64]) -> bool>,
    /// Where the diagnosis starts its fit beyond the uniform draws.
    pub hint: StartHint,
    /// Tried only when named (`--effects`), not by the default diagnosis:
    /// a realisation that has not yet shown it pays for the time and the
    /// wrong names it adds to every round.
    pub on_request: bool,
}

/// A realisation's parameter list.
#[derive(Debug, Clone, Copy)]
pub enum Params {
    /// The same parameters on any number of datasets.
    Fixed(&'static [Param]),
    /// One parameter per dataset after the first, named `name1`, `name2`,
    /// … (the load gains: dataset 0 is the reference).
    PerLaterDataset {
        name: &'static str,
        meaning: &'static str,
        unit: Unit,
    },
}

/// One parameter of a realisation: its name (also its WGSL field), what it
/// means, and what it is measured in.
#[derive(Debug, Clone, Copy)]
pub struct Param {
    pub name: &'static str,
    pub meaning: &'static str,
    pub unit: Unit,
}

impl Param {
    /// A pure number: a pole, a share, samples, a relative gain.
    pub const fn pure(name: &'static str, meaning: &'static str) -> Param {
        Param::new(name, meaning, Unit::Pure)
    }
    /// An input level or width, absolute or a difference.
    pub const fn input(name: &'static str, meaning: &'static str) -> Param {
        Param::new(name, meaning, Unit::Input)
    }
    /// An output level or step.
    pub const fn output(name: &'static str, meaning: &'static str) -> Param {
        Param::new(name, meaning, Unit::Output)
    }
    /// A gain: output per input unit.
    pub const fn gain(name: &'static str, meaning: &'static str) -> Param {
        Param::new(name, meaning, Unit::OutputPerInput)
    }
    /// A growth per input unit.
    pub const fn per_input(name: &'static str, meaning: &'static str) -> Param {
        Param::new(name, meaning, Unit::PerInput)
    }
    /// Seconds per input unit.
    pub const fn seconds_per_input(name: &'static str, meaning: &'static str) -> Param {
        Param::new(name, meaning, Unit::SecondsPerInput)
    }
    const fn new(name: &'static str, meaning: &'static str, unit: Unit) -> Param {
        Param {
            name,
            meaning,
            unit,
        }
    }
}

/// What a parameter is measured in, as powers of the data's input and
/// output units: what a model read in other units multiplies it by
/// ([`Unit::factor`], `Model::rescaled`), and how a person reads it
/// ([`Unit::text`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Unit {
    Pure,
    Input,
    Output,
    OutputPerInput,
    PerInput,
    SecondsPerInput,
    /// The output's unit to the power −n: a Bouc-Wen loop-shape weight,
    /// whose state moves with the output, at the model's exponent `n`.
    PerOutputToThe(f64),
}

impl Unit {
    /// The factor a value in this unit takes when the input is read in
    /// units `per_input` times the fitted ones and the output `per_output`
    /// times (psi to MPa: `per_input` 0.006895).
    pub fn factor(self, per_input: f64, per_output: f64) -> f64 {
        match self {
            Unit::Pure => 1.0,
            Unit::Input => per_input,
            Unit::Output => per_output,
            Unit::OutputPerInput => per_output / per_input,
            Unit::PerInput | Unit::SecondsPerInput => 1.0 / per_input,
            Unit::PerOutputToThe(n) => per_output.powf(-n),
        }
    }

    /// The unit written with the data's `input` and `output` units
    /// (`mm/MPa`; `1` for a pure number).
    pub fn text(self, input: &str, output: &str) -> String {
        match self {
            Unit::Pure => "1".into(),
            Unit::Input => input.into(),
            Unit::Output => output.into(),
            Unit::OutputPerInput => format!("{output}/{input}"),
            Unit::PerInput => format!("1/{input}"),
            Unit::SecondsPerInput => format!("s/{input}"),
            Unit::PerOutputToThe(1.0) => format!("1/{output}"),
            Unit::PerOutputToThe(n) => format!("{output}^-{}", crate::data::readable(n)),
        }
    }
}

/// Where the diagnosis starts a realisation's fit, read off the data
/// (`diagnose::hints`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StartHint {
    /// Only the uniform draws over the box.
    None,
    /// A mode whose first two parameters are `a1`, `a2` starts ringing at
    /// the peaks of the residual's spectrum; `kick`, where present, is the
    /// parameter of the input's kick, started at its least-squares value.
    /// With `only_on_a_peak` it is tried only when the residual has such a
    /// peak.
    ResidualPeak {
        kick: Option<usize>,
        only_on_a_peak: bool,
    },
}

/// The catalogue as one list: the physical effects (each its own first
/// realisation), then the other realisations, each `Variant => entry`
/// with its doc comment. Generates [`super::Effect`] with `ALL` (this order: the
/// order reports list them, and the diagnosis tries them), `PHYSICAL`
/// (the first group) and `entry`.
macro_rules! catalogue {
    (
        physical { $( $(#[$pdoc:meta])* $p:ident => $pentry:expr, )* }
        realisations { $( $(#[$rdoc:meta])* $r:ident => $rentry:expr, )* }
    ) => {
        /// One unmodelled effect of the catalogue (a realisation of a
        /// physical effect). Flags, JSON and reports use its name, so the
        /// names are part of the interface; each variant's entry in
        /// `catalogue.rs` says everything else about it.
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
        pub enum Effect {
            $( $(#[$pdoc])* $p, )*
            $( $(#[$rdoc])* $r, )*
        }

        impl Effect {
            /// The whole catalogue, in the order reports list it.
            pub const ALL: [Effect; [$(Effect::$p,)* $(Effect::$r,)*].len()] =
                [$(Effect::$p,)* $(Effect::$r,)*];

            /// The physical effects: each is its own first realisation, and
            /// they come first in [`Effect::ALL`].
            pub const PHYSICAL: &'static [Effect] = &[$(Effect::$p,)*];

            /// The realisation's entry in the catalogue.
            pub fn entry(self) -> &'static $crate::model::effects::Realisation {
                match self {
                    $( Effect::$p => {
                        const ENTRY: $crate::model::effects::Realisation = $pentry;
                        &ENTRY
                    } )*
                    $( Effect::$r => {
                        const ENTRY: $crate::model::effects::Realisation = $rentry;
                        &ENTRY
                    } )*
                }
            }
        }
    };
}
pub(super) use catalogue;
