//! The bench's fixed system delay (cables, horns, marker latency), measured on a reference target
//! at a known range.

use crate::dsp::C0;
use crate::measure::error::MeasureError;
use crate::measure::processing::pipeline::Processed;
use serde::Serialize;

/// What a calibration capture gave.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct DelayEstimate {
    pub system_delay_s: f64,
    pub reference_range_m: f64,
    /// The reference echo's range before calibration.
    pub measured_range_m: f64,
}

/// Checks the calibration inputs (before anything radiates).
pub fn check(reference_range_m: f64, search_m: f64) -> Result<(), MeasureError> {
    if !(reference_range_m.is_finite() && reference_range_m > 0.0 && reference_range_m < 100.0) {
        return Err(MeasureError::option(
            "reference-range",
            reference_range_m,
            "the reference target's range in metres, 0 < R < 100",
        ));
    }
    if !(search_m.is_finite() && search_m > 0.0 && search_m <= 100.0) {
        return Err(MeasureError::option(
            "search",
            search_m,
            "a distance in metres, 0 < search <= 100 (how far the uncalibrated echo may lie \
             beyond the true range)",
        ));
    }
    Ok(())
}

/// Uncalibrated ranges are true range + c * delay / 2: the reference is the strongest echo at or
/// beyond its true range, within `search_m` of it.
pub fn estimate_delay(
    processed: &Processed,
    reference_range_m: f64,
    search_m: f64,
) -> Result<DelayEstimate, MeasureError> {
    check(reference_range_m, search_m)?;
    let reference = processed
        .targets
        .iter()
        .filter(|t| {
            t.range_m >= reference_range_m - 0.05
                && t.range_m <= reference_range_m + search_m + 0.05
        })
        .max_by(|a, b| a.level_db.total_cmp(&b.level_db))
        .ok_or(MeasureError::NoReferenceEcho {
            from_m: reference_range_m,
            to_m: reference_range_m + search_m,
        })?;
    Ok(DelayEstimate {
        system_delay_s: 2.0 * (reference.range_m - reference_range_m) / C0,
        reference_range_m,
        measured_range_m: reference.range_m,
    })
}

/// The widest window a response calibration opens around its reference by default, seconds.
pub(crate) const MAX_DEFAULT_GATE_S: f64 = 8e-9;

/// The response calibration's default half-window around a reference at `reference_range_m`:
/// as wide as 8 ns (the chain's longer echoes), but with its taper (half as wide again) ending
/// 1 ns short of the Tx -> Rx leakage at the horns, which must stay out.
pub(crate) fn default_gate_s(reference_range_m: f64) -> f64 {
    let to_leakage = 2.0 * reference_range_m / C0;
    ((to_leakage - 1e-9) / 1.5).clamp(0.5e-9, MAX_DEFAULT_GATE_S)
}

#[cfg(test)]
mod gate_tests {
    use super::*;

    #[test]
    fn the_default_gate_keeps_the_leakage_out_and_opens_to_8_ns() {
        // 1 m: the leakage is 6.67 ns before the reference.
        let g = default_gate_s(1.0);
        assert!(1.5 * g < 2.0 / C0 - 0.99e-9 && g > 3.5e-9, "{g}");
        assert_eq!(default_gate_s(2.0), 8e-9);
        assert_eq!(default_gate_s(0.05), 0.5e-9);
    }
}
