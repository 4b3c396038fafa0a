//! Detection on a MUSIC pseudo-spectrum: it has no point spread to subtract, and its peak heights
//! are not target powers, so the targets are simply its `p` highest peaks (p from the model order,
//! given or MDL) that stand out by a prominence.

use super::super::metrics::find_peaks;

/// Indices of the `order` highest peaks of the linear pseudo-spectrum `pseudo` whose prominence on
/// its dB scale (10 log10 P) is at least `min_prominence_db` (3 dB is the thesis' "resolved"
/// rule), ascending index.
pub fn music_peaks(pseudo: &[f64], order: usize, min_prominence_db: f64) -> Vec<usize> {
    let db: Vec<f64> = pseudo
        .iter()
        .map(|p| 10.0 * p.max(1e-300).log10())
        .collect();
    let mut peaks = find_peaks(&db, min_prominence_db);
    peaks.sort_by(|a, b| b.value.total_cmp(&a.value));
    let mut out: Vec<usize> = peaks.iter().take(order).map(|p| p.index).collect();
    out.sort_unstable();
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn highest_prominent_peaks_of_the_order() {
        let mut p = vec![1.0; 100];
        p[20] = 100.0;
        p[50] = 1000.0;
        p[51] = 999.0; // a shoulder, not a peak
        p[80] = 1.5; // 1.8 dB: not prominent
        assert_eq!(music_peaks(&p, 3, 3.0), vec![20, 50]);
        assert_eq!(music_peaks(&p, 1, 3.0), vec![50]);
    }
}
