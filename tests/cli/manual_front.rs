//! A bench whose Tx and Rx are `driver = "manual"`: radbench never talks to them, tells the
//! operator what to set, needs the confirmation on standard input before the first RF, and says on
//! every exit what it switched off (the AWG) and what it did not (the modules).

use super::support::{start_lab, LIMIT};
use mock_lab::lab::Lab;
use mock_lab::server::launch::Transport;
use std::path::{Path, PathBuf};
use std::process::Stdio;
use tokio::io::AsyncWriteExt;
use tokio::process::Command;

const BIN: &str = env!("CARGO_BIN_EXE_radbench");

/// Runs radbench with `stdin` as its standard input; (exit code, stdout, stderr).
async fn radbench(dir: &Path, args: &[&str], stdin: &str) -> (i32, String, String) {
    let mut child = Command::new(BIN)
        .args(args)
        .current_dir(dir)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .kill_on_drop(true)
        .spawn()
        .expect("radbench runs");
    let mut input = child.stdin.take().unwrap();
    input.write_all(stdin.as_bytes()).await.unwrap();
    drop(input);
    let out = tokio::time::timeout(LIMIT, child.wait_with_output())
        .await
        .expect("radbench finishes in time")
        .unwrap();
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// The lab with both modules switched on by hand (as an operator would, through the lab itself:
/// radbench never reaches them), and its bench file with both front ends manual.
async fn manual_bench(dir: &Path) -> (Lab, PathBuf) {
    let lab = start_lab().await;
    for module in [&lab.bench.tx, &lab.bench.rx] {
        assert_eq!(module.line("W 03 0000"), "OK");
        assert_eq!(module.line("W 02 000F"), "OK");
        assert!(module.front_end().rf_enabled);
        module.log().clear();
    }
    let text = lab.bench_toml(Transport::Hislip, Transport::Vicp);
    let (head, rest) = text.split_once("[tx]").unwrap();
    let (_, simulation) = rest.split_once("[simulation]").unwrap();
    let file = format!(
        "{head}[tx]\ndriver = \"manual\"\nmodel = \"gotmic-eband-tx\"\nattenuation_db = 0.0\n\n\
         [rx]\ndriver = \"manual\"\n\n[simulation]{simulation}\n[calibration]\n\
         system_delay_s = {:e}\n",
        mock_lab::scene::Scene::default().system_delay_s
    );
    let path = dir.join("bench.toml");
    std::fs::write(&path, file).unwrap();
    (lab, path)
}

/// radbench sent the modules nothing, left them as the operator set them, and the AWG is off.
fn untouched_and_awg_off(lab: &Lab) {
    for module in [&lab.bench.tx, &lab.bench.rx] {
        assert!(
            module.log().texts().is_empty(),
            "{:?}",
            module.log().texts()
        );
        assert!(module.front_end().rf_enabled);
    }
    let pb = lab.bench.awg.playback();
    assert!(!pb.running && pb.channels.iter().all(|c| !c.output_on));
}

const SWITCHED_OFF: &str = "Tx and Rx are manual: radbench switched the AWG outputs off and \
                            stopped the AWG; it did not switch the Tx and Rx modules off: switch \
                            them off by hand";

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn doctor_reports_the_manual_front_ends() {
    let dir = tempfile::tempdir().unwrap();
    let (lab, bench) = manual_bench(dir.path()).await;
    let (code, out, err) = radbench(
        dir.path(),
        &["doctor", "--bench", bench.to_str().unwrap()],
        "",
    )
    .await;
    assert_eq!(code, 0, "{out}\n{err}");
    println!("{out}");
    assert!(
        out.contains("tx.driver") && out.contains("manual (driver = \"manual\")"),
        "{out}"
    );
    assert!(out.contains("rx.driver"), "{out}");
    assert!(!out.contains("tx.reachable"), "{out}");
    untouched_and_awg_off(&lab);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn capture_needs_the_operator_s_confirmation() {
    let dir = tempfile::tempdir().unwrap();
    let (lab, bench) = manual_bench(dir.path()).await;
    let args = |out: &'static str| {
        vec![
            "capture".to_string(),
            "--bench".into(),
            bench.display().to_string(),
            "--allow-rf".into(),
            "--out".into(),
            out.into(),
        ]
    };
    // No confirmation: refused as without --allow-rf, nothing connected or switched on.
    let refused = args("refused");
    let refused: Vec<&str> = refused.iter().map(String::as_str).collect();
    let (code, _, err) = radbench(dir.path(), &refused, "no\n").await;
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("Tx: RF 80.000 GHz (LO 13.3333 GHz, x6), attenuation 0.0 dB"),
        "{err}"
    );
    assert!(err.contains("were not confirmed"), "{err}");
    assert!(
        err.contains(
            "radbench did not connect to the AWG and switched nothing on; it did not switch the \
             Tx and Rx modules off"
        ),
        "{err}"
    );
    assert!(!dir.path().join("refused").exists());
    assert!(lab
        .bench
        .awg
        .playback()
        .channels
        .iter()
        .all(|c| !c.output_on));
    untouched_and_awg_off(&lab);
    // Confirmed: the capture runs on the modules as the operator set them.
    let confirmed = args("confirmed");
    let confirmed: Vec<&str> = confirmed.iter().map(String::as_str).collect();
    let (code, out, err) = radbench(dir.path(), &confirmed, "yes\n").await;
    assert_eq!(code, 0, "{out}\n{err}");
    assert!(err.contains("confirmed: the Tx and Rx settings"), "{err}");
    assert!(err.contains(SWITCHED_OFF), "{err}");
    let summary = std::fs::read_to_string(dir.path().join("confirmed/summary.json")).unwrap();
    assert!(
        summary.contains("manual,gotmic-eband-tx,not connected"),
        "{summary}"
    );
    untouched_and_awg_off(&lab);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_campaign_run_needs_the_confirmation_too() {
    let dir = tempfile::tempdir().unwrap();
    let (lab, _bench) = manual_bench(dir.path()).await;
    let spec = dir.path().join("spec.toml");
    std::fs::write(
        &spec,
        "name = \"manual\"\n[bench]\nfile = \"bench.toml\"\n[[steps]]\ntargets = [1.0]\n",
    )
    .unwrap();
    let run = |out: &'static str| {
        vec![
            "campaign".to_string(),
            "run".into(),
            spec.display().to_string(),
            "--out".into(),
            out.into(),
            "--allow-rf".into(),
        ]
    };
    let refused = run("refused");
    let refused: Vec<&str> = refused.iter().map(String::as_str).collect();
    let (code, _, err) = radbench(dir.path(), &refused, "").await;
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("the campaign run did not start"), "{err}");
    assert!(err.contains("radbench did not connect to the AWG"), "{err}");
    assert!(!dir.path().join("refused").exists());
    untouched_and_awg_off(&lab);
    let confirmed = run("confirmed");
    let confirmed: Vec<&str> = confirmed.iter().map(String::as_str).collect();
    let (code, out, err) = radbench(dir.path(), &confirmed, "yes\n").await;
    assert_eq!(code, 0, "{out}\n{err}");
    assert!(err.contains(SWITCHED_OFF), "{err}");
    assert!(out.contains("complete: 1 steps"), "{out}");
    untouched_and_awg_off(&lab);
}

/// The library (`measure::take`, and `radbench.Bench`'s session) refuses manual front ends
/// unless the permit carries the operator's confirmation: nothing is sent to the AWG first.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_library_refuses_manual_front_ends_without_the_confirmation() {
    use radbench::driver::RfPermit;
    use radbench::in_memory::{BenchSession, SessionSource};
    use radbench::measure::{self, Bench, BenchSource, Interrupt, MeasureError, ProcessOptions};
    use radbench::waveform::WaveformKind;
    let dir = tempfile::tempdir().unwrap();
    let (lab, path) = manual_bench(dir.path()).await;
    let bench = Bench::open(BenchSource::File(path.clone())).await.unwrap();
    let request = super::support::thesis_request(
        WaveformKind::MskLfm,
        ProcessOptions::for_waveform(WaveformKind::MskLfm),
        false,
    );
    lab.bench.awg.log().clear();
    let refused = measure::take(
        &bench,
        &request,
        None,
        1,
        &RfPermit::granted_by_user(),
        None,
        &Interrupt::never(),
    )
    .await
    .err()
    .expect("refused without the confirmation");
    assert!(
        matches!(refused, MeasureError::ManualNotConfirmed { .. }),
        "{refused}"
    );
    let text = refused.to_string();
    assert!(
        text.contains("Tx and Rx front end settings were not confirmed")
            && text.contains("manual_front_ends_confirmed=True")
            && text.contains("nothing was switched on"),
        "{text}"
    );
    assert!(
        lab.bench.awg.log().texts().is_empty(),
        "{:?}",
        lab.bench.awg.log().texts()
    );
    untouched_and_awg_off(&lab);
    drop(bench);

    // The session behind Python's radbench.Bench: refused without the keyword, measured with it.
    let session = move |confirmed: bool| SessionSource {
        bench: Some(path.clone()),
        allow_rf: true,
        manual_front_ends_confirmed: confirmed,
        ..SessionSource::default()
    };
    let (without, with) = tokio::task::spawn_blocking(move || {
        let capture = |s: &BenchSession| {
            let options = radbench::in_memory::CaptureOptions::from_keywords(
                WaveformKind::MskLfm,
                "{}",
                1,
                None,
            )
            .unwrap();
            s.capture(options)
                .wait(LIMIT)
                .expect("the capture ends in time")
                .map(|_| ())
                .map_err(|e| radbench::exit::render(&e))
        };
        let refused = BenchSession::open(session(false)).unwrap();
        let without = capture(&refused);
        drop(refused);
        let confirmed = BenchSession::open(session(true)).unwrap();
        let with = capture(&confirmed);
        drop(confirmed);
        (without, with)
    })
    .await
    .unwrap();
    let err = without.expect_err("refused without manual_front_ends_confirmed");
    assert!(err.contains("manual_front_ends_confirmed=True"), "{err}");
    with.expect("measured with manual_front_ends_confirmed");
    let pb = lab.bench.awg.playback();
    assert!(!pb.running && pb.channels.iter().all(|c| !c.output_on));
}
