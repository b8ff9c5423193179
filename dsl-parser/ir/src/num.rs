//! Number formats, one place for all of them.
//!
//! - [`exact`]: the shortest text that parses back to the same `f64` — for written models
//!   (`print::to_source` and the corrected model of a diagnosis).
//! - [`sig`]: a fixed number of significant digits, plain notation where that is readable,
//!   for tables and summaries.
//! - [`pm`]: `value ± stderr`, the value rounded to the error's second significant digit.
//!
//! None of them prints `NaN` or `inf` as if it were a number: a non-finite value is written
//! as `n/a` (callers that must treat it otherwise check before formatting).

/// A number as the language writes it; parsing the text gives the same `f64` back.
pub fn exact(v: f64) -> String {
    if !v.is_finite() {
        return "n/a".into();
    }
    if v == 0.0 {
        return "0".into();
    }
    if v.fract() == 0.0 && v.abs() < 1e15 {
        return format!("{}", v as i64);
    }
    let a = v.abs();
    if (1e-4..1e15).contains(&a) {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}

/// `digits` significant digits (at least 1); plain notation for magnitudes in
/// [1e-3, 1e5), scientific otherwise. Trailing zeros are kept when `keep_zeros` is set (a
/// table column), dropped otherwise (a value in running text or a model).
pub fn sig(v: f64, digits: usize, keep_zeros: bool) -> String {
    if !v.is_finite() {
        return "n/a".into();
    }
    let digits = digits.max(1);
    if v == 0.0 {
        return if keep_zeros && digits > 1 {
            format!("{:.*}", digits - 1, 0.0)
        } else {
            "0".into()
        };
    }
    let a = v.abs();
    let text = if (1e-3..1e5).contains(&a) {
        let mag = a.log10().floor() as i32;
        let dec = (digits as i32 - 1 - mag).max(0) as usize;
        format!("{v:.dec$}")
    } else {
        format!("{v:.*e}", digits - 1)
    };
    if keep_zeros {
        text
    } else {
        trim_zeros(&text)
    }
}

/// `value ± stderr`, the value rounded to the error's second significant digit; an error
/// that is missing or not positive is written `± ?`.
pub fn pm(value: f64, stderr: f64) -> String {
    if !value.is_finite() {
        return "n/a".into();
    }
    if !stderr.is_finite() || stderr <= 0.0 {
        return format!("{} (± ?)", sig(value, 4, true));
    }
    let digits = (1 - stderr.log10().floor() as i32).clamp(0, 12) as usize;
    format!("{value:.digits$} ± {stderr:.digits$}")
}

/// Round to `digits` significant digits (the value a written model should carry when more
/// digits would only be noise).
pub fn round_sig(v: f64, digits: i32) -> f64 {
    if v == 0.0 || !v.is_finite() {
        return v;
    }
    let e = v.abs().log10().floor() - (digits - 1) as f64;
    let f = 10f64.powf(e);
    let r = (v / f).round() * f;
    // `r` carries the rounding error of the multiplication: parse its short form back.
    exact_short(r, digits)
}

fn exact_short(r: f64, digits: i32) -> f64 {
    format!("{:.*e}", (digits - 1).max(0) as usize, r)
        .parse()
        .unwrap_or(r)
}

fn trim_zeros(text: &str) -> String {
    let (mantissa, exp) = match text.find('e') {
        Some(k) => text.split_at(k),
        None => (text, ""),
    };
    let m = if mantissa.contains('.') {
        mantissa.trim_end_matches('0').trim_end_matches('.')
    } else {
        mantissa
    };
    format!("{m}{exp}")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exact_round_trips() {
        for v in [
            0.1,
            1.0 / 3.0,
            -2.5e-9,
            6.02e23,
            12345.678,
            -7.0,
            1e15,
            5e-324,
        ] {
            assert_eq!(exact(v).parse::<f64>().unwrap(), v, "{}", exact(v));
        }
        assert_eq!(exact(3.0), "3");
        assert_eq!(exact(f64::NAN), "n/a");
    }

    #[test]
    fn significant_digits() {
        assert_eq!(sig(3.98765, 4, true), "3.988");
        assert_eq!(sig(0.4, 4, true), "0.4000");
        assert_eq!(sig(0.4, 4, false), "0.4");
        assert_eq!(sig(-1234.5, 5, false), "-1234.5");
        assert_eq!(sig(2.5e-7, 3, true), "2.50e-7");
        assert_eq!(sig(2.5e-7, 3, false), "2.5e-7");
        assert_eq!(sig(f64::INFINITY, 3, false), "n/a");
        assert_eq!(pm(4.01234, 0.0123), "4.012 ± 0.012");
        assert_eq!(round_sig(1.23456, 3), 1.23);
        assert_eq!(round_sig(-0.000123456, 2), -0.00012);
    }
}
