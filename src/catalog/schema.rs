//! The shape of one `instruments/*.toml` file.
//!
//! Every struct denies unknown fields, so a typo in a catalog file is an error that names the field
//! instead of a silently ignored setting. Units are in the field names (`_hz`, `_v`, `_ms`, ...).
//! Semantic rules (ranges, cross-field consistency) live in [`super::validate`].

use serde::Deserialize;

/// The catalog format version this code reads.
pub(crate) const SCHEMA_VERSION: u32 = 1;

/// One instrument model: everything radbench needs to know about it as data.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InstrumentModel {
    /// Catalog format version; must equal `SCHEMA_VERSION`.
    pub schema: u32,
    pub instrument: Info,
    pub identity: Identity,
    /// Ways to reach the instrument, most preferred first or marked `preferred = true`.
    #[serde(rename = "transport")]
    pub transports: Vec<TransportSpec>,
    pub timeouts: TimeoutPolicy,
    /// Present for `kind = "awg"`.
    pub awg: Option<AwgLimits>,
    /// Present for `kind = "digitizer"`.
    pub digitizer: Option<DigitizerLimits>,
    /// Present for `kind = "rf_tx"` and `kind = "rf_rx"`.
    pub rf: Option<RfLimits>,
    /// Serial line settings (for instruments reached over a serial port).
    pub serial: Option<SerialSettings>,
    /// The line protocol (project-defined Gotmic protocol).
    pub protocol: Option<LineProtocol>,
    /// Register map (RF front ends).
    #[serde(default, rename = "register")]
    pub registers: Vec<Register>,
    #[serde(default)]
    pub quirks: Quirks,
    /// `[vendor]`: fields only this model's driver family reads (the driver checks them when it
    /// opens the instrument, and a bench file's check before); empty when it has none.
    #[serde(default)]
    pub vendor: toml::Table,
}

/// What the instrument is.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Info {
    /// Stable key used in bench files, e.g. `keysight-m8195a`.
    pub key: String,
    pub kind: InstrumentKind,
    /// The driver family that speaks to it, e.g. `lecroy-maui` (the driver layer lists them).
    /// Optional for files written before the key existed: then the kind's first family
    /// (`keysight-m8195a`, `lecroy-maui`, `gotmic-line`).
    #[serde(default)]
    pub driver: Option<String>,
    pub manufacturer: String,
    pub model: String,
    pub summary: String,
}

/// The capability an instrument model provides; decides which limits section is required.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum InstrumentKind {
    Awg,
    Digitizer,
    RfTx,
    RfRx,
}

impl InstrumentKind {
    /// The name used in the TOML files.
    pub fn as_str(self) -> &'static str {
        match self {
            InstrumentKind::Awg => "awg",
            InstrumentKind::Digitizer => "digitizer",
            InstrumentKind::RfTx => "rf_tx",
            InstrumentKind::RfRx => "rf_rx",
        }
    }
}

/// How to recognise the model from its `*IDN?` reply.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Identity {
    /// Patterns for the first `*IDN?` field (case-insensitive, `*` matches any run of characters).
    pub manufacturer: Vec<String>,
    /// Patterns for the second `*IDN?` field.
    pub model: Vec<String>,
    /// What the mock_lab emulator of this model answers (it never pretends to be the vendor).
    pub emulator: EmulatorIdentity,
}

impl Identity {
    /// Whether an `*IDN?` reply's first two fields name this model: `Some(false)` for the vendor's
    /// instrument (patterns), `Some(true)` for its mock_lab emulator, `None` for neither.
    pub fn matches(&self, manufacturer: &str, model: &str) -> Option<bool> {
        use super::identity::pattern_matches;
        let vendor = self
            .manufacturer
            .iter()
            .any(|p| pattern_matches(p, manufacturer))
            && self.model.iter().any(|p| pattern_matches(p, model));
        let emulated = self
            .emulator
            .manufacturer
            .eq_ignore_ascii_case(manufacturer)
            && self.emulator.model.eq_ignore_ascii_case(model);
        (vendor || emulated).then_some(emulated)
    }
}

/// The `*IDN?` fields of the mock_lab emulator of this model.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EmulatorIdentity {
    pub manufacturer: String,
    pub model: String,
    pub serial: String,
    pub firmware: String,
}

/// The protocol family of a transport.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TransportKind {
    Socket,
    Vxi11,
    Hislip,
    Vicp,
    Serial,
}

impl TransportKind {
    pub fn as_str(self) -> &'static str {
        match self {
            TransportKind::Socket => "socket",
            TransportKind::Vxi11 => "vxi11",
            TransportKind::Hislip => "hislip",
            TransportKind::Vicp => "vicp",
            TransportKind::Serial => "serial",
        }
    }
}

/// One way to reach the instrument.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TransportSpec {
    pub kind: TransportKind,
    /// VISA-style resource template: `{host}` for network transports, `{device}` for serial.
    pub resource: String,
    /// Default TCP port (network transports; for VXI-11 the portmapper port).
    pub port: Option<u16>,
    #[serde(default)]
    pub preferred: bool,
}

impl TransportSpec {
    /// The resource string for a host (network) or device path (serial).
    pub fn resource_for(&self, host_or_device: &str) -> String {
        self.resource
            .replace("{host}", host_or_device)
            .replace("{device}", host_or_device)
    }
}

/// How long to wait for the instrument.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TimeoutPolicy {
    pub connect_ms: u64,
    pub read_ms: u64,
    pub write_ms: u64,
    /// Extra time per megabyte moved in one message (large downloads and waveform reads).
    pub per_megabyte_ms: u64,
    /// Longest wait for an operation-complete answer (`*OPC?`, scope `WAIT`).
    pub operation_complete_ms: u64,
}

impl TimeoutPolicy {
    /// Read/write timeout for a message of `bytes` bytes: the base plus the per-megabyte allowance.
    pub fn for_transfer(&self, base_ms: u64, bytes: usize) -> std::time::Duration {
        let extra = (bytes as u128 * self.per_megabyte_ms as u128).div_ceil(1_000_000);
        std::time::Duration::from_millis(base_ms.saturating_add(extra.min(u64::MAX as u128) as u64))
    }
}

/// Arbitrary waveform generator limits.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AwgLimits {
    pub channels: u8,
    pub sample_bits: u8,
    pub sample_min: i32,
    pub sample_max: i32,
    /// DAC sample clock (raster) range in Sa/s; the memory rate is raster / divider.
    pub dac_rate_min: f64,
    pub dac_rate_max: f64,
    pub dac_rate_default: f64,
    pub internal_memory_samples: u64,
    pub extended_memory_samples: u64,
    /// Highest segment id accepted by `:TRAC:DEF` (1 without the sequencer option).
    pub max_segment_id: u32,
    /// Samples per `:TRAC:DATA` chunk the driver should send.
    pub download_chunk_samples: u64,
    pub amplitude_vpp_min: f64,
    pub amplitude_vpp_max: f64,
    pub amplitude_vpp_default: f64,
    pub offset_v_min: f64,
    pub offset_v_max: f64,
    pub marker_amplitude_v_min: f64,
    pub marker_amplitude_v_max: f64,
    pub marker_offset_v_min: f64,
    pub marker_offset_v_max: f64,
    /// Two rising (or two falling) marker edges must be at least this many DAC samples apart.
    pub marker_min_edge_spacing_dac_samples: u32,
    /// Installed options as reported by `*OPT?`.
    #[serde(default)]
    pub options: Vec<String>,
    #[serde(rename = "divider")]
    pub dividers: Vec<DividerLimits>,
    #[serde(rename = "dac_mode")]
    pub dac_modes: Vec<DacMode>,
}

impl AwgLimits {
    /// The limits for a sample-rate divider (1, 2 or 4), if the model has it.
    pub fn divider(&self, divider: u32) -> Option<&DividerLimits> {
        self.dividers.iter().find(|d| d.divider == divider)
    }

    /// The DAC mode by its SCPI keyword (short or long form, case-insensitive).
    pub fn dac_mode(&self, name: &str) -> Option<&DacMode> {
        self.dac_modes
            .iter()
            .find(|m| m.keyword.eq_ignore_ascii_case(name) || m.long.eq_ignore_ascii_case(name))
    }
}

/// Segment rules at one sample-rate divider (extended memory).
#[derive(Debug, Clone, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DividerLimits {
    pub divider: u32,
    /// The SCPI keyword for `:INST:MEM:EXT:RDIV`, e.g. `DIV4`.
    pub keyword: String,
    /// Segment lengths (and download offsets) must be multiples of this many samples.
    pub granularity: u64,
    pub min_segment_samples: u64,
}

/// One DAC mode of an AWG and the channels it drives.
#[derive(Debug, Clone, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DacMode {
    /// Short SCPI form, which is also what the query returns (e.g. `DCM`).
    pub keyword: String,
    /// Long SCPI form with the short part in capitals (e.g. `DCMarker`).
    pub long: String,
    pub signal_channels: Vec<u8>,
    /// Channels that output the marker bits of channel 1 (bit0 -> first, bit1 -> second).
    pub marker_channels: Vec<u8>,
    pub dividers: Vec<u32>,
    /// Channels that must play from extended memory in this mode.
    pub extended_only_channels: Vec<u8>,
}

impl DacMode {}

/// Digitizer (oscilloscope) limits.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DigitizerLimits {
    pub channels: u8,
    pub adc_bits: u8,
    /// The sample rates the driver may request, in Sa/s.
    pub sample_rates: Vec<f64>,
    pub max_points_per_channel: u64,
    pub horizontal_divisions: u32,
    pub vertical_divisions: u32,
    /// ADC codes per vertical division in BYTE format.
    pub codes_per_division: u32,
    pub volts_per_div_min: f64,
    pub volts_per_div_max: f64,
    pub volts_per_div_default: f64,
    pub offset_v_min: f64,
    pub offset_v_max: f64,
    pub trigger_sources: Vec<String>,
    pub ext_trigger_level_v_min: f64,
    pub ext_trigger_level_v_max: f64,
    /// The old place of the LeCroy's `[vendor] wavedesc_template` (catalog files written before
    /// the `[vendor]` table). The loader moves it there; a file giving both places with different
    /// values is refused.
    #[serde(default)]
    pub(crate) wavedesc_template: Option<String>,
    /// The old place of the LeCroy's `[vendor] wavedesc_bytes` (as `wavedesc_template`).
    #[serde(default)]
    pub(crate) wavedesc_bytes: Option<u32>,
    /// Most segments one sequence-mode acquisition records (one trigger each); 0 when the model
    /// has no sequence mode, and repetitions are then separate acquisitions.
    #[serde(default)]
    pub max_sequence_segments: u32,
}

/// Limits of an RF up- or down-converter module.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RfLimits {
    pub direction: RfDirection,
    pub rf_min_hz: f64,
    pub rf_max_hz: f64,
    pub lo_multiplier: u32,
    pub lo_min_hz: f64,
    pub lo_max_hz: f64,
    /// Attenuation per `GAIN_ATT` code step, in dB.
    pub attenuation_step_db: f64,
    /// The module latches an over-temperature fault above this temperature.
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

/// Serial line settings.
#[derive(Debug, Clone, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SerialSettings {
    pub baud: u32,
    pub data_bits: u8,
    pub parity: Parity,
    pub stop_bits: u8,
    pub line_terminator: String,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Parity {
    None,
    Even,
    Odd,
}

/// The request/reply line protocol of a register-based module, as data: framing, request
/// words, reply words, number formats. Every key but `error` defaults to the radbench-project
/// protocol's spelling (instruments/README.md, "The line protocol as data").
#[derive(Debug, Clone, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LineProtocol {
    /// What this description is, for people (e.g. "radbench-project line protocol, not Gotmic's").
    #[serde(default)]
    pub name: String,
    /// Checksum on every line: `crc8` (`<line><separator><hh>`) or `none`.
    #[serde(default)]
    pub checksum: Checksum,
    #[serde(default)]
    pub crc_name: String,
    #[serde(default)]
    pub crc_poly: u8,
    #[serde(default)]
    pub crc_init: u8,
    /// The request that switches the checksum on (sent without one); empty: always on.
    #[serde(default = "default_checksum_on")]
    pub checksum_on: String,
    /// The request that switches the checksum off (the emulator's; the driver never sends it).
    #[serde(default = "default_checksum_off")]
    pub checksum_off: String,
    /// Text before every request (an address byte, `$`, ...), checksum computed after it.
    #[serde(default)]
    pub request_prefix: String,
    /// Text before every reply; a reply without it is unreadable.
    #[serde(default)]
    pub reply_prefix: String,
    /// The identity request; its reply is `<manufacturer>,<model>,<serial>,<firmware>`.
    #[serde(default = "default_identify")]
    pub identify: String,
    /// A register read; `{address}` is replaced by the register's address.
    #[serde(default = "default_read")]
    pub read: String,
    /// A register write; `{address}` and `{value}` are replaced.
    #[serde(default = "default_write")]
    pub write: String,
    #[serde(default = "default_address_format")]
    pub address_format: NumberFormat,
    #[serde(default = "default_value_format")]
    pub value_format: NumberFormat,
    /// The reply to an accepted request; a read's value follows after one space.
    #[serde(default = "default_reply_ok")]
    pub reply_ok: String,
    /// The start of a refusal: `<reply_error> <code> <text>`.
    #[serde(default = "default_reply_error")]
    pub reply_error: String,
    #[serde(rename = "error")]
    pub errors: Vec<ProtocolError>,
}

impl Default for LineProtocol {
    /// The radbench-project protocol's spelling, with no error table.
    fn default() -> Self {
        LineProtocol {
            name: String::new(),
            checksum: Checksum::Crc8,
            crc_name: "CRC-8/SMBUS".into(),
            crc_poly: 0x07,
            crc_init: 0x00,
            checksum_on: default_checksum_on(),
            checksum_off: default_checksum_off(),
            request_prefix: String::new(),
            reply_prefix: String::new(),
            identify: default_identify(),
            read: default_read(),
            write: default_write(),
            address_format: default_address_format(),
            value_format: default_value_format(),
            reply_ok: default_reply_ok(),
            reply_error: default_reply_error(),
            errors: Vec::new(),
        }
    }
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
    /// CRC-8 (`crc_poly`, `crc_init`, MSB first) as two hex digits after `*`.
    #[default]
    Crc8,
    /// Bare lines.
    None,
}

/// How a number is written in a request or reply.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum NumberFormat {
    /// Two upper-case hex digits (`0A`).
    Hex2,
    /// Four upper-case hex digits (`003F`).
    Hex4,
    /// Decimal (`63`).
    Dec,
}

impl NumberFormat {
    /// `value` written in this format.
    pub fn write(self, value: u16) -> String {
        match self {
            NumberFormat::Hex2 => format!("{value:02X}"),
            NumberFormat::Hex4 => format!("{value:04X}"),
            NumberFormat::Dec => value.to_string(),
        }
    }

    /// A number in this format (hex: 1 to 4 digits, any case); `None` otherwise.
    pub fn read(self, text: &str) -> Option<u16> {
        match self {
            NumberFormat::Hex2 | NumberFormat::Hex4 => {
                if text.is_empty() || text.len() > 4 || !text.chars().all(|c| c.is_ascii_hexdigit())
                {
                    return None;
                }
                u16::from_str_radix(text, 16).ok()
            }
            NumberFormat::Dec => {
                if text.is_empty() || !text.chars().all(|c| c.is_ascii_digit()) {
                    return None;
                }
                text.parse().ok()
            }
        }
    }
}

/// One `ERR <code> <text>` reply the module can give.
#[derive(Debug, Clone, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProtocolError {
    pub code: u8,
    pub name: String,
    pub text: String,
}

/// One 16-bit register of a module.
#[derive(Debug, Clone, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Register {
    pub address: u8,
    pub name: String,
    pub access: RegisterAccess,
    /// Value after power-on.
    pub reset: u16,
    /// Lowest value a write may carry (writable registers).
    pub min: Option<u16>,
    /// Highest value a write may carry (writable registers).
    pub max: Option<u16>,
    /// The raw value is a two's-complement signed number.
    #[serde(default)]
    pub signed: bool,
    pub unit: Option<String>,
    pub description: String,
    #[serde(default)]
    pub fields: Vec<BitField>,
}

impl Register {
    /// The bit number of a named field.
    pub fn bit(&self, name: &str) -> Option<u8> {
        self.fields.iter().find(|f| f.name == name).map(|f| f.bit)
    }
}

/// Register access rights.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RegisterAccess {
    /// Read-only.
    Ro,
    /// Read-write.
    Rw,
    /// Read, write 1 to clear.
    Rw1c,
}

/// A named single-bit field of a register.
#[derive(Debug, Clone, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BitField {
    pub name: String,
    pub bit: u8,
}

/// Known behaviours a driver must respect. All optional; each model sets the ones that apply.
#[derive(Debug, Clone, Default, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Quirks {
    /// The error-queue reply when empty (clients parse only the leading integer).
    pub no_error_reply: Option<String>,
    /// The run command must be the last command of a setup.
    #[serde(default)]
    pub init_imm_last: bool,
    /// Download chunk offsets must be multiples of the granularity.
    #[serde(default)]
    pub data_offset_multiple_of_granularity: bool,
    /// Only one remote protocol (VICP or VXI-11) is enabled at a time on the instrument.
    #[serde(default)]
    pub remote_interfaces_exclusive: bool,
    /// Token in front of the `#9` block of a waveform reply.
    pub waveform_reply_prefix: Option<String>,
    /// Prefix of `VBS?` replies when response headers are on.
    pub vbs_reply_prefix: Option<String>,
}
