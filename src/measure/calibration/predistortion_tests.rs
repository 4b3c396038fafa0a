//! The transmitter's pre-distortion against the mock lab's realistic chain, without a bench: the
//! scene's synthesiser plays the codes, the response is measured from what it returns, and the
//! pre-distorted codes must leave a chain that measures flat, with the transmitter's I/Q errors
//! gone and only the receiver's skew left.

use super::response::{measure, Calibration, Repetition, Response, ResponseFigures};
use crate::measure::processing::transmit::{Dac, Transmission};
use crate::waveform::WaveformKind;
use mock_lab::scene::{AwgPlayback, FrontEnds, Scene, Synthesizer};

const RANGE_M: f64 = 1.0;

/// One period of what the scope sees of `tx`'s codes (at the waveform's rate, from the marker).
fn played(scene: &Scene, tx: &Transmission) -> Vec<num_complex::Complex64> {
    let fs = tx.sample_rate_hz();
    let awg = AwgPlayback {
        i: &tx.iq.i,
        q: &tx.iq.q,
        sample_rate: fs,
        amplitude_vpp: [0.5, 0.5],
        marker_index: 0,
        playing: true,
        marker_out: true,
    };
    let mut synth = Synthesizer::new(5);
    let (y, _) = synth
        .volts(scene, &awg, FrontEnds::ALL_ON, fs, tx.len(), 0.0)
        .expect("a scene the synthesiser takes");
    y.to_vec()
}

/// The response of the chain to `played` against the designed waveform of `designed`.
fn measured(scene: &Scene, designed: &Transmission, played: &[num_complex::Complex64]) -> Response {
    let fs = designed.sample_rate_hz();
    let delay = 2.0 * RANGE_M / crate::dsp::C0 + scene.system_delay_s;
    let rep = Repetition {
        samples: played,
        residual_s: 0.0,
    };
    measure(
        &designed.reference,
        fs,
        &[rep],
        &[],
        delay,
        3e-9,
        scene.system_delay_s,
        None,
        &super::response::ResidualWindows {
            windows: &[],
            band_hz: designed.band_hz(),
        },
    )
    .expect("a response")
}

fn calibration(response: Response) -> Calibration {
    use super::response::{InstrumentsSeen, ReferenceFigures, ResponseHeader};
    Calibration {
        header: ResponseHeader {
            format: String::new(),
            data: String::new(),
            data_sha256: String::new(),
            columns: Vec::new(),
            measured_at: String::new(),
            radbench_version: String::new(),
            waveform: String::new(),
            band_hz: response.band_hz,
            reference_range_m: RANGE_M,
            repetitions: 1,
            gate_ns: 3.0,
            reflector_m: None,
            system_delay_s: 0.0,
            figures: response.figures,
            reference: ReferenceFigures::default(),
            instruments: InstrumentsSeen::default(),
            chain_echoes: Vec::new(),
            scene_echoes: Vec::new(),
            residual: Vec::new(),
        },
        response,
        path: "test-response.toml".into(),
        sha256: String::new(),
    }
}

#[test]
fn pre_distortion_leaves_a_flat_chain_and_only_the_receivers_skew() {
    let scene = Scene::from_toml(
        &format!(
            "snr_db = 70.0\n[[targets]]\nrange_m = {RANGE_M}\namplitude = 0.5\n\
             [chain]\npreset = \"thesis-lab\"\n"
        ),
        "test scene",
    )
    .unwrap();
    let truth = mock_lab::scene::ChainParams::thesis_lab();
    for kind in [WaveformKind::MskLfm, WaveformKind::Ofdm] {
        let tx = Transmission::new(&kind.thesis_default(), None, 1, Dac::default()).unwrap();
        let raw = measured(&scene, &tx, &played(&scene, &tx));
        let f: &ResponseFigures = &raw.figures;
        assert!(f.iq_skews_separated, "{kind:?}: {f:?}");
        assert!(
            (f.tx_iq_gain_db - truth.tx_iq_gain_db).abs() < 0.05,
            "{kind:?}: {f:?}"
        );
        assert!(
            (f.tx_iq_phase_deg - truth.tx_iq_phase_deg).abs() < 0.3,
            "{kind:?}: {f:?}"
        );
        // Within 0.3 ps, or twice the standard error the split states (the chain's ripple under
        // the image is what limits it here, not the noise).
        let skew_tol = 0.3f64.max(2.0 * f.iq_skew_sd_ps);
        assert!(
            (f.tx_iq_skew_ps - truth.tx_iq_skew_ps).abs() < skew_tol,
            "{kind:?}: {f:?}"
        );
        assert!(
            (f.rx_iq_skew_ps - truth.rx_iq_skew_ps).abs() < skew_tol,
            "{kind:?}: {f:?}"
        );
        assert!(f.ripple_db_pp > 1.0, "{kind:?}: {f:?}");

        let cal = calibration(raw.clone());
        let pd = tx.predistorted(&cal, true).unwrap();
        let report = pd.predistortion.as_ref().unwrap();
        assert!((report.tx_iq_skew_ps - f.tx_iq_skew_ps).abs() < 1e-9);
        // Measured against the waveform as designed: what the chain made of the new codes.
        let after = measured(&scene, &tx, &played(&scene, &pd));
        let g = &after.figures;
        assert!(
            g.ripple_db_pp < 0.3 * f.ripple_db_pp,
            "{kind:?}: {f:?} -> {g:?}"
        );
        assert!(g.tx_iq_gain_db.abs() < 0.05, "{kind:?}: {g:?}");
        assert!(g.tx_iq_phase_deg.abs() < 0.3, "{kind:?}: {g:?}");
        if g.iq_skews_separated {
            assert!(g.tx_iq_skew_ps.abs() < 0.3, "{kind:?}: {g:?}");
            assert!(
                (g.rx_iq_skew_ps - truth.rx_iq_skew_ps).abs() < 0.3,
                "{kind:?}: {g:?}"
            );
        }
        // The transmitter's image (about -29 dB) is gone; the receiver's skew leaves about -50.
        assert!(f.image_db > -32.0, "{kind:?}: {f:?}");
        assert!(g.image_db < -45.0, "{kind:?}: {f:?} -> {g:?}");
        // `both`: the receiver undoes its skew too, and no image is left.
        let mut y = played(&scene, &pd);
        let fs = tx.sample_rate_hz();
        raw.receiver_only(y.len(), fs)
            .unwrap()
            .apply(&mut y, false)
            .unwrap();
        let both = measured(&scene, &tx, &y).figures;
        assert!(both.image_db < -60.0, "{kind:?}: {g:?} -> {both:?}");
        assert!(
            both.ripple_db_pp < 0.3 * f.ripple_db_pp,
            "{kind:?}: {both:?}"
        );
    }
}
