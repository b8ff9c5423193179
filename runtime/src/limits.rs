//! Work and memory estimated before a long run, and the limits above which a run is
//! refused unless the caller allows it: a mistyped factor (`--substeps 1000000`) should be
//! an error naming the cost, not hours of computing or an abort when memory runs out.

/// Most RK4 steps of a simulation (all levels together) run without an explicit
/// allowance: `MAX_STEPS / STEPS_PER_SECOND` ≈ 10 minutes on one core for a small model;
/// the default `dynid simulate` of a three-level model takes 1.3·10⁷ steps.
pub const MAX_STEPS: f64 = 1e10;

/// RK4 steps per second of a one-body model on one core, for turning a step count into
/// time: `dynid simulate models/sdof_cubic_coulomb.dyn --duration 2000 --substeps 200
/// --levels 1 --out D` (release build) takes 4.2·10⁷ steps in 2.4 s of CPU time. Larger
/// models are slower, so estimates from it are lower bounds.
pub const STEPS_PER_SECOND: f64 = 1.7e7;

/// Most memory one buffer set may take without an explicit allowance: 8 GB.
pub const MAX_BYTES: f64 = 8e9;

/// A duration in words: `about 3.2 hours`.
pub fn duration_in_words(seconds: f64) -> String {
    let (v, unit) = if seconds < 120.0 {
        (seconds, "seconds")
    } else if seconds < 7200.0 {
        (seconds / 60.0, "minutes")
    } else if seconds < 2.0 * 86400.0 {
        (seconds / 3600.0, "hours")
    } else if seconds < 2.0 * 365.25 * 86400.0 {
        (seconds / 86400.0, "days")
    } else {
        (seconds / (365.25 * 86400.0), "years")
    };
    format!("about {} {unit}", dynid_ir::num::sig(v, 2, false))
}

/// A size in bytes in words: `about 69 GB`.
pub fn bytes_in_words(bytes: f64) -> String {
    let (v, unit) = if bytes < 1e6 {
        (bytes / 1e3, "kB")
    } else if bytes < 1e9 {
        (bytes / 1e6, "MB")
    } else if bytes < 1e12 {
        (bytes / 1e9, "GB")
    } else {
        (bytes / 1e12, "TB")
    };
    format!("about {} {unit}", dynid_ir::num::sig(v, 2, false))
}

/// `steps` RK4 steps in words: `about 3.2 hours of simulation (1.8e11 RK4 steps)`.
pub fn steps_in_words(steps: f64) -> String {
    format!(
        "{} of simulation ({steps:.1e} RK4 steps)",
        duration_in_words(steps / STEPS_PER_SECOND)
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_and_durations_read_in_the_units_people_use() {
        assert_eq!(duration_in_words(30.0), "about 30 seconds");
        assert_eq!(duration_in_words(11520.0), "about 3.2 hours");
        assert_eq!(duration_in_words(3.0 * 86400.0), "about 3 days");
        assert_eq!(bytes_in_words(6.9e10), "about 69 GB");
        assert_eq!(bytes_in_words(2.5e5), "about 250 kB");
    }
}
