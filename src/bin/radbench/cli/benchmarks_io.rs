//! `radbench bench io ADDRESS...`: moves a block to and from instruments that store one with
//! `DATA <block>` and return it with `DATA?` (mock-lab's loopback instrument), and reports MB/s.
//!
//! Per address: one untimed warm-up each way, then `--runs` timed uploads (`DATA #8<bytes>`
//! followed by `*OPC?`, so the instrument holds every byte), then `--runs` timed downloads
//! (`DATA?`). Every download is compared byte for byte with the payload after its timer stops.
//! The payload is SplitMix64 (`--seed`) as little-endian words; its SHA-256 is reported, so
//! another client (benches/compare_pyvisa.py) can check it moves exactly the same bytes.

use radbench::address::Resource;
use radbench::exit::bad_input;
use radbench::session::{BlockForm, Session, SessionError, SessionOptions};
use sha2::{Digest, Sha256};
use std::time::{Duration, Instant};

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Resource strings, e.g. TCPIP::127.0.0.1::5025::SOCKET, TCPIP::127.0.0.1::hislip0,4880::INSTR.
    #[arg(value_name = "ADDRESS", required = true)]
    pub addresses: Vec<String>,
    /// Block size in bytes.
    #[arg(long, default_value_t = 64 << 20, value_name = "BYTES")]
    pub size: usize,
    /// Timed runs per address and direction (the median is reported).
    #[arg(long, default_value_t = 7, value_name = "N")]
    pub runs: usize,
    /// Seed of the payload (SplitMix64).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Print one JSON object instead of a table.
    #[arg(long)]
    pub json: bool,
    /// Seconds allowed for a reply to start (the block itself gets its size at 10 MB/s on top).
    #[arg(long, default_value_t = 10.0, value_name = "SECONDS")]
    pub timeout: f64,
}

/// Throughput of one address in one direction.
#[derive(Debug, Clone, serde::Serialize)]
pub(crate) struct Measurement {
    pub address: String,
    pub protocol: &'static str,
    /// "read" (instrument to radbench) or "write" (radbench to instrument).
    pub direction: &'static str,
    pub bytes: usize,
    /// Decimal megabytes (1e6 bytes) per second.
    pub median_mb_s: f64,
    pub min_mb_s: f64,
    pub max_mb_s: f64,
    /// Every timed run, in seconds.
    pub seconds: Vec<f64>,
}

/// The payload: `len` bytes of SplitMix64 words, little-endian.
pub(crate) fn payload(len: usize, seed: u64) -> Vec<u8> {
    let mut rng = radbench::rng::SplitMix64::new(seed);
    let mut out = Vec::with_capacity(len + 8);
    while out.len() < len {
        out.extend_from_slice(&rng.next_u64().to_le_bytes());
    }
    out.truncate(len);
    out
}

fn sha256_hex(bytes: &[u8]) -> String {
    Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

fn summarise(
    address: &str,
    protocol: &'static str,
    direction: &'static str,
    bytes: usize,
    times: &[Duration],
) -> Measurement {
    let seconds: Vec<f64> = times.iter().map(Duration::as_secs_f64).collect();
    let rate = |s: f64| bytes as f64 / s.max(1e-9) / 1e6;
    let mut sorted = seconds.clone();
    sorted.sort_by(f64::total_cmp);
    let n = sorted.len();
    let median = if n % 2 == 1 {
        sorted[n / 2]
    } else {
        (sorted[n / 2 - 1] + sorted[n / 2]) / 2.0
    };
    Measurement {
        address: address.to_string(),
        protocol,
        direction,
        bytes,
        median_mb_s: rate(median),
        min_mb_s: rate(sorted[n - 1]),
        max_mb_s: rate(sorted[0]),
        seconds,
    }
}

async fn upload(session: &mut Session, data: &[u8]) -> anyhow::Result<()> {
    session
        .write_block("DATA ", data, BlockForm::Definite)
        .await?;
    session.opc().await?;
    Ok(())
}

/// Downloads once and checks the bytes (after the timer, which the caller stops first).
async fn download(session: &mut Session) -> anyhow::Result<bytes::Bytes> {
    Ok(session.query_block("DATA?").await?.into_payload())
}

fn check(address: &str, got: &[u8], want: &[u8]) -> anyhow::Result<()> {
    if got != want {
        anyhow::bail!(
            "{address}: DATA? returned {} bytes that differ from the {} bytes uploaded; is this \
             mock-lab's loopback instrument?",
            got.len(),
            want.len()
        );
    }
    Ok(())
}

/// What `bench io` needs of the instrument, said when the instrument refuses it.
const NEEDS_LOOPBACK: &str =
    "bench io needs an instrument that stores a block with `DATA <block>` \
and returns it with `DATA?`: the mock lab's loopback instrument (`radbench mock-lab serve \
--with-loopback` prints its addresses)";

/// Adds [`NEEDS_LOOPBACK`] to a refusal by the instrument (e.g. an AWG's -113 for `DATA?`).
fn explain_refusal(address: &str, result: anyhow::Result<()>) -> anyhow::Result<()> {
    result.map_err(|e| {
        let refused = e
            .downcast_ref::<SessionError>()
            .is_some_and(|s| s.device_errors().is_some());
        if refused {
            e.context(format!("{address}: {NEEDS_LOOPBACK}"))
        } else {
            e
        }
    })
}

async fn measure(
    address: &str,
    data: &[u8],
    runs: usize,
    timeout: Duration,
) -> anyhow::Result<(Measurement, Measurement)> {
    let resource: Resource = address.parse()?;
    let protocol = resource.protocol();
    let mut options = SessionOptions::default();
    options.link.timeouts.read = timeout;
    options.link.max_message_bytes = options.link.max_message_bytes.max(data.len() + 4096);
    let mut session = Session::open(resource, options, None, "bench").await?;
    // An instrument of the catalog (an AWG, a scope, a module) has no loopback commands: say so
    // at once rather than after a block and a reply timeout.
    if let Ok(idn) = session.query("*IDN?").await {
        let catalog = radbench::catalog::Catalog::embedded()?;
        if let Some(found) = catalog.identify(&idn) {
            let _ = session.close().await;
            return Err(bad_input(format!(
                "{address} is a {} ({}), not a loopback instrument: {NEEDS_LOOPBACK}",
                found.model.instrument.key,
                idn.trim()
            )));
        }
    }
    // Warm-up: connections, buffers and the instrument's stored block exist before timing. An
    // instrument without the loopback commands refuses here (`DATA?` goes unanswered and its
    // error queue says why).
    let warm = async {
        upload(&mut session, data).await?;
        let warm = download(&mut session).await?;
        check(address, &warm, data)
    };
    explain_refusal(address, warm.await)?;

    let mut writes = Vec::with_capacity(runs);
    for _ in 0..runs {
        let started = Instant::now();
        upload(&mut session, data).await?;
        writes.push(started.elapsed());
    }
    let mut reads = Vec::with_capacity(runs);
    for _ in 0..runs {
        let started = Instant::now();
        let block = download(&mut session).await?;
        reads.push(started.elapsed());
        // The download also proves the last upload arrived whole.
        check(address, &block, data)?;
    }
    let _ = session.close().await;
    Ok((
        summarise(address, protocol, "read", data.len(), &reads),
        summarise(address, protocol, "write", data.len(), &writes),
    ))
}

pub(crate) fn run(args: Args, global: &super::global::Global) -> anyhow::Result<()> {
    if args.runs == 0 {
        return Err(bad_input("--runs must be at least 1"));
    }
    if !(args.timeout.is_finite() && args.timeout > 0.0 && args.timeout <= 86_400.0) {
        return Err(bad_input(format!(
            "--timeout {}: give a number of seconds between 0 and 86400",
            args.timeout
        )));
    }
    let timeout = Duration::from_secs_f64(args.timeout);
    if args.size == 0 || args.size > 1 << 30 {
        return Err(bad_input(format!(
            "--size {}: give a block size between 1 byte and 1 GiB",
            args.size
        )));
    }
    for address in &args.addresses {
        address
            .parse::<Resource>()
            .map_err(|e| bad_input(format!("{address}: {e}")))?;
    }
    if global.trace_io.is_some() {
        // Journalling 64 MB messages would time the journal, not the link.
        eprintln!("radbench bench io: --trace-io is ignored (the journal would be timed too)");
    }
    let data = std::sync::Arc::new(payload(args.size, args.seed));
    let runtime = super::global::runtime()?;
    let mut results = Vec::new();
    for address in &args.addresses {
        // On a worker thread, the task that waits for the socket runs where tokio's I/O driver
        // wakes it; awaited from block_on, every readiness event would also hand over to the
        // main thread (measured: reads 20-50 % slower on this 2-core machine).
        let (address, payload, runs) = (address.clone(), data.clone(), args.runs);
        let task = runtime.spawn(async move { measure(&address, &payload, runs, timeout).await });
        let (read, write) = runtime.block_on(task)??;
        results.push(read);
        results.push(write);
    }
    if args.json {
        let doc = serde_json::json!({
            "bytes": args.size,
            "runs": args.runs,
            "seed": args.seed,
            "payload_sha256": sha256_hex(&data),
            "results": results,
        });
        println!("{}", serde_json::to_string_pretty(&doc)?);
    } else {
        println!(
            "{:<8} {:<6} {:>11} {:>9} {:>9}  address",
            "protocol", "dir", "median MB/s", "min", "max"
        );
        for m in &results {
            println!(
                "{:<8} {:<6} {:>11.0} {:>9.0} {:>9.0}  {}",
                m.protocol, m.direction, m.median_mb_s, m.min_mb_s, m.max_mb_s, m.address
            );
        }
        println!(
            "{} bytes per transfer, {} timed runs each way after one warm-up; every download \
             checked against the payload (SHA-256 {}).",
            args.size,
            args.runs,
            sha256_hex(&data)
        );
    }
    Ok(())
}
