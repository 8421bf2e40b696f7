//! Numbers in the data's own units, written so that they read alike
//! whatever those units are.

/// Significant digits a figure keeps however small it is.
const SIGNIFICANT: i32 = 4;

/// `v` with `decimals` decimals, or with as many more as it takes to show
/// four significant digits: an RMSE of 0.0016 m reads `0.001589` where four
/// decimals would print `0.0016`, and a floor of 3·10⁻⁵ m `0.00003030`
/// where they would print `0.0000`. Below 10⁻⁶ in magnitude it is written
/// in scientific notation.
pub fn significant(v: f64, decimals: usize) -> String {
    if !v.is_finite() || v == 0.0 {
        return format!("{v:.decimals$}");
    }
    let magnitude = v.abs().log10().floor() as i32;
    if magnitude < -6 {
        return format!("{:.*e}", (SIGNIFICANT - 1) as usize, v);
    }
    let needed = (SIGNIFICANT - 1 - magnitude).max(0) as usize;
    format!("{v:.*}", decimals.max(needed))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn small_figures_keep_four_significant_digits_and_large_ones_their_decimals() {
        assert_eq!(significant(1.50317, 4), "1.5032");
        assert_eq!(significant(2768.31, 1), "2768.3");
        assert_eq!(significant(0.15, 4), "0.1500");
        assert_eq!(significant(0.0303127, 4), "0.03031");
        assert_eq!(significant(0.00158937, 4), "0.001589");
        assert_eq!(significant(-0.00158937, 4), "-0.001589");
        assert_eq!(significant(2.3e-5, 3), "0.00002300");
        assert_eq!(significant(1.234e-9, 4), "1.234e-9");
        assert_eq!(significant(0.0, 4), "0.0000");
        assert_eq!(significant(f64::INFINITY, 4), "inf");
    }
}
