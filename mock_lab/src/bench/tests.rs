use super::*;
use crate::scene::{Leakage, Target, C0};
use crate::server::Handler;
use num_complex::Complex64;
use rustfft::FftPlanner;

const N: usize = 16_384; // one repetition: 1.024 us at 16 GSa/s

fn block(payload: &[u8]) -> Vec<u8> {
    let len = payload.len().to_string();
    let mut out = format!("#{}{}", len.len(), len).into_bytes();
    out.extend_from_slice(payload);
    out
}

/// A 1 GHz chirp over one repetition, as AWG codes.
fn chirp() -> (Vec<i8>, Vec<i8>) {
    let fs = 16e9;
    let tp = N as f64 / fs;
    (0..N)
        .map(|n| {
            let t = n as f64 / fs - tp / 2.0;
            let ph = std::f64::consts::PI * 1e9 / tp * t * t;
            (
                (100.0 * ph.cos()).round() as i8,
                (100.0 * ph.sin()).round() as i8,
            )
        })
        .unzip()
}

fn send(h: &dyn Handler, msg: &[u8]) -> String {
    h.message(msg)
        .first()
        .map(|r| String::from_utf8_lossy(r).trim().to_string())
        .unwrap_or_default()
}

fn play(bench: &Bench, i: &[i8], q: &[i8]) {
    let awg: &dyn Handler = &*bench.awg;
    for cmd in [
        "*RST",
        ":INST:DACM DCM;:INST:MEM:EXT:RDIV DIV4;:TRAC1:MMOD EXT;:TRAC2:MMOD EXT",
        ":FREQ:RAST 6.4E10;:FUNC:MODE ARB;:INIT:CONT 1",
        &format!(":TRAC1:DEF 1,{N}"),
    ] {
        send(awg, cmd.as_bytes());
    }
    let mut pairs = Vec::with_capacity(2 * N);
    for (k, s) in i.iter().enumerate() {
        pairs.push(*s as u8);
        pairs.push(u8::from(k < 64));
    }
    let mut msg = b":TRAC1:DATA 1,0,".to_vec();
    msg.extend(block(&pairs));
    send(awg, &msg);
    let mut msg = b":TRAC2:DATA 1,0,".to_vec();
    msg.extend(block(&q.iter().map(|s| *s as u8).collect::<Vec<_>>()));
    send(awg, &msg);
    for cmd in [
        ":TRAC1:SEL 1;:TRAC2:SEL 1;:VOLT1 0.5;:VOLT2 0.5;:VOLT3:AMPL 0.8;:VOLT3:OFFS 0.4",
        ":OUTP1 ON;:OUTP2 ON;:OUTP3 ON",
        ":INIT:IMM",
    ] {
        send(awg, cmd.as_bytes());
    }
    assert_eq!(send(awg, b":SYST:ERR?"), "0,\"No error\"");
}

fn rf(module: &Gotmic, on: bool) {
    assert_eq!(module.line("W 03 003F"), "OK");
    assert_eq!(
        module.line(if on { "W 02 000F" } else { "W 02 0000" }),
        "OK"
    );
    if on {
        assert_eq!(module.line("W 03 0000"), "OK");
    }
}

fn setup_scope(bench: &Bench) {
    let scope: &dyn Handler = &*bench.scope;
    for cmd in [
        "CHDR OFF;CFMT DEF9,WORD,BIN;CORD LO;WFSU SP,0,NP,0,FP,0,SN,0",
        "VBS 'app.Acquisition.Horizontal.Maximize = \"FixedSampleRate\"'",
        "VBS 'app.Acquisition.Horizontal.SampleRate = 80e9'",
        "VBS 'app.Acquisition.Horizontal.HorScale = 1.024e-7'",
        "C1:VDIV 0.05;C2:VDIV 0.05",
        "TRSE EDGE,SR,EX,HT,OFF;EX:TRLV 0.2V;EX:TRSL POS;TRMD SINGLE",
    ] {
        send(scope, cmd.as_bytes());
    }
}

/// Arms, waits up to `wait_s`, and returns I + jQ in volts with the time of the first point, or
/// `None` when nothing triggered.
fn acquire(bench: &Bench, wait_s: f64) -> Option<(Vec<Complex64>, f64)> {
    let scope: &dyn Handler = &*bench.scope;
    send(scope, b"TRMD SINGLE");
    send(scope, format!("ARM;WAIT {wait_s}").as_bytes());
    let inr: u32 = send(scope, b"INR?").parse().unwrap();
    if inr & 1 == 0 {
        return None;
    }
    let acq = bench.scope.state().acquisition?;
    let ch = |k: usize| acq.channels[k].clone().unwrap();
    let (i, q) = (ch(0), ch(1));
    let y = i
        .values
        .iter()
        .zip(&q.values)
        .map(|(a, b)| {
            Complex64::new(
                f64::from(*a) * i.gain_word - i.offset_v,
                f64::from(*b) * q.gain_word - q.offset_v,
            )
        })
        .collect();
    Some((y, acq.first_point_s))
}

fn quiet_bench(range_m: f64) -> Bench {
    Bench::new(Scene {
        targets: vec![Target {
            range_m,
            amplitude: 0.5,
            velocity_mps: 0.0,
        }],
        leakage: Leakage {
            amplitude: 0.0,
            delay_s: 0.0,
        },
        snr_db: 40.0,
        ..Scene::default()
    })
    .unwrap()
}

/// Delay of the strongest echo: circular correlation with the ideal 80 GSa/s chirp, parabolic peak.
fn echo_delay(y: &[Complex64], i: &[i8], q: &[i8], first_point_s: f64) -> f64 {
    let up = 5;
    let n = N * up;
    assert_eq!(y.len(), n, "one repetition at 80 GSa/s");
    let mut planner = FftPlanner::<f64>::new();
    let mut x: Vec<Complex64> = i
        .iter()
        .zip(q)
        .map(|(a, b)| Complex64::new(f64::from(*a), f64::from(*b)))
        .collect();
    planner.plan_fft_forward(N).process(&mut x);
    let mut xr = vec![Complex64::new(0.0, 0.0); n];
    for (k, v) in x.iter().enumerate() {
        let signed = if k < N / 2 {
            k as i64
        } else {
            k as i64 - N as i64
        };
        xr[signed.rem_euclid(n as i64) as usize] = *v;
    }
    let mut yy = y.to_vec();
    planner.plan_fft_forward(n).process(&mut yy);
    for (a, b) in yy.iter_mut().zip(&xr) {
        *a *= b.conj();
    }
    planner.plan_fft_inverse(n).process(&mut yy);
    let mag: Vec<f64> = yy.iter().map(|v| v.norm()).collect();
    let (l, _) = mag
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.total_cmp(b.1))
        .unwrap();
    let (a, b, c) = (mag[(l + n - 1) % n], mag[l], mag[(l + 1) % n]);
    let frac = 0.5 * (a - c) / (a - 2.0 * b + c);
    let lag = l as f64 + frac;
    let period = n as f64 / 80e9;
    (first_point_s + lag / 80e9).rem_euclid(period)
}

#[test]
fn marker_triggered_capture_shows_the_echo_at_its_range() {
    let bench = quiet_bench(1.2);
    let (i, q) = chirp();
    play(&bench, &i, &q);
    rf(&bench.tx, true);
    rf(&bench.rx, true);
    setup_scope(&bench);
    let (y, first) = acquire(&bench, 5.0).expect("the marker triggers the scope");
    let tau = echo_delay(&y, &i, &q, first);
    let expected = 2.0 * 1.2 / C0 + Scene::default().system_delay_s;
    let range_error_m = (tau - expected) * C0 / 2.0;
    assert!(range_error_m.abs() < 1e-3, "range error {range_error_m} m");
    let (captures, truth) = bench.scene.last_capture();
    assert_eq!(captures, 1);
    assert_eq!(truth.unwrap().targets[0].range_m, 1.2);
}

#[test]
fn without_the_marker_output_the_acquisition_times_out() {
    let bench = quiet_bench(1.0);
    let (i, q) = chirp();
    play(&bench, &i, &q);
    send(&*bench.awg, b":OUTP3 OFF");
    setup_scope(&bench);
    assert!(acquire(&bench, 0.05).is_none());
    assert_eq!(bench.scene.last_capture().0, 0);
}

#[test]
fn transmitter_off_shows_noise_only() {
    let bench = quiet_bench(1.0);
    let (i, q) = chirp();
    play(&bench, &i, &q);
    rf(&bench.rx, true);
    setup_scope(&bench);
    let power = |y: &[Complex64]| y.iter().map(|v| v.norm_sqr()).sum::<f64>() / y.len() as f64;
    let (off, _) = acquire(&bench, 5.0).unwrap();
    rf(&bench.tx, true);
    let (on, _) = acquire(&bench, 5.0).unwrap();
    assert!(
        power(&on) > 100.0 * power(&off),
        "{} vs {}",
        power(&on),
        power(&off)
    );
    assert!(!bench.is_safe());
    rf(&bench.tx, false);
    send(&*bench.awg, b":ABOR;:OUTP1 OFF;:OUTP2 OFF;:OUTP3 OFF");
    assert!(bench.is_safe());
}

#[test]
fn rising_edge_search_wraps() {
    assert_eq!(first_rising_edge(&[0, 0, 1, 1, 0]), 2);
    assert_eq!(first_rising_edge(&[1, 1, 0, 0]), 0);
    assert_eq!(first_rising_edge(&[1, 0, 0, 1]), 3);
    assert_eq!(first_rising_edge(&[]), 0);
}

#[test]
fn a_seed_request_replays_the_same_noise() {
    let bench = quiet_bench(1.0);
    let (i, q) = chirp();
    play(&bench, &i, &q);
    rf(&bench.rx, true);
    rf(&bench.tx, true);
    setup_scope(&bench);
    let seed = |n: u64| {
        let reply = bench
            .scene
            .apply(&format!(r#"{{"cmd":"seed","seed":{n}}}"#));
        assert_eq!(reply["ok"], true, "{reply}");
    };
    seed(7);
    let (a, _) = acquire(&bench, 5.0).unwrap();
    let (b, _) = acquire(&bench, 5.0).unwrap();
    assert_ne!(a, b, "successive captures get new noise");
    seed(7);
    let (c, _) = acquire(&bench, 5.0).unwrap();
    assert_eq!(a, c, "the same seed replays the same capture");
    // A whole scene set restarts from its seed too.
    let mut scene = bench.scene.snapshot();
    scene.seed = 7;
    let reply = bench
        .scene
        .apply(&serde_json::json!({"cmd": "set", "scene": scene}).to_string());
    assert_eq!(reply["ok"], true);
    let (d, _) = acquire(&bench, 5.0).unwrap();
    assert_eq!(a, d);
}
