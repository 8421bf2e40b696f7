//! Output for people and scripts: figures (SVG) and small table helpers.

pub mod fit;
pub mod history;
pub mod json;
pub mod number;
pub mod plot;

pub use fit::fit_figures;
pub use plot::{Figure, Panel, Series};
