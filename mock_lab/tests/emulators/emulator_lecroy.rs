//! The LeCroy emulator through its `Handler` interface: the driver's single-shot sequence, WAVEDESC
//! bytes checked field by field with an independent decoder (offsets of instruments.md 2.6), marker
//! gating, VBS statements, error registers and the remote-interface setting.

use std::sync::Arc;
use std::time::Duration;

use mock_lab::emulator::lecroy::{Lecroy, RemoteInterface, TestSignal};
use mock_lab::server::Handler;

fn scope_with(signal: Arc<TestSignal>) -> Arc<Lecroy> {
    scope_with_source(signal)
}

fn scope_with_source(source: Arc<dyn mock_lab::emulator::lecroy::TriggerSource>) -> Arc<Lecroy> {
    let scope = Lecroy::embedded_with(source).expect("built-in catalog loads");
    scope.set_wait_cap(Duration::from_secs(5));
    Arc::new(scope)
}

fn send(h: &dyn Handler, message: &str) -> Vec<u8> {
    let replies = h.message(message.as_bytes());
    assert!(replies.len() <= 1);
    replies.into_iter().next().unwrap_or_default()
}

fn q(h: &dyn Handler, message: &str) -> String {
    String::from_utf8(send(h, message)).unwrap()
}

/// An independent WAVEDESC reader: offsets from instruments.md section 2.6, byte order from COMM_ORDER.
struct Desc<'a> {
    d: &'a [u8],
    little: bool,
}

impl Desc<'_> {
    fn string(&self, off: usize, len: usize) -> String {
        let raw = &self.d[off..off + len];
        let end = raw.iter().position(|b| *b == 0).unwrap_or(len);
        String::from_utf8_lossy(&raw[..end]).into_owned()
    }
    fn bytes<const N: usize>(&self, off: usize) -> [u8; N] {
        self.d[off..off + N].try_into().unwrap()
    }
    fn i16(&self, off: usize) -> i16 {
        if self.little {
            i16::from_le_bytes(self.bytes(off))
        } else {
            i16::from_be_bytes(self.bytes(off))
        }
    }
    fn i32(&self, off: usize) -> i32 {
        if self.little {
            i32::from_le_bytes(self.bytes(off))
        } else {
            i32::from_be_bytes(self.bytes(off))
        }
    }
    fn f32(&self, off: usize) -> f32 {
        if self.little {
            f32::from_le_bytes(self.bytes(off))
        } else {
            f32::from_be_bytes(self.bytes(off))
        }
    }
    fn f64(&self, off: usize) -> f64 {
        if self.little {
            f64::from_le_bytes(self.bytes(off))
        } else {
            f64::from_be_bytes(self.bytes(off))
        }
    }
}

/// Decoded `WF? ALL` reply.
struct Wave {
    prefix: String,
    desc: Vec<u8>,
    little: bool,
    volts: Vec<f64>,
    times: Vec<f64>,
    codes: Vec<i32>,
}

fn decode(reply: &[u8]) -> Wave {
    let hash = reply.windows(2).position(|w| w == b"#9").expect("#9 block");
    let prefix = String::from_utf8(reply[..hash].to_vec()).unwrap();
    let len: usize = std::str::from_utf8(&reply[hash + 2..hash + 11])
        .unwrap()
        .parse()
        .unwrap();
    let block = &reply[hash + 11..];
    assert_eq!(
        block.len(),
        len,
        "the block is exactly as long as announced"
    );
    assert_eq!(&block[..8], b"WAVEDESC");
    let little = u16::from_be_bytes([block[34], block[35]]) != 0;
    let d = Desc { d: block, little };
    let desc_len = d.i32(36) as usize;
    let user = d.i32(40) as usize;
    let trig = d.i32(48) as usize;
    let ris = d.i32(52) as usize;
    let array1 = d.i32(60) as usize;
    let count = d.i32(116) as usize;
    let word = d.i16(32) == 1;
    let start = desc_len + user + trig + ris;
    assert_eq!(block.len(), start + array1);
    let data = &block[start..start + array1];
    let codes: Vec<i32> = if word {
        data.chunks_exact(2)
            .map(|c| {
                i32::from(if little {
                    i16::from_le_bytes([c[0], c[1]])
                } else {
                    i16::from_be_bytes([c[0], c[1]])
                })
            })
            .collect()
    } else {
        data.iter().map(|b| i32::from(*b as i8)).collect()
    };
    assert_eq!(codes.len(), count);
    let gain = f64::from(d.f32(156));
    let offset = f64::from(d.f32(160));
    let dt = f64::from(d.f32(176));
    let t0 = d.f64(180);
    Wave {
        prefix,
        desc: block[..desc_len].to_vec(),
        little,
        volts: codes
            .iter()
            .map(|c| gain * f64::from(*c) - offset)
            .collect(),
        times: (0..count).map(|i| t0 + i as f64 * dt).collect(),
        codes,
    }
}

impl Wave {
    fn d(&self) -> Desc<'_> {
        Desc {
            d: &self.desc,
            little: self.little,
        }
    }
}

const SETUP: &str = "CHDR OFF;CFMT DEF9,WORD,BIN;CORD LO;WFSU SP,0,NP,0,FP,0,SN,0";
const TIMEBASE: &str = "VBS 'app.Acquisition.Horizontal.Maximize = \"FixedSampleRate\"';\
VBS 'app.Acquisition.Horizontal.SampleRate = 80e9';VBS 'app.Acquisition.Horizontal.HorScale = 1.024e-7'";
const TRIGGER: &str = "TRSE EDGE,SR,EX,HT,OFF;EX:TRLV 0.2V;EX:TRSL POS;TRMD SINGLE";

#[test]
fn identifies_as_an_emulator() {
    let scope = scope_with(Arc::new(TestSignal::default()));
    send(&*scope, "CHDR OFF");
    assert_eq!(
        q(&*scope, "*IDN?"),
        "MOCK_LAB,LABMASTER10ZI-A-EMU,EMU0002,mock_lab-1"
    );
}

#[test]
fn single_shot_with_marker_gives_a_decodable_wavedesc() {
    let signal = Arc::new(TestSignal::new(true, 1e9, 0.1));
    let scope = scope_with(signal);
    send(&*scope, SETUP);
    send(&*scope, TIMEBASE);
    send(&*scope, TRIGGER);
    assert_eq!(q(&*scope, "ARM;WAIT 5;*OPC?"), "1");
    assert_eq!(q(&*scope, "INR?").parse::<u32>().unwrap() & 1, 1);
    assert_eq!(
        q(&*scope, "TRMD?"),
        "STOP",
        "a single acquisition stops the trigger"
    );

    let reply = send(&*scope, "C1:WF? ALL");
    let wave = decode(&reply);
    assert_eq!(wave.prefix, "ALL,");
    let d = wave.d();
    assert_eq!(d.string(0, 16), "WAVEDESC");
    assert_eq!(d.string(16, 16), "LECROY_2_3");
    assert_eq!(d.i16(32), 1, "COMM_TYPE word");
    assert_eq!(d.i16(34), 1, "COMM_ORDER LOFIRST");
    assert_eq!(d.i32(36), 346);
    assert_eq!(d.i32(60), 2 * 81_920, "WAVE_ARRAY_1 bytes");
    assert_eq!(d.string(76, 16), "MOCK_LAB EMU");
    assert_eq!(
        d.i32(116),
        81_920,
        "WAVE_ARRAY_COUNT = 10 div x 1.024e-7 s x 80 GSa/s"
    );
    assert_eq!(d.i32(128), 81_919, "LAST_VALID_PNT");
    assert_eq!(d.i16(172), 8, "NOMINAL_BITS");
    assert_eq!(d.f32(176), 1.0 / 80e9_f32, "HORIZ_INTERVAL");
    assert_eq!(
        d.f64(180),
        -5.0 * 1.024e-7,
        "HORIZ_OFFSET: trigger mid-grid"
    );
    assert_eq!(d.string(196, 48), "V");
    assert_eq!(d.string(244, 48), "S");
    assert_eq!(d.i16(308), 2026, "TRIGGER_TIME year");
    assert_eq!(d.i16(316), 0, "RECORD_TYPE single_sweep");
    assert_eq!(
        d.i16(324),
        15,
        "TIMEBASE enum: 102.4 ns/div is nearest the 100 ns/div step"
    );
    assert_eq!(d.i16(344), 0, "WAVE_SOURCE C1");
    let gain = f64::from(d.f32(156));
    assert!((gain - 0.05 / 6400.0).abs() < 1e-12, "VERTICAL_GAIN {gain}");

    // The volts follow the test tone I = 0.1 cos(2 pi 1 GHz t) at the decoded times within one ADC step.
    let step = 0.05 / 25.0;
    for (i, (v, t)) in wave.volts.iter().zip(&wave.times).enumerate().step_by(997) {
        let expected = 0.1 * (2.0 * std::f64::consts::PI * 1e9 * t).cos();
        assert!(
            (v - expected).abs() <= step / 2.0 + 1e-9,
            "point {i}: {v} vs {expected}"
        );
    }
    assert!(
        wave.codes.iter().all(|c| c % 256 == 0),
        "8-bit ADC values in the upper byte"
    );

    let q_wave = decode(&send(&*scope, "C2:WF? ALL"));
    assert_eq!(q_wave.d().i16(344), 1, "WAVE_SOURCE C2");
    let t = q_wave.times[100];
    assert!((q_wave.volts[100] - 0.1 * (2.0 * std::f64::consts::PI * 1e9 * t).sin()).abs() <= step);
}

#[test]
fn big_endian_bytes_and_the_transfer_window() {
    let scope = scope_with(Arc::new(TestSignal::default()));
    send(
        &*scope,
        "CHDR OFF;CFMT DEF9,BYTE,BIN;CORD HI;WFSU SP,4,NP,10,FP,8,SN,0",
    );
    send(&*scope, "TDIV 1E-9;TRMD SINGLE;WAIT 1");
    let wave = decode(&send(&*scope, "C1:WF? ALL"));
    let d = wave.d();
    assert!(!wave.little);
    assert_eq!(d.i16(32), 0, "COMM_TYPE byte");
    assert_eq!(d.i16(34), 0, "COMM_ORDER HIFIRST");
    assert_eq!(d.i32(116), 10);
    assert_eq!(d.i32(60), 10);
    assert_eq!(d.i32(120), 800, "PNTS_PER_SCREEN = whole record");
    assert_eq!(d.i32(132), 8, "FIRST_POINT");
    assert_eq!(d.i32(136), 4, "SPARSING_FACTOR");
    assert_eq!(d.f32(176), 4.0 / 80e9_f32);
    let expected_offset = -5e-9 + 8.0 / 80e9;
    assert!((d.f64(180) - expected_offset).abs() < 1e-18);
    assert!(
        (f64::from(d.f32(156)) - 0.05 / 25.0).abs() < 1e-9,
        "BYTE gain is 256 x WORD gain"
    );
}

#[test]
fn without_a_marker_wait_times_out_and_nothing_is_acquired() {
    let signal = Arc::new(TestSignal::new(false, 1e9, 0.1));
    let scope = scope_with(signal.clone());
    send(&*scope, SETUP);
    send(&*scope, TRIGGER);
    assert_eq!(q(&*scope, "ARM;WAIT 0.02;*OPC?"), "1");
    let inr: u32 = q(&*scope, "INR?").parse().unwrap();
    assert_eq!(inr & 1, 0, "no new acquisition");
    assert_ne!(inr & (1 << 13), 0, "still armed");
    let wave = decode(&send(&*scope, "C1:WF? ALL"));
    assert_eq!(wave.d().i32(116), 0, "no data before the first acquisition");

    // A marker edge arriving while a client waits completes the acquisition.
    let waiter = {
        let scope = scope.clone();
        std::thread::spawn(move || q(&*scope, "WAIT 5;*OPC?"))
    };
    signal.set_marker(true);
    assert_eq!(waiter.join().unwrap(), "1");
    assert_eq!(q(&*scope, "INR?").parse::<u32>().unwrap() & 1, 1);
}

#[test]
fn force_trigger_acquires_without_a_marker() {
    let scope = scope_with(Arc::new(TestSignal::new(false, 1e9, 0.1)));
    send(&*scope, SETUP);
    send(&*scope, "TDIV 1E-9;TRMD SINGLE;FRTR");
    assert_eq!(q(&*scope, "INR?").parse::<u32>().unwrap() & 1, 1);
    assert_eq!(decode(&send(&*scope, "C1:WF? ALL")).codes.len(), 800);
}

#[test]
fn vbs_sample_rate_adapts_to_the_fixed_rate_and_flags_vab() {
    let scope = scope_with(Arc::new(TestSignal::new(false, 1e9, 0.1)));
    send(&*scope, "CHDR SHORT");
    send(
        &*scope,
        "VBS 'app.Acquisition.Horizontal.SampleRate = \"40 GS/s\"'",
    );
    assert_eq!(
        q(
            &*scope,
            "VBS? 'return = app.Acquisition.Horizontal.SamplingRate'"
        ),
        "VBS 80000000000"
    );
    assert_ne!(
        q(&*scope, "*STB?")
            .trim_start_matches("*STB ")
            .parse::<u8>()
            .unwrap()
            & 4,
        0,
        "VAB"
    );
}

#[test]
fn vbs_horizontal_scale_sets_the_points() {
    let scope = scope_with(Arc::new(TestSignal::new(false, 1e9, 0.1)));
    send(&*scope, "CHDR OFF");
    send(&*scope, "VBS 'app.Acquisition.Horizontal.HorScale = 1e-9'");
    assert_eq!(
        q(
            &*scope,
            "VBS? 'return = app.Acquisition.Horizontal.NumPoints'"
        ),
        "800"
    );
}

#[test]
fn vbs_trigger_settings_reach_the_legacy_commands() {
    let scope = scope_with(Arc::new(TestSignal::new(false, 1e9, 0.1)));
    send(&*scope, "CHDR OFF");
    send(&*scope, "VBS 'app.Acquisition.Trigger.Source = \"Ext\"';VBS 'app.Acquisition.Trigger.Edge.Level = 0.25'");
    assert_eq!(q(&*scope, "EX:TRLV?"), "2.50E-01 V");
    assert_eq!(q(&*scope, "TRSE?"), "EDGE,SR,EX,HT,OFF");
}

#[test]
fn vbs_acquire_without_a_marker_times_out_and_forcing_still_records() {
    let scope = scope_with(Arc::new(TestSignal::new(false, 1e9, 0.1)));
    send(
        &*scope,
        "CHDR OFF;VBS 'app.Acquisition.Horizontal.HorScale = 1e-9'",
    );
    assert_eq!(
        q(
            &*scope,
            "VBS? 'return = app.Acquisition.acquire(0.02, False)'"
        ),
        "0"
    );
    assert_eq!(
        q(
            &*scope,
            "VBS? 'return = app.Acquisition.acquire(0.02, True)'"
        ),
        "0"
    );
    assert_eq!(
        q(&*scope, "INR?").parse::<u32>().unwrap() & 1,
        1,
        "forced acquisition exists"
    );
}

#[test]
fn vbs_acquire_with_a_marker_triggers_and_stops() {
    let signal = Arc::new(TestSignal::new(false, 1e9, 0.1));
    let scope = scope_with(signal.clone());
    send(
        &*scope,
        "CHDR OFF;VBS 'app.Acquisition.Horizontal.HorScale = 1e-9'",
    );
    signal.set_marker(true);
    assert_eq!(
        q(&*scope, "VBS? 'return = app.Acquisition.acquire(1, False)'"),
        "1"
    );
    assert_eq!(
        q(&*scope, "VBS? 'return = app.Acquisition.TriggerMode'"),
        "Stopped"
    );
}

#[test]
fn response_headers_follow_comm_header() {
    let scope = scope_with(Arc::new(TestSignal::default()));
    assert_eq!(q(&*scope, "C1:VDIV?"), "C1:VDIV 5.00E-02 V");
    send(&*scope, "CHDR LONG");
    assert_eq!(q(&*scope, "TRMD?"), "TRIG_MODE AUTO");
    assert_eq!(
        q(&*scope, "VDIV?"),
        "C1:VOLT_DIV 5.00E-02 V",
        "the C1 path is sticky"
    );
    send(&*scope, "COMM_HEADER SHORT;TRMD SINGLE;WAIT 1");
    let reply = send(&*scope, "C2:WF? ALL");
    assert!(reply.starts_with(b"C2:WF ALL,#9"));
    assert_eq!(q(&*scope, "CFMT?;CORD?"), "CFMT DEF9,BYTE,BIN;CORD HI");
}

/// A scope with response headers off.
fn plain_scope() -> Arc<Lecroy> {
    let scope = scope_with(Arc::new(TestSignal::default()));
    send(&*scope, "CHDR OFF");
    scope
}

#[test]
fn command_errors_set_cmr_and_reading_clears_it() {
    let scope = plain_scope();
    send(&*scope, "BOGUS 1");
    assert_eq!(q(&*scope, "CMR?"), "1");
    assert_eq!(q(&*scope, "CMR?"), "0", "reading clears");
    for (command, code) in [
        ("C9:VDIV 0.1", "2"),
        ("TRMD SOMETIMES", "5"),
        ("TDIV fast", "3"),
    ] {
        send(&*scope, command);
        assert_eq!(q(&*scope, "CMR?"), code, "{command}");
    }
}

#[test]
fn execution_errors_set_exr() {
    let scope = plain_scope();
    for (command, code) in [
        ("CFMT IND0,WORD,BIN", "26"),
        ("VBS 'app.Display.GridMode = \"Dual\"'", "26"),
        ("EX:WF? ALL", "22"),
    ] {
        send(&*scope, command);
        assert_eq!(q(&*scope, "EXR?"), code, "{command}");
    }
}

#[test]
fn command_and_execution_errors_set_their_esr_bits() {
    let scope = plain_scope();
    send(&*scope, "BOGUS 1");
    send(&*scope, "CFMT IND0,WORD,BIN");
    assert_eq!(q(&*scope, "*ESR?"), "48", "CME and EXE");
}

#[test]
fn a_command_error_abandons_the_message() {
    let scope = plain_scope();
    assert_eq!(q(&*scope, "BOGUS;*IDN?"), "");
}

#[test]
fn out_of_range_values_are_adapted_and_flagged() {
    let scope = scope_with(Arc::new(TestSignal::default()));
    send(&*scope, "CHDR OFF;C1:VDIV 10;EX:TRLV 3");
    assert_eq!(q(&*scope, "C1:VDIV?"), "5.00E-01 V");
    assert_eq!(q(&*scope, "EX:TRLV?"), "5.00E-01 V");
    assert_eq!(q(&*scope, "*STB?").parse::<u8>().unwrap() & 4, 4);
    send(&*scope, "*CLS");
    assert_eq!(q(&*scope, "*STB?"), "0");
    send(&*scope, "TDIV 1");
    let points: u64 = q(
        &*scope,
        "VBS? 'return = app.Acquisition.Horizontal.NumPoints'",
    )
    .parse()
    .unwrap();
    assert_eq!(points, mock_lab::emulator::lecroy::EMULATOR_MAX_POINTS);
}

#[test]
fn remote_interface_setting_refuses_the_other_protocol() {
    let scope = scope_with(Arc::new(TestSignal::default()));
    let vicp = scope.port(RemoteInterface::Vicp);
    let vxi = scope.port(RemoteInterface::Vxi11);
    assert!(!send(&vicp, "*IDN?").is_empty());
    assert!(send(&vxi, "*IDN?").is_empty());
    let reason = scope.accepts(RemoteInterface::Vxi11).unwrap_err();
    assert!(
        reason.contains("TCPIP (VICP)") && reason.contains("Remote"),
        "{reason}"
    );
    scope.set_remote_interface(RemoteInterface::Vxi11);
    assert!(!send(&vxi, "*IDN?").is_empty());
    assert!(send(&vicp, "*IDN?").is_empty());
    assert!(scope.log().texts().iter().filter(|t| *t == "*IDN?").count() == 4);
}

#[test]
fn trc_bytes_equal_the_wf_all_block() {
    let scope = scope_with(Arc::new(TestSignal::default()));
    send(&*scope, SETUP);
    send(&*scope, "TDIV 2E-9;TRMD SINGLE;WAIT 1");
    let reply = send(&*scope, "C1:WF? ALL");
    let trc = scope.trc_bytes(1).unwrap();
    assert_eq!(&reply[4..], &trc[..]);
    assert!(trc.starts_with(b"#9"));
    assert!(scope.trc_bytes(5).is_none());
}

#[test]
fn desc_and_dat1_parts() {
    let scope = scope_with(Arc::new(TestSignal::default()));
    send(&*scope, SETUP);
    send(&*scope, "TDIV 1E-9;TRMD SINGLE;WAIT 1");
    let desc = send(&*scope, "C1:WF? DESC");
    assert!(desc.starts_with(b"DESC,#9000000346WAVEDESC"));
    let dat = send(&*scope, "C1:WF? DAT1");
    assert!(dat.starts_with(b"DAT1,#9000001600"));
}

#[test]
fn a_model_the_emulator_cannot_use_is_refused() {
    let mut model = mock_lab::catalog::lecroy().unwrap();
    model.limits.sample_rates.clear();
    assert!(Lecroy::new(model, Arc::new(TestSignal::default())).is_err());
}

const SEQUENCE_OF_3: &str = "VBS 'app.Acquisition.Horizontal.SampleMode = \"Sequence\"';\
VBS 'app.Acquisition.Horizontal.NumSegments = 3'";

/// Segments and TRIGTIME entries of a `WF? ALL` reply (the independent reader above).
fn segments(reply: &[u8]) -> (Wave, Vec<(f64, f64)>) {
    let wave = decode(reply);
    let d = wave.d();
    let count = d.i32(144) as usize;
    let trig = d.i32(48) as usize;
    assert_eq!(trig, 16 * count, "one TRIGTIME entry per segment");
    assert_eq!(d.i16(174) as usize, count, "NOM_SUBARRAY_COUNT");
    let hash = reply.windows(2).position(|w| w == b"#9").unwrap();
    let arrays = &reply[hash + 11 + 346..];
    let f = |b: &[u8]| {
        let b: [u8; 8] = b.try_into().unwrap();
        if wave.little {
            f64::from_le_bytes(b)
        } else {
            f64::from_be_bytes(b)
        }
    };
    let times = (0..count)
        .map(|k| {
            (
                f(&arrays[16 * k..16 * k + 8]),
                f(&arrays[16 * k + 8..16 * k + 16]),
            )
        })
        .collect();
    (wave, times)
}

#[test]
fn sequence_mode_records_one_segment_per_edge_with_trigger_times() {
    let scope = scope_with(Arc::new(TestSignal::new(true, 1e9, 0.1)));
    send(&*scope, SETUP);
    send(&*scope, TIMEBASE);
    send(&*scope, SEQUENCE_OF_3);
    assert_eq!(
        q(
            &*scope,
            "VBS? 'return = app.Acquisition.Horizontal.SampleMode'"
        ),
        "Sequence"
    );
    assert_eq!(
        q(
            &*scope,
            "VBS? 'return = app.Acquisition.Horizontal.NumSegments'"
        ),
        "3"
    );
    send(&*scope, TRIGGER);
    assert_eq!(q(&*scope, "ARM;WAIT 5;*OPC?"), "1");
    assert_eq!(q(&*scope, "INR?").parse::<u32>().unwrap() & 1, 1);

    let (wave, times) = segments(&send(&*scope, "C1:WF? ALL"));
    assert_eq!(wave.d().i32(144), 3, "SUBARRAY_COUNT");
    assert_eq!(wave.codes.len(), 3 * 81_920, "every segment's points");
    assert_eq!(wave.d().i32(120), 81_920, "PNTS_PER_SCREEN: one segment");
    // Without a repeating edge the scope takes the next one when it is ready again: after the
    // part of the record behind the trigger and the re-arm time.
    let ready = 5.0 * 1.024e-7 + mock_lab::emulator::lecroy::SEQUENCE_REARM_S;
    for (k, (time, offset)) in times.iter().enumerate() {
        assert!(
            (time - k as f64 * ready).abs() < 1e-15,
            "segment {k}: {time}"
        );
        assert_eq!(*offset, -5.0 * 1.024e-7, "trigger offset mid-grid");
    }

    // SN picks one segment; DAT1 is the data array alone.
    send(&*scope, "WFSU SP,0,NP,0,FP,0,SN,2");
    let (one, times) = segments(&send(&*scope, "C1:WF? ALL"));
    assert_eq!(one.codes[..], wave.codes[81_920..2 * 81_920]);
    assert_eq!(times.len(), 1);
    assert!((times[0].0 - ready).abs() < 1e-15);
    send(&*scope, "WFSU SP,0,NP,0,FP,0,SN,0");
    let dat = send(&*scope, "C1:WF? DAT1");
    assert!(dat.starts_with(format!("DAT1,#9{:09}", 2 * 3 * 81_920).as_bytes()));
}

#[test]
fn sequence_segments_share_the_memory_and_real_time_restores_one_record() {
    let scope = scope_with(Arc::new(TestSignal::default()));
    send(&*scope, SETUP);
    // 32 Mpoints shared by 40 segments: 800 000 points each.
    send(
        &*scope,
        "VBS 'app.Acquisition.Horizontal.HorScale = 1e-5';\
VBS 'app.Acquisition.Horizontal.SampleMode = \"Sequence\"';\
VBS 'app.Acquisition.Horizontal.NumSegments = 40'",
    );
    assert_eq!(
        q(
            &*scope,
            "VBS? 'return = app.Acquisition.Horizontal.NumPoints'"
        ),
        "800000"
    );
    send(&*scope, "VBS 'app.Acquisition.Horizontal.NumSegments = 80'");
    assert_eq!(
        q(
            &*scope,
            "VBS? 'return = app.Acquisition.Horizontal.NumPoints'"
        ),
        "400000",
        "the scope shortens the segments to fit"
    );
    send(
        &*scope,
        "VBS 'app.Acquisition.Horizontal.SampleMode = \"RealTime\"'",
    );
    send(
        &*scope,
        "VBS 'app.Acquisition.Horizontal.HorScale = 1.024e-7'",
    );
    send(&*scope, TRIGGER);
    assert_eq!(q(&*scope, "ARM;WAIT 5;*OPC?"), "1");
    let wave = decode(&send(&*scope, "C1:WF? ALL"));
    assert_eq!(wave.d().i32(144), 1, "SUBARRAY_COUNT");
    assert_eq!(wave.d().i32(48), 0, "no TRIGTIME array");
    assert_eq!(wave.codes.len(), 81_920);
}

#[test]
fn a_model_without_sequence_mode_refuses_it() {
    let mut model = mock_lab::catalog::lecroy().unwrap();
    model.limits.max_sequence_segments = 0;
    let scope = Lecroy::new(model, Arc::new(TestSignal::default())).unwrap();
    send(&scope, "CHDR OFF;EXR?");
    send(
        &scope,
        "VBS 'app.Acquisition.Horizontal.SampleMode = \"Sequence\"'",
    );
    assert_eq!(q(&scope, "EXR?"), "26", "not implemented on this model");
    assert_eq!(
        q(
            &scope,
            "VBS? 'return = app.Acquisition.Horizontal.SampleMode'"
        ),
        "RealTime"
    );
}

/// A test signal that counts its acquisitions and, at the second, has another client stop the
/// scope (what a client's safe state sends when it gives up on a capture).
struct StoppedAtTheSecondEdge {
    signal: TestSignal,
    acquisitions: std::sync::atomic::AtomicUsize,
    scope: std::sync::OnceLock<std::sync::Weak<Lecroy>>,
}

impl mock_lab::emulator::lecroy::TriggerSource for StoppedAtTheSecondEdge {
    fn acquire(
        &self,
        request: &mock_lab::emulator::lecroy::AcquisitionRequest,
        deadline: std::time::Instant,
    ) -> Option<mock_lab::emulator::lecroy::Capture> {
        let n = 1 + self
            .acquisitions
            .fetch_add(1, std::sync::atomic::Ordering::SeqCst);
        if n == 2 {
            let scope = self.scope.get().and_then(std::sync::Weak::upgrade).unwrap();
            std::thread::spawn(move || send(&*scope, "STOP"))
                .join()
                .unwrap();
        }
        self.signal.acquire(request, deadline)
    }

    fn force(
        &self,
        request: &mock_lab::emulator::lecroy::AcquisitionRequest,
    ) -> mock_lab::emulator::lecroy::Capture {
        self.signal.force(request)
    }
}

#[test]
fn a_stop_during_a_sequence_ends_it_without_recording_the_segments_left() {
    let source = Arc::new(StoppedAtTheSecondEdge {
        signal: TestSignal::new(true, 1e9, 0.1),
        acquisitions: Default::default(),
        scope: Default::default(),
    });
    let scope = scope_with_source(source.clone());
    source.scope.set(Arc::downgrade(&scope)).unwrap();
    send(&*scope, SETUP);
    send(&*scope, TIMEBASE);
    send(
        &*scope,
        "VBS 'app.Acquisition.Horizontal.SampleMode = \"Sequence\"';\
         VBS 'app.Acquisition.Horizontal.NumSegments = 200'",
    );
    send(&*scope, TRIGGER);
    send(&*scope, "ARM;WAIT 5");
    // The segments after the stop are not synthesised, and the stopped acquisition records nothing.
    assert_eq!(
        source
            .acquisitions
            .load(std::sync::atomic::Ordering::SeqCst),
        2
    );
    assert_eq!(q(&*scope, "INR?").parse::<u32>().unwrap() & 1, 0);
}
