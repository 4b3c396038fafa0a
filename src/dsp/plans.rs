//! FFT plans shared by the whole process: a pipeline's parts (the correlation, the echo spectrum,
//! the payload decoder, the point spread) and the workers of `radbench process` ask for the same
//! lengths, and each plan's twiddle factors (a sine and a cosine per point) would otherwise be
//! computed again for every part and every worker. A plan for a length is the same algorithm
//! whichever planner makes it (rustfft chooses it from the length and the CPU alone), so sharing
//! changes no result.

use rustfft::{Fft, FftDirection, FftPlanner};
use std::collections::HashMap;
use std::sync::{Arc, Mutex};

/// Plans kept at most: past this the oldest half is forgotten (the plans stay alive where they
/// are used), so a long session of many lengths does not grow without bound.
const KEPT: usize = 32;

/// A plan made, with when it was last asked for.
type Made = (u64, Arc<dyn Fft<f64>>);

struct Plans {
    planner: FftPlanner<f64>,
    /// By length and direction (forward: true).
    made: HashMap<(usize, bool), Made>,
    clock: u64,
}

static PLANS: Mutex<Option<Plans>> = Mutex::new(None);

fn plan(len: usize, direction: FftDirection) -> Arc<dyn Fft<f64>> {
    let mut guard = PLANS.lock().unwrap_or_else(|p| p.into_inner());
    let plans = guard.get_or_insert_with(|| Plans {
        planner: FftPlanner::new(),
        made: HashMap::new(),
        clock: 0,
    });
    plans.clock += 1;
    let key = (len, direction == FftDirection::Forward);
    if let Some((used, fft)) = plans.made.get_mut(&key) {
        *used = plans.clock;
        return fft.clone();
    }
    if plans.made.len() >= KEPT {
        // A fresh planner too: rustfft's own cache would keep every plan it ever made.
        let mut by_use: Vec<u64> = plans.made.values().map(|(u, _)| *u).collect();
        by_use.sort_unstable();
        let cut = by_use[by_use.len() / 2];
        plans.made.retain(|_, (u, _)| *u > cut);
        plans.planner = FftPlanner::new();
    }
    let fft = plans.planner.plan_fft(len, direction);
    plans.made.insert(key, (plans.clock, fft.clone()));
    fft
}

/// The forward FFT of `len` points (shared).
pub(crate) fn forward(len: usize) -> Arc<dyn Fft<f64>> {
    plan(len, FftDirection::Forward)
}

/// The inverse (unnormalised) FFT of `len` points (shared).
pub(crate) fn inverse(len: usize) -> Arc<dyn Fft<f64>> {
    plan(len, FftDirection::Inverse)
}

#[cfg(test)]
mod tests {
    use super::*;
    use num_complex::Complex64;

    /// The two tests share the process-wide plans: the forgetting test's burst of new lengths
    /// must not evict a plan between the other test's two look-ups.
    static ONE_AT_A_TIME: Mutex<()> = Mutex::new(());

    fn bits(v: &[Complex64]) -> Vec<(u64, u64)> {
        v.iter().map(|c| (c.re.to_bits(), c.im.to_bits())).collect()
    }

    #[test]
    fn a_shared_plan_gives_the_bits_of_a_planner_of_its_own() {
        let _alone = ONE_AT_A_TIME.lock().unwrap_or_else(|p| p.into_inner());
        for len in [1, 7, 1000, 160_000, 160_063, 4096] {
            let x: Vec<Complex64> = (0..len)
                .map(|k| Complex64::new((k as f64 * 0.37).sin(), (k as f64 * 0.11).cos()))
                .collect();
            for direction in [FftDirection::Forward, FftDirection::Inverse] {
                let own = FftPlanner::<f64>::new().plan_fft(len, direction);
                let shared = plan(len, direction);
                assert!(Arc::ptr_eq(&shared, &plan(len, direction)));
                let (mut a, mut b) = (x.clone(), x.clone());
                own.process(&mut a);
                shared.process(&mut b);
                assert_eq!(bits(&a), bits(&b), "{len} points, {direction:?}");
            }
        }
    }

    #[test]
    fn past_the_limit_the_least_recently_used_plans_are_forgotten() {
        let _alone = ONE_AT_A_TIME.lock().unwrap_or_else(|p| p.into_inner());
        // Lengths no other test asks for, more than are kept.
        let first = forward(100_003);
        for len in 0..KEPT + 4 {
            forward(200_000 + len);
        }
        let guard = PLANS.lock().unwrap();
        let plans = guard.as_ref().unwrap();
        assert!(plans.made.len() <= KEPT);
        assert!(!plans.made.contains_key(&(100_003, true)));
        drop(guard);
        // Still usable where it is held.
        let mut x = vec![Complex64::new(1.0, 0.0); 100_003];
        first.process(&mut x);
        assert!((x[0].re - 100_003.0).abs() < 1e-6);
    }
}
