//! The shape of a realisation's CPU stage ([`Stage`], run as an
//! [`InputLoop`], a [`StateLoop`], an [`OutputLoop`] or a [`Lane`] of a
//! shared loop) and the `stages!` macro that turns the step order in
//! `catalogue.rs` into the realisations' constants (`Stages`), their states
//! (`States`) and the pieces of [`super::Prepared::step`] and
//! [`super::Prepared::restart`] that call them: a realisation's CPU step is
//! declared once, in its stage (`stages/`), and placed once, in the order.
//!
//! Every call is to a known type and `#[inline(always)]`, so the step
//! compiles to one function, as if written out by hand: the lanes' values
//! stay in registers from stage to stage and each stage's loop over the
//! lanes compiles to vector instructions.

use super::Context;

/// What a stage may read of the dataset besides its own parameters, in
/// `f32` once per candidate.
#[derive(Debug, Clone, Copy)]
pub struct Frame {
    /// Which dataset of the model's (the load gain is per dataset).
    pub dataset: usize,
    /// [`Context::u_mean`], [`Context::y_mean`] and
    /// [`Context::branch_tol`].
    pub u_mean: f32,
    pub y_mean: f32,
    pub branch_tol: f32,
    /// +1 where the input drives the output up, −1 where down. The end
    /// stops are stored times it and applied as `toward · min(toward · x,
    /// bound)`: `max(x, b)` is `−min(−x, −b)` bit for bit (negation is
    /// exact, and ties and NaN pick the bound either way), so each stop is
    /// one lane loop with no branch on the direction: choosing per lane, or
    /// a loop per direction, is much slower (docs/PERFORMANCE.md, "Effect
    /// stages on the CPU batch path"). WGSL writes each direction out
    /// (`shaders/effects.wgsl`).
    pub toward: f32,
    /// [`Context::knee`] and [`Context::rest_input`].
    pub knee: [f32; 3],
    pub rest: f32,
    /// `1/dt`: the input rate is multiplied by it, so that no stage divides.
    pub inv_dt: f32,
}

impl Frame {
    /// The frame of dataset `dataset` with its context.
    pub fn of(ctx: &Context, dataset: usize) -> Frame {
        Frame {
            dataset,
            u_mean: ctx.u_mean as f32,
            y_mean: ctx.y_mean as f32,
            branch_tol: ctx.branch_tol as f32,
            toward: if ctx.drives_up { 1.0 } else { -1.0 },
            knee: ctx.knee(),
            rest: ctx.rest_input(),
            inv_dt: (1.0 / ctx.dt) as f32,
        }
    }
}

/// One realisation's parameters for `L` candidates: `get(j)` is its
/// parameter `j` (in vector order) of every lane.
pub struct Columns<'a, const L: usize> {
    /// `L` rows of the whole parameter vector, row-major.
    pub rows: &'a [f32],
    /// The whole vector's length.
    pub dim: usize,
    /// Where the realisation's parameters start in it.
    pub at: usize,
}

impl<const L: usize> Columns<'_, L> {
    pub fn get(&self, j: usize) -> [f32; L] {
        std::array::from_fn(|l| self.rows[l * self.dim + self.at + j])
    }
}

/// Constants that can be all zeros: what a realisation the model lacks
/// holds ([`Slot`]).
pub trait Zeroed {
    fn zeroed() -> Self;
}

impl Zeroed for f32 {
    fn zeroed() -> Self {
        0.0
    }
}

impl Zeroed for i32 {
    fn zeroed() -> Self {
        0
    }
}

impl<T: Zeroed, const N: usize> Zeroed for [T; N] {
    fn zeroed() -> Self {
        std::array::from_fn(|_| T::zeroed())
    }
}

impl<A: Zeroed, B: Zeroed> Zeroed for (A, B) {
    fn zeroed() -> Self {
        (A::zeroed(), B::zeroed())
    }
}

impl<A: Zeroed, B: Zeroed, C: Zeroed> Zeroed for (A, B, C) {
    fn zeroed() -> Self {
        (A::zeroed(), B::zeroed(), C::zeroed())
    }
}

/// One realisation's constants and whether the model has it. Where it does
/// not, they are zeros, not left unset as an `Option`'s `None` leaves its
/// payload: the compiler may compute a stage's terms before it tests
/// whether the stage is on (they are cheap and their result is dropped),
/// and stack memory that happens to read as a subnormal float makes each
/// of those operations take a microcode assist. Measured on a build whose
/// unset constants did: every free run took twice as long
/// (docs/PERFORMANCE.md, "Absent stages hold zeros").
#[derive(Debug, Clone)]
pub struct Slot<C> {
    on: bool,
    consts: C,
}

impl<C: Zeroed> Slot<C> {
    /// A realisation the model lacks.
    pub fn off() -> Self {
        Slot {
            on: false,
            consts: C::zeroed(),
        }
    }

    /// A realisation the model has, with its constants.
    pub fn on(consts: C) -> Self {
        Slot { on: true, consts }
    }

    /// Its constants, where the model has it.
    #[inline(always)]
    pub fn get(&self) -> Option<&C> {
        if self.on { Some(&self.consts) } else { None }
    }
}

/// What a stage may read of the sample being stepped, `k ≥ 1`.
pub struct At<'a, const L: usize> {
    /// The whole input (deviation coordinates) and the sample.
    pub u: &'a [f32],
    pub k: usize,
    /// The measured input `u(k−1)`.
    pub raw: f32,
    /// Whether a step was taken before this one (the play and the lags
    /// start at the first input).
    pub started: bool,
    /// The output state `x(k−1)` of every lane.
    pub x: &'a [f32; L],
    pub frame: &'a Frame,
}

/// A realisation's CPU step, the twin of its stage in
/// `shaders/effects.wgsl` (the same operations in the same order). It runs
/// as a loop over the lanes of its own on one side of the step
/// ([`InputLoop`], [`StateLoop`], [`OutputLoop`]: the signals it moves are
/// its arguments, so that each stays a local array of the step's), or as
/// one lane's part of a loop it shares ([`Lane`]); `catalogue.rs`' step
/// order says where, and the compiler checks that it is the stage's kind.
pub trait Stage<const L: usize> {
    /// What the step needs of its parameters, derived once per candidate.
    type Consts: Clone + std::fmt::Debug + Zeroed;
    /// The states it carries from sample to sample (`()` for none): whole
    /// lane arrays, or a type aligned to a cache line, so that every lane
    /// array of the effect state starts on one (docs/PERFORMANCE.md,
    /// "Effect stages on the CPU batch path").
    type State: Clone + std::fmt::Debug;

    /// Its constants from its parameters.
    fn prepare(p: &Columns<'_, L>, frame: &Frame) -> Self::Consts;

    /// Its states at the first sample, from the output state `x` and the
    /// first input `u0`; `c` is `None` where the model lacks it, and then
    /// its restart term must leave the output as it is.
    fn start(c: Option<&Self::Consts>, x: &[f32; L], u0: f32) -> Self::State;

    /// Its term in a restart of lane `l` to the measurement `y`: the output
    /// state `x` less what the stage adds to the output; it may restart its
    /// states. Without one, its states run on.
    #[inline(always)]
    fn restart(_s: &mut Self::State, _l: usize, _y: f32, x: f32) -> f32 {
        x
    }
}

/// A stage on the input side that is a loop over the lanes of its own,
/// moving the input `ui`. A new realisation's stage is a loop of its own
/// (a loop with more stages in it than the first realisations' four no
/// longer compiled to vector code).
pub trait InputLoop<const L: usize>: Stage<L> {
    fn apply(c: &Self::Consts, s: &mut Self::State, ui: &mut [f32; L], at: &At<'_, L>);
}

/// A stage on the state side after its shared loop, moving the new output
/// state `xk` or the Bouc-Wen stiffness `a_eff` of the step.
pub trait StateLoop<const L: usize>: Stage<L> {
    fn apply(
        c: &Self::Consts,
        s: &mut Self::State,
        xk: &mut [f32; L],
        a_eff: &mut [f32; L],
        at: &At<'_, L>,
    );
}

/// A stage on the output side, moving the predicted output `y`; `ui` is
/// the input after the input side and `xk` the new output state.
pub trait OutputLoop<const L: usize>: Stage<L> {
    fn apply(
        c: &Self::Consts,
        s: &mut Self::State,
        y: &mut [f32; L],
        ui: &[f32; L],
        xk: &[f32; L],
        at: &At<'_, L>,
    );
}

/// A stage that shares one loop over the lanes with its neighbours, so
/// that the lane's value stays in registers between them: the input
/// side's first realisations, and the state side's (with the baseline's
/// linear part).
pub trait Lane<const L: usize>: Stage<L> {
    /// Once per sample, before the shared loop: what is the same in every
    /// lane.
    #[inline(always)]
    fn before(_c: &Self::Consts, _s: &mut Self::State, _at: &At<'_, L>) {}

    /// Lane `l`'s value `v` after the stage.
    fn lane(c: &Self::Consts, s: &mut Self::State, l: usize, v: f32, at: &At<'_, L>) -> f32;

    /// Once per sample, after the shared loop. A state that the loop only
    /// reads moves on here: a store in the loop is compiled to a masked
    /// store that runs whether or not the model has the stage (the
    /// inertia's would add instructions to every model's step; the play's
    /// output is needed in the loop, so its store stays there).
    #[inline(always)]
    fn after(_c: &Self::Consts, _s: &mut Self::State, _at: &At<'_, L>) {}
}

/// The side of the step a stage moves: the input (an `InputLoop` or an
/// input `Lane`), the new output state and the Bouc-Wen stiffness (a
/// `StateLoop` or a state `Lane`), or the predicted output (an
/// `OutputLoop`). The WGSL step has one signature per side
/// (`eval::gpu::stages`, `shaders/effects.wgsl`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Side {
    Input,
    State,
    Output,
}

/// A realisation's place in the step order, as the GPU's step is
/// generated from it: the realisation (`E`: the catalogue's enum, as in
/// [`super::table::Realisation`]), the side it moves, and whether its
/// stage carries states (its [`Stage::State`] is not `()`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Placed<E> {
    pub effect: E,
    pub side: Side,
    pub stateful: bool,
}

/// `a` if it is the larger (ties and NaN: `b`), spelled as in the shader.
#[inline(always)]
pub fn larger(a: f32, b: f32) -> f32 {
    if a > b { a } else { b }
}

/// `a` if it is the smaller (ties and NaN: `b`), spelled as in the shader.
#[inline(always)]
pub fn smaller(a: f32, b: f32) -> f32 {
    if a < b { a } else { b }
}

/// The step order: every realisation once, by the name of its variant
/// (which is its stage's type), in the slot of the step it runs in and in
/// the order it runs there. Generates `Stages<L>` (each realisation's
/// constants in a [`Slot`], off where the model lacks it), `States<L>`
/// (each one's states, in this order), and on `Stages` `prepare`, `start`,
/// the sides of the step (`input`, `state_before`, `state_lane`,
/// `state_after`, `state`, `output`) and `restart` (the terms in this
/// order), and `STEP_ORDER`, the order as data ([`Placed`]), which the
/// GPU's step is generated from. The types and traits of this file it
/// names must be in scope where it is used.
macro_rules! stages {
    (
        input: $($input:ident),* ;
        input_lanes: $($input_lane:ident),* ;
        input_late: $($input_late:ident),* ;
        state_lanes: $($state_lane:ident),* ;
        state: $($state:ident),* ;
        output: $($output:ident),* ;
    ) => {
        /// Each realisation's constants for `L` candidates, off where the
        /// model lacks it. (Fields are named by the variants, which the
        /// stages' types are named by.)
        #[allow(non_snake_case)]
        #[derive(Debug, Clone)]
        pub struct Stages<const L: usize> {
            $( $input: Slot<<$input as Stage<L>>::Consts>, )*
            $( $input_lane: Slot<<$input_lane as Stage<L>>::Consts>, )*
            $( $input_late: Slot<<$input_late as Stage<L>>::Consts>, )*
            $( $state_lane: Slot<<$state_lane as Stage<L>>::Consts>, )*
            $( $state: Slot<<$state as Stage<L>>::Consts>, )*
            $( $output: Slot<<$output as Stage<L>>::Consts>, )*
        }

        /// Each realisation's states, in the step's order (`repr(C)`: see
        /// [`Stage::State`]).
        #[allow(non_snake_case)]
        #[derive(Debug, Clone)]
        #[repr(C)]
        pub struct States<const L: usize> {
            $( $input: <$input as Stage<L>>::State, )*
            $( $input_lane: <$input_lane as Stage<L>>::State, )*
            $( $input_late: <$input_late as Stage<L>>::State, )*
            $( $state_lane: <$state_lane as Stage<L>>::State, )*
            $( $state: <$state as Stage<L>>::State, )*
            $( $output: <$output as Stage<L>>::State, )*
        }

        /// The step order as data: every realisation in the order the
        /// step runs it, with the side it moves and whether it carries
        /// states.
        pub const STEP_ORDER: &[Placed<Effect>] = &[
            $( placed::<$input>(Effect::$input, Side::Input), )*
            $( placed::<$input_lane>(Effect::$input_lane, Side::Input), )*
            $( placed::<$input_late>(Effect::$input_late, Side::Input), )*
            $( placed::<$state_lane>(Effect::$state_lane, Side::State), )*
            $( placed::<$state>(Effect::$state, Side::State), )*
            $( placed::<$output>(Effect::$output, Side::Output), )*
        ];

        /// `effect`'s place, its stage `S` carrying states unless they
        /// are `()`.
        const fn placed<S: Stage<1>>(effect: Effect, side: Side) -> Placed<Effect> {
            Placed {
                effect,
                side,
                stateful: std::mem::size_of::<S::State>() != 0,
            }
        }

        impl<const L: usize> Stages<L> {
            /// No realisation.
            pub fn none() -> Self {
                Stages {
                    $( $input: Slot::off(), )*
                    $( $input_lane: Slot::off(), )*
                    $( $input_late: Slot::off(), )*
                    $( $state_lane: Slot::off(), )*
                    $( $state: Slot::off(), )*
                    $( $output: Slot::off(), )*
                }
            }

            /// Adds realisation `e` with its parameters `p`.
            pub fn prepare(&mut self, e: Effect, p: &Columns<'_, L>, frame: &Frame) {
                match e {
                    $( Effect::$input => self.$input = Slot::on(<$input as Stage<L>>::prepare(p, frame)), )*
                    $( Effect::$input_lane => self.$input_lane = Slot::on(<$input_lane as Stage<L>>::prepare(p, frame)), )*
                    $( Effect::$input_late => self.$input_late = Slot::on(<$input_late as Stage<L>>::prepare(p, frame)), )*
                    $( Effect::$state_lane => self.$state_lane = Slot::on(<$state_lane as Stage<L>>::prepare(p, frame)), )*
                    $( Effect::$state => self.$state = Slot::on(<$state as Stage<L>>::prepare(p, frame)), )*
                    $( Effect::$output => self.$output = Slot::on(<$output as Stage<L>>::prepare(p, frame)), )*
                }
            }

            /// Every realisation's states at the first sample.
            #[inline(always)]
            pub fn start(&self, x: &[f32; L], u0: f32) -> States<L> {
                States {
                    $( $input: <$input as Stage<L>>::start(self.$input.get(), x, u0), )*
                    $( $input_lane: <$input_lane as Stage<L>>::start(self.$input_lane.get(), x, u0), )*
                    $( $input_late: <$input_late as Stage<L>>::start(self.$input_late.get(), x, u0), )*
                    $( $state_lane: <$state_lane as Stage<L>>::start(self.$state_lane.get(), x, u0), )*
                    $( $state: <$state as Stage<L>>::start(self.$state.get(), x, u0), )*
                    $( $output: <$output as Stage<L>>::start(self.$output.get(), x, u0), )*
                }
            }

            /// The input side: its loops, the shared loop, its late loops.
            #[inline(always)]
            pub fn input(&self, s: &mut States<L>, ui: &mut [f32; L], at: &At<'_, L>) {
                $( if let Some(c) = self.$input.get() {
                    <$input as InputLoop<L>>::apply(c, &mut s.$input, ui, at);
                } )*
                $( if let Some(c) = self.$input_lane.get() {
                    <$input_lane as Lane<L>>::before(c, &mut s.$input_lane, at);
                } )*
                for l in 0..L {
                    let mut v = ui[l];
                    $( if let Some(c) = self.$input_lane.get() {
                        v = <$input_lane as Lane<L>>::lane(c, &mut s.$input_lane, l, v, at);
                    } )*
                    ui[l] = v;
                }
                $( if let Some(c) = self.$input_lane.get() {
                    <$input_lane as Lane<L>>::after(c, &mut s.$input_lane, at);
                } )*
                $( if let Some(c) = self.$input_late.get() {
                    <$input_late as InputLoop<L>>::apply(c, &mut s.$input_late, ui, at);
                } )*
            }

            /// What the state side's shared loop needs before it, once
            /// per sample.
            #[inline(always)]
            pub fn state_before(&self, s: &mut States<L>, at: &At<'_, L>) {
                $( if let Some(c) = self.$state_lane.get() {
                    <$state_lane as Lane<L>>::before(c, &mut s.$state_lane, at);
                } )*
            }

            /// What the state side's shared loop moves after it, once per
            /// sample.
            #[inline(always)]
            pub fn state_after(&self, s: &mut States<L>, at: &At<'_, L>) {
                $( if let Some(c) = self.$state_lane.get() {
                    <$state_lane as Lane<L>>::after(c, &mut s.$state_lane, at);
                } )*
            }

            /// Lane `l` of the state side's shared loop on the baseline's
            /// new output state `x`.
            #[inline(always)]
            pub fn state_lane(&self, s: &mut States<L>, l: usize, x: f32, at: &At<'_, L>) -> f32 {
                let mut v = x;
                $( if let Some(c) = self.$state_lane.get() {
                    v = <$state_lane as Lane<L>>::lane(c, &mut s.$state_lane, l, v, at);
                } )*
                v
            }

            /// The state side's loops, after its shared loop.
            #[inline(always)]
            pub fn state(
                &self,
                s: &mut States<L>,
                xk: &mut [f32; L],
                a_eff: &mut [f32; L],
                at: &At<'_, L>,
            ) {
                $( if let Some(c) = self.$state.get() {
                    <$state as StateLoop<L>>::apply(c, &mut s.$state, xk, a_eff, at);
                } )*
            }

            /// The output side.
            #[inline(always)]
            pub fn output(
                &self,
                s: &mut States<L>,
                y: &mut [f32; L],
                ui: &[f32; L],
                xk: &[f32; L],
                at: &At<'_, L>,
            ) {
                $( if let Some(c) = self.$output.get() {
                    <$output as OutputLoop<L>>::apply(c, &mut s.$output, y, ui, xk, at);
                } )*
            }

            /// Lane `l`'s output state restarted at the measurement `y`:
            /// `y` less every realisation's term, in the step's order.
            #[inline(always)]
            pub fn restart(s: &mut States<L>, l: usize, y: f32) -> f32 {
                let x = y;
                $( let x = <$input as Stage<L>>::restart(&mut s.$input, l, y, x); )*
                $( let x = <$input_lane as Stage<L>>::restart(&mut s.$input_lane, l, y, x); )*
                $( let x = <$input_late as Stage<L>>::restart(&mut s.$input_late, l, y, x); )*
                $( let x = <$state_lane as Stage<L>>::restart(&mut s.$state_lane, l, y, x); )*
                $( let x = <$state as Stage<L>>::restart(&mut s.$state, l, y, x); )*
                $( let x = <$output as Stage<L>>::restart(&mut s.$output, l, y, x); )*
                x
            }
        }
    };
}
pub(super) use stages;
