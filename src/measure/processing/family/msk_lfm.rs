//! MSK-LFM's room: a chirp carrying MSK bits (thesis 2.2). Correlation is its only range
//! algorithm; its data is decoded from the strongest echo (shifted to sample 0, derotated, then
//! the generator's dechirp and half-sine integrate-and-dump).

use super::contract::{Family, Modulated, ThesisWidths};
use super::overrides::{OverrideError, WaveformOverrides, MAX_SAMPLES_PER_REPETITION};
use crate::dsp::link_quality::link_quality;
use crate::measure::error::MeasureError;
use crate::measure::processing::receiver::{
    unwrapped_deg, DecodePayload, Decoded, LinkTrace, Modulation,
};
use crate::measure::{Algorithm, ProcessOptions};
use crate::waveform::ber_msk_lfm_theory;
use crate::waveform::BitSource;
use crate::waveform::ParamError;
use crate::waveform::{MskLfm, MskLfmParams, PulseLength};
use crate::waveform::{SweepBand, WaveformSpec};
use num_complex::Complex64;
use rustfft::Fft;
use std::collections::BTreeMap;
use std::sync::Arc;

/// Bits of the MSK-LFM phase trajectory drawn.
const TRAJECTORY_BITS: f64 = 32.0;

/// Points of the MSK-LFM phase trajectory drawn (per line).
const TRAJECTORY_POINTS: usize = 2000;

/// The parameters of an MSK-LFM spec.
pub(super) struct MskLfmRoom {
    pub(super) sample_rate_hz: f64,
    pub(super) bandwidth_hz: f64,
    pub(super) pulse_s: f64,
    pub(super) bits_per_pulse: usize,
    pub(super) band: SweepBand,
}

impl MskLfmRoom {
    fn spec(&self) -> WaveformSpec {
        WaveformSpec::MskLfm {
            sample_rate_hz: self.sample_rate_hz,
            bandwidth_hz: self.bandwidth_hz,
            pulse_s: self.pulse_s,
            bits_per_pulse: self.bits_per_pulse,
            band: self.band,
        }
    }

    fn params(&self) -> MskLfmParams {
        MskLfmParams {
            sample_rate_hz: self.sample_rate_hz,
            bandwidth_hz: self.bandwidth_hz,
            centre_hz: self.band.centre_hz(self.bandwidth_hz),
            pulse: PulseLength::Seconds(self.pulse_s),
            bits_per_pulse: self.bits_per_pulse,
        }
    }
}

impl Family for MskLfmRoom {
    fn label(&self) -> &'static str {
        "MSK-LFM"
    }

    fn parameters(&self) -> &'static [&'static str] {
        &[
            "bandwidth_hz",
            "sample_rate_hz",
            "pulse_s",
            "bits_per_pulse",
            "band",
        ]
    }

    fn apply(&self, o: &WaveformOverrides) -> Result<WaveformSpec, OverrideError> {
        let sample_rate_hz = o.sample_rate_hz.unwrap_or(self.sample_rate_hz);
        let pulse_s = o.pulse_s.unwrap_or(self.pulse_s);
        let samples = pulse_s * sample_rate_hz;
        if samples > MAX_SAMPLES_PER_REPETITION {
            return Err(OverrideError::TooLong {
                field: "pulse_s",
                samples,
            });
        }
        Ok(WaveformSpec::MskLfm {
            sample_rate_hz,
            bandwidth_hz: o.bandwidth_hz.unwrap_or(self.bandwidth_hz),
            pulse_s,
            bits_per_pulse: o.bits_per_pulse.unwrap_or(self.bits_per_pulse),
            band: o.band.unwrap_or(self.band),
        })
    }

    fn check(&self) -> Result<(), ParamError> {
        MskLfm::new(self.params()).map(|_| ())
    }

    fn modulate(&self, source: &BitSource) -> Result<Modulated, MeasureError> {
        let generator = MskLfm::new(self.params())?;
        let signal = generator.generate(source, 1)?;
        Ok(Modulated {
            samples: signal.samples,
            bits: signal.bits,
            modulation: Arc::new(MskLfmModulation {
                generator: Arc::new(generator),
            }),
        })
    }

    fn bits_per_repetition(&self) -> usize {
        self.bits_per_pulse
    }

    fn describe(&self, v: &mut serde_json::Value) {
        v["bits_per_pulse"] = self.bits_per_pulse.into();
        v["pulse_s"] = self.pulse_s.into();
    }

    fn algorithms(&self) -> &'static [Algorithm] {
        &[Algorithm::Correlation]
    }

    fn default_algorithm(&self) -> Algorithm {
        Algorithm::Correlation
    }

    fn is_periodic(&self) -> bool {
        false
    }

    fn own_settings(&self, _options: &ProcessOptions) -> BTreeMap<String, serde_json::Value> {
        BTreeMap::new()
    }

    fn ber_theory(&self, ebn0_db: f64) -> f64 {
        ber_msk_lfm_theory(ebn0_db)
    }

    fn ber_theory_formula(&self) -> &'static str {
        "Q(sqrt(2 Eb/N0))"
    }

    fn thesis_widths(&self) -> Option<ThesisWidths> {
        // Table 4.5 and the lab section 4.4.1.
        Some(ThesisWidths {
            simulation: (13.2, -13.24, "Table 4.5"),
            lab: (12.73, -10.49, "4.4.1"),
        })
    }

    fn as_simulated(&self) -> WaveformSpec {
        self.spec()
    }

    fn subcarriers(&self) -> Option<usize> {
        None
    }
}

/// The pulse generator (its tables built once), shared by the transmission and its decoders.
#[derive(Debug)]
struct MskLfmModulation {
    generator: Arc<MskLfm>,
}

impl Modulation for MskLfmModulation {
    fn payload_decoder(&self, period: usize) -> Box<dyn DecodePayload> {
        let forward = crate::dsp::plans::forward(period);
        let inverse = crate::dsp::plans::inverse(period);
        let scratch_len = forward
            .get_inplace_scratch_len()
            .max(inverse.get_inplace_scratch_len());
        Box::new(MskLfmDecoder {
            generator: self.generator.clone(),
            forward,
            inverse,
            buf: Vec::with_capacity(period),
            scratch: vec![Complex64::new(0.0, 0.0); scratch_len],
        })
    }
}

/// Advance the capture by the strongest echo's (fractional) lag, remove its carrier phase,
/// demodulate. The FFT plans of the shift are made once.
struct MskLfmDecoder {
    generator: Arc<MskLfm>,
    forward: Arc<dyn Fft<f64>>,
    inverse: Arc<dyn Fft<f64>>,
    buf: Vec<Complex64>,
    scratch: Vec<Complex64>,
}

impl DecodePayload for MskLfmDecoder {
    fn decode(
        &mut self,
        rx: &[Complex64],
        reference: &[Complex64],
        bits: &[u8],
        lag: Option<f64>,
    ) -> Option<Result<Decoded, String>> {
        // The correlation profile's cell is the echo's lag in samples of the aligned
        // repetition: advance the capture by it so the echo starts at sample 0.
        let lag = lag?;
        let buf = &mut self.buf;
        buf.clear();
        buf.extend_from_slice(rx);
        fractional_shift(
            buf,
            -lag,
            self.forward.as_ref(),
            self.inverse.as_ref(),
            &mut self.scratch,
        );
        // Remove the echo's carrier phase: correlate with the reference at lag 0.
        let c: Complex64 = buf.iter().zip(reference).map(|(a, b)| a * b.conj()).sum();
        let derot = if c.norm() > 0.0 {
            c.conj() / c.norm()
        } else {
            Complex64::new(1.0, 0.0)
        };
        let used = reference.len().min(buf.len());
        for v in &mut buf[..used] {
            *v *= derot;
        }
        let generator = &self.generator;
        Some(
            generator
                .soft_symbols(&buf[..used])
                .map(|soft| msk_decoded(generator, &soft, &buf[..used], reference, bits))
                .map_err(|e| e.to_string()),
        )
    }
}

/// The MSK-LFM decoder's figures from the matched-filter outputs `soft` (every symbol, bit
/// order) of the aligned, derotated pulses `pulses` that carried `sent`: hard decisions, EVM and
/// MER of the (I, Q) symbol pairs against the sent ones with the echo's amplitude taken out
/// (data-aided), and the first pulse's phase trajectory.
fn msk_decoded(
    gen: &MskLfm,
    soft: &[f64],
    pulses: &[Complex64],
    reference: &[Complex64],
    sent: &[u8],
) -> Decoded {
    let bits: Vec<u8> = soft.iter().map(|&v| u8::from(v < 0.0)).collect();
    let n = soft.len().min(sent.len()) / 2 * 2;
    let sign = |b: u8| 1.0 - 2.0 * f64::from(b & 1);
    let (num, den) = soft[..n]
        .iter()
        .zip(&sent[..n])
        .fold((0.0, 0.0), |(a, b), (v, &s)| (a + v * sign(s), b + 1.0));
    let gain = if den > 0.0 { num / den } else { 0.0 };
    let (mut quality, mut constellation) = (None, Vec::new());
    if gain.abs() > 0.0 && gain.is_finite() {
        constellation = soft[..n]
            .chunks_exact(2)
            .map(|p| Complex64::new(p[0], p[1]) / gain)
            .collect();
        let ideal: Vec<Complex64> = sent[..n]
            .chunks_exact(2)
            .map(|b| Complex64::new(sign(b[0]), sign(b[1])))
            .collect();
        quality = link_quality(&constellation, &ideal);
    }
    let spb = gen.samples_per_bit();
    let shown = ((TRAJECTORY_BITS * spb).ceil() as usize).min(pulses.len());
    // The phase is taken at the points drawn, not at every sample: a bit turns it by 90 degrees
    // over `spb` samples, so a step of a few degrees unwraps as at the full rate.
    let stride = shown.div_ceil(TRAJECTORY_POINTS).max(1);
    let phase_deg = unwrapped_deg(&gen.dechirped(pulses, shown, stride));
    // What was sent: the transmitted reference (the first pulse, as the AWG's codes play it).
    let ideal_phase_deg = unwrapped_deg(&gen.dechirped(reference, shown, stride));
    Decoded {
        bits,
        quality,
        trace: Some(LinkTrace::MskLfm {
            constellation,
            phase_deg,
            ideal_phase_deg,
            samples_per_bit: spb / stride as f64,
        }),
    }
}

/// `x` advanced by `shift` samples in place (circularly, band-limited): out[n] = x[n - shift].
fn fractional_shift(
    x: &mut [Complex64],
    shift: f64,
    forward: &dyn Fft<f64>,
    inverse: &dyn Fft<f64>,
    scratch: &mut [Complex64],
) {
    let n = x.len();
    forward.process_with_scratch(x, scratch);
    let step = -2.0 * std::f64::consts::PI * shift / n as f64;
    ramp(x, step, 1.0 / n as f64);
    inverse.process_with_scratch(x, scratch);
}

/// The phase ramp restarts from an exact phasor every `RAMP_EXACT_EVERY` bins (and at the first
/// negative frequency) so rounding cannot accumulate.
const RAMP_EXACT_EVERY: usize = 1024;

/// Segments of the ramp run side by side (independent recurrences: their products overlap in
/// the CPU instead of waiting for each other).
const RAMP_LANES: usize = 4;

/// `x[k] *= scale * e^(i step k')` for every bin `k` (`k'` its signed frequency): the phase
/// ramp by recurrence (one complex product per bin, no sin/cos per bin), restarted from an exact
/// phasor at every multiple of `RAMP_EXACT_EVERY` and at `n / 2 + 1`. The segments between
/// restarts are independent, so `RAMP_LANES` of them are advanced together; each bin gets the
/// same products in the same order as one recurrence over all bins, so the same bits.
fn ramp(x: &mut [Complex64], step: f64, scale: f64) {
    let n = x.len();
    let exact = |k: usize| {
        let signed = if k <= n / 2 {
            k as f64
        } else {
            k as f64 - n as f64
        };
        Complex64::from_polar(scale, step * signed)
    };
    let rotate = Complex64::from_polar(1.0, step);
    let mut starts: Vec<usize> = (0..n).step_by(RAMP_EXACT_EVERY).collect();
    let negative = n / 2 + 1;
    if negative < n && negative % RAMP_EXACT_EVERY != 0 {
        let at = starts.partition_point(|&s| s < negative);
        starts.insert(at, negative);
    }
    let ends: Vec<usize> = starts.iter().skip(1).copied().chain([n]).collect();
    let segments: Vec<(usize, usize)> = starts.into_iter().zip(ends).collect();
    let mut groups = segments.chunks_exact(RAMP_LANES);
    for group in &mut groups {
        let shortest = group.iter().map(|(a, b)| b - a).min().unwrap_or(0);
        let mut phasor: [Complex64; RAMP_LANES] = std::array::from_fn(|l| exact(group[l].0));
        for t in 0..shortest {
            for l in 0..RAMP_LANES {
                x[group[l].0 + t] *= phasor[l];
                phasor[l] *= rotate;
            }
        }
        for (l, &(a, b)) in group.iter().enumerate() {
            let mut p = phasor[l];
            for v in &mut x[a + shortest..b] {
                *v *= p;
                p *= rotate;
            }
        }
    }
    for &(a, b) in groups.remainder() {
        let mut p = exact(a);
        for v in &mut x[a..b] {
            *v *= p;
            p *= rotate;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// The ramp as one recurrence over all bins (the decoder's loop before session 18).
    fn ramp_one_recurrence(x: &mut [Complex64], step: f64, scale: f64) {
        let n = x.len();
        const EXACT_EVERY: usize = 1024;
        let rotate = Complex64::from_polar(1.0, step);
        let mut phasor = Complex64::new(0.0, 0.0);
        for (k, v) in x.iter_mut().enumerate() {
            if k % EXACT_EVERY == 0 || k == n / 2 + 1 {
                let signed = if k <= n / 2 {
                    k as f64
                } else {
                    k as f64 - n as f64
                };
                phasor = Complex64::from_polar(scale, step * signed);
            }
            *v *= phasor;
            phasor *= rotate;
        }
    }

    /// `n` seeded values in -1..1 (a 64-bit LCG's top bits).
    fn noise(n: usize, seed: u64) -> Vec<Complex64> {
        let mut s = seed | 1;
        let mut next = move || {
            s = s
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (s >> 11) as f64 / (1u64 << 52) as f64 - 1.0
        };
        (0..n).map(|_| Complex64::new(next(), next())).collect()
    }

    fn same_bits(n: usize, shift: f64, seed: u64) -> Result<(), TestCaseError> {
        let x = noise(n, seed);
        let step = -2.0 * std::f64::consts::PI * shift / n.max(1) as f64;
        let scale = 1.0 / n.max(1) as f64;
        let (mut a, mut b) = (x.clone(), x);
        ramp(&mut a, step, scale);
        ramp_one_recurrence(&mut b, step, scale);
        for (k, (u, v)) in a.iter().zip(&b).enumerate() {
            prop_assert_eq!(u.re.to_bits(), v.re.to_bits(), "bin {} of {}", k, n);
            prop_assert_eq!(u.im.to_bits(), v.im.to_bits(), "bin {} of {}", k, n);
        }
        Ok(())
    }

    proptest! {
        #[test]
        fn the_ramp_side_by_side_gives_the_bits_of_one_recurrence(
            n in 0usize..20_000,
            shift in -5000.0f64..5000.0,
            seed in any::<u64>(),
        ) {
            same_bits(n, shift, seed)?;
        }
    }

    #[test]
    fn the_ramp_side_by_side_at_the_segment_edges_and_the_capture_length() {
        let lengths = [
            1, 2, 3, 1023, 1024, 1025, 2046, 2047, 2048, 2049, 2050, 4096, 8194,
        ];
        for (k, n) in lengths
            .into_iter()
            .chain([160_000, 6 * 1024 + 2])
            .enumerate()
        {
            same_bits(n, 12.345 * k as f64 - 40.0, k as u64).unwrap();
        }
    }
}
