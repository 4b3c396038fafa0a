//! Each part of the chain is applied as documented: the response's ratio, the standing wave's and
//! the group-delay ripple's echoes, the I/Q skews' and imbalance's images, the timebase's drift,
//! the second path, the shared LO's phase noise and the Tx's compression.

use super::*;

const FS_AWG: f64 = 16e9;
const FS: f64 = 80e9;

/// Codes of a complex tone of `bin` cycles per `l`-sample segment at 16 GSa/s.
fn tone(l: usize, bin: i64, amplitude: f64) -> (Vec<i8>, Vec<i8>) {
    (0..l)
        .map(|n| {
            let ph = 2.0 * PI * bin as f64 * n as f64 / l as f64;
            (
                (amplitude * ph.cos()).round() as i8,
                (amplitude * ph.sin()).round() as i8,
            )
        })
        .unzip()
}

/// A 1 GHz chirp over the whole segment.
fn chirp(l: usize) -> (Vec<i8>, Vec<i8>) {
    let tp = l as f64 / FS_AWG;
    (0..l)
        .map(|n| {
            let t = n as f64 / FS_AWG - tp / 2.0;
            let ph = PI * 1e9 / tp * t * t;
            (
                (100.0 * ph.cos()).round() as i8,
                (100.0 * ph.sin()).round() as i8,
            )
        })
        .unzip()
}

fn awg<'a>(i: &'a [i8], q: &'a [i8]) -> AwgPlayback<'a> {
    AwgPlayback {
        i,
        q,
        sample_rate: FS_AWG,
        amplitude_vpp: [0.5, 0.5],
        marker_index: 0,
        playing: true,
        marker_out: true,
    }
}

/// One noise-free pillar at `range_m`, no leakage, on `chain`.
fn scene(range_m: f64, chain: Chain) -> Scene {
    Scene {
        targets: vec![Target {
            range_m,
            amplitude: 0.5,
            velocity_mps: 0.0,
        }],
        leakage: Leakage {
            amplitude: 0.0,
            delay_s: 0.0,
        },
        snr_db: 200.0,
        chain,
        ..Scene::default()
    }
}

fn record(scene: &Scene, i: &[i8], q: &[i8], points: usize) -> Vec<Complex64> {
    let mut synth = Synthesizer::new(9);
    let (y, _) = synth
        .volts(scene, &awg(i, q), FrontEnds::ALL_ON, FS, points, 0.0)
        .unwrap();
    y.to_vec()
}

fn spectrum(mut y: Vec<Complex64>) -> Vec<Complex64> {
    FftPlanner::new().plan_fft_forward(y.len()).process(&mut y);
    y
}

fn bin_of(f: f64, n: usize) -> usize {
    ((f / FS * n as f64).round() as i64).rem_euclid(n as i64) as usize
}

fn thesis_lab_linear() -> Chain {
    Chain {
        preset: ChainPreset::ThesisLab,
        tx_iq_gain_db: Some(0.0),
        tx_iq_phase_deg: Some(0.0),
        tx_iq_skew_ps: Some(0.0),
        rx_iq_skew_ps: Some(0.0),
        ..Chain::default()
    }
}

#[test]
fn the_response_divides_out_as_configured_across_the_band() {
    let l = 4096;
    let (i, q) = chirp(l);
    let n = l * 5;
    let ideal = spectrum(record(&scene(1.0, Chain::default()), &i, &q, n));
    let chain = thesis_lab_linear();
    let params = chain.resolve();
    let shaped = spectrum(record(&scene(1.0, chain), &i, &q, n));
    let mut f = -0.45e9;
    while f <= 0.45e9 {
        let k = bin_of(f, n);
        let f_bin = signed_bin(k, n) as f64 * FS / n as f64;
        let want = params.response_at(f_bin) * params.channel_filter(f_bin, FS_AWG);
        let got = shaped[k] / ideal[k];
        assert!(
            (got - want).norm() < 1e-6 * want.norm(),
            "{f_bin} Hz: got {got}, want {want}"
        );
        f += 0.05e9;
    }
    // The preset's numbers: the standing wave swings 1.8 dB peak to peak (over one 890 MHz
    // period).
    let mags: Vec<f64> = (-500..=500)
        .map(|k| {
            let f = k as f64 * 1e6;
            20.0 * (params.response_at(f).norm() / 10f64.powf(-0.8 * f / 1e9 / 20.0)).log10()
        })
        .collect();
    let pp = mags.iter().cloned().fold(f64::MIN, f64::max)
        - mags.iter().cloned().fold(f64::MAX, f64::min);
    assert!((pp - 1.8).abs() < 0.02, "ripple {pp} dB p-p");
}

/// The complex correlation of `y` with `reference` at integer lags `lags` (samples).
fn correlate_at(y: &[Complex64], reference: &[Complex64], lag: i64) -> Complex64 {
    let n = y.len() as i64;
    (0..n)
        .map(|m| y[m as usize] * reference[((m - lag).rem_euclid(n)) as usize].conj())
        .sum::<Complex64>()
        / reference.iter().map(|v| v.norm_sqr()).sum::<f64>()
}

#[test]
fn a_standing_wave_is_one_echo_its_period_predicts_and_group_delay_ripple_a_pair() {
    let l = 4096;
    let (i, q) = chirp(l);
    let n = l * 5;
    let ideal = record(&scene(1.0, Chain::default()), &i, &q, n);
    // 2 dB p-p at a 500 MHz period: one echo 2 ns behind, g = (r - 1) / (r + 1).
    let standing = Chain {
        ripple_db: Some(2.0),
        ripple_period_hz: Some(500e6),
        ..Chain::default()
    };
    let y = record(&scene(1.0, standing), &i, &q, n);
    let r = 10f64.powf(2.0 / 20.0);
    let g = (r - 1.0) / (r + 1.0);
    let lag = (2e-9 * FS).round() as i64;
    let diff = |y: Vec<Complex64>| -> Vec<Complex64> {
        y.iter().zip(&ideal).map(|(a, b)| a - b).collect()
    };
    let y = diff(y);
    let echo = correlate_at(&y, &ideal, lag).norm();
    assert!((echo - g).abs() < 0.01, "echo {echo}, want {g}");
    let ahead = correlate_at(&y, &ideal, -lag).norm();
    assert!(ahead < 0.02, "a standing wave has no echo ahead: {ahead}");
    // 100 ps p-p at a 250 MHz period: phase A sin(2 pi f / P) with A = gd_pp P / 2, echoes 4 ns
    // either side, each A / 2.
    let ripple = Chain {
        group_delay_ripple_ps: Some(100.0),
        group_delay_ripple_period_hz: Some(250e6),
        ..Chain::default()
    };
    let y = diff(record(&scene(1.0, ripple), &i, &q, n));
    let a = 100e-12 * 250e6 / 2.0;
    let lag = (4e-9 * FS).round() as i64;
    for l in [lag, -lag] {
        let e = correlate_at(&y, &ideal, l).norm();
        assert!(
            (e - a / 2.0).abs() < 0.2 * a / 2.0,
            "lag {l}: {e}, want {}",
            a / 2.0
        );
    }
}

/// Power at `+f` and `-f` of `y`.
fn tone_and_image(y: Vec<Complex64>, f: f64) -> (f64, f64) {
    let n = y.len();
    let s = spectrum(y);
    (s[bin_of(f, n)].norm(), s[bin_of(-f, n)].norm())
}

#[test]
fn iq_skews_and_the_tx_imbalance_give_the_images_they_should() {
    let l = 1600; // 10 MHz bins at 16 GSa/s
    let (i, q) = tone(l, 50, 100.0); // 500 MHz
    let f = 500e6;
    let n = l * 5;
    // Q delayed by tau: image / tone = tan(pi f tau).
    for (name, chain) in [
        (
            "rx",
            Chain {
                rx_iq_skew_ps: Some(20.0),
                ..Chain::default()
            },
        ),
        (
            "tx",
            Chain {
                tx_iq_skew_ps: Some(20.0),
                ..Chain::default()
            },
        ),
    ] {
        let (t, im) = tone_and_image(record(&scene(1.0, chain), &i, &q, n), f);
        let want = (PI * f * 20e-12).tan();
        assert!(
            (im / t - want).abs() < 0.05 * want,
            "{name}: {} want {want}",
            im / t
        );
    }
    // Gain g and phase phi on Q: image / tone = |1 - g e^{-j phi}| / |1 + g e^{-j phi}|.
    let chain = Chain {
        tx_iq_gain_db: Some(1.0),
        tx_iq_phase_deg: Some(9.0),
        ..Chain::default()
    };
    let (t, im) = tone_and_image(record(&scene(1.0, chain), &i, &q, n), f);
    let g = Complex64::from_polar(10f64.powf(1.0 / 20.0), -9f64.to_radians());
    let want = (1.0 - g).norm() / (1.0 + g).norm();
    assert!(
        (im / t - want).abs() < 0.02 * want,
        "{} want {want}",
        im / t
    );
    assert!(
        (20.0 * want.log10() + 20.2).abs() < 0.3,
        "1 dB and 9 degrees: about -20 dB"
    );
}

#[test]
fn a_timebase_offset_drifts_the_echo_as_predicted() {
    let l = 16_000; // 1 us chirps
    let (i, q) = chirp(l);
    let period = l * 5;
    let n = period * 8;
    let ideal = record(&scene(1.0, Chain::default()), &i, &q, n);
    let chain = Chain {
        shared_reference: Some(false),
        timebase_offset_ppm: Some(50.0),
        ..Chain::default()
    };
    let y = record(&scene(1.0, chain), &i, &q, n);
    // The delay of each repetition against the ideal one, from the phase slope across the band.
    let delay = |k: usize| {
        let a = spectrum(y[k * period..(k + 1) * period].to_vec());
        let b = spectrum(ideal[k * period..(k + 1) * period].to_vec());
        let df = FS / period as f64;
        // The mean phase step from bin to bin across +-0.3 GHz.
        let cross = |k: i64| {
            let b_k = bin_of(k as f64 * df, period);
            a[b_k] * b[b_k].conj()
        };
        let edge = (0.3e9 / df) as i64;
        let step: Complex64 = (-edge..edge).map(|k| cross(k + 1) * cross(k).conj()).sum();
        -step.arg() / (2.0 * PI * df)
    };
    // Scope sample n is at true time n (1 - eps): the echo arrives eps t late at scope time t,
    // 350 ps more in the 8th microsecond than in the 1st.
    let want = |k: usize| {
        let t_mid = (k as f64 + 0.5) * period as f64 / FS;
        50e-6 * (t_mid + 2.0 / C0 + Scene::default().system_delay_s)
    };
    let (first, last) = (delay(0), delay(7));
    for (k, got) in [(0, first), (7, last)] {
        assert!(
            (got - want(k)).abs() < 2e-12,
            "repetition {k}: {got} s, want {} s",
            want(k)
        );
    }
    let drift = last - first;
    assert!((drift - 350e-12).abs() < 2e-12, "drift {drift} s");
}

#[test]
fn multipath_adds_a_second_echo_at_its_extra_length() {
    let l = 4096;
    let (i, q) = chirp(l);
    let n = l * 5;
    let ideal = record(&scene(1.0, Chain::default()), &i, &q, n);
    let chain = Chain {
        multipath_extra_m: Some(0.6),
        multipath_level_db: Some(-12.0),
        ..Chain::default()
    };
    let y = record(&scene(1.0, chain), &i, &q, n);
    let lag = (0.6 / C0 * FS).round() as i64;
    let e = correlate_at(&y, &ideal, lag).norm();
    let want = 10f64.powf(-12.0 / 20.0);
    assert!((e - want).abs() < 0.02, "{e} want {want}");
}

#[test]
fn a_shared_lo_leaves_the_round_trip_phase_noise_not_a_drift() {
    let l = 1600;
    let (i, q) = tone(l, 50, 100.0);
    let n = l * 5 * 16; // 1.6 us
    let range = 1.5; // 10 ns round trip with the system delay
    let ideal = record(&scene(range, Chain::default()), &i, &q, n);
    let linewidth = 1e6;
    let phase_spread = |chain: Chain| {
        let mut s = scene(range, chain);
        s.impairments.phase_noise_linewidth_hz = linewidth;
        let mut synth = Synthesizer::new(4);
        let y = synth
            .volts(&s, &awg(&i, &q), FrontEnds::ALL_ON, FS, n, 0.0)
            .unwrap()
            .0
            .to_vec();
        let ph: Vec<f64> = y
            .iter()
            .zip(&ideal)
            .map(|(a, b)| (a * b.conj()).arg())
            .collect();
        let early = ph[..n / 8].iter().map(|p| p * p).sum::<f64>() / (n / 8) as f64;
        let late = ph[7 * n / 8..].iter().map(|p| p * p).sum::<f64>() / (n / 8) as f64;
        (early, late)
    };
    let tau = 2.0 * range / C0 + Scene::default().system_delay_s;
    let want = 2.0 * PI * linewidth * tau;
    let (early, late) = phase_spread(Chain::default());
    for v in [early, late] {
        assert!(
            v > 0.5 * want && v < 1.6 * want,
            "shared LO: {v} rad^2, want ~{want}"
        );
    }
    // Independent LOs: the phase wanders over the record, far more by its end.
    let (_, late) = phase_spread(Chain {
        shared_lo: Some(false),
        ..Chain::default()
    });
    assert!(late > 10.0 * want, "independent LOs: {late} rad^2");
}

#[test]
fn the_tx_compresses_1_db_at_its_p1db() {
    let l = 1600;
    let (i, q) = tone(l, 50, 127.0);
    let drive = 127.0 * 0.5 / 255.0; // |I + jQ| of the tone, volts
    let n = l * 5;
    let level = |chain: Chain| tone_and_image(record(&scene(1.0, chain), &i, &q, n), 500e6).0;
    let linear = level(Chain::default());
    let compressed = level(Chain {
        tx_p1db_v: Some(drive),
        ..Chain::default()
    });
    let db = 20.0 * (compressed / linear).log10();
    assert!((db + 1.0).abs() < 0.05, "{db} dB");
}

#[test]
fn presets_resolve_and_fields_override_them() {
    let text = "[chain]\npreset = \"thesis-lab\"\nripple_db = 0.5\n";
    let s = Scene::from_toml(text, "s.toml").unwrap();
    let p = s.chain.resolve();
    assert_eq!(p.ripple_db, 0.5);
    assert_eq!(p.tilt_db_per_ghz, ChainParams::thesis_lab().tilt_db_per_ghz);
    assert!(Scene::default().chain.resolve().is_ideal());
    for (text, field) in [
        ("[chain]\nripple_db = 12.0\n", "chain.ripple_db"),
        (
            "[chain]\ntimebase_offset_ppm = 3.0\n",
            "chain.timebase_offset_ppm",
        ),
        ("[chain]\npreset = \"lab\"\n", "preset"),
        (
            "[chain]\nresponse = [[1e8, 0.0, 0.0], [0.0, 0.0, 0.0]]\n",
            "chain.response[1][0]",
        ),
    ] {
        let err = Scene::from_toml(text, "s.toml").unwrap_err().to_string();
        assert!(err.contains(field), "{text}: {err}");
    }
}

/// The tone's complex value at the capture of the record `y` (its bin).
fn tone_value(y: Vec<Complex64>, bin_hz: f64) -> Complex64 {
    let n = y.len();
    spectrum(y)[bin_of(bin_hz, n)]
}

#[test]
fn the_drift_moves_every_path_by_its_delay_and_phase_against_the_simulated_clock() {
    let l = 4096;
    let bin = 64;
    let (i, q) = tone(l, bin, 100.0);
    let f = bin as f64 * FS_AWG / l as f64;
    let n = l * 5;
    let chain = Chain {
        drift_ps_per_min: Some(2.0),
        drift_deg_per_min: Some(10.0),
        ..Chain::default()
    };
    let at = |clock_s: f64| {
        let s = Scene {
            clock_s,
            ..scene(1.0, chain.clone())
        };
        tone_value(record(&s, &i, &q, n), f)
    };
    let (start, later) = (at(0.0), at(180.0));
    // 3 minutes: 6 ps of delay (the carrier and the tone turn with it) and 30 degrees.
    let want = -2.0 * PI * (80e9 + f) * 6e-12 + 30f64.to_radians();
    let got = (later / start).arg();
    let wrap = |x: f64| (x + PI).rem_euclid(2.0 * PI) - PI;
    assert!(wrap(got - want).abs() < 1e-6, "{got} rad, want {want} rad");
    assert!(((later.norm() / start.norm()) - 1.0).abs() < 1e-9);
}

#[test]
fn the_clock_advances_by_the_capture_interval_and_the_ground_truth_records_it() {
    let (i, q) = tone(1024, 8, 100.0);
    let s = Scene {
        clock_s: 60.0,
        capture_interval_s: 10.0,
        reference: Some(Target {
            range_m: 0.5,
            amplitude: 0.1,
            velocity_mps: 0.0,
        }),
        ..scene(1.0, Chain::default())
    };
    let mut synth = Synthesizer::new(3);
    let setup = CaptureSetup {
        sample_rate: FS,
        points: 5120,
        trigger_offset_s: 0.0,
        volts_per_div: [0.1, 0.1],
        offset_v: [0.0, 0.0],
    };
    let clocks: Vec<f64> = (0..3)
        .map(|_| {
            synth
                .capture(&s, &awg(&i, &q), FrontEnds::ALL_ON, &setup)
                .unwrap()
                .scene
                .clock_s
        })
        .collect();
    assert_eq!(clocks, [60.0, 70.0, 80.0]);
}

#[test]
fn a_reference_reflector_is_one_more_fixed_path() {
    let l = 4096;
    let bin = 64;
    let (i, q) = tone(l, bin, 100.0);
    let f = bin as f64 * FS_AWG / l as f64;
    let n = l * 5;
    let reflector = Target {
        range_m: 0.5,
        amplitude: 0.1,
        velocity_mps: 0.0,
    };
    let without = tone_value(record(&scene(1.0, Chain::default()), &i, &q, n), f);
    let with = Scene {
        reference: Some(reflector.clone()),
        ..scene(1.0, Chain::default())
    };
    let with = tone_value(record(&with, &i, &q, n), f);
    let alone = Scene {
        targets: vec![reflector],
        ..scene(1.0, Chain::default())
    };
    let alone = tone_value(record(&alone, &i, &q, n), f);
    assert!((with - without - alone).norm() < 1e-9 * without.norm());
    let bad = Scene {
        reference: Some(Target {
            range_m: -1.0,
            amplitude: 0.1,
            velocity_mps: 0.0,
        }),
        ..Scene::default()
    };
    let err = bad.validate().unwrap_err().to_string();
    assert!(err.contains("reference.range_m"), "{err}");
}
