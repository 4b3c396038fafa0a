//! Model-order selection from covariance eigenvalues: MDL and AIC (Wax & Kailath, 1985).
//!
//! For a candidate order k, the M - k smallest eigenvalues should be equal (white noise). With
//! `g` and `a` their geometric and arithmetic means and `n` snapshots:
//! `AIC(k) = -2 n (M-k) ln(g/a) + 2 k (2M - k)` and
//! `MDL(k) = -n (M-k) ln(g/a) + k (2M - k) ln(n) / 2`; the estimate minimises the criterion over
//! `k = 0..M-1`. MDL is consistent (right as n grows); AIC tends to overestimate but detects weak
//! targets sooner. Smoothed sub-vectors overlap, so they are not independent snapshots; `Music`
//! passes `n = S floor(N / M)`, the number of non-overlapping sub-vectors (see
//! `Music::order_snapshots` for why). Eigenvalues below 1e-10 of the
//! largest (rounding noise of a noise-free covariance) are floored there, so noise-free data give
//! the exact number of components.

/// Which information criterion estimates the number of targets.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OrderCriterion {
    Mdl,
    Aic,
}

/// The order minimising `criterion` for eigenvalues sorted in descending order; 0 to M-1.
pub(crate) fn estimate_order(
    eigenvalues_desc: &[f64],
    snapshots: usize,
    criterion: OrderCriterion,
) -> usize {
    let m = eigenvalues_desc.len();
    if m < 2 {
        return 0;
    }
    let floor = eigenvalues_desc[0].abs().max(f64::MIN_POSITIVE) * 1e-10;
    let n = snapshots.max(1) as f64;
    let mut best = (f64::INFINITY, 0);
    for k in 0..m {
        let tail = &eigenvalues_desc[k..];
        let count = tail.len() as f64;
        let (mut log_sum, mut sum) = (0.0, 0.0);
        for &v in tail {
            let v = v.max(floor);
            log_sum += v.ln();
            sum += v;
        }
        let log_ratio = log_sum / count - (sum / count).ln(); // ln(g / a) <= 0
        let kf = k as f64;
        let free = kf * (2.0 * m as f64 - kf);
        let value = match criterion {
            OrderCriterion::Aic => -2.0 * n * count * log_ratio + 2.0 * free,
            OrderCriterion::Mdl => -n * count * log_ratio + 0.5 * free * n.ln(),
        };
        if value < best.0 {
            best = (value, k);
        }
    }
    best.1
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clear_gap_gives_the_number_of_large_eigenvalues() {
        let mut ev = vec![100.0, 40.0, 9.0];
        ev.extend((0..13).map(|i| 1.0 + 0.01 * i as f64));
        ev.sort_by(|a, b| b.total_cmp(a));
        assert_eq!(estimate_order(&ev, 100, OrderCriterion::Mdl), 3);
        assert_eq!(estimate_order(&ev, 100, OrderCriterion::Aic), 3);
    }

    #[test]
    fn white_noise_gives_zero() {
        let ev: Vec<f64> = (0..16).map(|i| 1.02 - 0.002 * i as f64).collect();
        assert_eq!(estimate_order(&ev, 200, OrderCriterion::Mdl), 0);
    }

    #[test]
    fn noise_free_rounding_is_floored() {
        let ev = [5.0, 2.0, 1e-15, 3e-16, -2e-16, 1e-17];
        assert_eq!(estimate_order(&ev, 50, OrderCriterion::Mdl), 2);
        assert_eq!(estimate_order(&ev, 50, OrderCriterion::Aic), 2);
    }
}
