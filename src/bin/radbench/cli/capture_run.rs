//! `radbench capture`'s run: the arguments checked, the bench opened, the options and the
//! calibration resolved, then one capture (`capture::once`) or a series (`repeat`, for
//! `--repeat`).

use super::capture::{
    bench_source, default_out, once, open_bench, prepare_out, resolve_correction, Args,
};
use radbench::driver::RfPermit;
use radbench::exit::bad_input;
use radbench::measure;
use radbench::measure::CaptureRequest;
use radbench::measure::CorrectionMode;
use radbench::measure::Interrupt;
use radbench::measure::MeasureError;
use radbench::waveform::WaveformKind;
use std::path::Path;

pub(crate) fn run(args: Args, global: &super::global::Global) -> anyhow::Result<()> {
    let runtime = super::global::runtime()?;
    runtime.block_on(run_async(args, global))
}

async fn run_async(args: Args, global: &super::global::Global) -> anyhow::Result<()> {
    let kind = args.waveform;
    let waveform = args.waveform_args.spec(kind)?;
    if !args.allow_rf {
        return Err(MeasureError::NoPermit { run: "capture" }.into());
    }
    args.timeout.apply()?;
    if args.live.live && args.repeat.is_none() {
        return Err(bad_input(
            "--live: needs --repeat N|forever (one capture is over before a page could show it)",
        ));
    }
    let source = args.scope_model.apply(bench_source(
        args.bench.as_deref(),
        args.scene.as_deref(),
        args.awg_transport,
        args.scope_transport,
    )?)?;
    let manual = super::manual_front::confirm_file(args.bench.as_deref(), "capture")?;
    let out = args.out.clone().unwrap_or_else(|| default_out(kind.name()));
    let created = !out.exists();
    prepare_out(&out, args.force)?;
    let result = measure_into(args, global, kind, waveform, source, &out, &manual.permit()).await;
    if result.is_err() && created {
        // A refused or failed capture leaves no empty folder behind (one with files stays).
        let _ = std::fs::remove_dir(&out);
    }
    // Its files are durable: into the run catalog (bounded; never the command's error).
    super::runs::register_now(&out);
    result
}

async fn measure_into(
    args: Args,
    global: &super::global::Global,
    kind: WaveformKind,
    waveform: radbench::waveform::WaveformSpec,
    source: radbench::measure::BenchSource,
    out: &Path,
    permit: &RfPermit,
) -> anyhow::Result<()> {
    let out = out.to_path_buf();
    let payload = args.bits.payload.as_ref().map(|p| p.as_bytes().to_vec());
    // The transmission is generated while the bench file is read and the options resolved.
    let generation = args
        .repeat
        .is_none()
        .then(|| measure::Generation::start(waveform, payload.clone(), args.bits.seed));
    let interrupt = Interrupt::listen()?;
    let bench = open_bench(source, false).await?;
    let mut options = args.processing.options(kind);
    bench.file.processing_of_this_bench(&mut options);
    if let Some(w) = bench.file.uncalibrated_warning() {
        // At once, before the capture; the outputs (report, --json, summary.json) repeat it.
        eprintln!("warning: {w}");
    }
    let calibration = resolve_correction(
        args.processing.correction,
        args.processing.calibration.as_deref(),
        &bench,
    )?;
    let mode = args.processing.correction.unwrap_or(CorrectionMode::Rx);
    options.correction = calibration.as_ref().map(|c| c.used_as(mode));
    let request = CaptureRequest {
        waveform,
        payload,
        seed: args.bits.seed,
        options,
        tx_off: args.tx_off,
        wait_s: args.wait,
        background: args.background.clone(),
    };
    let Some(repeat) = args.repeat else {
        return once(
            &args,
            global,
            &bench,
            &request,
            generation,
            permit,
            &interrupt,
            &out,
            calibration.as_deref(),
        )
        .await;
    };
    super::repeat::captures(
        &args,
        global,
        repeat,
        &bench,
        &request,
        &interrupt,
        permit,
        &out,
        calibration.as_deref(),
    )
    .await
}
