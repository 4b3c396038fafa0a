//! Peak detection with prominence and sub-sample peak interpolation.

use super::db::amplitude_db;

/// A local maximum of a sampled profile.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Peak {
    /// Sample index of the maximum (the middle sample of a flat top).
    pub index: usize,
    /// The sample's value, in the scale that was searched.
    pub value: f64,
    /// Prominence (scipy.signal.peak_prominences): height above the higher of the two lowest points
    /// reached on each side before a higher sample or the end of the profile. Same scale as `value`,
    /// so searching a dB profile gives prominence in dB.
    pub prominence: f64,
}

/// Indices of the local maxima of `values` (the middle sample of a flat top; never the first or
/// last sample), ascending, without computing prominences: O(n).
pub(crate) fn local_maxima(values: &[f64]) -> impl Iterator<Item = usize> + '_ {
    let n = values.len();
    let mut i = 1;
    std::iter::from_fn(move || {
        while i + 1 < n {
            if values[i] > values[i - 1] {
                let mut j = i;
                while j + 1 < n && values[j + 1] == values[i] {
                    j += 1;
                }
                let top = (i + j) / 2;
                let is_peak = j + 1 < n && values[j + 1] < values[i];
                i = j + 1;
                if is_peak {
                    return Some(top);
                }
            } else {
                i += 1;
            }
        }
        None
    })
}

/// Local maxima of `values` with prominence at least `min_prominence`, in ascending index order.
///
/// The first and last samples are never peaks (their neighbourhood is unknown). Flat tops count
/// once, at their middle sample. Cost O(n * typical peak reach).
pub fn find_peaks(values: &[f64], min_prominence: f64) -> Vec<Peak> {
    let n = values.len();
    let mut peaks = Vec::new();
    let mut i = 1;
    while i + 1 < n {
        if values[i] > values[i - 1] {
            // Skip a plateau.
            let mut j = i;
            while j + 1 < n && values[j + 1] == values[i] {
                j += 1;
            }
            if j + 1 < n && values[j + 1] < values[i] {
                let index = (i + j) / 2;
                let prominence = prominence(values, i, j);
                if prominence >= min_prominence {
                    peaks.push(Peak {
                        index,
                        value: values[index],
                        prominence,
                    });
                }
            }
            i = j + 1;
        } else {
            i += 1;
        }
    }
    peaks
}

/// Prominence of the plateau `values[first..=last]`.
fn prominence(values: &[f64], first: usize, last: usize) -> f64 {
    let top = values[first];
    let mut left_min = top;
    for &v in values[..first].iter().rev() {
        if v > top {
            break;
        }
        left_min = left_min.min(v);
    }
    let mut right_min = top;
    for &v in &values[last + 1..] {
        if v > top {
            break;
        }
        right_min = right_min.min(v);
    }
    top - left_min.max(right_min)
}

/// How to place a peak between samples.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Interpolation {
    /// The sample itself: error up to half a sample.
    None,
    /// A parabola through the three linear magnitudes around the maximum.
    Parabolic,
    /// A parabola through the three magnitudes in dB (a Gaussian fit): about 1.5x more accurate than
    /// [`Interpolation::Parabolic`] on sinc main lobes (worst error 6.4e-4 against 9.5e-4 samples
    /// with 10 samples per lobe half-width). For an exact, band-limited position of an OFDM peak see
    /// `OfdmRadar::refine_peak`.
    #[default]
    ParabolicDb,
}

/// The sub-sample position (fractional index) and height (linear amplitude) of the maximum at
/// `index` of the linear-amplitude profile `amplitude`. At either end of the profile, or when the
/// neighbours do not bracket a maximum, returns the sample itself.
pub fn interpolate_peak(amplitude: &[f64], index: usize, method: Interpolation) -> (f64, f64) {
    let at_sample = (index as f64, amplitude[index]);
    if method == Interpolation::None || index == 0 || index + 1 >= amplitude.len() {
        return at_sample;
    }
    let (a, b, c) = (amplitude[index - 1], amplitude[index], amplitude[index + 1]);
    if b < a || b < c {
        return at_sample;
    }
    match method {
        Interpolation::None => at_sample,
        Interpolation::Parabolic => {
            let (d, h) = vertex(a, b, c);
            (index as f64 + d, h)
        }
        Interpolation::ParabolicDb => {
            if a <= 0.0 || c <= 0.0 {
                let (d, h) = vertex(a, b, c);
                return (index as f64 + d, h);
            }
            let (d, h_db) = vertex(amplitude_db(a), amplitude_db(b), amplitude_db(c));
            (index as f64 + d, 10f64.powf(h_db / 20.0))
        }
    }
}

/// Offset (in samples, within +-0.5) and height of the vertex of the parabola through
/// (-1, a), (0, b), (1, c).
fn vertex(a: f64, b: f64, c: f64) -> (f64, f64) {
    let denom = a - 2.0 * b + c;
    if denom >= 0.0 {
        return (0.0, b);
    }
    let d = (0.5 * (a - c) / denom).clamp(-0.5, 0.5);
    (d, b - 0.25 * (a - c) * d)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn prominence_matches_hand_computation() {
        // Peak 5: lowest points 0 (left) and 0.5 (right, the walk reaches the end) -> 4.5;
        // peak 3: 1 (left, stopped by 5) and 0.5 (right) -> 2; peak 2.5: 2 and 0.5 -> 0.5.
        let v = [0.0, 5.0, 1.0, 3.0, 2.0, 2.5, 0.5];
        let p = find_peaks(&v, 0.0);
        assert_eq!(p.len(), 3);
        assert_eq!((p[0].index, p[0].prominence), (1, 4.5));
        assert_eq!((p[1].index, p[1].prominence), (3, 2.0));
        assert_eq!((p[2].index, p[2].prominence), (5, 0.5));
        assert_eq!(find_peaks(&v, 1.0).len(), 2);
    }

    #[test]
    fn plateau_counts_once_at_its_middle() {
        let v = [0.0, 1.0, 2.0, 2.0, 2.0, 1.0];
        let p = find_peaks(&v, 0.0);
        assert_eq!(p.len(), 1);
        assert_eq!(p[0].index, 3);
        assert_eq!(local_maxima(&v).collect::<Vec<_>>(), vec![3]);
        let w = [0.0, 5.0, 1.0, 3.0, 2.0, 2.5, 0.5, 0.5];
        assert_eq!(local_maxima(&w).collect::<Vec<_>>(), vec![1, 3, 5]);
    }

    #[test]
    fn parabola_is_exact_on_a_parabola() {
        let x0 = 10.3;
        let v: Vec<f64> = (0..20).map(|i| 100.0 - (i as f64 - x0).powi(2)).collect();
        let (x, h) = interpolate_peak(&v, 10, Interpolation::Parabolic);
        assert!((x - x0).abs() < 1e-12 && (h - 100.0).abs() < 1e-12);
    }

    #[test]
    fn db_parabola_beats_linear_parabola_on_a_sinc() {
        // A sinc main lobe with 10 samples from peak to first null (an OFDM profile zero-padded x10).
        let sinc = |x: f64| if x == 0.0 { 1.0 } else { x.sin() / x };
        let mut worst = [0.0f64; 2];
        for k in 0..20 {
            let x0 = 50.0 + k as f64 * 0.05;
            let v: Vec<f64> = (0..100)
                .map(|i| sinc((i as f64 - x0) * std::f64::consts::PI / 10.0).abs())
                .collect();
            let i = x0.round() as usize;
            let (xl, _) = interpolate_peak(&v, i, Interpolation::Parabolic);
            let (xd, _) = interpolate_peak(&v, i, Interpolation::ParabolicDb);
            worst[0] = worst[0].max((xl - x0).abs());
            worst[1] = worst[1].max((xd - x0).abs());
        }
        // Measured: 9.5e-4 (magnitude) and 6.4e-4 (dB) samples.
        assert!(worst[1] < worst[0] / 1.3, "{worst:?}");
        assert!(worst[1] < 7e-4, "{worst:?}");
    }
}
