//! `--live`, `--port`, `--listen`: the live view of `capture --repeat`, `campaign run|resume` and
//! `align` (the server is `crate::live`; this wires it to the interrupt, the drivers' RF state
//! and the campaign's observer).

use crate::live::{Event, Live, Options};
use radbench::campaign::Step;
use radbench::campaign::{Observer, Retrying, StepDone};
use radbench::exit::bad_input;
use radbench::measure::Bench;
use radbench::measure::{Interrupt, StopSignal};
use serde_json::{json, Value};
use std::net::{IpAddr, Ipv4Addr, SocketAddr};
use std::time::Duration;

/// How long the end of a measurement waits for the browsers that keep up to receive its last
/// state (a stalled one is not waited for).
const LINGER: Duration = Duration::from_secs(1);

#[derive(Debug, Clone, Default, clap::Args)]
pub struct LiveArgs {
    /// Serve a live view in the browser while this runs: the latest range profile, the steps,
    /// the bench's RF state, warnings, and a Stop button that does what Ctrl-C does. On
    /// 127.0.0.1; the URL (with its token) is printed on stderr.
    #[arg(long)]
    pub live: bool,
    /// The live view's port (default: a free one the system picks).
    #[arg(long, value_name = "PORT", requires = "live")]
    pub port: Option<u16>,
    /// Serve the live view on this address instead of 127.0.0.1 (for example 0.0.0.0: every
    /// interface). Anyone who can reach it and has the URL's token can see the page and press
    /// Stop; a warning says so.
    #[arg(long, value_name = "ADDR", requires = "live")]
    pub listen: Option<IpAddr>,
}

impl LiveArgs {
    /// Starts the live view when `--live` asks for it (inside the runtime), says where on stderr
    /// and, with `json`, as a `{"event":"live","url":...}` line on stdout.
    pub(crate) async fn start(
        &self,
        interrupt: &Interrupt,
        json: bool,
    ) -> anyhow::Result<Option<Live>> {
        if !self.live {
            return Ok(None);
        }
        let ip = self.listen.unwrap_or(IpAddr::V4(Ipv4Addr::LOCALHOST));
        let addr = SocketAddr::new(ip, self.port.unwrap_or(0));
        let stop = interrupt.clone();
        let live = Live::start(Options {
            listen: addr,
            on_stop: Box::new(move || {
                eprintln!("Stop pressed on the live page: stopping as on Ctrl-C");
                stop.raise(StopSignal::Interrupt);
            }),
            bench_state: Box::new(radbench::driver::snapshot),
        })
        .await
        .map_err(|e| {
            let what = match (self.listen, self.port) {
                (Some(ip), Some(p)) => format!("--listen {ip} --port {p}"),
                (Some(ip), None) => format!("--listen {ip}"),
                (None, Some(p)) => format!("--port {p}"),
                (None, None) => "--live".into(),
            };
            bad_input(format!(
                "{what}: cannot serve the live view on {addr}: {e} (a port in use: give another \
                 --port, or none for a free one; --listen takes an address of this machine)"
            ))
        })?;
        if let Some(warning) = beyond_loopback_warning(ip) {
            eprintln!("{warning}");
        }
        eprintln!(
            "live view: {} (Stop on the page does what Ctrl-C does)",
            live.url()
        );
        if json {
            println!("{}", json!({"event": "live", "url": live.url()}));
        }
        Ok(Some(live))
    }
}

/// The warning `--listen ip` prints when `ip` is not a loopback address: who can reach the page,
/// and that the traffic is not encrypted.
fn beyond_loopback_warning(ip: std::net::IpAddr) -> Option<String> {
    if ip.is_loopback() {
        return None;
    }
    Some(format!(
        "WARNING: --listen {ip}: the live view is served beyond this machine's loopback; whoever \
         can reach {ip} and has the URL below (its token) can watch and press Stop. The traffic \
         is not encrypted.{}",
        if ip.is_unspecified() {
            " From another machine, put this machine's address in place of 127.0.0.1."
        } else {
            ""
        }
    ))
}

/// Publishes `event` when there is a live view.
pub(crate) fn send(live: Option<&Live>, event: Event) {
    if let Some(live) = live {
        live.send(event);
    }
}

/// Tells the page, once, what every capture on `bench` warns of (it is not calibrated).
pub(crate) fn bench_warnings(live: Option<&Live>, bench: &Bench) {
    if let Some(w) = bench.file.uncalibrated_warning() {
        send(live, Event::Log("warning", w));
    }
}

/// Capture `k`'s warnings on the page, without the bench's (told once by [`bench_warnings`]).
pub(crate) fn capture_warnings(live: &Live, bench: &Bench, k: u64, warnings: &[String]) {
    let told = bench.file.uncalibrated_warning();
    for w in warnings.iter().filter(|w| Some(*w) != told.as_ref()) {
        live.send(Event::Log("warning", format!("capture {k}: {w}")));
    }
}

/// The end: the status published, the browsers that keep up given a moment, the server stopped.
pub(crate) async fn finish(live: Option<Live>, status: &str, error: Option<&anyhow::Error>) {
    if let Some(live) = live {
        if let Some(e) = error {
            live.send(Event::Log("error", format!("{e:#}")));
        }
        live.finish(status, LINGER).await;
        let s = live.stats();
        tracing::info!(
            frames = s.frames,
            skipped = s.skipped,
            dropped_events = s.dropped_events,
            forgotten = s.forgotten,
            refused = s.refused,
            "live view closed"
        );
        // The counters, always: what the page was sent and what a slow browser or a full queue
        // cost it (never the measurement).
        eprintln!(
            "live view closed: {} frames published, {} skipped by slow browsers, {} events \
             dropped (queue full), {} browsers gone, {} requests refused",
            s.frames, s.skipped, s.dropped_events, s.forgotten, s.refused
        );
    }
}

/// The status a finished command shows on the page.
pub(crate) fn status_of(result: &anyhow::Result<()>, interrupt: &Interrupt) -> &'static str {
    match (result, interrupt.received()) {
        (Ok(()), _) => "complete",
        (Err(_), Some(_)) => "interrupted",
        (Err(_), None) => "failed",
    }
}

/// The campaign's observer, with the live view told the same.
pub(crate) struct LiveObserver<'a> {
    pub inner: &'a mut dyn Observer,
    pub live: Option<Live>,
}

impl LiveObserver<'_> {
    fn send(&self, event: Event) {
        send(self.live.as_ref(), event);
    }
}

/// A step's row of the page's table (and its point of the campaign's plot).
fn step_row(done: &StepDone<'_>) -> Value {
    let r = done.result;
    let primary = r.algorithms.get(done.primary);
    let ranges: Vec<f64> = primary
        .map(|a| a.targets.iter().map(|t| t.range_m).collect())
        .unwrap_or_default();
    let error_mm = primary.and_then(|a| a.error_m).map(|e| e * 1e3);
    let bits = primary
        .and_then(|a| a.payload.as_ref())
        .map(|p| format!("{} errors in {}", p.bit_errors, p.bits));
    json!({
        "index": r.index,
        "nominal": r.nominal.describe(),
        "ranges": ranges,
        "error_mm": error_mm,
        "bits": bits,
        "skipped": done.skipped,
        "x": r.nominal.value.unwrap_or(r.index as f64),
        "y": error_mm.or(ranges.first().copied()),
    })
}

impl Observer for LiveObserver<'_> {
    fn step_starting(&mut self, step: &Step, of: usize, bench: &Bench) {
        self.inner.step_starting(step, of, bench);
        self.send(Event::Set("of", json!(of)));
        // The swept parameter names the plot's x axis (a resume learns it here).
        self.send(Event::Set(
            "plot_axes",
            campaign_axes(step.nominal.parameter.map(|p| p.name())),
        ));
        self.send(Event::Set(
            "current",
            json!(format!(
                "step {}/{of}: {} (capturing)",
                step.index,
                step.nominal.describe()
            )),
        ));
    }

    fn step_done(&mut self, done: &StepDone<'_>) {
        self.inner.step_done(done);
        if self.live.is_none() {
            return;
        }
        let r = done.result;
        self.send(Event::Set("of", json!(done.of)));
        let primary = r.algorithms.get(done.primary);
        let detections = primary
            .map(|a| a.targets.iter().map(|t| (t.range_m, t.level_db)).collect())
            .unwrap_or_default();
        let truth = r
            .truth
            .as_ref()
            .map(|t| t.targets.iter().map(|x| x.range_m).collect())
            .unwrap_or_default();
        self.send(Event::Row(step_row(done)));
        // A detection taken for the chain's echo: the calibration's warning, as the capture says it.
        for e in primary
            .map(|a| a.chain_echoes.as_slice())
            .unwrap_or_default()
        {
            let text = format!("step {}/{}: {}", r.index, done.of, e.describe());
            self.send(Event::Log("warning", text));
        }
        self.send(Event::ProfileFile {
            csv: done.dir.join("profile.csv"),
            detections,
            truth,
            label: format!("step {}/{}", r.index, done.of),
        });
    }

    fn note(&mut self, text: &str) {
        self.inner.note(text);
        let level = if text.to_lowercase().contains("warning") {
            "warning"
        } else {
            "note"
        };
        self.send(Event::Log(level, text.to_string()));
    }

    fn retrying(&mut self, retry: &Retrying<'_>) {
        self.inner.retrying(retry);
        let r = retry.record;
        // The page's log lists it (a retry's own colour), and the current line says it.
        self.send(Event::Log("retry", retry.text.to_string()));
        self.send(Event::Set(
            "current",
            json!(format!(
                "step {}/{}: {} failed ({}); retry {} of {} in {:.1} s",
                r.step, retry.of, r.instrument, r.fault, r.attempt, retry.retries, r.wait_s
            )),
        ));
    }
}

/// The page's axes of a campaign's plot.
pub(crate) fn campaign_axes(parameter: Option<&str>) -> Value {
    // The page names the y axis: the error where every step has one, else the first target.
    json!({ "x": parameter.unwrap_or("step") })
}

#[cfg(test)]
mod tests {
    use super::beyond_loopback_warning;

    /// Tested without binding: a test serves on loopback only.
    #[test]
    fn only_an_address_beyond_loopback_is_warned_about() {
        for quiet in ["127.0.0.1", "127.0.0.2", "::1"] {
            assert_eq!(
                beyond_loopback_warning(quiet.parse().unwrap()),
                None,
                "{quiet}"
            );
        }
        // The unspecified address is only classified here, never bound.
        let all = beyond_loopback_warning(std::net::Ipv4Addr::UNSPECIFIED.into()).unwrap();
        assert!(all.starts_with("WARNING: --listen 0.0.0.0"), "{all}");
        assert!(all.contains("not encrypted") && all.contains("in place of 127.0.0.1"));
        let lan = beyond_loopback_warning("192.0.2.7".parse().unwrap()).unwrap();
        assert!(lan.contains("--listen 192.0.2.7") && lan.contains("not encrypted"));
        assert!(!lan.contains("in place of"), "{lan}");
        let v6 = beyond_loopback_warning(std::net::Ipv6Addr::UNSPECIFIED.into()).unwrap();
        assert!(v6.contains("in place of 127.0.0.1"), "{v6}");
    }
}
