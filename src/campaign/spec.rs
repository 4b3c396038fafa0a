//! The campaign spec: a TOML file naming the bench, the waveform, the processing (one or more
//! algorithms applied to the same captures), the repetitions, the positioner and the steps (an
//! explicit list or a sweep). `radbench campaign new KIND` prints a commented one; docs/campaign.md
//! lists every field.
//!
//! Every error names the file, the line and the field, and what is allowed: unknown fields and
//! wrong types come from the TOML parser's span; values out of range are located again in the
//! text (toml_edit keeps the spans) when the checks after parsing find them.

use super::axis::AxisValue;
use super::kind::{allowed_names, Reads, Setting};
use super::spec_error::FieldErrors;
pub use super::spec_error::SpecError;
#[cfg(test)]
use crate::measure::CorrectionMode;
use crate::measure::ProcessingChoices;
#[cfg(test)]
use crate::measure::{ModelOrderChoice as ModelOrder, ModelOrderName};
use crate::waveform::WaveformKind;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The whole spec, as written.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Spec {
    /// Name of the campaign (default: the file name without `.toml`).
    #[serde(default)]
    pub name: Option<String>,
    /// One line on what it measures.
    #[serde(default)]
    pub description: Option<String>,
    /// Seed of the PRBS bits and, on a simulated bench, of each step's noise.
    #[serde(default = "default_seed")]
    pub seed: u64,
    /// Marker-triggered repetitions per step (averaged coherently, their spread reported).
    #[serde(default = "default_repetitions")]
    pub repetitions: usize,
    /// Longest wait for one marker-triggered acquisition, seconds.
    #[serde(default = "default_wait")]
    pub wait_s: f64,
    #[serde(default)]
    pub bench: BenchSection,
    #[serde(default)]
    pub waveform: WaveformSection,
    #[serde(default)]
    /// `[processing]`: the algorithms (each applied to the same captures) and the choices they
    /// share; anything not given takes the defaults of `radbench capture`.
    pub processing: ProcessingChoices,
    #[serde(default)]
    pub positioner: Option<PositionerSection>,
    /// `[sweep]` (one axis) or `[[sweep]]` tables (several axes, nested: the last varies
    /// fastest).
    #[serde(default)]
    pub sweep: Option<Sweeps>,
    #[serde(default)]
    pub steps: Vec<StepSection>,
    #[serde(default)]
    pub run: RunSection,
    #[serde(default)]
    pub output: OutputSection,
}

/// `[output]`: which of a step's files stay in the run folder (docs/campaign.md, "Disk budget").
/// By default a night's: every file but the scope's `.trc` copy, whose words the SigMF recording
/// holds (3.9 MB a step instead of 7.2).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct OutputSection {
    /// The scope's own `.trc` files (the same words as the SigMF recording).
    #[serde(default)]
    pub keep_trc: bool,
    /// The PNG copies of the profile and link plots (the SVGs stay).
    #[serde(default = "yes")]
    pub keep_bitmaps: bool,
    /// The link figure (`link.svg`, and `link.png` with the bitmaps).
    #[serde(default = "yes")]
    pub keep_link_plots: bool,
}

fn yes() -> bool {
    true
}

impl Default for OutputSection {
    /// A night's: the `.trc` copy dropped, the bitmaps and the link figure kept.
    fn default() -> Self {
        OutputSection {
            keep_trc: false,
            keep_bitmaps: true,
            keep_link_plots: true,
        }
    }
}

impl OutputSection {
    /// Every file kept: a plan recorded before `[output]` existed (its run kept every file).
    pub(crate) fn keep_all() -> Self {
        OutputSection {
            keep_trc: true,
            keep_bitmaps: true,
            keep_link_plots: true,
        }
    }
    /// Whether a step's file named `name` stays.
    pub fn keeps(&self, name: &str) -> bool {
        let bitmap = name.ends_with(".png");
        let link = name == "link.svg" || name == "link.png";
        let trc = name.ends_with(".trc");
        (self.keep_trc || !trc) && (self.keep_bitmaps || !bitmap) && (self.keep_link_plots || !link)
    }
}

/// `[run]`: how the run rides out a transient fault (docs/campaign.md, "Retries").
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct RunSection {
    /// Times a step is measured again after a transient fault (`--retries` overrides it).
    #[serde(default = "default_retries")]
    pub retries: usize,
    /// The wait before the first retry of a step, seconds; doubled before each next one.
    #[serde(default = "default_retry_backoff")]
    pub retry_backoff_s: f64,
    /// A program and its arguments run when the run ends (complete, failed or stopped), with
    /// `RADBENCH_RUN_DIR`, `RADBENCH_STATUS` and `RADBENCH_SUMMARY` in its environment.
    #[serde(default)]
    pub notify: Vec<String>,
    /// The longest the notify program may run, seconds (killed past it).
    #[serde(default = "default_notify_timeout")]
    pub notify_timeout_s: f64,
    /// Who runs the campaign, as the report names them (else `$USER`, `$LOGNAME`).
    #[serde(default)]
    pub operator: Option<String>,
}

fn default_notify_timeout() -> f64 {
    super::notify::DEFAULT_NOTIFY_TIMEOUT_S
}

impl Default for RunSection {
    fn default() -> Self {
        RunSection {
            retries: default_retries(),
            retry_backoff_s: default_retry_backoff(),
            notify: Vec::new(),
            notify_timeout_s: default_notify_timeout(),
            operator: None,
        }
    }
}

fn default_retries() -> usize {
    2
}

fn default_retry_backoff() -> f64 {
    2.0
}

fn default_seed() -> u64 {
    1
}

fn default_repetitions() -> usize {
    1
}

fn default_wait() -> f64 {
    10.0
}

/// `[bench]`: a bench file, or (without one) the built-in mock lab.
#[derive(Debug, Clone, Default, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct BenchSection {
    /// A bench file, relative to the spec's folder (`--bench` overrides it).
    #[serde(default)]
    pub file: Option<PathBuf>,
    /// Built-in mock lab only: its scene file, relative to the spec's folder.
    #[serde(default)]
    pub scene: Option<PathBuf>,
    /// Built-in mock lab only: the AWG's transport.
    #[serde(default)]
    pub awg_transport: Option<crate::measure::AwgLink>,
    /// Built-in mock lab only: the scope's transport.
    #[serde(default)]
    pub scope_transport: Option<crate::measure::ScopeLink>,
    /// Built-in mock lab only: the scope it serves (a name of mock_lab's table of scopes; default
    /// the first, `lecroy`).
    #[serde(default)]
    pub scope_model: Option<crate::measure::ScopeModel>,
}

/// `[waveform]`: the family and any parameters that differ from the thesis' defaults.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct WaveformSection {
    /// `msk-lfm` when not given, as the docs say.
    #[serde(default = "msk_lfm")]
    pub kind: WaveformKind,
    #[serde(default)]
    pub bandwidth_hz: Option<f64>,
    /// MSK-LFM only.
    #[serde(default)]
    pub sample_rate_hz: Option<f64>,
    /// MSK-LFM only.
    #[serde(default)]
    pub pulse_s: Option<f64>,
    /// MSK-LFM only.
    #[serde(default)]
    pub bits_per_pulse: Option<usize>,
    /// MSK-LFM only: `centred` (default), `upper` (0 .. B, the thesis' sweep) or `lower`.
    #[serde(default)]
    pub band: Option<crate::waveform::SweepBand>,
    /// OFDM only.
    #[serde(default)]
    pub subcarriers: Option<usize>,
    /// OFDM only.
    #[serde(default)]
    pub oversampling: Option<usize>,
    /// OFDM only.
    #[serde(default)]
    pub cp_fraction: Option<f64>,
    /// OFDM only.
    #[serde(default)]
    pub symbols: Option<usize>,
    /// OFDM only.
    #[serde(default)]
    pub preamble_symbols: Option<usize>,
    /// Text to send (default: PRBS bits from `seed`).
    #[serde(default)]
    pub payload: Option<String>,
}

fn msk_lfm() -> WaveformKind {
    WaveformKind::MskLfm
}

impl Default for WaveformSection {
    fn default() -> Self {
        Self {
            kind: WaveformKind::MskLfm,
            bandwidth_hz: None,
            sample_rate_hz: None,
            pulse_s: None,
            bits_per_pulse: None,
            band: None,
            subcarriers: None,
            oversampling: None,
            cp_fraction: None,
            symbols: None,
            preamble_symbols: None,
            payload: None,
        }
    }
}

/// `[positioner]`: who places the targets.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct PositionerSection {
    pub kind: PositionerKind,
    /// `command`: the program (a path relative to the spec's folder, or a name on `PATH`).
    #[serde(default)]
    pub program: Option<String>,
    /// `command`: its arguments; `{position_m}`, `{positions_m}`, `{step}` and `{of}` are
    /// replaced.
    #[serde(default)]
    pub args: Vec<String>,
    /// `command`: longest run, seconds (killed after it, and the campaign stops).
    #[serde(default)]
    pub timeout_s: Option<f64>,
    /// Wait after each move before measuring, seconds.
    #[serde(default)]
    pub settle_s: Option<f64>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum PositionerKind {
    /// Moves the simulated targets through the mock lab's control channel.
    MockLab,
    /// Tells the operator where to put the pillars and waits for Enter (RF is off meanwhile).
    Prompt,
    /// Runs a program with the positions (a linear stage's script).
    Command,
}

impl PositionerKind {
    pub fn name(self) -> &'static str {
        match self {
            PositionerKind::MockLab => "mock-lab",
            PositionerKind::Prompt => "prompt",
            PositionerKind::Command => "command",
        }
    }
}

/// `[sweep]` or `[[sweep]]`: one table, or several nested.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(untagged)]
pub enum Sweeps {
    One(SweepSection),
    Many(Vec<SweepSection>),
}

impl Sweeps {
    /// The tables, outer first, each with the prefix of its fields (`sweep`, `sweep[1]`).
    pub fn tables(&self) -> Vec<(String, &SweepSection)> {
        match self {
            Sweeps::One(s) => vec![("sweep".into(), s)],
            Sweeps::Many(v) => v
                .iter()
                .enumerate()
                .map(|(i, s)| (format!("sweep[{i}]"), s))
                .collect(),
        }
    }
}

// A table or an array of tables, each read by `SweepSection`'s own derive (so its errors keep
// their place in the file).
impl<'de> Deserialize<'de> for Sweeps {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> serde::de::Visitor<'de> for V {
            type Value = Sweeps;
            fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str("a [sweep] table or [[sweep]] tables")
            }
            fn visit_map<A: serde::de::MapAccess<'de>>(self, m: A) -> Result<Sweeps, A::Error> {
                SweepSection::deserialize(serde::de::value::MapAccessDeserializer::new(m))
                    .map(Sweeps::One)
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(self, s: A) -> Result<Sweeps, A::Error> {
                Vec::<SweepSection>::deserialize(serde::de::value::SeqAccessDeserializer::new(s))
                    .map(Sweeps::Many)
            }
        }
        d.deserialize_any(V)
    }
}

/// One sweep axis: a setting over a list of values.
#[derive(Debug, Clone, Default, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct SweepSection {
    /// A setting's name (campaign/kind.rs (`SETTINGS`) lists them: `position`, `awg-amplitude`, ...).
    pub parameter: String,
    /// The values, in the parameter's unit, or names (or `start`, `step`, `count`).
    #[serde(default)]
    pub values: Option<Vec<AxisValue>>,
    #[serde(default)]
    pub start: Option<f64>,
    #[serde(default)]
    pub step: Option<f64>,
    #[serde(default)]
    pub count: Option<usize>,
    /// Where the targets stand, metres (`position`: the moved one's entry is replaced by each
    /// value; `separation`: the first target, the second stands one separation behind it).
    #[serde(default)]
    pub targets: Option<Vec<f64>>,
    /// `position`: which target moves (0 = the first).
    #[serde(default)]
    pub target: Option<usize>,
}

/// `[[steps]]`: one explicit step; what it does not give stays as the step before left it (the
/// first step starts from the spec's waveform and the bench's own settings).
#[derive(Debug, Clone, Default, PartialEq, Deserialize, Serialize)]
pub struct StepSection {
    #[serde(default)]
    pub label: Option<String>,
    /// Where the targets stand, metres.
    #[serde(default)]
    pub targets: Option<Vec<f64>>,
    #[serde(default)]
    pub bandwidth_hz: Option<f64>,
    #[serde(default)]
    pub tx_attenuation_db: Option<f64>,
    /// Mock lab only.
    #[serde(default)]
    pub snr_db: Option<f64>,
    /// Simulated benches only: the targets' radial velocity, m/s (positive receding).
    #[serde(default)]
    pub velocity_mps: Option<f64>,
    /// Any other setting by its name (`awg-amplitude = 0.5`, `window = "hann"`), checked
    /// against campaign/kind.rs (`SETTINGS`) once parsed.
    #[serde(flatten)]
    pub settings: std::collections::BTreeMap<String, AxisValue>,
}

/// The fields a `[[steps]]` entry has besides the settings' names.
const STEP_FIELDS: [&str; 6] = [
    "label",
    "targets",
    "bandwidth_hz",
    "tx_attenuation_db",
    "snr_db",
    "velocity_mps",
];

/// A spec read from a file, with its text (for locating fields) and its folder (for relative
/// paths).
#[derive(Debug, Clone)]
pub struct SpecFile {
    pub path: PathBuf,
    pub text: String,
    pub spec: Spec,
}

impl SpecFile {
    /// Reads and parses a spec file.
    pub fn load(path: &Path) -> Result<SpecFile, SpecError> {
        let text = std::fs::read_to_string(path).map_err(|source| SpecError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        Self::parse(&text, path)
    }

    /// Parses spec text; `path` names it in errors and anchors relative paths.
    pub fn parse(text: &str, path: &Path) -> Result<SpecFile, SpecError> {
        let spec: Spec = toml::from_str(text).map_err(|e| syntax_error(text, path, &e))?;
        let file = SpecFile {
            path: path.to_path_buf(),
            text: text.to_string(),
            spec,
        };
        file.check_setting_names()?;
        Ok(file)
    }

    /// Every `[[sweep]] parameter` and `[[steps]]` key names a setting of campaign/kind.rs (`SETTINGS`),
    /// and `start`/`step`/`count` sweep numbers only.
    fn check_setting_names(&self) -> Result<(), SpecError> {
        if let Some(sweeps) = &self.spec.sweep {
            for (prefix, sw) in sweeps.tables() {
                let Some(setting) = Setting::named(&sw.parameter) else {
                    return Err(self.error(
                        &format!("{prefix}.parameter"),
                        format!(
                            "\"{}\" is not a setting a step can set; allowed: {}",
                            sw.parameter,
                            allowed_names()
                        ),
                    ));
                };
                let ranged = sw.start.is_some() || sw.step.is_some() || sw.count.is_some();
                if let (Reads::Name(names), true) = (setting.reads, ranged) {
                    return Err(self.error(
                        &prefix,
                        format!(
                            "{} is swept over names: give values = [{}] (not start, step, \
                             count)",
                            setting.name,
                            names
                                .iter()
                                .map(|n| format!("\"{n}\""))
                                .collect::<Vec<_>>()
                                .join(", ")
                        ),
                    ));
                }
            }
        }
        for (k, st) in self.spec.steps.iter().enumerate() {
            if let Some(name) = st.settings.keys().find(|n| Setting::named(n).is_none()) {
                return Err(self.error(
                    &format!("steps[{k}].{name}"),
                    format!(
                        "unknown field; allowed: {}, or a setting: {}",
                        STEP_FIELDS.join(", "),
                        allowed_names()
                    ),
                ));
            }
        }
        Ok(())
    }

    /// The folder relative paths of the spec start from.
    pub fn folder(&self) -> PathBuf {
        match self.path.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        }
    }

    /// `path` relative to the spec's folder (absolute paths stay).
    pub fn resolve(&self, path: &Path) -> PathBuf {
        if path.is_absolute() {
            path.to_path_buf()
        } else {
            self.folder().join(path)
        }
    }

    /// An error on `field` (dotted, with `[i]` for array entries), located in the text.
    pub fn error(&self, field: &str, message: impl Into<String>) -> SpecError {
        SpecError::Field {
            path: self.path.clone(),
            line: locate(&self.text, field),
            field: field.to_string(),
            message: message.into(),
        }
    }

    /// The campaign's name: `name`, or the file name without its extension.
    pub fn name(&self) -> String {
        self.spec.name.clone().unwrap_or_else(|| {
            self.path
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_else(|| "campaign".into())
        })
    }
}

/// 1-based line of byte `offset` in `text`.
fn line_of(text: &str, offset: usize) -> usize {
    text[..offset.min(text.len())].matches('\n').count() + 1
}

/// A parser error as file:line:field and the parser's message (which names what is allowed).
fn syntax_error(text: &str, path: &Path, e: &toml::de::Error) -> SpecError {
    let mut message = crate::exit::with_key_hint(e.message().trim());
    if message.contains("untagged enum ModelOrderChoice") {
        message = "allowed: a number of targets (1 or more, below music_m), or \"targets\" (each \
                   step's number of targets)"
            .into();
    }
    if message.contains("expected `none` or `rx`") {
        message.push_str(" (tx and both, the AWG's waveform pre-distorted, are not available yet)");
    }
    let Some(span) = e.span() else {
        return SpecError::Field {
            path: path.to_path_buf(),
            line: None,
            field: "(file)".into(),
            message,
        };
    };
    let line = line_of(text, span.start);
    let field = field_at(text, span.start).unwrap_or_else(|| "(file)".into());
    SpecError::Field {
        path: path.to_path_buf(),
        line: Some(line),
        field,
        message,
    }
}

/// The dotted name of the key on the line holding `offset`, under the table header above it.
fn field_at(text: &str, offset: usize) -> Option<String> {
    let start = text[..offset.min(text.len())]
        .rfind('\n')
        .map_or(0, |i| i + 1);
    let line = text[start..].lines().next().unwrap_or("");
    let trimmed = line.trim();
    let header = |l: &str| -> Option<String> {
        let l = l.trim();
        let inner = l
            .strip_prefix("[[")
            .and_then(|r| r.split("]]").next())
            .or_else(|| l.strip_prefix('[').and_then(|r| r.split(']').next()))?;
        Some(inner.trim().to_string())
    };
    if trimmed.starts_with('[') {
        return header(trimmed);
    }
    let key = trimmed
        .split('=')
        .next()
        .map(|k| k.trim().trim_matches('"').to_string())
        .filter(|k| !k.is_empty() && !k.starts_with('#'));
    let table = text[..start].lines().rev().find_map(|l| {
        let l = l.trim();
        if l.starts_with('[') {
            header(l)
        } else {
            None
        }
    });
    match (table, key) {
        (Some(t), Some(k)) => Some(format!("{t}.{k}")),
        (None, Some(k)) => Some(k),
        (Some(t), None) => Some(t),
        (None, None) => None,
    }
}

/// The line of `field` (`a.b`, `steps[2].targets`) in `text`, when it is written there.
pub(crate) fn locate(text: &str, field: &str) -> Option<usize> {
    let doc = toml_edit::ImDocument::parse(text.to_string()).ok()?;
    let mut table: &toml_edit::Table = doc.as_table();
    let mut last_span = None;
    let parts: Vec<&str> = field.split('.').collect();
    for (k, part) in parts.iter().enumerate() {
        let (name, index) = match part.split_once('[') {
            Some((n, rest)) => (n, rest.trim_end_matches(']').parse::<usize>().ok()),
            None => (*part, None),
        };
        let item = table.get(name)?;
        let key_span = table.key(name).and_then(|key| key.span());
        last_span = key_span.or_else(|| item.span()).or(last_span);
        let is_last = k + 1 == parts.len();
        match (item, index) {
            (toml_edit::Item::ArrayOfTables(a), Some(i)) => {
                let t = a.get(i)?;
                last_span = t.span().or(last_span);
                table = t;
            }
            (toml_edit::Item::Value(toml_edit::Value::Array(a)), Some(i)) => {
                last_span = a.get(i).and_then(|v| v.span()).or(last_span);
                break;
            }
            (toml_edit::Item::Table(t), None) if !is_last => {
                last_span = t.span().or(last_span);
                table = t;
            }
            _ => break,
        }
    }
    last_span.map(|s| line_of(text, s.start))
}

/// The kinds' table names the spec's fields in its errors through this.
impl FieldErrors for SpecFile {
    fn field_error(&self, field: &str, message: String) -> SpecError {
        self.error(field, message)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<SpecFile, SpecError> {
        SpecFile::parse(text, Path::new("c.toml"))
    }

    #[test]
    fn an_unknown_field_names_file_line_field_and_what_is_allowed() {
        let err = parse("seed = 3\n\n[sweep]\nparameter = \"position\"\nstpe = 0.03\n")
            .unwrap_err()
            .to_string();
        assert!(err.starts_with("c.toml:5: `sweep.stpe`"), "{err}");
        assert!(err.contains("expected one of"), "{err}");
    }

    #[test]
    fn a_wrong_variant_lists_the_allowed_ones() {
        let err = parse("[sweep]\nparameter = \"height\"\n")
            .unwrap_err()
            .to_string();
        assert!(err.starts_with("c.toml:2: `sweep.parameter`"), "{err}");
        assert!(err.contains("position") && err.contains("snr"), "{err}");
    }

    #[test]
    fn a_wrong_type_is_located() {
        let err = parse("repetitions = \"four\"\n").unwrap_err().to_string();
        assert!(err.starts_with("c.toml:1: `repetitions`"), "{err}");
    }

    #[test]
    fn fields_are_located_after_parsing() {
        let text = "name = \"x\"\n[sweep]\nparameter = \"snr\"\ncount = 0\n\n[[steps]]\n\n[[steps]]\ntargets = [1.0, -2.0]\n";
        assert_eq!(locate(text, "sweep.count"), Some(4));
        assert_eq!(locate(text, "steps[1].targets"), Some(9));
        assert_eq!(locate(text, "steps[1].targets[1]"), Some(9));
        assert_eq!(locate(text, "steps[0]"), Some(6));
        assert_eq!(locate(text, "seed"), None);
    }

    #[test]
    fn the_model_order_is_a_number_or_targets() {
        let f = parse("[processing]\nmusic_p = \"targets\"\n").unwrap();
        assert_eq!(
            f.spec.processing.music_p,
            Some(ModelOrder::Named(ModelOrderName::Targets))
        );
        let f = parse("[processing]\nmusic_p = 2\n").unwrap();
        assert_eq!(f.spec.processing.music_p, Some(ModelOrder::Fixed(2)));
        let err = parse("[processing]\nmusic_p = \"many\"\n")
            .unwrap_err()
            .to_string();
        assert!(err.starts_with("c.toml:2: `processing.music_p`"), "{err}");
        assert!(err.contains("\"targets\""), "{err}");
    }

    #[test]
    fn the_correction_is_none_rx_tx_or_both() {
        let f = parse("[processing]\ncorrection = \"rx\"\ncalibration = \"c.toml\"\n").unwrap();
        assert_eq!(f.spec.processing.correction, Some(CorrectionMode::Rx));
        let f = parse("[processing]\ncorrection = \"both\"\n").unwrap();
        assert_eq!(f.spec.processing.correction, Some(CorrectionMode::Both));
        let err = parse("[processing]\ncorrection = \"rxtx\"\n")
            .unwrap_err()
            .to_string();
        assert!(
            err.starts_with("c.toml:2: `processing.correction`"),
            "{err}"
        );
        assert!(err.contains("`rx`") && err.contains("`both`"), "{err}");
    }

    #[test]
    fn defaults_fill_what_is_not_written() {
        let f = parse("").unwrap();
        assert_eq!(f.spec.seed, 1);
        assert_eq!(f.spec.repetitions, 1);
        assert_eq!(f.spec.waveform.kind, WaveformKind::MskLfm);
        assert_eq!(f.name(), "c");
        // A [waveform] table that changes a parameter but names no kind: the default kind.
        let f = parse("[waveform]\nbandwidth_hz = 2e9\n").unwrap();
        assert_eq!(f.spec.waveform.kind, WaveformKind::MskLfm);
        assert_eq!(f.spec.waveform.bandwidth_hz, Some(2e9));
    }
}
