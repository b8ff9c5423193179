//! Descriptive statistics of one column of samples — one definition for every module.

/// Arithmetic mean; 0 for an empty column.
pub fn mean(x: &[f64]) -> f64 {
    if x.is_empty() {
        return 0.0;
    }
    x.iter().sum::<f64>() / x.len() as f64
}

/// Population standard deviation (divides by n); 0 for an empty column.
pub fn std_dev(x: &[f64]) -> f64 {
    if x.is_empty() {
        return 0.0;
    }
    let m = mean(x);
    (x.iter().map(|v| (v - m) * (v - m)).sum::<f64>() / x.len() as f64).sqrt()
}

#[cfg(test)]
mod tests {
    #[test]
    fn population_moments() {
        let x = [1.0, 2.0, 3.0, 4.0];
        assert_eq!(super::mean(&x), 2.5);
        assert!((super::std_dev(&x) - 1.25f64.sqrt()).abs() < 1e-15);
        assert_eq!(super::std_dev(&[]), 0.0);
    }
}
