//! The M8195A emulator through its `Handler` interface: the driver's command sequence, long and short
//! forms, the instrument's rules and the SCPI error codes it answers with.

use mock_lab::emulator::m8195a::{M8195a, Memory};
use mock_lab::server::Handler;

fn awg() -> M8195a {
    M8195a::embedded().expect("built-in catalog loads")
}

/// Sends one message; returns the response text ("" when there is none).
fn send(awg: &M8195a, message: &[u8]) -> String {
    let replies = awg.message(message);
    assert!(replies.len() <= 1, "one response message at most");
    replies
        .first()
        .map(|r| String::from_utf8(r.clone()).unwrap())
        .unwrap_or_default()
}

fn q(awg: &M8195a, query: &str) -> String {
    send(awg, query.as_bytes())
}

/// Pops the whole error queue as `code` numbers.
fn error_codes(awg: &M8195a) -> Vec<i32> {
    let mut codes = Vec::new();
    loop {
        let reply = q(awg, ":SYST:ERR?");
        let code: i32 = reply.split(',').next().unwrap().parse().unwrap();
        if code == 0 {
            assert_eq!(reply, "0,\"No error\"");
            return codes;
        }
        codes.push(code);
    }
}

fn block(payload: &[u8]) -> Vec<u8> {
    let len = payload.len().to_string();
    let mut out = format!("#{}{}", len.len(), len).into_bytes();
    out.extend_from_slice(payload);
    out
}

/// The driver's 16 GSa/s I/Q + marker setup of instruments.md 1.4 with an N-sample segment.
fn configure_iq(awg: &M8195a, n: usize) -> (Vec<i8>, Vec<u8>, Vec<i8>) {
    for cmd in [
        "*RST;*OPC?",
        ":ABOR",
        ":INST:DACM DCM",
        ":INST:MEM:EXT:RDIV DIV4",
        ":TRAC1:MMOD EXT;:TRAC2:MMOD EXT",
        ":FREQ:RAST 6.4E10",
        ":FUNC:MODE ARB",
        ":INIT:CONT 1;:INIT:GATE 0",
        ":TRAC1:DEL:ALL",
        &format!(":TRAC1:DEF 1,{n}"),
    ] {
        send(awg, cmd.as_bytes());
    }
    let i: Vec<i8> = (0..n).map(|k| ((k * 7) % 256) as u8 as i8).collect();
    let q_: Vec<i8> = (0..n).map(|k| ((k * 13 + 5) % 256) as u8 as i8).collect();
    let markers: Vec<u8> = (0..n).map(|k| u8::from(k < 32)).collect();
    let mut pairs = Vec::with_capacity(2 * n);
    for k in 0..n {
        pairs.push(i[k] as u8);
        pairs.push(markers[k]);
    }
    let mut msg = b":TRAC1:DATA 1,0,".to_vec();
    msg.extend(block(&pairs));
    msg.extend_from_slice(b"\n");
    send(awg, &msg);
    let mut msg = b":TRAC2:DATA 1,0,".to_vec();
    msg.extend(block(&q_.iter().map(|s| *s as u8).collect::<Vec<_>>()));
    send(awg, &msg);
    assert_eq!(q(awg, "*OPC?"), "1");
    for cmd in [
        ":TRAC1:SEL 1;:TRAC2:SEL 1",
        ":VOLT1 0.5;:VOLT2 0.5",
        ":VOLT3:AMPL 0.8;:VOLT3:OFFS 0.4",
        ":OUTP1 ON;:OUTP2 ON;:OUTP3 ON;:OUTP4 ON",
        ":INIT:IMM",
    ] {
        send(awg, cmd.as_bytes());
    }
    (i, markers, q_)
}

#[test]
fn identifies_as_an_emulator() {
    let awg = awg();
    let idn = q(&awg, "*IDN?");
    assert_eq!(idn, "MOCK_LAB,M8195A-EMU,EMU0001,mock_lab-1");
    assert!(!idn.to_ascii_lowercase().contains("keysight"));
}

#[test]
fn driver_setup_plays_iq_with_markers_at_16_gsps() {
    let awg = awg();
    let n = 1024;
    let (i, markers, q_) = configure_iq(&awg, n);
    assert_eq!(error_codes(&awg), Vec::<i32>::new());

    let play = awg.playback();
    assert!(play.running && play.continuous);
    assert_eq!(play.dac_mode, "DCM");
    assert_eq!(play.divider, 4);
    assert_eq!(play.dac_rate, 64e9);
    let ch1 = play.channel(1).unwrap();
    assert_eq!(ch1.sample_rate, 16e9);
    assert_eq!(ch1.memory, Memory::Extended);
    assert_eq!(&ch1.samples[..], &i[..]);
    assert_eq!(&play.channel(2).unwrap().samples[..], &q_[..]);
    assert_eq!(&play.markers[..], &markers[..]);
    assert_eq!(play.marker_channels, [3, 4]);
    assert!(play.marker_active());
    assert_eq!(play.channel(3).unwrap().amplitude_vpp, 0.8);
    assert!(play.channels.iter().all(|c| c.output_on));

    assert_eq!(q(&awg, ":INST:DACM?"), "DCM");
    assert_eq!(q(&awg, ":INST:MEM:EXT:RDIV?"), "DIV4");
    assert_eq!(q(&awg, ":FREQ:RAST?"), "6.4000000000E+10");
    assert_eq!(q(&awg, ":TRAC1:CAT?"), "1,1024");
    assert_eq!(q(&awg, ":TRAC2:CAT?"), "1,1024");
    assert_eq!(
        q(&awg, ":TRAC2:MMOD?;:OUTP3?;:VOLT3:HIGH?"),
        "EXT;1;8.0000000000E-01"
    );
    assert_eq!(
        q(&awg, ":TRAC1:DATA? 1,0,2"),
        format!("{},1,{},1", i[0], i[1])
    );

    let before = play.generation;
    send(&awg, b":ABOR");
    let stopped = awg.playback();
    assert!(!stopped.running && !stopped.marker_active());
    assert!(stopped.generation > before);
}

#[test]
fn long_forms_optional_nodes_and_relative_headers() {
    let awg = awg();
    send(
        &awg,
        b":INSTRUMENT:DACMODE DCMARKER;:INSTrument:MEMory:EXTended:RDIVider DIV2",
    );
    send(&awg, b":SOURCE:FREQUENCY:RASTER 60 GHz");
    send(&awg, b":TRACE1:DEFINE 1,640;DATA 1,0,#11\x00");
    send(&awg, b":SOUR:VOLT2:LEV:IMM:AMPL 250 mV");
    assert_eq!(
        error_codes(&awg),
        vec![-161],
        "odd byte count in marker mode"
    );
    assert_eq!(q(&awg, ":inst:dacm?"), "DCM");
    assert_eq!(q(&awg, ":FREQ:RAST?"), "6.0000000000E+10");
    assert_eq!(q(&awg, ":VOLT2?"), "2.5000000000E-01");
    assert_eq!(
        q(&awg, ":TRAC:CAT?"),
        "1,640",
        "TRAC without suffix is channel 1"
    );
    assert_eq!(
        awg.log().texts()[2],
        ":TRACE1:DEFINE 1,640;DATA 1,0,#<1 bytes>"
    );
}

#[test]
fn undefined_headers_and_bad_parameters_give_scpi_codes() {
    let awg = awg();
    send(&awg, b":FOO:BAR 1");
    send(&awg, b":TRAC5:DEF 1,1280");
    send(&awg, b":INST:DACM TRIPLE");
    send(&awg, b":INST:MEM:EXT:RDIV DIV3");
    send(&awg, b":FREQ:RAST fast");
    send(&awg, b":TRAC:CAT 1");
    send(&awg, b":OUTP1");
    send(&awg, b"*IDN? 1");
    assert_eq!(
        error_codes(&awg),
        [-113, -114, -224, -224, -104, -113, -109, -108]
    );
}

#[test]
fn command_errors_abandon_the_rest_of_the_message_execution_errors_do_not() {
    let awg = awg();
    assert_eq!(q(&awg, ":BOGUS;*OPC?"), "");
    assert_eq!(error_codes(&awg), [-113]);
    assert_eq!(q(&awg, ":FREQ:RAST 70e9;*OPC?"), "1");
    assert_eq!(error_codes(&awg), [-222]);
}

#[test]
fn raster_outside_the_catalog_range_is_refused() {
    let awg = awg();
    send(&awg, b":FREQ:RAST 16E9");
    send(&awg, b":FREQ:RAST 65.1E9");
    send(&awg, b":FREQ:RAST 53.76E9");
    assert_eq!(error_codes(&awg), [-222, -222]);
    assert_eq!(q(&awg, ":FREQ:RAST?"), "5.3760000000E+10");
    send(&awg, b":FREQ:RAST MAX");
    assert_eq!(awg.playback().dac_rate, 65e9);
}

/// DCM at DIV4 with both signal channels in extended memory.
fn dcm_div4() -> M8195a {
    let awg = awg();
    send(
        &awg,
        b":INST:DACM DCM;:INST:MEM:EXT:RDIV DIV4;:TRAC2:MMOD EXT",
    );
    awg
}

#[test]
fn at_div4_segments_need_the_granularity_and_the_minimum_length() {
    let awg = dcm_div4();
    send(&awg, b":TRAC1:DEF 1,1000");
    send(&awg, b":TRAC1:DEF 1,256");
    send(&awg, b":TRAC1:DEF 1,320");
    assert_eq!(error_codes(&awg), [-222, -222]);
    assert_eq!(
        q(&awg, ":TRAC2:CAT?"),
        "1,320",
        "defined on every extended channel"
    );
}

#[test]
fn a_segment_cannot_be_defined_twice() {
    let awg = dcm_div4();
    send(&awg, b":TRAC1:DEF 1,320");
    send(&awg, b":TRAC1:DEF 1,320");
    assert_eq!(error_codes(&awg), [-221]);
}

#[test]
fn a_divider_change_clears_extended_memory_and_brings_its_own_rules() {
    let awg = dcm_div4();
    send(&awg, b":TRAC1:DEF 1,320");
    send(&awg, b":INST:MEM:EXT:RDIV DIV1");
    assert_eq!(q(&awg, ":TRAC1:CAT?"), "0,0");
    send(&awg, b":TRAC1:DEF 1,1024");
    send(&awg, b":TRAC1:DEF 1,1280");
    assert_eq!(error_codes(&awg), [-222], "1024 is below DIV1's minimum");
    assert!(awg.pending_errors().is_empty());
}

#[test]
fn error_texts_say_what_is_allowed() {
    let awg = awg();
    send(
        &awg,
        b":INST:DACM DCM;:INST:MEM:EXT:RDIV DIV4;:TRAC1:DEF 1,1000",
    );
    let reply = q(&awg, ":SYST:ERR?");
    assert!(reply.starts_with("-222,\"Data out of range;"), "{reply}");
    assert!(reply.contains("granularity 64"), "{reply}");
}

/// FOUR mode with a 1280-sample segment 1 on channel 1.
fn one_segment() -> M8195a {
    let awg = awg();
    send(&awg, b":INST:DACM FOUR;:TRAC1:DEF 1,1280");
    awg
}

/// `:TRAC1:DATA <id>,<offset>,<block>`.
fn download(awg: &M8195a, id: u32, offset: u64, payload: &[u8]) {
    let mut msg = format!(":TRAC1:DATA {id},{offset},").into_bytes();
    msg.extend(block(payload));
    send(awg, &msg);
}

#[test]
fn a_download_past_the_segment_end_is_too_much_data() {
    let awg = one_segment();
    download(&awg, 1, 1024, &[0u8; 512]);
    assert_eq!(error_codes(&awg), [-223]);
}

#[test]
fn a_download_at_an_offset_off_the_granularity_is_refused() {
    let awg = one_segment();
    download(&awg, 1, 100, &[0u8; 4]);
    assert_eq!(error_codes(&awg), [-222]);
}

#[test]
fn a_download_to_an_undefined_segment_is_refused() {
    let awg = one_segment();
    download(&awg, 2, 0, &[0u8]);
    assert_eq!(error_codes(&awg), [-222]);
}

#[test]
fn ascii_download_values_must_be_bytes() {
    let awg = one_segment();
    send(&awg, b":TRAC1:DATA 1,0,1,2,300");
    assert_eq!(error_codes(&awg), [-222]);
}

#[test]
fn ascii_downloads_read_back() {
    let awg = one_segment();
    send(&awg, b":TRAC1:DATA 1,0,1,-2,127");
    assert_eq!(error_codes(&awg), Vec::<i32>::new());
    assert_eq!(q(&awg, ":TRAC1:DATA? 1,0,3"), "1,-2,127");
}

/// DCM with channel 2 in extended memory, and nothing loaded.
fn dcm() -> M8195a {
    let awg = awg();
    send(&awg, b":INST:DACM DCM;:TRAC2:MMOD EXT");
    awg
}

/// DCM playing segment 1 with its outputs on.
fn dcm_running() -> M8195a {
    let awg = dcm();
    send(&awg, b":TRAC1:DEF 1,1280;:TRAC1:SEL 1");
    send(&awg, b":OUTP1 ON;:OUTP3 ON;:OUTP2 OFF;:INIT:IMM");
    awg
}

#[test]
fn outputs_and_run_are_refused_without_a_waveform() {
    let awg = dcm();
    send(&awg, b":OUTP1 ON");
    send(&awg, b":OUTP3 ON");
    send(&awg, b":INIT:IMM");
    assert_eq!(error_codes(&awg), [-221, -221, -221]);
    let play = awg.playback();
    assert!(!play.running && play.channels.iter().all(|c| !c.output_on));
}

#[test]
fn with_a_waveform_outputs_and_run_are_accepted() {
    let awg = dcm_running();
    assert_eq!(error_codes(&awg), Vec::<i32>::new());
    assert!(awg.playback().running);
}

#[test]
fn while_running_the_memory_layout_cannot_change() {
    let awg = dcm_running();
    send(&awg, b":TRAC1:DEL:ALL");
    send(&awg, b":INST:DACM FOUR");
    assert_eq!(error_codes(&awg), [-221, -221]);
}

#[test]
fn channel_roles_follow_the_dac_mode() {
    let awg = awg();
    send(&awg, b":INST:DACM DCM");
    send(&awg, b":TRAC1:MMOD INT");
    send(&awg, b":TRAC3:DEF 1,1280");
    send(&awg, b":VOLT3 0.05");
    send(&awg, b":VOLT1 1.5");
    assert_eq!(error_codes(&awg), [-221, -221, -222, -222]);
    send(&awg, b":VOLT3 0.5;:VOLT1 0.075");
    assert_eq!(error_codes(&awg), Vec::<i32>::new());
    assert_eq!(awg.state().channel(1).memory, Memory::Extended);

    send(
        &awg,
        b":INST:DACM DCD;:TRAC1:DEF 1,1280;:TRAC1:SEL 1;:TRAC2:DEF 1,1280;:TRAC2:SEL 1",
    );
    send(&awg, b":INIT:IMM");
    assert_eq!(error_codes(&awg), [-221], "DCD needs DIV2");
}

#[test]
fn sequencer_modes_need_the_option() {
    let awg = awg();
    send(&awg, b":FUNC:MODE STS");
    assert_eq!(error_codes(&awg), [-241]);
    assert_eq!(q(&awg, ":FUNC:MODE?"), "ARB");
}

#[test]
fn status_registers_and_clear() {
    let awg = awg();
    send(&awg, b"*ESE 60;*SRE 32");
    send(&awg, b":NOPE");
    assert_eq!(awg.status_byte() & 0x24, 0x24);
    assert_eq!(awg.status_byte() & 0x40, 0x40);
    assert_eq!(q(&awg, ":SYST:ERR:COUN?"), "1");
    assert_eq!(q(&awg, "*ESR?"), "32");
    send(&awg, b"*CLS");
    assert_eq!(q(&awg, ":SYST:ERR:COUN?"), "0");
    assert_eq!(awg.status_byte(), 0);
    assert_eq!(q(&awg, "*OPT?"), "001,002,004,16G");
}

#[test]
fn reset_restores_defaults_but_keeps_the_error_queue() {
    let awg = awg();
    let _ = configure_iq(&awg, 320);
    send(&awg, b":FREQ:RAST 99e9");
    send(&awg, b"*RST");
    let play = awg.playback();
    assert!(!play.running);
    assert_eq!(play.dac_mode, "SING");
    assert_eq!(play.divider, 1);
    assert!(play
        .channels
        .iter()
        .all(|c| c.samples.is_empty() && !c.output_on));
    assert_eq!(error_codes(&awg), [-222]);
}

#[test]
fn block_payload_may_contain_separators_and_newlines() {
    let awg = awg();
    send(&awg, b":INST:DACM SING;:TRAC1:DEF 1,1280");
    let payload: Vec<u8> = (0..1280u32)
        .map(|k| [b';', b'\n', b',', b'#'][k as usize % 4])
        .collect();
    let mut msg = b":TRAC:DATA 1,0,".to_vec();
    msg.extend(block(&payload));
    msg.extend_from_slice(b";:TRAC:SEL 1\r\n");
    send(&awg, &msg);
    assert_eq!(error_codes(&awg), Vec::<i32>::new());
    let samples = awg.playback().channel(1).unwrap().samples.clone();
    assert_eq!(
        samples.iter().map(|s| *s as u8).collect::<Vec<_>>(),
        payload
    );
}

#[test]
fn error_queue_overflows_to_350() {
    let awg = awg();
    for _ in 0..40 {
        send(&awg, b":NOPE");
    }
    let codes = error_codes(&awg);
    assert_eq!(codes.len(), 30);
    assert_eq!(codes[29], -350);
}

#[test]
fn a_model_the_emulator_cannot_use_is_refused() {
    let mut model = mock_lab::catalog::m8195a().unwrap();
    model.limits.dividers.clear();
    assert!(M8195a::new(model).is_err());
    let mut model = mock_lab::catalog::m8195a().unwrap();
    model.limits.dac_modes[0].signal_channels.push(9);
    let err = M8195a::new(model).err().unwrap();
    assert!(err.to_string().contains("outside 1..=4"), "{err}");
}
