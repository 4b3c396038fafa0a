//! The Infiniium UXR driver against a scripted session: the command sequence of a configure, a
//! segmented capture decoded from its preamble and block, and bad replies refused with a clear
//! error (never a panic).

use crate::driver_support::{bounded, model};
use radbench::driver::{Digitizer, DigitizerSettings, DriverError, KeysightUxr, Scripted};

const IDN: &str = "MOCK_LAB,UXR0334A-EMU,EMU0005,mock_lab-1";

async fn scope(fake: Scripted) -> Result<KeysightUxr, DriverError> {
    let fake = fake.reply("*IDN?", IDN);
    bounded(KeysightUxr::connect(
        Box::new(fake),
        &model("keysight-uxr0334a"),
        "scope",
    ))
    .await
}

fn settings(segments: u32) -> DigitizerSettings {
    DigitizerSettings {
        sample_rate_hz: 128e9,
        repetition_s: 1000.0 / 128e9,
        longest_echo_s: 0.0,
        segments,
        ..DigitizerSettings::default()
    }
}

fn configured(fake: Scripted, segments: u32) -> Scripted {
    let fake = fake
        .reply(":ACQuire:SRATe:ANALog?", "1.28E+11")
        .reply(":ACQuire:POINts:ANALog?", "1000");
    if segments > 1 {
        fake.reply(":ACQuire:SEGMented:COUNt?", &segments.to_string())
    } else {
        fake
    }
}

fn words(codes: &[i16]) -> Vec<u8> {
    let payload: Vec<u8> = codes.iter().flat_map(|c| c.to_le_bytes()).collect();
    let len = payload.len().to_string();
    let mut out = format!("#{}{len}", len.len()).into_bytes();
    out.extend(payload);
    out
}

const PREAMBLE: &str = "2,1,1000,1,7.8125E-12,-0.0E+00,0,6.1035E-06,1.0E-03,0,1";

#[tokio::test]
async fn configure_then_a_segmented_capture_is_decoded_in_volts() {
    let codes: Vec<i16> = (0..2000).map(|k| (k % 64) as i16 * 64).collect();
    let fake = configured(Scripted::new("scope"), 2)
        .reply(":ADER?", "0")
        .reply(":ADER?", "1")
        .reply(":WAVeform:PREamble?", PREAMBLE)
        .reply_block(":WAVeform:DATA?", words(&codes))
        .reply(":WAVeform:SEGMented:XLISt? TTAG", "0,6.25E-07")
        .reply(":WAVeform:PREamble?", PREAMBLE)
        .reply_block(":WAVeform:DATA?", words(&codes))
        .reply(":WAVeform:SEGMented:XLISt? TTAG", "0,6.25E-07");
    let log = fake.log();
    let mut s = scope(fake).await.unwrap();
    let applied = bounded(s.configure(&settings(2))).await.unwrap();
    assert_eq!(applied.points, 1000);
    assert_eq!(applied.trigger_source, "AUX");
    let ops = log.ops().join("\n");
    for command in [
        ":WAVeform:FORMat WORD",
        ":WAVeform:BYTeorder LSBFirst",
        ":ACQuire:MODE SEGMented",
        ":ACQuire:SEGMented:COUNt 2",
        ":WAVeform:SEGMented:ALL ON",
        ":ACQuire:POINts:ANALog 1000",
        ":TRIGger:EDGE:SOURce AUX",
    ] {
        assert!(ops.contains(command), "{command} not sent:\n{ops}");
    }
    let iq = bounded(s.capture_iq(1.0)).await.unwrap();
    assert_eq!(iq.segments(), 2);
    assert_eq!(iq.i.segment_len(), 1000);
    assert!(iq.i.native.is_none(), "the UXR path saves no native file");
    let t = iq.i.timing(1);
    assert_eq!(t.trigger_time_s, Some(6.25e-7));
    // volts = code x Y increment + Y origin.
    let v = iq.i.volts_per_code * f64::from(iq.i.codes[1]) - iq.i.offset_v;
    assert!((v - (64.0 * 6.1035e-6 + 1e-3)).abs() < 1e-12, "{v}");
}

#[tokio::test]
async fn bad_replies_are_refused_with_a_clear_error() {
    let cases: [(&str, Scripted); 4] = [
        (
            "a preamble in BYTE format",
            Scripted::new("scope").reply(":WAVeform:PREamble?", "1,1,1000,1,1E-11,0,0,1E-5,0,0"),
        ),
        (
            "a preamble with too few fields",
            Scripted::new("scope").reply(":WAVeform:PREamble?", "2,1,1000"),
        ),
        (
            "an odd block",
            Scripted::new("scope")
                .reply(":WAVeform:PREamble?", PREAMBLE)
                .reply_block(":WAVeform:DATA?", b"#13abc".to_vec()),
        ),
        (
            "a non-numeric acquisition register",
            Scripted::new("scope").reply(":ADER?", "maybe"),
        ),
    ];
    for (what, fake) in cases {
        let mut s = scope(fake.reply(":ADER?", "0").reply(":ADER?", "1"))
            .await
            .unwrap();
        let e = if what.contains("register") {
            bounded(s.acquire(1.0)).await.err()
        } else {
            bounded(s.fetch(1)).await.err()
        };
        let e = e.unwrap_or_else(|| panic!("{what}: accepted"));
        assert!(
            matches!(e, DriverError::Reply { .. }),
            "{what}: {e} ({e:?})"
        );
        assert!(e.to_string().contains(":WAVeform") || e.to_string().contains(":ADER?"));
    }
}

#[tokio::test]
async fn settings_outside_the_catalog_are_refused_before_anything_is_sent() {
    let fake = Scripted::new("scope");
    let log = fake.log();
    let mut s = scope(fake).await.unwrap();
    log.clear();
    let e = bounded(s.configure(&DigitizerSettings {
        sample_rate_hz: 80e9,
        ..settings(1)
    }))
    .await
    .unwrap_err();
    assert!(e.to_string().contains("sample_rate_hz"), "{e}");
    assert!(log.ops().is_empty(), "{:?}", log.ops());
}

#[tokio::test]
async fn a_missing_trigger_disarms_and_says_so() {
    let fake = Scripted::new("scope").reply_times(":ADER?", "0", 1000);
    let log = fake.log();
    let mut s = scope(fake).await.unwrap();
    let e = bounded(s.acquire(0.02)).await.unwrap_err();
    assert!(matches!(e, DriverError::NoTrigger { .. }), "{e}");
    assert!(log.ops().iter().any(|o| o.contains(":STOP")));
}
