//! The bench file: which instrument is where, and the bench's calibration.
//!
//! ```toml
//! catalog = "my-instruments"                      # optional: instrument files of your own
//! catalog_overrides = "overrides.toml"            # optional: your units' differing values
//!
//! [awg]
//! model = "keysight-m8195a"                       # a key of the instrument catalog
//! resource = "TCPIP::192.168.1.20::hislip0::INSTR"
//! reference_clock_hz = 10e6                       # optional: lock to the shared 10 MHz at
//!                                                 # REF IN (default: its internal reference)
//!
//! [scope]
//! model = "lecroy-labmaster10zi-a"                # or "keysight-uxr0334a" (HiSLIP / VXI-11)
//! driver = "lecroy-maui"                          # optional: checked against the catalog
//! resource = "VICP::192.168.1.30"
//! volts_per_div = 0.05                            # optional, both channels
//! trigger_jitter_s = 1e-12                        # optional: RMS, data sheet (1 ps if not given)
//!
//! [tx]                                            # optional: without it, no Tx is driven
//! model = "gotmic-eband-tx"
//! resource = "ASRL/dev/ttyUSB0::INSTR"
//! attenuation_db = 10.0                           # optional, once enabled
//!
//! [rx]                                            # optional, like [tx]; or a manual front end:
//! driver = "manual"                               # radbench does not talk to it: the operator
//! attenuation_db = 0.0                            # sets it and confirms before the first RF
//! rf_frequency_hz = 80e9                          # optional (default 80 GHz), for the operator
//!
//! [simulation]                                    # only for a mock_lab bench
//! control = "127.0.0.1:40001"                     # its scene control channel
//!
//! [calibration]                                   # written by `radbench calibrate`
//! system_delay_s = 2.5e-9
//! reference_range_m = 1.0
//! measured_at = "2026-11-21T20:00:00.000Z"
//! response = "bench-response.toml"                # written by `radbench calibrate response`
//! ```

use crate::address::Resource;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// One instrument of the bench.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct InstrumentEntry {
    /// Catalog key (`radbench` embeds `instruments/*.toml`); optional for a manual front end.
    #[serde(default)]
    pub model: String,
    /// VISA-style resource string; none for a manual front end.
    #[serde(default)]
    pub resource: String,
    /// Optional: the driver family the catalog entry must name (`lecroy-maui`,
    /// `keysight-infiniium`, ...), checked on load; the catalog's `driver` decides either way.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub driver: Option<String>,
    /// Scope only: vertical scale of I and Q, volts per division.
    #[serde(default)]
    pub volts_per_div: Option<f64>,
    /// Front ends only: attenuation once enabled, dB.
    #[serde(default)]
    pub attenuation_db: Option<f64>,
    /// AWG only: the external reference at its REF IN, Hz (10e6 for a lab's shared 10 MHz):
    /// every capture then sends `:ROSC:SOUR EXT`; absent, `:ROSC:SOUR INT` (its own clock).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reference_clock_hz: Option<f64>,
    /// Scope only: its RMS trigger jitter, seconds, from its data sheet (or measured): every
    /// range's uncertainty carries it (docs/metrology.md; 1 ps when not stated).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub trigger_jitter_s: Option<f64>,
    /// Manual front ends only: the RF frequency the operator sets, Hz (default 80 GHz).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rf_frequency_hz: Option<f64>,
}

/// The `driver` of a front end radbench does not talk to: the operator sets it by hand.
pub(crate) const MANUAL_DRIVER: &str = "manual";

/// A front end with `driver = "manual"`: radbench never opens it; it tells the operator what to
/// set, asks for a confirmation before the first RF, and relies on the AWG outputs for the safe
/// state.
#[derive(Debug, Clone, PartialEq)]
pub struct ManualFrontEnd {
    /// `tx` or `rx`: the bench file's section.
    pub section: &'static str,
    /// The catalog key, when the bench file names one (for the LO multiplier and limits).
    pub model: Option<String>,
    pub attenuation_db: Option<f64>,
    pub rf_frequency_hz: Option<f64>,
}

impl ManualFrontEnd {
    /// `Tx` or `Rx`, for messages.
    pub fn name(&self) -> &'static str {
        if self.section == "tx" {
            "Tx"
        } else {
            "Rx"
        }
    }
}

/// A simulated bench's extras.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Simulation {
    /// `host:port` of mock_lab's scene control channel.
    pub control: String,
}

/// What `radbench calibrate` measured.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct BenchCalibration {
    /// Fixed delay of cables, horns and marker latency, subtracted from every echo delay.
    pub system_delay_s: f64,
    /// The reference target's range used to measure it, metres.
    #[serde(default)]
    pub reference_range_m: Option<f64>,
    /// When it was measured (RFC 3339 UTC).
    #[serde(default)]
    pub measured_at: Option<String>,
    /// The chain's response (`radbench calibrate response`), relative to this file.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub response: Option<String>,
}

/// The bench's fixed reference reflector (`[reference]`).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct BenchReference {
    /// A reflector that stays put through every measurement (a corner reflector, a mount),
    /// antennas to reflector, metres: `calibrate response` measures it as the scene's (as
    /// `--reflector` does) and phase ranging takes it as the time and phase reference where the
    /// leakage is not seen (docs/metrology.md).
    pub reflector_m: f64,
}

/// The whole bench file.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct BenchFile {
    /// A folder of instrument files (`*.toml` as in `instruments/`, relative to the bench file)
    /// that extends the built-in catalog, or overrides a built-in model of the same key.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub catalog: Option<PathBuf>,
    /// One TOML file of values that replace the catalog's for this bench's units (relative to
    /// the bench file; `doctor --verify-catalog --write-overrides FILE` writes it), applied on
    /// top of the built-in models and the `catalog` folder.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub catalog_overrides: Option<PathBuf>,
    pub awg: InstrumentEntry,
    pub scope: InstrumentEntry,
    #[serde(default)]
    pub tx: Option<InstrumentEntry>,
    #[serde(default)]
    pub rx: Option<InstrumentEntry>,
    #[serde(default)]
    pub simulation: Option<Simulation>,
    #[serde(default)]
    pub calibration: Option<BenchCalibration>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reference: Option<BenchReference>,
    /// The front ends of `[tx]`/`[rx]` with `driver = "manual"` (taken out of `tx`/`rx`, which
    /// hold only the front ends radbench drives).
    #[serde(skip)]
    pub manual: Vec<ManualFrontEnd>,
    /// Where each `section.key` is written (1-based lines), for errors found after parsing.
    #[serde(skip)]
    pub lines: std::collections::BTreeMap<String, usize>,
    /// The file this came from (for errors).
    #[serde(skip)]
    pub path: PathBuf,
}

/// A bench file that cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum BenchFileError {
    #[error("cannot read bench file {path}: {source}")]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("bench file {path}: {message}")]
    Invalid { path: PathBuf, message: String },
    #[error("cannot write the calibration to {path}: {source}")]
    Write {
        path: PathBuf,
        source: crate::storage::StorageError,
    },
}

impl crate::exit::Classify for BenchFileError {
    fn exit_class(&self) -> crate::exit::ExitClass {
        match self {
            BenchFileError::Write { .. } => crate::exit::ExitClass::Processing,
            _ => crate::exit::ExitClass::BadInput,
        }
    }
}

impl BenchFile {
    /// Reads and checks a bench file; errors name the file, the line and the field.
    pub fn load(path: &Path) -> Result<BenchFile, BenchFileError> {
        let text = std::fs::read_to_string(path).map_err(|source| BenchFileError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        Self::parse(&text, path)
    }

    /// Parses bench-file text; `path` names it in errors.
    pub fn parse(text: &str, path: &Path) -> Result<BenchFile, BenchFileError> {
        let invalid = |message: String| BenchFileError::Invalid {
            path: path.to_path_buf(),
            message,
        };
        let mut bench: BenchFile = toml::from_str(text)
            .map_err(|e| invalid(crate::exit::with_key_hint(&e.to_string())))?;
        let index = crate::catalog::locate::FieldIndex::new(text);
        bench.path = path.to_path_buf();
        for section in [
            "awg",
            "scope",
            "tx",
            "rx",
            "calibration",
            "simulation",
            "reference",
        ] {
            for key in [
                "model",
                "driver",
                "resource",
                "volts_per_div",
                "attenuation_db",
                "rf_frequency_hz",
                "trigger_jitter_s",
                "system_delay_s",
                "control",
                "reflector_m",
            ] {
                let field = format!("{section}.{key}");
                if let Some(line) = index.line_of_path(&field) {
                    bench.lines.insert(field, line);
                }
            }
        }
        let taken = take_manual(&mut bench);
        let at = |field: &str| {
            bench
                .lines
                .get(field)
                .map(|l| format!("line {l}: "))
                .unwrap_or_default()
        };
        let invalid_at = |field: &str, message: String| invalid(format!("{}{message}", at(field)));
        bench.manual = taken.map_err(|(field, m)| invalid_at(&field, m))?;
        if let Some(r) = bench.reference.as_ref().map(|r| r.reflector_m) {
            if !(r.is_finite() && r > 0.0) {
                return Err(invalid_at(
                    "reference.reflector_m",
                    format!(
                        "[reference] reflector_m = {r}: the fixed reflector's range from the \
                         antennas, in metres, over 0"
                    ),
                ));
            }
        }
        for (section, entry) in [
            ("awg", Some(&bench.awg)),
            ("scope", Some(&bench.scope)),
            ("tx", bench.tx.as_ref()),
            ("rx", bench.rx.as_ref()),
        ] {
            let Some(entry) = entry else { continue };
            for (key, value) in [("model", &entry.model), ("resource", &entry.resource)] {
                if value.is_empty() {
                    let manual = if matches!(section, "tx" | "rx") {
                        format!(", or driver = \"{MANUAL_DRIVER}\" for a front end radbench does not talk to")
                    } else {
                        String::new()
                    };
                    return Err(invalid(format!(
                        "[{section}] {key}: missing; give the instrument's {}{manual}",
                        if key == "model" {
                            "catalog key"
                        } else {
                            "resource string"
                        }
                    )));
                }
            }
            if entry.rf_frequency_hz.is_some() {
                return Err(invalid_at(
                    &format!("{section}.rf_frequency_hz"),
                    format!(
                        "[{section}] rf_frequency_hz: only for driver = \"{MANUAL_DRIVER}\" (a \
                         driven front end's frequency is set by radbench)"
                    ),
                ));
            }
        }
        for (section, entry) in [
            ("awg", Some(&bench.awg)),
            ("scope", Some(&bench.scope)),
            ("tx", bench.tx.as_ref()),
            ("rx", bench.rx.as_ref()),
        ] {
            let Some(entry) = entry else { continue };
            entry.resource.parse::<Resource>().map_err(|e| {
                invalid_at(
                    &format!("{section}.resource"),
                    format!("[{section}] resource = {:?}: {e}", entry.resource),
                )
            })?;
            if let Some(v) = entry.volts_per_div {
                if !(v.is_finite() && v > 0.0) {
                    return Err(invalid_at(
                        &format!("{section}.volts_per_div"),
                        format!(
                            "[{section}] volts_per_div = {v}: must be a positive number of volts"
                        ),
                    ));
                }
            }
            if let Some(hz) = entry.reference_clock_hz {
                let key = format!("{section}.reference_clock_hz");
                if section != "awg" {
                    return Err(invalid_at(
                        &key,
                        format!(
                            "[{section}] reference_clock_hz: only [awg] takes it (the AWG's \
                             external reference); a scope's is set on the scope"
                        ),
                    ));
                }
                if !(hz.is_finite() && (10e6..=300e6).contains(&hz)) {
                    return Err(invalid_at(
                        &key,
                        format!(
                            "[awg] reference_clock_hz = {hz}: the external reference's frequency \
                             in Hz, 10e6 ..= 300e6 (a lab's shared reference is 10e6)"
                        ),
                    ));
                }
            }
            if let Some(j) = entry.trigger_jitter_s {
                if !(j.is_finite() && (0.0..=1e-9).contains(&j)) {
                    return Err(invalid_at(
                        &format!("{section}.trigger_jitter_s"),
                        format!(
                            "[{section}] trigger_jitter_s = {j}: must be an RMS jitter in \
                             seconds, 0 ..= 1e-9 (a scope's is 0.1e-12 .. 2e-12)"
                        ),
                    ));
                }
            }
            if let Some(a) = entry.attenuation_db {
                if !(a.is_finite() && a >= 0.0) {
                    return Err(invalid_at(
                        &format!("{section}.attenuation_db"),
                        format!("[{section}] attenuation_db = {a}: must be 0 dB or more"),
                    ));
                }
            }
        }
        if let Some(c) = &bench.calibration {
            if !(c.system_delay_s.is_finite() && c.system_delay_s.abs() < 1e-6) {
                return Err(invalid_at(
                    "calibration.system_delay_s",
                    format!(
                        "[calibration] system_delay_s = {}: must be a finite delay under 1 us",
                        c.system_delay_s
                    ),
                ));
            }
        }
        Ok(bench)
    }

    /// The instrument catalog of this bench: the built-in models, extended and overridden by the
    /// files of its `catalog` folder when it names one, then its `catalog_overrides` file.
    pub fn catalog(&self) -> Result<crate::catalog::Catalog, crate::catalog::CatalogError> {
        let mut catalog = crate::catalog::Catalog::load(self.catalog_dir().as_deref())?;
        if let Some(path) = self.catalog_overrides_file() {
            catalog.apply_overrides(&path)?;
        }
        Ok(catalog)
    }

    /// The `catalog_overrides` file it names, relative to the bench file's own folder.
    pub(crate) fn catalog_overrides_file(&self) -> Option<PathBuf> {
        let base = self.path.parent().unwrap_or(Path::new("."));
        self.catalog_overrides.as_ref().map(|file| base.join(file))
    }

    /// Every file the bench's catalog is read from beyond the built-in ones: the `catalog`
    /// folder's instrument files, then the overrides file (what a run folder keeps a copy of).
    pub(crate) fn catalog_files(&self) -> Result<Vec<PathBuf>, crate::catalog::CatalogError> {
        let mut files = match self.catalog_dir() {
            Some(dir) => crate::catalog::folder_files(&dir)?,
            None => Vec::new(),
        };
        files.extend(self.catalog_overrides_file());
        Ok(files)
    }

    /// The `catalog` folder it names, relative to the bench file's own folder.
    pub(crate) fn catalog_dir(&self) -> Option<PathBuf> {
        let base = self.path.parent().unwrap_or(Path::new("."));
        self.catalog.as_ref().map(|dir| base.join(dir))
    }

    /// Checks that every model names an instrument of the catalog of the right kind; the error
    /// names the file, the line and the field, and lists the models there are.
    pub(crate) fn check_models(
        &self,
        catalog: &crate::catalog::Catalog,
    ) -> Result<(), BenchFileError> {
        use crate::catalog::InstrumentKind;
        for (section, entry, kind) in [
            ("awg", Some(&self.awg), InstrumentKind::Awg),
            ("scope", Some(&self.scope), InstrumentKind::Digitizer),
            ("tx", self.tx.as_ref(), InstrumentKind::RfTx),
            ("rx", self.rx.as_ref(), InstrumentKind::RfRx),
        ] {
            let Some(entry) = entry else { continue };
            let line = self
                .lines
                .get(&format!("{section}.model"))
                .map(|l| format!("line {l}: "))
                .unwrap_or_default();
            let fits: Vec<&str> = catalog
                .models()
                .filter(|(m, _)| m.instrument.kind == kind)
                .map(|(m, _)| m.instrument.key.as_str())
                .collect();
            let model = catalog.get(&entry.model).ok();
            if model.is_none_or(|m| m.instrument.kind != kind) {
                return Err(BenchFileError::Invalid {
                    path: self.path.clone(),
                    message: format!(
                        "{line}[{section}] model = {:?}: {}; allowed: {}",
                        entry.model,
                        if model.is_some() {
                            "that model is not this kind of instrument"
                        } else {
                            "not in the instrument catalog"
                        },
                        fits.join(", ")
                    ),
                });
            }
            if let Some(model) = model {
                let family = crate::driver::open::spelling(model);
                if let Some(wanted) = &entry.driver {
                    if wanted != family {
                        let line = self
                            .lines
                            .get(&format!("{section}.driver"))
                            .map(|l| format!("line {l}: "))
                            .unwrap_or_default();
                        return Err(BenchFileError::Invalid {
                            path: self.path.clone(),
                            message: format!(
                                "{line}[{section}] driver = {wanted:?}: the catalog's {:?} is driven by \
                                 {family:?}; write driver = {family:?} or leave the key out",
                                entry.model
                            ),
                        });
                    }
                }
                crate::driver::open::check(model).map_err(|e| BenchFileError::Invalid {
                    path: self.path.clone(),
                    message: format!("{line}[{section}] model = {:?}: {e}", entry.model),
                })?;
            }
        }
        for m in &self.manual {
            let Some(key) = &m.model else { continue };
            let kind = if m.section == "tx" {
                InstrumentKind::RfTx
            } else {
                InstrumentKind::RfRx
            };
            if catalog
                .get(key)
                .ok()
                .is_none_or(|c| c.instrument.kind != kind)
            {
                let line = self
                    .lines
                    .get(&format!("{}.model", m.section))
                    .map(|l| format!("line {l}: "))
                    .unwrap_or_default();
                let fits: Vec<&str> = catalog
                    .models()
                    .filter(|(c, _)| c.instrument.kind == kind)
                    .map(|(c, _)| c.instrument.key.as_str())
                    .collect();
                return Err(BenchFileError::Invalid {
                    path: self.path.clone(),
                    message: format!(
                        "{line}[{}] model = {key:?}: not a {} front end of the instrument \
                         catalog (a manual front end may leave the model out); allowed: {}",
                        m.section,
                        m.name(),
                        fits.join(", ")
                    ),
                });
            }
        }
        Ok(())
    }

    /// The response calibration the bench file names, relative to `bench_path`'s folder.
    pub(crate) fn response_path(&self, bench_path: &Path) -> Option<PathBuf> {
        let name = self.calibration.as_ref()?.response.as_ref()?;
        Some(bench_path.parent().unwrap_or(Path::new(".")).join(name))
    }

    /// The stored system delay, or 0 when the bench was never calibrated.
    /// The fixed reference reflector's range (`[reference] reflector_m`), m.
    pub(crate) fn reference_reflector_m(&self) -> Option<f64> {
        self.reference.as_ref().map(|r| r.reflector_m)
    }

    pub fn system_delay_s(&self) -> f64 {
        self.calibration.as_ref().map_or(0.0, |c| c.system_delay_s)
    }

    /// What this bench's captures are processed with, whatever the command: its calibrated
    /// system delay and its scope's stated trigger jitter (each range's uncertainty).
    pub fn processing_of_this_bench(&self, options: &mut crate::measure::ProcessOptions) {
        options.system_delay_s = self.system_delay_s();
        options.trigger_jitter_s = self.scope.trigger_jitter_s;
    }

    /// The warning a capture on this bench carries in every output while it has no delay
    /// calibration; `None` once `radbench calibrate` has stored one.
    pub fn uncalibrated_warning(&self) -> Option<String> {
        self.calibration
            .is_none()
            .then(|| uncalibrated_warning(Some(&self.path)))
    }
}

/// Moves the `[tx]`/`[rx]` entries with `driver = "manual"` out of `bench` and checks them; an
/// error is (the field, the message).
fn take_manual(bench: &mut BenchFile) -> Result<Vec<ManualFrontEnd>, (String, String)> {
    let mut manual = Vec::new();
    for section in ["tx", "rx"] {
        let slot = if section == "tx" {
            &mut bench.tx
        } else {
            &mut bench.rx
        };
        if slot.as_ref().and_then(|e| e.driver.as_deref()) != Some(MANUAL_DRIVER) {
            continue;
        }
        let Some(e) = slot.take() else { continue };
        let field = |key: &str| format!("{section}.{key}");
        if !e.resource.is_empty() {
            return Err((
                field("resource"),
                format!(
                    "[{section}] resource = {:?}: a manual front end is not connected; remove \
                     the resource, or the driver = \"{MANUAL_DRIVER}\" line to drive it",
                    e.resource
                ),
            ));
        }
        if e.volts_per_div.is_some() {
            return Err((
                field("volts_per_div"),
                format!("[{section}] volts_per_div: only for [scope]"),
            ));
        }
        if let Some(a) = e.attenuation_db {
            if !(a.is_finite() && a >= 0.0) {
                return Err((
                    field("attenuation_db"),
                    format!("[{section}] attenuation_db = {a}: must be 0 dB or more"),
                ));
            }
        }
        if let Some(f) = e.rf_frequency_hz {
            if !(f.is_finite() && f > 0.0) {
                return Err((
                    field("rf_frequency_hz"),
                    format!(
                        "[{section}] rf_frequency_hz = {f}: must be a positive frequency in Hz"
                    ),
                ));
            }
        }
        manual.push(ManualFrontEnd {
            section,
            model: (!e.model.is_empty()).then_some(e.model),
            attenuation_db: e.attenuation_db,
            rf_frequency_hz: e.rf_frequency_hz,
        });
    }
    Ok(manual)
}

/// The warning of a bench without `[calibration]` (`bench_file`: its path, for the command to
/// run). Ranges are then 0.375 m or so too long: nothing else shows it.
pub fn uncalibrated_warning(bench_file: Option<&Path>) -> String {
    let file = bench_file.map_or("FILE".to_string(), |p| p.display().to_string());
    format!(
        "the bench is not calibrated (its bench file has no [calibration]: system_delay_s 0): \
         every range includes the fixed delay of cables, horns and marker latency; put a \
         target at a known range and run `radbench calibrate --reference-range METRES --bench \
         {file} --allow-rf`"
    )
}

/// Writes `calibration` into the bench file at `path`: its `[calibration]` section's values are
/// set in place (a key no longer given is removed), and every other line, comments included (also
/// those inside the section and after a value), is kept as it was. The write is atomic.
pub fn store_calibration(
    path: &Path,
    calibration: &BenchCalibration,
) -> Result<(), BenchFileError> {
    let text = std::fs::read_to_string(path).map_err(|source| BenchFileError::Read {
        path: path.to_path_buf(),
        source,
    })?;
    let invalid = |message: String| BenchFileError::Invalid {
        path: path.to_path_buf(),
        message,
    };
    let mut doc: toml_edit::DocumentMut = text.parse().map_err(|e| invalid(format!("{e}")))?;
    let fresh = !doc.contains_key("calibration");
    if fresh {
        let mut table = toml_edit::Table::new();
        table
            .decor_mut()
            .set_prefix("\n# Written by `radbench calibrate`.\n");
        doc.insert("calibration", toml_edit::Item::Table(table));
    }
    let table = doc["calibration"]
        .as_table_mut()
        .ok_or_else(|| invalid("[calibration] must be a table".into()))?;
    let float = |v: f64| Some(toml_edit::Value::from(v));
    let text_value = |v: &Option<String>| v.as_deref().map(toml_edit::Value::from);
    set_keeping_comments(table, "system_delay_s", float(calibration.system_delay_s));
    set_keeping_comments(
        table,
        "reference_range_m",
        calibration.reference_range_m.and_then(float),
    );
    set_keeping_comments(table, "measured_at", text_value(&calibration.measured_at));
    set_keeping_comments(table, "response", text_value(&calibration.response));
    let out = doc.to_string();
    // A bench file kept as a symlink (e.g. into a shared configuration folder) is updated where
    // it really lives; the atomic writer never writes through a link itself.
    let target = std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf());
    crate::storage::write_atomic(&target, out.as_bytes()).map_err(|source| {
        BenchFileError::Write {
            path: path.to_path_buf(),
            source,
        }
    })?;
    // The result must still parse: never leave a broken bench file behind.
    BenchFile::load(path).map(|_| ())
}

/// Sets `key` to `value` in `table` keeping the line's comments (before the key and after the
/// value); `None` removes the key.
fn set_keeping_comments(table: &mut toml_edit::Table, key: &str, value: Option<toml_edit::Value>) {
    match (value, table.get_mut(key)) {
        (None, _) => {
            table.remove(key);
        }
        (Some(mut value), Some(item)) => {
            if let Some(old) = item.as_value() {
                *value.decor_mut() = old.decor().clone();
            }
            *item = toml_edit::Item::Value(value);
        }
        (Some(value), None) => {
            table.insert(key, toml_edit::Item::Value(value));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = r#"
# my bench
[awg]
model = "keysight-m8195a"
resource = "TCPIP::127.0.0.1::hislip0,4880::INSTR"

[scope]
model = "lecroy-labmaster10zi-a"
resource = "VICP::127.0.0.1"

[calibration]
system_delay_s = 1e-9
"#;

    #[test]
    fn parses_and_rejects_with_the_field_named() {
        let b = BenchFile::parse(GOOD, Path::new("b.toml")).unwrap();
        assert_eq!(b.system_delay_s(), 1e-9);
        assert!(b.tx.is_none());
        let bad = GOOD.replace("VICP::127.0.0.1", "VICP:127.0.0.1");
        let e = BenchFile::parse(&bad, Path::new("b.toml")).unwrap_err();
        assert!(e.to_string().contains("[scope] resource"), "{e}");
        let bad = GOOD.replace("model = \"keysight-m8195a\"", "modle = 1");
        let e = BenchFile::parse(&bad, Path::new("b.toml")).unwrap_err();
        assert!(
            e.to_string().contains("modle") && e.to_string().contains("b.toml"),
            "{e}"
        );
    }

    #[test]
    fn a_reference_reflector_is_read_and_a_bad_one_named_with_its_line() {
        let b = BenchFile::parse(
            &format!("{GOOD}\n[reference]\nreflector_m = 0.45\n"),
            Path::new("b.toml"),
        )
        .unwrap();
        assert_eq!(b.reference_reflector_m(), Some(0.45));
        assert_eq!(
            BenchFile::parse(GOOD, Path::new("b.toml"))
                .unwrap()
                .reference_reflector_m(),
            None
        );
        for bad in ["-0.2", "0.0", "nan"] {
            let text = format!("{GOOD}\n[reference]\nreflector_m = {bad}\n");
            let e = BenchFile::parse(&text, Path::new("b.toml"))
                .unwrap_err()
                .to_string();
            assert!(
                e.contains("[reference] reflector_m") && e.contains("line 15"),
                "{bad}: {e}"
            );
        }
        let e = BenchFile::parse(
            &format!("{GOOD}\n[reference]\nreflector = 0.45\n"),
            Path::new("b.toml"),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("reflector"), "{e}");
    }

    #[test]
    fn the_driver_key_is_checked_against_the_catalog() {
        let catalog = crate::catalog::Catalog::embedded().unwrap();
        let uxr = GOOD
            .replace("lecroy-labmaster10zi-a", "keysight-uxr0334a")
            .replace("VICP::127.0.0.1", "TCPIP::127.0.0.1::hislip0::INSTR");
        let ok = uxr.replace("[scope]\n", "[scope]\ndriver = \"keysight-infiniium\"\n");
        let b = BenchFile::parse(&ok, Path::new("b.toml")).unwrap();
        b.check_models(&catalog).unwrap();
        // Without the key the catalog decides, as for bench files written before it existed.
        let b = BenchFile::parse(&uxr, Path::new("b.toml")).unwrap();
        b.check_models(&catalog).unwrap();
        let wrong = uxr.replace("[scope]\n", "[scope]\ndriver = \"lecroy-maui\"\n");
        let b = BenchFile::parse(&wrong, Path::new("b.toml")).unwrap();
        let e = b.check_models(&catalog).unwrap_err().to_string();
        assert!(
            e.contains("[scope] driver = \"lecroy-maui\"")
                && e.contains("\"keysight-infiniium\"")
                && e.contains("line 8"),
            "{e}"
        );
    }

    #[test]
    fn calibration_sets_the_section_s_values_and_keeps_every_comment() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("bench.toml");
        std::fs::write(&path, GOOD).unwrap();
        let cal = BenchCalibration {
            system_delay_s: 2.5e-9,
            reference_range_m: Some(1.0),
            measured_at: Some("2026-11-21T20:00:00.000Z".into()),
            response: None,
        };
        store_calibration(&path, &cal).unwrap();
        store_calibration(&path, &cal).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(text.contains("# my bench"));
        assert_eq!(text.matches("[calibration]").count(), 1, "{text}");
        assert_eq!(
            BenchFile::load(&path).unwrap().calibration,
            Some(cal.clone())
        );
        // Comments inside the section and after a value survive a new value.
        let commented = text.replace(
            "[calibration]\n",
            "[calibration]\n# the horns were moved on Monday\n",
        );
        std::fs::write(
            &path,
            commented.replace(
                "reference_range_m = 1.0",
                "reference_range_m = 1.0 # pillar B",
            ),
        )
        .unwrap();
        let again = BenchCalibration {
            system_delay_s: 2.6e-9,
            reference_range_m: Some(1.5),
            response: Some("bench-response.toml".into()),
            ..cal
        };
        store_calibration(&path, &again).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(text.contains("# the horns were moved on Monday"), "{text}");
        assert!(
            text.contains("reference_range_m = 1.5 # pillar B"),
            "{text}"
        );
        assert_eq!(BenchFile::load(&path).unwrap().calibration, Some(again));
    }
}
