//! Drivers against the scripted fake session: the exact command sequence of every operation,
//! limits refused before anything is sent, refusals surfaced with code and text, and the safe
//! state still sent after an error mid-configuration.

use crate::driver_support;

use std::time::Duration;

use driver_support::{bounded, guarded, model, AWG_SAFE_STATE};
use radbench::driver::{
    Awg, AwgSettings, Digitizer, DigitizerSettings, DriverError, Gotmic, IqWaveform, Lecroy,
    M8195a, ReferenceClock, RfFrontEnd, RfPermit, RfSettings, ScriptLog, Scripted,
};
use radbench::driver::{Failure, ERROR_CHECK};
use radbench::exit::{Classify, ExitClass};
use radbench::trc::BlockBuilder;

// ---------------------------------------------------------------- M8195A

const AWG_IDN: &str = "Keysight Technologies,M8195A,MY00000001,4.0.0.0";

/// The AWG's state read back as one compound query ([`AWG_READBACK`]).
fn awg_readback(fake: Scripted, segment: &str, outputs: &str) -> Scripted {
    let replies = [
        "DCM",
        "DIV4",
        "6.4000000000E+10",
        segment,
        "5.0000E-01",
        "5.0000E-01",
        "5.0000E-01",
        "2.5000E-01",
        "INT",
        outputs,
        outputs,
        outputs,
    ];
    fake.reply(AWG_READBACK[0], &replies.join(";"))
}

const AWG_CONFIGURE: &[&str] = &[
    ERROR_CHECK,
    ":ABOR",
    ":ROSC:SOUR INT",
    ":INST:DACM DCM",
    ":INST:MEM:EXT:RDIV DIV4",
    ":TRAC1:MMOD EXT",
    ":TRAC2:MMOD EXT",
    ":FREQ:RAST 64000000000",
    ":FUNC:MODE ARB",
    ":INIT:CONT 1",
    ":INIT:GATE 0",
    ERROR_CHECK,
    ":VOLT1 0.5",
    ":VOLT1:OFFS 0",
    ":VOLT2 0.5",
    ":VOLT2:OFFS 0",
    ":VOLT3:AMPL 0.5",
    ":VOLT3:OFFS 0.25",
    ERROR_CHECK,
];

const AWG_READBACK: &[&str] = &[":INST:DACM?;:INST:MEM:EXT:RDIV?;:FREQ:RAST?;:TRAC1:CAT?;\
    :VOLT1?;:VOLT2?;:VOLT3:AMPL?;:VOLT3:OFFS?;:ROSC:SOUR?;:OUTP1?;:OUTP2?;:OUTP3?"];
async fn awg(fake: Scripted) -> (M8195a, ScriptLog) {
    let fake = fake.reply("*IDN?", AWG_IDN);
    let log = fake.log();
    let driver = bounded(M8195a::connect(
        Box::new(fake),
        &model("keysight-m8195a"),
        "awg",
    ))
    .await
    .unwrap();
    assert_eq!(log.ops(), ["*IDN?"]);
    log.clear();
    (driver, log)
}

fn strings(parts: &[&[&str]]) -> Vec<String> {
    parts
        .iter()
        .flat_map(|p| p.iter().map(|s| s.to_string()))
        .collect()
}

#[tokio::test]
async fn m8195a_configure_sends_the_cookbook_sequence_and_reads_back() {
    let (mut awg, log) = awg(awg_readback(Scripted::new("awg"), "0,0", "0")).await;
    let applied = bounded(awg.configure(&AwgSettings::default()))
        .await
        .unwrap();
    assert_eq!(log.ops(), strings(&[AWG_CONFIGURE, AWG_READBACK]));
    assert_eq!(applied.dac_mode, "DCM");
    assert_eq!(applied.divider, 4);
    assert_eq!(applied.sample_rate_hz, 16e9);
    assert!(applied.segments.is_empty());
    log.assert_no_surprises();
}

#[tokio::test]
async fn m8195a_download_interleaves_i_with_the_marker_and_pads_to_granularity() {
    let fake = awg_readback(Scripted::new("awg"), "0,0", "0")
        .reply("*OPC?", "1")
        .reply(":TRAC1:CAT?", "1,1024");
    let (mut awg, log) = awg(fake).await;
    bounded(awg.configure(&AwgSettings::default()))
        .await
        .unwrap();
    log.clear();
    let n = 1000;
    let waveform = IqWaveform {
        i: (0..n).map(|k| (k % 100) as i8).collect(),
        q: (0..n).map(|k| -((k % 100) as i8)).collect(),
        marker_high_samples: 64,
    };
    let loaded = bounded(awg.load(&waveform)).await.unwrap();
    assert_eq!(loaded.padded_samples, 1024);
    assert_eq!(loaded.chunks_per_channel, 1);
    // `*OPC?` after the download waits the catalog's operation-complete time, passed per call.
    let opc_ms = model("keysight-m8195a").timeouts.operation_complete_ms;
    assert_eq!(
        log.timeouts(),
        [("*OPC?".to_string(), Duration::from_millis(opc_ms))]
    );
    assert_eq!(
        log.ops(),
        [
            ":ABOR",
            ":TRAC1:DEL:ALL",
            ":TRAC1:DEF 1,1024",
            ":TRAC1:DATA 1,0,#<2048 bytes>",
            ":TRAC2:DATA 1,0,#<1024 bytes>",
            "*OPC?",
            ":TRAC1:SEL 1",
            ":TRAC2:SEL 1",
            ERROR_CHECK,
            ":TRAC1:CAT?",
        ]
    );
    let blocks = log.blocks();
    let ch1 = &blocks[0].1;
    assert_eq!(ch1[2 * 5], 5, "sample byte first");
    assert_eq!(
        ch1[2 * 5 + 1],
        1,
        "marker bit0 high in the first 64 samples"
    );
    assert_eq!(ch1[2 * 64 + 1], 0, "marker low after 64 samples");
    assert_eq!(&ch1[2 * 1000..], &[0u8; 48][..], "zero padding");
    let ch2 = &blocks[1].1;
    assert_eq!(ch2[7] as i8, -7);
    log.assert_no_surprises();
}

#[tokio::test]
async fn m8195a_outputs_run_stop_and_safe_state() {
    let (mut awg, log) = awg(Scripted::new("awg")).await;
    let permit = RfPermit::granted_by_user();
    bounded(awg.enable_outputs(&permit)).await.unwrap();
    bounded(awg.run()).await.unwrap();
    bounded(awg.stop()).await.unwrap();
    bounded(awg.safe_state()).await.unwrap();
    let mut expected = vec![
        ":OUTP1 ON",
        ":OUTP2 ON",
        ":OUTP3 ON",
        ERROR_CHECK,
        ":INIT:IMM",
        ERROR_CHECK,
        ":ABOR",
        ERROR_CHECK,
    ];
    expected.extend(AWG_SAFE_STATE);
    assert_eq!(log.ops(), expected);
}

/// Configures `settings` on a scripted AWG: the limit error, and nothing sent.
async fn awg_refuses(settings: AwgSettings, field: &str) {
    let (mut awg, log) = awg(Scripted::new("awg")).await;
    let e = bounded(awg.configure(&settings)).await.unwrap_err();
    assert!(
        matches!(&e, DriverError::OutOfLimits { field: f, .. } if f.contains(field)),
        "{e}"
    );
    assert_eq!(e.exit_class(), ExitClass::BadInput);
    assert!(log.ops().is_empty(), "sent {:?}", log.ops());
}

#[tokio::test]
async fn m8195a_a_sample_rate_off_the_divider_ranges_sends_nothing() {
    let settings = AwgSettings {
        sample_rate_hz: 20e9,
        ..AwgSettings::default()
    };
    awg_refuses(settings, "sample_rate_hz").await;
}

#[tokio::test]
async fn m8195a_an_amplitude_above_the_catalog_sends_nothing() {
    let settings = AwgSettings {
        i_amplitude_vpp: 1.5,
        ..AwgSettings::default()
    };
    awg_refuses(settings, "i_amplitude_vpp").await;
}

#[tokio::test]
async fn m8195a_a_marker_level_below_the_catalog_sends_nothing() {
    let settings = AwgSettings {
        marker_amplitude_v: 0.01,
        ..AwgSettings::default()
    };
    awg_refuses(settings, "marker_amplitude_v").await;
}

#[tokio::test]
async fn m8195a_a_reference_frequency_off_the_range_sends_nothing() {
    let settings = AwgSettings {
        reference_clock: ReferenceClock::External { frequency_hz: 5e6 },
        ..AwgSettings::default()
    };
    awg_refuses(settings, "frequency").await;
}

#[tokio::test]
async fn m8195a_loading_before_configuring_sends_nothing() {
    let (mut awg, log) = awg(Scripted::new("awg")).await;
    let e = bounded(awg.load(&IqWaveform {
        i: vec![0; 10],
        q: vec![0; 10],
        marker_high_samples: 1,
    }))
    .await
    .unwrap_err();
    assert!(matches!(e, DriverError::Sequence { .. }), "{e}");
    assert!(log.ops().is_empty(), "sent {:?}", log.ops());
}

#[tokio::test]
async fn m8195a_refusal_mid_configuration_names_the_batch_code_and_text() {
    let fake = Scripted::new("awg").refuse(":FREQ:RAST 64000000000", -222, "Data out of range");
    let (mut awg, log) = awg(fake).await;
    let e = bounded(awg.configure(&AwgSettings::default()))
        .await
        .unwrap_err();
    let text = e.to_string();
    assert!(text.contains("DAC mode and sample clock"), "{text}");
    assert!(text.contains("-222,\"Data out of range\""), "{text}");
    assert_eq!(e.device_errors().unwrap()[0].code, -222);
    assert_eq!(e.exit_class(), ExitClass::Instrument);
    assert_eq!(log.ops().last().map(String::as_str), Some(ERROR_CHECK));
    assert!(!log.ops().iter().any(|c| c.starts_with(":VOLT")));
}

#[tokio::test]
async fn m8195a_wrong_identity_is_refused() {
    let fake = Scripted::new("awg").reply("*IDN?", "Rigol,DG1022,1,1");
    let e = bounded(M8195a::connect(
        Box::new(fake),
        &model("keysight-m8195a"),
        "awg",
    ))
    .await
    .err()
    .unwrap();
    assert!(matches!(e, DriverError::WrongInstrument { .. }), "{e}");
}

// ---------------------------------------------------------------- LeCroy

const SCOPE_IDN: &str = "MOCK_LAB,LABMASTER10ZI-A-EMU,EMU0002,mock_lab-1";

async fn scope(fake: Scripted) -> (Lecroy, ScriptLog) {
    let fake = fake.reply("*IDN?", SCOPE_IDN);
    let log = fake.log();
    let driver = bounded(Lecroy::connect(
        Box::new(fake),
        &model("lecroy-labmaster10zi-a"),
        "scope",
    ))
    .await
    .unwrap();
    log.clear();
    (driver, log)
}

#[tokio::test]
async fn lecroy_configure_sets_format_rate_record_and_external_trigger() {
    let settings = DigitizerSettings {
        repetition_s: 1.0e-6,
        longest_echo_s: 0.024e-6,
        pre_trigger_s: 0.0,
        ..DigitizerSettings::default()
    };
    let (mut scope, log) = scope(configure_replies(Scripted::new("scope"))).await;
    let applied = bounded(scope.configure(&settings)).await.unwrap();
    assert_eq!(
        log.ops(),
        [
            "CMR?",
            "EXR?",
            "CHDR OFF",
            "CFMT DEF9,WORD,BIN",
            "CORD LO",
            "WFSU SP,0,NP,0,FP,0,SN,0",
            "CMR?",
            "EXR?",
            "C1:TRA ON",
            "C1:VDIV 0.05",
            "C1:OFST 0",
            "C2:TRA ON",
            "C2:VDIV 0.05",
            "C2:OFST 0",
            "CMR?",
            "EXR?",
            // Set even for one segment: a scope left in sequence mode would record several.
            "VBS 'app.Acquisition.Horizontal.SampleMode = \"RealTime\"'",
            "CMR?",
            "EXR?",
            "VBS 'app.Acquisition.Horizontal.Maximize = \"FixedSampleRate\"'",
            "VBS 'app.Acquisition.Horizontal.SampleRate = 80000000000'",
            "VBS 'app.Acquisition.Horizontal.HorScale = 0.0000001024'",
            "CMR?",
            "EXR?",
            "VBS? 'return = app.Acquisition.Horizontal.SamplingRate'",
            "VBS? 'return = app.Acquisition.Horizontal.HorScale'",
            "TRSE EDGE,SR,EX,HT,OFF",
            "EX:TRLV 0.2",
            "EX:TRSL POS",
            "TRDL -0.000000512",
            "CMR?",
            "EXR?",
        ]
    );
    assert_eq!(applied.points, 81_920);
    assert!((applied.record_s - 1.024e-6).abs() < 1e-15);
    log.assert_no_surprises();
}

/// What a healthy scope answers while it is configured for a 1.024 us record at 80 GSa/s: clean
/// error registers after each batch, and the rate and scale read back.
fn configure_replies(fake: Scripted) -> Scripted {
    fake.reply_times("CMR?", "0", 7)
        .reply_times("EXR?", "0", 7)
        .reply(
            "VBS? 'return = app.Acquisition.Horizontal.SamplingRate'",
            "80000000000",
        )
        .reply(
            "VBS? 'return = app.Acquisition.Horizontal.HorScale'",
            "VBS 1.024e-7",
        )
}

/// Configures `settings` on a scripted scope: refused as bad input, nothing sent.
async fn scope_refuses(settings: DigitizerSettings, field: &str) {
    let (mut scope, log) = scope(Scripted::new("scope")).await;
    let e = bounded(scope.configure(&settings)).await.unwrap_err();
    assert!(
        matches!(&e, DriverError::OutOfLimits { field: f, .. } if f.contains(field)),
        "{e}"
    );
    assert_eq!(e.exit_class(), ExitClass::BadInput, "{e}");
    assert!(log.ops().is_empty());
}

#[tokio::test]
async fn lecroy_refuses_a_rate_outside_the_catalog() {
    let settings = DigitizerSettings {
        sample_rate_hz: 40e9,
        ..DigitizerSettings::default()
    };
    scope_refuses(settings, "sample_rate_hz").await;
}

#[tokio::test]
async fn lecroy_refuses_a_record_longer_than_its_memory() {
    let settings = DigitizerSettings {
        repetition_s: 1.0e-3,
        ..DigitizerSettings::default()
    };
    scope_refuses(settings, "repetition_s").await;
}

#[tokio::test]
async fn lecroy_refuses_a_trigger_level_outside_the_catalog() {
    let settings = DigitizerSettings {
        trigger_level_v: 3.0,
        ..DigitizerSettings::default()
    };
    scope_refuses(settings, "trigger_level_v").await;
}

#[tokio::test]
async fn lecroy_refuses_segments_beyond_the_catalog_or_its_memory() {
    // None; more than the catalog's 15 000; 41 records of 10 us (800 000 points) where 32
    // Mpoints hold 40.
    for segments in [0, 15_001, 41] {
        let settings = DigitizerSettings {
            segments,
            ..DigitizerSettings::default()
        };
        scope_refuses(settings, "segments").await;
    }
}

#[tokio::test]
async fn lecroy_without_sequence_mode_in_the_catalog_refuses_segments() {
    let mut model = model("lecroy-labmaster10zi-a");
    if let Some(d) = model.digitizer.as_mut() {
        d.max_sequence_segments = 0;
    }
    let fake = Scripted::new("scope").reply("*IDN?", SCOPE_IDN);
    let log = fake.log();
    let mut scope = bounded(Lecroy::connect(Box::new(fake), &model, "scope"))
        .await
        .unwrap();
    log.clear();
    let settings = DigitizerSettings {
        segments: 2,
        ..DigitizerSettings::default()
    };
    let e = bounded(scope.configure(&settings)).await.unwrap_err();
    assert!(e.to_string().contains("no sequence mode"), "{e}");
    assert!(log.ops().is_empty());
}

#[tokio::test]
async fn lecroy_sequence_sets_the_mode_reads_back_the_count_and_splits_the_segments() {
    let settings = sequence_settings();
    let fake = configure_replies(Scripted::new("scope")).reply(SEGMENTS_QUERY, "VBS 3");
    let (mut scope, log) = scope(fake).await;
    let applied = bounded(scope.configure(&settings)).await.unwrap();
    assert_eq!(applied.segments, 3);
    let ops = log.ops();
    let at = ops
        .iter()
        .position(|c| c.contains("SampleMode = \"Sequence\""))
        .expect("sequence mode set");
    assert_eq!(
        ops[at..at + 5],
        [
            "VBS 'app.Acquisition.Horizontal.SampleMode = \"Sequence\"'",
            "VBS 'app.Acquisition.Horizontal.NumSegments = 3'",
            "CMR?",
            "EXR?",
            SEGMENTS_QUERY,
        ]
    );
    log.assert_no_surprises();

    // One acquisition, one block per channel holding the three segments and their trigger times.
    let codes: Vec<i16> = (0..3 * 81_920).map(|k| (k % 100) as i16).collect();
    let times = [(0.0, -1e-9), (2e-6, -1e-9), (4e-6, -1e-9)];
    let mut scope = sequence_capture(&codes, &times).await;
    let capture = bounded(scope.capture_iq(2.0)).await.unwrap();
    assert_eq!(capture.segments(), 3);
    assert_eq!(capture.i.segment_len(), 81_920);
    // Segment 2 starts at sample 163 840 of the record.
    assert_eq!(capture.q.segment_codes(2)[..3], [40, 41, 42]);
    assert_eq!(capture.i.timing(1).trigger_time_s, Some(2e-6));
    assert_eq!(capture.i.timing(2).first_sample_s, -1e-9);
}

#[tokio::test]
async fn lecroy_sequence_with_missing_segments_is_not_taken_for_a_full_one() {
    let codes: Vec<i16> = vec![7; 2 * 81_920];
    let mut scope = sequence_capture(&codes, &[(0.0, 0.0), (2e-6, 0.0)]).await;
    let e = bounded(scope.capture_iq(2.0)).await.unwrap_err();
    assert!(matches!(e, DriverError::NotApplied { .. }), "{e}");
    assert!(e.to_string().contains("2 segments"), "{e}");
}

/// A scope configured for `settings` (a sequence), then scripted with `fake`'s exchanges.
async fn sequenced(fake: Scripted, settings: &DigitizerSettings) -> (Lecroy, ScriptLog) {
    let fake = configure_replies(fake).reply(SEGMENTS_QUERY, &settings.segments.to_string());
    let (mut scope, log) = scope(fake).await;
    bounded(scope.configure(settings)).await.unwrap();
    log.clear();
    (scope, log)
}

const SEGMENTS_QUERY: &str = "VBS? 'return = app.Acquisition.Horizontal.NumSegments'";

/// A three-segment sequence of 1.024 us records.
fn sequence_settings() -> DigitizerSettings {
    DigitizerSettings {
        repetition_s: 1.0e-6,
        longest_echo_s: 0.024e-6,
        segments: 3,
        ..DigitizerSettings::default()
    }
}

/// A sequence-configured scope whose one acquisition returns `codes` in the segments `times`
/// describe, on both channels.
async fn sequence_capture(codes: &[i16], times: &[(f64, f64)]) -> Lecroy {
    let reply = |source| {
        block_reply(
            BlockBuilder {
                source,
                segments: times.to_vec(),
                ..BlockBuilder::default()
            },
            codes,
        )
    };
    let fake = Scripted::new("scope")
        .reply("INR?", "0")
        .reply("TRMD SINGLE;ARM;WAIT 2;*OPC?", "1")
        .reply("INR?", "1")
        .reply_block("C1:WF? ALL", reply(0))
        .reply_block("C2:WF? ALL", reply(1));
    sequenced(fake, &sequence_settings()).await.0
}

fn wf_reply(codes: &[i16], source: i16) -> Vec<u8> {
    let builder = BlockBuilder {
        gain: 0.002,
        offset: 0.1,
        source,
        ..BlockBuilder::default()
    };
    block_reply(builder, codes)
}

/// The scope's `WF? ALL` reply carrying `builder`'s block of `codes`.
fn block_reply(builder: BlockBuilder, codes: &[i16]) -> Vec<u8> {
    let block = builder.build(codes);
    let mut reply = format!("ALL,#9{:09}", block.len()).into_bytes();
    reply.extend_from_slice(&block);
    reply.push(b'\n');
    reply
}

#[tokio::test]
async fn lecroy_single_shot_then_both_channels_in_words() {
    let fake = Scripted::new("scope")
        .reply("INR?", "0")
        .reply("TRMD SINGLE;ARM;WAIT 2;*OPC?", "1")
        .reply("INR?", "8193")
        .reply_block("C1:WF? ALL", wf_reply(&[100, -100, 0], 0))
        .reply_block("C2:WF? ALL", wf_reply(&[5, 6, 7], 1));
    let (mut scope, log) = scope(fake).await;
    let capture = bounded(scope.capture_iq(2.0)).await.unwrap();
    assert_eq!(
        log.ops(),
        [
            "INR?",
            "TRMD SINGLE;ARM;WAIT 2;*OPC?",
            "INR?",
            "C1:WF? ALL",
            "C2:WF? ALL"
        ]
    );
    assert!(log.timeouts()[0].1 >= Duration::from_secs(2));
    assert_eq!(capture.i.codes, vec![100, -100, 0]);
    let v = capture.i.segment_volts(0);
    assert!((v[0] - (0.2 - 0.1)).abs() < 1e-6);
    assert_eq!(capture.q.codes, vec![5, 6, 7]);
    assert!(
        capture.i.segment_times(0)[0] < 0.0,
        "HORIZ_OFFSET is in the time axis"
    );
    let trc = capture.i.native.as_ref().unwrap().to_vec();
    assert!(
        trc.starts_with(b"#9000000"),
        "a .trc starts with the block's length"
    );
}

#[tokio::test]
async fn lecroy_without_a_marker_edge_disarms_and_says_why() {
    let fake = Scripted::new("scope")
        .reply("INR?", "0")
        .reply("TRMD SINGLE;ARM;WAIT 0.5;*OPC?", "1")
        .reply("INR?", "8192");
    let (mut scope, log) = scope(fake).await;
    let e = bounded(scope.acquire(0.5)).await.unwrap_err();
    assert!(
        e.to_string()
            .starts_with("no marker edge: check the AWG runs and its marker output is on"),
        "{e}"
    );
    assert_eq!(log.ops().last().map(String::as_str), Some("STOP"));
}

#[tokio::test]
async fn lecroy_truncated_block_is_a_clear_error() {
    let mut reply = wf_reply(&[1, 2, 3, 4], 0);
    // Announce the full length but claim more points than the block holds.
    let at = "ALL,#9000000000".len() + 116;
    reply[at] = 200;
    let fake = Scripted::new("scope").reply_block("C1:WF? ALL", reply);
    let (mut scope, _log) = scope(fake).await;
    let e = bounded(scope.fetch(1)).await.unwrap_err();
    assert!(matches!(e, DriverError::Waveform { channel: 1, .. }), "{e}");
    assert!(e.to_string().contains("WAVE_ARRAY_COUNT"), "{e}");
}

#[tokio::test]
async fn lecroy_silent_on_this_protocol_points_at_the_remote_setting() {
    let fake = Scripted::new("scope").fail_query("*IDN?", Failure::Timeout);
    let e = bounded(Lecroy::connect(
        Box::new(fake),
        &model("lecroy-labmaster10zi-a"),
        "scope",
    ))
    .await
    .err()
    .unwrap();
    let text = e.to_string();
    assert!(matches!(e, DriverError::RemoteInterface { .. }), "{text}");
    assert!(
        text.contains("Utilities > Utilities Setup > Remote"),
        "{text}"
    );
}

// ---------------------------------------------------------------- Gotmic

const TX_IDN: &str = "MOCK_LAB,GOTMIC-EBAND-TX-EMU,EMU0003,mock_lab-1";

async fn tx(fake: Scripted) -> (Gotmic, ScriptLog) {
    let fake = fake.reply("*IDN?", TX_IDN).reply("R 00", "OK 5458");
    let log = fake.log();
    let driver = bounded(Gotmic::connect(
        Box::new(fake),
        &model("gotmic-eband-tx"),
        "tx",
    ))
    .await
    .unwrap();
    assert_eq!(log.ops(), ["*IDN?", "R 00"]);
    log.clear();
    (driver, log)
}

/// Replies of one status read: STATUS, CONTROL, GAIN_ATT, TEMP_DC, FAULT_LATCH.
fn status(fake: Scripted, status: &str, control: &str, att: &str, faults: &str) -> Scripted {
    fake.reply("R 01", status)
        .reply("R 02", control)
        .reply("R 03", att)
        .reply("R 06", "OK 00FA")
        .reply("R 07", faults)
}

const STATUS_READ: &[&str] = &["R 01", "R 02", "R 03", "R 06", "R 07"];

/// Replies of a switch-on that takes: the enables written, RF on and LO locked with no fault
/// read back, then 10 dB of attenuation written and verified.
fn switched_on_at_10_db(fake: Scripted) -> Scripted {
    fake.reply("W 02 000F", "OK")
        .reply("R 01", "OK 0007")
        .reply("R 02", "OK 000F")
        .reply("R 07", "OK 0000")
        .reply("W 03 0014", "OK")
        .reply("R 03", "OK 0014")
}

/// What RF safety reads back after writing the enables: STATUS, CONTROL, FAULT_LATCH.
const AFTER_ENABLE: &[&str] = &["R 01", "R 02", "R 07"];

#[tokio::test]
async fn gotmic_enable_goes_through_max_attenuation_checks_and_verifies() {
    let mut fake = status(
        Scripted::new("tx"),
        "OK 0001",
        "OK 0000",
        "OK 003F",
        "OK 0000",
    );
    fake = fake.reply("W 05 3415", "OK").reply("R 05", "OK 3415");
    fake = switched_on_at_10_db(fake);
    let (mut tx, log) = tx(fake).await;
    let settings = RfSettings {
        attenuation_db: 10.0,
        lo_frequency_hz: Some(13.333e9),
    };
    let permit = RfPermit::granted_by_user();
    let st = bounded(tx.enable(&permit, &settings)).await.unwrap();
    assert!(st.rf_enabled && st.lo_locked);
    assert_eq!(st.attenuation_db, 10.0);
    assert_eq!(st.temperature_c, 25.0);
    assert_eq!(st.control, 0x000F);
    // The attenuation was found at its maximum: not written again before the enable.
    assert_eq!(
        log.ops(),
        strings(&[
            STATUS_READ,
            &["W 05 3415", "R 05"],
            &["W 02 000F"],
            AFTER_ENABLE,
            &["W 03 0014", "R 03"],
        ])
    );
    log.assert_no_surprises();
}

#[tokio::test]
async fn gotmic_enable_maxes_the_attenuation_first_when_it_is_not() {
    let mut fake = status(
        Scripted::new("tx"),
        "OK 0001",
        "OK 0000",
        "OK 0000",
        "OK 0000",
    );
    fake = fake.reply("W 03 003F", "OK").reply("R 03", "OK 003F");
    fake = switched_on_at_10_db(fake);
    let (mut tx, log) = tx(fake).await;
    let settings = RfSettings {
        attenuation_db: 10.0,
        lo_frequency_hz: None,
    };
    let permit = RfPermit::granted_by_user();
    bounded(tx.enable(&permit, &settings)).await.unwrap();
    assert_eq!(
        log.ops(),
        strings(&[
            STATUS_READ,
            &["W 03 003F", "R 03"],
            &["W 02 000F"],
            AFTER_ENABLE,
            &["W 03 0014", "R 03"],
        ])
    );
    log.assert_no_surprises();
}

/// Enables a module whose read-back after `W 02 000F` is `status` and `control`: refused with a
/// message holding `says`, and switched off again (RF off, maximum attenuation, each read back).
async fn enable_refused_then_switched_off(status_after: &str, control_after: &str, says: &str) {
    let fake = status(
        Scripted::new("tx"),
        "OK 0001",
        "OK 0000",
        "OK 003F",
        "OK 0000",
    )
    .reply("W 02 000F", "OK")
    .reply("R 01", status_after)
    .reply("R 02", control_after)
    .reply("R 07", "OK 0000")
    .reply("W 02 0000", "OK")
    .reply("R 02", "OK 0000")
    .reply("W 03 003F", "OK")
    .reply("R 03", "OK 003F");
    let (mut tx, log) = tx(fake).await;
    let permit = RfPermit::granted_by_user();
    let e = bounded(tx.enable(&permit, &RfSettings::default()))
        .await
        .unwrap_err();
    assert!(e.to_string().contains(says), "{e}");
    let ops = log.ops();
    assert_eq!(
        &ops[ops.len() - 4..],
        ["W 02 0000", "R 02", "W 03 003F", "R 03"]
    );
    log.assert_no_surprises();
}

#[tokio::test]
async fn gotmic_enable_not_taken_switches_off_again() {
    // The control register reads back 0: the enable did not take.
    enable_refused_then_switched_off("OK 0001", "OK 0000", "read back").await;
}

#[tokio::test]
async fn gotmic_lo_not_locked_switches_off_again() {
    enable_refused_then_switched_off("OK 0005", "OK 000F", "LO is not locked").await;
}

#[tokio::test]
async fn gotmic_latched_faults_or_open_interlock_refuse_before_enabling() {
    let fake = status(
        Scripted::new("tx"),
        "OK 0011",
        "OK 0000",
        "OK 003F",
        "OK 0002",
    );
    let (mut tx, log) = tx(fake).await;
    let permit = RfPermit::granted_by_user();
    let e = bounded(tx.enable(&permit, &RfSettings::default()))
        .await
        .unwrap_err();
    assert!(e.to_string().contains("INTERLOCK_OPENED"), "{e}");
    assert!(
        !log.ops().iter().any(|c| c.starts_with("W 02")),
        "never enabled"
    );
}

#[tokio::test]
async fn gotmic_module_errors_carry_code_and_text() {
    let fake = Scripted::new("tx").reply("W 03 003F", "ERR 5 not allowed");
    let (mut tx, log) = tx(fake).await;
    let e = bounded(tx.set_attenuation(31.5)).await.unwrap_err();
    assert!(
        matches!(&e, DriverError::LineRefused { code: 5, text, .. } if text == "not allowed"),
        "{e}"
    );
    assert_eq!(log.ops(), ["W 03 003F"]);
}

#[tokio::test]
async fn gotmic_attenuation_beyond_the_register_range_sends_nothing() {
    let (mut tx, log) = tx(Scripted::new("tx")).await;
    let e = bounded(tx.set_attenuation(40.0)).await.unwrap_err();
    assert_eq!(e.exit_class(), ExitClass::BadInput);
    assert!(log.ops().is_empty(), "sent {:?}", log.ops());
}

// ---------------------------------------------------------------- safe state

#[tokio::test]
async fn error_mid_configuration_still_sends_the_safe_state_in_order() {
    let awg_fake = Scripted::new("awg").refuse(":INST:DACM DCM", -221, "Settings conflict");
    let (awg, awg_log) = awg(awg_fake).await;
    let tx_fake = Scripted::new("tx")
        .reply("W 02 0000", "OK")
        .reply("R 02", "OK 0000")
        .reply("W 03 003F", "OK")
        .reply("R 03", "OK 003F");
    let (tx, tx_log) = tx(tx_fake).await;
    let (safe, awg, _tx) = guarded(Box::new(awg), Some(Box::new(tx)));
    let guard = safe.guard();
    let result = bounded(async { awg.lock().await.configure(&AwgSettings::default()).await }).await;
    assert!(matches!(result, Err(DriverError::Refused { .. })));
    awg_log.clear();
    let report = bounded(guard.engage()).await;
    assert!(report.is_safe(), "{report}");
    assert_eq!(
        report.steps.iter().map(|s| s.step).collect::<Vec<_>>(),
        ["Tx RF off", "AWG outputs off and :ABOR"]
    );
    assert_eq!(tx_log.ops(), ["W 02 0000", "R 02", "W 03 003F", "R 03"]);
    assert_eq!(awg_log.ops(), AWG_SAFE_STATE);
}

#[tokio::test]
async fn safe_state_tries_every_step_even_when_one_fails() {
    let awg_fake = Scripted::new("awg").fail_write(":OUTP2 OFF", Failure::Closed);
    let (awg, awg_log) = awg(awg_fake).await;
    let tx_fake = Scripted::new("tx")
        .reply("W 02 0000", "ERR 5 not allowed")
        .reply("W 03 003F", "OK")
        .reply("R 03", "OK 003F");
    let (tx, tx_log) = tx(tx_fake).await;
    let (safe, _awg, _tx) = guarded(Box::new(awg), Some(Box::new(tx)));
    let report = bounded(safe.engage()).await;
    assert!(!report.is_safe());
    assert!(report.steps[0].error.as_deref().unwrap().contains("ERR 5"));
    assert_eq!(
        tx_log.ops(),
        ["W 02 0000", "W 03 003F", "R 03"],
        "attenuation still maxed"
    );
    assert_eq!(awg_log.ops(), AWG_SAFE_STATE);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_dropped_guard_runs_the_safe_state_synchronously() {
    let (awg, awg_log) = awg(Scripted::new("awg")).await;
    let (safe, _awg, _tx) = guarded(Box::new(awg), None);
    {
        let _guard = safe.guard();
    }
    assert_eq!(awg_log.ops(), AWG_SAFE_STATE);
}

#[tokio::test]
async fn gotmic_crc_framing_frames_requests_and_rejects_corrupted_replies() {
    use radbench::driver::Framing;
    use radbench::session::Crc8;
    let m = model("gotmic-eband-tx");
    let smbus = Crc8 {
        poly: 0x07,
        init: 0x00,
    };
    let f = |s: &str| smbus.frame(s);
    let fake = Scripted::new("tx")
        .reply("CRC ON", "OK")
        .reply(&f("*IDN?"), &f(TX_IDN))
        .reply(&f("R 00"), &f("OK 5458"))
        .reply(&f("R 01"), "OK 0001*00");
    let log = fake.log();
    let mut tx = bounded(Gotmic::connect_with(
        Box::new(fake),
        &m,
        "tx",
        Framing::from_catalog(&m),
    ))
    .await
    .unwrap();
    assert_eq!(log.ops(), ["CRC ON".to_string(), f("*IDN?"), f("R 00")]);
    let e = bounded(tx.status()).await.unwrap_err();
    assert!(e.to_string().contains("CRC-8"), "{e}");
    log.assert_no_surprises();
}
