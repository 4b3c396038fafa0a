//! Connecting the bench's drivers and running one capture under the safe-state guard.

use super::bench_file::BenchFile;
use super::process::RawIq;
use super::transmit::Transmission;
use super::MeasureError;
use crate::address::Resource;
use crate::catalog::Catalog;
use crate::driver::safe_state::{self, Shared};
use crate::driver::{
    Awg, AwgApplied, AwgSettings, Digitizer, DigitizerApplied, DigitizerSettings, Gotmic,
    IqCapture, Lecroy, LoadedSegment, M8195a, Outcome, RfFrontEnd, RfPermit, RfSettings, RfStatus,
    SafeState, SafeStateReport,
};
use crate::session::Identity;
use crate::transport::Journal;
use num_complex::Complex64;
use serde::Serialize;
use std::future::Future;
use std::time::Duration;

/// The bench's drivers, shared with the safe state.
pub struct Connected {
    pub awg: Shared<dyn Awg>,
    pub scope: Box<dyn Digitizer>,
    pub tx: Option<Shared<dyn RfFrontEnd>>,
    pub rx: Option<Shared<dyn RfFrontEnd>>,
    pub identities: Identities,
    pub safe: SafeState,
}

/// `*IDN?` of every instrument, for the run's files.
#[derive(Debug, Clone, Serialize, Default)]
pub struct Identities {
    pub awg: String,
    pub scope: String,
    pub tx: Option<String>,
    pub rx: Option<String>,
}

fn idn(i: &Identity) -> String {
    format!("{},{},{},{}", i.manufacturer, i.model, i.serial, i.firmware)
}

fn resource(text: &str, section: &str) -> Result<Resource, MeasureError> {
    text.parse()
        .map_err(|e| MeasureError::Param(format!("[{section}] resource = {text:?}: {e}")))
}

/// Opens every instrument of the bench file (front ends optional) and builds the safe state.
pub async fn connect(
    bench: &BenchFile,
    catalog: &Catalog,
    journal: Option<Journal>,
) -> Result<Connected, MeasureError> {
    let awg_model = catalog.get(&bench.awg.model)?;
    let awg = M8195a::open(
        resource(&bench.awg.resource, "awg")?,
        awg_model,
        journal.clone(),
        "awg",
    )
    .await?;
    let scope_model = catalog.get(&bench.scope.model)?;
    let scope = Lecroy::open(
        resource(&bench.scope.resource, "scope")?,
        scope_model,
        journal.clone(),
        "scope",
    )
    .await?;
    let mut identities = Identities {
        awg: idn(awg.identity()),
        scope: idn(scope.identity()),
        ..Identities::default()
    };
    let front = |entry: &Option<super::bench_file::InstrumentEntry>, name: &'static str| {
        let entry = entry.clone();
        let journal = journal.clone();
        async move {
            let Some(e) = entry else {
                return Ok::<_, MeasureError>(None);
            };
            let model = catalog.get(&e.model)?;
            let g = Gotmic::open(resource(&e.resource, name)?, model, journal, name).await?;
            Ok(Some(g))
        }
    };
    let tx = front(&bench.tx, "tx").await?;
    let rx = front(&bench.rx, "rx").await?;
    identities.tx = tx.as_ref().map(|g| idn(g.identity()));
    identities.rx = rx.as_ref().map(|g| idn(g.identity()));
    let awg: Shared<dyn Awg> = safe_state::share(Box::new(awg) as Box<dyn Awg>);
    let tx: Option<Shared<dyn RfFrontEnd>> =
        tx.map(|g| safe_state::share(Box::new(g) as Box<dyn RfFrontEnd>));
    let rx: Option<Shared<dyn RfFrontEnd>> =
        rx.map(|g| safe_state::share(Box::new(g) as Box<dyn RfFrontEnd>));
    let safe = SafeState::new(
        safe_state::Bench {
            tx: tx.clone(),
            rx: rx.clone(),
            awg: Some(awg.clone()),
        },
        Duration::from_secs(5),
    );
    Ok(Connected {
        awg,
        scope: Box::new(scope),
        tx,
        rx,
        identities,
        safe,
    })
}

/// How to drive the bench for one capture.
#[derive(Debug)]
pub struct CaptureSettings {
    pub awg: AwgSettings,
    pub scope: DigitizerSettings,
    pub tx: RfSettings,
    pub rx: RfSettings,
    /// The user's explicit permit to switch on the AWG outputs and the front ends.
    pub permit: Option<RfPermit>,
    /// Leave the transmitter off (noise floor / leakage checks); the receiver still runs.
    pub tx_off: bool,
    /// How long to wait for the marker-triggered acquisition, seconds.
    pub wait_s: f64,
}

/// What the instruments did for the capture.
#[derive(Debug, Clone, Serialize)]
pub struct Applied {
    pub awg: AwgApplied,
    pub segment: LoadedSegment,
    pub scope: DigitizerApplied,
    pub tx: Option<RfStatus>,
    pub rx: Option<RfStatus>,
}

/// One raw capture and how it was made.
pub struct Captured {
    pub iq: IqCapture,
    pub applied: Applied,
}

impl Captured {
    /// I + jQ in volts with the time of the first point after the trigger.
    pub fn raw(&self) -> RawIq {
        let i = self.iq.i.volts();
        let q = self.iq.q.volts();
        RawIq {
            samples: i
                .iter()
                .zip(&q)
                .map(|(a, b)| Complex64::new(*a, *b))
                .collect(),
            // WAVEDESC stores the interval as f32: take the rate the scope reported applying.
            sample_rate_hz: self.applied.scope.sample_rate_hz,
            first_point_s: self.iq.i.first_sample_s(),
        }
    }
}

/// Configures, enables (with the permit), captures one repetition, then puts the bench in its safe
/// state, also when `interrupt` fires first (the CLI passes Ctrl-C).
pub async fn capture<I>(
    bench: &mut Connected,
    tx: &Transmission,
    settings: &CaptureSettings,
    interrupt: impl Future<Output = I>,
) -> (Result<Captured, MeasureError>, SafeStateReport) {
    let safe = bench.safe.clone();
    let work = capture_unguarded(bench, tx, settings);
    let (outcome, report) = crate::driver::run_guarded(&safe, work, interrupt).await;
    let result = match outcome {
        Outcome::Finished(r) => r,
        Outcome::Interrupted => Err(MeasureError::Interrupted(report.to_string())),
    };
    (result, report)
}

async fn capture_unguarded(
    bench: &mut Connected,
    tx: &Transmission,
    settings: &CaptureSettings,
) -> Result<Captured, MeasureError> {
    let (awg_applied, segment) = {
        let mut awg = bench.awg.lock().await;
        let applied = awg.configure(&settings.awg).await?;
        let segment = awg.load(&tx.iq).await?;
        (applied, segment)
    };
    let mut scope_settings = settings.scope.clone();
    scope_settings.repetition_s = segment.padded_samples as f64 / tx.sample_rate_hz;
    let scope_applied = bench.scope.configure(&scope_settings).await?;
    let mut rx_status = None;
    let mut tx_status = None;
    if let Some(permit) = &settings.permit {
        if let Some(rx) = &bench.rx {
            rx_status = Some(rx.lock().await.enable(permit, &settings.rx).await?);
        }
        if let Some(txm) = &bench.tx {
            if !settings.tx_off {
                tx_status = Some(txm.lock().await.enable(permit, &settings.tx).await?);
            }
        }
        let mut awg = bench.awg.lock().await;
        awg.enable_outputs(permit).await?;
        awg.run().await?;
    } else {
        return Err(MeasureError::Param(
            "the AWG outputs and the front ends stay off without an explicit permit: pass \
             --allow-rf to switch them on for this capture"
                .into(),
        ));
    }
    let iq = bench.scope.capture_iq(settings.wait_s).await?;
    if tx_status.is_none() {
        if let Some(txm) = &bench.tx {
            tx_status = Some(txm.lock().await.status().await?);
        }
    }
    Ok(Captured {
        iq,
        applied: Applied {
            awg: awg_applied,
            segment,
            scope: scope_applied,
            tx: tx_status,
            rx: rx_status,
        },
    })
}
