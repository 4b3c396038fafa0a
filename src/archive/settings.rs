//! The processing options of archive processing and their hash (the second part of an
//! output's address).

use crate::in_memory::{ProcessArgs, ProcessRequest};
use crate::measure::{ProcessOverrides, WaveformChoice};
use std::path::PathBuf;

/// The processing options every unit of an archive run is processed with.
#[derive(Debug, Clone)]
pub struct ArchiveSettings {
    pub(crate) waveform: WaveformChoice,
    pub(crate) overrides: ProcessOverrides,
    pub(crate) background: Option<PathBuf>,
    pub(crate) trigger_offset: Option<f64>,
    pub(crate) link_png: bool,
    described: String,
    options_sha256: String,
}

impl ArchiveSettings {
    /// The options as `radbench process` parsed them. `--reference-range` (which measures and
    /// writes a response first) is refused: measure it once, then give its file.
    pub fn from_args(args: &ProcessArgs, link_png: bool) -> anyhow::Result<ArchiveSettings> {
        if args.reference_range.is_some() {
            return Err(crate::exit::bad_input(
                "--reference-range with --from-catalog: measure the response once (`radbench \
                 process --calibration CAPTURE --reference-range M`), then give its file as \
                 --calibration",
            ));
        }
        let (waveform, overrides) = args.settings(None)?;
        Ok(Self::new(
            waveform,
            overrides,
            args.background.clone(),
            args.trigger_offset,
            link_png,
        ))
    }

    /// The Python package's keywords (a JSON object, as `radbench.process` takes them).
    pub fn from_keywords(keywords: &str) -> anyhow::Result<ArchiveSettings> {
        let request = ProcessRequest::from_keywords(keywords)?;
        let (args, waveform, overrides) = request.parts();
        Ok(Self::new(
            waveform.clone(),
            overrides.clone(),
            args.background.clone(),
            args.trigger_offset,
            false,
        ))
    }

    fn new(
        waveform: WaveformChoice,
        overrides: ProcessOverrides,
        background: Option<PathBuf>,
        trigger_offset: Option<f64>,
        link_png: bool,
    ) -> ArchiveSettings {
        // The options as parsed and resolved (a calibration file's content included), not as
        // spelled: `--m 32` and `m=32` address the same outputs. Within one radbench version
        // (the address's third part) this text is stable.
        let described = format!(
            "{waveform:?}\n{overrides:?}\nbackground={background:?}\n\
             trigger_offset={trigger_offset:?}\nlink_png={link_png}"
        );
        let options_sha256 = crate::storage::sha256(described.as_bytes());
        ArchiveSettings {
            waveform,
            overrides,
            background,
            trigger_offset,
            link_png,
            described,
            options_sha256,
        }
    }

    /// The options' SHA-256 (of their parsed form).
    pub fn options_sha256(&self) -> &str {
        &self.options_sha256
    }

    /// The options as hashed.
    pub(crate) fn described(&self) -> &str {
        &self.described
    }
}
