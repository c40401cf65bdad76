//! Numbers as benchmark tables and plots show them: 4 significant digits ([`num`]), the
//! same without trailing zeros for commands and prose ([`arg`]), short axis labels
//! ([`label`]), `mean ± std` ([`pm`], [`pm_count`]). A leaf: tables (`outputs`), plots
//! (`plot`) and reports use it.

use super::metrics::Spread;

/// A number with 4 significant digits, in `e` notation when tiny or huge.
#[must_use]
pub fn num(v: f64) -> String {
    let a = v.abs();
    if v == 0.0 {
        "0".into()
    } else if !v.is_finite() {
        format!("{v}")
    } else if !(1e-3..1e5).contains(&a) {
        format!("{v:.3e}")
    } else {
        let decimals = (3 - a.log10().floor() as i32).max(0) as usize;
        format!("{v:.decimals$}")
    }
}

/// A number for a command line or a sentence: [`num`] without trailing zeros.
#[must_use]
pub fn arg(v: f64) -> String {
    let s = num(v);
    if s.contains('.') && !s.contains('e') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

/// A short axis label: 3 significant digits, trailing zeros dropped.
#[must_use]
pub fn label(v: f64) -> String {
    let a = v.abs();
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    if !(1e-3..1e5).contains(&a) {
        let s = format!("{v:.1e}");
        return s.replace(".0e", "e");
    }
    let decimals = (2 - a.log10().floor() as i32).max(0) as usize;
    let s = format!("{v:.decimals$}");
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

/// `mean ± std` with [`num`].
#[must_use]
pub fn pm(s: &Spread) -> String {
    if s.n > 1 {
        format!("{} ± {}", num(s.mean), num(s.std))
    } else {
        num(s.mean)
    }
}

/// `mean ± std` of a count: whole numbers when every run agrees.
#[must_use]
pub fn pm_count(s: &Spread) -> String {
    if s.std == 0.0 && s.mean.fract() == 0.0 {
        format!("{:.0}", s.mean)
    } else {
        format!("{:.1} ± {:.1}", s.mean, s.std)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_keep_four_digits() {
        assert_eq!(num(0.0), "0");
        assert_eq!(num(0.012345), "0.01235");
        assert_eq!(num(12.3456), "12.35");
        assert_eq!(num(1234.56), "1235");
        assert_eq!(num(1.5e-7), "1.500e-7");
        assert_eq!(label(50.0), "50");
        assert_eq!(label(0.125), "0.125");
        assert_eq!(label(2e-5), "2e-5");
        assert_eq!(pm_count(&Spread { mean: 75.0, std: 0.0, n: 3 }), "75");
    }
}
