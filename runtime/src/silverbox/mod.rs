//! The Silverbox benchmark (Wigren & Schoukens 2013): a real electronic Duffing oscillator,
//! `m y'' + d y' + (a + b y²) y = u`, measured as input voltage `V1 = u` and output voltage
//! `V2 = y` only.
//!
//! Procedure (see `docs/silverbox.md`): load `SNLS80mV.csv`, remove the means of both
//! columns, find the ten multisine realisations after the arrow from the pauses of the input
//! (runs of near-zero input), identify on the first 75 % of the multisine samples (one
//! level per realisation, so each realisation's start-up transient is covered by the
//! finite-record boundary terms), and score the identified continuous-time model by
//! free-run simulation driven by the measured input: on the arrow (the first 40 000
//! samples, from rest) and on the last 25 % of the multisine samples.
//!
//! The parts: `data` (loading, the realisations and the split, records of sample ranges,
//! band-limited upsampling), `procedure` (identification on the estimation parts and the
//! free-run scores), `arrow` (the arrow cut into levels of growing amplitude, for detection),
//! `error` (what the procedure refuses).

mod arrow;
mod data;
mod error;
mod procedure;

pub use arrow::{arrow_level_fits, arrow_levels, ArrowLevel};
pub use data::{
    check_work, find_realisations, load, record, record_upsampled, split, Segment, SilverboxData,
    Split,
};
pub use data::{ARROW_LEN, FILE, MIN_REALISATION, PAUSE_LEVEL, PAUSE_MIN_LEN, TEST_SHARE, TS};
pub use error::SilverboxError;
pub use procedure::{
    default_options, free_run_rms, identify_estimation, run, with_estimates, RefinedReport,
    RunOptions, SilverboxReport, PUBLISHED,
};

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn realisations_between_pauses() {
        let mut u = vec![0.05; 100];
        u.extend(vec![0.0; 30]);
        u.extend((0..6000).map(|k| if k % 2 == 0 { 0.02 } else { -0.02 }));
        u.extend(vec![0.0; 25]);
        u.extend(vec![0.03; 5500]);
        u.extend(vec![0.0; 40]);
        u.extend(vec![0.03; 100]);
        let r = find_realisations(&u, 50);
        assert_eq!(
            r,
            vec![
                Segment {
                    start: 130,
                    end: 6130
                },
                Segment {
                    start: 6155,
                    end: 11655
                }
            ]
        );
    }
}
