//! A saved capture's arrays for a notebook (`radbench export`): got the way `radbench process`
//! gets them ([`reprocess`](crate::measure::records::reprocess): the transmission made again from the capture's
//! description, the recorded options, the same [`Pipeline`](crate::measure::Pipeline)), so they are what
//! radbench computes, not a second implementation. Names, shapes and units: `docs/export.md`.

use super::reprocess::{self, Record, Source, WaveformChoice};
use crate::measure::error::MeasureError;
use crate::measure::processing::choices::ProcessOverrides;
use crate::measure::processing::options::ProcessOptions;
use crate::measure::processing::pipeline::{Alignable, Processed};
use crate::storage::Array;
use serde_json::{json, Map, Value};

/// Version of the export's layout (`metadata["format_version"]`).
pub(crate) const FORMAT_VERSION: u32 = 1;

/// One named array and its unit.
#[derive(Debug, Clone)]
pub struct Entry {
    pub name: String,
    pub array: Array,
    pub unit: Option<&'static str>,
}

fn entry(name: &str, array: Array, unit: Option<&'static str>) -> Entry {
    Entry {
        name: name.to_string(),
        array,
        unit,
    }
}

/// What a capture exports: for each processing asked for (the recorded one first), its arrays;
/// the first also holds the capture's own (I/Q, transmission) and one `metadata` for both.
pub struct CaptureExport {
    pub processings: Vec<Vec<Entry>>,
    /// The algorithm of each processing, in order.
    pub algorithms: Vec<&'static str>,
}

/// The arrays of the capture `source`, processed as it was recorded, and once more with each of
/// `others` (a campaign step's further algorithms).
pub fn export_capture(
    source: &Source,
    others: &[ProcessOptions],
) -> Result<CaptureExport, MeasureError> {
    let loaded = reprocess::load_for_processing(source, None, None)?;
    let Some(first) = loaded.repetitions.first() else {
        return Err(MeasureError::option(
            "input",
            source.files()[0].display(),
            "a capture with at least one repetition",
        ));
    };
    let rate = first.sample_rate_hz();
    let overrides = std::iter::once(ProcessOverrides {
        keep_background: true,
        ..ProcessOverrides::default()
    })
    .chain(others.iter().map(ProcessOverrides::replacing));
    let mut processings = Vec::new();
    let mut algorithms = Vec::new();
    for (k, o) in overrides.enumerate() {
        let resolved = reprocess::resolve(&loaded, &WaveformChoice::default(), &o, None)?;
        let mut pipeline = reprocess::pipeline(&resolved, rate)?;
        let r = reprocess::process(&mut pipeline, &loaded, resolved)?;
        let tx = &r.resolved.tx;
        let options = &r.resolved.options;
        let mut entries = Vec::new();
        let mut meta = Map::new();
        meta.insert("format".into(), json!("radbench export"));
        meta.insert("format_version".into(), json!(FORMAT_VERSION));
        meta.insert("radbench_version".into(), json!(env!("CARGO_PKG_VERSION")));
        if k == 0 {
            // The capture itself: each repetition decimated and aligned as the pipeline aligns
            // it (in volts, before the background and the receive correction).
            let aligned = loaded
                .repetitions
                .iter()
                .map(|rep| rep.align_in(&mut pipeline))
                .collect::<Result<Vec<_>, _>>()?;
            let n = aligned.first().map_or(0, |a| a.samples.len());
            let fs = tx.sample_rate_hz();
            entries.push(entry(
                "iq",
                Array::C128 {
                    shape: vec![aligned.len(), n],
                    data: aligned.iter().flat_map(|a| a.samples.clone()).collect(),
                },
                Some("V"),
            ));
            entries.push(entry("iq_rate_hz", Array::scalar(fs), Some("Hz")));
            entries.push(entry(
                "iq_t0_s",
                Array::f64s(aligned.iter().map(|a| a.residual_s).collect()),
                Some("s"),
            ));
            entries.push(entry(
                "reference",
                Array::c128s(tx.reference.clone()),
                Some("full scale"),
            ));
            entries.push(entry("bits", Array::U8(tx.bits.clone()), None));
            if let Some(p) = &tx.payload {
                entries.push(entry("payload", Array::U8(p.clone()), None));
            }
            meta.insert("source".into(), json!(source));
            meta.insert("capture_rate_hz".into(), json!(rate));
            meta.insert("repetitions".into(), json!(loaded.repetitions.len()));
            meta.insert("transmission".into(), tx.describe());
            meta.insert("scene".into(), json!(loaded.ground_truth()));
        }
        entries.extend(processed_entries(&r.processed));
        meta.insert("algorithm".into(), json!(options.algorithm.name()));
        meta.insert("processing".into(), json!(options));
        meta.insert(
            "summary".into(),
            Value::Object(super::record::result_json(tx, &r.processed, options)),
        );
        meta.insert("background".into(), json!(r.resolved.background));
        meta.insert("spread".into(), json!(r.spread));
        meta.insert("each_repetition".into(), json!(r.repetitions));
        meta.insert("warnings".into(), json!(r.processed.warnings));
        meta.insert(
            "units".into(),
            Value::Object(
                entries
                    .iter()
                    .filter_map(|e| Some((e.name.clone(), json!(e.unit?))))
                    .collect(),
            ),
        );
        entries.push(entry(
            "metadata",
            Array::Text(json!(meta).to_string()),
            None,
        ));
        processings.push(entries);
        algorithms.push(options.algorithm.name());
    }
    Ok(CaptureExport {
        processings,
        algorithms,
    })
}

/// NaN for an absent value (the tables hold float64 only).
fn or_nan(v: Option<f64>) -> f64 {
    v.unwrap_or(f64::NAN)
}

/// The arrays of one processing: the record processed, the profiles, the detection, the
/// range-Doppler map.
fn processed_entries(p: &Processed) -> Vec<Entry> {
    let mut out = vec![entry(
        "iq_processed",
        Array::c128s(p.aligned.clone()),
        Some("V"),
    )];
    for (k, profile) in p.profiles.iter().enumerate() {
        let prefix = match k {
            0 => "profile".to_string(),
            1 => "overlay".to_string(),
            k => format!("overlay{k}"),
        };
        let range_name = if k == 0 {
            "range_m".to_string()
        } else {
            format!("{prefix}_range_m")
        };
        out.push(entry(&range_name, Array::f64s(profile.ranges()), Some("m")));
        out.push(entry(
            &format!("{prefix}_amplitude"),
            Array::f64s(profile.amplitude.clone()),
            Some("re unit-gain path"),
        ));
        out.push(entry(
            &format!("{prefix}_label"),
            Array::Text(profile.label.clone()),
            None,
        ));
    }
    if let Some(z) = &p.complex_profile {
        out.push(entry(
            "profile",
            Array::c128s(z.clone()),
            Some("re unit-gain path"),
        ));
    }
    let cells = p.profiles.first().map_or(0, |x| x.amplitude.len());
    for (name, values) in [
        ("threshold", &p.detection.threshold),
        ("residual", &p.detection.residual),
    ] {
        if !values.is_empty() && values.len() == cells {
            out.push(entry(
                name,
                Array::f64s(values.clone()),
                Some("re unit-gain path"),
            ));
        }
    }
    let t = &p.targets;
    let column =
        |f: &dyn Fn(&crate::measure::processing::pipeline::Detection) -> Option<f64>| -> Vec<f64> {
            t.iter().map(|d| or_nan(f(d))).collect()
        };
    out.push(entry(
        "targets",
        Array::Records {
            rows: t.len(),
            fields: vec![
                ("range_m", column(&|d| Some(d.range_m))),
                ("level_db", column(&|d| Some(d.level_db))),
                ("above_threshold_db", column(&|d| d.above_threshold_db)),
                ("on_grid_m", column(&|d| d.on_grid_m)),
                ("snr_db", column(&|d| d.snr_db)),
                ("width_3db_cm", column(&|d| d.width_3db_cm)),
                ("sidelobe_db", column(&|d| d.sidelobe_db)),
                ("velocity_mps", column(&|d| d.velocity_mps)),
            ],
        },
        None,
    ));
    if let Some(map) = &p.range_doppler {
        out.push(entry(
            "range_doppler",
            Array::F64 {
                shape: vec![map.range_m.len(), map.velocity_mps.len()],
                data: map.amplitude.clone(),
            },
            Some("re unit-gain path"),
        ));
        out.push(entry(
            "range_doppler_range_m",
            Array::f64s(map.range_m.clone()),
            Some("m"),
        ));
        out.push(entry(
            "range_doppler_velocity_mps",
            Array::f64s(map.velocity_mps.clone()),
            Some("m/s"),
        ));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::measure::processing::transmit::{Dac, Transmission};
    use crate::measure::{Pipeline, RawIq, RecordGeometry};
    use crate::waveform::WaveformKind;
    use num_complex::Complex64;
    use std::sync::Arc;

    #[test]
    fn the_complex_profile_is_the_amplitude_profile_with_its_phase() {
        let kind = WaveformKind::MskLfm;
        let tx = Arc::new(Transmission::new(&kind.thesis_default(), None, 1, Dac::Ideal).unwrap());
        let (period, fs) = (tx.len(), tx.sample_rate_hz());
        let geometry = RecordGeometry {
            period,
            correlation_lags: 2000,
        };
        let mut pipeline =
            Pipeline::new(tx.clone(), ProcessOptions::for_waveform(kind), geometry).unwrap();
        let delay = 107;
        let samples: Vec<Complex64> = (0..period)
            .map(|n| 0.1 * tx.reference[(n + period - delay) % period])
            .collect();
        let aligned = pipeline
            .align(&RawIq {
                samples,
                sample_rate_hz: fs,
                first_point_s: 0.0,
            })
            .unwrap();
        let p = pipeline.process(aligned, None).unwrap();
        let z = p.complex_profile.as_ref().unwrap();
        let norms: Vec<f64> = z.iter().map(|v| v.norm()).collect();
        assert_eq!(norms, p.profiles[0].amplitude);
        let names: Vec<String> = processed_entries(&p).into_iter().map(|e| e.name).collect();
        for name in [
            "iq_processed",
            "range_m",
            "profile",
            "profile_amplitude",
            "profile_label",
            "targets",
        ] {
            assert!(names.iter().any(|n| n == name), "{name} in {names:?}");
        }
    }
}
