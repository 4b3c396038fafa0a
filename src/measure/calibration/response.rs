//! The chain's response calibration: measured on one reference pillar (`radbench calibrate
//! response`), stored as a TOML header beside a `.npy` table, and applied on receive
//! (`--correction rx`).
//!
//! Measurement: with the transmitter off, the receiver's DC offset (the mean) and its I/Q gain
//! and phase imbalance (from its own noise, which is circular before the I/Q demodulator); with
//! it on, each repetition corrected for those, the chain's direct and image response around the
//! reference's delay (`dsp::response::ChainEstimator`, the echo deconvolved by the known
//! transmitted repetition: it works for any waveform, and uses every sample, not only OFDM's
//! subcarriers). The repetitions are averaged; their spread is reported per frequency. The
//! response is normalised to unit mean gain and zero mean phase over the band and keeps its
//! linear phase relative to the expected delay `2 R / c + system delay`: corrected, the reference
//! lands at its true range with the bench's system delay.

use crate::dsp::chain_echoes;
use crate::dsp::iq_image::{rx_skew_direct, split_measured, TxIq};
use crate::dsp::response::{
    iq_imbalance_of_noise, undo_iq, ChainEstimator, Fitted, ResponseTable, RxEqualiser, BAND_FLOOR,
};
use crate::dsp::C0;
use crate::measure::error::MeasureError;
use num_complex::Complex64;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;
use std::path::{Path, PathBuf};

/// The header's format tag.
pub(crate) const FORMAT: &str = "radbench-response/1";

/// The `.npy` table's columns, in order.
pub(crate) const COLUMNS: [&str; 7] = [
    "frequency_hz (baseband offset from the carrier)",
    "gain_db (relative to the band's mean)",
    "phase_deg (after the mean phase; the linear phase of any delay error kept)",
    "gain_std_db (spread over the repetitions)",
    "phase_std_deg (spread over the repetitions)",
    "image_re (the image response, relative to the direct one)",
    "image_im",
];

/// Figures are taken where the waveform's power is within 3 dB of its peak.
const FIGURE_COVERAGE: f64 = 0.5;

/// The chain's discrete echoes are searched this far behind the reference at least (and the
/// leakage as far ahead), s: an IF cable's round trip is 6-20 ns on a lab bench.
pub(crate) const MIN_ECHO_REACH_S: f64 = 40e-9;
/// Scene echoes (the leakage) weaker than this relative to the reference are left alone, dB.
const WEAKEST_SCENE_ECHO_DB: f64 = -75.0;
/// Chain echoes weaker than this are left alone, dB: a lab's IF cable gives -25 to -45 dB;
/// weaker local maxima of what the gated fit leaves (about -63 dB at 9 ns on the thesis-lab
/// chain, which has no echo there) are the fit's own residue, and a pre-distortion made with
/// them puts a ghost where they are.
const WEAKEST_CHAIN_ECHO_DB: f64 = -50.0;
/// The leakage is sought this close to range 0 (its coupling at the horns, and the system
/// delay's error), s.
const LEAKAGE_PLACE_S: f64 = 1e-9;
/// A named reflector is sought within this of where the user put it, s (7.5 cm of range).
const NAMED_WITHIN_S: f64 = 0.5e-9;
/// The gate a named reflector is measured against closes before it, but no shorter than this, s
/// (the reference's main lobe at 1 GHz of band).
const NAMED_SHORTEST_GATE_S: f64 = 1e-9;
/// A named reflector this close to the reference cannot be told from it, m (its main lobe and
/// the gate's margin).
pub(crate) const NAMED_CLOSEST_M: f64 = 0.3;

/// `--reflector` checked against the reference's range: in front of the antennas, at least
/// 0.3 m from the reference (`NAMED_CLOSEST_M`) and within the reach the calibration searches.
pub fn check_reflector_m(reflector_m: Option<f64>, reference_m: f64) -> Result<(), MeasureError> {
    let Some(r) = reflector_m else {
        return Ok(());
    };
    let reach_m = 0.5 * MIN_ECHO_REACH_S * crate::dsp::C0;
    let fine = r.is_finite()
        && r > 0.0
        && (r - reference_m).abs() >= NAMED_CLOSEST_M
        && (r - reference_m).abs() <= reach_m.max(reference_m);
    if fine {
        return Ok(());
    }
    Err(MeasureError::option(
        "reflector",
        r,
        format!(
            "the fixed reflector's range in metres, over 0, at least {NAMED_CLOSEST_M} m from the \
             reference at {reference_m} m (closer, it is one echo with it) and at most {:.1} m \
             from it",
            reach_m.max(reference_m)
        ),
    ))
}

/// Most echoes taken out of one reference.
const MOST_ECHOES: usize = 12;
/// Rounds of the scene's search (the leakage, then what its first estimate left).
const SCENE_ROUNDS: usize = 3;
/// The leakage nearer than this to the reference (under about 0.77 m from the horns) is measured
/// jointly with the gate's fit, s. From 0.8 m on the search places it within 50 ps and the
/// reach tests hold; applied there (in an earlier form) the joint measure failed reach and
/// metrology tests (docs/calibration.md, Known limits).
const NEAR_LEAKAGE_S: f64 = 5e-9;
/// Up to this far (a reference under about 0.9 m) the scene is measured again by alternating
/// rounds, s: each searched in the reference as recorded, against the fit made with the last
/// round's scene divided out, and replacing it.
const ALTERNATE_BELOW_S: f64 = 5.8e-9;
/// Rounds of that alternation, at most.
const ALTERNATE_ROUNDS: usize = 4;
/// ... ended sooner once no echo moves by more than this, s, ...
const SETTLED_S: f64 = 0.5e-12;
/// ... nor changes its gain by more than this share of the strongest's.
const SETTLED_GAIN: f64 = 1e-3;
/// A scene echo this near the gate's fit (beyond its support) is measured jointly with it, s.
const JOINT_NEAR_S: f64 = 1.5e-9;
/// Rounds of the joint measure (the echo's delay, then the fit it rides on): the first rides on
/// the gate's local fit, which is zero outside the band.
const JOINT_ROUNDS: usize = 3;
/// The joint measure searches each echo's delay this far either side of where it was found, s.
const JOINT_DELAY_STEP_S: f64 = 0.3e-9;
/// Scene echoes this near the one measured jointly were what its first measure left, s.
const JOINT_RESIDUE_S: f64 = 1.0e-9;
/// A gate closed before a chain echo ends its taper this far ahead of it, s (the echo's main
/// lobe at 1 GHz of band).
const GATE_MARGIN_S: f64 = 1e-9;
/// ... but keeps this much of the chain's main response in the fit, s (a module-to-horn
/// standing wave and its second round trip).
const SHORTEST_CLOSED_GATE_S: f64 = 3e-9;

/// An unnamed echo ahead of the reference is reported from this level on, dB relative to the
/// reference: a mount 28 dB under a reference at 1 m, 0.5 m ahead of it, made phase ranges err
/// periodically by 10 um (docs/calibration.md).
const ECHO_AHEAD_DB: f64 = -45.0;

/// A ripple's paired echo behind is sought this close to the mirror of one ahead, s.
const MIRROR_WITHIN_S: f64 = 0.25e-9;

/// Which of the chain's measured errors a measurement corrects (`--correction`, a campaign's
/// `processing.correction`; recorded as `CorrectionUsed::mode`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
#[derive(strum::VariantArray, strum::IntoStaticStr, strum::EnumMessage)]
#[strum(serialize_all = "kebab-case")]
pub enum CorrectionMode {
    /// Nothing corrected.
    None,
    /// On receive: DC, I/Q imbalance, and the chain's response divided out.
    Rx,
    /// On transmit: the AWG's codes pre-distorted by the inverse of the chain's response.
    Tx,
    /// Both: the codes pre-distorted, and the receiver's own DC and I/Q imbalance corrected.
    Both,
}

impl CorrectionMode {
    /// Whether the AWG's codes are pre-distorted (tx, both).
    pub(crate) fn predistorts(self) -> bool {
        matches!(self, CorrectionMode::Tx | CorrectionMode::Both)
    }
}

named_enum!(CorrectionMode, "correction");

/// The instruments a calibration was measured with (`*IDN?`).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InstrumentsSeen {
    pub awg: String,
    pub scope: String,
    #[serde(default)]
    pub tx: Option<String>,
    #[serde(default)]
    pub rx: Option<String>,
}

/// The reference pillar before and after the correction.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReferenceFigures {
    pub sidelobe_db_before: Option<f64>,
    pub sidelobe_db_after: Option<f64>,
    pub width_cm_before: Option<f64>,
    pub width_cm_after: Option<f64>,
    pub range_m_before: Option<f64>,
    pub range_m_after: Option<f64>,
    /// The corrected reference's carrier phase against the leakage in its record: what
    /// `--ranging phase` measures every range from (absent in calibrations made before it, or
    /// where no leakage was seen).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub phase_anchor: Option<PhaseAnchor>,
}

/// The reference of a response calibration as phase ranging needs it (`[reference.phase_anchor]`
/// in the calibration's header): where it was, where its envelope and the Tx -> Rx leakage's were
/// seen in its corrected record, and its carrier phase against the leakage's.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PhaseAnchor {
    /// The reference's stated range, m (`--reference-range`): phase ranges are measured from it.
    pub range_m: f64,
    /// Its envelope's fitted range in the corrected record, m.
    pub envelope_range_m: f64,
    /// That envelope's standard uncertainty from its SNR, m (the record's trigger jitter apart).
    pub envelope_snr_std_m: f64,
    /// The leakage's fitted range in the same record, m.
    pub leakage_range_m: f64,
    /// Its standard uncertainty from its SNR, m.
    pub leakage_snr_std_m: f64,
    /// The reference's carrier phase minus the leakage's, rad.
    pub phase_to_leakage_rad: f64,
    /// That phase difference's standard uncertainty from the two SNRs, rad.
    pub phase_std_rad: f64,
    /// A fixed reflector in the same record (the strongest other target), m, and its envelope's
    /// standard uncertainty from its SNR: phase ranging's unwrapping takes the trigger's jitter
    /// and the chain's drift from its move.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fixed_range_m: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fixed_snr_std_m: Option<f64>,
    /// The repetitions the record averages, each with its own trigger jitter (absent in
    /// calibrations made before it was written: taken as one, the conservative reading).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub repetitions: Option<usize>,
    /// The time and phase reference is the reflector named to the calibration (`--reflector`),
    /// not the leakage, which its record did not show: the `leakage_*` fields describe that
    /// reflector.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub by_reflector: bool,
}

impl PhaseAnchor {
    /// What the anchor's phase is measured against, for messages.
    pub(crate) fn reference_name(&self) -> &'static str {
        if self.by_reflector {
            "the named reflector"
        } else {
            "the Tx -> Rx leakage"
        }
    }

    /// The envelope's calibration uncertainty it gives, m: its SNR's, and its record's trigger
    /// jitter (`jitter_m` as range, one record's: the average of `repetitions` records carries
    /// `1 / sqrt(repetitions)` of it) or, when larger, the corrected reference's own offset from
    /// its stated range (one draw of that jitter plus what the correction leaves: a clutter's
    /// pull, the chain's misfit).
    pub(crate) fn envelope_std_m(&self, jitter_m: f64) -> f64 {
        let offset = self.envelope_range_m - self.range_m;
        let records = self.repetitions.unwrap_or(1).max(1) as f64;
        let jitter_var = jitter_m.powi(2) / records;
        (self.envelope_snr_std_m.powi(2) + jitter_var.max(offset.powi(2))).sqrt()
    }
}

/// What was measured, in figures.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ResponseFigures {
    /// Gain ripple over the band, dB peak to peak.
    pub ripple_db_pp: f64,
    /// Phase ripple after the best straight line, degrees peak to peak.
    pub phase_ripple_deg_pp: f64,
    /// Group-delay ripple, ps peak to peak (over 1 / (4 gate) steps).
    pub group_delay_ripple_ps_pp: f64,
    /// The best straight line's delay against the expected one, ps (a system-delay error).
    pub delay_offset_ps: f64,
    /// DC offset of I and Q at the scope, volts.
    pub dc_v: [f64; 2],
    /// Receiver Q gain and phase relative to I (from its noise, transmitter off).
    pub rx_iq_gain_db: f64,
    pub rx_iq_phase_deg: f64,
    /// I/Q skew seen in the image's slope over the band (transmit and receive together), ps.
    pub iq_skew_ps: f64,
    /// The transmitter's Q gain and phase relative to I, and its Q skew, from the image with the
    /// receiver's part told apart (`dsp::iq_image`).
    #[serde(default)]
    pub tx_iq_gain_db: f64,
    #[serde(default)]
    pub tx_iq_phase_deg: f64,
    #[serde(default)]
    pub tx_iq_skew_ps: f64,
    /// The receiver's Q skew (Q sampled late), ps.
    #[serde(default)]
    pub rx_iq_skew_ps: f64,
    /// The larger of the two skews' standard errors, ps.
    #[serde(default)]
    pub iq_skew_sd_ps: f64,
    /// Whether the two skews were told apart (the reference's carrier phase allowed it); when
    /// not, neither is corrected and the output says how to measure again.
    #[serde(default)]
    pub iq_skews_separated: bool,
    /// When the Tx->Rx leakage was not found where it must be (2 R / c ahead of the reference):
    /// the level under which it hides (the echo search's floor there, dB relative to the
    /// reference). A fit may then hold it as the chain's, and every corrected capture may show
    /// its image that far ahead of each strong target: the residual profile covers it there.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub leakage_unseen_db: Option<f64>,
    /// A discrete echo ahead of the reference inside the gate's reach, not named (`--reflector`)
    /// and with no mirror behind it (a ripple's paired echoes come in twos): antennas to echo,
    /// m, and its level relative to the reference, dB. A chain's echoes follow its main path,
    /// so it is most likely the scene's (a mount, a table edge), which the fit takes for the
    /// chain's own response: the output says to name it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub echo_ahead_m: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub echo_ahead_db: Option<f64>,
    /// The image's mean level against the direct response, dB (after the receive imbalance was
    /// taken out: what is left is mostly the transmitter's).
    pub image_db: f64,
    /// Largest spread over the repetitions across the band.
    pub spread_db_max: f64,
    pub spread_deg_max: f64,
}

/// The calibration file's header.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ResponseHeader {
    pub format: String,
    /// The table, beside the header.
    pub data: String,
    pub data_sha256: String,
    pub columns: Vec<String>,
    pub measured_at: String,
    pub radbench_version: String,
    pub waveform: String,
    /// The band the table covers (waveform power within 20 dB of its peak), Hz.
    pub band_hz: [f64; 2],
    pub reference_range_m: f64,
    pub repetitions: usize,
    pub gate_ns: f64,
    /// The fixed reflector named in the reference's scene (`--reflector`), m.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reflector_m: Option<f64>,
    /// The system delay the response is relative to, s.
    pub system_delay_s: f64,
    pub figures: ResponseFigures,
    pub reference: ReferenceFigures,
    pub instruments: InstrumentsSeen,
    /// Discrete echoes behind every path, beyond the gate (an IF cable's), folded into the table.
    #[serde(default)]
    pub chain_echoes: Vec<EchoSeen>,
    /// The reference scene's own echoes beyond the gate (the Tx->Rx leakage ahead of the
    /// reference, and its chain echoes): taken out of the reference before the fit, not
    /// corrected in captures.
    #[serde(default)]
    pub scene_echoes: Vec<EchoSeen>,
    /// What the correction leaves on the reference beyond its main lobe, per range window
    /// (`[[residual]]`): the detector's floor near strong targets follows it. Absent in
    /// calibrations written before it was measured (no such floor then).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub residual: Vec<ResidualSeen>,
}

/// A calibration's residual profile for one window (`dsp::residual`): the largest power the
/// correction leaves on the reference relative to its peak, in bins of range offset behind it
/// and ahead of it, dB.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ResidualSeen {
    /// The range window (`--window`: rect, hann, taylor, chebyshev).
    pub window: String,
    /// Bin `j` covers offsets `[j bin_m, (j + 1) bin_m)`, m.
    pub bin_m: f64,
    pub behind_db: Vec<f64>,
    pub ahead_db: Vec<f64>,
}

impl ResidualSeen {
    /// The detector's floor from it (`None` for a profile that does not parse as one).
    pub(crate) fn floor(&self) -> Option<crate::dsp::ResidualFloor> {
        crate::dsp::ResidualFloor::from_db(self.bin_m, &self.behind_db, &self.ahead_db)
    }
}

/// One discrete echo relative to the reference's delay (`dsp::chain_echoes`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EchoSeen {
    /// After the reference (negative: ahead of it), ns.
    pub delay_ns: f64,
    /// Relative to the reference, dB.
    pub level_db: f64,
    /// Relative to the reference at the carrier, degrees.
    pub phase_deg: f64,
}

impl EchoSeen {
    fn of(e: &crate::dsp::chain_echoes::Echo) -> Self {
        EchoSeen {
            delay_ns: e.delay_s * 1e9,
            level_db: 20.0 * e.gain.norm().max(1e-300).log10(),
            phase_deg: e.gain.arg().to_degrees(),
        }
    }
}

/// A measured response: the header's figures and the table.
#[derive(Debug, Clone, PartialEq)]
pub struct Response {
    pub table: ResponseTable,
    pub spread_db: Vec<f64>,
    pub spread_deg: Vec<f64>,
    pub image: Vec<Complex64>,
    pub figures: ResponseFigures,
    pub band_hz: [f64; 2],
    pub system_delay_s: f64,
    /// The chain's discrete echoes beyond the gate (folded into `table`).
    pub chain_echoes: Vec<EchoSeen>,
    /// The reference scene's echoes beyond the gate (not in `table`).
    pub scene_echoes: Vec<EchoSeen>,
    /// What the correction leaves on the reference, per window.
    pub residual: Vec<ResidualSeen>,
}

impl Response {
    /// The transmitter's I/Q errors as measured (its skew only when told apart from the
    /// receiver's).
    pub(crate) fn tx_iq(&self) -> TxIq {
        let f = &self.figures;
        TxIq {
            gain: 10f64.powf(f.tx_iq_gain_db / 20.0),
            phase: f.tx_iq_phase_deg.to_radians(),
            skew_s: if f.iq_skews_separated {
                f.tx_iq_skew_ps * 1e-12
            } else {
                0.0
            },
        }
    }

    /// The receiver's Q skew, s (0 unless told apart from the transmitter's).
    pub(crate) fn rx_skew_s(&self) -> f64 {
        if self.figures.iq_skews_separated {
            self.figures.rx_iq_skew_ps * 1e-12
        } else {
            0.0
        }
    }

    /// The table with `part(f)` divided out of every row.
    fn table_without(&self, part: impl Fn(f64) -> Complex64) -> ResponseTable {
        ResponseTable {
            freq_hz: self.table.freq_hz.clone(),
            response: self
                .table
                .freq_hz
                .iter()
                .zip(&self.table.response)
                .map(|(&f, h)| h / part(f))
                .collect(),
        }
    }

    /// The response the receiver sees once its own skew is undone.
    fn rx_table(&self) -> ResponseTable {
        let skew = self.rx_skew_s();
        self.table_without(|f| rx_skew_direct(f, skew))
    }

    /// The RF chain alone: the measured response without either end's I/Q errors (what the
    /// transmitter's pre-distortion divides out before it undoes its own I/Q errors).
    pub(crate) fn rf_table(&self) -> ResponseTable {
        let (tx, skew) = (self.tx_iq(), self.rx_skew_s());
        self.table_without(|f| tx.direct(f) * rx_skew_direct(f, skew))
    }

    /// The response from the transmitter's output to where the receiver's corrections leave
    /// it: the RF chain, and the receiver's skew unless `rx_corrected` (the receiver undoes it).
    pub(crate) fn after_transmitter(&self, rx_corrected: bool) -> ResponseTable {
        if rx_corrected {
            self.rf_table()
        } else {
            let tx = self.tx_iq();
            self.table_without(|f| tx.direct(f))
        }
    }

    fn dc(&self) -> Complex64 {
        let [di, dq] = self.figures.dc_v;
        Complex64::new(di, dq)
    }

    fn rx_iq(&self) -> Option<(f64, f64)> {
        Some((self.figures.rx_iq_gain_db, self.figures.rx_iq_phase_deg))
    }

    /// The receive equaliser for repetitions of `period` samples at `fs`: DC, the receiver's I/Q
    /// imbalance and skew, then the response.
    pub(crate) fn equaliser(&self, period: usize, fs: f64) -> Result<RxEqualiser, MeasureError> {
        Ok(
            RxEqualiser::new(&self.rx_table(), self.dc(), self.rx_iq(), period, fs)?
                .with_rx_skew(self.rx_skew_s()),
        )
    }

    /// The receiver's part alone (DC, I/Q imbalance and skew), the response left flat: for a
    /// transmitter that pre-distorts the response.
    pub(crate) fn receiver_only(
        &self,
        period: usize,
        fs: f64,
    ) -> Result<RxEqualiser, MeasureError> {
        let flat = ResponseTable {
            freq_hz: vec![-1.0, 1.0],
            response: vec![Complex64::new(1.0, 0.0); 2],
        };
        Ok(
            RxEqualiser::new(&flat, self.dc(), self.rx_iq(), period, fs)?
                .with_rx_skew(self.rx_skew_s()),
        )
    }
}

/// A calibration read from its file.
#[derive(Debug, Clone)]
pub struct Calibration {
    pub header: ResponseHeader,
    pub response: Response,
    pub path: PathBuf,
    pub sha256: String,
}

impl Calibration {
    /// Reads the header at `path` and its table, checking the table's SHA-256.
    pub fn load(path: &Path) -> Result<Calibration, MeasureError> {
        let bad = |reason: String| MeasureError::CalibrationFile {
            path: path.display().to_string(),
            reason,
        };
        let text =
            std::fs::read_to_string(path).map_err(|e| bad(format!("cannot read it: {e}")))?;
        let header: ResponseHeader = toml::from_str(&text).map_err(|e| {
            bad(format!(
                "not a response calibration (`radbench calibrate response` writes one): {}",
                e.message()
            ))
        })?;
        if header.format != FORMAT {
            return Err(bad(format!(
                "format = {:?}: this radbench reads {FORMAT:?}",
                header.format
            )));
        }
        let data_path = path.parent().unwrap_or(Path::new(".")).join(&header.data);
        let bytes = std::fs::read(&data_path).map_err(|e| {
            bad(format!(
                "its table {} cannot be read: {e} (keep the .npy beside the header)",
                data_path.display()
            ))
        })?;
        let sha = crate::storage::sha256(&bytes);
        if sha != header.data_sha256 {
            return Err(bad(format!(
                "its table {} has changed since it was measured (SHA-256 {sha}, the header \
                 says {}): measure again",
                data_path.display(),
                header.data_sha256
            )));
        }
        let (shape, values) = crate::storage::npy::decode_f64(&bytes)
            .map_err(|e| bad(format!("its table {}: {e}", data_path.display())))?;
        let response = table_from(&shape, &values, &header).map_err(bad)?;
        let path = std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf());
        Ok(Calibration {
            sha256: crate::storage::sha256(text.as_bytes()),
            header,
            response,
            path,
        })
    }

    /// Writes the header to `path` and the table beside it (`<stem>.npy`), atomically each.
    pub(crate) fn save(
        path: &Path,
        response: &Response,
        mut header: ResponseHeader,
    ) -> Result<Calibration, MeasureError> {
        let bad = |reason: String| MeasureError::CalibrationFile {
            path: path.display().to_string(),
            reason,
        };
        let stem = path
            .file_stem()
            .and_then(|s| s.to_str())
            .ok_or_else(|| bad("a file name ending in .toml".into()))?;
        let data_name = format!("{stem}.npy");
        let data_path = path.parent().unwrap_or(Path::new(".")).join(&data_name);
        let rows = response.table.freq_hz.len();
        let mut data = Vec::with_capacity(rows * COLUMNS.len());
        for k in 0..rows {
            let h = response.table.response[k];
            data.extend_from_slice(&[
                response.table.freq_hz[k],
                20.0 * h.norm().max(1e-300).log10(),
                h.arg().to_degrees(),
                response.spread_db[k],
                response.spread_deg[k],
                response.image[k].re,
                response.image[k].im,
            ]);
        }
        let bytes = crate::storage::npy::encode_f64(&[rows, COLUMNS.len()], &data).map_err(bad)?;
        header.data = data_name;
        header.data_sha256 = crate::storage::sha256(&bytes);
        header.columns = COLUMNS.iter().map(|c| c.to_string()).collect();
        let text = format!(
            "# The chain's response, measured by `radbench calibrate response`.\n# The table is \
             {} (numpy.load; one row per frequency, columns below).\n{}",
            header.data,
            toml::to_string(&header).map_err(|e| bad(e.to_string()))?
        );
        crate::storage::write_atomic(&data_path, &bytes)?;
        crate::storage::write_atomic(path, text.as_bytes())?;
        Calibration::load(path)
    }
}

/// The response of a table's rows (columns as [`COLUMNS`]).
fn table_from(
    shape: &[usize],
    values: &[f64],
    header: &ResponseHeader,
) -> Result<Response, String> {
    let [rows, cols] = shape else {
        return Err(format!(
            "table of shape {shape:?}: 2 dimensions, rows by 7 columns"
        ));
    };
    if *cols != COLUMNS.len() || *rows < 2 {
        return Err(format!(
            "table of {rows} rows by {cols} columns: at least 2 rows by {} columns",
            COLUMNS.len()
        ));
    }
    if values.iter().any(|v| !v.is_finite()) {
        return Err("table holds a value that is not finite".into());
    }
    let row = |k: usize| &values[k * cols..(k + 1) * cols];
    let freq_hz: Vec<f64> = (0..*rows).map(|k| row(k)[0]).collect();
    if freq_hz.windows(2).any(|w| w[1] <= w[0]) {
        return Err("table's frequencies are not strictly ascending".into());
    }
    let response = (0..*rows)
        .map(|k| Complex64::from_polar(10f64.powf(row(k)[1] / 20.0), row(k)[2].to_radians()))
        .collect();
    Ok(Response {
        table: ResponseTable { freq_hz, response },
        spread_db: (0..*rows).map(|k| row(k)[3]).collect(),
        spread_deg: (0..*rows).map(|k| row(k)[4]).collect(),
        image: (0..*rows)
            .map(|k| Complex64::new(row(k)[5], row(k)[6]))
            .collect(),
        figures: header.figures,
        band_hz: header.band_hz,
        system_delay_s: header.system_delay_s,
        chain_echoes: header.chain_echoes.clone(),
        scene_echoes: header.scene_echoes.clone(),
        residual: header.residual.clone(),
    })
}

/// One aligned repetition: its samples at the waveform rate, and when sample 0 lies after the
/// marker edge (the pipeline's `Aligned`, borrowed).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Repetition<'a> {
    pub(crate) samples: &'a [Complex64],
    pub(crate) residual_s: f64,
}

/// How the reference is processed for its residual profiles: the range windows (name and
/// window) and the waveform's band `[low, high]` Hz they span.
pub(crate) struct ResidualWindows<'a> {
    pub(crate) windows: &'a [(&'a str, crate::dsp::Window)],
    pub(crate) band_hz: [f64; 2],
}

/// The residual profiles' bins, m: a few per 1 GHz range cell (15 cm).
const RESIDUAL_BIN_M: f64 = 0.05;

/// Measures the chain's response from aligned repetitions of one reference reflector (`on`) and
/// of the receiver with the transmitter off (`off`). `reference` is the transmitted repetition;
/// the reflector is expected at `expected_delay_s` after the marker (2 R / c + system delay).
/// What the correction leaves on the reference is recorded for each of `residual`'s windows.
#[allow(clippy::too_many_arguments)]
pub(crate) fn measure(
    reference: &[Complex64],
    fs: f64,
    on: &[Repetition<'_>],
    off: &[&[Complex64]],
    expected_delay_s: f64,
    gate_s: f64,
    system_delay_s: f64,
    named_s: Option<f64>,
    residual: &ResidualWindows<'_>,
) -> Result<Response, MeasureError> {
    let period = on.first().map(|a| a.samples.len()).ok_or_else(|| {
        MeasureError::option("repetitions", 0, "at least 1 repetition with RF on")
    })?;
    // The receiver alone: its DC and its I/Q imbalance (from its noise).
    let noise: Vec<Complex64> = off.iter().flat_map(|a| a.iter().copied()).collect();
    let dc = if noise.is_empty() {
        Complex64::new(0.0, 0.0)
    } else {
        noise.iter().sum::<Complex64>() / noise.len() as f64
    };
    let (gain_db, phase_deg) = iq_imbalance_of_noise(&noise).unwrap_or((0.0, 0.0));
    let iq = Some((10f64.powf(gain_db / 20.0), phase_deg.to_radians()));

    let est = ChainEstimator::new(reference, period, fs, gate_s)?;
    let n = est.period();
    // Each repetition corrected, checked to hold the reference where expected, and made
    // relative to its delay (on every core: the repetitions are independent).
    let relative = on
        .par_iter()
        .map_init(Vec::new, |scratch, a| {
            let mut y = a.samples.to_vec();
            undo_iq(&mut y, dc, iq);
            let mut spectrum = est.spectrum_with(&y, scratch);
            let delay = (expected_delay_s - a.residual_s) * fs;
            check_reference_near(&est, &spectrum, delay, gate_s * fs, scratch)?;
            est.relative_to(&mut spectrum, delay);
            Ok(spectrum)
        })
        .collect::<Result<Vec<Vec<Complex64>>, MeasureError>>()?;
    let reps = relative.len() as f64;
    // The fit is linear: the repetitions' mean response is the fit of their mean spectrum (two
    // rounds, once). Each repetition's own direct response, for the spread, is one fit against
    // the image the mean's was fitted with.
    let mut mean_spectrum = vec![Complex64::new(0.0, 0.0); n];
    for z in &relative {
        for (m, v) in mean_spectrum.iter_mut().zip(z) {
            *m += v;
        }
    }
    for m in mean_spectrum.iter_mut() {
        *m /= reps;
    }
    let reach_s = MIN_ECHO_REACH_S.max(expected_delay_s - system_delay_s + 3e-9);
    // The leakage couples at the horns, at range 0: 2 R / c ahead of the reference.
    let leakage_at_s = -(expected_delay_s - system_delay_s);
    let whole = fit_whole_chain(est, mean_spectrum, relative, reach_s, leakage_at_s, named_s)?;
    let residual = residual_profiles(&whole, reach_s, residual)?;
    let whole_leakage_unseen = whole.leakage_unseen;
    let echo_ahead = whole.echo_ahead;
    let (est, echoes, gate_s) = (whole.est, whole.echoes, whole.gate_s);
    let directs: Vec<Vec<Complex64>> = whole
        .relative
        .par_iter()
        .map_init(Vec::new, |scratch, z| {
            let mut d = est.direct_given_image(z, &whole.fitted.image_for_direct, scratch);
            for (v, e) in d.iter_mut().zip(&whole.chain_factor) {
                *v *= e;
            }
            d
        })
        .collect();
    let cover = est.coverage();
    let fitted = Fitted {
        direct: whole
            .fitted
            .direct
            .iter()
            .zip(&whole.chain_factor)
            .map(|(d, e)| d * e)
            .collect(),
        ..whole.fitted
    };
    // Normalise to the band's mean (power-weighted): unit gain, zero mean phase.
    let (mut num, mut den) = (Complex64::new(0.0, 0.0), 0.0);
    for k in (0..n).filter(|&k| cover[k] >= FIGURE_COVERAGE) {
        num += fitted.direct[k] * cover[k];
        den += cover[k];
    }
    if !(den > 0.0 && num.norm() > 0.0) {
        return Err(MeasureError::NoReferenceEcho {
            from_m: expected_delay_s * C0 / 2.0,
            to_m: expected_delay_s * C0 / 2.0,
        });
    }
    let scale = num / den;
    let mut bins: Vec<usize> = (0..n).filter(|&k| cover[k] >= BAND_FLOOR).collect();
    bins.sort_by(|&a, &b| est.frequency_hz(a).total_cmp(&est.frequency_hz(b)));
    let mut table = ResponseTable {
        freq_hz: Vec::with_capacity(bins.len()),
        response: Vec::with_capacity(bins.len()),
    };
    let (mut spread_db, mut spread_deg, mut image) = (Vec::new(), Vec::new(), Vec::new());
    for &k in &bins {
        let h = fitted.direct[k] / scale;
        table.freq_hz.push(est.frequency_hz(k));
        table.response.push(h);
        let (mut s_db, mut s_deg) = (0.0, 0.0);
        for d in &directs {
            let r = d[k] / scale / h;
            s_db += (20.0 * r.norm().max(1e-300).log10()).powi(2);
            s_deg += r.arg().to_degrees().powi(2);
        }
        let dof = (reps - 1.0).max(1.0);
        spread_db.push((s_db / dof).sqrt());
        spread_deg.push((s_deg / dof).sqrt());
        image.push(fitted.image[k] / scale);
    }
    let in_figures: Vec<bool> = bins.iter().map(|&k| cover[k] >= FIGURE_COVERAGE).collect();
    let figures = figures_of(
        &table,
        &image,
        &in_figures,
        &spread_db,
        &spread_deg,
        gate_s,
        dc,
        (gain_db, phase_deg),
    );
    let mut figures = figures;
    figures.leakage_unseen_db = whole_leakage_unseen.map(|p| 10.0 * p.log10());
    if let Some(e) = echo_ahead {
        figures.echo_ahead_m = Some((expected_delay_s - system_delay_s + e.delay_s) * C0 / 2.0);
        figures.echo_ahead_db = Some(20.0 * e.gain.norm().log10());
    }
    if let Some(split) = split_iq(&est, &fitted.direct, &fitted.image, &cover, gate_s) {
        figures.tx_iq_gain_db = 20.0 * split.tx.gain.log10();
        figures.tx_iq_phase_deg = split.tx.phase.to_degrees();
        figures.tx_iq_skew_ps = split.tx.skew_s * 1e12;
        figures.rx_iq_skew_ps = split.rx_skew_s * 1e12;
        figures.iq_skew_sd_ps = split.tx_skew_sd_s.max(split.rx_skew_sd_s) * 1e12;
        figures.iq_skews_separated = split.skews_separated();
    }
    let band_hz = [
        *table.freq_hz.first().unwrap_or(&0.0),
        *table.freq_hz.last().unwrap_or(&0.0),
    ];
    Ok(Response {
        table,
        spread_db,
        spread_deg,
        image,
        figures,
        band_hz,
        system_delay_s,
        chain_echoes: echoes.chain.iter().map(EchoSeen::of).collect(),
        scene_echoes: echoes.scene.iter().map(EchoSeen::of).collect(),
        residual,
    })
}

/// What the final fit leaves of the reference's mean spectrum (`dsp::residual`: `Z / (X H0) -
/// 1` over the band, the scene's and the chain's echoes divided out as the table and the
/// captures' correction take them), through each window, out to `reach_s` of delay either side.
fn residual_profiles(
    whole: &WholeChain,
    reach_s: f64,
    windows: &ResidualWindows<'_>,
) -> Result<Vec<ResidualSeen>, MeasureError> {
    let est = &whole.est;
    let n = est.period();
    let fs = est.frequency_hz(1) * n as f64;
    let cover = est.coverage();
    let model = est.predicted(&whole.fitted);
    let ratio: Vec<Complex64> = (0..n)
        .map(|k| {
            if cover[k] >= BAND_FLOOR && model[k].norm_sqr() > 0.0 {
                whole.mean[k] / model[k] - 1.0
            } else {
                Complex64::new(0.0, 0.0)
            }
        })
        .collect();
    let power: Vec<f64> = cover
        .iter()
        .map(|&c| if c >= BAND_FLOOR { c } else { 0.0 })
        .collect();
    let reach_m = reach_s * C0 / 2.0;
    windows
        .windows
        .iter()
        .map(|(name, window)| {
            let weight = crate::dsp::residual::window_weights(
                window,
                &power,
                |k| est.frequency_hz(k),
                windows.band_hz,
            )?;
            let r = crate::dsp::residual::profile(&ratio, &weight, fs, RESIDUAL_BIN_M, reach_m)?;
            let (mut behind_db, mut ahead_db) = (r.behind_db, r.ahead_db);
            let blind = |behind: bool| {
                whole
                    .echoes
                    .scene
                    .iter()
                    .filter(move |e| (e.delay_s >= 0.0) == behind)
                    .map(|e| e.delay_s.abs() * C0 / 2.0)
            };
            let half_m = LEAKAGE_PLACE_S * C0 / 2.0;
            fill_blind(&mut behind_db, r.bin_m, blind(true), half_m);
            fill_blind(&mut ahead_db, r.bin_m, blind(false), half_m);
            if let Some(floor) = whole.leakage_unseen {
                let centre_m = whole.leakage_at_s.abs() * C0 / 2.0;
                let half_m = LEAKAGE_PLACE_S * C0 / 2.0;
                raise(
                    &mut ahead_db,
                    r.bin_m,
                    centre_m,
                    half_m,
                    10.0 * floor.log10(),
                );
            }
            Ok(ResidualSeen {
                window: (*name).to_string(),
                bin_m: r.bin_m,
                behind_db,
                ahead_db,
            })
        })
        .collect()
}

/// Where the reference's scene had an echo (the leakage, `centres_m` of offset, each `+- half_m`),
/// what the correction leaves there was divided out with it: a chain's tail beyond the gate
/// that falls there reads 5-10 dB low (a response stepping 0.5 dB within 20 MHz: -68 dB at
/// the leakage's place, -51 dB 0.3 m on, and its corrected captures showed it there 46 dB under
/// the pillar). Each run of such bins is raised to the highest level within `half_m` beside it.
fn fill_blind(
    levels_db: &mut [f64],
    bin_m: f64,
    centres_m: impl Iterator<Item = f64>,
    half_m: f64,
) {
    let n = levels_db.len();
    let mut blind = vec![false; n];
    for c in centres_m {
        let first = ((c - half_m) / bin_m).floor().max(0.0) as usize;
        let last = (((c + half_m) / bin_m).floor() as usize).min(n.saturating_sub(1));
        for b in blind.iter_mut().take(last + 1).skip(first) {
            *b = true;
        }
    }
    let beside = (half_m / bin_m).ceil() as usize;
    let mut j = 0;
    while j < n {
        if !blind[j] {
            j += 1;
            continue;
        }
        let start = j;
        while j < n && blind[j] {
            j += 1;
        }
        let seen = levels_db[start.saturating_sub(beside)..start]
            .iter()
            .chain(&levels_db[j..(j + beside).min(n)])
            .copied()
            .fold(f64::NEG_INFINITY, f64::max);
        for v in &mut levels_db[start..j] {
            *v = v.max(seen);
        }
    }
}

/// Raises the bins of `levels_db` (bins of `bin_m`) over offsets `centre_m +- half_m` to `db`.
fn raise(levels_db: &mut [f64], bin_m: f64, centre_m: f64, half_m: f64, db: f64) {
    let first = ((centre_m - half_m) / bin_m).floor().max(0.0) as usize;
    let last = ((centre_m + half_m) / bin_m).floor() as usize;
    for v in levels_db.iter_mut().take(last + 1).skip(first) {
        *v = v.max(db);
    }
}

/// The gated fit of the reference's mean relative spectrum, with what lies beyond the gate
/// accounted for (`dsp::chain_echoes`), and the repetitions' spectra made alike.
struct WholeChain {
    est: ChainEstimator,
    /// The gate the final fit was made with, s.
    gate_s: f64,
    /// The gated fit, the chain's echoes beyond the gate not in it.
    fitted: Fitted,
    /// The chain's echoes beyond the gate, per bin: the response is `fitted.direct` times this.
    chain_factor: Vec<Complex64>,
    /// The repetitions' relative spectra with every echo found divided out.
    relative: Vec<Vec<Complex64>>,
    /// Their mean, likewise: what `fitted` was fitted to.
    mean: Vec<Complex64>,
    echoes: chain_echoes::Echoes,
    /// Where the leakage must be, relative to the reference, s.
    leakage_at_s: f64,
    /// Not found there: the search's floor (power relative to the reference).
    leakage_unseen: Option<f64>,
    /// An unnamed discrete echo ahead of the reference inside the gate's reach ([`echo_ahead`]).
    echo_ahead: Option<chain_echoes::Echo>,
}

/// First the scene beyond the gate (the leakage ahead of the reference) is divided out. The gate
/// stays as it was: opened to the widest default, it took in what the division leaves of the
/// leakage, a ghost ahead of every corrected target. Then the chain's own echoes beyond the gate
/// (an IF cable's), divided out before the last fit and multiplied back into the response. The
/// last fit is the least-squares one over the gate's lags.
fn fit_whole_chain(
    est: ChainEstimator,
    mut mean: Vec<Complex64>,
    mut relative: Vec<Vec<Complex64>>,
    reach_s: f64,
    leakage_at_s: f64,
    named_s: Option<f64>,
) -> Result<WholeChain, MeasureError> {
    let n = est.period();
    let fs = est.frequency_hz(1) * n as f64;
    let search = |est: &ChainEstimator,
                  fitted: &Fitted,
                  mean: &[Complex64],
                  gate_s: f64,
                  weakest_db: f64| {
        chain_echoes::find(
            mean,
            &est.predicted(fitted),
            &est.coverage(),
            |k| est.frequency_hz(k),
            fs,
            chain_echoes::Search {
                inner_s: 1.5 * gate_s,
                reach_s,
                weakest_db,
                most: MOST_ECHOES,
            },
        )
    };
    let divide = |mean: &mut Vec<Complex64>,
                  relative: &mut Vec<Vec<Complex64>>,
                  by: &dyn Fn(f64) -> Complex64,
                  est: &ChainEstimator| {
        let d: Vec<Complex64> = (0..n).map(|k| by(est.frequency_hz(k))).collect();
        let apply = |z: &mut Vec<Complex64>| z.iter_mut().zip(&d).for_each(|(v, d)| *v /= d);
        relative.par_iter_mut().for_each(apply);
        apply(mean);
    };
    let mut gate_s = est.gate_s();
    let echo_ahead = match named_s {
        None => {
            let probe = ChainEstimator::new(est.reference(), n, fs, NAMED_SHORTEST_GATE_S)?;
            let fit = probe.fit_relative(&mean, &mut Vec::new());
            let found = search(&probe, &fit, &mean, NAMED_SHORTEST_GATE_S, ECHO_AHEAD_DB);
            echo_ahead(&found, gate_s, leakage_at_s)
        }
        Some(_) => None,
    };
    let mut est = est;
    let mut fitted = est.fit_relative(&mean, &mut Vec::new());
    let mut echoes = chain_echoes::Echoes {
        reach_s,
        ..Default::default()
    };
    // The leakage's main lobe may reach into the gate's taper and bias the first estimate of it:
    // what the division leaves is searched again with the gate's fit made without it.
    let mut scene_floor = None;
    // A reflector the user named in the reference's scene: inside the gate the fit would hold it
    // as the chain's own, and every capture's correction would divide out an echo its chain does
    // not have (its image, turned by each target's phase, lands beside the leakage: phase ranges
    // then drift with the target's place). Measured against a gate closed before it and divided
    // out of the reference as the scene's, again each round (the leakage beside it biases the
    // first measure).
    let probe = match named_s {
        Some(at_s) => {
            let short = ((at_s.abs() - GATE_MARGIN_S) / 1.5).clamp(NAMED_SHORTEST_GATE_S, gate_s);
            Some((at_s, ChainEstimator::new(est.reference(), n, fs, short)?))
        }
        None => None,
    };
    let near = leakage_at_s.abs() < NEAR_LEAKAGE_S;
    let alternate = !near && probe.is_none() && leakage_at_s.abs() < ALTERNATE_BELOW_S;
    let mut original = (near || alternate).then(|| (mean.clone(), relative.clone()));
    for _ in 0..SCENE_ROUNDS {
        if let Some((at_s, probe)) = &probe {
            let fit = probe.fit_relative(&mean, &mut Vec::new());
            let named = chain_echoes::named(
                &mean,
                &probe.predicted(&fit),
                &probe.coverage(),
                |k| probe.frequency_hz(k),
                fs,
                *at_s,
                NAMED_WITHIN_S,
            );
            if let Some(echo) = named {
                let found = chain_echoes::Echoes {
                    scene: vec![echo],
                    ..Default::default()
                };
                divide(&mut mean, &mut relative, &|f| found.scene_at(f), &est);
                fitted = est.fit_relative(&mean, &mut Vec::new());
                echoes.scene.push(echo);
            }
        }
        let first = search(&est, &fitted, &mean, gate_s, WEAKEST_SCENE_ECHO_DB);
        scene_floor.get_or_insert(first.floor);
        let scene = first.scene;
        if scene.is_empty() {
            break;
        }
        let found = chain_echoes::Echoes {
            scene,
            ..Default::default()
        };
        divide(&mut mean, &mut relative, &|f| found.scene_at(f), &est);
        fitted = est.fit_relative(&mean, &mut Vec::new());
        echoes.scene.extend(found.scene);
    }
    // From 0.77 to 0.9 m the gate's taper holds part of the leakage's main lobe, and each
    // round's search against that fit misplaced it by 10-20 ps: what its division left lifted
    // the side-lobes ahead of every corrected target (Dolph-Chebyshev to -47.6 dB). Searched
    // again in the reference as recorded, each round against the fit made without the last
    // round's scene, it settles (docs/calibration.md, "Reach"). Not further out: on the
    // metrology bench it moved the leakage's fitted place.
    if let Some((mean0, relative0)) = original.take_if(|_| alternate) {
        let mut scene = std::mem::take(&mut echoes.scene);
        for _ in 0..ALTERNATE_ROUNDS {
            let mut m = mean0.clone();
            let mut none = Vec::new();
            let by = chain_echoes::Echoes {
                scene: scene.clone(),
                ..Default::default()
            };
            divide(&mut m, &mut none, &|f| by.scene_at(f), &est);
            let fit = est.fit_relative(&m, &mut Vec::new());
            let found = search(&est, &fit, &mean0, gate_s, WEAKEST_SCENE_ECHO_DB).scene;
            if found.is_empty() {
                break;
            }
            let settled = settled(&scene, &found);
            scene = found;
            if settled {
                break;
            }
        }
        (mean, relative) = (mean0, relative0);
        let by = chain_echoes::Echoes {
            scene: scene.clone(),
            ..Default::default()
        };
        divide(&mut mean, &mut relative, &|f| by.scene_at(f), &est);
        fitted = est.fit_relative(&mean, &mut Vec::new());
        echoes.scene = scene;
    }
    // Nearer than NEAR_LEAKAGE_S the gate is short and its local fit leans (a data-modulated
    // waveform's power varies within its kernel): the search, made against it, misplaces the
    // leakage by up to 0.2 ns, and the last fit holds what its division left.
    if let Some(original) =
        original.filter(|(mean, _)| refine_near_scene(&est, mean, &fitted, &mut echoes.scene))
    {
        (mean, relative) = original;
        divide(&mut mean, &mut relative, &|f| echoes.scene_at(f), &est);
        fitted = est.fit_relative(&mean, &mut Vec::new());
    }
    // A chain echo in the gate's taper would be half in the fit and half out: the gate closes
    // before the nearest one, and the search is made again.
    let nearest = search(&est, &fitted, &mean, gate_s / 1.5, WEAKEST_CHAIN_ECHO_DB)
        .chain
        .iter()
        .map(|e| e.delay_s)
        .fold(f64::INFINITY, f64::min);
    if nearest < 1.5 * gate_s {
        let closed = ((nearest - GATE_MARGIN_S) / 1.5).max(SHORTEST_CLOSED_GATE_S);
        if closed < gate_s {
            let reference = est.reference().to_vec();
            est = ChainEstimator::new(&reference, n, fs, closed)?;
            gate_s = closed;
            fitted = est.fit_relative(&mean, &mut Vec::new());
        }
    }
    let second = search(&est, &fitted, &mean, gate_s, WEAKEST_CHAIN_ECHO_DB);
    let mut chain_factor = vec![Complex64::new(1.0, 0.0); n];
    if !(second.chain.is_empty() && second.scene.is_empty()) {
        divide(
            &mut mean,
            &mut relative,
            &|f| second.chain_at(f) * second.scene_at(f),
            &est,
        );
        chain_factor = (0..n)
            .map(|k| second.chain_at(est.frequency_hz(k)))
            .collect();
        echoes.chain = second.chain;
        echoes.scene.extend(second.scene);
    }
    // The searches' local means lean where the waveform's power is uneven (the band's edges, the
    // MSK data inside a short gate's wide frequency kernel): the table is the least-squares fit.
    est.use_least_squares();
    fitted = est.fit_relative(&mean, &mut Vec::new());
    // Inside the gate's reach the fit holds it, beyond it the search should have found it: where
    // it did not, the chain's tail there (a sharp step in its response) raised the search's
    // floor over it, or cancelled it. The fit then holds whatever is there as the chain's.
    let leakage_unseen = (leakage_at_s.abs() > 1.5 * gate_s
        && !echoes
            .scene
            .iter()
            .any(|e| (e.delay_s - leakage_at_s).abs() <= LEAKAGE_PLACE_S))
    .then_some(scene_floor)
    .flatten();
    Ok(WholeChain {
        est,
        gate_s,
        fitted,
        chain_factor,
        relative,
        mean,
        echoes,
        leakage_at_s,
        leakage_unseen,
        echo_ahead,
    })
}

/// Whether a round of the scene's alternation changed nothing that matters: the same echoes,
/// each within [`SETTLED_S`] of its place and [`SETTLED_GAIN`] of its gain (relative to the
/// strongest).
fn settled(last: &[chain_echoes::Echo], next: &[chain_echoes::Echo]) -> bool {
    let strongest = next.iter().map(|e| e.gain.norm()).fold(0.0, f64::max);
    last.len() == next.len()
        && last.iter().zip(next).all(|(a, b)| {
            (a.delay_s - b.delay_s).abs() <= SETTLED_S
                && (a.gain - b.gain).norm() <= SETTLED_GAIN * strongest
        })
}

/// The scene's strongest echo within [`JOINT_NEAR_S`] beyond the gate's fit, measured again
/// jointly with it (`ChainEstimator::echo_beside_fit`): its delay where the joint fit leaves
/// least, then its gain, [`JOINT_ROUNDS`] times (each riding on the last joint fit). Searched against
/// the gate's fit alone, the leakage ahead of a reference under 0.8 m was found up to 0.2 ns from
/// its place, and the fit then held what its division left: a ghost 0.5 m ahead of every
/// corrected target. The echoes the search took out within [`JOINT_RESIDUE_S`] of it were what
/// that left: dropped. `mean` is the reference's mean relative spectrum with no scene echo
/// divided out, `fitted` its fit with all of them divided out. False when none is that near, or
/// a joint fit fails (nothing changed).
fn refine_near_scene(
    est: &ChainEstimator,
    mean: &[Complex64],
    fitted: &Fitted,
    scene: &mut Vec<chain_echoes::Echo>,
) -> bool {
    let reach = est.support_s() + JOINT_NEAR_S;
    let Some(strongest) = (0..scene.len())
        .filter(|&i| scene[i].delay_s.abs() <= reach)
        .max_by(|&a, &b| scene[a].gain.norm().total_cmp(&scene[b].gain.norm()))
    else {
        return false;
    };
    let found = scene[strongest];
    let (residue, others): (Vec<_>, Vec<_>) = scene
        .iter()
        .enumerate()
        .filter(|&(i, _)| i != strongest)
        .map(|(_, e)| *e)
        .partition(|e| (e.delay_s - found.delay_s).abs() <= JOINT_RESIDUE_S);
    let others = chain_echoes::Echoes {
        scene: others,
        ..Default::default()
    };
    let z: Vec<Complex64> = (0..est.period())
        .map(|k| mean[k] / others.scene_at(est.frequency_hz(k)))
        .collect();
    let mut through = fitted.clone();
    let mut measured = found;
    for _ in 0..JOINT_ROUNDS {
        let Some(joint) = est.echo_beside_fit(&z, &through) else {
            return false;
        };
        let t = chain_echoes::refine_delay(
            |t| -joint.residual_at(t),
            measured.delay_s,
            JOINT_DELAY_STEP_S,
        );
        let Some((gain, direct)) = joint.fit_at(t) else {
            return false;
        };
        through.direct = direct;
        measured = chain_echoes::Echo { delay_s: t, gain };
    }
    tracing::debug!(
        target: "radbench::calibration",
        "the leakage measured jointly with the gate's fit: {:.4} ns -> {:.4} ns, {} residue echoes dropped",
        found.delay_s * 1e9,
        measured.delay_s * 1e9,
        residue.len()
    );
    *scene = others.scene;
    scene.push(measured);
    true
}

/// The strongest echo `found` (with a short gate) ahead of the reference, from where a reflector
/// can be named (`NAMED_CLOSEST_M`) to the gate's reach (`1.5 gate_s`; beyond it the search
/// divides it out as the scene's), away from the leakage (`leakage_at_s`), with no echo behind
/// it at the same delay within 10 dB (a ripple's paired echoes stand either side of the main
/// path).
fn echo_ahead(
    found: &chain_echoes::Echoes,
    gate_s: f64,
    leakage_at_s: f64,
) -> Option<chain_echoes::Echo> {
    let all: Vec<&chain_echoes::Echo> = found.chain.iter().chain(&found.scene).collect();
    let closest_s = 2.0 * NAMED_CLOSEST_M / C0;
    let level = |e: &chain_echoes::Echo| e.gain.norm();
    all.iter()
        .filter(|e| e.delay_s <= -closest_s && e.delay_s >= -1.5 * gate_s)
        .filter(|e| (e.delay_s - leakage_at_s).abs() > LEAKAGE_PLACE_S)
        .filter(|e| {
            !all.iter().any(|m| {
                (m.delay_s + e.delay_s).abs() <= MIRROR_WITHIN_S
                    && level(m) >= level(e) * 10f64.powf(-10.0 / 20.0)
            })
        })
        .max_by(|a, b| level(a).total_cmp(&level(b)))
        .map(|e| **e)
}

/// The two ends' I/Q errors from the image `image` against the direct response `direct` (both
/// per bin of the period, unnormalised), over the bins where the waveform's power at `f` and at
/// `-f` is within 3 dB of its peak.
fn split_iq(
    est: &ChainEstimator,
    direct: &[Complex64],
    image: &[Complex64],
    cover: &[f64],
    gate_s: f64,
) -> Option<crate::dsp::iq_image::IqSplit> {
    let n = est.period();
    let w: Vec<f64> = (0..n)
        .map(|k| {
            let weight = cover[k].min(cover[(n - k) % n]);
            if weight >= FIGURE_COVERAGE {
                weight
            } else {
                0.0
            }
        })
        .collect();
    // The gate (flat +-gate, a taper half as long each side) spans 3 gate: its estimates are
    // correlated over 1 / (3 gate).
    let df = est.frequency_hz(1);
    split_measured(direct, image, &w, df * n as f64, 1.0 / (3.0 * gate_s * df))
}

/// The strongest echo within 2 m of where the reference should be must lie within the gate of
/// it: otherwise the system delay is off (calibrate it first) or the pillar is elsewhere.
fn check_reference_near(
    est: &ChainEstimator,
    spectrum: &[Complex64],
    delay: f64,
    gate: f64,
    scratch: &mut Vec<Complex64>,
) -> Result<(), MeasureError> {
    let n = est.period();
    let c = est.correlation(spectrum, scratch);
    let search = (2.0 * 2.0 / C0 * est.frequency_hz(1) * n as f64).ceil() as i64;
    let centre = delay.round() as i64;
    let peak = (centre - search..=centre + search)
        .max_by(|a, b| {
            let (a, b) = (
                a.rem_euclid(n as i64) as usize,
                b.rem_euclid(n as i64) as usize,
            );
            c[a].norm().total_cmp(&c[b].norm())
        })
        .unwrap_or(centre);
    if ((peak - centre) as f64).abs() > gate {
        let fs = est.frequency_hz(1) * n as f64;
        let off_m = (peak - centre) as f64 / fs * C0 / 2.0;
        return Err(MeasureError::CorrectionRefused(format!(
            "the strongest echo near the reference lies {off_m:+.3} m from where it should be: \
             the system delay is off or the pillar is not at --reference-range; run `radbench \
             calibrate --reference-range R` first (the delay), or check the range"
        )));
    }
    Ok(())
}

/// The figures of a normalised response over the bins within 3 dB of the band's peak power.
#[allow(clippy::too_many_arguments)]
fn figures_of(
    table: &ResponseTable,
    image: &[Complex64],
    in_figures: &[bool],
    spread_db: &[f64],
    spread_deg: &[f64],
    gate_s: f64,
    dc: Complex64,
    (gain_db, phase_deg): (f64, f64),
) -> ResponseFigures {
    let idx: Vec<usize> = (0..table.freq_hz.len())
        .filter(|&k| in_figures[k])
        .collect();
    let f: Vec<f64> = idx.iter().map(|&k| table.freq_hz[k]).collect();
    let db: Vec<f64> = idx
        .iter()
        .map(|&k| 20.0 * table.response[k].norm().max(1e-300).log10())
        .collect();
    // Unwrapped phase and its best straight line.
    let mut phase = Vec::with_capacity(idx.len());
    let mut last = 0.0;
    for (j, &k) in idx.iter().enumerate() {
        let mut p = table.response[k].arg();
        if j > 0 {
            while p - last > PI {
                p -= 2.0 * PI;
            }
            while p - last < -PI {
                p += 2.0 * PI;
            }
        }
        phase.push(p);
        last = p;
    }
    let (slope, icept) = line_fit(&f, &phase);
    let residual: Vec<f64> = f
        .iter()
        .zip(&phase)
        .map(|(f, p)| (p - (slope * f + icept)).to_degrees())
        .collect();
    // Group delay over steps of a quarter of the gate's resolution.
    let df = f.get(1).zip(f.first()).map_or(1.0, |(b, a)| b - a).max(1.0);
    let step = ((0.25 / (2.0 * gate_s)) / df).round().max(1.0) as usize;
    let gd: Vec<f64> = (step..phase.len())
        .map(|j| -(phase[j] - phase[j - step]) / (2.0 * PI * (f[j] - f[j - step])) * 1e12)
        .collect();
    let pp = |v: &[f64]| {
        let (lo, hi) = v
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), x| {
                (lo.min(*x), hi.max(*x))
            });
        if lo.is_finite() {
            hi - lo
        } else {
            0.0
        }
    };
    let w: Vec<Complex64> = idx.iter().map(|&k| image[k]).collect();
    let (w_slope_im, _) = line_fit(&f, &w.iter().map(|v| v.im).collect::<Vec<_>>());
    let image_power = w.iter().map(|v| v.norm_sqr()).sum::<f64>() / w.len().max(1) as f64;
    let max = |v: &[f64]| idx.iter().map(|&k| v[k]).fold(0.0, f64::max);
    ResponseFigures {
        ripple_db_pp: pp(&db),
        phase_ripple_deg_pp: pp(&residual),
        group_delay_ripple_ps_pp: pp(&gd),
        delay_offset_ps: -slope / (2.0 * PI) * 1e12,
        dc_v: [dc.re, dc.im],
        rx_iq_gain_db: gain_db,
        rx_iq_phase_deg: phase_deg,
        // Q late by s leaves an image of about j pi f s.
        iq_skew_ps: w_slope_im / PI * 1e12,
        image_db: 10.0 * image_power.max(1e-30).log10(),
        spread_db_max: max(spread_db),
        spread_deg_max: max(spread_deg),
        ..ResponseFigures::default()
    }
}

/// Least-squares line `y = a x + b`.
fn line_fit(x: &[f64], y: &[f64]) -> (f64, f64) {
    let n = x.len() as f64;
    if x.len() < 2 {
        return (0.0, y.first().copied().unwrap_or(0.0));
    }
    let (mx, my) = (x.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
    let (mut sxy, mut sxx) = (0.0, 0.0);
    for (a, b) in x.iter().zip(y) {
        sxy += (a - mx) * (b - my);
        sxx += (a - mx) * (a - mx);
    }
    let a = if sxx > 0.0 { sxy / sxx } else { 0.0 };
    (a, my - a * mx)
}

#[cfg(test)]
mod tests {
    use super::{fill_blind, raise, settled};
    use crate::dsp::chain_echoes::Echo;
    use num_complex::Complex64;

    #[test]
    fn a_blind_place_takes_the_highest_level_beside_it_and_never_lowers() {
        // 0.1 m bins; an echo at 0.35 +- 0.1 m blinds bins 2 ..= 4; 1 bin each side is beside.
        let mut levels = vec![-50.0, -60.0, -70.0, -40.0, -75.0, -55.0, -45.0];
        fill_blind(&mut levels, 0.1, [0.35].into_iter(), 0.1);
        assert_eq!(levels, [-50.0, -60.0, -55.0, -40.0, -55.0, -55.0, -45.0]);
        // Two echoes whose places overlap are one run; a place at the profile's end, or beyond
        // it, neither panics nor reads outside.
        let mut levels = vec![-50.0, -90.0, -90.0, -90.0, -90.0, -52.0];
        fill_blind(&mut levels, 0.1, [0.15, 0.3, 9.0].into_iter(), 0.1);
        assert_eq!(levels, [-50.0, -52.0, -52.0, -52.0, -52.0, -52.0]);
    }

    #[test]
    fn raise_lifts_only_the_bins_around_the_place_and_never_lowers() {
        let mut levels = vec![-80.0, -80.0, -30.0, -80.0, -80.0, -80.0];
        // 0.1 m bins; 0.25 +- 0.1 m covers bins 1 ..= 3.
        raise(&mut levels, 0.1, 0.25, 0.1, -40.0);
        assert_eq!(levels, [-80.0, -40.0, -30.0, -40.0, -80.0, -80.0]);
        // Beyond the profile: nothing to raise, no panic.
        raise(&mut levels, 0.1, 5.0, 0.1, -10.0);
        assert_eq!(levels, [-80.0, -40.0, -30.0, -40.0, -80.0, -80.0]);
    }

    #[test]
    fn the_alternation_settles_only_when_no_echo_moves_or_changes() {
        let echo = |delay_ns: f64, re: f64| Echo {
            delay_s: delay_ns * 1e-9,
            gain: Complex64::new(re, 0.0),
        };
        let last = [echo(-5.15, 0.01), echo(-4.2, 0.001)];
        assert!(settled(&last, &[echo(-5.1502, 0.01), echo(-4.2, 0.001)]));
        // 1 ps is more than the 0.5 ps a settled echo may move.
        assert!(!settled(&last, &[echo(-5.151, 0.01), echo(-4.2, 0.001)]));
        // A gain change of 0.2 % of the strongest's.
        assert!(!settled(&last, &[echo(-5.15, 0.01), echo(-4.2, 0.00102)]));
        // An echo more or fewer is not settled.
        assert!(!settled(&last, &last[..1]));
    }
}
