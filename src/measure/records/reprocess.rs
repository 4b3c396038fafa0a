//! Re-processing saved captures, long after the bench is gone: a capture folder, a SigMF
//! recording (radbench's or anyone's) or a pair of LeCroy `.trc` files (I and Q, sequence-mode
//! segments as repetitions) go through the same [`Pipeline`] as a live capture.
//!
//! A radbench capture carries everything needed to process it again exactly as it was (the
//! transmitted waveform and its bits, every processing option, the record's period, the
//! background it subtracted); any of it can be overridden. A capture radbench did not make needs
//! the waveform from the caller.

use super::repeat::{RepetitionResult, Spread};
use crate::measure::capture::{process_repetitions, BackgroundFile};
use crate::measure::error::MeasureError;
use crate::measure::processing::choices::ProcessOverrides;
use crate::measure::processing::clipping::{ClipCount, Rails, RecordClipping, ScopeAdc};
use crate::measure::processing::options::ProcessOptions;
use crate::measure::processing::pipeline::{
    Alignable, Aligned, Pipeline, Processed, RawIq, RawWords, RecordGeometry,
};
use crate::measure::processing::transmit::{self, Dac, Transmission};
use crate::storage::hash::sha256_file;
use crate::storage::recording::{
    read_sigmf, read_sigmf_stored, read_trc, sigmf_paths, Recording, SampleUnit,
};
use crate::waveform::WaveformSpec;
use serde::Serialize;
use serde_json::{Map, Value};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

/// Where one capture to re-process is.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Source {
    /// A SigMF recording (its `.sigmf-meta` path).
    Sigmf { meta: PathBuf, data: PathBuf },
    /// LeCroy `.trc` files of I and Q.
    TrcPair { i: PathBuf, q: PathBuf },
}

impl Source {
    /// The files read, for the manifest.
    pub fn files(&self) -> Vec<&Path> {
        match self {
            Source::Sigmf { meta, data } => vec![meta, data],
            Source::TrcPair { i, q } => vec![i, q],
        }
    }

    /// A short name for folders and messages.
    pub fn label(&self) -> String {
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
pub struct InputError {
    pub path: PathBuf,
    pub reason: String,
}

/// The captures the inputs name, in order: a capture folder (its `capture.sigmf-meta`), a run
/// folder of a campaign (every step's capture), a SigMF file, or two `.trc` files given one
/// after the other (I then Q). Each entry is a capture or why an input is not one.
pub fn discover(inputs: &[PathBuf]) -> Vec<Result<Source, InputError>> {
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

/// The capture of a SigMF file or of a capture folder's `.sigmf-meta`.
pub fn sigmf(path: &Path) -> Result<Source, InputError> {
    sigmf_paths(path)
        .map(|(meta, data)| Source::Sigmf { meta, data })
        .map_err(|e| InputError {
            path: path.to_path_buf(),
            reason: e.to_string(),
        })
}

/// A capture read back: its repetitions (in volts, or [`Repetition`]s for
/// `load_for_processing`) and what radbench recorded about it.
#[derive(Debug, Clone)]
pub struct Loaded<R = RawIq> {
    pub repetitions: Vec<R>,
    /// Each repetition's samples at the ADC's rails, when the capture holds the scope's codes (a
    /// radbench capture, a `.trc` pair); empty otherwise.
    pub clipping: Vec<Option<RecordClipping>>,
    /// The `radbench:` metadata (empty for a capture radbench did not make).
    pub radbench: Map<String, Value>,
    /// SHA-256 of source files, of the bytes read while loading (for the manifest; files not
    /// here are hashed from disk).
    pub sha256: Vec<(PathBuf, String)>,
}

/// One repetition of a capture read for processing: the scope's 16-bit words when the file holds
/// them (a `ci16` recording: the pipeline converts them to volts as it reads them, with the same
/// arithmetic as reading the file in volts, so the same results without a record in volts), else
/// the samples in volts.
#[derive(Debug, Clone)]
pub enum Repetition {
    Volts(RawIq),
    Words(RawWords),
}

/// A repetition the pipeline aligns, at its sample rate.
pub trait Record: Alignable {
    fn sample_rate_hz(&self) -> f64;
}

impl Record for RawIq {
    fn sample_rate_hz(&self) -> f64 {
        self.sample_rate_hz
    }
}

impl Record for Repetition {
    fn sample_rate_hz(&self) -> f64 {
        match self {
            Repetition::Volts(r) => r.sample_rate_hz,
            Repetition::Words(w) => w.sample_rate_hz,
        }
    }
}

impl Alignable for Repetition {
    fn align_in(&self, pipeline: &mut Pipeline) -> Result<Aligned, MeasureError> {
        match self {
            Repetition::Volts(r) => pipeline.align(r),
            Repetition::Words(w) => pipeline.align_words(w),
        }
    }
}

impl Repetition {
    /// The samples in volts (as the pipeline converts words: `gain * word - offset`).
    fn into_volts(self) -> RawIq {
        match self {
            Repetition::Volts(r) => r,
            Repetition::Words(w) => {
                let ([gi, gq], [oi, oq]) = (w.gain, w.offset);
                RawIq {
                    samples: w
                        .i
                        .iter()
                        .zip(&w.q)
                        .map(|(&i, &q)| {
                            num_complex::Complex64::new(
                                gi * f64::from(i) - oi,
                                gq * f64::from(q) - oq,
                            )
                        })
                        .collect(),
                    sample_rate_hz: w.sample_rate_hz,
                    first_point_s: w.first_point_s,
                }
            }
        }
    }
}

impl<R> Loaded<R> {
    fn key(&self, k: &str) -> Option<&Value> {
        self.radbench.get(k)
    }

    /// The processing options the capture was processed with.
    pub(crate) fn recorded_options(&self) -> Option<ProcessOptions> {
        serde_json::from_value(self.key("processing")?.clone()).ok()
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
    let loaded = match source {
        Source::Sigmf { meta, .. } => {
            let rec = read_sigmf(meta)?;
            load_sigmf(meta, rec, None, trigger_offset_s)?
        }
        Source::TrcPair { i, q } => return load_trc_pair(i, q, trigger_offset_s),
    };
    Ok(Loaded {
        repetitions: loaded
            .repetitions
            .into_iter()
            .map(Repetition::into_volts)
            .collect(),
        clipping: loaded.clipping,
        radbench: loaded.radbench,
        sha256: loaded.sha256,
    })
}

/// [`load`] for processing: a `ci16` recording's repetitions stay the scope's words (no record
/// in volts, 4 bytes a sample instead of 16), and its files are hashed as they are read.
/// `recorded_sha256`: the data file's SHA-256 as a run manifest recorded it, if known (it then
/// stands for the recording's own SHA-512 check when the data matches it).
pub(crate) fn load_for_processing(
    source: &Source,
    trigger_offset_s: Option<f64>,
    recorded_sha256: Option<&str>,
) -> Result<Loaded<Repetition>, MeasureError> {
    match source {
        Source::Sigmf { meta, .. } => {
            let stored = read_sigmf_stored(meta, recorded_sha256)?;
            let mut loaded = load_sigmf(meta, stored.recording, stored.words, trigger_offset_s)?;
            loaded.sha256 = stored.sha256.to_vec();
            Ok(loaded)
        }
        Source::TrcPair { i, q } => {
            let loaded = load_trc_pair(i, q, trigger_offset_s)?;
            Ok(Loaded {
                repetitions: loaded
                    .repetitions
                    .into_iter()
                    .map(Repetition::Volts)
                    .collect(),
                clipping: loaded.clipping,
                radbench: loaded.radbench,
                sha256: loaded.sha256,
            })
        }
    }
}

/// A SigMF recording: one repetition, or those its `radbench:repetitions` list names; the
/// recording's words (I, Q) when given, else its samples.
fn load_sigmf(
    meta: &Path,
    rec: Recording,
    words: Option<(Vec<i16>, Vec<i16>)>,
    trigger_offset_s: Option<f64>,
) -> Result<Loaded<Repetition>, MeasureError> {
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
    // A first sample 1e300 s after the trigger is a damaged file, not a bench.
    if let Some((k, (_, _, t))) = reps
        .iter()
        .enumerate()
        .find(|(_, (_, _, t))| !(t.is_finite() && t.abs() <= 1.0))
    {
        return Err(input_error(
            meta,
            format!(
                "radbench:repetitions[{k}].trigger_offset_s = {t:e}: a time from the trigger \
                 within -1 ..= 1 s"
            ),
        ));
    }
    // The scope's words come back from the volts with the recorded scaling.
    let scaling = (rec.unit == SampleUnit::Volts)
        .then_some(rec.radbench.as_ref())
        .flatten()
        .and_then(|r| Some((r.vertical_gain?, r.vertical_offset?)));
    // The recording's own scaling, as reading it in volts applies it (none: native scale).
    let decoding = rec.radbench.as_ref().and_then(|r| {
        r.vertical_gain
            .map(|g| (g, r.vertical_offset.unwrap_or([0.0; 2])))
    });
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
    let mut stored = match words {
        Some((i, q)) => Stored::Words {
            i,
            q,
            decoding: decoding.unwrap_or(([1.0; 2], [0.0; 2])),
        },
        None => Stored::Volts(rec.samples),
    };
    let n = stored.len() as u64;
    let spans: Vec<(u64, u64, f64)> = if reps.is_empty() {
        vec![(0, n, first)]
    } else {
        reps
    };
    for &(start, count, _) in &spans {
        if start + count > n {
            return Err(input_error(
                meta,
                format!(
                    "radbench:repetitions names samples {start}..{} but the data holds {n}: \
                     the data file is truncated",
                    start + count
                ),
            ));
        }
    }
    let clipping = match scaling {
        Some(global) => spans
            .iter()
            .enumerate()
            .map(|(k, &(start, count, _))| {
                let (gain, offset) = repetition_scaling
                    .get(k)
                    .copied()
                    .flatten()
                    .unwrap_or(global);
                let range = start as usize..(start + count) as usize;
                Some(stored.clipping(range, gain, offset, &adc))
            })
            .collect(),
        None => Vec::new(),
    };
    let whole = spans.len() == 1;
    let repetitions = spans
        .iter()
        .map(|&(start, count, offset)| {
            let range = start as usize..(start + count) as usize;
            stored.repetition(range, whole, rate, offset)
        })
        .collect();
    Ok(Loaded {
        repetitions,
        clipping,
        radbench,
        sha256: Vec::new(),
    })
}

/// A recording's samples: in volts, or the scope's words with the scaling that gives the volts.
enum Stored {
    Volts(Vec<num_complex::Complex64>),
    Words {
        i: Vec<i16>,
        q: Vec<i16>,
        /// (gain, offset) of I and Q: volts = gain * word - offset.
        decoding: ([f64; 2], [f64; 2]),
    },
}

impl Stored {
    fn len(&self) -> usize {
        match self {
            Stored::Volts(v) => v.len(),
            Stored::Words { i, q, .. } => i.len().min(q.len()),
        }
    }

    /// The samples in `range` as one repetition; `whole`: the only one, taken without a copy.
    fn repetition(
        &mut self,
        range: std::ops::Range<usize>,
        whole: bool,
        sample_rate_hz: f64,
        first_point_s: f64,
    ) -> Repetition {
        fn take<T: Clone>(v: &mut Vec<T>, range: std::ops::Range<usize>, whole: bool) -> Vec<T> {
            if whole {
                let mut v = std::mem::take(v);
                v.truncate(range.end);
                v.drain(..range.start);
                v
            } else {
                v[range].to_vec()
            }
        }
        match self {
            Stored::Volts(v) => Repetition::Volts(RawIq {
                samples: take(v, range, whole),
                sample_rate_hz,
                first_point_s,
            }),
            Stored::Words { i, q, decoding } => Repetition::Words(RawWords {
                i: take(i, range.clone(), whole),
                q: take(q, range, whole),
                gain: decoding.0,
                offset: decoding.1,
                sample_rate_hz,
                first_point_s,
            }),
        }
    }

    /// The samples in `range` at the ADC's rails, their words taken back from the volts with
    /// the repetition's scaling (`gain`, `offset`).
    fn clipping(
        &self,
        range: std::ops::Range<usize>,
        gain: [f64; 2],
        offset: [f64; 2],
        adc: &(Rails, Option<ScopeAdc>),
    ) -> RecordClipping {
        match self {
            Stored::Volts(v) => clipping_of_volts(&v[range], gain, offset, adc),
            Stored::Words { i, q, decoding } => {
                let count = |words: &[i16], ch: usize| {
                    rail_count(
                        words,
                        decoding.0[ch],
                        decoding.1[ch],
                        gain[ch],
                        offset[ch],
                        adc.0,
                    )
                };
                let (i, q) = (&i[range.clone()], &q[range]);
                RecordClipping {
                    count: ClipCount {
                        i: count(i, 0),
                        q: count(q, 1),
                        samples: i.len().min(q.len()),
                    },
                    rails_v: [
                        adc.0.volts(gain[0], offset[0]),
                        adc.0.volts(gain[1], offset[1]),
                    ],
                    scope: adc.1,
                }
            }
        }
    }
}

/// The word [`clipping_of_volts`] takes back from a sample in volts with a channel's scaling.
fn word_of_volts(v: f64, gain: f64, offset: f64) -> i16 {
    let w = ((v + offset) / gain).round();
    w.clamp(f64::from(i16::MIN), f64::from(i16::MAX)) as i16
}

/// Words at the rails as [`clipping_of_volts`] counts them on their volts (decoded with `gain_d`,
/// `offset_d`, taken back with `gain`, `offset`): a word's answer depends on the word alone, so
/// it is worked out once for each of the 65536 words; where that is plain [`Rails::at_rail`]
/// (the usual case: the same scaling both ways) the words are counted directly.
fn rail_count(
    words: &[i16],
    gain_d: f64,
    offset_d: f64,
    gain: f64,
    offset: f64,
    rails: Rails,
) -> usize {
    /// The last tables worked out, by scaling and rails (`None`: plain `at_rail`): a run's
    /// captures share one scope setting.
    type Tables = Vec<([u64; 4], Rails, Option<Arc<Vec<bool>>>)>;
    static TABLES: Mutex<Tables> = Mutex::new(Vec::new());
    let key = [gain_d, offset_d, gain, offset].map(f64::to_bits);
    let index = |w: i16| (i32::from(w) - i32::from(i16::MIN)) as usize;
    let known = {
        let tables = TABLES.lock().unwrap_or_else(|p| p.into_inner());
        tables
            .iter()
            .find(|(k, r, _)| *k == key && *r == rails)
            .map(|(_, _, t)| t.clone())
    };
    let table = known.unwrap_or_else(|| {
        let table: Vec<bool> = (i16::MIN..=i16::MAX)
            .map(|w| {
                let v = gain_d * f64::from(w) - offset_d;
                rails.at_rail(word_of_volts(v, gain, offset))
            })
            .collect();
        let plain = (i16::MIN..=i16::MAX).all(|w| table[index(w)] == rails.at_rail(w));
        let table = (!plain).then(|| Arc::new(table));
        let mut tables = TABLES.lock().unwrap_or_else(|p| p.into_inner());
        if tables.len() >= 8 {
            tables.remove(0);
        }
        tables.push((key, rails, table.clone()));
        table
    });
    match table {
        None => rails.count(words),
        Some(table) => words.iter().map(|&w| usize::from(table[index(w)])).sum(),
    }
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
    let word = |v: f64, ch: usize| word_of_volts(v, gain[ch], offset[ch]);
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
        radbench: capture_metadata_beside(i, q).unwrap_or_default(),
        sha256: Vec::new(),
    })
}

/// The `radbench:` metadata of the radbench capture a `.trc` pair came from: the folder's
/// `summary.json` names the pair (I then Q, by file name) among its files, and its SigMF
/// metadata file. Without it a pair radbench wrote would be processed with no waveform and no
/// system delay.
fn capture_metadata_beside(i: &Path, q: &Path) -> Option<Map<String, Value>> {
    let folder = |p: &Path| {
        let dir = p.parent().filter(|d| !d.as_os_str().is_empty());
        std::fs::canonicalize(dir.unwrap_or(Path::new("."))).ok()
    };
    let dir = folder(i)?;
    if folder(q)? != dir {
        return None;
    }
    let summary: Value =
        serde_json::from_slice(&std::fs::read(dir.join("summary.json")).ok()?).ok()?;
    let files = summary.get("files")?;
    let name = |v: &Value| Path::new(v.as_str()?).file_name().map(|n| n.to_owned());
    let listed: Vec<_> = files
        .get("trc")?
        .as_array()?
        .iter()
        .filter_map(name)
        .collect();
    if listed != [i.file_name()?.to_owned(), q.file_name()?.to_owned()] {
        return None;
    }
    let meta: Value =
        serde_json::from_slice(&std::fs::read(dir.join(name(files.get("sigmf_meta")?)?)).ok()?)
            .ok()?;
    let keys: Map<String, Value> = meta
        .get("global")?
        .as_object()?
        .iter()
        .filter_map(|(k, v)| Some((k.strip_prefix("radbench:")?.to_string(), v.clone())))
        .collect();
    (!keys.is_empty()).then_some(keys)
}

/// What the caller says about the waveform of a capture (required for captures radbench did not
/// make; overrides what a radbench capture recorded).
#[derive(Debug, Clone, Default)]
pub struct WaveformChoice {
    pub spec: Option<WaveformSpec>,
    pub seed: Option<u64>,
    pub payload: Option<Vec<u8>>,
}

/// How one capture will be processed, resolved from what it recorded and the caller's choices.
#[derive(Debug, Clone)]
pub struct Resolved {
    pub tx: Arc<Transmission>,
    pub options: ProcessOptions,
    pub period: usize,
    pub background: Option<PathBuf>,
    /// What had to be assumed because neither the capture nor the caller said it (warnings).
    pub assumed: Vec<String>,
}

/// Resolves the transmission, the options, the period and the background of `loaded`.
pub(crate) fn resolve<R>(
    loaded: &Loaded<R>,
    waveform: &WaveformChoice,
    overrides: &ProcessOverrides,
    background: Option<&Path>,
) -> Result<Resolved, MeasureError> {
    let recorded = recorded_transmission(loaded).transpose()?;
    let mut assumed = Vec::new();
    if recorded.is_none() && waveform.seed.is_none() && waveform.payload.is_none() {
        assumed.push(
            "the capture does not record its bits: PRBS seed 1 was assumed (give --seed or \
             --payload); bit errors mean nothing if that is not what was sent"
                .to_string(),
        );
    }
    if loaded.recorded_options().is_none() && !overrides.system_delay_given() {
        assumed.push(
            "the capture does not record the bench's system delay and --system-delay was not \
             given: 0 s was assumed, so every range includes the fixed delay of cables and horns \
             (give --system-delay S, e.g. from the bench file's [calibration])"
                .to_string(),
        );
    }
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
            Arc::new(Transmission::new(&spec, payload.as_deref(), seed, dac)?)
        }
    };
    let base = loaded
        .recorded_options()
        .filter(|o| o.algorithm.supports(tx.spec.kind()) || overrides.algorithm_given())
        .unwrap_or_else(|| ProcessOptions::for_waveform(tx.spec.kind()));
    let mut options = overrides.apply(base);
    if let Some(mode) = overrides.require_correction {
        let Some(used) = options.correction.as_mut() else {
            return Err(MeasureError::option(
                "correction",
                mode,
                format!(
                    "{mode} needs a calibration: this capture was made without one; pass \
                     --calibration FILE (`radbench calibrate response` writes one)"
                ),
            ));
        };
        used.mode = mode;
    }
    check_predistorted(loaded.recorded_options().as_ref(), &options)?;
    // The calibration the capture recorded is read here, once, and checked to be the one it
    // used; the transmission and the pipeline take it from the options.
    crate::measure::calibration::correction::load_recorded(options.correction.as_mut())?;
    // `with_correction` changes only a transmission pre-distorted for the chain (tx, both).
    let tx = if predistorts(&options) {
        Arc::new(Arc::unwrap_or_clone(tx).with_correction(&options)?)
    } else {
        tx
    };
    let period = loaded.recorded_period().unwrap_or(tx.len()).max(tx.len());
    let background = background.map(Path::to_path_buf).or_else(|| {
        overrides
            .keep_background
            .then(|| loaded.recorded_background().map(|b| b.path))
            .flatten()
    });
    Ok(Resolved {
        assumed,
        tx,
        options,
        period,
        background,
    })
}

/// tx and both process a capture against its own pre-distorted codes: refused for a capture
/// that was not captured with them; rx for one that was (its codes already carry the chain's
/// inverse: dividing the response out again would correct twice).
fn check_predistorted(
    recorded: Option<&ProcessOptions>,
    options: &ProcessOptions,
) -> Result<(), MeasureError> {
    let Some(used) = options.correction.as_ref() else {
        return Ok(());
    };
    let sent = recorded.and_then(|o| o.correction.as_ref()).map(|u| u.mode);
    let predistorted = sent.is_some_and(|m| m.predistorts());
    if predistorted == used.mode.predistorts() {
        return Ok(());
    }
    if predistorted {
        return Err(MeasureError::option(
            "correction",
            used.mode,
            format!(
                "tx, both or none for this capture: it was captured with correction {}, so its \
                 codes already carry the chain's inverse (rx would correct twice)",
                sent.map_or("none", |m| m.name())
            ),
        ));
    }
    Err(MeasureError::option(
        "correction",
        used.mode,
        format!(
            "none or rx for this capture: it was captured with correction {}, so its codes were \
             not pre-distorted; tx and both process a capture made with them, against its own \
             codes",
            sent.map_or("none", |m| m.name())
        ),
    ))
}

/// Whether [`Transmission::with_correction`] pre-distorts for `options` (anything else leaves
/// the transmission as it is).
fn predistorts(options: &ProcessOptions) -> bool {
    matches!(&options.correction, Some(used) if used.mode.predistorts())
}

/// Transmissions made again from captures' descriptions, by the description: the captures of a
/// run or an archive share one, and making it (waveform, quantisation, reference) costs more than
/// processing a capture. A few at most; the same description makes the same transmission.
static TRANSMISSIONS: Mutex<Vec<(String, Arc<Transmission>)>> = Mutex::new(Vec::new());

/// Most transmissions [`TRANSMISSIONS`] keeps.
const TRANSMISSIONS_KEPT: usize = 4;

/// The transmission the capture recorded (spec, bits, DAC model), made once per description.
fn recorded_transmission<R>(loaded: &Loaded<R>) -> Option<Result<Arc<Transmission>, MeasureError>> {
    let description = loaded.key("waveform")?;
    let key = description.to_string();
    // Held while a transmission is made: a second thread wanting it waits for it.
    let mut cache = TRANSMISSIONS.lock().unwrap_or_else(|p| p.into_inner());
    if let Some((_, tx)) = cache.iter().find(|(k, _)| *k == key) {
        return Some(Ok(tx.clone()));
    }
    let tx = match transmit::from_description(description)? {
        Ok(tx) => Arc::new(tx),
        Err(e) => return Some(Err(e)),
    };
    if cache.len() >= TRANSMISSIONS_KEPT {
        cache.remove(0);
    }
    cache.push((key, tx.clone()));
    Some(Ok(tx))
}

/// One capture processed again.
#[derive(Debug, Clone)]
pub struct Reprocessed {
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
pub(crate) fn process<R: Record>(
    pipeline: &mut Pipeline,
    loaded: &Loaded<R>,
    resolved: Resolved,
) -> Result<Reprocessed, MeasureError> {
    let background: Option<Aligned> = match (&resolved.background, loaded.repetitions.first()) {
        (Some(path), Some(first)) => Some(crate::measure::capture::read_background(
            pipeline,
            path,
            first.sample_rate_hz(),
        )?),
        // No repetition: process_repetitions refuses the capture.
        _ => None,
    };
    let bandwidth = resolved.tx.bandwidth_hz();
    let (mut processed, repetitions, spread) = process_repetitions(
        pipeline,
        &loaded.repetitions,
        background.as_ref(),
        bandwidth,
        &loaded.clipping,
    )?;
    processed.warnings.extend(resolved.assumed.iter().cloned());
    Ok(Reprocessed {
        processed,
        repetitions,
        spread,
        resolved,
    })
}

/// The SHA-256 of every file of `source`, for the manifest: those `known` (hashed as they were
/// read) as they are, the others read again.
pub(crate) fn source_hashes(
    source: &Source,
    known: &[(PathBuf, String)],
) -> Result<Vec<(PathBuf, String)>, MeasureError> {
    source
        .files()
        .into_iter()
        .map(|p| {
            let sha256 = match known.iter().find(|(k, _)| k == p) {
                Some((_, h)) => h.clone(),
                None => sha256_file(p)?,
            };
            Ok((p.to_path_buf(), sha256))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A `ci16_le` recording radbench could have written: `n` samples in two repetitions,
    /// each with its own scaling beside the global one, words at both rails.
    fn recording(dir: &Path, global: ([f64; 2], [f64; 2]), n: usize) -> Source {
        let words: Vec<(i16, i16)> = (0..n)
            .map(|k| match k % 7 {
                0 => (i16::MAX, i16::MIN),
                1 => (i16::MIN + 200, 0x7f00),
                _ => ((k as i16).wrapping_mul(97), (k as i16).wrapping_mul(-31)),
            })
            .collect();
        let data: Vec<u8> = words
            .iter()
            .flat_map(|(i, q)| [i.to_le_bytes(), q.to_le_bytes()].concat())
            .collect();
        let half = (n / 2) as u64;
        let meta = serde_json::json!({
            "global": {
                "core:datatype": "ci16_le",
                "core:sample_rate": 80e9,
                "core:version": "1.0.0",
                "radbench:vertical_gain": global.0,
                "radbench:vertical_offset": global.1,
                "radbench:trigger_offset_s": 1e-9,
                "radbench:adc": {"bits": 8, "volts_per_div": [0.05, 0.05], "volts_per_div_max": 1.0},
                "radbench:repetitions": [
                    {"sample_start": 0, "sample_count": half, "trigger_offset_s": 1e-9,
                     "vertical_gain": global.0, "vertical_offset": global.1},
                    {"sample_start": half, "sample_count": half, "trigger_offset_s": 2e-9,
                     "vertical_gain": [global.0[0] * 2.0, global.0[1]],
                     "vertical_offset": [global.1[0], global.1[1] + 0.01]},
                ],
            },
            "captures": [{"core:sample_start": 0}],
            "annotations": [],
        });
        let meta_path = dir.join("capture.sigmf-meta");
        std::fs::write(&meta_path, meta.to_string()).unwrap();
        std::fs::write(dir.join("capture.sigmf-data"), data).unwrap();
        Source::Sigmf {
            meta: meta_path,
            data: dir.join("capture.sigmf-data"),
        }
    }

    /// Reading for processing keeps the words, and gives what reading in volts gives: the same
    /// samples to the bit, the same clipping, the same source hashes.
    fn same_as_in_volts(global: ([f64; 2], [f64; 2])) {
        let dir = tempfile::tempdir().unwrap();
        let source = recording(dir.path(), global, 1000);
        let volts = load(&source, None).unwrap();
        let words = load_for_processing(&source, None, None).unwrap();
        assert!(words
            .repetitions
            .iter()
            .all(|r| matches!(r, Repetition::Words(_))));
        assert_eq!(words.clipping, volts.clipping);
        // Words at the rails in the first repetition; the second's own scaling (I's gain
        // doubled) takes them back elsewhere.
        let first = volts.clipping[0].unwrap().count;
        assert!(first.i > 0 && first.q > 0, "{first:?}");
        assert_eq!(words.radbench, volts.radbench);
        assert_eq!(words.repetitions.len(), 2);
        for (w, v) in words.repetitions.into_iter().zip(&volts.repetitions) {
            let w = w.into_volts();
            assert_eq!(w.sample_rate_hz, v.sample_rate_hz);
            assert_eq!(w.first_point_s, v.first_point_s);
            let bits = |s: &[num_complex::Complex64]| -> Vec<(u64, u64)> {
                s.iter().map(|c| (c.re.to_bits(), c.im.to_bits())).collect()
            };
            assert_eq!(bits(&w.samples), bits(&v.samples));
        }
        assert_eq!(
            source_hashes(&source, &words.sha256).unwrap(),
            source_hashes(&source, &[]).unwrap()
        );
        assert_eq!(words.sha256.len(), 2);
    }

    #[test]
    fn words_read_for_processing_are_the_volts_read_otherwise() {
        same_as_in_volts(([1.5e-5, 1.6e-5], [0.002, -0.001]));
    }

    #[test]
    fn words_whose_volts_do_not_round_trip_are_counted_as_the_volts_are() {
        // An offset so large that a word taken back from its volts is not always itself: the
        // clipping comes from the per-word table, and still matches the volts' count.
        let (gain, offset) = ([1e-3, 1e-3], [1e14, -1e14]);
        assert!((i16::MIN..=i16::MAX).any(|w| word_of_volts(
            gain[0] * f64::from(w) - offset[0],
            gain[0],
            offset[0]
        ) != w));
        same_as_in_volts((gain, offset));
    }

    #[test]
    fn a_transmission_is_made_once_per_description() {
        let tx =
            Transmission::new(&WaveformSpec::msk_lfm_default(), None, 7, Dac::default()).unwrap();
        let loaded: Loaded = Loaded {
            repetitions: Vec::new(),
            clipping: Vec::new(),
            radbench: [("waveform".to_string(), tx.describe())]
                .into_iter()
                .collect(),
            sha256: Vec::new(),
        };
        let a = recorded_transmission(&loaded).unwrap().unwrap();
        let b = recorded_transmission(&loaded).unwrap().unwrap();
        assert!(Arc::ptr_eq(&a, &b));
        assert_eq!(a.describe(), tx.describe());
        assert_eq!(a.reference, tx.reference);
    }
}
