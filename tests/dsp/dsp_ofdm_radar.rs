//! OFDM radar receiver: framing, CP, scaling, bin order, the thesis' one- and two-target figures,
//! averaging, windows and the range-Doppler map.

use crate::dsp_support;

use dsp_support::*;
use num_complex::Complex64;
use radbench::dsp::Window;
use radbench::dsp::{interpolate_peak, resolve_targets, sidelobe_levels, width_3db, Interpolation};
use radbench::dsp::{
    Averaging, FftPrecision, IDiv, OfdmRadar, OfdmRadarConfig, RangeDoppler, RangeDopplerConfig,
    RangeDopplerMap, RangeProfile,
};
use radbench::rng::SplitMix64;

fn argmax(v: &[f64]) -> usize {
    v.iter()
        .enumerate()
        .max_by(|a, b| a.1.total_cmp(b.1))
        .unwrap()
        .0
}

/// The default receiver with its FFT in double precision, for checks at the 1e-9 level.
fn double() -> OfdmRadarConfig {
    OfdmRadarConfig {
        fft_precision: FftPrecision::Double,
        ..Default::default()
    }
}

fn profile_of(
    config: OfdmRadarConfig,
    symbols: usize,
    fc: f64,
    targets: &[Target],
) -> RangeProfile {
    let mut rng = SplitMix64::new(1);
    let tx = qpsk(&mut rng, symbols, N);
    let rx = received_signal(&mut rng, &tx, fc, targets, None);
    let mut radar = OfdmRadar::new(config).unwrap();
    let (mut idiv, mut profile) = (IDiv::new(), RangeProfile::new());
    radar.process(&rx, 0, &tx, &mut idiv, &mut profile).unwrap();
    profile
}

#[test]
fn spectral_division_recovers_the_echo_model_exactly() {
    let mut rng = SplitMix64::new(5);
    let tx = qpsk(&mut rng, 3, N);
    let t = target(2.345);
    let rx = received_signal(&mut rng, &tx, FC_PHYSICAL, &[t], None);
    let mut radar = OfdmRadar::new(double()).unwrap();
    let mut idiv = IDiv::new();
    radar.divide(&rx, 0, &tx, &mut idiv).unwrap();
    assert_eq!((idiv.symbols(), idiv.subcarriers()), (3, N));
    let tau = 2.0 * t.range / radbench::dsp::C0;
    for s in 0..3 {
        for (k, v) in idiv.symbol(s).iter().enumerate() {
            let f = FC_PHYSICAL + (k as f64 - 64.0) * DF;
            let expect = Complex64::from_polar(1.0, -2.0 * std::f64::consts::PI * f * tau);
            assert!((v - expect).norm() < 1e-9, "s {s} k {k}: {v} vs {expect}");
        }
    }
}

#[test]
fn single_precision_fft_matches_double_precision_far_below_adc_noise() {
    // Two targets and noise at an 8-bit scope's level: the single-precision FFT (the default) must
    // change I_div by no more than ~1e-6 of its size, and the profile and peak not measurably.
    let mut rng = SplitMix64::new(21);
    let tx = qpsk(&mut rng, 20, N);
    let targets = [
        target(1.234),
        Target {
            amp: 0.3,
            ..target(4.321)
        },
    ];
    let rx = received_signal(&mut rng, &tx, FC_PHYSICAL, &targets, Some(40.0));
    let run = |config: OfdmRadarConfig| {
        let mut radar = OfdmRadar::new(config).unwrap();
        let (mut idiv, mut profile) = (IDiv::new(), RangeProfile::new());
        radar.process(&rx, 0, &tx, &mut idiv, &mut profile).unwrap();
        let peak = radar.refine_peak(&idiv, 1.234).unwrap();
        (idiv, profile, peak)
    };
    assert_eq!(
        OfdmRadarConfig::default().fft_precision,
        FftPrecision::Single
    );
    let (i32_, p32, peak32) = run(OfdmRadarConfig::default());
    let (i64_, p64, peak64) = run(double());
    let rms =
        |v: &[Complex64]| (v.iter().map(|x| x.norm_sqr()).sum::<f64>() / v.len() as f64).sqrt();
    let diff: Vec<Complex64> = i32_
        .as_slice()
        .iter()
        .zip(i64_.as_slice())
        .map(|(a, b)| a - b)
        .collect();
    let rel = rms(&diff) / rms(i64_.as_slice());
    assert!(
        rel > 0.0 && rel < 1e-6,
        "I_div relative RMS difference {rel:e}"
    );
    let peak_amp = p64.amplitude.iter().cloned().fold(0.0, f64::max);
    for (a, b) in p32.amplitude.iter().zip(&p64.amplitude) {
        assert!((a - b).abs() < 1e-6 * peak_amp, "{a} vs {b}");
    }
    assert!(
        (peak32.0 - peak64.0).abs() < 1e-6,
        "{peak32:?} vs {peak64:?}"
    );
}

#[test]
fn framing_with_a_start_offset_and_a_truly_delayed_frame() {
    // Delay the whole frame (not symbol by symbol) and put 777 samples of silence in front: the CP
    // must absorb the 20 ns echo delay and the start offset must find the symbols.
    let mut rng = SplitMix64::new(9);
    let symbols = 4;
    let tx = qpsk(&mut rng, symbols, N);
    let clean = modulate(&tx, N, OS, N * OS / 4);
    let offset = 777;
    let mut padded = vec![Complex64::default(); offset];
    padded.extend_from_slice(&clean);
    padded.extend(std::iter::repeat_n(Complex64::default(), 4096));
    let range = 3.0;
    let rx = delay(
        &padded,
        B * OS as f64,
        2.0 * range / radbench::dsp::C0,
        FC_PHYSICAL,
        0.5,
    );
    let mut radar = OfdmRadar::new(double()).unwrap();
    let (mut idiv, mut profile) = (IDiv::new(), RangeProfile::new());
    radar
        .process(&rx, offset, &tx, &mut idiv, &mut profile)
        .unwrap();
    let i = argmax(&profile.amplitude);
    let (x, h) = interpolate_peak(&profile.amplitude, i, Interpolation::ParabolicDb);
    let r = profile.axis().at(x);
    assert!((r - range).abs() < 2e-4, "peak at {r} m");
    assert!((h - 0.5).abs() < 1e-3, "amplitude {h}");
    let (rr, hh) = radar.refine_peak(&idiv, r).unwrap();
    assert!(
        (rr - range).abs() < 1e-7 && (hh - 0.5).abs() < 1e-7,
        "{rr} {hh}"
    );
}

#[test]
fn one_target_at_3_m_has_the_thesis_width_and_sidelobes() {
    let profile = profile_of(OfdmRadarConfig::default(), 10, FC_PHYSICAL, &[target(3.0)]);
    assert_eq!(profile.amplitude.len(), 1280);
    let axis = profile.axis();
    assert!((axis.step - 0.01499).abs() < 1e-5, "bin {}", axis.step);
    let i = argmax(&profile.amplitude);
    let (x, h) = interpolate_peak(&profile.amplitude, i, Interpolation::ParabolicDb);
    assert!((axis.at(x) - 3.0).abs() < 1e-3);
    assert!((h - 1.0).abs() < 1e-3, "unit target peaks at {h}");
    let width_cm = width_3db(&profile.amplitude, i, h).unwrap() * axis.step * 100.0;
    assert!(
        (13.2..=13.4).contains(&width_cm),
        "-3 dB width {width_cm} cm"
    );
    let psl = sidelobe_levels(&profile.amplitude, i, Interpolation::ParabolicDb)
        .unwrap()
        .psl_db;
    assert!((-13.6..=-13.0).contains(&psl), "PSL {psl} dB");
}

#[test]
fn ofdm_3_00_and_3_15_m_with_a_128_point_ifft_are_not_resolved() {
    let targets = [target(3.0), target(3.15)];
    let config = OfdmRadarConfig {
        zero_pad: 1,
        ..Default::default()
    };
    let p = profile_of(config, 4, FC_PHYSICAL, &targets);
    assert_eq!(p.amplitude.len(), 128);
    let r = resolve_targets(
        p.axis(),
        &p.amplitude,
        &[3.0, 3.15],
        3.0,
        Interpolation::None,
    );
    assert!(!r.resolved, "{r:?}");
}

#[test]
fn thesis_phase_convention_gives_two_peaks_at_1280_points() {
    let targets = [target(3.0), target(3.15)];
    let resolved_with = |carrier_hz: f64| {
        let p = profile_of(OfdmRadarConfig::default(), 4, carrier_hz, &targets);
        resolve_targets(
            p.axis(),
            &p.amplitude,
            &[3.0, 3.15],
            3.0,
            Interpolation::ParabolicDb,
        )
    };
    let r = resolved_with(FC_THESIS);
    assert!(r.resolved, "thesis convention: {r:?}");
    // The physical 80 GHz carrier puts the two echoes nearly in phase: one merged peak.
    let r = resolved_with(FC_PHYSICAL);
    assert!(!r.resolved, "physical convention: {r:?}");
}

#[test]
fn coherent_averaging_lowers_the_noise_floor_and_power_averaging_does_not() {
    let mut rng = SplitMix64::new(21);
    let symbols = 64;
    let tx = qpsk(&mut rng, symbols, N);
    // Noise only: a target's far side-lobes (about -40 dB) would sit above the averaged floor.
    let rx = received_signal(&mut rng, &tx, FC_PHYSICAL, &[], Some(0.0));
    let floor = |averaging| {
        let config = OfdmRadarConfig {
            averaging,
            ..Default::default()
        };
        let mut radar = OfdmRadar::new(config).unwrap();
        let (mut idiv, mut p) = (IDiv::new(), RangeProfile::new());
        radar.process(&rx, 0, &tx, &mut idiv, &mut p).unwrap();
        p.amplitude.iter().map(|a| a * a).sum::<f64>() / p.amplitude.len() as f64
    };
    // Noise per subcarrier after the receiver: 1/16 (the 16x oversampling drops out-of-band noise),
    // per profile bin 1/(16 N) for one symbol.
    let one_symbol = 1.0 / (16.0 * N as f64);
    let power = floor(Averaging::Power);
    let coherent = floor(Averaging::Coherent);
    assert!(
        (power / one_symbol - 1.0).abs() < 0.15,
        "power-averaged floor {power}"
    );
    let gain_db = 10.0 * (power / coherent).log10();
    assert!(
        (gain_db - 10.0 * (symbols as f64).log10()).abs() < 1.0,
        "gain {gain_db} dB"
    );
}

fn windowed(window: Window) -> (f64, f64) {
    let config = OfdmRadarConfig {
        window,
        ..Default::default()
    };
    let p = profile_of(config, 2, FC_PHYSICAL, &[target(3.0)]);
    let i = argmax(&p.amplitude);
    let (_, h) = interpolate_peak(&p.amplitude, i, Interpolation::ParabolicDb);
    let width_cm = width_3db(&p.amplitude, i, h).unwrap() * p.axis().step * 100.0;
    let psl = sidelobe_levels(&p.amplitude, i, Interpolation::ParabolicDb)
        .unwrap()
        .psl_db;
    assert!(
        (h - 1.0).abs() < 0.01,
        "{window:?}: windowed peak keeps the amplitude, got {h}"
    );
    (width_cm, psl)
}

#[test]
fn windows_trade_sidelobes_for_width() {
    let (w_rect, psl_rect) = windowed(Window::Rectangular);
    let (w_hann, psl_hann) = windowed(Window::Hann);
    let (w_tay, psl_tay) = windowed(Window::Taylor {
        nbar: 4,
        sll_db: -35.0,
    });
    let (w_cheb, psl_cheb) = windowed(Window::Chebyshev { sll_db: -50.0 });
    eprintln!("rect {w_rect:.2} cm {psl_rect:.2} dB; hann {w_hann:.2} {psl_hann:.2}; taylor {w_tay:.2} {psl_tay:.2}; cheb {w_cheb:.2} {psl_cheb:.2}");
    // Hann: below -30 dB, main lobe 1.6x wider (documented in src/dsp/window.rs).
    assert!(psl_hann < -30.0, "Hann PSL {psl_hann}");
    assert!(
        (w_hann / w_rect - 1.63).abs() < 0.05,
        "Hann widening {}",
        w_hann / w_rect
    );
    assert!((psl_tay + 35.0).abs() < 1.0, "Taylor PSL {psl_tay}");
    assert!(w_tay > w_rect && w_tay < w_hann, "Taylor width {w_tay}");
    assert!((psl_cheb + 50.0).abs() < 0.5, "Chebyshev PSL {psl_cheb}");
    assert!(w_cheb > w_rect, "Chebyshev width {w_cheb}");
}

#[test]
fn range_doppler_map_finds_range_and_velocity() {
    let mut rng = SplitMix64::new(33);
    let symbols = 64;
    let tx = qpsk(&mut rng, symbols, N);
    let radar = OfdmRadarConfig::default();
    let period = radar.symbol_period_s();
    let rd_config = RangeDopplerConfig::default();
    // Range rate resolution C0 / (2 fc T Q) = 183 m/s with Q = 64; put the target on bin +5.
    let v_res = radbench::dsp::C0 / (2.0 * 80e9 * period * symbols as f64);
    let t = Target {
        range: 4.0,
        amp: 1.0,
        velocity: 5.0 * v_res,
    };
    let rx_sym = echo_symbols(&tx, N, DF, FC_PHYSICAL, period, &[t, target(1.5)]);
    let rx = modulate(&rx_sym, N, OS, N * OS / 4);
    let mut receiver = OfdmRadar::new(radar.clone()).unwrap();
    let mut idiv = IDiv::new();
    receiver.divide(&rx, 0, &tx, &mut idiv).unwrap();
    let mut rd = RangeDoppler::new(&radar, symbols, &rd_config).unwrap();
    let mut map = RangeDopplerMap::default();
    rd.process(&idiv, &mut map).unwrap();
    assert_eq!(map.velocity_mps.len(), symbols);
    let zero_v = symbols / 2;
    assert!(map.velocity_mps[zero_v].abs() < 1e-9);
    // The moving target: range 4 m (bin 267), velocity bin +5 from zero, amplitude 1.
    let m = (4.0 / radar.range_bin_m()).round() as usize;
    let row = &map.amplitude[m * symbols..(m + 1) * symbols];
    let q = argmax(row);
    assert_eq!(q, zero_v + 5, "velocity {}", map.velocity_mps[q]);
    assert!((row[q] - 1.0).abs() < 0.02, "amplitude {}", row[q]);
    // The static target sits at zero velocity.
    let m = (1.5 / radar.range_bin_m()).round() as usize;
    let row = &map.amplitude[m * symbols..(m + 1) * symbols];
    assert_eq!(argmax(row), zero_v);
}

#[test]
fn bad_input_is_a_parameter_error_not_a_panic() {
    let bad = |c: OfdmRadarConfig| OfdmRadar::new(c).err().map(|e| e.to_string());
    assert!(bad(OfdmRadarConfig {
        cp_fraction: 0.3,
        ..Default::default()
    })
    .unwrap()
    .contains("whole number"));
    assert!(bad(OfdmRadarConfig {
        zero_pad: 0,
        ..Default::default()
    })
    .is_some());
    let mut radar = OfdmRadar::new(OfdmRadarConfig::default()).unwrap();
    let mut rng = SplitMix64::new(1);
    let tx = qpsk(&mut rng, 2, N);
    let rx = vec![Complex64::default(); 2560];
    let err = radar.divide(&rx, 0, &tx, &mut IDiv::new()).unwrap_err();
    assert!(err.to_string().contains("need 5120"), "{err}");
    let err = radar
        .divide(&rx, usize::MAX - 10, &tx, &mut IDiv::new())
        .unwrap_err();
    assert!(err.to_string().contains("lower the start offset"), "{err}");
    let err = radar
        .divide(&rx, 0, &tx[..100], &mut IDiv::new())
        .unwrap_err();
    assert!(err.to_string().contains("whole"), "{err}");
    let mut zero_tx = tx.clone();
    zero_tx[130] = Complex64::default();
    let rx = vec![Complex64::default(); 5120];
    let err = radar
        .divide(&rx, 0, &zero_tx, &mut IDiv::new())
        .unwrap_err();
    assert!(err.to_string().contains("symbol 1 subcarrier 2"), "{err}");
}
