//! Linear identification (§4.3): ARX least squares and the fit measures.

pub mod arx;
pub mod fit;

pub use arx::{Arx, ArxOrders};
pub use fit::{fit_percent, loop_area, pooled_fit_percent, rmse};
