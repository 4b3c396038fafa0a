//! Command-line arguments shared by several subcommands: the waveform and its parameters, the
//! processing choices, the built-in lab's transports. The library's named enums (waveform,
//! algorithm, window, FFT precision, detector, ranging, carrier phase, correction, the built-in
//! lab's transports) are parsed as they are, by their own `FromStr` over the values they list
//! (`Listed`, `listed`), and the built-in lab's scope by the lab's table of scopes
//! (`scope_models`). The waveform's and `process`'s
//! options live in the library (`radbench::in_memory`): the Python package parses them too.

pub(crate) use radbench::in_memory::{listed, PayloadArgs, WaveformArgs};
pub(crate) use radbench::measure::scope_models;

#[cfg(test)]
mod tests {
    use super::*;
    use radbench::in_memory::Listed;
    use radbench::measure::CorrectionMode;
    use radbench::measure::{Algorithm, DetectorName, FftPrecisionName, WindowName};
    use radbench::simulate::CarrierPhase;
    use radbench::waveform::WaveformKind;

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
        round_trip::<radbench::measure::Ranging>();
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
