//! Semantic checks of one instrument model: ranges ordered, defaults inside their ranges, channels
//! that exist, the sections a kind needs, a register map the RF drivers can rely on.
//!
//! Each check yields `(field path, reason)`; the loader adds the file name and line.

use std::collections::HashSet;

use super::identity::pattern_matches;
use super::schema::*;

/// Registers every RF front end must define (the driver and the emulator address them by name).
pub(crate) const REQUIRED_RF_REGISTERS: [&str; 6] = [
    "ID",
    "STATUS",
    "CONTROL",
    "GAIN_ATT",
    "TEMP_DC",
    "FAULT_LATCH",
];

/// Named bits the RF driver relies on, per register.
pub(crate) const REQUIRED_RF_FIELDS: [(&str, &str); 6] = [
    ("STATUS", "LO_LOCKED"),
    ("STATUS", "RF_ENABLED"),
    ("STATUS", "OVER_TEMPERATURE"),
    ("STATUS", "INTERLOCK_OPEN"),
    ("CONTROL", "MASTER_ENABLE"),
    ("CONTROL", "AMP_ENABLE"),
];

/// Error names of the line protocol the RF driver maps to its own errors.
pub(crate) const REQUIRED_PROTOCOL_ERRORS: [&str; 6] = [
    "syntax",
    "unknown_register",
    "read_only",
    "out_of_range",
    "not_allowed",
    "crc",
];

/// Collected problems: `(field path, reason)`.
#[derive(Default)]
struct Checks(Vec<(String, String)>);

impl Checks {
    fn fail(&mut self, field: impl Into<String>, reason: impl Into<String>) {
        self.0.push((field.into(), reason.into()));
    }

    fn positive(&mut self, field: &str, value: f64) {
        if !(value.is_finite() && value > 0.0) {
            self.fail(field, format!("must be a positive number (got {value})"));
        }
    }

    /// `min < max`, both finite; reported on the `max` field.
    fn ordered(&mut self, min_field: &str, min: f64, max_field: &str, max: f64) {
        if !(min.is_finite() && max.is_finite() && min < max) {
            self.fail(
                max_field,
                format!("must be greater than `{min_field}` ({min}) (got {max})"),
            );
        }
    }

    /// A count or width in `1..=max`.
    fn count(&mut self, field: &str, value: u8, max: u8) -> bool {
        let ok = (1..=max).contains(&value);
        if !ok {
            self.fail(field, format!("must be 1..={max} (got {value})"));
        }
        ok
    }

    fn within(&mut self, field: &str, value: f64, min: f64, max: f64) {
        if !(value >= min && value <= max) {
            self.fail(field, format!("must lie in {min} ..= {max} (got {value})"));
        }
    }
}

/// Checks a parsed model; returns `(field, reason)` for every problem found.
pub(super) fn validate(model: &InstrumentModel) -> Vec<(String, String)> {
    let mut c = Checks::default();
    if model.schema != SCHEMA_VERSION {
        c.fail(
            "schema",
            format!(
                "this radbench reads catalog schema {SCHEMA_VERSION} (got {})",
                model.schema
            ),
        );
    }
    check_info(&mut c, &model.instrument);
    check_identity(&mut c, &model.identity);
    check_transports(&mut c, &model.transports);
    check_timeouts(&mut c, &model.timeouts);
    check_sections(&mut c, model);
    if let Some(awg) = &model.awg {
        check_awg(&mut c, awg);
    }
    if let Some(digitizer) = &model.digitizer {
        check_digitizer(&mut c, digitizer);
    }
    if let Some(rf) = &model.rf {
        check_rf(&mut c, rf, model.instrument.kind);
    }
    if let Some(serial) = &model.serial {
        check_serial(&mut c, serial);
    }
    if let Some(protocol) = &model.protocol {
        check_protocol(&mut c, protocol);
    }
    check_registers(&mut c, &model.registers);
    c.0
}

fn check_info(c: &mut Checks, info: &Info) {
    let key_ok = !info.key.is_empty()
        && info
            .key
            .chars()
            .all(|ch| ch.is_ascii_lowercase() || ch.is_ascii_digit() || ch == '-');
    if !key_ok {
        c.fail(
            "instrument.key",
            format!(
                "must be non-empty lowercase letters, digits and '-' (got {:?})",
                info.key
            ),
        );
    }
    for (field, value) in [
        ("instrument.manufacturer", &info.manufacturer),
        ("instrument.model", &info.model),
    ] {
        if value.trim().is_empty() {
            c.fail(field, "must not be empty");
        }
    }
}

fn check_identity(c: &mut Checks, identity: &Identity) {
    for (name, patterns) in [
        ("manufacturer", &identity.manufacturer),
        ("model", &identity.model),
    ] {
        if patterns.is_empty() {
            c.fail(
                format!("identity.{name}"),
                "needs at least one *IDN? pattern",
            );
        }
        for (i, pattern) in patterns.iter().enumerate() {
            if pattern.trim().is_empty() || pattern.contains(',') {
                c.fail(
                    format!("identity.{name}[{i}]"),
                    format!("a pattern must be non-empty and contain no ',' (got {pattern:?})"),
                );
            }
        }
    }
    let emu = &identity.emulator;
    for (name, value) in [
        ("manufacturer", &emu.manufacturer),
        ("model", &emu.model),
        ("serial", &emu.serial),
        ("firmware", &emu.firmware),
    ] {
        if value.trim().is_empty() || value.contains(',') {
            c.fail(
                format!("identity.emulator.{name}"),
                format!("must be non-empty and contain no ',' (got {value:?})"),
            );
        }
    }
    if identity
        .manufacturer
        .iter()
        .any(|p| pattern_matches(p, &emu.manufacturer))
    {
        c.fail(
            "identity.emulator.manufacturer",
            format!(
                "the emulator must not identify as the vendor: {:?} matches a vendor pattern",
                emu.manufacturer
            ),
        );
    }
}

fn check_transports(c: &mut Checks, transports: &[TransportSpec]) {
    if transports.is_empty() {
        c.fail("transport", "needs at least one [[transport]]");
    }
    if transports.iter().filter(|t| t.preferred).count() > 1 {
        c.fail(
            "transport",
            "at most one transport may be `preferred = true`",
        );
    }
    let mut seen = HashSet::new();
    for (i, t) in transports.iter().enumerate() {
        let at = format!("transport[{i}]");
        if !seen.insert(t.kind) {
            c.fail(
                format!("{at}.kind"),
                format!("transport `{}` is listed twice", t.kind.as_str()),
            );
        }
        let serial = t.kind == TransportKind::Serial;
        let placeholder = if serial { "{device}" } else { "{host}" };
        if !t.resource.contains(placeholder) {
            c.fail(
                format!("{at}.resource"),
                format!(
                    "a {} resource template must contain {placeholder} (got {:?})",
                    t.kind.as_str(),
                    t.resource
                ),
            );
        }
        match (serial, t.port) {
            (true, Some(_)) => c.fail(format!("{at}.port"), "a serial transport has no port"),
            (false, None) => c.fail(
                format!("{at}.port"),
                "a network transport needs its default port",
            ),
            (false, Some(0)) => c.fail(format!("{at}.port"), "must be 1..=65535 (got 0)"),
            _ => {}
        }
    }
}

fn check_timeouts(c: &mut Checks, t: &TimeoutPolicy) {
    for (name, value) in [
        ("connect_ms", t.connect_ms),
        ("read_ms", t.read_ms),
        ("write_ms", t.write_ms),
        ("operation_complete_ms", t.operation_complete_ms),
    ] {
        if value == 0 || value > 3_600_000 {
            c.fail(
                format!("timeouts.{name}"),
                format!("must be 1 ..= 3600000 ms (got {value})"),
            );
        }
    }
}

fn check_sections(c: &mut Checks, model: &InstrumentModel) {
    let kind = model.instrument.kind;
    let present = [
        ("awg", model.awg.is_some(), kind == InstrumentKind::Awg),
        (
            "digitizer",
            model.digitizer.is_some(),
            kind == InstrumentKind::Digitizer,
        ),
        (
            "rf",
            model.rf.is_some(),
            matches!(kind, InstrumentKind::RfTx | InstrumentKind::RfRx),
        ),
    ];
    for (section, is_present, wanted) in present {
        if wanted && !is_present {
            c.fail(
                section,
                format!(
                    "a `{}` instrument needs a [{section}] section",
                    kind.as_str()
                ),
            );
        }
        if !wanted && is_present {
            c.fail(
                section,
                format!(
                    "a `{}` instrument must not have a [{section}] section",
                    kind.as_str()
                ),
            );
        }
    }
    if matches!(kind, InstrumentKind::RfTx | InstrumentKind::RfRx) {
        if model.registers.is_empty() {
            c.fail("register", "an RF module needs its [[register]] map");
        }
        if model.protocol.is_none() {
            c.fail("protocol", "an RF module needs a [protocol] section");
        }
        let serial = model
            .transports
            .iter()
            .any(|t| t.kind == TransportKind::Serial);
        if serial && model.serial.is_none() {
            c.fail(
                "serial",
                "a serial transport needs a [serial] section (baud, bits, parity)",
            );
        }
    }
}

fn check_awg(c: &mut Checks, a: &AwgLimits) {
    c.count("awg.channels", a.channels, 8);
    if c.count("awg.sample_bits", a.sample_bits, 16) {
        let lo = -(1i32 << (a.sample_bits - 1));
        let hi = (1i32 << (a.sample_bits - 1)) - 1;
        if a.sample_min < lo || a.sample_max > hi || a.sample_min >= a.sample_max {
            c.fail(
                "awg.sample_max",
                format!(
                    "sample_min..sample_max must be an increasing range inside {lo}..={hi} (got {}..={})",
                    a.sample_min, a.sample_max
                ),
            );
        }
    }
    c.positive("awg.dac_rate_min", a.dac_rate_min);
    c.ordered(
        "awg.dac_rate_min",
        a.dac_rate_min,
        "awg.dac_rate_max",
        a.dac_rate_max,
    );
    c.within(
        "awg.dac_rate_default",
        a.dac_rate_default,
        a.dac_rate_min,
        a.dac_rate_max,
    );
    for (field, value) in [
        ("internal_memory_samples", a.internal_memory_samples),
        ("extended_memory_samples", a.extended_memory_samples),
        ("download_chunk_samples", a.download_chunk_samples),
    ] {
        if value == 0 {
            c.fail(format!("awg.{field}"), "must be greater than 0");
        }
    }
    if a.max_segment_id == 0 {
        c.fail("awg.max_segment_id", "must be at least 1");
    }
    c.positive("awg.amplitude_vpp_min", a.amplitude_vpp_min);
    c.ordered(
        "awg.amplitude_vpp_min",
        a.amplitude_vpp_min,
        "awg.amplitude_vpp_max",
        a.amplitude_vpp_max,
    );
    c.within(
        "awg.amplitude_vpp_default",
        a.amplitude_vpp_default,
        a.amplitude_vpp_min,
        a.amplitude_vpp_max,
    );
    c.ordered(
        "awg.offset_v_min",
        a.offset_v_min,
        "awg.offset_v_max",
        a.offset_v_max,
    );
    c.positive("awg.marker_amplitude_v_min", a.marker_amplitude_v_min);
    c.ordered(
        "awg.marker_amplitude_v_min",
        a.marker_amplitude_v_min,
        "awg.marker_amplitude_v_max",
        a.marker_amplitude_v_max,
    );
    c.ordered(
        "awg.marker_offset_v_min",
        a.marker_offset_v_min,
        "awg.marker_offset_v_max",
        a.marker_offset_v_max,
    );
    check_dividers(c, a);
    check_dac_modes(c, a);
}

fn check_dividers(c: &mut Checks, a: &AwgLimits) {
    if a.dividers.is_empty() {
        c.fail("awg.divider", "needs at least one [[awg.divider]]");
    }
    let mut seen = HashSet::new();
    for (i, d) in a.dividers.iter().enumerate() {
        let at = format!("awg.divider[{i}]");
        if !d.divider.is_power_of_two() {
            c.fail(
                format!("{at}.divider"),
                format!("must be a power of two (got {})", d.divider),
            );
        }
        if !seen.insert(d.divider) {
            c.fail(
                format!("{at}.divider"),
                format!("divider {} is listed twice", d.divider),
            );
        }
        if d.keyword.trim().is_empty() {
            c.fail(format!("{at}.keyword"), "must not be empty");
        }
        if d.granularity == 0 {
            c.fail(format!("{at}.granularity"), "must be greater than 0");
        } else {
            if d.min_segment_samples < d.granularity || d.min_segment_samples % d.granularity != 0 {
                c.fail(
                    format!("{at}.min_segment_samples"),
                    format!(
                        "must be a non-zero multiple of the granularity {} (got {})",
                        d.granularity, d.min_segment_samples
                    ),
                );
            }
            if a.download_chunk_samples % d.granularity != 0 {
                c.fail(
                    "awg.download_chunk_samples",
                    format!(
                        "must be a multiple of every divider's granularity; {} is not a multiple of {}",
                        a.download_chunk_samples, d.granularity
                    ),
                );
            }
        }
    }
}

fn check_dac_modes(c: &mut Checks, a: &AwgLimits) {
    if a.dac_modes.is_empty() {
        c.fail("awg.dac_mode", "needs at least one [[awg.dac_mode]]");
    }
    let mut keywords = HashSet::new();
    let channel_ok = |ch: &u8| *ch >= 1 && *ch <= a.channels;
    for (i, m) in a.dac_modes.iter().enumerate() {
        let at = format!("awg.dac_mode[{i}]");
        if !keywords.insert(m.keyword.to_ascii_uppercase()) {
            c.fail(
                format!("{at}.keyword"),
                format!("DAC mode {} is listed twice", m.keyword),
            );
        }
        if !m
            .long
            .to_ascii_uppercase()
            .starts_with(&m.keyword.to_ascii_uppercase())
        {
            c.fail(
                format!("{at}.long"),
                format!(
                    "the long form must start with the short form {:?} (got {:?})",
                    m.keyword, m.long
                ),
            );
        }
        if m.signal_channels.is_empty() {
            c.fail(
                format!("{at}.signal_channels"),
                "needs at least one channel",
            );
        }
        for (field, list) in [
            ("signal_channels", &m.signal_channels),
            ("marker_channels", &m.marker_channels),
            ("extended_only_channels", &m.extended_only_channels),
        ] {
            if let Some(bad) = list.iter().find(|ch| !channel_ok(ch)) {
                c.fail(
                    format!("{at}.{field}"),
                    format!("channel {bad} does not exist (1..={})", a.channels),
                );
            }
        }
        if m.marker_channels.len() > 2 {
            c.fail(
                format!("{at}.marker_channels"),
                "at most two marker channels (marker bits 0 and 1)",
            );
        }
        if let Some(both) = m
            .marker_channels
            .iter()
            .find(|ch| m.signal_channels.contains(ch))
        {
            c.fail(
                format!("{at}.marker_channels"),
                format!("channel {both} cannot be both a signal and a marker channel"),
            );
        }
        if let Some(bad) = m
            .extended_only_channels
            .iter()
            .find(|ch| !m.signal_channels.contains(ch))
        {
            c.fail(
                format!("{at}.extended_only_channels"),
                format!("channel {bad} is not a signal channel of this mode"),
            );
        }
        if m.dividers.is_empty() {
            c.fail(format!("{at}.dividers"), "needs at least one divider");
        }
        if let Some(bad) = m.dividers.iter().find(|d| a.divider(**d).is_none()) {
            c.fail(
                format!("{at}.dividers"),
                format!("divider {bad} has no [[awg.divider]] entry"),
            );
        }
    }
}

fn check_digitizer(c: &mut Checks, d: &DigitizerLimits) {
    c.count("digitizer.channels", d.channels, 8);
    c.count("digitizer.adc_bits", d.adc_bits, 16);
    if d.sample_rates.is_empty() {
        c.fail("digitizer.sample_rates", "needs at least one sample rate");
    }
    for (i, rate) in d.sample_rates.iter().enumerate() {
        c.positive(&format!("digitizer.sample_rates[{i}]"), *rate);
    }
    for (field, value) in [
        ("max_points_per_channel", d.max_points_per_channel),
        ("horizontal_divisions", d.horizontal_divisions.into()),
        ("vertical_divisions", d.vertical_divisions.into()),
        ("codes_per_division", d.codes_per_division.into()),
    ] {
        if value == 0 {
            c.fail(format!("digitizer.{field}"), "must be greater than 0");
        }
    }
    if u64::from(d.codes_per_division) * u64::from(d.vertical_divisions) > 256 {
        c.fail(
            "digitizer.codes_per_division",
            format!(
                "codes_per_division x vertical_divisions must fit an 8-bit byte (got {} x {})",
                d.codes_per_division, d.vertical_divisions
            ),
        );
    }
    c.positive("digitizer.volts_per_div_min", d.volts_per_div_min);
    c.ordered(
        "digitizer.volts_per_div_min",
        d.volts_per_div_min,
        "digitizer.volts_per_div_max",
        d.volts_per_div_max,
    );
    c.within(
        "digitizer.volts_per_div_default",
        d.volts_per_div_default,
        d.volts_per_div_min,
        d.volts_per_div_max,
    );
    c.ordered(
        "digitizer.offset_v_min",
        d.offset_v_min,
        "digitizer.offset_v_max",
        d.offset_v_max,
    );
    c.ordered(
        "digitizer.ext_trigger_level_v_min",
        d.ext_trigger_level_v_min,
        "digitizer.ext_trigger_level_v_max",
        d.ext_trigger_level_v_max,
    );
    if d.trigger_sources.is_empty() {
        c.fail("digitizer.trigger_sources", "needs at least one source");
    }
}

/// Moves fields written in their old place (a generic section, before the `[vendor]` table
/// existed) into `[vendor]`, where the driver family reads them. A file that gives a field in both
/// places with different values is refused, naming both; the same value twice is accepted.
pub(super) fn adopt_old_places(model: &mut InstrumentModel) -> Vec<(String, String)> {
    let mut c = Checks::default();
    let Some(d) = &model.digitizer else {
        return c.0;
    };
    let old = [
        (
            "wavedesc_template",
            d.wavedesc_template.clone().map(toml::Value::String),
        ),
        (
            "wavedesc_bytes",
            d.wavedesc_bytes.map(|b| toml::Value::Integer(b.into())),
        ),
    ];
    for (key, value) in old {
        let Some(value) = value else { continue };
        match model.vendor.get(key) {
            Some(new) if *new != value => c.fail(
                format!("digitizer.{key}"),
                format!(
                    "given twice with different values: `vendor.{key}` = {new} and \
                     `digitizer.{key}` = {value} (its old place); keep `vendor.{key}` only"
                ),
            ),
            Some(_) => {}
            None => {
                model.vendor.insert(key.to_string(), value);
            }
        }
    }
    c.0
}

fn check_rf(c: &mut Checks, rf: &RfLimits, kind: InstrumentKind) {
    let expected = if kind == InstrumentKind::RfTx {
        RfDirection::Tx
    } else {
        RfDirection::Rx
    };
    if matches!(kind, InstrumentKind::RfTx | InstrumentKind::RfRx) && rf.direction != expected {
        c.fail(
            "rf.direction",
            format!("must match instrument.kind `{}`", kind.as_str()),
        );
    }
    c.positive("rf.rf_min_hz", rf.rf_min_hz);
    c.ordered("rf.rf_min_hz", rf.rf_min_hz, "rf.rf_max_hz", rf.rf_max_hz);
    c.positive("rf.lo_min_hz", rf.lo_min_hz);
    c.ordered("rf.lo_min_hz", rf.lo_min_hz, "rf.lo_max_hz", rf.lo_max_hz);
    if rf.lo_multiplier == 0 {
        c.fail("rf.lo_multiplier", "must be at least 1");
    }
    c.positive("rf.attenuation_step_db", rf.attenuation_step_db);
    c.ordered(
        "rf.ambient_temperature_c",
        rf.ambient_temperature_c,
        "rf.over_temperature_c",
        rf.over_temperature_c,
    );
}

fn check_serial(c: &mut Checks, s: &SerialSettings) {
    if s.baud == 0 {
        c.fail("serial.baud", "must be greater than 0");
    }
    if !(5..=8).contains(&s.data_bits) {
        c.fail(
            "serial.data_bits",
            format!("must be 5..=8 (got {})", s.data_bits),
        );
    }
    if !(1..=2).contains(&s.stop_bits) {
        c.fail(
            "serial.stop_bits",
            format!("must be 1 or 2 (got {})", s.stop_bits),
        );
    }
    if s.line_terminator.is_empty() || s.line_terminator.len() > 4 {
        c.fail(
            "serial.line_terminator",
            format!(
                "must be 1 to 4 characters, e.g. \"\\n\", \"\\r\" or \"\\r\\n\" (got {:?})",
                s.line_terminator
            ),
        );
    }
}

fn check_protocol(c: &mut Checks, p: &LineProtocol) {
    let template = |c: &mut Checks, key: &str, text: &str, needs: &[&str]| {
        for placeholder in ["{address}", "{value}"] {
            let wanted = needs.contains(&placeholder);
            let count = text.matches(placeholder).count();
            if wanted && count != 1 {
                c.fail(
                    format!("protocol.{key}"),
                    format!(
                        "{text:?} must hold {placeholder} once (allowed: {})",
                        needs.join(" and ")
                    ),
                );
            } else if !wanted && count > 0 {
                c.fail(
                    format!("protocol.{key}"),
                    format!(
                        "{text:?} holds {placeholder}; allowed: {}",
                        needs.join(" and ")
                    ),
                );
            }
        }
    };
    template(c, "read", &p.read, &["{address}"]);
    template(c, "write", &p.write, &["{address}", "{value}"]);
    if p.read.contains("{address}{value}") || p.write.contains("{address}{value}") {
        c.fail(
            "protocol.write",
            "{address} and {value} need text between them",
        );
    }
    for (key, text) in [
        ("identify", &p.identify),
        ("reply_ok", &p.reply_ok),
        ("reply_error", &p.reply_error),
    ] {
        if text.trim().is_empty() {
            c.fail(format!("protocol.{key}"), "must not be empty");
        }
    }
    if p.reply_ok.starts_with(&p.reply_error) || p.reply_error.starts_with(&p.reply_ok) {
        c.fail(
            "protocol.reply_error",
            format!(
                "{:?} and reply_ok {:?} must not start alike (a reply must be one or the other)",
                p.reply_error, p.reply_ok
            ),
        );
    }
    if p.checksum == Checksum::Crc8 && p.crc_poly == 0 {
        c.fail(
            "protocol.crc_poly",
            "checksum = \"crc8\" needs a polynomial (e.g. 0x07); or checksum = \"none\"",
        );
    }
    let mut codes = HashSet::new();
    for (i, e) in p.errors.iter().enumerate() {
        if !codes.insert(e.code) {
            c.fail(
                format!("protocol.error[{i}].code"),
                format!("error code {} is listed twice", e.code),
            );
        }
    }
    for name in REQUIRED_PROTOCOL_ERRORS {
        if !p.errors.iter().any(|e| e.name == name) {
            c.fail(
                "protocol.error",
                format!("needs an error named `{name}` (the driver maps it)"),
            );
        }
    }
}

fn check_registers(c: &mut Checks, registers: &[Register]) {
    let mut addresses = HashSet::new();
    let mut names = HashSet::new();
    for (i, r) in registers.iter().enumerate() {
        let at = format!("register[{i}]");
        if !addresses.insert(r.address) {
            c.fail(
                format!("{at}.address"),
                format!("address 0x{:02X} is used twice", r.address),
            );
        }
        if !names.insert(r.name.as_str()) {
            c.fail(
                format!("{at}.name"),
                format!("register {} is listed twice", r.name),
            );
        }
        match r.access {
            RegisterAccess::Ro => {
                if r.min.is_some() || r.max.is_some() {
                    c.fail(format!("{at}.min"), "a read-only register takes no min/max");
                }
            }
            RegisterAccess::Rw | RegisterAccess::Rw1c => match (r.min, r.max) {
                (Some(min), Some(max)) if min <= max => {
                    if r.reset < min || r.reset > max {
                        c.fail(
                            format!("{at}.reset"),
                            format!("must lie in {min}..={max} (got {})", r.reset),
                        );
                    }
                }
                (Some(min), Some(max)) => c.fail(
                    format!("{at}.max"),
                    format!("must be at least min ({min}) (got {max})"),
                ),
                _ => c.fail(
                    format!("{at}.max"),
                    "a writable register needs both `min` and `max`",
                ),
            },
        }
        let mut bits = HashSet::new();
        for (j, f) in r.fields.iter().enumerate() {
            if f.bit > 15 {
                c.fail(
                    format!("{at}.fields[{j}].bit"),
                    format!("registers are 16-bit: bit must be 0..=15 (got {})", f.bit),
                );
            }
            if !bits.insert(f.bit) {
                c.fail(
                    format!("{at}.fields[{j}].bit"),
                    format!("bit {} is used twice", f.bit),
                );
            }
        }
    }
    if registers.is_empty() {
        return;
    }
    for name in REQUIRED_RF_REGISTERS {
        if !registers.iter().any(|r| r.name == name) {
            c.fail(
                "register",
                format!("the register map needs a register named {name}"),
            );
        }
    }
    for (register, field) in REQUIRED_RF_FIELDS {
        if let Some((i, r)) = registers
            .iter()
            .enumerate()
            .find(|(_, r)| r.name == register)
        {
            if r.bit(field).is_none() {
                c.fail(
                    format!("register[{i}].fields"),
                    format!("{register} needs a bit field named {field}"),
                );
            }
        }
    }
    if let Some((i, r)) = registers
        .iter()
        .enumerate()
        .find(|(_, r)| r.name == "FAULT_LATCH")
    {
        if r.access != RegisterAccess::Rw1c {
            c.fail(
                format!("register[{i}].access"),
                "FAULT_LATCH must be `rw1c` (write 1 to clear)",
            );
        }
    }
}
