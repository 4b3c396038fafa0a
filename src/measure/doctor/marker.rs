//! `marker` and `safe_state`: the AWG plays a segment of zero codes with only its marker output
//! on (I and Q outputs off, the transmitter off) and the scope must see the marker's edge on its
//! external trigger: the cable every capture's timing rests on, tested without radiating. The
//! bench's safe state runs after it whatever happens (a panic and Ctrl-C included) and is
//! reported as its own check.

use super::bounds::{Deadline, CHECKS_TOTAL};
use super::checklist::List;
use super::front_ends::Module;
use crate::catalog::InstrumentModel;
use crate::driver::safe_state::{self, Shared};
use crate::driver::{
    Awg, AwgSettings, Digitizer, DigitizerSettings, DriverError, IqWaveform, Outcome, SafeState,
};
use crate::measure::bench::interrupt::{Interrupt, StopSignal};
use crate::measure::bench::station::capture_rate;
use crate::measure::error::MeasureError;
use std::time::Duration;

/// Longest wait for the marker's edge at the scope, seconds.
const MARKER_WAIT_S: f64 = 1.0;
/// Longest the whole marker check may take (configure, download, acquire), seconds.
const MARKER_DEADLINE: Duration = Duration::from_secs(20);
/// Bound on each step of the safe state.
const SAFE_STEP_TIMEOUT: Duration = Duration::from_secs(5);

/// What the checks before the marker leave connected: the instruments that were identified,
/// and whether the transmitter radiates now.
pub(super) struct Connected {
    pub(super) awg: Option<Box<dyn Awg>>,
    pub(super) scope: Option<Box<dyn Digitizer>>,
    pub(super) modules: Vec<Module>,
    pub(super) tx_on: bool,
}

/// The marker check, when it may run: both instruments identified, no stop signal, the
/// transmitter off, and time left for the scope's wait. Otherwise skipped, saying why; nothing
/// is switched on then.
///
/// # Errors
/// [`MeasureError::Interrupted`] when a stop signal comes while the marker plays (the bench is
/// in its safe state by then, the error's report says so).
pub(super) async fn check_marker(
    list: &mut List,
    connected: Connected,
    scope_model: &InstrumentModel,
    interrupt: &Interrupt,
    deadline: Deadline,
) -> Result<(), MeasureError> {
    let Connected {
        awg,
        scope,
        modules,
        tx_on,
    } = connected;
    match (awg, scope) {
        _ if interrupt.received().is_some() => list.skip("marker", "interrupted: not tried"),
        // Too little left for the scope's wait: nothing is switched on.
        (Some(_), Some(_))
            if deadline.bound(MARKER_DEADLINE).as_secs_f64() < 2.0 * MARKER_WAIT_S =>
        {
            list.skip(
                "marker",
                format!(
                    "not tried: the doctor's {} s for its checks were spent before it",
                    CHECKS_TOTAL.as_secs()
                ),
            )
        }
        (Some(a), Some(s)) if !tx_on => {
            let deadline = deadline.bound(MARKER_DEADLINE);
            play_marker(list, a, s, modules, scope_model, interrupt, deadline).await?;
        }
        (Some(_), Some(_)) => list.skip("marker", "the transmitter is on: not tried"),
        _ => list.skip("marker", "the AWG or the scope was not identified"),
    }
    Ok(())
}

/// Plays zero codes with only the marker output on and arms the scope on its external trigger;
/// the bench's safe state runs after it whatever happens.
async fn play_marker(
    list: &mut List,
    awg: Box<dyn Awg>,
    mut scope: Box<dyn Digitizer>,
    modules: Vec<Module>,
    scope_model: &InstrumentModel,
    interrupt: &Interrupt,
    deadline: Duration,
) -> Result<(), MeasureError> {
    let awg: Shared<dyn Awg> = safe_state::share(awg);
    let fronts_off = if modules.is_empty() {
        "no front end driven by radbench"
    } else {
        "the front ends it drives off"
    };
    let mut tx = None;
    let mut rx = None;
    for (name, g) in modules {
        let shared = safe_state::share(g);
        if name == "tx" {
            tx = Some(shared);
        } else {
            rx = Some(shared);
        }
    }
    let safe = SafeState::new(
        safe_state::Bench {
            tx,
            rx,
            awg: Some(awg.clone()),
        },
        SAFE_STEP_TIMEOUT,
    );
    // A panic while the AWG plays runs this bench's safe state too.
    crate::driver::set_panic_safe_state(safe.clone());
    let settings = AwgSettings::default();
    let limits = scope_model.digitizer.clone();
    let work = async {
        let rate = match &limits {
            Some(l) => capture_rate(l, settings.sample_rate_hz)?,
            None => settings.sample_rate_hz,
        };
        let n = 16_000usize;
        let waveform = IqWaveform {
            i: vec![0; n],
            q: vec![0; n],
            marker_high_samples: 64,
        };
        let loaded = {
            let mut a = awg.lock().await;
            a.configure(&settings).await?;
            a.load(&waveform).await?
        };
        let scope_settings = DigitizerSettings {
            sample_rate_hz: rate,
            repetition_s: loaded.padded_samples as f64 / settings.sample_rate_hz,
            longest_echo_s: 0.0,
            pre_trigger_s: 0.0,
            trigger_level_v: settings.marker_offset_v,
            segments: 1,
            ..DigitizerSettings::default()
        };
        let scope_settings = match &limits {
            Some(l) => DigitizerSettings {
                i_volts_per_div: l.volts_per_div_default,
                q_volts_per_div: l.volts_per_div_default,
                ..scope_settings
            },
            None => scope_settings,
        };
        scope.configure(&scope_settings).await?;
        {
            let mut a = awg.lock().await;
            a.enable_marker().await?;
            a.run().await?;
        }
        let seen = scope.acquire(MARKER_WAIT_S).await;
        let _ = scope.stop().await;
        Ok::<_, MeasureError>(seen)
    };
    let bounded_work = async {
        tokio::time::timeout(deadline, work)
            .await
            .unwrap_or(Err(MeasureError::RfDeadline {
                seconds: deadline.as_secs_f64(),
            }))
    };
    let (outcome, report) = crate::driver::run_guarded(&safe, bounded_work, interrupt.wait()).await;
    crate::driver::clear_panic_safe_state(&safe);
    let safe_ok = report.is_safe();
    match outcome {
        Outcome::Interrupted => {
            return Err(MeasureError::Interrupted {
                signal: interrupt.received().unwrap_or(StopSignal::Interrupt),
                report: report.to_string(),
            })
        }
        Outcome::Finished(Ok(Ok(()))) => list.pass(
            "marker",
            "the AWG's marker (I and Q outputs off, transmitter off) triggers the scope's \
             external input",
        ),
        Outcome::Finished(Ok(Err(DriverError::NoTrigger { waited_s, .. }))) => list.fail(
            "marker",
            format!(
                "no marker edge reached the scope's external trigger within {waited_s} s, with \
                 the AWG running and its marker output on"
            ),
            "check the cable from the AWG's marker output to the scope's EXT trigger input, and \
             the trigger level (the marker's mid level)",
        ),
        Outcome::Finished(Ok(Err(e))) => list.fail(
            "marker",
            format!("the scope's acquisition failed: {e}"),
            "check the scope's trigger settings and its link",
        ),
        Outcome::Finished(Err(e)) => list.fail(
            "marker",
            format!("could not set up the marker test: {e}"),
            "fix the error above (the AWG's or the scope's settings)",
        ),
    }
    if safe_ok {
        list.pass(
            "safe_state",
            format!("after the checks: AWG outputs off and stopped, {fronts_off}"),
        );
    } else {
        list.fail(
            "safe_state",
            format!("the safe state did not complete: {report}"),
            "switch the AWG's outputs and the front ends off by hand, then check their links",
        );
    }
    Ok(())
}
