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

/// An uncertainty with two significant digits (`0.0021`, `0.44`, `12`):
/// its own uncertainty makes more digits noise. Below 10⁻⁶ in magnitude it
/// is written in scientific notation.
pub fn uncertainty(v: f64) -> String {
    if !v.is_finite() || v == 0.0 {
        return format!("{v}");
    }
    let magnitude = v.abs().log10().floor() as i32;
    if magnitude < -6 {
        return format!("{v:.1e}");
    }
    format!("{v:.*}", (1 - magnitude).max(0) as usize)
}

/// `cells`, figures as [`significant`] writes them, padded to one width
/// with their decimal points in one column: a parameter of `0.000004685`
/// under one of `18.901187` reads as a column of numbers, where right
/// alignment would put their last digits, not their points, one under the
/// other. A cell without a point (`inf`, `NaN`) lines up as a whole number.
pub fn decimal_column(cells: &[String]) -> Vec<String> {
    let split = |c: &str| c.find('.').map_or((c.len(), 0), |p| (p, c.len() - p));
    let (whole, fraction) = cells.iter().fold((0, 0), |(w, f), c| {
        let (cw, cf) = split(c);
        (w.max(cw), f.max(cf))
    });
    cells
        .iter()
        .map(|c| {
            let (cw, cf) = split(c);
            format!("{}{c}{}", " ".repeat(whole - cw), " ".repeat(fraction - cf))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_decimal_column_puts_every_point_under_the_first() {
        let cells: Vec<String> = ["18.901187", "0.000004685", "-510.8", "1.234e-9", "inf"]
            .iter()
            .map(|c| c.to_string())
            .collect();
        let column = decimal_column(&cells);
        assert_eq!(
            column,
            [
                "  18.901187   ",
                "   0.000004685",
                "-510.8        ",
                "   1.234e-9   ",
                " inf          ",
            ]
        );
        let width = column[0].len();
        assert!(column.iter().all(|c| c.len() == width));
    }

    #[test]
    fn an_uncertainty_keeps_two_significant_digits() {
        assert_eq!(uncertainty(0.0020961), "0.0021");
        assert_eq!(uncertainty(0.4435), "0.44");
        assert_eq!(uncertainty(0.3), "0.30");
        assert_eq!(uncertainty(12.34), "12");
        assert_eq!(uncertainty(1234.5), "1234");
        assert_eq!(uncertainty(2.3e-8), "2.3e-8");
        assert_eq!(uncertainty(0.0), "0");
    }

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
