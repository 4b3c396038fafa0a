//! A measurement's files: the raw capture (SigMF and the scope's `.trc`), the range profiles (CSV,
//! npy), plots and `summary.json`, every one written atomically into one folder. In what order
//! and on which thread a capture's are written is the recorder's (`recorder::Recorder`).

use crate::measure::capture::{Measurement, Taken};
use crate::measure::error::MeasureError;
use crate::measure::processing::options::ProcessOptions;
use crate::measure::processing::pipeline::Processed;
use crate::measure::processing::transmit::Transmission;
use crate::storage::atomic::{write_atomic, write_atomic_parts};
use crate::storage::plot;
use crate::storage::sigmf::{self, SigmfMeta};
use crate::storage::StorageError;
use serde::Serialize;
use serde_json::{json, Value};
use std::path::{Path, PathBuf};

/// Where the files of one capture went.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub(crate) struct CaptureFiles {
    pub(crate) dir: PathBuf,
    pub(crate) sigmf_meta: PathBuf,
    pub(crate) sigmf_data: PathBuf,
    /// The scope's own files of the first acquisition (`C1.trc`, `C2.trc` from a LeCroy); the
    /// JSON name stays `trc` for scripts written before other scopes.
    #[serde(rename = "trc")]
    pub(crate) native: Vec<PathBuf>,
    #[serde(flatten)]
    pub(crate) profiles: ProfileFiles,
    pub(crate) summary: PathBuf,
}

/// The files of one processing of a capture: the range profiles and their plots.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct ProfileFiles {
    pub profile_csv: PathBuf,
    pub profile_npy: PathBuf,
    pub plot_svg: PathBuf,
    pub plot_png: PathBuf,
    /// The range-Doppler map (OFDM frames of two symbols or more).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub range_doppler_png: Option<PathBuf>,
    /// The link's plot: constellation, and channel estimate (OFDM) or phase trajectory
    /// (MSK-LFM), when data was decoded.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub link_svg: Option<PathBuf>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub link_png: Option<PathBuf>,
}

/// Which of a measurement's files are written, by file name: a campaign's `[output]` drops
/// some (the `.trc` copy, the bitmaps, the link plots), which are then never written (not
/// written and removed: a night run's disk never holds them). `summary.json` still names them.
pub(crate) type Keep<'a> = &'a dyn Fn(&str) -> bool;

/// Every file written (a lone capture, a re-processing).
pub(crate) fn keep_all(_: &str) -> bool {
    true
}

/// Writes the profiles of `processed` into `out` (CSV, npy, SVG and PNG plots, the
/// range-Doppler map when there is one, the link figure when data was decoded: `link.svg`, and
/// `link.png` when `link_png`), titled `"{program}: {waveform} {algorithm}"`, the scene's targets
/// drawn when `scene` (a simulated bench's ground truth) names them. `beside`: the link figure is
/// drawn on a thread of its own while the profiles are written (a one-shot capture, whose
/// second core is free by then), its files put in place before this returns.
#[allow(clippy::too_many_arguments)]
fn write_profiles(
    out: &Path,
    program: &str,
    tx: &Transmission,
    processed: &Processed,
    o: &ProcessOptions,
    scene: Option<&Value>,
    link_png: bool,
    beside: bool,
    keep: Keep<'_>,
) -> Result<ProfileFiles, MeasureError> {
    let mut files = ProfileFiles {
        profile_csv: out.join("profile.csv"),
        profile_npy: out.join("profile.npy"),
        plot_svg: out.join("profile.svg"),
        plot_png: out.join("profile.png"),
        range_doppler_png: processed
            .range_doppler
            .as_ref()
            .map(|_| out.join("range_doppler.png")),
        link_svg: None,
        link_png: None,
    };
    let link = processed
        .payload
        .as_ref()
        .and_then(|p| p.trace.as_ref().map(|t| (p, t)))
        .map(|(p, trace)| {
            let figures = match (p.evm_rms_pct, p.mer_db) {
                (Some(e), Some(m)) => format!(": EVM {e:.2} % rms, MER {m:.1} dB"),
                _ => String::new(),
            };
            let fig = trace.figure(format!("{program}: {} link{figures}", tx.name()));
            let svg = out.join("link.svg");
            let png = link_png.then(|| out.join("link.png"));
            files.link_svg = Some(svg.clone());
            files.link_png = png.clone();
            // Files `keep` drops are named (summary.json) but never written.
            let svg = keep("link.svg").then_some(svg);
            let png = png.filter(|_| keep("link.png"));
            move || -> Result<(), MeasureError> {
                if let Some(svg) = svg {
                    plot::link::draw_link(&svg, &fig)?;
                }
                if let Some(png) = png {
                    plot::link::draw_link(&png, &fig)?;
                }
                Ok(())
            }
        });
    let profiles = || -> Result<(), MeasureError> {
        let truth: Vec<f64> = scene
            .and_then(|s| s["targets"].as_array())
            .map(|t| t.iter().filter_map(|x| x["range_m"].as_f64()).collect())
            .unwrap_or_default();
        let (plot, table) = super::figure::profile_figure(
            format!("{program}: {} {}", tx.name(), o.algorithm.name()),
            processed,
            o,
            truth,
        );
        table.write(&files.profile_csv)?;
        table.write(&files.profile_npy)?;
        if keep("profile.svg") {
            plot::draw(&files.plot_svg, &plot)?;
        }
        if keep("profile.png") {
            plot::draw(&files.plot_png, &plot)?;
        }
        let rd = files
            .range_doppler_png
            .as_ref()
            .filter(|_| keep("range_doppler.png"));
        if let (Some(map), Some(path)) = (&processed.range_doppler, rd) {
            let fig = super::figure::range_doppler_figure(
                format!("{program}: {} range-Doppler", tx.name()),
                map,
                &processed.targets,
                o,
            );
            plot::draw_heatmap(path, &fig)?;
        }
        Ok(())
    };
    match link {
        Some(link) if beside => {
            let (drawn, written) = std::thread::scope(|scope| {
                // A group of its own on its thread (groups are per thread), ended below.
                let drawn = scope.spawn(|| crate::storage::atomic::write_group_open(link));
                let written = profiles();
                (drawn.join(), written)
            });
            let (_, group) = drawn
                .map_err(|_| MeasureError::Worker("drawing the link figure panicked".into()))??;
            group.finish()?;
            written?;
        }
        Some(link) => {
            link()?;
            profiles()?;
        }
        None => profiles()?,
    }
    Ok(files)
}

/// The summary keys a capture and a re-processing share: what was sent, how it was processed
/// and what was found. Each adds its own after them.
pub(crate) fn result_json(
    tx: &Transmission,
    p: &Processed,
    o: &ProcessOptions,
) -> serde_json::Map<String, Value> {
    let Value::Object(map) = json!({
        "waveform": tx.name(),
        "algorithm": o.algorithm.name(),
        "targets": p.targets,
        "chain_echoes": p.detection.chain_echoes,
        "width_3db_cm": p.width_3db_cm,
        "sidelobe_db": p.sidelobe_db,
        "snr_db": p.snr_db,
        "peak_to_floor_db": p.peak_to_floor_db,
        "losses_db": p.losses_db,
        "velocity_resolution_mps": p.detection.velocity_resolution_mps,
        "payload": p.payload,
        "clipped_samples": p.clipping,
    }) else {
        unreachable!("a JSON object literal")
    };
    map
}

/// `base` with `more`'s keys after its own.
fn extended(mut base: serde_json::Map<String, Value>, more: Value) -> Value {
    if let Value::Object(more) = more {
        base.extend(more);
    }
    Value::Object(base)
}

/// Where the bench came from, for the files.
#[derive(Debug, Clone, Default)]
pub struct Provenance {
    pub bench_file: Option<PathBuf>,
    pub simulated: bool,
}

/// Where the raw capture of one measurement went.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub(crate) struct RawFiles {
    pub(crate) sigmf_meta: PathBuf,
    pub(crate) sigmf_data: PathBuf,
    #[serde(rename = "trc")]
    pub(crate) native: Vec<PathBuf>,
}

fn create_dir(out: &Path) -> Result<(), MeasureError> {
    std::fs::create_dir_all(out).map_err(|source| StorageError::Io {
        path: out.to_path_buf(),
        source,
    })?;
    // Temporary files a killed run left behind go first.
    crate::storage::atomic::remove_stale_temporaries(out)?;
    Ok(())
}

/// Writes the raw capture of `taken` into `out`: SigMF (every repetition) and the scope's `.trc`,
/// those `keep` keeps (the SigMF recording always). `options`: those the capture is processed
/// with (`Prepared::options_for`).
pub(crate) fn write_raw(
    out: &Path,
    taken: &Taken,
    options: &ProcessOptions,
    provenance: &Provenance,
    keep: Keep<'_>,
) -> Result<RawFiles, MeasureError> {
    create_dir(out)?;
    let captured = &taken.captured;
    let first = captured.first();
    let (i, q) = (&first.i, &first.q);
    let o = options;
    let mut ns = serde_json::Map::new();
    ns.insert(
        "vertical_gain".into(),
        json!([i.volts_per_code, q.volts_per_code]),
    );
    ns.insert("vertical_offset".into(), json!([i.offset_v, q.offset_v]));
    ns.insert("trigger_offset_s".into(), json!(i.first_sample_s()));
    // Several repetitions follow each other in the data; each keeps its own trigger offset, and
    // in sequence mode the acquisition, segment and trigger time it came from.
    let mut start = 0u64;
    let mut reps = Vec::new();
    let mut annotations = Vec::new();
    let (mut i_words, mut q_words) = (Vec::new(), Vec::new());
    let adc = taken.plan.scope_adc();
    for k in 0..captured.repetitions() {
        let words = captured.raw_words(k);
        let at = captured.source(k);
        let n = words.i.len() as u64;
        let clipped = words.clipping(&adc).count;
        reps.push(json!({
            "sample_start": start,
            "sample_count": n,
            "trigger_offset_s": at.timing.first_sample_s,
            "trigger_time_s": at.timing.trigger_time_s,
            "acquisition": at.acquisition,
            "segment": at.segment,
            "vertical_gain": words.gain,
            "vertical_offset": words.offset,
            "clipped_samples": {"i": clipped.i, "q": clipped.q},
        }));
        if captured.repetitions() > 1 {
            annotations.push((start, n, format!("repetition {}", k + 1)));
        }
        i_words.extend_from_slice(&words.i);
        q_words.extend_from_slice(&words.q);
        start += n;
    }
    ns.insert("repetitions".into(), json!(reps));
    // Where the ADC's rails are and the vertical scale, so `process` counts clipping as capture
    // did and gives the same advice.
    ns.insert(
        "adc".into(),
        json!({
            "bits": adc.rails.bits(),
            "volts_per_div": adc.volts_per_div,
            "volts_per_div_max": adc.volts_per_div_max,
        }),
    );
    ns.insert("waveform".into(), taken.tx.describe());
    ns.insert("instruments".into(), json!(taken.identities));
    ns.insert(
        "sample_rates_hz".into(),
        json!({"awg": taken.tx.sample_rate_hz(), "scope": taken.captured.applied.scope.sample_rate_hz, "processing": taken.tx.sample_rate_hz()}),
    );
    ns.insert("system_delay_s".into(), json!(o.system_delay_s));
    // One repetition at the waveform rate after the AWG's padding: the record's period.
    ns.insert("period_samples".into(), json!(taken.plan.period));
    if let Some(bg) = &taken.background {
        ns.insert("background".into(), json!(bg));
    }
    ns.insert("processing".into(), json!(o));
    if let Some(truth) = &taken.ground_truth {
        ns.insert("scene".into(), truth.clone());
    }
    if let Some(path) = &provenance.bench_file {
        ns.insert("bench_file".into(), json!(path.display().to_string()));
    }
    let meta = SigmfMeta {
        sample_rate: taken.captured.applied.scope.sample_rate_hz,
        frequency_hz: taken
            .ground_truth
            .as_ref()
            .and_then(|s| s["carrier_hz"].as_f64())
            .unwrap_or(80e9),
        datetime: sigmf::utc_now_rfc3339(),
        description: format!(
            "radbench capture: {} at the scope (I on channel {}, Q on channel {}), raw 16-bit words",
            taken.tx.name(),
            i.channel,
            q.channel
        ),
        hw: taken.identities.scope.clone(),
        radbench: ns,
        annotations,
    };
    let sig = sigmf::write_ci16(&out.join("capture"), &i_words, &q_words, &meta)?;
    let mut native = Vec::new();
    for trace in [i, q] {
        if let Some(file) = &trace.native {
            let name = format!("C{}.{}", trace.channel, file.extension);
            let path = out.join(&name);
            if keep(&name) {
                write_atomic_parts(&path, &[&file.header, &file.body])?;
            }
            native.push(path);
        }
    }
    Ok(RawFiles {
        sigmf_meta: sig.meta,
        sigmf_data: sig.data,
        native,
    })
}

/// Writes what the processing of `m` gave into `out`: the range profiles (CSV, npy), plots and
/// `summary.json` (last), which names `raw` as the capture; only the files `keep` keeps
/// (`summary.json` always). Every file is written on the calling thread (in its write group, if
/// any), but for the link figure when `beside`: drawn on a thread of its own (in a write group of
/// its own, ended before `summary.json` is written) while the profiles are written, for a
/// one-shot capture whose second core is free by then.
pub(crate) fn write_processed(
    out: &Path,
    m: &Measurement,
    raw: &RawFiles,
    provenance: &Provenance,
    beside: bool,
    keep: Keep<'_>,
) -> Result<(CaptureFiles, Value), MeasureError> {
    create_dir(out)?;
    let profiles = write_profiles(
        out,
        "radbench capture",
        &m.taken.tx,
        &m.processing.processed,
        &m.processing.options,
        m.taken.ground_truth.as_ref(),
        true,
        beside,
        keep,
    )?;
    let files = CaptureFiles {
        dir: out.to_path_buf(),
        sigmf_meta: raw.sigmf_meta.clone(),
        sigmf_data: raw.sigmf_data.clone(),
        native: raw.native.clone(),
        profiles,
        summary: out.join("summary.json"),
    };
    let summary = summary_json(m, &files, provenance);
    write_atomic(&files.summary, format!("{summary:#}\n").as_bytes())?;
    Ok((files, summary))
}

/// What `capture --json` prints and `summary.json` holds (docs/capture.md, "--json").
pub(crate) fn summary_json(
    m: &Measurement,
    files: &CaptureFiles,
    provenance: &Provenance,
) -> Value {
    let mut summary = capture_summary(m, provenance);
    summary["files"] = json!(files);
    summary
}

/// [`summary_json`] of a capture whose files were not written (no `files` key): what a warm
/// session returns when it writes nothing.
pub(crate) fn capture_summary(m: &Measurement, provenance: &Provenance) -> Value {
    let p = &m.processing.processed;
    let o = &m.processing.options;
    extended(
        result_json(&m.taken.tx, p, o),
        json!({
            "repetitions": m.taken.captured.repetitions(),
            "background": m.taken.background,
            "spread": m.processing.spread,
            "each_repetition": m.processing.repetitions,
            "warnings": p.warnings,
            "system_delay_s": o.system_delay_s,
            "processing": o,
            "radbench_version": env!("CARGO_PKG_VERSION"),
            "simulated": provenance.simulated,
            "scene": m.taken.ground_truth,
            "instruments": m.taken.identities,
            "applied": m.taken.captured.applied,
            "transmission": m.taken.tx.describe(),
        }),
    )
}

/// Where the files of one re-processed capture went.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct ReprocessFiles {
    pub dir: PathBuf,
    pub manifest: PathBuf,
    #[serde(flatten)]
    pub profiles: ProfileFiles,
    pub summary: PathBuf,
}

/// A source file of a re-processing, with its SHA-256.
#[derive(Debug, Clone, Serialize, serde::Deserialize, PartialEq)]
pub struct SourceFile {
    pub path: PathBuf,
    pub sha256: String,
}

#[derive(Serialize)]
struct ReprocessManifest<'a> {
    radbench_version: &'a str,
    /// None in a folder addressed by content (its bytes depend on its inputs alone).
    #[serde(skip_serializing_if = "Option::is_none")]
    written_at: Option<String>,
    /// What was read (never written to).
    sources: &'a [SourceFile],
    processing: &'a crate::measure::processing::options::ProcessOptions,
}

/// Writes a re-processed capture into `out` (a new folder): `manifest.toml` naming the sources
/// with their SHA-256, the profiles, the plots and `summary.json` (same keys as a capture's).
pub fn write_reprocessed<R>(
    out: &Path,
    sources: &[SourceFile],
    loaded: &super::reprocess::Loaded<R>,
    r: &super::reprocess::Reprocessed,
    link_png: bool,
) -> Result<(ReprocessFiles, Value), MeasureError> {
    write_reprocessed_as(out, sources, loaded, r, link_png, false)
}

/// [`write_reprocessed`] for a folder addressed by content (archive processing): its bytes are
/// a function of the sources, the options and radbench's version alone, so the manifest has no
/// write time and the summary names its files relative to the folder (written under a
/// temporary name, then renamed).
pub(crate) fn write_reprocessed_by_content<R>(
    out: &Path,
    sources: &[SourceFile],
    loaded: &super::reprocess::Loaded<R>,
    r: &super::reprocess::Reprocessed,
    link_png: bool,
) -> Result<(ReprocessFiles, Value), MeasureError> {
    write_reprocessed_as(out, sources, loaded, r, link_png, true)
}

fn write_reprocessed_as<R>(
    out: &Path,
    sources: &[SourceFile],
    loaded: &super::reprocess::Loaded<R>,
    r: &super::reprocess::Reprocessed,
    link_png: bool,
    by_content: bool,
) -> Result<(ReprocessFiles, Value), MeasureError> {
    std::fs::create_dir_all(out).map_err(|source| StorageError::Io {
        path: out.to_path_buf(),
        source,
    })?;
    crate::storage::atomic::remove_stale_temporaries(out)?;
    let o = &r.resolved.options;
    let tx = &r.resolved.tx;
    let files = ReprocessFiles {
        dir: out.to_path_buf(),
        manifest: out.join("manifest.toml"),
        profiles: write_profiles(
            out,
            "radbench process",
            tx,
            &r.processed,
            o,
            loaded.ground_truth(),
            link_png,
            false,
            &keep_all,
        )?,
        summary: out.join("summary.json"),
    };
    let manifest = ReprocessManifest {
        radbench_version: env!("CARGO_PKG_VERSION"),
        written_at: (!by_content).then(crate::storage::utc_now_rfc3339),
        sources,
        processing: o,
    };
    let text = toml::to_string(&manifest).map_err(|e| StorageError::BadData {
        path: files.manifest.clone(),
        reason: e.to_string(),
    })?;
    write_atomic(&files.manifest, text.as_bytes())?;
    let mut summary = reprocessed_summary(sources, loaded, r);
    if let Value::Object(map) = &mut summary {
        let mut named = json!(files);
        if by_content {
            relative_to(&mut named, out);
        }
        map.insert("files".into(), named);
    }
    write_atomic(&files.summary, format!("{summary:#}\n").as_bytes())?;
    Ok((files, summary))
}

/// Every path in `v` under `dir`, made relative to it (`dir` itself becomes `.`).
fn relative_to(v: &mut Value, dir: &Path) {
    match v {
        Value::String(s) => {
            if let Ok(rel) = Path::new(s.as_str()).strip_prefix(dir) {
                let rel = rel.to_string_lossy();
                *s = if rel.is_empty() {
                    ".".into()
                } else {
                    rel.into_owned()
                };
            }
        }
        Value::Array(a) => a.iter_mut().for_each(|x| relative_to(x, dir)),
        Value::Object(o) => o.values_mut().for_each(|x| relative_to(x, dir)),
        _ => {}
    }
}

/// The `summary.json` of a re-processed capture but its `files` (what `radbench process` writes
/// and the Python package returns).
pub(crate) fn reprocessed_summary<R>(
    sources: &[SourceFile],
    loaded: &super::reprocess::Loaded<R>,
    r: &super::reprocess::Reprocessed,
) -> Value {
    let o = &r.resolved.options;
    let tx = &r.resolved.tx;
    let p = &r.processed;
    extended(
        result_json(tx, p, o),
        json!({
            "repetitions": loaded.repetitions.len(),
            "background": r.resolved.background,
            "spread": r.spread,
            "each_repetition": r.repetitions,
            "warnings": p.warnings,
            "system_delay_s": o.system_delay_s,
            "processing": o,
            "radbench_version": env!("CARGO_PKG_VERSION"),
            "simulated": loaded.ground_truth().is_some(),
            "scene": loaded.ground_truth(),
            "transmission": tx.describe(),
            "sources": sources,
        }),
    )
}
