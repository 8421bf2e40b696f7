//! The realisations' CPU stages, one [`super::stage::Stage`] each, in a
//! file per physical effect: a realisation's constants, states, start,
//! stage and restart term, the twin of its stage in
//! `shaders/effects.wgsl`. Where each runs in the step is the step order
//! in `catalogue.rs`.

mod asymmetry;
mod backlash;
mod creep;
mod deadzone;
mod delay;
mod inertia;
mod load;
mod rate;
mod saturation;
mod set;
mod softening;

pub use asymmetry::*;
pub use backlash::*;
pub use creep::*;
pub use deadzone::*;
pub use delay::*;
pub use inertia::*;
pub use load::*;
pub use rate::*;
pub use saturation::*;
pub use set::*;
pub use softening::*;
