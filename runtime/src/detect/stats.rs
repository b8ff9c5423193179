//! Tail probabilities for the tests of detection (χ² and F) and erfc, from `statrs`.
//! A distribution with invalid degrees of freedom gives NaN, which the callers treat as
//! "no test".

use statrs::distribution::{ChiSquared, ContinuousCDF, FisherSnedecor};

/// Complementary error function.
pub fn erfc(x: f64) -> f64 {
    statrs::function::erf::erfc(x)
}

/// P(χ²_dof > x).
pub fn chi2_sf(x: f64, dof: f64) -> f64 {
    ChiSquared::new(dof).map_or(f64::NAN, |d| d.sf(x.max(0.0)))
}

/// P(F_{d1,d2} > f).
pub fn f_sf(f: f64, d1: f64, d2: f64) -> f64 {
    if f <= 0.0 {
        return 1.0;
    }
    FisherSnedecor::new(d1, d2).map_or(f64::NAN, |d| d.sf(f))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_values() {
        // erfc(1) = 0.157299207050285130658...; statrs 0.18 is off by 7.0e-12 here and by
        // 4.9e-11 at −0.5 (far below what the templates need: their fits carry errors of 1e-2).
        assert!((erfc(1.0) - 0.157_299_207_050_285_13).abs() < 2e-11);
        assert!((erfc(-0.5) - 1.520_499_877_813_046_5).abs() < 1.5e-10);
        assert!((erfc(4.0) - 1.541_725_790_028_002e-8).abs() < 1e-18); // statrs: 3.8e-19
                                                                       // χ²: P(χ²_1 > 3.841458820694124) = 0.05, P(χ²_4 > 18.46682695) = 0.001.
        assert!((chi2_sf(3.841_458_820_694_124, 1.0) - 0.05).abs() < 1e-12);
        assert!((chi2_sf(18.466_826_952_903_15, 4.0) - 0.001).abs() < 1e-12);
        // F: the 0.001 upper quantile of F(2, 9) is 16.387..., exact sf = (1 + 2f/9)^(-4.5).
        let f = 16.387_0;
        let exact = (1.0 + 2.0 * f / 9.0f64).powf(-4.5);
        assert!((f_sf(f, 2.0, 9.0) - exact).abs() < 1e-13);
        // F(1, d2) tail equals the two-sided t tail: P(|t_9| > 3.2498355) = 0.01.
        assert!((f_sf(3.249_835_541_592_7f64.powi(2), 1.0, 9.0) - 0.01).abs() < 1e-9);
    }
}
