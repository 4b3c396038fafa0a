//! The retry policy: which faults of a step are worth measuring it again (a glitch, not a
//! broken bench), and how long to wait before each retry. The runner does the rest: the bench in
//! its safe state, the links closed and opened again (identities checked again), the step measured
//! again from the start, each retry recorded in the manifest and the report.

use super::error::CampaignError;
use crate::driver::DriverError;
use crate::driver::ErrorKind;
use crate::measure::MeasureError;
use serde::{Deserialize, Serialize};
use std::time::Duration;

/// One retry of a step, as the manifest and the report record it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RetryRecord {
    /// The step (1-based).
    pub step: usize,
    /// 1 for the step's first retry.
    pub attempt: usize,
    /// The instrument that failed (`awg`, `scope`, `tx`, `rx`).
    pub instrument: String,
    /// What failed, as the error said it.
    pub fault: String,
    /// When the fault was met (RFC 3339 UTC).
    pub at: String,
    /// The safe-state sequence run before the retry, step by step.
    pub safe_state: String,
    /// The wait before the step was measured again, seconds.
    pub wait_s: f64,
}

/// The instrument of a transient fault in `e`, `None` when the fault is not one to retry: a lost
/// or refused connection, a timeout, a missing trigger (marker edge), a Gotmic module's reply
/// that fails its CRC or its identity, a Gotmic module found reset after a capture (back at its
/// power-on state, RF off or silent: it lost power during the capture). Everything else stops
/// the run at once, as without retries: an identity that changed (the runner's own check), an
/// interlock or a latched fault, a refused setting, a spec error, the run folder gone, a signal.
pub(crate) fn transient_instrument(e: &CampaignError) -> Option<&str> {
    let CampaignError::Measure(MeasureError::Driver(d)) = e else {
        return None;
    };
    match d {
        // Connect, timeout, closed, I/O, serial: the link's own Retry class.
        DriverError::Session { instrument, .. } if d.kind() == ErrorKind::Retry => Some(instrument),
        // The scope silent or refusing while a retry connects (still stalled, rebooting): the
        // class of the link's own error, which the remote-interface hint wraps.
        DriverError::RemoteInterface { source, .. } if source.kind() == ErrorKind::Retry => {
            Some("scope")
        }
        DriverError::NoTrigger { instrument, .. } => Some(instrument),
        DriverError::StateLost { instrument, .. } => Some(instrument),
        DriverError::Reply { instrument, .. } if is_front_end(instrument) => Some(instrument),
        // A module's identity garbled on its serial line (named by its resource there).
        DriverError::WrongInstrument { resource, .. } if resource.starts_with("ASRL") => {
            Some(resource)
        }
        DriverError::LineRefused {
            instrument, text, ..
        } if is_front_end(instrument) && text.to_ascii_lowercase().contains("crc") => {
            Some(instrument)
        }
        _ => None,
    }
}

/// A Gotmic Tx or Rx module (the runner names them `tx` and `rx`).
fn is_front_end(instrument: &str) -> bool {
    instrument.starts_with("tx") || instrument.starts_with("rx")
}

/// The wait before retry `attempt` (1-based): `first`, doubled each time, at most 10 minutes.
pub(crate) fn backoff(first_s: f64, attempt: usize) -> Duration {
    let factor = 2f64.powi(attempt.saturating_sub(1).min(16) as i32);
    Duration::from_secs_f64((first_s * factor).clamp(0.0, 600.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn driver(d: DriverError) -> CampaignError {
        CampaignError::Measure(MeasureError::Driver(d))
    }

    #[test]
    fn glitches_are_retried_and_a_broken_bench_is_not() {
        // A lost connection (a session error of the transport's kind) is ridden out end to end
        // in tests/cli/unattended.rs (a dropped AWG and a dropped scope): campaign may not name
        // the session and transport layers, even in its tests.
        let trigger = driver(DriverError::NoTrigger {
            instrument: "scope".into(),
            source_name: "EX".into(),
            waited_s: 1.0,
            safe_state: None,
        });
        assert_eq!(transient_instrument(&trigger), Some("scope"));
        let crc = driver(DriverError::Reply {
            instrument: "tx".into(),
            command: "RD 0x00*1F".into(),
            expected: "a reply ending in a valid *<hh> CRC-8",
            reply: "OK 0x0001*00".into(),
        });
        assert_eq!(transient_instrument(&crc), Some("tx"));
        let reset = driver(DriverError::StateLost {
            instrument: "rx".into(),
            found: "the module is back at its power-on state (RF off)".into(),
            certain: true,
        });
        assert_eq!(transient_instrument(&reset), Some("rx"));
        // The same kind of reply from the AWG is no glitch of a serial line.
        let awg_reply = driver(DriverError::Reply {
            instrument: "awg".into(),
            command: "*OPC?".into(),
            expected: "1",
            reply: "2".into(),
        });
        assert_eq!(transient_instrument(&awg_reply), None);
        let garbled = |resource: &str| {
            driver(DriverError::WrongInstrument {
                resource: resource.into(),
                expected: "gotmic-eband-tx".into(),
                idn: "GOTM".into(),
            })
        };
        assert_eq!(
            transient_instrument(&garbled("ASRL/dev/ttyUSB0::INSTR")),
            Some("ASRL/dev/ttyUSB0::INSTR")
        );
        assert_eq!(
            transient_instrument(&garbled("TCPIP::10.0.0.2::hislip0::INSTR")),
            None
        );
        let interlock = driver(DriverError::RfNotReady {
            instrument: "tx".into(),
            reason: "the interlock is open".into(),
        });
        assert_eq!(transient_instrument(&interlock), None);
        let changed = CampaignError::DifferentBench {
            what: "the instruments answer differently".into(),
        };
        assert_eq!(transient_instrument(&changed), None);
    }

    /// A scope that refuses the connection a retry opens (still rebooting) is retried again:
    /// the driver's remote-interface hint wraps the refusal, whose class decides.
    #[tokio::test]
    async fn a_scope_refusing_a_retrys_connection_is_retried() {
        let port = std::net::TcpListener::bind("127.0.0.1:0")
            .unwrap()
            .local_addr()
            .unwrap()
            .port();
        let resource = format!("VICP::127.0.0.1,{port}::INSTR").parse().unwrap();
        let catalog = crate::catalog::Catalog::load(None).unwrap();
        let model = catalog.get("lecroy-labmaster10zi-a").unwrap();
        let open = crate::driver::Lecroy::open(resource, model, None, "scope");
        let e = tokio::time::timeout(Duration::from_secs(30), open)
            .await
            .expect("a refused connection fails at once")
            .err()
            .expect("nothing listens there");
        assert!(matches!(e, DriverError::RemoteInterface { .. }), "{e}");
        assert_eq!(transient_instrument(&driver(e)), Some("scope"));
    }

    #[test]
    fn the_wait_doubles_and_is_bounded() {
        assert_eq!(backoff(2.0, 1), Duration::from_secs(2));
        assert_eq!(backoff(2.0, 2), Duration::from_secs(4));
        assert_eq!(backoff(2.0, 3), Duration::from_secs(8));
        assert_eq!(backoff(400.0, 2), Duration::from_secs(600));
        assert_eq!(backoff(0.0, 5), Duration::ZERO);
    }
}
