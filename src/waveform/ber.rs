//! Bit-error rates: `erfc`, the theoretical curves of thesis-notes.md, and a Monte-Carlo helper.
//!
//! # Eb/N0 and noise
//! Noise is circular complex white Gaussian of variance `sigma^2` per sample. With the signal's mean
//! power 1 per sample, the energy per bit measured in samples is `Eb = samples per bit` and
//! `N0 = sigma^2`, so `sigma^2 = samples_per_bit / (Eb/N0)`:
//!
//! * MSK-LFM: `samples_per_bit = samples_per_pulse / bits_per_pulse`.
//! * OFDM: `samples_per_bit = symbol_len / (2 N)`: the CP energy counts in `Eb` (it is transmitted),
//!   so only the fraction `1 / (1 + cp_fraction)` (0.8 by default) reaches the decision. Preamble
//!   symbols are overhead and not counted.
//!
//! # Run time
//! The helpers push every bit through the real receivers, so the cost is one Gaussian deviate pair
//! per sample: about 1250 samples per bit for the thesis' MSK-LFM pulse and 10 for the default OFDM
//! frame. The measured BER does not depend on the sampling (the matched filters are exact at any
//! rate with at least 2 samples per bit), so BER curves can use a coarser sampling, e.g. MSK-LFM at
//! 2 GSa/s (156 samples per bit) or OFDM with `oversampling` 1 or 2, and a [`BerBudget`] whose
//! `max_bits` bounds the low-BER points.

use num_complex::Complex64;

use super::bits::{count_bit_errors, BitSource};
use super::msk_lfm::MskLfm;
use super::ofdm::{Equalisation, Ofdm};
use super::ParamError;
use crate::rng::SplitMix64;

/// Complementary error function, relative accuracy about 1e-15 for all finite `x`.
///
/// A positive power series of `erf` for `|x| < 1` (no cancellation: `erfc(1)` = 0.157) and the
/// continued fraction of `erfc` (modified Lentz) above; `erfc(-x) = 2 - erfc(x)`.
pub(crate) fn erfc(x: f64) -> f64 {
    const TWO_OVER_SQRT_PI: f64 = std::f64::consts::FRAC_2_SQRT_PI;
    if x.is_nan() {
        return f64::NAN;
    }
    if x < 0.0 {
        return 2.0 - erfc(-x);
    }
    if x < 1.0 {
        // erf(x) = 2/sqrt(pi) exp(-x^2) sum_n (2x^2)^n x / (1 * 3 * ... * (2n+1))
        let x2 = 2.0 * x * x;
        let (mut term, mut sum) = (x, x);
        let mut n = 0.0;
        while term > sum * 1e-17 {
            n += 1.0;
            term *= x2 / (2.0 * n + 1.0);
            sum += term;
        }
        return 1.0 - TWO_OVER_SQRT_PI * (-x * x).exp() * sum;
    }
    if x > 27.3 {
        return 0.0; // below the smallest subnormal
    }
    // erfc(x) = exp(-x^2)/sqrt(pi) / (x + (1/2)/(x + 1/(x + (3/2)/(x + ...)))): a_n = n/2, b_n = x.
    let tiny = 1e-300;
    let mut f = x;
    let (mut c, mut d) = (x, 0.0);
    for n in 1..2000 {
        let a = n as f64 / 2.0;
        d = x + a * d;
        if d.abs() < tiny {
            d = tiny;
        }
        d = 1.0 / d;
        c = x + a / c;
        if c.abs() < tiny {
            c = tiny;
        }
        let delta = c * d;
        f *= delta;
        if (delta - 1.0).abs() < 1e-16 {
            break;
        }
    }
    TWO_OVER_SQRT_PI / 2.0 * (-x * x).exp() / f
}

/// Gaussian tail `Q(x) = erfc(x / sqrt 2) / 2`.
pub(crate) fn q_function(x: f64) -> f64 {
    0.5 * erfc(x * std::f64::consts::FRAC_1_SQRT_2)
}

fn db_to_linear(db: f64) -> f64 {
    10f64.powf(db / 10.0)
}

/// Theoretical MSK-LFM BER in AWGN: `Q(sqrt(2 Eb/N0))` (coherent MSK = BPSK per quadrature).
pub fn ber_msk_lfm_theory(ebn0_db: f64) -> f64 {
    q_function((2.0 * db_to_linear(ebn0_db)).sqrt())
}

/// Theoretical OFDM QPSK BER in AWGN with `Eb` counting the CP energy:
/// `Q(sqrt(2 Eb/N0 / (1 + cp_fraction)))`, i.e. `Q(sqrt(2 * 0.8 * Eb/N0))` for the default CP of 1/4.
pub fn ber_ofdm_theory(ebn0_db: f64, cp_fraction: f64) -> f64 {
    q_function((2.0 * db_to_linear(ebn0_db) / (1.0 + cp_fraction)).sqrt())
}

/// How long a Monte-Carlo BER run goes on: at least `min_bits`, then until `min_errors` errors or
/// `max_bits` bits, whichever comes first (whole pulses / frames, so slightly more is possible).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BerBudget {
    pub min_bits: usize,
    pub min_errors: usize,
    pub max_bits: usize,
}

impl Default for BerBudget {
    /// 10 000 bits at least, 100 errors wanted, 10 million bits at most.
    fn default() -> Self {
        Self {
            min_bits: 10_000,
            min_errors: 100,
            max_bits: 10_000_000,
        }
    }
}

/// One measured point of a BER curve, next to theory.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BerPoint {
    pub ebn0_db: f64,
    /// Bits sent.
    pub bits: usize,
    /// Bits received wrong.
    pub errors: usize,
    /// `errors / bits`.
    pub ber: f64,
    /// The theoretical BER at this Eb/N0.
    pub theory: f64,
}

impl BerPoint {
    /// Binomial standard deviation of the measured BER if theory were exact:
    /// `sqrt(theory (1 - theory) / bits)`.
    pub fn std_dev(&self) -> f64 {
        (self.theory * (1.0 - self.theory) / self.bits as f64).sqrt()
    }
}

fn check(ebn0_db: f64, budget: &BerBudget) -> Result<(), ParamError> {
    if !ebn0_db.is_finite() {
        return Err(ParamError::out_of_range(
            "Eb/N0",
            format!("{ebn0_db} dB"),
            "must be a finite number of dB",
        ));
    }
    if budget.min_bits == 0 || budget.max_bits < budget.min_bits {
        return Err(ParamError::out_of_range(
            "BER bit budget",
            format!("min {} max {}", budget.min_bits, budget.max_bits),
            "needs min_bits >= 1 and max_bits >= min_bits",
        ));
    }
    Ok(())
}

fn run(
    budget: &BerBudget,
    seed: u64,
    mut batch: impl FnMut(u64, &mut SplitMix64) -> Result<(usize, usize), ParamError>,
) -> Result<(usize, usize), ParamError> {
    let mut seeds = SplitMix64::new(seed);
    let mut noise = SplitMix64::new(seed ^ 0x4E4F_4953_4500_0000);
    let (mut bits, mut errors) = (0, 0);
    while bits < budget.min_bits || (errors < budget.min_errors && bits < budget.max_bits) {
        let (b, e) = batch(seeds.next_u64(), &mut noise)?;
        bits += b;
        errors += e;
    }
    Ok((bits, errors))
}

/// Measures the MSK-LFM BER at `ebn0_db` over an AWGN channel with the coherent, aligned receiver
/// of [`MskLfm::demodulate`]. Deterministic for a given `seed`.
///
/// # Errors
///
/// [`ParamError`] when `ebn0_db` is not finite, the budget has `min_bits` of 0 or `max_bits`
/// below `min_bits`, or generating or demodulating a batch fails.
pub fn measure_ber_msk_lfm(
    waveform: &MskLfm,
    ebn0_db: f64,
    budget: &BerBudget,
    seed: u64,
) -> Result<BerPoint, ParamError> {
    check(ebn0_db, budget)?;
    let variance = waveform.samples_per_bit() / db_to_linear(ebn0_db);
    // Batches of about 8192 bits but at most about 2^20 samples (16 MB), whole pulses.
    let pulses = (8192 / waveform.bits_per_pulse())
        .min((1 << 20) / waveform.samples_per_pulse())
        .max(1);
    let (bits, errors) = run(budget, seed, |bit_seed, noise| {
        let mut sig = waveform.generate(&BitSource::Prbs { seed: bit_seed }, pulses)?;
        noise.add_noise(&mut sig.samples, variance);
        let rx = waveform.demodulate(&sig.samples)?;
        Ok((sig.bits.len(), count_bit_errors(&rx, &sig.bits)))
    })?;
    Ok(BerPoint {
        ebn0_db,
        bits,
        errors,
        ber: errors as f64 / bits as f64,
        theory: ber_msk_lfm_theory(ebn0_db),
    })
}

/// Measures the OFDM BER at `ebn0_db` over an AWGN channel, equalising with the known (unit)
/// channel so the result compares with [`ber_ofdm_theory`]; a preamble estimate would add its own
/// estimation noise. Deterministic for a given `seed`.
///
/// # Errors
///
/// [`ParamError`] when `ebn0_db` is not finite, the budget has `min_bits` of 0 or `max_bits`
/// below `min_bits`, or generating or receiving a frame fails.
pub fn measure_ber_ofdm(
    waveform: &Ofdm,
    ebn0_db: f64,
    budget: &BerBudget,
    seed: u64,
) -> Result<BerPoint, ParamError> {
    check(ebn0_db, budget)?;
    let n = waveform.subcarriers();
    let samples_per_bit = waveform.symbol_len() as f64 / (2 * n) as f64;
    let variance = samples_per_bit / db_to_linear(ebn0_db);
    let mut receiver = waveform.receiver();
    let unit = Equalisation::Known(vec![Complex64::new(1.0, 0.0); n]);
    let (bits, errors) = run(budget, seed, |bit_seed, noise| {
        let mut sig = waveform.generate(&BitSource::Prbs { seed: bit_seed }, 1)?;
        noise.add_noise(&mut sig.samples, variance);
        let rx = receiver.receive(&sig.samples, &unit)?;
        Ok((sig.bits.len(), count_bit_errors(&rx.bits, &sig.bits)))
    })?;
    Ok(BerPoint {
        ebn0_db,
        bits,
        errors,
        ber: errors as f64 / bits as f64,
        theory: ber_ofdm_theory(ebn0_db, waveform.params().cp_fraction),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn erfc_matches_reference_values() {
        let cases = [
            (0.0, 1.0),
            (0.5, 0.479_500_122_186_953_5),
            (1.0, 0.157_299_207_050_285_13),
            (2.0, 0.004_677_734_981_047_266),
            (3.0, 2.209_049_699_858_544e-5),
            (5.0, 1.537_459_794_428_035e-12),
            (10.0, 2.088_487_583_762_545e-45),
            (-1.0, 1.842_700_792_949_715),
        ];
        for (x, want) in cases {
            let got = erfc(x);
            assert!(
                ((got - want) / want).abs() < 1e-13,
                "erfc({x}) = {got}, want {want}"
            );
        }
        assert_eq!(erfc(40.0), 0.0);
        assert!(erfc(f64::NAN).is_nan());
    }

    #[test]
    fn theory_curves() {
        // Q(sqrt 2) at 0 dB.
        assert!((ber_msk_lfm_theory(0.0) - 0.078_649_603_525_143_2).abs() < 1e-12);
        // The CP costs 10 log10(1.25) = 0.969 dB.
        let shifted = ber_ofdm_theory(5.0 + 10.0 * 1.25f64.log10(), 0.25);
        assert!((shifted - ber_msk_lfm_theory(5.0)).abs() < 1e-15);
    }

    #[test]
    fn bad_budget_is_an_error() {
        let w = MskLfm::new(Default::default()).unwrap();
        let b = BerBudget {
            min_bits: 0,
            ..Default::default()
        };
        assert!(measure_ber_msk_lfm(&w, 3.0, &b, 1).is_err());
        assert!(measure_ber_msk_lfm(&w, f64::NAN, &BerBudget::default(), 1).is_err());
    }
}
