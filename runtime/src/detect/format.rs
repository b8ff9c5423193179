//! The number formats of detection's text: a value with its standard error, and four
//! significant digits.

use dynid_ir::num;

/// `value ± stderr` with the value rounded to the stderr's second significant digit.
pub fn fmt_pm(value: f64, stderr: f64) -> String {
    num::pm(value, stderr)
}

/// Four significant digits, plain notation where readable.
pub fn fmt_g(x: f64) -> String {
    num::sig(x, 4, true)
}
