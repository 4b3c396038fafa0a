//! The VBS automation statements a driver uses (instruments.md section 2.4):
//! `VBS 'app.X.Y = value'` sets, `VBS? 'return = app.X.Y'` reads, `return = app.Acquisition.acquire(t, force)`
//! arms, waits and answers 1 (triggered) or 0 (timed out). Property names are case-insensitive.
//! `SampleMode = "Sequence"` with `NumSegments = N` makes one acquisition record N triggers.

use std::time::{Duration, Instant};

use super::params::adapt;
use super::state::{SampleMode, ScopeState, TriggerMode};
use super::trigger::Slope;
use super::{Fault, Lecroy};
use crate::catalog::DigitizerModel;

fn not_implemented(what: &str) -> Fault {
    Fault::Execution(
        26,
        format!("automation: {what} is not implemented by the emulator"),
    )
}

fn bad_value(what: &str, value: &str) -> Fault {
    Fault::Execution(
        25,
        format!("automation: {value:?} is not a valid value for {what}"),
    )
}

/// A VBS literal: a number, a quoted string or a boolean.
fn literal(raw: &str) -> String {
    raw.trim().trim_matches('"').trim().to_string()
}

fn number(what: &str, raw: &str) -> Result<f64, Fault> {
    let text = literal(raw);
    // Accept "80 GS/s", "1.024e-7", "80e9".
    let lower = text.to_ascii_lowercase().replace(' ', "");
    let (digits, mult) = if let Some(d) = lower.strip_suffix("gs/s") {
        (d.to_string(), 1e9)
    } else if let Some(d) = lower.strip_suffix("ms/s") {
        (d.to_string(), 1e6)
    } else if let Some(d) = lower.strip_suffix("s/s") {
        (d.to_string(), 1.0)
    } else {
        (lower, 1.0)
    };
    digits
        .parse::<f64>()
        .ok()
        .filter(|v| v.is_finite())
        .map(|v| v * mult)
        .ok_or_else(|| bad_value(what, &text))
}

fn vb_number(v: f64) -> String {
    format!("{v}")
}

impl Lecroy {
    pub(super) fn vbs(&self, statement: &str, query: bool) -> Result<Option<String>, Fault> {
        let (lhs, rhs) = statement
            .split_once('=')
            .map(|(l, r)| (l.trim(), r.trim()))
            .ok_or_else(|| {
                Fault::Execution(24, format!("automation: cannot parse {statement:?}"))
            })?;
        if lhs.eq_ignore_ascii_case("return") {
            if !query {
                return Err(Fault::Execution(
                    24,
                    "automation: `return = ...` needs VBS?".into(),
                ));
            }
            return self.vbs_read(rhs).map(Some);
        }
        self.vbs_write(lhs, rhs)?;
        // `VBS? '<assignment>'` (scopehal does this) answers with an empty value.
        Ok(query.then(String::new))
    }

    fn vbs_read(&self, expr: &str) -> Result<String, Fault> {
        let key = expr.to_ascii_lowercase().replace(' ', "");
        if let Some(args) = key
            .strip_prefix("app.acquisition.acquire(")
            .and_then(|a| a.strip_suffix(')'))
        {
            return self.vbs_acquire(args);
        }
        if key == "app.acquisition.triggermode" {
            self.settle(Instant::now());
        }
        let st = self.lock();
        let rate = ScopeState::sample_rate(&self.model);
        let value = match key.as_str() {
            "app.acquisition.horizontal.samplingrate" | "app.acquisition.horizontal.samplerate" => {
                vb_number(rate)
            }
            "app.acquisition.horizontal.maximize" => st.maximize.clone(),
            "app.acquisition.horizontal.horscale" => vb_number(st.hor_scale),
            "app.acquisition.horizontal.numpoints" => st.record_points(&self.model).to_string(),
            "app.acquisition.horizontal.maxsamples" => st.max_samples.to_string(),
            "app.acquisition.horizontal.acquisitionduration" => {
                vb_number(st.record_points(&self.model) as f64 / rate)
            }
            "app.acquisition.horizontal.samplemode" => st.sample_mode.automation().into(),
            "app.acquisition.horizontal.numsegments" => st.segments.to_string(),
            "app.acquisition.triggermode" => st.trigger_mode.automation().into(),
            "app.acquisition.trigger.type" => "Edge".into(),
            "app.acquisition.trigger.source" => automation_source(&st.trigger_source),
            "app.acquisition.trigger.edge.level" => vb_number(st.level(&st.trigger_source)),
            "app.acquisition.trigger.edge.slope" => match st.slope(&st.trigger_source) {
                Slope::Positive => "Positive",
                Slope::Negative => "Negative",
                Slope::Either => "Either",
            }
            .into(),
            "app.acquisition.istriggerready" => if st.armed { "True" } else { "False" }.into(),
            _ => return Err(not_implemented(expr)),
        };
        Ok(value)
    }

    fn vbs_acquire(&self, args: &str) -> Result<String, Fault> {
        let mut parts = args.split(',');
        let timeout = parts
            .next()
            .filter(|t| !t.is_empty())
            .map(|t| number("acquire timeout", t))
            .transpose()?
            .unwrap_or(self.wait_cap().as_secs_f64());
        let force = parts
            .next()
            .map(|f| {
                matches!(
                    literal(f).to_ascii_lowercase().as_str(),
                    "true" | "1" | "-1"
                )
            })
            .unwrap_or(false);
        if timeout.is_nan() || timeout < 0.0 {
            return Err(bad_value("acquire timeout", &timeout.to_string()));
        }
        let arm_id = {
            let mut st = self.lock();
            st.set_trigger_mode(TriggerMode::Single);
            st.arm_id
        };
        let limit = Duration::from_secs_f64(timeout.min(self.wait_cap().as_secs_f64()));
        self.settle(Instant::now() + limit);
        let triggered = self.lock().completed_arm_id == arm_id;
        if !triggered && force {
            self.force();
        }
        Ok(if triggered { "1" } else { "0" }.into())
    }

    fn vbs_write(&self, lhs: &str, rhs: &str) -> Result<(), Fault> {
        let key = lhs.to_ascii_lowercase().replace(' ', "");
        let (_, set) = SETTERS
            .iter()
            .find(|(property, _)| *property == key)
            .ok_or_else(|| not_implemented(lhs))?;
        set(&self.model, &mut self.lock(), lhs, rhs)
    }
}

fn automation_source(source: &str) -> String {
    match source {
        "EX" => "Ext".into(),
        "EX10" => "Ext10".into(),
        "LINE" => "Line".into(),
        other => other.into(),
    }
}

/// Sets one automation property (`lhs` as the client wrote it, for messages; `rhs` its value).
type Setter = fn(&DigitizerModel, &mut ScopeState, &str, &str) -> Result<(), Fault>;

/// The automation properties a client may set, lower case without spaces.
const SETTERS: &[(&str, Setter)] = &[
    (
        "app.acquisition.horizontal.samplerate",
        set_horizontal_samplerate,
    ),
    (
        "app.acquisition.horizontal.maximize",
        set_horizontal_maximize,
    ),
    (
        "app.acquisition.horizontal.horscale",
        set_horizontal_horscale,
    ),
    (
        "app.acquisition.horizontal.maxsamples",
        set_horizontal_maxsamples,
    ),
    (
        "app.acquisition.horizontal.samplemode",
        set_horizontal_samplemode,
    ),
    (
        "app.acquisition.horizontal.numsegments",
        set_horizontal_numsegments,
    ),
    ("app.acquisition.triggermode", set_triggermode),
    ("app.acquisition.trigger.type", set_trigger_type),
    ("app.acquisition.trigger.source", set_trigger_source),
    ("app.acquisition.trigger.edge.level", set_trigger_edge_level),
    ("app.acquisition.trigger.edge.slope", set_trigger_edge_slope),
];

fn set_horizontal_samplerate(
    model: &DigitizerModel,
    st: &mut ScopeState,
    lhs: &str,
    rhs: &str,
) -> Result<(), Fault> {
    let wanted = number(lhs, rhs)?;
    if wanted != ScopeState::sample_rate(model) {
        // The scope adapts to its fixed rate; SamplingRate reads back what it uses.
        st.value_adapted = true;
    }
    st.requested_rate = wanted;
    Ok(())
}

fn set_horizontal_maximize(
    _: &DigitizerModel,
    st: &mut ScopeState,
    lhs: &str,
    rhs: &str,
) -> Result<(), Fault> {
    let v = literal(rhs);
    match v.to_ascii_lowercase().as_str() {
        "fixedsamplerate" => st.maximize = "FixedSampleRate".into(),
        "setmaximummemory" => st.maximize = "SetMaximumMemory".into(),
        _ => return Err(bad_value(lhs, &v)),
    }
    Ok(())
}

fn set_horizontal_horscale(
    model: &DigitizerModel,
    st: &mut ScopeState,
    lhs: &str,
    rhs: &str,
) -> Result<(), Fault> {
    let v = number(lhs, rhs)?;
    if v <= 0.0 {
        return Err(bad_value(lhs, rhs));
    }
    st.set_hor_scale(model, v);
    Ok(())
}

fn set_horizontal_maxsamples(
    model: &DigitizerModel,
    st: &mut ScopeState,
    lhs: &str,
    rhs: &str,
) -> Result<(), Fault> {
    let limits = &model.limits;
    let v = number(lhs, rhs)?;
    let max = limits.max_points_per_channel as f64;
    st.max_samples = adapt(st, v, 1.0, max).round() as u64;
    Ok(())
}

fn set_horizontal_samplemode(
    model: &DigitizerModel,
    st: &mut ScopeState,
    _: &str,
    rhs: &str,
) -> Result<(), Fault> {
    let limits = &model.limits;
    let v = literal(rhs);
    st.sample_mode = match v.to_ascii_lowercase().as_str() {
        "realtime" => SampleMode::RealTime,
        "sequence" if limits.max_sequence_segments > 1 => SampleMode::Sequence,
        "sequence" => return Err(not_implemented("SampleMode Sequence on this model")),
        _ => return Err(not_implemented(&format!("SampleMode {v}"))),
    };
    Ok(())
}

fn set_horizontal_numsegments(
    model: &DigitizerModel,
    st: &mut ScopeState,
    lhs: &str,
    rhs: &str,
) -> Result<(), Fault> {
    let limits = &model.limits;
    let v = number(lhs, rhs)?;
    if v.fract() != 0.0 {
        return Err(bad_value(lhs, rhs));
    }
    // The scope adapts a count out of range to the nearest it can do.
    let max = f64::from(limits.max_sequence_segments.max(2));
    st.segments = adapt(st, v, 2.0, max) as u32;
    Ok(())
}

fn set_triggermode(
    _: &DigitizerModel,
    st: &mut ScopeState,
    lhs: &str,
    rhs: &str,
) -> Result<(), Fault> {
    let v = literal(rhs);
    let mode = match v.to_ascii_lowercase().as_str() {
        "single" => TriggerMode::Single,
        "normal" => TriggerMode::Normal,
        "auto" => TriggerMode::Auto,
        "stopped" | "stop" => TriggerMode::Stop,
        _ => return Err(bad_value(lhs, &v)),
    };
    st.set_trigger_mode(mode);
    Ok(())
}

fn set_trigger_type(
    _: &DigitizerModel,
    st: &mut ScopeState,
    _: &str,
    rhs: &str,
) -> Result<(), Fault> {
    let v = literal(rhs);
    if !v.eq_ignore_ascii_case("edge") {
        return Err(not_implemented(&format!("trigger type {v}")));
    }
    st.trigger_type = "EDGE".into();
    Ok(())
}

fn set_trigger_source(
    model: &DigitizerModel,
    st: &mut ScopeState,
    lhs: &str,
    rhs: &str,
) -> Result<(), Fault> {
    let limits = &model.limits;
    let v = literal(rhs).to_ascii_uppercase();
    let source = match v.as_str() {
        "EXT" => "EX".to_string(),
        "EXT10" => "EX10".to_string(),
        other => other.to_string(),
    };
    if !limits.trigger_sources.contains(&source) {
        return Err(bad_value(lhs, &v));
    }
    st.trigger_source = source;
    Ok(())
}

fn set_trigger_edge_level(
    model: &DigitizerModel,
    st: &mut ScopeState,
    lhs: &str,
    rhs: &str,
) -> Result<(), Fault> {
    let limits = &model.limits;
    let v = number(lhs, rhs)?;
    let source = st.trigger_source.clone();
    let (min, max) = if source.starts_with("EX") {
        let scale = if source == "EX10" { 10.0 } else { 1.0 };
        (
            limits.ext_trigger_level_v_min * scale,
            limits.ext_trigger_level_v_max * scale,
        )
    } else {
        (f64::MIN, f64::MAX)
    };
    let level = adapt(st, v, min, max);
    st.set_level(&source, level);
    Ok(())
}

fn set_trigger_edge_slope(
    _: &DigitizerModel,
    st: &mut ScopeState,
    lhs: &str,
    rhs: &str,
) -> Result<(), Fault> {
    let v = literal(rhs);
    let slope = match v.to_ascii_lowercase().as_str() {
        "positive" => Slope::Positive,
        "negative" => Slope::Negative,
        "either" => Slope::Either,
        _ => return Err(bad_value(lhs, &v)),
    };
    let source = st.trigger_source.clone();
    st.set_slope(&source, slope);
    Ok(())
}
