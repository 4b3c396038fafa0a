use super::*;

/// A band-limited periodic test segment: a 1 GHz chirp of `l` samples at 16 GSa/s, as codes.
fn chirp_codes(l: usize) -> (Vec<i8>, Vec<i8>) {
    let fs = 16e9;
    let b = 1e9;
    let tp = l as f64 / fs;
    let (mut i, mut q) = (Vec::new(), Vec::new());
    for n in 0..l {
        let t = n as f64 / fs - tp / 2.0;
        let ph = PI * b / tp * t * t;
        i.push((100.0 * ph.cos()).round() as i8);
        q.push((100.0 * ph.sin()).round() as i8);
    }
    (i, q)
}

/// The analogue AWG output at time `t` (seconds after segment start), by the Fourier series.
fn direct(i: &[i8], q: &[i8], vpp: f64, fs: f64, t: f64) -> Complex64 {
    let l = i.len();
    let x: Vec<Complex64> = i
        .iter()
        .zip(q)
        .map(|(&a, &b)| Complex64::new(f64::from(a), f64::from(b)) * (vpp / 255.0))
        .collect();
    let mut acc = Complex64::new(0.0, 0.0);
    for k in 0..l {
        let signed = if k < l / 2 {
            k as f64
        } else {
            k as f64 - l as f64
        };
        let mut xk = Complex64::new(0.0, 0.0);
        for (n, v) in x.iter().enumerate() {
            xk += v * Complex64::from_polar(1.0, -2.0 * PI * (k * n) as f64 / l as f64);
        }
        acc += xk * Complex64::from_polar(1.0, 2.0 * PI * signed * fs / l as f64 * t);
    }
    acc / l as f64
}

fn quiet_scene(targets: Vec<Target>) -> Scene {
    Scene {
        targets,
        leakage: Leakage {
            amplitude: 0.0,
            delay_s: 0.0,
        },
        snr_db: 200.0,
        ..Scene::default()
    }
}

fn setup(points: usize) -> CaptureSetup {
    CaptureSetup {
        sample_rate: 80e9,
        points,
        trigger_offset_s: 0.0,
        volts_per_div: [0.05, 0.05],
        offset_v: [0.0, 0.0],
    }
}

fn volts(c: &Capture, m: usize) -> Complex64 {
    Complex64::new(
        f64::from(c.i_words[m]) * c.vertical_gain[0] - c.vertical_offset[0],
        f64::from(c.q_words[m]) * c.vertical_gain[1] - c.vertical_offset[1],
    )
}

/// The AWG playing `i` and `q` at 16 GSa/s, 0.5 Vpp, the marker at the segment start.
fn playing<'a>(i: &'a [i8], q: &'a [i8]) -> AwgPlayback<'a> {
    AwgPlayback {
        i,
        q,
        sample_rate: 16e9,
        amplitude_vpp: [0.5, 0.5],
        marker_index: 0,
        playing: true,
        marker_out: true,
    }
}

#[test]
fn echo_matches_the_analytic_model_sample_by_sample() {
    let (i, q) = chirp_codes(256);
    let awg = playing(&i, &q);
    let scene = quiet_scene(vec![Target {
        range_m: 1.2345,
        amplitude: 0.5,
        velocity_mps: 0.0,
    }]);
    let mut synth = Synthesizer::new(3);
    let cap = synth
        .capture(&scene, &awg, FrontEnds::ALL_ON, &setup(1280))
        .unwrap();
    let tau = 2.0 * 1.2345 / C0 + scene.system_delay_s;
    let lsb = 8.0 * 0.05 / 256.0;
    for m in (0..1280).step_by(97) {
        let t = m as f64 / 80e9;
        let want = direct(&i, &q, 0.5, 16e9, t - tau)
            * 0.5
            * Complex64::from_polar(1.0, -2.0 * PI * 80e9 * tau);
        let got = volts(&cap, m);
        assert!(
            (got - want).norm() < lsb,
            "sample {m}: got {got}, want {want}"
        );
    }
}

#[test]
fn transmitter_off_or_awg_stopped_gives_noise_only() {
    let (i, q) = chirp_codes(512);
    let mut awg = playing(&i, &q);
    let scene = Scene {
        snr_db: 20.0,
        ..quiet_scene(vec![Target {
            range_m: 1.0,
            amplitude: 1.0,
            velocity_mps: 0.0,
        }])
    };
    let mut synth = Synthesizer::new(5);
    let power = |c: &Capture| {
        (0..c.i_words.len())
            .map(|m| volts(c, m).norm_sqr())
            .sum::<f64>()
            / c.i_words.len() as f64
    };
    let on = synth
        .capture(&scene, &awg, FrontEnds::ALL_ON, &setup(2560))
        .unwrap();
    let tx_off = FrontEnds {
        tx_enabled: false,
        ..FrontEnds::ALL_ON
    };
    let off = synth.capture(&scene, &awg, tx_off, &setup(2560)).unwrap();
    awg.playing = false;
    let stopped = synth
        .capture(&scene, &awg, FrontEnds::ALL_ON, &setup(2560))
        .unwrap();
    // Signal power equals the waveform's; noise sits 20 dB below it.
    assert!(
        power(&on) > 50.0 * power(&off),
        "{} vs {}",
        power(&on),
        power(&off)
    );
    let ratio = power(&off) / power(&stopped);
    assert!((0.7..1.4).contains(&ratio), "noise floors differ: {ratio}");
}

#[test]
fn moving_target_rotates_at_its_doppler() {
    let (i, q) = chirp_codes(256);
    let awg = playing(&i, &q);
    let v = 30.0;
    let still = quiet_scene(vec![Target {
        range_m: 1.0,
        amplitude: 0.5,
        velocity_mps: 0.0,
    }]);
    let moving = quiet_scene(vec![Target {
        range_m: 1.0,
        amplitude: 0.5,
        velocity_mps: v,
    }]);
    let mut synth = Synthesizer::new(1);
    let a = synth
        .capture(&still, &awg, FrontEnds::ALL_ON, &setup(1280))
        .unwrap();
    let b = synth
        .capture(&moving, &awg, FrontEnds::ALL_ON, &setup(1280))
        .unwrap();
    let fd = -2.0 * v * 80e9 / C0;
    // Compare the phase difference between the two captures at two strong samples.
    let phase_at = |m: usize| (volts(&b, m) * volts(&a, m).conj()).arg();
    let (m1, m2) = (100, 1200);
    let measured = phase_at(m2) - phase_at(m1);
    let expected = 2.0 * PI * fd * (m2 - m1) as f64 / 80e9;
    assert!(
        (measured - expected).abs() < 0.05,
        "{measured} vs {expected}"
    );
}

#[test]
fn clipping_is_counted_and_codes_stay_in_range() {
    let (i, q) = chirp_codes(256);
    let awg = AwgPlayback {
        amplitude_vpp: [1.0, 1.0],
        ..playing(&i, &q)
    };
    let scene = quiet_scene(vec![Target {
        range_m: 1.0,
        amplitude: 1.0,
        velocity_mps: 0.0,
    }]);
    let mut s = setup(1280);
    s.volts_per_div = [0.01, 0.01];
    let cap = Synthesizer::new(1)
        .capture(&scene, &awg, FrontEnds::ALL_ON, &s)
        .unwrap();
    assert!(cap.clipped[0] > 100 && cap.clipped[1] > 100);
    assert!(cap.i_words.iter().all(|w| w & 0xff == 0));
}

#[test]
fn jitter_moves_the_trigger_offset() {
    let (i, q) = chirp_codes(256);
    let awg = playing(&i, &q);
    let scene = Scene {
        trigger_jitter_s: 1e-12,
        ..quiet_scene(vec![])
    };
    let mut synth = Synthesizer::new(9);
    let offsets: Vec<f64> = (0..200)
        .map(|_| {
            synth
                .capture(&scene, &awg, FrontEnds::ALL_ON, &setup(64))
                .unwrap()
                .horiz_offset
        })
        .collect();
    let rms = (offsets.iter().map(|o| o * o).sum::<f64>() / 200.0).sqrt();
    assert!((0.8e-12..1.2e-12).contains(&rms), "rms jitter {rms}");
}

#[test]
fn bad_scene_files_name_the_field() {
    let err = Scene::from_toml("snr_db = 500.0", "s.toml").unwrap_err();
    assert!(err.to_string().contains("snr_db"), "{err}");
    let err = Scene::from_toml("[[targets]]\nrange_m = -1.0", "s.toml").unwrap_err();
    assert!(err.to_string().contains("targets[0].range_m"), "{err}");
    let err = Scene::from_toml("colour = 3", "s.toml").unwrap_err();
    assert!(
        err.to_string().contains("s.toml") && err.to_string().contains("colour"),
        "{err}"
    );
    let err = Scene::from_toml(
        "snr_db = 20\n\n[[targets]]\nrange_m = 1.0\namplitude = 1e300\n",
        "s.toml",
    )
    .unwrap_err();
    assert_eq!(
        err.to_string(),
        "scene file s.toml, line 5: `targets[0].amplitude`: 1e300 is outside the allowed range 0 ..= 10"
    );
    let err = Scene::from_toml("[impairments]\ndc_offset_v = [0.0, 0.0, 0.1]\n", "s.toml")
        .unwrap_err()
        .to_string();
    for part in [
        "s.toml",
        "line 2",
        "dc_offset_v",
        "exactly 2 values",
        "got 3",
    ] {
        assert!(err.contains(part), "{part}: {err}");
    }
    let too_many = "[[targets]]\nrange_m = 1.0\n".repeat(MAX_REFLECTORS + 1);
    let err = Scene::from_toml(&too_many, "s.toml")
        .unwrap_err()
        .to_string();
    assert!(err.contains("line 1: `targets`: 101 entries"), "{err}");
    let ok = Scene::from_toml(
        "snr_db = 25.0\n[[targets]]\nrange_m = 1.5\namplitude = 0.3\n",
        "s.toml",
    )
    .unwrap();
    assert_eq!(ok.targets[0].range_m, 1.5);
}

#[test]
fn mismatched_rates_and_empty_segments_are_refused() {
    let (i, q) = chirp_codes(256);
    let awg = playing(&i, &q);
    let mut s = setup(64);
    s.sample_rate = 70e9;
    let err = Synthesizer::new(1)
        .capture(&Scene::default(), &awg, FrontEnds::ALL_ON, &s)
        .unwrap_err();
    assert!(err.to_string().contains("integer multiple"), "{err}");
    let empty = AwgPlayback {
        i: &[],
        q: &[],
        ..awg
    };
    assert!(Synthesizer::new(1)
        .capture(&Scene::default(), &empty, FrontEnds::ALL_ON, &setup(64))
        .is_err());
}

/// A still scene's record is rendered once and its noise drawn for every capture: the records
/// are the bits rendering afresh gives, and a moved target or a different grid is rendered anew.
#[test]
fn a_kept_render_gives_the_bits_of_a_fresh_one() {
    let (i, q) = chirp_codes(512);
    let awg = playing(&i, &q);
    let target = |range_m| Target {
        range_m,
        amplitude: 0.5,
        velocity_mps: 0.0,
    };
    let scene = Scene {
        snr_db: 30.0,
        chain: Chain {
            preset: ChainPreset::ThesisLab,
            ..Chain::default()
        },
        ..quiet_scene(vec![target(1.0)])
    };
    let moved = Scene {
        targets: vec![target(1.01)],
        ..scene.clone()
    };
    let record = |synth: &mut Synthesizer, scene: &Scene, points: usize| {
        synth
            .volts(scene, &awg, FrontEnds::ALL_ON, 80e9, points, 0.0)
            .unwrap()
            .0
            .to_vec()
    };
    let (mut kept, mut fresh) = (Synthesizer::new(7), Synthesizer::new(7));
    for (scene, points) in [
        (&scene, 2560),
        (&scene, 2560),
        (&moved, 2560),
        (&moved, 2000),
    ] {
        fresh.forget_clean();
        let a = record(&mut kept, scene, points);
        let b = record(&mut fresh, scene, points);
        assert!(a.iter().zip(&b).all(|(x, y)| x == y) && a.len() == b.len());
    }
}
