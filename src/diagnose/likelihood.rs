//! The likelihood-ratio test at 95 % on an estimation SSE: the one
//! threshold below which the estimation data cannot tell two fits apart. The
//! profile intervals (`interval`), the seed spread (`fitting::SeededFit`)
//! and the ties of the final refits (`refits`) all use it; it is defined
//! once, with the fit measures (`ident::fit`), where the generated cases'
//! judge uses it too.

pub(super) use crate::ident::fit::{CHI2_1_95, indistinguishable_up_to};
