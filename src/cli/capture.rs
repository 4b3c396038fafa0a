//! `radbench capture`: one complete measurement, on the bench of a bench file or on the built-in
//! mock lab.

use crate::catalog::Catalog;
use crate::driver::{AwgSettings, DigitizerSettings, RfPermit, RfSettings};
use crate::exit::bad_input;
use crate::measure::bench_file::{BenchFile, Calibration};
use crate::measure::process::{self, ProcessOptions, Processed, RawIq};
use crate::measure::run::{self, CaptureSettings, Captured, Identities};
use crate::measure::transmit::{Transmission, WaveformKind, DEFAULT_BACKOFF_DB};
use crate::processing::{Algorithm, FftPrecisionName, WindowName};
use crate::storage::plot::{self, Curve, ProfilePlot};
use crate::storage::profile::ProfileTable;
use crate::storage::sigmf::{self, SigmfMeta};
use anyhow::Context;
use mock_lab::lab::{Lab, LabOptions};
use mock_lab::server::launch::Transport;
use num_complex::Complex64;
use serde_json::{json, Value};
use std::path::{Path, PathBuf};

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Bench file (TOML) naming the instruments; without one, a simulated bench (mock_lab) is
    /// started in-process on 127.0.0.1.
    #[arg(long, value_name = "FILE")]
    pub bench: Option<PathBuf>,
    #[arg(long, value_enum, default_value = "msk-lfm")]
    pub waveform: WaveformKind,
    /// Range processing: correlation (default for MSK-LFM), fourier (default for OFDM), music,
    /// root-music or esprit (OFDM).
    #[arg(long, value_enum)]
    pub algorithm: Option<Algorithm>,
    /// Subtract this earlier capture (its .sigmf-meta) before processing, e.g. an empty scene.
    #[arg(long, value_name = "FILE")]
    pub background: Option<PathBuf>,
    /// Output folder (default runs/<UTC time>-<waveform>).
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Explicit permit to switch on the AWG outputs and the Tx/Rx front ends for this capture.
    #[arg(long)]
    pub allow_rf: bool,
    /// Leave the transmitter off (noise-floor and leakage checks); needs --allow-rf for the rest.
    #[arg(long)]
    pub tx_off: bool,
    /// Print one JSON object instead of the text report.
    #[arg(long)]
    pub json: bool,
    /// Text to send in the waveform (default: PRBS bits).
    #[arg(long, value_name = "TEXT")]
    pub payload: Option<String>,
    /// Seed of the PRBS bits when no payload is given.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// MUSIC sub-vector length M.
    #[arg(long = "m", default_value_t = 64)]
    pub music_m: usize,
    /// Number of targets for MUSIC/root-MUSIC/ESPRIT (default: estimated by MDL).
    #[arg(long = "p")]
    pub music_p: Option<usize>,
    /// OFDM Fourier zero-padding factor.
    #[arg(long, default_value_t = 10)]
    pub zero_pad: usize,
    #[arg(long, value_enum, default_value = "rect")]
    pub window: WindowName,
    /// Precision of the OFDM receiver's per-symbol FFT (the rest is double precision).
    #[arg(long, value_enum, value_name = "P", default_value = "single")]
    pub fft_precision: FftPrecisionName,
    /// Ignore detections closer than this (the Tx -> Rx leakage sits near 0 m), metres.
    #[arg(long, default_value_t = 0.15)]
    pub min_range: f64,
    /// Ignore detections farther than this, metres.
    #[arg(long, default_value_t = 10.0)]
    pub max_range: f64,
    /// Longest wait for the marker-triggered acquisition, seconds.
    #[arg(long, default_value_t = 10.0)]
    pub wait: f64,
    /// Built-in mock lab only: its scene file (see examples/scene.toml).
    #[arg(long, value_name = "FILE")]
    pub scene: Option<PathBuf>,
    /// Built-in mock lab only: transport to the AWG.
    #[arg(long, value_enum, default_value = "hislip")]
    pub awg_transport: AwgTransport,
    /// Built-in mock lab only: transport to the scope.
    #[arg(long, value_enum, default_value = "vicp")]
    pub scope_transport: ScopeTransport,
}

#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum AwgTransport {
    Raw,
    Hislip,
    Vxi11,
}

#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum ScopeTransport {
    Vicp,
    Vxi11,
}

/// The bench a command runs on: a bench file, or a built-in lab kept alive for the command.
pub struct BenchInUse {
    pub file: BenchFile,
    pub path: Option<PathBuf>,
    pub lab: Option<Lab>,
}

impl BenchInUse {
    /// Opens the bench file, or starts the built-in mock lab (must run inside the runtime).
    pub async fn open(
        bench: Option<&Path>,
        scene: Option<&Path>,
        awg: AwgTransport,
        scope: ScopeTransport,
        quiet: bool,
    ) -> anyhow::Result<BenchInUse> {
        if let Some(path) = bench {
            if scene.is_some() {
                return Err(bad_input(
                    "--scene applies to the built-in mock lab only: with --bench, change the \
                     scene through the lab's control channel",
                ));
            }
            return Ok(BenchInUse {
                file: BenchFile::load(path)?,
                path: Some(path.to_path_buf()),
                lab: None,
            });
        }
        let scene = match scene {
            Some(p) => super::mock_lab::load_scene(p)?,
            None => mock_lab::scene::Scene::default(),
        };
        let nominal_delay = scene.system_delay_s;
        let scope_remote = match scope {
            ScopeTransport::Vicp => mock_lab::emulator::lecroy::RemoteInterface::Vicp,
            ScopeTransport::Vxi11 => mock_lab::emulator::lecroy::RemoteInterface::Vxi11,
        };
        let lab = mock_lab::lab::start(LabOptions {
            scene,
            scope_remote,
            ..LabOptions::default()
        })
        .await
        .context("cannot start the built-in mock lab")?;
        let awg_t = match awg {
            AwgTransport::Raw => Transport::Raw,
            AwgTransport::Hislip => Transport::Hislip,
            AwgTransport::Vxi11 => Transport::Vxi11,
        };
        let scope_t = match scope {
            ScopeTransport::Vicp => Transport::Vicp,
            ScopeTransport::Vxi11 => Transport::Vxi11,
        };
        let mut file = BenchFile::parse(
            &lab.bench_toml(awg_t, scope_t),
            Path::new("<built-in mock lab>"),
        )?;
        // The simulated bench's cables are known exactly: its nominal delay is its calibration.
        file.calibration = Some(Calibration {
            system_delay_s: nominal_delay,
            reference_range_m: None,
            measured_at: None,
        });
        if !quiet {
            eprintln!(
                "no --bench file: using the built-in mock lab (a simulated bench on 127.0.0.1; \
                 AWG over {awg:?}, scope over {scope:?}, system delay {:.3} ns)",
                nominal_delay * 1e9
            );
        }
        Ok(BenchInUse {
            file,
            path: None,
            lab: Some(lab),
        })
    }

    /// The simulated scene of the last capture (ground truth), when the bench is simulated.
    pub async fn ground_truth(&self) -> Option<Value> {
        if let Some(lab) = &self.lab {
            let (_, scene) = lab.bench.scene.last_capture();
            return scene.and_then(|s| serde_json::to_value(s).ok());
        }
        let control = self.file.simulation.as_ref()?.control.clone();
        query_control(&control, r#"{"cmd":"last_capture"}"#)
            .await
            .and_then(|v| v.get("scene").cloned())
    }
}

/// One request on mock_lab's control channel (bounded by a timeout; `None` on any failure).
pub async fn query_control(address: &str, request: &str) -> Option<Value> {
    use tokio::io::{AsyncBufReadExt, AsyncWriteExt, BufReader};
    let work = async {
        let stream = tokio::net::TcpStream::connect(address).await.ok()?;
        let (rd, mut wr) = stream.into_split();
        wr.write_all(format!("{request}\n").as_bytes()).await.ok()?;
        let mut line = String::new();
        BufReader::new(rd).read_line(&mut line).await.ok()?;
        serde_json::from_str::<Value>(&line).ok()
    };
    tokio::time::timeout(std::time::Duration::from_secs(5), work)
        .await
        .ok()
        .flatten()
}

/// The processing options of these arguments.
fn process_options(args: &Args, system_delay_s: f64) -> anyhow::Result<ProcessOptions> {
    let algorithm = args.algorithm.unwrap_or(match args.waveform {
        WaveformKind::MskLfm => Algorithm::Correlation,
        WaveformKind::Ofdm => Algorithm::Fourier,
    });
    if args.waveform == WaveformKind::MskLfm && algorithm != Algorithm::Correlation {
        return Err(bad_input(format!(
            "--algorithm {}: MSK-LFM is processed by correlation; fourier, music, root-music and \
             esprit need --waveform ofdm",
            algorithm.name()
        )));
    }
    if !(args.min_range.is_finite()
        && args.max_range.is_finite()
        && args.min_range < args.max_range)
    {
        return Err(bad_input(format!(
            "--min-range {} / --max-range {}: give finite ranges with min below max",
            args.min_range, args.max_range
        )));
    }
    if !(args.wait.is_finite() && args.wait > 0.0 && args.wait <= 3600.0) {
        return Err(bad_input(format!(
            "--wait {}: allowed 0 < seconds <= 3600",
            args.wait
        )));
    }
    Ok(ProcessOptions {
        algorithm,
        music_m: args.music_m,
        music_p: args.music_p,
        zero_pad: args.zero_pad,
        window: args.window,
        fft_precision: args.fft_precision,
        system_delay_s,
        min_range_m: args.min_range,
        max_range_m: args.max_range,
        ..ProcessOptions::default()
    })
}

/// Capture settings from a bench file.
pub fn capture_settings(
    file: &BenchFile,
    permit: Option<RfPermit>,
    tx_off: bool,
    wait_s: f64,
) -> CaptureSettings {
    let vdiv = file.scope.volts_per_div.unwrap_or(0.05);
    let awg = AwgSettings::default();
    CaptureSettings {
        scope: DigitizerSettings {
            sample_rate_hz: 80e9,
            longest_echo_s: 0.0,
            pre_trigger_s: 0.0,
            i_volts_per_div: vdiv,
            q_volts_per_div: vdiv,
            trigger_level_v: awg.marker_offset_v,
            ..DigitizerSettings::default()
        },
        awg,
        tx: RfSettings {
            attenuation_db: file
                .tx
                .as_ref()
                .and_then(|t| t.attenuation_db)
                .unwrap_or(0.0),
            lo_frequency_hz: None,
        },
        rx: RfSettings {
            attenuation_db: file
                .rx
                .as_ref()
                .and_then(|t| t.attenuation_db)
                .unwrap_or(0.0),
            lo_frequency_hz: None,
        },
        permit,
        tx_off,
        wait_s,
    }
}

/// A finished capture, processed.
pub struct Measurement {
    pub tx: Transmission,
    pub captured: Captured,
    pub processed: Processed,
    pub identities: Identities,
    pub ground_truth: Option<Value>,
    pub period: usize,
}

/// Runs one capture and processes it (shared by `capture` and `calibrate`).
pub async fn measure(
    bench: &BenchInUse,
    tx: Transmission,
    settings: CaptureSettings,
    options: &ProcessOptions,
    background: Option<&Path>,
    global: &super::Global,
) -> anyhow::Result<Measurement> {
    let catalog = Catalog::embedded()?;
    let journal = match &global.trace_io {
        Some(p) => Some(crate::transport::Journal::create(p, false)?),
        None => None,
    };
    let mut connected = run::connect(&bench.file, &catalog, journal).await?;
    crate::driver::install_panic_hook(connected.safe.clone());
    let (result, report) =
        run::capture(&mut connected, &tx, &settings, tokio::signal::ctrl_c()).await;
    if !report.is_safe() {
        eprintln!(
            "WARNING: the safe state did not complete: {report}; switch the bench off by hand"
        );
    }
    let captured = result?;
    let period = captured.applied.segment.padded_samples as usize;
    let raw = captured.raw();
    let (aligned, residual) = process::align(&raw, &tx, period)?;
    let bg = match background {
        Some(path) => {
            let raw_bg = load_background(path)?;
            Some(process::align(&raw_bg, &tx, period)?.0)
        }
        None => None,
    };
    let options = ProcessOptions {
        awg_amplitude_vpp: captured.applied.awg.i_amplitude_vpp,
        ..options.clone()
    };
    let processed = process::process(aligned, residual, bg.as_deref(), &tx, period, &options)?;
    let ground_truth = bench.ground_truth().await;
    Ok(Measurement {
        identities: connected.identities.clone(),
        tx,
        captured,
        processed,
        ground_truth,
        period,
    })
}

/// Reads a capture radbench wrote as SigMF (its `.sigmf-meta` or the base path).
pub fn load_background(path: &Path) -> anyhow::Result<RawIq> {
    let text = path.to_string_lossy();
    let base = text
        .strip_suffix(".sigmf-meta")
        .or_else(|| text.strip_suffix(".sigmf-data"))
        .unwrap_or(&text)
        .to_string();
    let meta_path = PathBuf::from(format!("{base}.sigmf-meta"));
    let data_path = PathBuf::from(format!("{base}.sigmf-data"));
    let meta: Value = serde_json::from_slice(
        &std::fs::read(&meta_path)
            .map_err(|e| bad_input(format!("--background {}: {e}", meta_path.display())))?,
    )
    .map_err(|e| {
        bad_input(format!(
            "--background {}: not JSON: {e}",
            meta_path.display()
        ))
    })?;
    let g = &meta["global"];
    let field = |k: &str| -> anyhow::Result<&Value> {
        g.get(k).ok_or_else(|| {
            bad_input(format!(
                "--background {}: no `{k}`: give a capture written by radbench capture",
                meta_path.display()
            ))
        })
    };
    if field("core:datatype")?.as_str() != Some("ci16_le") {
        return Err(bad_input(format!(
            "--background {}: core:datatype must be ci16_le (radbench's raw scope words)",
            meta_path.display()
        )));
    }
    let rate = field("core:sample_rate")?.as_f64().unwrap_or(0.0);
    let pair = |k: &str| -> anyhow::Result<[f64; 2]> {
        let v = field(k)?;
        Ok([
            v[0].as_f64().unwrap_or(f64::NAN),
            v[1].as_f64().unwrap_or(f64::NAN),
        ])
    };
    let gain = pair("radbench:vertical_gain")?;
    let offset = pair("radbench:vertical_offset")?;
    let first = field("radbench:trigger_offset_s")?.as_f64().unwrap_or(0.0);
    let bytes = std::fs::read(&data_path)
        .map_err(|e| bad_input(format!("--background {}: {e}", data_path.display())))?;
    let samples = bytes
        .chunks_exact(4)
        .map(|c| {
            let i = f64::from(i16::from_le_bytes([c[0], c[1]]));
            let q = f64::from(i16::from_le_bytes([c[2], c[3]]));
            Complex64::new(gain[0] * i - offset[0], gain[1] * q - offset[1])
        })
        .collect();
    Ok(RawIq {
        samples,
        sample_rate_hz: rate,
        first_point_s: first,
    })
}

pub fn run(args: Args, global: &super::Global) -> anyhow::Result<()> {
    let runtime = super::runtime()?;
    runtime.block_on(run_async(args, global))
}

async fn run_async(args: Args, global: &super::Global) -> anyhow::Result<()> {
    let bench = BenchInUse::open(
        args.bench.as_deref(),
        args.scene.as_deref(),
        args.awg_transport,
        args.scope_transport,
        false,
    )
    .await?;
    let options = process_options(&args, bench.file.system_delay_s())?;
    if bench.file.calibration.is_none() {
        eprintln!(
            "note: the bench file has no [calibration]: ranges include the fixed system delay; \
             run `radbench calibrate --reference-range METRES --bench FILE` first"
        );
    }
    if !args.allow_rf {
        return Err(bad_input(
            "the AWG outputs and the front ends stay off without an explicit permit: pass \
             --allow-rf to switch them on for this capture (they are switched off again at the end)",
        ));
    }
    let tx = Transmission::new(
        args.waveform,
        args.payload.as_deref().map(str::as_bytes),
        args.seed,
        DEFAULT_BACKOFF_DB,
    )?;
    let settings = capture_settings(
        &bench.file,
        Some(RfPermit::granted_by_user()),
        args.tx_off,
        args.wait,
    );
    let m = measure(
        &bench,
        tx,
        settings,
        &options,
        args.background.as_deref(),
        global,
    )
    .await?;
    let out = args.out.clone().unwrap_or_else(|| {
        let stamp = sigmf::utc_now_rfc3339()
            .replace([':', '-'], "")
            .replace(".", "_");
        PathBuf::from("runs").join(format!("{stamp}-{}", args.waveform.name()))
    });
    let files = write_outputs(&out, &m, &options, &bench)?;
    let summary = summary_json(&m, &options, &files, &bench);
    crate::storage::atomic::write_atomic(
        &out.join("summary.json"),
        format!("{:#}\n", summary).as_bytes(),
    )?;
    if args.json {
        println!("{summary}");
    } else {
        print_report(&m, &options, &out);
    }
    Ok(())
}

fn summary_json(m: &Measurement, o: &ProcessOptions, files: &Value, bench: &BenchInUse) -> Value {
    let p = &m.processed;
    json!({
        "waveform": m.tx.kind.name(),
        "algorithm": o.algorithm.name(),
        "targets": p.targets,
        "width_3db_cm": p.width_3db_cm,
        "sidelobe_db": p.sidelobe_db,
        "snr_db": p.snr_db,
        "payload": p.payload,
        "warnings": p.warnings,
        "system_delay_s": o.system_delay_s,
        "processing": o,
        "radbench_version": env!("CARGO_PKG_VERSION"),
        "simulated": bench.lab.is_some() || bench.file.simulation.is_some(),
        "scene": m.ground_truth,
        "instruments": m.identities,
        "applied": m.captured.applied,
        "transmission": m.tx.describe(),
        "files": files,
    })
}

fn write_outputs(
    out: &Path,
    m: &Measurement,
    o: &ProcessOptions,
    bench: &BenchInUse,
) -> anyhow::Result<Value> {
    std::fs::create_dir_all(out)
        .with_context(|| format!("cannot create the output folder {}", out.display()))?;
    let i = &m.captured.iq.i;
    let q = &m.captured.iq.q;
    let mut ns = serde_json::Map::new();
    ns.insert(
        "vertical_gain".into(),
        json!([i.desc.vertical_gain, q.desc.vertical_gain]),
    );
    ns.insert(
        "vertical_offset".into(),
        json!([i.desc.vertical_offset, q.desc.vertical_offset]),
    );
    ns.insert("trigger_offset_s".into(), json!(i.first_sample_s()));
    ns.insert("waveform".into(), m.tx.describe());
    ns.insert("instruments".into(), json!(m.identities));
    ns.insert(
        "sample_rates_hz".into(),
        json!({"awg": m.tx.sample_rate_hz, "scope": m.captured.applied.scope.sample_rate_hz, "processing": m.tx.sample_rate_hz}),
    );
    ns.insert("system_delay_s".into(), json!(o.system_delay_s));
    ns.insert("processing".into(), json!(o));
    if let Some(truth) = &m.ground_truth {
        ns.insert("scene".into(), truth.clone());
    }
    if let Some(path) = &bench.path {
        ns.insert("bench_file".into(), json!(path.display().to_string()));
    }
    let meta = SigmfMeta {
        sample_rate: m.captured.applied.scope.sample_rate_hz,
        frequency_hz: m
            .ground_truth
            .as_ref()
            .and_then(|s| s["carrier_hz"].as_f64())
            .unwrap_or(80e9),
        datetime: sigmf::utc_now_rfc3339(),
        description: format!(
            "radbench capture: {} at the scope (I on C1, Q on C2), raw 16-bit words",
            m.tx.kind.name()
        ),
        hw: m.identities.scope.clone(),
        radbench: ns,
        annotations: Vec::new(),
    };
    let words = |t: &crate::driver::Trace| t.codes.clone();
    let sig = sigmf::write_ci16(&out.join("capture"), &words(i), &words(q), &meta)?;
    crate::storage::atomic::write_atomic(&out.join("C1.trc"), &i.trc_bytes())?;
    crate::storage::atomic::write_atomic(&out.join("C2.trc"), &q.trc_bytes())?;
    let p = &m.processed;
    let primary = &p.profiles[0];
    let table = ProfileTable {
        range_m: primary.ranges(),
        columns: p
            .profiles
            .iter()
            .filter(|x| x.axis == primary.axis && x.amplitude.len() == primary.amplitude.len())
            .map(|x| {
                let name = x
                    .label
                    .split(' ')
                    .next()
                    .unwrap_or("profile")
                    .to_lowercase();
                (
                    format!("{name}_db"),
                    x.amplitude
                        .iter()
                        .map(|a| 20.0 * a.max(1e-300).log10())
                        .collect(),
                )
            })
            .collect(),
    };
    table.write(&out.join("profile.csv"))?;
    table.write(&out.join("profile.npy"))?;
    let targets: Vec<f64> = m
        .ground_truth
        .as_ref()
        .and_then(|s| s["targets"].as_array().cloned())
        .map(|t| t.iter().filter_map(|x| x["range_m"].as_f64()).collect())
        .unwrap_or_default();
    let plot = ProfilePlot {
        title: format!(
            "radbench capture: {} {}",
            m.tx.kind.name(),
            o.algorithm.name()
        ),
        curves: p
            .profiles
            .iter()
            .map(|x| Curve {
                label: x.label.clone(),
                range_m: x.ranges(),
                db: x.normalised_db(),
            })
            .collect(),
        targets_m: targets,
        window_m: Some((
            o.min_range_m.max(0.0) - 0.2,
            o.max_range_m
                .min(p.targets.iter().map(|t| t.range_m).fold(1.0, f64::max) + 1.0),
        )),
        floor_db: -60.0,
        reference_db: None,
    };
    plot::draw(&out.join("profile.svg"), &plot)?;
    plot::draw(&out.join("profile.png"), &plot)?;
    Ok(json!({
        "dir": out.display().to_string(),
        "sigmf_meta": sig.meta.display().to_string(),
        "sigmf_data": sig.data.display().to_string(),
        "trc": [out.join("C1.trc").display().to_string(), out.join("C2.trc").display().to_string()],
        "profile_csv": out.join("profile.csv").display().to_string(),
        "profile_npy": out.join("profile.npy").display().to_string(),
        "plot_svg": out.join("profile.svg").display().to_string(),
        "plot_png": out.join("profile.png").display().to_string(),
        "summary": out.join("summary.json").display().to_string(),
    }))
}

fn print_report(m: &Measurement, o: &ProcessOptions, out: &Path) {
    let p = &m.processed;
    println!(
        "{} capture, {} processing, {} samples per repetition at {} GSa/s",
        m.tx.kind.name(),
        o.algorithm.name(),
        m.period,
        m.tx.sample_rate_hz / 1e9
    );
    if p.targets.is_empty() {
        println!("targets: none");
    } else {
        println!("targets:");
        for t in &p.targets {
            println!("  {:>9.4} m   {:>6.1} dB", t.range_m, t.level_db);
        }
    }
    let opt = |v: Option<f64>, unit: &str| v.map_or("-".to_string(), |x| format!("{x:.2} {unit}"));
    println!("-3 dB width: {}", opt(p.width_3db_cm, "cm"));
    println!("peak side-lobe: {}", opt(p.sidelobe_db, "dB"));
    println!("SNR (profile peak over median): {}", opt(p.snr_db, "dB"));
    if let Some(pl) = &p.payload {
        match (&pl.text, &pl.error) {
            (Some(t), _) => println!(
                "payload: {t:?} ({} bit errors in {})",
                pl.bit_errors, pl.bits
            ),
            (None, Some(e)) => println!("payload: not decoded: {e}"),
            (None, None) => println!(
                "data bits: {} errors in {} (BER {:.2e})",
                pl.bit_errors, pl.bits, pl.ber
            ),
        }
    }
    if let Some(truth) = &m.ground_truth {
        let ranges: Vec<String> = truth["targets"]
            .as_array()
            .map(|t| {
                t.iter()
                    .filter_map(|x| x["range_m"].as_f64())
                    .map(|r| format!("{r:.4} m"))
                    .collect()
            })
            .unwrap_or_default();
        println!("simulated scene (ground truth): {}", ranges.join(", "));
    }
    for w in &p.warnings {
        println!("warning: {w}");
    }
    println!("files: {}", out.display());
}
