//! Output for people and scripts: figures (SVG) and small table helpers.

pub mod plot;

pub use plot::{Figure, Panel, Series};
