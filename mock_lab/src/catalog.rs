//! mock_lab's own reader of the instrument catalog (`instruments/*.toml`).
//!
//! radbench has the full schema and validation; mock_lab shares no code with it on purpose, so it
//! reads just the fields its emulators need, with its own small serde structs (unknown fields are
//! ignored here: radbench's loader is the one that refuses typos). The files are compiled in.

use serde::Deserialize;

/// The catalog texts built into mock_lab.
pub(crate) mod embedded {
    pub(crate) const M8195A: &str = include_str!("../../instruments/keysight_m8195a.toml");
    pub(crate) const LECROY: &str = include_str!("../../instruments/lecroy_labmaster10zi_a.toml");
    pub(crate) const GOTMIC_TX: &str = include_str!("../../instruments/gotmic_eband_tx.toml");
    pub(crate) const GOTMIC_RX: &str = include_str!("../../instruments/gotmic_eband_rx.toml");
}

/// A catalog file mock_lab could not use.
#[derive(Debug, thiserror::Error)]
pub enum CatalogError {
    #[error("instrument file for {what}: {source}")]
    Toml {
        what: &'static str,
        #[source]
        source: toml::de::Error,
    },
    #[error("instrument file for {what}: field `{field}`: {reason}")]
    Invalid {
        what: &'static str,
        field: String,
        reason: String,
    },
}

/// The `*IDN?` fields an emulator answers with.
#[derive(Debug, Clone, PartialEq, Eq, Deserialize)]
pub struct EmulatorIdentity {
    pub manufacturer: String,
    pub model: String,
    pub serial: String,
    pub firmware: String,
}

impl EmulatorIdentity {
    /// The `*IDN?` reply: `manufacturer,model,serial,firmware`.
    pub fn idn(&self) -> String {
        format!(
            "{},{},{},{}",
            self.manufacturer, self.model, self.serial, self.firmware
        )
    }
}

#[derive(Debug, Deserialize)]
struct Identity {
    emulator: EmulatorIdentity,
}

/// Segment rules at one sample-rate divider.
#[derive(Debug, Clone, PartialEq, Eq, Deserialize)]
pub struct Divider {
    pub divider: u32,
    pub keyword: String,
    pub granularity: u64,
    pub min_segment_samples: u64,
}

/// One AWG DAC mode.
#[derive(Debug, Clone, PartialEq, Eq, Deserialize)]
pub struct DacMode {
    pub keyword: String,
    pub long: String,
    pub signal_channels: Vec<u8>,
    pub marker_channels: Vec<u8>,
    pub dividers: Vec<u32>,
    pub extended_only_channels: Vec<u8>,
}

/// What the M8195A emulator needs from the catalog.
#[derive(Debug, Clone, PartialEq, Deserialize)]
pub struct AwgLimits {
    pub channels: u8,
    pub sample_min: i32,
    pub sample_max: i32,
    pub dac_rate_min: f64,
    pub dac_rate_max: f64,
    pub dac_rate_default: f64,
    pub internal_memory_samples: u64,
    pub extended_memory_samples: u64,
    pub max_segment_id: u32,
    pub amplitude_vpp_min: f64,
    pub amplitude_vpp_max: f64,
    pub amplitude_vpp_default: f64,
    pub offset_v_min: f64,
    pub offset_v_max: f64,
    pub marker_amplitude_v_min: f64,
    pub marker_amplitude_v_max: f64,
    pub marker_offset_v_min: f64,
    pub marker_offset_v_max: f64,
    #[serde(default)]
    pub options: Vec<String>,
    #[serde(rename = "divider")]
    pub dividers: Vec<Divider>,
    #[serde(rename = "dac_mode")]
    pub dac_modes: Vec<DacMode>,
}

impl AwgLimits {
    pub fn divider(&self, divider: u32) -> Option<&Divider> {
        self.dividers.iter().find(|d| d.divider == divider)
    }
}

/// The AWG model: identity and limits.
#[derive(Debug, Clone, PartialEq)]
pub struct AwgModel {
    pub identity: EmulatorIdentity,
    pub limits: AwgLimits,
}

/// What the scope emulator needs from the catalog.
#[derive(Debug, Clone, PartialEq, Deserialize)]
pub struct DigitizerLimits {
    pub channels: u8,
    pub adc_bits: u8,
    pub sample_rates: Vec<f64>,
    pub max_points_per_channel: u64,
    pub horizontal_divisions: u32,
    pub vertical_divisions: u32,
    pub codes_per_division: u32,
    pub volts_per_div_min: f64,
    pub volts_per_div_max: f64,
    pub volts_per_div_default: f64,
    pub offset_v_min: f64,
    pub offset_v_max: f64,
    pub trigger_sources: Vec<String>,
    pub ext_trigger_level_v_min: f64,
    pub ext_trigger_level_v_max: f64,
    /// Most segments of one sequence-mode acquisition (0: no sequence mode).
    #[serde(default)]
    pub max_sequence_segments: u32,
}

/// The scope model: identity and limits.
#[derive(Debug, Clone, PartialEq)]
pub struct DigitizerModel {
    pub identity: EmulatorIdentity,
    pub limits: DigitizerLimits,
}

/// RF module behaviour the Gotmic emulator needs.
#[derive(Debug, Clone, PartialEq, Deserialize)]
pub struct RfLimits {
    pub direction: RfDirection,
    pub attenuation_step_db: f64,
    pub over_temperature_c: f64,
    pub ambient_temperature_c: f64,
    pub enable_requires_interlock_closed: bool,
    pub enable_requires_lo: bool,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RfDirection {
    Tx,
    Rx,
}

/// Register access rights.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Access {
    Ro,
    Rw,
    Rw1c,
}

#[derive(Debug, Clone, PartialEq, Eq, Deserialize)]
pub struct BitField {
    pub name: String,
    pub bit: u8,
}

/// One 16-bit register.
#[derive(Debug, Clone, PartialEq, Eq, Deserialize)]
pub struct Register {
    pub address: u8,
    pub name: String,
    pub access: Access,
    pub reset: u16,
    pub min: Option<u16>,
    pub max: Option<u16>,
    #[serde(default)]
    pub fields: Vec<BitField>,
}

impl Register {
    /// The mask of a named bit field, if the register has it.
    pub fn mask(&self, field: &str) -> Option<u16> {
        self.fields
            .iter()
            .find(|f| f.name == field)
            .and_then(|f| 1u16.checked_shl(u32::from(f.bit)))
    }
}

/// One `ERR <code> <text>` reply.
#[derive(Debug, Clone, PartialEq, Eq, Deserialize)]
pub struct ProtocolError {
    pub code: u8,
    pub name: String,
    pub text: String,
}

/// The module's line protocol as the catalog describes it (instruments/README.md, "The line
/// protocol as data"); every key but `error` defaults to the radbench-project protocol's spelling.
#[derive(Debug, Clone, PartialEq, Eq, Deserialize)]
pub struct LineProtocol {
    /// `crc8` or `none`.
    #[serde(default)]
    pub checksum: Checksum,
    #[serde(default)]
    pub crc_poly: u8,
    #[serde(default)]
    pub crc_init: u8,
    /// Switches the checksum on; empty: always on (with `crc8`).
    #[serde(default = "default_checksum_on")]
    pub checksum_on: String,
    #[serde(default = "default_checksum_off")]
    pub checksum_off: String,
    #[serde(default)]
    pub request_prefix: String,
    #[serde(default)]
    pub reply_prefix: String,
    #[serde(default = "default_identify")]
    pub identify: String,
    #[serde(default = "default_read")]
    pub read: String,
    #[serde(default = "default_write")]
    pub write: String,
    #[serde(default = "default_address_format")]
    pub address_format: NumberFormat,
    #[serde(default = "default_value_format")]
    pub value_format: NumberFormat,
    #[serde(default = "default_reply_ok")]
    pub reply_ok: String,
    #[serde(default = "default_reply_error")]
    pub reply_error: String,
    #[serde(rename = "error")]
    pub errors: Vec<ProtocolError>,
}

fn default_checksum_on() -> String {
    "CRC ON".into()
}
fn default_checksum_off() -> String {
    "CRC OFF".into()
}
fn default_identify() -> String {
    "*IDN?".into()
}
fn default_read() -> String {
    "R {address}".into()
}
fn default_write() -> String {
    "W {address} {value}".into()
}
fn default_address_format() -> NumberFormat {
    NumberFormat::Hex2
}
fn default_value_format() -> NumberFormat {
    NumberFormat::Hex4
}
fn default_reply_ok() -> String {
    "OK".into()
}
fn default_reply_error() -> String {
    "ERR".into()
}

/// A line's checksum.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Checksum {
    #[default]
    Crc8,
    None,
}

/// How a number is written on the line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum NumberFormat {
    Hex2,
    Hex4,
    Dec,
}

impl NumberFormat {
    pub fn write(self, value: u16) -> String {
        match self {
            NumberFormat::Hex2 => format!("{value:02X}"),
            NumberFormat::Hex4 => format!("{value:04X}"),
            NumberFormat::Dec => value.to_string(),
        }
    }

    /// A number in this format (hex with an optional `0x`, at most as many digits as the
    /// format writes; decimal up to 65535).
    pub fn read(self, text: &str) -> Option<u16> {
        let (digits, radix, most) = match self {
            NumberFormat::Hex2 | NumberFormat::Hex4 => {
                let most = if self == NumberFormat::Hex2 { 2 } else { 4 };
                let digits = text
                    .strip_prefix("0x")
                    .or_else(|| text.strip_prefix("0X"))
                    .unwrap_or(text);
                (digits, 16, most)
            }
            NumberFormat::Dec => (text, 10, 5),
        };
        if digits.is_empty() || digits.len() > most || !digits.chars().all(|c| c.is_digit(radix)) {
            return None;
        }
        u16::from_str_radix(digits, radix).ok()
    }
}

/// A Gotmic module model: identity, behaviour, protocol and register map.
#[derive(Debug, Clone, PartialEq)]
pub struct RfModel {
    pub identity: EmulatorIdentity,
    pub limits: RfLimits,
    pub protocol: LineProtocol,
    pub registers: Vec<Register>,
    /// What ends every line in both directions (`[serial] line_terminator`, LF by default).
    pub line_terminator: String,
    /// The file's `[instrument] key`: the model a bench file names (empty when the file has none).
    pub key: String,
}

impl RfModel {
    pub fn register(&self, name: &str) -> Option<&Register> {
        self.registers.iter().find(|r| r.name == name)
    }

    pub fn error(&self, name: &str) -> Option<&ProtocolError> {
        self.protocol.errors.iter().find(|e| e.name == name)
    }
}

#[derive(Debug, Deserialize)]
struct AwgFile {
    identity: Identity,
    awg: AwgLimits,
}

#[derive(Debug, Deserialize)]
struct DigitizerFile {
    identity: Identity,
    digitizer: DigitizerLimits,
}

#[derive(Debug, Deserialize)]
struct RfFile {
    identity: Identity,
    rf: RfLimits,
    protocol: LineProtocol,
    #[serde(rename = "register")]
    registers: Vec<Register>,
    serial: Option<RfSerial>,
    instrument: Option<RfInstrument>,
}

/// The part of `[instrument]` the emulator needs: the key a bench file names.
#[derive(Debug, Deserialize)]
struct RfInstrument {
    key: String,
}

/// The part of `[serial]` the emulator needs: the baud rate and parity mean nothing on a pty.
#[derive(Debug, Deserialize)]
struct RfSerial {
    line_terminator: String,
}

fn parse<T: for<'de> Deserialize<'de>>(what: &'static str, text: &str) -> Result<T, CatalogError> {
    toml::from_str(text).map_err(|source| CatalogError::Toml { what, source })
}

fn invalid(what: &'static str, field: &str, reason: impl Into<String>) -> CatalogError {
    CatalogError::Invalid {
        what,
        field: field.to_string(),
        reason: reason.into(),
    }
}

/// Reads an AWG file (for example `embedded::M8195A`).
pub(crate) fn awg_from_str(text: &str) -> Result<AwgModel, CatalogError> {
    let file: AwgFile = parse("AWG", text)?;
    let model = AwgModel {
        identity: file.identity.emulator,
        limits: file.awg,
    };
    check_awg(&model)?;
    Ok(model)
}

/// Checks what the M8195A emulator relies on: dividers with a granularity, DAC modes whose channels
/// exist, 1..=8 channels.
pub fn check_awg(model: &AwgModel) -> Result<(), CatalogError> {
    const WHAT: &str = "AWG";
    let limits = &model.limits;
    if limits.dividers.is_empty() {
        return Err(invalid(WHAT, "awg.divider", "needs at least one divider"));
    }
    if limits
        .dividers
        .iter()
        .any(|d| d.granularity == 0 || d.divider == 0)
    {
        return Err(invalid(
            WHAT,
            "awg.divider",
            "divider and granularity must be > 0",
        ));
    }
    if limits.dac_modes.is_empty() {
        return Err(invalid(WHAT, "awg.dac_mode", "needs at least one DAC mode"));
    }
    if !(1..=8).contains(&limits.channels) {
        return Err(invalid(WHAT, "awg.channels", "must be 1..=8"));
    }
    let channel_ok = |ch: &u8| (1..=limits.channels).contains(ch);
    for mode in &limits.dac_modes {
        let all = mode
            .signal_channels
            .iter()
            .chain(&mode.marker_channels)
            .chain(&mode.extended_only_channels);
        if mode.signal_channels.is_empty() || !all.clone().all(channel_ok) {
            return Err(invalid(
                WHAT,
                "awg.dac_mode",
                format!(
                    "DAC mode {} names a channel outside 1..={}",
                    mode.keyword, limits.channels
                ),
            ));
        }
    }
    Ok(())
}

/// Reads a digitizer file (for example `embedded::LECROY`).
pub fn digitizer_from_str(text: &str) -> Result<DigitizerModel, CatalogError> {
    let file: DigitizerFile = parse("digitizer", text)?;
    let model = DigitizerModel {
        identity: file.identity.emulator,
        limits: file.digitizer,
    };
    check_digitizer(&model)?;
    Ok(model)
}

/// Checks what the scope emulator relies on: a positive sample rate, non-zero divisions, 1..=8
/// channels, ADC bits 1..=16.
pub fn check_digitizer(model: &DigitizerModel) -> Result<(), CatalogError> {
    const WHAT: &str = "digitizer";
    let limits = &model.limits;
    if limits
        .sample_rates
        .first()
        .is_none_or(|r| !(r.is_finite() && *r > 0.0))
    {
        return Err(invalid(
            WHAT,
            "digitizer.sample_rates",
            "needs a positive sample rate",
        ));
    }
    if limits.codes_per_division == 0 || limits.horizontal_divisions == 0 {
        return Err(invalid(
            WHAT,
            "digitizer.codes_per_division",
            "divisions and codes per division must be > 0",
        ));
    }
    if !(1..=8).contains(&limits.channels) {
        return Err(invalid(WHAT, "digitizer.channels", "must be 1..=8"));
    }
    if !(1..=16).contains(&limits.adc_bits) {
        return Err(invalid(WHAT, "digitizer.adc_bits", "must be 1..=16"));
    }
    Ok(())
}

/// Reads a Gotmic module file (for example `embedded::GOTMIC_TX`, or a lab's own description of
/// its modules' protocol).
pub fn rf_from_str(text: &str) -> Result<RfModel, CatalogError> {
    const WHAT: &str = "RF module";
    let file: RfFile = parse(WHAT, text)?;
    let model = RfModel {
        identity: file.identity.emulator,
        limits: file.rf,
        protocol: file.protocol,
        registers: file.registers,
        line_terminator: file
            .serial
            .map_or_else(|| "\n".into(), |s| s.line_terminator),
        key: file.instrument.map(|i| i.key).unwrap_or_default(),
    };
    check_rf(&model)?;
    Ok(model)
}

/// Checks that an RF model has the registers, bit fields and error names the emulator relies on.
pub fn check_rf(model: &RfModel) -> Result<(), CatalogError> {
    const WHAT: &str = "RF module";
    if model.line_terminator.is_empty() || model.line_terminator.len() > 4 {
        return Err(invalid(
            WHAT,
            "serial.line_terminator",
            format!(
                "must be 1 to 4 characters (got {:?})",
                model.line_terminator
            ),
        ));
    }
    for name in [
        "ID",
        "STATUS",
        "CONTROL",
        "GAIN_ATT",
        "TEMP_DC",
        "FAULT_LATCH",
    ] {
        if model.register(name).is_none() {
            return Err(invalid(
                WHAT,
                "register",
                format!("needs a register named {name}"),
            ));
        }
    }
    for (register, field) in [
        ("STATUS", "POWERED"),
        ("STATUS", "LO_LOCKED"),
        ("STATUS", "RF_ENABLED"),
        ("STATUS", "OVER_TEMPERATURE"),
        ("STATUS", "INTERLOCK_OPEN"),
        ("CONTROL", "MASTER_ENABLE"),
        ("CONTROL", "AMP_ENABLE"),
        ("FAULT_LATCH", "OVER_TEMPERATURE"),
        ("FAULT_LATCH", "INTERLOCK_OPENED"),
        ("FAULT_LATCH", "LO_LOST"),
    ] {
        if model
            .register(register)
            .and_then(|r| r.mask(field))
            .is_none()
        {
            return Err(invalid(
                WHAT,
                "register.fields",
                format!("{register} needs a bit field named {field}"),
            ));
        }
    }
    let p = &model.protocol;
    for (key, template, needs) in [
        ("protocol.read", &p.read, &["{address}"][..]),
        ("protocol.write", &p.write, &["{address}", "{value}"][..]),
    ] {
        for placeholder in ["{address}", "{value}"] {
            if template.matches(placeholder).count() != usize::from(needs.contains(&placeholder)) {
                return Err(invalid(
                    WHAT,
                    key,
                    format!(
                        "{template:?}: allowed placeholders, once each: {}",
                        needs.join(" ")
                    ),
                ));
            }
        }
    }
    if p.identify.trim().is_empty() || p.reply_ok.is_empty() || p.reply_error.is_empty() {
        return Err(invalid(
            WHAT,
            "protocol",
            "identify, reply_ok and reply_error must not be empty",
        ));
    }
    for name in [
        "syntax",
        "unknown_register",
        "read_only",
        "out_of_range",
        "not_allowed",
        "crc",
    ] {
        if model.error(name).is_none() {
            return Err(invalid(
                WHAT,
                "protocol.error",
                format!("needs an error named {name}"),
            ));
        }
    }
    Ok(())
}

/// The built-in M8195A model.
pub fn m8195a() -> Result<AwgModel, CatalogError> {
    awg_from_str(embedded::M8195A)
}

/// The built-in LabMaster 10 Zi-A model.
pub fn lecroy() -> Result<DigitizerModel, CatalogError> {
    digitizer_from_str(embedded::LECROY)
}

/// The built-in Gotmic E-band transmitter model.
pub fn gotmic_tx() -> Result<RfModel, CatalogError> {
    rf_from_str(embedded::GOTMIC_TX)
}

/// The front ends a lab serves: each from its catalog file when one is given (a lab's own line
/// protocol, tried before its modules arrive), else the built-in model. `None` when neither is
/// given. Errors name the file.
pub fn front_ends_from_files(
    tx: Option<&std::path::Path>,
    rx: Option<&std::path::Path>,
) -> Result<Option<(RfModel, RfModel)>, String> {
    if tx.is_none() && rx.is_none() {
        return Ok(None);
    }
    let load = |path: Option<&std::path::Path>, built_in: fn() -> Result<RfModel, CatalogError>| {
        match path {
            None => built_in().map_err(|e| e.to_string()),
            Some(path) => std::fs::read_to_string(path)
                .map_err(|e| format!("cannot read {}: {e}", path.display()))
                .and_then(|text| {
                    rf_from_str(&text).map_err(|e| format!("{}: {e}", path.display()))
                }),
        }
    };
    Ok(Some((load(tx, gotmic_tx)?, load(rx, gotmic_rx)?)))
}

/// The built-in Gotmic E-band receiver model.
pub(crate) fn gotmic_rx() -> Result<RfModel, CatalogError> {
    rf_from_str(embedded::GOTMIC_RX)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn embedded_models_load() {
        let awg = m8195a().unwrap();
        assert_eq!(awg.identity.idn(), "MOCK_LAB,M8195A-EMU,EMU0001,mock_lab-1");
        assert_eq!(awg.limits.divider(2).unwrap().granularity, 128);
        assert_eq!(lecroy().unwrap().limits.sample_rates, [80e9]);
        let tx = gotmic_tx().unwrap();
        assert_eq!(tx.register("CONTROL").unwrap().mask("AMP_ENABLE"), Some(2));
        assert_eq!(gotmic_rx().unwrap().limits.direction, RfDirection::Rx);
    }

    #[test]
    fn missing_register_is_refused() {
        let text = embedded::GOTMIC_TX.replace("name = \"TEMP_DC\"", "name = \"TEMP\"");
        let err = rf_from_str(&text).unwrap_err();
        assert!(err.to_string().contains("TEMP_DC"), "{err}");
    }
}
