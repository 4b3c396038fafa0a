//! Waveforms through the AWG's 8-bit DAC: clipping reported, data still decoded.

use radbench::waveform::{quantise, BackoffReference};
use radbench::waveform::{unframe_payload, BitSource};
use radbench::waveform::{Equalisation, Ofdm, OfdmParams};
use radbench::waveform::{MskLfm, MskLfmParams};

#[test]
fn msk_lfm_uses_full_scale_without_clipping() {
    let w = MskLfm::new(MskLfmParams::default()).unwrap();
    let sig = w.generate(&BitSource::text("8-bit DAC"), 1).unwrap();
    let q = quantise(&sig.samples, 0.0, BackoffReference::Peak).unwrap();
    assert_eq!(q.clipped(), 0);
    assert!(q.peak_dbfs().abs() < 1e-3, "{}", q.peak_dbfs());
    // Constant envelope: 8 bits give about 6.02 * 8 + 1.76 dB less the I/Q crest factor.
    assert!(q.sqnr_db > 45.0, "{}", q.sqnr_db);
    let bits = w.demodulate(&q.to_complex()).unwrap();
    assert_eq!(unframe_payload(&bits).unwrap(), b"8-bit DAC");
}

#[test]
fn ofdm_back_off_trades_clipping_for_quantisation_noise() {
    let o = Ofdm::new(OfdmParams {
        symbols_per_frame: 20,
        ..Default::default()
    })
    .unwrap();
    let sig = o.generate(&BitSource::Prbs { seed: 6 }, 1).unwrap();
    let mut previous_clipped = usize::MAX;
    for backoff in [3.0, 6.0, 9.0, 12.0] {
        let q = quantise(&sig.samples, backoff, BackoffReference::Rms).unwrap();
        // More back-off never clips more.
        assert!(q.clipped() <= previous_clipped);
        previous_clipped = q.clipped();
        if backoff >= 9.0 {
            // Gaussian-like components: 9 dB above RMS is 2.8 sigma (about 0.5 % of each of I
            // and Q beyond it), 12 dB is 4 sigma.
            assert!(
                q.clipped() < sig.samples.len() / 50,
                "{backoff} dB: {}",
                q.clipped()
            );
            let r = o
                .receiver()
                .receive(&q.to_complex(), &Equalisation::Preamble)
                .unwrap();
            assert_eq!(r.bits, sig.bits, "{backoff} dB");
        }
    }
    // 3 dB above RMS clips a visible share of the samples.
    let q = quantise(&sig.samples, 3.0, BackoffReference::Rms).unwrap();
    assert!(q.clipped() > sig.samples.len() / 50);
    assert!(q.clipped_i > 0 && q.clipped_q > 0);
}
