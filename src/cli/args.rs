//! Command-line arguments shared by several subcommands: the waveform and its parameters, the
//! processing choices, the built-in lab's transports. The library's named enums (waveform,
//! algorithm, window, FFT precision, detector, carrier phase, correction, the built-in lab's
//! transports and scope) are parsed as they are, by their own
//! `FromStr` over the values they list (`Listed`, `listed`). The waveform's and `process`'s
//! options live in the library (`radbench::in_memory`): the Python package parses them too.

pub(crate) use radbench::in_memory::{listed, PayloadArgs, WaveformArgs};
use radbench::measure::{
    Algorithm, DetectorName, FftPrecisionName, ProcessOptions, Ranging, WindowName,
};
use radbench::waveform::WaveformKind;

/// Range processing choices shared by `capture`, `simulate run` and `process`.
#[derive(Debug, Clone, clap::Args)]
pub struct ProcessingArgs {
    /// Range processing: correlation (default for MSK-LFM), fourier (default for OFDM), music,
    /// root-music or esprit (OFDM).
    #[arg(long, value_parser = listed::<Algorithm>())]
    pub algorithm: Option<Algorithm>,
    /// MUSIC sub-vector (covariance) length M.
    #[arg(long = "m", value_name = "M", default_value_t = 64)]
    pub music_m: usize,
    /// Number of targets for MUSIC/root-MUSIC/ESPRIT (default: estimated with MDL).
    #[arg(long = "p", value_name = "P")]
    pub music_p: Option<usize>,
    /// Forward smoothing only (no forward-backward averaging) for MUSIC.
    #[arg(long)]
    pub forward_only: bool,
    /// OFDM Fourier zero-padding factor: IFFT length = K x subcarriers.
    #[arg(long, value_name = "K", default_value_t = 10)]
    pub zero_pad: usize,
    /// Window on the range processing (OFDM: across the subcarriers; correlation: on the matched
    /// filter's spectrum).
    #[arg(long, value_parser = listed::<WindowName>(), value_name = "NAME", default_value = "rect")]
    pub window: WindowName,
    /// Precision of the OFDM receiver's per-symbol FFT (the rest is double precision).
    #[arg(long, value_parser = listed::<FftPrecisionName>(), value_name = "P", default_value = "single")]
    pub fft_precision: FftPrecisionName,
    /// Report the on-grid peak (no sub-sample interpolation).
    #[arg(long)]
    pub no_interpolation: bool,
    /// Detector of the correlation and Fourier profiles (docs/detection.md compares them).
    #[arg(long, value_parser = listed::<DetectorName>(), value_name = "NAME", default_value = "clean")]
    pub detector: DetectorName,
    /// Probability of false alarm of the detector, per profile cell.
    #[arg(
        long,
        value_name = "P",
        default_value_t = 1e-6,
        allow_hyphen_values = true
    )]
    pub pfa: f64,
    /// Targets closer than this are reported as one, metres (default: 0.75 resolution cells).
    #[arg(long, value_name = "METRES", allow_hyphen_values = true)]
    pub min_separation: Option<f64>,
    /// Around a target whose main lobe does not fit the ideal point spread to 50 dB, a weaker
    /// echo within 1.6 m is a target only within this many dB of it (the chain's own echoes are
    /// part of its response; docs/detection.md). Lower it for a bench known to be cleaner;
    /// -200 turns it off.
    #[arg(
        long,
        value_name = "DB",
        default_value_t = -17.0,
        allow_hyphen_values = true
    )]
    pub chain_floor_db: f64,
    /// How each target's range is measured: envelope (default), or phase: refined by the echo's
    /// carrier phase against the calibration's reference, to a fraction of a micrometre
    /// (docs/metrology.md; needs --calibration of a response calibration).
    #[arg(long, value_parser = listed::<Ranging>(), value_name = "MODE", default_value = "envelope")]
    pub ranging: Ranging,
}

impl ProcessingArgs {
    /// The library options for `waveform` (ranges and calibration left at their defaults).
    pub fn options(&self, waveform: WaveformKind) -> ProcessOptions {
        ProcessOptions {
            algorithm: self.algorithm.unwrap_or(Algorithm::default_for(waveform)),
            music_m: self.music_m,
            music_p: self.music_p,
            forward_backward: !self.forward_only,
            zero_pad: self.zero_pad,
            window: self.window,
            fft_precision: self.fft_precision,
            interpolate: !self.no_interpolation,
            detector: self.detector,
            pfa: self.pfa,
            min_separation_m: self.min_separation,
            chain_floor_db: self.chain_floor_db,
            ranging: self.ranging,
            ..ProcessOptions::default()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use radbench::in_memory::Listed;
    use radbench::measure::CorrectionMode;
    use radbench::simulate::CarrierPhase;

    /// Every value of `T` parses from its name (by clap too) and prints as it; clap refuses
    /// another one naming the option and every allowed value.
    fn round_trip<T: Listed + std::fmt::Display + PartialEq + std::fmt::Debug>() {
        let cmd = || {
            clap::Command::new("radbench").arg(
                clap::Arg::new("opt")
                    .long("opt")
                    .value_parser(listed::<T>()),
            )
        };
        for &v in T::all() {
            assert_eq!(v.name().parse::<T>().ok(), Some(v));
            assert_eq!(v.to_string(), v.name());
            let m = cmd()
                .try_get_matches_from(["radbench", "--opt", v.name()])
                .unwrap();
            assert_eq!(m.get_one::<T>("opt"), Some(&v));
        }
        let err = cmd()
            .try_get_matches_from(["radbench", "--opt", "nonsense"])
            .unwrap_err()
            .to_string();
        assert!(err.contains("--opt"), "{err}");
        for &v in T::all() {
            assert!(err.contains(v.name()), "{err}");
        }
    }

    #[test]
    fn the_library_enums_parse_by_their_own_names() {
        round_trip::<WaveformKind>();
        round_trip::<Algorithm>();
        round_trip::<WindowName>();
        round_trip::<FftPrecisionName>();
        round_trip::<DetectorName>();
        round_trip::<CarrierPhase>();
        round_trip::<CorrectionMode>();
        round_trip::<Ranging>();
        let err = "pmcw".parse::<WaveformKind>().unwrap_err();
        assert!(err.contains("msk-lfm, ofdm"), "{err}");
    }
}

/// `--timeout`: how long an instrument may take to start a reply, for every instrument of the
/// bench (the catalog's `[timeouts] read_ms` otherwise). Named by the timeout messages' advice.
#[derive(Debug, Clone, Copy, Default, clap::Args)]
pub struct TimeoutArgs {
    /// Longest wait for an instrument's reply to start, seconds, for every instrument of the
    /// bench (default: each model's catalog `[timeouts] read_ms`); raise it for a slow one.
    #[arg(long, value_name = "SECONDS", allow_hyphen_values = true)]
    pub timeout: Option<f64>,
}

/// The largest `--timeout`: an hour (a reply that takes longer is not coming).
const MAX_TIMEOUT_S: f64 = 3600.0;

impl TimeoutArgs {
    /// Gives every link opened from now on the timeout, when one is given; refuses one that is
    /// not a positive number of seconds up to an hour.
    pub(crate) fn apply(self) -> anyhow::Result<()> {
        let Some(s) = self.timeout else {
            return Ok(());
        };
        if !(s.is_finite() && s > 0.0 && s <= MAX_TIMEOUT_S) {
            return Err(radbench::exit::bad_input(format!(
                "--timeout {s}: allowed: a positive number of seconds, at most {MAX_TIMEOUT_S}"
            )));
        }
        radbench::driver::set_read_timeout(std::time::Duration::from_secs_f64(s));
        Ok(())
    }
}
