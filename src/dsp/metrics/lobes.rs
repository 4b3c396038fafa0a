//! Main-lobe width and side-lobe levels of a single-target profile.

use super::peaks::{interpolate_peak, Interpolation};

/// Width of the main lobe at -3 dB (half power), in samples, with the crossing on each side placed
/// by linear interpolation of the magnitude between the samples that bracket `peak_value / sqrt 2`.
/// `peak_value` should be the interpolated peak height ([`interpolate_peak`]); returns `None` when
/// the lobe does not fall to -3 dB before an end of the profile. Multiply by the axis step for metres.
pub fn width_3db(amplitude: &[f64], peak_index: usize, peak_value: f64) -> Option<f64> {
    let level = peak_value * std::f64::consts::FRAC_1_SQRT_2;
    let mut left = None;
    for i in (0..peak_index).rev() {
        if amplitude[i] < level {
            let (lo, hi) = (amplitude[i], amplitude[i + 1]);
            left = Some(i as f64 + (level - lo) / (hi - lo));
            break;
        }
    }
    let mut right = None;
    for i in peak_index + 1..amplitude.len() {
        if amplitude[i] < level {
            let (hi, lo) = (amplitude[i - 1], amplitude[i]);
            right = Some((i - 1) as f64 + (hi - level) / (hi - lo));
            break;
        }
    }
    Some(right? - left?)
}

/// Side-lobe levels around one main lobe.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SidelobeLevels {
    /// Peak side-lobe level: the highest point outside the first nulls, relative to the main peak,
    /// in dB (negative). The side-lobe's own top is interpolated like the main peak.
    pub psl_db: f64,
    /// Integrated side-lobe level: power outside the first nulls over power inside them, in dB.
    pub isl_db: f64,
    /// Sample index of the highest side-lobe sample.
    pub sidelobe_index: usize,
    /// The first nulls (local minima) on each side of the main peak: the main lobe is
    /// `null_left..=null_right`.
    pub null_left: usize,
    pub null_right: usize,
}

/// Peak and integrated side-lobe levels of the main lobe at `peak_index` of a linear-amplitude
/// profile. `None` when no sample lies outside the first nulls.
pub fn sidelobe_levels(
    amplitude: &[f64],
    peak_index: usize,
    interpolation: Interpolation,
) -> Option<SidelobeLevels> {
    let n = amplitude.len();
    let mut null_left = peak_index;
    while null_left > 0 && amplitude[null_left - 1] < amplitude[null_left] {
        null_left -= 1;
    }
    let mut null_right = peak_index;
    while null_right + 1 < n && amplitude[null_right + 1] < amplitude[null_right] {
        null_right += 1;
    }
    let outside = (0..null_left).chain(null_right + 1..n);
    let sidelobe_index = outside.max_by(|&a, &b| amplitude[a].total_cmp(&amplitude[b]))?;
    let (_, main) = interpolate_peak(amplitude, peak_index, interpolation);
    let (_, side) = interpolate_peak(amplitude, sidelobe_index, interpolation);
    let power = |r: std::ops::Range<usize>| amplitude[r].iter().map(|a| a * a).sum::<f64>();
    let inside = power(null_left..null_right + 1);
    let outside = power(0..null_left) + power(null_right + 1..n);
    Some(SidelobeLevels {
        psl_db: 20.0 * (side / main).log10(),
        isl_db: 10.0 * (outside / inside).log10(),
        sidelobe_index,
        null_left,
        null_right,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sinc_profile(x0: f64, step: f64, n: usize) -> Vec<f64> {
        let sinc = |x: f64| if x.abs() < 1e-12 { 1.0 } else { x.sin() / x };
        (0..n)
            .map(|i| sinc((i as f64 - x0) * step * std::f64::consts::PI).abs())
            .collect()
    }

    #[test]
    fn sinc_width_and_psl_are_textbook_values() {
        // sinc(pi x) has its -3 dB width at 0.8859 and side-lobes at -13.26 dB.
        let step = 0.01;
        let v = sinc_profile(500.3, step, 1000);
        let (_, h) = interpolate_peak(&v, 500, Interpolation::ParabolicDb);
        let w = width_3db(&v, 500, h).unwrap() * step;
        assert!((w - 0.8859).abs() < 1e-3, "width {w}");
        let s = sidelobe_levels(&v, 500, Interpolation::ParabolicDb).unwrap();
        assert!((s.psl_db + 13.26).abs() < 0.02, "psl {}", s.psl_db);
        // Five side-lobes each side of a sinc hold about 6 % of the power of the main lobe.
        assert!(s.isl_db < -9.0 && s.isl_db > -13.5, "isl {}", s.isl_db);
        assert!((s.null_right as f64 - 600.3).abs() < 1.0);
    }

    #[test]
    fn lobe_running_off_the_end_has_no_width() {
        let v = [1.0, 0.9, 0.8];
        assert_eq!(width_3db(&v, 0, 1.0), None);
        assert!(sidelobe_levels(&v, 0, Interpolation::None).is_none());
    }
}
