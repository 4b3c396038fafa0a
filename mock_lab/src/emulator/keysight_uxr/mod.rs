//! Keysight Infiniium UXR-class scope emulator: the SCPI subset a driver uses to capture I and Q
//! on the auxiliary trigger, in real-time or segmented memory, as 16-bit `:WAVeform:DATA?` blocks
//! scaled by `:WAVeform:PREamble?` (Infiniium's format codes: 0 ASCii, 1 BYTE, 2 WORD).
//!
//! An armed acquisition (`:SINGle`) completes when the pluggable [`TriggerSource`] reports a
//! marker edge on the auxiliary input; the Acquisition Done Event Register (`:ADER?`) says so
//! once (reading clears it). Each query of `:ADER?` looks at the inputs once and never waits, so
//! no connection is ever blocked. `:DIGitize` waits (bounded) for the edge. Errors go to the SCPI
//! error queue (`:SYSTem:ERRor?`): -113 undefined header, -222 data out of range, -230 no data.
//! Facts and their certainty: instruments/README.md, "Keysight Infiniium UXR".

use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, Instant};

use serde::Deserialize;

use super::lecroy::trigger::{AcquisitionRequest, Slope, TriggerSetup, TriggerSource};
use super::received_log::ReceivedLog;
use super::scpi::error_queue::{ErrorQueue, ScpiError};
use super::scpi::header::{Header, Pattern};
use super::scpi::message::{parse_unit, split_units, Param};
use super::scpi::numeric::{boolean, keyword, nr3, unsigned};
use crate::catalog::{CatalogError, EmulatorIdentity};
use crate::server::Handler;

/// The catalog file this emulator serves (read with its own small structs).
const CATALOG: &str = include_str!("../../../../instruments/keysight_uxr0334a.toml");
/// Longest `:DIGitize` waits for a trigger edge.
const DIGITIZE_WAIT: Duration = Duration::from_secs(5);
/// Segments' spacing when the source does not say (seconds).
const DEFAULT_EDGE_PERIOD_S: f64 = 1e-3;

#[derive(Debug, Deserialize)]
struct CatalogFile {
    identity: CatalogIdentity,
    digitizer: Limits,
}

#[derive(Debug, Deserialize)]
struct CatalogIdentity {
    emulator: EmulatorIdentity,
}

/// The limits the emulator enforces, from the catalog.
#[derive(Debug, Clone, PartialEq, Deserialize)]
pub struct Limits {
    pub channels: u8,
    pub adc_bits: u8,
    pub sample_rates: Vec<f64>,
    pub max_points_per_channel: u64,
    pub vertical_divisions: u32,
    pub volts_per_div_min: f64,
    pub volts_per_div_max: f64,
    pub volts_per_div_default: f64,
    pub offset_v_min: f64,
    pub offset_v_max: f64,
    pub ext_trigger_level_v_min: f64,
    pub ext_trigger_level_v_max: f64,
    #[serde(default)]
    pub max_sequence_segments: u32,
}

/// One channel's front-panel settings.
#[derive(Debug, Clone, PartialEq)]
pub struct ChannelSettings {
    pub display: bool,
    pub scale_v: f64,
    pub offset_v: f64,
}

/// One channel's last record: every segment's codes and scaling.
#[derive(Debug, Clone, PartialEq)]
pub struct Record {
    /// `segments x points` codes.
    pub codes: Vec<Vec<i16>>,
    pub y_increment: f64,
    pub y_origin: f64,
}

/// Everything the scope holds.
#[derive(Debug, Clone, PartialEq)]
pub struct UxrState {
    pub headers: bool,
    pub word_format: bool,
    pub lsb_first: bool,
    pub channels: Vec<ChannelSettings>,
    pub segmented: bool,
    pub segment_count: u32,
    pub all_segments: bool,
    /// 1-based segment `:WAVeform:DATA?` returns when not all of them.
    pub segment_index: u32,
    pub sample_rate: f64,
    pub points: u64,
    pub position_s: f64,
    pub trigger_source: String,
    pub trigger_level_v: f64,
    pub trigger_positive: bool,
    pub external_reference: bool,
    pub waveform_source: u8,
    pub armed: bool,
    /// The Acquisition Done Event Register (cleared by reading it).
    pub done: bool,
    pub records: Vec<Option<Record>>,
    pub time_tags: Vec<f64>,
    pub acquisitions: u64,
}

impl UxrState {
    fn reset(limits: &Limits) -> UxrState {
        UxrState {
            headers: true,
            word_format: false,
            lsb_first: false,
            channels: (0..limits.channels)
                .map(|_| ChannelSettings {
                    display: false,
                    scale_v: limits.volts_per_div_default,
                    offset_v: 0.0,
                })
                .collect(),
            segmented: false,
            segment_count: 2,
            all_segments: false,
            segment_index: 1,
            sample_rate: limits.sample_rates.first().copied().unwrap_or(1e9),
            points: 1000,
            position_s: 0.0,
            trigger_source: "CHAN1".into(),
            trigger_level_v: 0.0,
            trigger_positive: true,
            external_reference: false,
            waveform_source: 1,
            armed: false,
            done: false,
            records: vec![None; usize::from(limits.channels)],
            time_tags: Vec::new(),
            acquisitions: 0,
        }
    }
}

/// The emulated scope.
pub struct KeysightUxr {
    identity: EmulatorIdentity,
    limits: Limits,
    inner: Mutex<Inner>,
    source: Arc<dyn TriggerSource>,
    log: ReceivedLog,
}

struct Inner {
    state: UxrState,
    errors: ErrorQueue,
}

fn err(code: i32, detail: impl AsRef<str>) -> ScpiError {
    ScpiError::new(code, detail)
}

fn text_param(params: &[Param], k: usize) -> Result<&str, ScpiError> {
    params
        .get(k)
        .and_then(Param::text)
        .ok_or_else(|| err(-109, "a parameter is missing"))
}

fn number(text: &str) -> Result<f64, ScpiError> {
    text.trim()
        .parse::<f64>()
        .ok()
        .filter(|v| v.is_finite())
        .ok_or_else(|| err(-104, format!("{text:?} is not a number")))
}

fn in_range(value: f64, min: f64, max: f64, what: &str) -> Result<f64, ScpiError> {
    if value >= min && value <= max {
        Ok(value)
    } else {
        Err(err(
            -222,
            format!("{what} {value} is outside {min} ..= {max}"),
        ))
    }
}

/// The `#<d><len>` header of a definite-length block.
fn block(payload: &[u8]) -> Vec<u8> {
    let len = payload.len().to_string();
    let mut out = format!("#{}{len}", len.len()).into_bytes();
    out.extend_from_slice(payload);
    out
}

impl KeysightUxr {
    /// The built-in UXR model whose inputs see `source`.
    pub fn embedded_with(source: Arc<dyn TriggerSource>) -> Result<KeysightUxr, CatalogError> {
        let file: CatalogFile = toml::from_str(CATALOG).map_err(|source| CatalogError::Toml {
            what: "the Keysight UXR",
            source,
        })?;
        if file.digitizer.channels < 2 || file.digitizer.sample_rates.is_empty() {
            return Err(CatalogError::Invalid {
                what: "the Keysight UXR",
                field: "digitizer".into(),
                reason: "the emulator needs two channels and a sample rate".into(),
            });
        }
        Ok(KeysightUxr {
            inner: Mutex::new(Inner {
                state: UxrState::reset(&file.digitizer),
                errors: ErrorQueue::new(30),
            }),
            identity: file.identity.emulator,
            limits: file.digitizer,
            source,
            log: ReceivedLog::new("keysight-uxr", 1000),
        })
    }

    /// The emulator with a test signal (marker present, 1 GHz tone).
    pub fn embedded() -> Result<KeysightUxr, CatalogError> {
        KeysightUxr::embedded_with(Arc::new(super::lecroy::TestSignal::default()))
    }

    pub fn limits(&self) -> &Limits {
        &self.limits
    }

    pub fn log(&self) -> &ReceivedLog {
        &self.log
    }

    /// A copy of the settings and the last acquisition.
    pub fn state(&self) -> UxrState {
        self.lock().state.clone()
    }

    fn lock(&self) -> MutexGuard<'_, Inner> {
        self.inner.lock().unwrap_or_else(|e| e.into_inner())
    }

    fn request(&self, s: &UxrState) -> AcquisitionRequest {
        // The auxiliary input is the bench's external trigger input.
        let source = if s.trigger_source.eq_ignore_ascii_case("AUX") {
            "EX".to_string()
        } else {
            s.trigger_source.clone()
        };
        AcquisitionRequest {
            sample_rate: s.sample_rate,
            points: s.points as usize,
            first_point_s: s.position_s,
            trigger: TriggerSetup {
                source,
                level_v: s.trigger_level_v,
                slope: if s.trigger_positive {
                    Slope::Positive
                } else {
                    Slope::Negative
                },
            },
            channels_on: s.channels.iter().map(|c| c.display).collect(),
        }
    }

    /// Looks at the inputs once (or until `deadline`); records the acquisition when an edge came.
    fn try_acquire(&self, inner: &mut Inner, deadline: Instant) -> bool {
        let s = &inner.state;
        let request = self.request(s);
        let segments = if s.segmented { s.segment_count } else { 1 };
        let Some(first) = self.source.acquire(&request, deadline) else {
            return false;
        };
        let period = first.edge_period_s.unwrap_or(DEFAULT_EDGE_PERIOD_S);
        let mut captures = vec![first];
        for _ in 1..segments {
            // The edges repeat with the looped segment: each later segment is the next edge.
            match self.source.acquire(&request, Instant::now()) {
                Some(c) => captures.push(c),
                None => return false,
            }
        }
        let s = &mut inner.state;
        let bits = u32::from(self.limits.adc_bits.clamp(1, 16));
        let step = 1i32 << (16 - bits);
        s.records = s
            .channels
            .iter()
            .enumerate()
            .map(|(k, ch)| {
                if !ch.display {
                    return None;
                }
                let full = f64::from(self.limits.vertical_divisions) * ch.scale_v;
                let y_increment = full / 65536.0;
                let codes = captures
                    .iter()
                    .map(|c| {
                        let volts = c.channels.get(k).cloned().flatten();
                        (0..s.points as usize)
                            .map(|n| {
                                let v = volts
                                    .as_ref()
                                    .and_then(|v| v.get(n))
                                    .copied()
                                    .unwrap_or(0.0);
                                let code = ((f64::from(v) - ch.offset_v) / y_increment).round();
                                let code = code.clamp(-32768.0, f64::from(32767 - (step - 1)));
                                let code = code as i32;
                                (code.div_euclid(step) * step) as i16
                            })
                            .collect()
                    })
                    .collect();
                Some(Record {
                    codes,
                    y_increment,
                    y_origin: ch.offset_v,
                })
            })
            .collect();
        s.time_tags = (0..captures.len()).map(|k| k as f64 * period).collect();
        s.armed = false;
        s.done = true;
        s.acquisitions += 1;
        true
    }

    fn preamble(&self, s: &UxrState) -> Result<String, ScpiError> {
        let record = s
            .records
            .get(usize::from(s.waveform_source.saturating_sub(1)))
            .cloned()
            .flatten()
            .ok_or_else(|| err(-230, "no acquisition of this source"))?;
        let format = if s.word_format { 2 } else { 1 };
        let points = s.points;
        let x_inc = 1.0 / s.sample_rate;
        Ok(format!(
            "{format},1,{points},1,{},{},0,{},{},0,1,{},{},{},{},\"27 NOV 2026\",\"00:00:00:00\",\"{}\",1,100,2,1,{},{}",
            nr3(x_inc),
            nr3(s.position_s),
            nr3(record.y_increment),
            nr3(record.y_origin),
            nr3(points as f64 * x_inc),
            nr3(s.position_s),
            nr3(record.y_increment * 65536.0),
            nr3(record.y_origin),
            self.identity.model,
            nr3(33e9),
            nr3(0.0),
        ))
    }

    fn data(&self, s: &UxrState) -> Result<Vec<u8>, ScpiError> {
        if !s.word_format {
            return Err(err(
                -221,
                "the emulator sends WORD data only (:WAVeform:FORMat WORD)",
            ));
        }
        let record = s
            .records
            .get(usize::from(s.waveform_source.saturating_sub(1)))
            .cloned()
            .flatten()
            .ok_or_else(|| err(-230, "no acquisition of this source"))?;
        let segments: Vec<&Vec<i16>> = if s.segmented && s.all_segments {
            record.codes.iter().collect()
        } else {
            let k = s.segment_index.saturating_sub(1) as usize;
            record.codes.get(k).into_iter().collect()
        };
        let mut payload = Vec::new();
        for seg in segments {
            for &c in seg {
                let b = if s.lsb_first {
                    c.to_le_bytes()
                } else {
                    c.to_be_bytes()
                };
                payload.extend_from_slice(&b);
            }
        }
        Ok(block(&payload))
    }

    /// Runs one program message unit; `Some` is a response.
    fn unit(&self, inner: &mut Inner, text: &[u8]) -> Result<Option<Vec<u8>>, ScpiError> {
        let unit = parse_unit(text)?;
        let h = unit.header.to_ascii_uppercase();
        let p = &unit.params;
        let l = &self.limits;
        let reply = |s: String| Ok(Some(s.into_bytes()));
        match h.as_str() {
            "*IDN?" => return reply(self.identity.idn()),
            "*OPC?" => return reply("1".into()),
            "*CLS" => {
                inner.errors.clear();
                inner.state.done = false;
                return Ok(None);
            }
            "*RST" => {
                inner.state = UxrState::reset(l);
                return Ok(None);
            }
            "*ESR?" => return reply("0".into()),
            _ => {}
        }
        let header = Header::parse(&unit.header)?;
        let is = |pattern: &str| Pattern::new(pattern).matches(&header.nodes);
        let s = &mut inner.state;
        let q = header.query;
        if is(":SYSTem:ERRor").is_some() && q {
            let e = inner.errors.pop();
            return reply(e.reply());
        }
        if is(":SYSTem:HEADer").is_some() {
            if q {
                return reply(if s.headers { "1" } else { "0" }.into());
            }
            s.headers = boolean(text_param(p, 0)?)?;
        } else if is(":WAVeform:FORMat").is_some() {
            if q {
                return reply(if s.word_format { "WORD" } else { "BYTE" }.into());
            }
            let k = keyword(text_param(p, 0)?, &[("WORD", "WORD"), ("BYTE", "BYTE")])?;
            s.word_format = k == "WORD";
        } else if is(":WAVeform:BYTeorder").is_some() {
            if q {
                return reply(if s.lsb_first { "LSBF" } else { "MSBF" }.into());
            }
            let k = keyword(
                text_param(p, 0)?,
                &[("LSBF", "LSBFIRST"), ("MSBF", "MSBFIRST")],
            )?;
            s.lsb_first = k == "LSBF";
        } else if is(":WAVeform:STReaming").is_some() {
            if q {
                return reply("0".into());
            }
            boolean(text_param(p, 0)?)?;
        } else if let Some(sfx) = is(":CHANnel#:DISPlay") {
            let ch = self.channel(s, sfx[0])?;
            if q {
                return reply(if ch.display { "1" } else { "0" }.into());
            }
            ch.display = boolean(text_param(p, 0)?)?;
        } else if let Some(sfx) = is(":CHANnel#:SCALe") {
            let ch = self.channel(s, sfx[0])?;
            if q {
                return reply(nr3(ch.scale_v));
            }
            ch.scale_v = in_range(
                number(text_param(p, 0)?)?,
                l.volts_per_div_min,
                l.volts_per_div_max,
                "scale",
            )?;
        } else if let Some(sfx) = is(":CHANnel#:OFFSet") {
            let ch = self.channel(s, sfx[0])?;
            if q {
                return reply(nr3(ch.offset_v));
            }
            ch.offset_v = in_range(
                number(text_param(p, 0)?)?,
                l.offset_v_min,
                l.offset_v_max,
                "offset",
            )?;
        } else if is(":ACQuire:MODE").is_some() {
            if q {
                return reply(if s.segmented { "SEGM" } else { "RTIM" }.into());
            }
            let k = keyword(
                text_param(p, 0)?,
                &[("RTIM", "RTIME"), ("SEGM", "SEGMENTED")],
            )?;
            s.segmented = k == "SEGM";
        } else if is(":ACQuire:SEGMented:COUNt").is_some() {
            if q {
                return reply(s.segment_count.to_string());
            }
            let n = unsigned(text_param(p, 0)?)?;
            let max = u64::from(l.max_sequence_segments.max(2));
            s.segment_count = in_range(n as f64, 2.0, max as f64, "segment count")? as u32;
        } else if is(":ACQuire:SEGMented:INDex").is_some() {
            if q {
                return reply(s.segment_index.to_string());
            }
            let n = unsigned(text_param(p, 0)?)?;
            s.segment_index =
                in_range(n as f64, 1.0, f64::from(s.segment_count), "segment")? as u32;
        } else if is(":WAVeform:SEGMented:ALL").is_some() {
            if q {
                return reply(if s.all_segments { "1" } else { "0" }.into());
            }
            s.all_segments = boolean(text_param(p, 0)?)?;
        } else if is(":WAVeform:SEGMented:XLISt").is_some() && q {
            let what = text_param(p, 0).unwrap_or("TTAG");
            keyword(what, &[("TTAG", "TTAG")])?;
            let tags: Vec<String> = s.time_tags.iter().map(|t| nr3(*t)).collect();
            return reply(tags.join(","));
        } else if is(":ACQuire:SRATe[:ANALog]").is_some() {
            if q {
                return reply(nr3(s.sample_rate));
            }
            let rate = number(text_param(p, 0)?)?;
            if !l.sample_rates.iter().any(|r| (r - rate).abs() <= 1e-9 * r) {
                return Err(err(
                    -222,
                    format!("sample rate {rate} is not one of {:?}", l.sample_rates),
                ));
            }
            s.sample_rate = rate;
        } else if is(":ACQuire:POINts[:ANALog]").is_some() {
            if q {
                return reply(s.points.to_string());
            }
            let n = unsigned(text_param(p, 0)?)?;
            s.points = in_range(n as f64, 16.0, l.max_points_per_channel as f64, "points")? as u64;
        } else if is(":TIMebase:REFerence").is_some() {
            if q {
                return reply("LEFT".into());
            }
            keyword(
                text_param(p, 0)?,
                &[("LEFT", "LEFT"), ("CENT", "CENTER"), ("RIGH", "RIGHT")],
            )?;
        } else if is(":TIMebase:SCALe").is_some() {
            if q {
                return reply(nr3(s.points as f64 / s.sample_rate / 10.0));
            }
            number(text_param(p, 0)?)?;
        } else if is(":TIMebase:POSition").is_some() {
            if q {
                return reply(nr3(s.position_s));
            }
            s.position_s = number(text_param(p, 0)?)?;
        } else if is(":TIMebase:REFClock").is_some() {
            if q {
                return reply(if s.external_reference { "1" } else { "0" }.into());
            }
            s.external_reference = boolean(text_param(p, 0)?)?;
        } else if is(":TRIGger:MODE").is_some() {
            if q {
                return reply("EDGE".into());
            }
            keyword(text_param(p, 0)?, &[("EDGE", "EDGE")])?;
        } else if is(":TRIGger:SWEep").is_some() {
            if q {
                return reply("TRIG".into());
            }
            keyword(
                text_param(p, 0)?,
                &[("TRIG", "TRIGGERED"), ("AUTO", "AUTO"), ("SING", "SINGLE")],
            )?;
        } else if is(":TRIGger:EDGE:SOURce").is_some() {
            if q {
                return reply(s.trigger_source.clone());
            }
            let k = keyword(
                text_param(p, 0)?,
                &[("AUX", "AUX"), ("CHAN1", "CHANNEL1"), ("CHAN2", "CHANNEL2")],
            )?;
            s.trigger_source = k.to_string();
        } else if is(":TRIGger:EDGE:SLOPe").is_some() {
            if q {
                return reply(if s.trigger_positive { "POS" } else { "NEG" }.into());
            }
            let k = keyword(
                text_param(p, 0)?,
                &[("POS", "POSITIVE"), ("NEG", "NEGATIVE")],
            )?;
            s.trigger_positive = k == "POS";
        } else if is(":TRIGger:LEVel").is_some() {
            let src = text_param(p, 0)?;
            keyword(src, &[("AUX", "AUX")])?;
            if q {
                return reply(nr3(s.trigger_level_v));
            }
            s.trigger_level_v = in_range(
                number(text_param(p, 1)?)?,
                l.ext_trigger_level_v_min,
                l.ext_trigger_level_v_max,
                "AUX trigger level",
            )?;
        } else if is(":WAVeform:SOURce").is_some() {
            if q {
                return reply(format!("CHAN{}", s.waveform_source));
            }
            let t = text_param(p, 0)?.to_ascii_uppercase();
            let n = t
                .strip_prefix("CHANNEL")
                .or_else(|| t.strip_prefix("CHAN"))
                .and_then(|d| d.parse::<u8>().ok())
                .filter(|n| (1..=l.channels).contains(n))
                .ok_or_else(|| {
                    err(
                        -224,
                        format!("{t:?} is not CHANnel1 ..= CHANnel{}", l.channels),
                    )
                })?;
            s.waveform_source = n;
        } else if is(":WAVeform:PREamble").is_some() && q {
            return self.preamble(s).map(|t| Some(t.into_bytes()));
        } else if is(":WAVeform:DATA").is_some() && q {
            return self.data(s).map(Some);
        } else if is(":ADER").is_some() && q {
            if s.armed {
                self.try_acquire(inner, Instant::now());
            }
            let s = &mut inner.state;
            let done = std::mem::take(&mut s.done);
            return reply(if done { "1" } else { "0" }.into());
        } else if is(":SINGle").is_some() {
            s.armed = true;
            s.done = false;
        } else if is(":STOP").is_some() {
            s.armed = false;
        } else if is(":DIGitize").is_some() {
            s.armed = true;
            s.done = false;
            if !self.try_acquire(inner, Instant::now() + DIGITIZE_WAIT) {
                inner.state.armed = false;
                return Err(err(-200, "no trigger within the emulator's DIGitize wait"));
            }
        } else {
            return Err(err(-113, format!("{:?}", unit.header)));
        }
        Ok(None)
    }

    fn channel<'a>(
        &self,
        s: &'a mut UxrState,
        suffix: u32,
    ) -> Result<&'a mut ChannelSettings, ScpiError> {
        let n = s.channels.len();
        usize::try_from(suffix)
            .ok()
            .and_then(|k| k.checked_sub(1))
            .and_then(|k| s.channels.get_mut(k))
            .ok_or_else(|| err(-114, format!("CHANnel{suffix}: allowed 1 ..= {n}")))
    }

    /// Runs a whole program message; returns its responses joined by `;` (one message).
    pub fn execute(&self, message: &[u8]) -> Option<Vec<u8>> {
        self.log.record(message);
        let mut inner = self.lock();
        let units = match split_units(message) {
            Ok(u) => u,
            Err(e) => {
                inner.errors.push(e);
                return None;
            }
        };
        let mut out: Vec<Vec<u8>> = Vec::new();
        for unit in units {
            match self.unit(&mut inner, unit) {
                Ok(Some(r)) => out.push(r),
                Ok(None) => {}
                Err(e) => {
                    let abort = e.is_command_error();
                    inner.errors.push(e);
                    if abort {
                        break;
                    }
                }
            }
        }
        if out.is_empty() {
            return None;
        }
        Some(out.join(&b";"[..]))
    }
}

impl Handler for KeysightUxr {
    fn message(&self, data: &[u8]) -> Vec<Vec<u8>> {
        self.execute(data).map(|r| vec![r]).unwrap_or_default()
    }

    fn device_clear(&self) {
        self.lock().state.armed = false;
    }
}

#[cfg(test)]
mod tests;
