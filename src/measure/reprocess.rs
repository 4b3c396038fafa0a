//! Re-processing saved captures, long after the bench is gone: a capture folder, a SigMF
//! recording (radbench's or anyone's) or a pair of LeCroy `.trc` files (I and Q, sequence-mode
//! segments as repetitions) go through the same [`Pipeline`] as a live capture.
//!
//! A radbench capture carries everything needed to process it again exactly as it was (the
//! transmitted waveform and its bits, every processing option, the record's period, the
//! background it subtracted); any of it can be overridden. A capture radbench did not make needs
//! the waveform from the caller.

use super::capture::{process_repetitions, BackgroundFile};
use super::clipping::{ClipCount, Rails, RecordClipping, ScopeAdc};
use super::options::{ProcessOptions, ProcessOverrides};
use super::pipeline::{Aligned, Pipeline, Processed, RawIq, RecordGeometry};
use super::repeat::{RepetitionResult, Spread};
use super::transmit::{self, Dac, Transmission};
use super::MeasureError;
use crate::storage::hash::sha256_file;
use crate::storage::recording::{read_sigmf, read_trc, sigmf_paths, SampleUnit};
use crate::waveform::spec::WaveformSpec;
use serde::Serialize;
use serde_json::{Map, Value};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Where one capture to re-process is.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub(crate) enum Source {
    /// A SigMF recording (its `.sigmf-meta` path).
    Sigmf { meta: PathBuf, data: PathBuf },
    /// LeCroy `.trc` files of I and Q.
    TrcPair { i: PathBuf, q: PathBuf },
}

impl Source {
    /// The files read, for the manifest.
    pub(crate) fn files(&self) -> Vec<&Path> {
        match self {
            Source::Sigmf { meta, data } => vec![meta, data],
            Source::TrcPair { i, q } => vec![i, q],
        }
    }

    /// A short name for folders and messages.
    pub(crate) fn label(&self) -> String {
        let file = match self {
            Source::Sigmf { meta, .. } => meta,
            Source::TrcPair { i, .. } => i,
        };
        let dir = file
            .parent()
            .and_then(|p| p.file_name())
            .map(|n| n.to_string_lossy().into_owned());
        let stem = file
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default()
            .replace(".sigmf-meta", "")
            .replace(".trc", "");
        match dir {
            Some(d) if stem == "capture" || stem == "C1" => d,
            Some(d) => format!("{d}-{stem}"),
            None => stem,
        }
    }
}

/// An input the user named that is not a capture.
#[derive(Debug, thiserror::Error)]
#[error("{path}: {reason}")]
pub(crate) struct InputError {
    pub path: PathBuf,
    pub reason: String,
}

/// The captures the inputs name, in order: a capture folder (its `capture.sigmf-meta`), a run
/// folder of a campaign (every step's capture), a SigMF file, or two `.trc` files given one
/// after the other (I then Q). Each entry is a capture or why an input is not one.
pub(crate) fn discover(inputs: &[PathBuf]) -> Vec<Result<Source, InputError>> {
    let mut out = Vec::new();
    let mut k = 0;
    while k < inputs.len() {
        let path = &inputs[k];
        let bad = |reason: &str| InputError {
            path: path.clone(),
            reason: reason.to_string(),
        };
        let name = path.to_string_lossy().to_lowercase();
        if name.ends_with(".trc") {
            match inputs.get(k + 1) {
                Some(q) if q.to_string_lossy().to_lowercase().ends_with(".trc") => {
                    out.push(Ok(Source::TrcPair {
                        i: path.clone(),
                        q: q.clone(),
                    }));
                    k += 2;
                }
                _ => {
                    out.push(Err(bad(
                        "a .trc file needs its partner: give the I and the Q channel's files one \
                         after the other (C1.trc C2.trc)",
                    )));
                    k += 1;
                }
            }
            continue;
        }
        k += 1;
        if path.is_dir() {
            let capture = path.join("capture.sigmf-meta");
            if capture.is_file() {
                out.push(sigmf(&capture));
                continue;
            }
            // A run folder: its sub-folders' captures, in name order.
            let mut found: Vec<PathBuf> = std::fs::read_dir(path)
                .map(|entries| {
                    entries
                        .filter_map(Result::ok)
                        .map(|e| e.path().join("capture.sigmf-meta"))
                        .filter(|p| p.is_file())
                        .collect()
                })
                .unwrap_or_default();
            found.sort();
            if found.is_empty() {
                out.push(Err(bad(
                    "holds no capture: give a capture folder (with capture.sigmf-meta), a run \
                     folder of such folders, a .sigmf-meta file or a pair of .trc files",
                )));
            }
            out.extend(found.iter().map(|p| sigmf(p)));
        } else if name.ends_with(".sigmf-meta") || name.ends_with(".sigmf-data") {
            out.push(sigmf(path));
        } else if path.exists() {
            out.push(Err(bad(
                "not a capture: give a capture folder, a .sigmf-meta file or a pair of .trc files",
            )));
        } else {
            out.push(Err(bad("no such file or folder")));
        }
    }
    out
}

fn sigmf(path: &Path) -> Result<Source, InputError> {
    sigmf_paths(path)
        .map(|(meta, data)| Source::Sigmf { meta, data })
        .map_err(|e| InputError {
            path: path.to_path_buf(),
            reason: e.to_string(),
        })
}

/// A capture read back: its repetitions in volts and what radbench recorded about it.
#[derive(Debug, Clone)]
pub(crate) struct Loaded {
    pub repetitions: Vec<RawIq>,
    /// Each repetition's samples at the ADC's rails, when the capture holds the scope's codes (a
    /// radbench capture, a `.trc` pair); empty otherwise.
    pub clipping: Vec<Option<RecordClipping>>,
    /// The `radbench:` metadata (empty for a capture radbench did not make).
    pub radbench: Map<String, Value>,
}

impl Loaded {
    fn key(&self, k: &str) -> Option<&Value> {
        self.radbench.get(k)
    }

    /// The processing options the capture was processed with.
    pub(crate) fn recorded_options(&self) -> Option<ProcessOptions> {
        serde_json::from_value(self.key("processing")?.clone()).ok()
    }

    /// The transmission the capture recorded (spec, bits, DAC model).
    pub(crate) fn recorded_transmission(&self) -> Option<Result<Transmission, MeasureError>> {
        transmit::from_description(self.key("waveform")?)
    }

    /// Samples of one repetition at the waveform rate (the AWG's padded segment).
    pub(crate) fn recorded_period(&self) -> Option<usize> {
        self.key("period_samples")?.as_u64().map(|n| n as usize)
    }

    /// The background the capture subtracted.
    pub(crate) fn recorded_background(&self) -> Option<BackgroundFile> {
        serde_json::from_value(self.key("background")?.clone()).ok()
    }

    /// The simulated scene (ground truth) of a simulated bench's capture.
    pub(crate) fn ground_truth(&self) -> Option<&Value> {
        self.key("scene")
    }
}

fn input_error(path: &Path, reason: impl Into<String>) -> MeasureError {
    MeasureError::option("input", path.display(), reason.into())
}

/// Reads a capture: a SigMF recording (repetitions from `radbench:repetitions`, else the whole
/// recording as one) or a `.trc` pair (each sequence segment one repetition).
pub(crate) fn load(source: &Source, trigger_offset_s: Option<f64>) -> Result<Loaded, MeasureError> {
    match source {
        Source::Sigmf { meta, .. } => load_sigmf(meta, trigger_offset_s),
        Source::TrcPair { i, q } => load_trc_pair(i, q, trigger_offset_s),
    }
}

/// A SigMF recording: one repetition, or those its `radbench:repetitions` list names.
fn load_sigmf(meta: &Path, trigger_offset_s: Option<f64>) -> Result<Loaded, MeasureError> {
    let rec = read_sigmf(meta)?;
    let radbench = rec
        .radbench
        .as_ref()
        .map(|r| r.keys.clone())
        .unwrap_or_default();
    let rate = rec.sample_rate_hz.ok_or_else(|| {
        input_error(
            meta,
            "core:sample_rate is missing: the sample rate must be known",
        )
    })?;
    if rec.unit != SampleUnit::Volts {
        tracing::info!(
            "{}: no radbench:vertical_gain/offset, samples in the datatype's own scale",
            meta.display()
        );
    }
    let first = trigger_offset_s
        .or_else(|| rec.radbench.as_ref().and_then(|r| r.trigger_offset_s))
        .unwrap_or(0.0);
    let reps: Vec<(u64, u64, f64)> = radbench
        .get("repetitions")
        .and_then(Value::as_array)
        .map(|a| {
            a.iter()
                .filter_map(|r| {
                    Some((
                        r.get("sample_start")?.as_u64()?,
                        r.get("sample_count")?.as_u64()?,
                        trigger_offset_s
                            .or_else(|| r.get("trigger_offset_s")?.as_f64())
                            .unwrap_or(first),
                    ))
                })
                .collect()
        })
        .unwrap_or_default();
    let n = rec.samples.len() as u64;
    // The scope's words come back from the volts with the recorded scaling.
    let scaling = (rec.unit == SampleUnit::Volts)
        .then_some(rec.radbench.as_ref())
        .flatten()
        .and_then(|r| Some((r.vertical_gain?, r.vertical_offset?)));
    let adc = recorded_adc(&radbench);
    let repetition_scaling: Vec<Option<([f64; 2], [f64; 2])>> = radbench
        .get("repetitions")
        .and_then(Value::as_array)
        .map(|a| {
            a.iter()
                .map(|r| {
                    let pair = |k: &str| -> Option<[f64; 2]> {
                        let v = r.get(k)?.as_array()?;
                        Some([v.first()?.as_f64()?, v.get(1)?.as_f64()?])
                    };
                    Some((pair("vertical_gain")?, pair("vertical_offset")?))
                })
                .collect()
        })
        .unwrap_or_default();
    let repetitions = if reps.is_empty() {
        vec![RawIq {
            samples: rec.samples,
            sample_rate_hz: rate,
            first_point_s: first,
        }]
    } else {
        reps.iter()
            .map(|&(start, count, offset)| {
                if start + count > n {
                    return Err(input_error(
                        meta,
                        format!(
                            "radbench:repetitions names samples {start}..{} but the data \
                             holds {n}: the data file is truncated",
                            start + count
                        ),
                    ));
                }
                Ok(RawIq {
                    samples: rec.samples[start as usize..(start + count) as usize].to_vec(),
                    sample_rate_hz: rate,
                    first_point_s: offset,
                })
            })
            .collect::<Result<_, _>>()?
    };
    let clipping = match scaling {
        Some(global) => repetitions
            .iter()
            .enumerate()
            .map(|(k, r)| {
                let (gain, offset) = repetition_scaling
                    .get(k)
                    .copied()
                    .flatten()
                    .unwrap_or(global);
                Some(clipping_of_volts(&r.samples, gain, offset, &adc))
            })
            .collect(),
        None => Vec::new(),
    };
    Ok(Loaded {
        repetitions,
        clipping,
        radbench,
    })
}

/// The scope's ADC a radbench capture recorded (`radbench:adc`; before it was recorded, an 8-bit
/// code in the upper byte, the vertical scale unknown).
fn recorded_adc(radbench: &Map<String, Value>) -> (Rails, Option<ScopeAdc>) {
    let adc = radbench.get("adc");
    let bits = adc
        .and_then(|a| a.get("bits"))
        .and_then(Value::as_u64)
        .map_or(8, |b| b.clamp(1, 16) as u8);
    let rails = Rails::word(bits);
    let scope = adc.and_then(|a| {
        let v = a.get("volts_per_div")?.as_array()?;
        Some(ScopeAdc {
            rails,
            volts_per_div: [v.first()?.as_f64()?, v.get(1)?.as_f64()?],
            volts_per_div_max: a.get("volts_per_div_max")?.as_f64()?,
        })
    });
    (rails, scope)
}

/// The samples at the ADC's rails of a repetition held in volts that were the scope's words
/// (`volts = gain * word - offset`).
fn clipping_of_volts(
    samples: &[num_complex::Complex64],
    gain: [f64; 2],
    offset: [f64; 2],
    (rails, scope): &(Rails, Option<ScopeAdc>),
) -> RecordClipping {
    let word = |v: f64, ch: usize| {
        let w = ((v + offset[ch]) / gain[ch]).round();
        w.clamp(f64::from(i16::MIN), f64::from(i16::MAX)) as i16
    };
    let (mut i, mut q) = (0, 0);
    for v in samples {
        i += usize::from(rails.at_rail(word(v.re, 0)));
        q += usize::from(rails.at_rail(word(v.im, 1)));
    }
    RecordClipping {
        count: ClipCount {
            i,
            q,
            samples: samples.len(),
        },
        rails_v: [
            rails.volts(gain[0], offset[0]),
            rails.volts(gain[1], offset[1]),
        ],
        scope: *scope,
    }
}

/// Two LeCroy traces, I and Q of one acquisition: a repetition per segment.
fn load_trc_pair(
    i: &Path,
    q: &Path,
    trigger_offset_s: Option<f64>,
) -> Result<Loaded, MeasureError> {
    let ti = read_trc(i)?;
    let tq = read_trc(q)?;
    if ti.segment_count() != tq.segment_count() || ti.codes.len() != tq.codes.len() {
        return Err(input_error(
            q,
            format!(
                "I holds {} points in {} segments, Q {} in {}: give the two channels of \
                 one acquisition",
                ti.codes.len(),
                ti.segment_count(),
                tq.codes.len(),
                tq.segment_count()
            ),
        ));
    }
    let rate = 1.0 / ti.sample_interval_s();
    // The codes as the scope sent them: an 8-bit code is the value (BYTE) or sits in the upper
    // bits of a word (WORD, NOMINAL_BITS of them).
    let rails = |t: &crate::trc::Trace| {
        if t.desc.sample_width() == 2 {
            let bits = u8::try_from(t.desc.nominal_bits).unwrap_or(8);
            Rails::word(if (1..=16).contains(&bits) { bits } else { 8 })
        } else {
            Rails::byte()
        }
    };
    let (ri, rq) = (rails(&ti), rails(&tq));
    let scaling = |t: &crate::trc::Trace, r: &Rails| {
        r.volts(
            f64::from(t.desc.vertical_gain),
            f64::from(t.desc.vertical_offset),
        )
    };
    let clipping = ti
        .segments()
        .zip(tq.segments())
        .map(|(a, b)| {
            Some(RecordClipping {
                count: ClipCount {
                    i: ri.count(a.codes),
                    q: rq.count(b.codes),
                    samples: a.codes.len().min(b.codes.len()),
                },
                rails_v: [scaling(&ti, &ri), scaling(&tq, &rq)],
                scope: None,
            })
        })
        .collect();
    let repetitions = ti
        .segments()
        .zip(tq.segments())
        .map(|(a, b)| RawIq {
            samples: a
                .volts()
                .iter()
                .zip(b.volts())
                .map(|(x, y)| num_complex::Complex64::new(*x, y))
                .collect(),
            sample_rate_hz: rate,
            first_point_s: trigger_offset_s.unwrap_or(a.trigger_offset_s),
        })
        .collect();
    Ok(Loaded {
        repetitions,
        clipping,
        radbench: Map::new(),
    })
}

/// What the caller says about the waveform of a capture (required for captures radbench did not
/// make; overrides what a radbench capture recorded).
#[derive(Debug, Clone, Default)]
pub(crate) struct WaveformChoice {
    pub spec: Option<WaveformSpec>,
    pub seed: Option<u64>,
    pub payload: Option<Vec<u8>>,
}

/// How one capture will be processed, resolved from what it recorded and the caller's choices.
#[derive(Debug, Clone)]
pub(crate) struct Resolved {
    pub tx: Arc<Transmission>,
    pub options: ProcessOptions,
    pub period: usize,
    pub background: Option<PathBuf>,
}

/// Resolves the transmission, the options, the period and the background of `loaded`.
pub(crate) fn resolve(
    loaded: &Loaded,
    waveform: &WaveformChoice,
    overrides: &ProcessOverrides,
    background: Option<&Path>,
) -> Result<Resolved, MeasureError> {
    let recorded = loaded.recorded_transmission().transpose()?;
    let as_recorded =
        waveform.spec.is_none() && waveform.seed.is_none() && waveform.payload.is_none();
    let tx = match recorded {
        Some(tx) if as_recorded => tx,
        recorded => {
            let spec = waveform
                .spec
                .or(recorded.as_ref().map(|t| t.spec))
                .ok_or(MeasureError::NeedsWaveform)?;
            let seed = waveform
                .seed
                .or(recorded.as_ref().map(|t| t.seed))
                .unwrap_or(1);
            let payload = waveform
                .payload
                .clone()
                .or_else(|| recorded.as_ref().and_then(|t| t.payload.clone()));
            let dac = recorded.as_ref().map_or(Dac::default(), |t| t.dac);
            Transmission::new(&spec, payload.as_deref(), seed, dac)?
        }
    };
    let base = loaded
        .recorded_options()
        .filter(|o| o.algorithm.supports(tx.spec.kind()) || overrides.algorithm.is_some())
        .unwrap_or_else(|| ProcessOptions::for_waveform(tx.spec.kind()));
    let options = overrides.apply(base);
    let tx = tx.with_correction(&options)?;
    if overrides.require_correction && options.correction.is_none() {
        return Err(MeasureError::option(
            "correction",
            "rx",
            "rx needs a calibration: this capture was made without one; pass --calibration FILE \
             (`radbench calibrate response` writes one)",
        ));
    }
    let period = loaded.recorded_period().unwrap_or(tx.len()).max(tx.len());
    let background = background.map(Path::to_path_buf).or_else(|| {
        overrides
            .keep_background
            .then(|| loaded.recorded_background().map(|b| b.path))
            .flatten()
    });
    Ok(Resolved {
        tx: Arc::new(tx),
        options,
        period,
        background,
    })
}

/// One capture processed again.
#[derive(Debug, Clone)]
pub(crate) struct Reprocessed {
    pub processed: Processed,
    pub repetitions: Vec<RepetitionResult>,
    pub spread: Option<Spread>,
    pub resolved: Resolved,
}

/// Builds the pipeline of `resolved` for captures at `rate` (reuse it for captures that resolve
/// the same way).
pub(crate) fn pipeline(resolved: &Resolved, rate: f64) -> Result<Pipeline, MeasureError> {
    let geometry = RecordGeometry::for_capture(
        resolved.period,
        resolved.tx.sample_rate_hz(),
        &resolved.options,
    );
    let mut p = Pipeline::new(resolved.tx.clone(), resolved.options.clone(), geometry)?;
    p.prepare_capture_rate(rate)?;
    Ok(p)
}

/// Processes `loaded` through `pipeline` (built by [`pipeline`] for `resolved`).
pub(crate) fn process(
    pipeline: &mut Pipeline,
    loaded: &Loaded,
    resolved: Resolved,
) -> Result<Reprocessed, MeasureError> {
    let background: Option<Aligned> = match &resolved.background {
        Some(path) => Some(super::capture::read_background(
            pipeline,
            path,
            loaded.repetitions[0].sample_rate_hz,
        )?),
        None => None,
    };
    let bandwidth = resolved.tx.bandwidth_hz();
    let (processed, repetitions, spread) = process_repetitions(
        pipeline,
        &loaded.repetitions,
        background.as_ref(),
        bandwidth,
        &loaded.clipping,
    )?;
    Ok(Reprocessed {
        processed,
        repetitions,
        spread,
        resolved,
    })
}

/// The SHA-256 of every file of `source`, for the manifest.
pub(crate) fn source_hashes(source: &Source) -> Result<Vec<(PathBuf, String)>, MeasureError> {
    source
        .files()
        .into_iter()
        .map(|p| Ok((p.to_path_buf(), sha256_file(p)?)))
        .collect()
}
