//! `radbench waveform ambiguity`: the waveform as uploaded (the closed form of a plain LFM is
//! checked in `dsp::ambiguity`'s unit tests), its plot, a capture's cross-ambiguity peaking at
//! the pillar's delay, and bad input.

use serde_json::Value;

async fn json(args: &[&str]) -> Value {
    let mut all = vec!["waveform", "ambiguity", "--json"];
    all.extend_from_slice(args);
    let (code, out, err) = crate::support::radbench_in(None, &all).await;
    assert_eq!(code, 0, "{all:?}: {err}");
    serde_json::from_str(&out).unwrap_or_else(|e| panic!("not JSON ({e}): {out}"))
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn ambiguity_of_the_uploaded_codes_and_a_captures_cross_ambiguity() {
    let tmp = tempfile::tempdir().unwrap();
    let plot = tmp.path().join("amb.png");
    let v = json(&["--plot", plot.to_str().unwrap()]).await;
    assert_eq!(v["kind"], "ambiguity");
    assert_eq!(v["wrap"], "periodic");
    assert!((v["peak"].as_f64().unwrap() - 1.0).abs() < 1e-9, "{v}");
    // The thesis' 1 GHz chirp: 0.886 / B wide, side-lobes near the sinc's -13.26 dB.
    let width = v["width_3db_s"].as_f64().unwrap();
    assert!((width * 1e9 - 0.886).abs() < 0.01, "{v}");
    let psl = v["psl_db"].as_f64().unwrap();
    assert!((-14.0..-12.5).contains(&psl), "{v}");
    let nu = v["doppler_1db_hz"].as_f64().unwrap();
    assert!(
        nu > 0.0 && v["velocity_1db_mps"].as_f64().unwrap() > 0.0,
        "{v}"
    );
    assert!(std::fs::read(&plot).unwrap().starts_with(b"\x89PNG"));
    // OFDM: a whole 12.8 us frame decorrelates under a Doppler shift far sooner.
    let o = json(&["--waveform", "ofdm"]).await;
    assert!(o["doppler_1db_hz"].as_f64().unwrap() < nu, "{o}");
    // One pulse alone (zero-padded) against the looped segment.
    let single = json(&["--single"]).await;
    assert_eq!(single["wrap"], "single");

    // A capture of the default scene (a pillar at 1.0 m, system delay 2.5 ns): the
    // cross-ambiguity peaks at the echo's delay.
    let out = tmp.path().join("cap");
    let (code, _, err) = crate::support::radbench_in(
        None,
        &["capture", "--allow-rf", "--out", out.to_str().unwrap()],
    )
    .await;
    assert_eq!(code, 0, "{err}");
    let x = json(&["--capture", out.to_str().unwrap()]).await;
    assert_eq!(x["kind"], "cross-ambiguity");
    let delay = x["peak_delay_s"].as_f64().unwrap();
    let expected = 2.0 * 1.0 / 299_792_458.0 + 2.5e-9;
    assert!(
        (delay - expected).abs() < 1.0 / 16e9,
        "{delay} vs {expected}"
    );
    assert!(x["peak"].as_f64().unwrap() > 0.0);

    // Bad input: named, exit 2.
    for args in [
        vec!["waveform", "ambiguity", "--carrier", "-1"],
        vec!["waveform", "ambiguity", "--capture", "/nonexistent/capture"],
        vec!["waveform", "ambiguity", "--plot", "amb.gif"],
    ] {
        let (code, _, err) = crate::support::radbench_in(Some(tmp.path()), &args).await;
        assert_eq!(code, 2, "{args:?}: {err}");
        assert!(!err.is_empty());
    }
}
