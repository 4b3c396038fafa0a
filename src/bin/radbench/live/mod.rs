//! The live view: a small HTTP server on the measurement's side that serves one self-contained
//! page (its script and styles are inside the binary) and a stream of the measurement's state
//! (Server-Sent Events), and a Stop button that does what Ctrl-C does.
//!
//! The measurement never waits for it. Producers hand [`Event`]s to a bounded queue with
//! `try_send` (a full queue drops the event and counts it); one composer task folds them into the
//! page's state and publishes each state as a numbered frame on a watch channel, which keeps only
//! the newest. Each browser's task sends the newest frame when its socket takes it: a slow or
//! stalled browser skips frames (counted), one whose socket takes nothing for
//! [`WRITE_TIMEOUT`] is dropped, and one that closes its connection is forgotten at once.
//!
//! Every request needs the random token of the printed URL (`?token=`): without it, or with
//! another one, the answer is 403 and nothing changes.

use serde_json::{json, Map, Value};
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::{mpsc, watch};

#[cfg(test)]
mod tests;

/// The page: HTML, script and styles in one file, nothing fetched from anywhere else.
const PAGE: &str = include_str!("page.html");

/// Events waiting for the composer; more are dropped (and counted), never waited for.
const QUEUE: usize = 64;
/// A browser whose socket takes nothing for this long is dropped.
pub(crate) const WRITE_TIMEOUT: Duration = Duration::from_secs(5);
/// How often the composer looks at the bench state (RF on or off) for a change.
const TICK: Duration = Duration::from_millis(100);
/// The most warnings and errors the page keeps.
const LOG_LINES: usize = 20;
/// The most points of a profile sent to the page (the largest value of each bin is kept).
const PROFILE_POINTS: usize = 1200;
/// Longest request head a browser may send.
const HEAD_LIMIT: usize = 16 * 1024;

/// What changed, as the measurement tells it.
#[derive(Debug)]
pub(crate) enum Event {
    /// Sets a top-level key of the page's state (`kind`, `title`, `status`, `current`,
    /// `align`, `of`, `profile`, ...).
    Set(&'static str, Value),
    /// A finished step: its row of the steps table (replaces a row of the same `index`).
    Row(Value),
    /// A warning, an error or a campaign's retry (`level` "warning", "error", "note" or
    /// "retry"; each retry also counts in the state's `retries`).
    Log(&'static str, String),
    /// The profile written to this `profile.csv` (read by the composer, off the measurement's
    /// path), with the detections and the simulated truth to draw on it.
    ProfileFile {
        csv: PathBuf,
        detections: Vec<(f64, f64)>,
        truth: Vec<f64>,
        label: String,
    },
}

/// Where and how to serve.
pub(crate) struct Options {
    pub listen: SocketAddr,
    /// What the Stop button does (the CLI raises the interrupt Ctrl-C raises).
    pub on_stop: Box<dyn Fn() + Send + Sync>,
    /// The bench's RF state per instrument (name, on), as the drivers last set it.
    pub bench_state: Box<dyn Fn() -> Vec<(String, bool)> + Send + Sync>,
}

/// Counters of the server, for tests and the final note.
#[derive(Debug, Default)]
struct Counters {
    /// Frames published.
    frames: AtomicU64,
    /// Frames a browser skipped because its socket had not taken the one before.
    skipped: AtomicU64,
    /// Events dropped because the composer's queue was full.
    dropped_events: AtomicU64,
    /// Browsers connected to the stream now.
    clients: AtomicUsize,
    /// Browsers dropped or gone.
    forgotten: AtomicU64,
    /// Requests refused for their token.
    refused: AtomicU64,
    /// Stop requests carried out.
    stops: AtomicU64,
}

/// A snapshot of the counters.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub(crate) struct Stats {
    pub frames: u64,
    pub skipped: u64,
    pub dropped_events: u64,
    pub clients: usize,
    pub forgotten: u64,
    pub refused: u64,
    pub stops: u64,
}

struct Shared {
    token: String,
    counters: Counters,
    /// The browsers on the stream: what each was sent, whether a write is under way.
    clients: Mutex<Vec<std::sync::Weak<Client>>>,
    frames: watch::Receiver<Frame>,
    on_stop: Box<dyn Fn() + Send + Sync>,
}

/// One published state: its number and its JSON text.
#[derive(Clone)]
struct Frame {
    seq: u64,
    json: Arc<str>,
}

/// The running live view; cheap to clone. Dropping the last handle does not stop the server:
/// [`Live::finish`] does.
#[derive(Clone)]
pub(crate) struct Live {
    events: mpsc::Sender<(Event, f64)>,
    shared: Arc<Shared>,
    url: String,
    #[cfg_attr(not(test), allow(dead_code))]
    addr: SocketAddr,
    tasks: Arc<Mutex<Vec<tokio::task::JoinHandle<()>>>>,
}

impl Live {
    /// Binds `options.listen` (inside a tokio runtime) and starts serving.
    pub(crate) async fn start(options: Options) -> std::io::Result<Live> {
        let listener = TcpListener::bind(options.listen).await?;
        let addr = listener.local_addr()?;
        let token = random_token();
        let host = if addr.ip().is_unspecified() {
            "127.0.0.1".to_string()
        } else if addr.is_ipv6() {
            format!("[{}]", addr.ip())
        } else {
            addr.ip().to_string()
        };
        let url = format!("http://{host}:{}/?token={token}", addr.port());
        let (events_tx, events_rx) = mpsc::channel(QUEUE);
        let (frames_tx, frames_rx) = watch::channel(Frame {
            seq: 0,
            json: Arc::from("{}"),
        });
        let shared = Arc::new(Shared {
            token,
            counters: Counters::default(),
            clients: Mutex::new(Vec::new()),
            frames: frames_rx,
            on_stop: options.on_stop,
        });
        let composer = tokio::spawn(compose(
            events_rx,
            frames_tx,
            options.bench_state,
            shared.clone(),
        ));
        let server = tokio::spawn(serve(listener, shared.clone()));
        Ok(Live {
            events: events_tx,
            shared,
            url,
            addr,
            tasks: Arc::new(Mutex::new(vec![composer, server])),
        })
    }

    /// The page's address with its token.
    pub(crate) fn url(&self) -> &str {
        &self.url
    }

    /// The address served.
    #[cfg(test)]
    pub(crate) fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// The token every request needs.
    #[cfg(test)]
    pub(crate) fn token(&self) -> &str {
        &self.shared.token
    }

    /// Hands `event` to the composer without waiting: a full queue drops it (counted). The
    /// event carries the wall-clock time it was handed over, so the page can tell how long it
    /// took to show it (`event_unix_ms` of the frame).
    pub(crate) fn send(&self, event: Event) {
        if self.events.try_send((event, unix_ms())).is_err() {
            self.shared
                .counters
                .dropped_events
                .fetch_add(1, Ordering::Relaxed);
        }
    }

    pub(crate) fn stats(&self) -> Stats {
        let c = &self.shared.counters;
        // A browser still connected but behind (a stalled one whose socket is full) will never
        // get the frames between the one it was last given and the newest: skipped already.
        let newest = self.shared.frames.borrow().seq;
        let behind: u64 = self
            .shared
            .clients
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .iter()
            .filter_map(std::sync::Weak::upgrade)
            .map(|c| newest.saturating_sub(c.accounted.load(Ordering::Relaxed) + 1))
            .sum();
        Stats {
            frames: c.frames.load(Ordering::Relaxed),
            skipped: c.skipped.load(Ordering::Relaxed) + behind,
            dropped_events: c.dropped_events.load(Ordering::Relaxed),
            clients: c.clients.load(Ordering::Relaxed),
            forgotten: c.forgotten.load(Ordering::Relaxed),
            refused: c.refused.load(Ordering::Relaxed),
            stops: c.stops.load(Ordering::Relaxed),
        }
    }

    /// The end of the measurement: `status` published, then up to `linger` for the browsers that
    /// keep up to receive it (a stalled one is not waited for), then the server stops.
    pub(crate) async fn finish(&self, status: &str, linger: Duration) {
        self.send(Event::Set("status", json!(status)));
        let deadline = Instant::now() + linger;
        // The composer publishes the status within a tick; then each browser's task sends it. A
        // browser whose socket is full (a write under way) is not waited for.
        while Instant::now() < deadline {
            let frame = self.shared.frames.borrow().clone();
            if frame.json.contains("\"final\":true") {
                let clients = self
                    .shared
                    .clients
                    .lock()
                    .unwrap_or_else(|p| p.into_inner());
                let waiting = clients
                    .iter()
                    .filter_map(std::sync::Weak::upgrade)
                    .any(|c| {
                        c.sent.load(Ordering::Relaxed) < frame.seq
                            && !c.writing.load(Ordering::Relaxed)
                    });
                if !waiting {
                    break;
                }
            }
            tokio::time::sleep(Duration::from_millis(10)).await;
        }
        for task in self
            .tasks
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .drain(..)
        {
            task.abort();
        }
    }
}

/// Milliseconds since the Unix epoch (the browser's `Date.now()` counts the same).
fn unix_ms() -> f64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64() * 1e3)
}

/// 128 random bits as hex, from the kernel.
fn random_token() -> String {
    use std::io::Read;
    let mut bytes = [0u8; 16];
    if std::fs::File::open("/dev/urandom")
        .and_then(|mut f| f.read_exact(&mut bytes))
        .is_err()
    {
        // No /dev/urandom: the clock's nanoseconds and the process id, mixed (SplitMix64).
        let mut x = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_nanos() as u64)
            ^ u64::from(std::process::id()).rotate_left(32);
        for chunk in bytes.chunks_mut(8) {
            x = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = x;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            chunk.copy_from_slice(&(z ^ (z >> 31)).to_le_bytes());
        }
    }
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// The composer: folds events into the state and publishes it.
async fn compose(
    mut events: mpsc::Receiver<(Event, f64)>,
    frames: watch::Sender<Frame>,
    bench_state: Box<dyn Fn() -> Vec<(String, bool)> + Send + Sync>,
    shared: Arc<Shared>,
) {
    let started = Instant::now();
    let mut state = Map::new();
    state.insert("status".into(), json!("running"));
    state.insert("steps".into(), json!([]));
    state.insert("log".into(), json!([]));
    let mut bench = Vec::new();
    let mut seq = 0u64;
    let mut tick = tokio::time::interval(TICK);
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    let mut dirty = true;
    loop {
        // The oldest event folded into this frame: when it was handed over.
        let mut oldest: Option<f64> = None;
        tokio::select! {
            e = events.recv() => match e {
                Some((e, at)) => {
                    oldest = Some(at);
                    apply(&mut state, e).await;
                    dirty = true;
                }
                None => break,
            },
            _ = tick.tick() => {}
        }
        // Everything queued meanwhile goes into the same frame.
        while let Ok((e, at)) = events.try_recv() {
            oldest = Some(oldest.map_or(at, |o| o.min(at)));
            apply(&mut state, e).await;
            dirty = true;
        }
        let now = bench_state();
        if now != bench {
            bench = now;
            dirty = true;
        }
        if !dirty {
            continue;
        }
        dirty = false;
        seq += 1;
        let elapsed = started.elapsed().as_secs_f64();
        state.insert("seq".into(), json!(seq));
        state.insert("elapsed_s".into(), json!(elapsed));
        state.insert("eta_s".into(), eta(&state, elapsed));
        state.insert(
            "bench".into(),
            Value::Array(
                bench
                    .iter()
                    .map(|(name, on)| json!({"instrument": name, "rf_on": on}))
                    .collect(),
            ),
        );
        let status = state["status"].as_str().unwrap_or("running");
        state.insert("final".into(), json!(status != "running"));
        // For the page's latency record: when the oldest event of this frame was handed over
        // (null for a frame of the bench state alone) and when the frame was published.
        state.insert(
            "event_unix_ms".into(),
            oldest.map_or(Value::Null, |t| json!(t.round())),
        );
        state.insert("published_unix_ms".into(), json!(unix_ms().round()));
        // Serialised in place (no copy of the state): the profile alone is thousands of values.
        let text = serde_json::to_string(&state).unwrap_or_else(|_| "{}".into());
        shared.counters.frames.fetch_add(1, Ordering::Relaxed);
        frames.send_replace(Frame {
            seq,
            json: Arc::from(text),
        });
    }
}

/// The time left: the mean time of a finished step times the steps left (campaigns).
fn eta(state: &Map<String, Value>, elapsed: f64) -> Value {
    let of = state.get("of").and_then(Value::as_u64).unwrap_or(0) as f64;
    let done = state
        .get("steps")
        .and_then(Value::as_array)
        .map_or(0, |rows| {
            rows.iter()
                .filter(|r| !r["skipped"].as_bool().unwrap_or(false))
                .count()
        }) as f64;
    let skipped = state
        .get("steps")
        .and_then(Value::as_array)
        .map_or(0, Vec::len) as f64
        - done;
    let left = of - done - skipped;
    if of == 0.0 || done == 0.0 || left < 0.0 || state["status"] != "running" {
        return Value::Null;
    }
    json!(elapsed / done * left)
}

async fn apply(state: &mut Map<String, Value>, event: Event) {
    match event {
        Event::Set(key, value) => {
            state.insert(key.into(), value);
        }
        Event::Row(row) => {
            let rows = state
                .entry("steps")
                .or_insert_with(|| json!([]))
                .as_array_mut();
            if let Some(rows) = rows {
                rows.retain(|r| r["index"] != row["index"]);
                rows.push(row);
                rows.sort_by_key(|r| r["index"].as_u64().unwrap_or(0));
            }
        }
        Event::Log(level, text) => {
            if level == "retry" {
                let n = state.get("retries").and_then(Value::as_u64).unwrap_or(0);
                state.insert("retries".into(), json!(n + 1));
            }
            if let Some(log) = state
                .entry("log")
                .or_insert_with(|| json!([]))
                .as_array_mut()
            {
                log.push(json!({"level": level, "text": text}));
                let n = log.len();
                if n > LOG_LINES {
                    log.drain(..n - LOG_LINES);
                }
            }
        }
        Event::ProfileFile {
            csv,
            detections,
            truth,
            label,
        } => {
            let read = tokio::task::spawn_blocking(move || read_profile_csv(&csv)).await;
            match read {
                Ok(Ok((range, columns))) => {
                    state.insert(
                        "profile".into(),
                        profile_json(&label, &range, &columns, &detections, &truth),
                    );
                }
                Ok(Err(e)) => {
                    tracing::debug!("live view: the profile could not be read: {e}");
                }
                Err(_) => {}
            }
        }
    }
}

/// A profile CSV as radbench writes it: `range_m` then named columns.
type Columns = Vec<(String, Vec<f64>)>;

fn read_profile_csv(path: &Path) -> Result<(Vec<f64>, Columns), String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let mut lines = text.lines();
    let header: Vec<String> = lines
        .next()
        .ok_or("empty")?
        .split(',')
        .map(str::to_string)
        .collect();
    let mut range = Vec::new();
    let mut columns: Columns = header[1..]
        .iter()
        .map(|h| (h.clone(), Vec::new()))
        .collect();
    for line in lines {
        let mut cells = line.split(',');
        let r: f64 = cells
            .next()
            .and_then(|c| c.parse().ok())
            .ok_or("bad range")?;
        range.push(r);
        for (k, cell) in cells.enumerate() {
            if let Some(col) = columns.get_mut(k) {
                col.1.push(cell.parse().unwrap_or(f64::NAN));
            }
        }
    }
    Ok((range, columns))
}

/// The page's profile: the first column as the profile, a `threshold_db` column as the threshold,
/// at most [`PROFILE_POINTS`] points (each bin's largest value, so peaks survive).
pub(crate) fn profile_json(
    label: &str,
    range_m: &[f64],
    columns: &[(String, Vec<f64>)],
    detections: &[(f64, f64)],
    truth: &[f64],
) -> Value {
    let n = range_m.len();
    let bin = n.div_ceil(PROFILE_POINTS).max(1);
    let finite = |v: f64| {
        if v.is_finite() {
            json!(round(v))
        } else {
            Value::Null
        }
    };
    let pooled = |values: &[f64]| -> Vec<Value> {
        values
            .chunks(bin)
            .map(|c| finite(c.iter().copied().fold(f64::NEG_INFINITY, f64::max)))
            .collect()
    };
    let ranges: Vec<Value> = range_m
        .chunks(bin)
        .map(|c| json!(round(c[c.len() / 2])))
        .collect();
    let main = columns
        .iter()
        .find(|(name, _)| name != "threshold_db" && name != "residual_db");
    let threshold = columns.iter().find(|(name, _)| name == "threshold_db");
    json!({
        "label": main.map_or(label.to_string(), |(name, _)| {
            format!("{label}, {}", column_title(name))
        }),
        "range_m": ranges,
        "level_db": main.map(|(_, v)| pooled(v)),
        "threshold_db": threshold.map(|(_, v)| pooled(v)),
        "detections": detections
            .iter()
            .map(|(r, l)| json!({"range_m": r, "level_db": l}))
            .collect::<Vec<_>>(),
        "truth_m": truth,
    })
}

/// A profile column's name as a person reads it: `correlation_db` is `correlation (dB)`.
fn column_title(name: &str) -> String {
    match name.strip_suffix("_db") {
        Some(stem) => format!("{} (dB)", stem.replace('_', " ")),
        None => name.replace('_', " "),
    }
}

fn round(v: f64) -> f64 {
    (v * 1e4).round() / 1e4
}

/// Accepts browsers until the task is aborted.
async fn serve(listener: TcpListener, shared: Arc<Shared>) {
    loop {
        let Ok((stream, _)) = listener.accept().await else {
            continue;
        };
        let shared = shared.clone();
        tokio::spawn(async move {
            let _ = connection(stream, shared).await;
        });
    }
}

/// The parts of a request the server looks at.
struct Request {
    method: String,
    path: String,
    token: Option<String>,
}

async fn read_head(stream: &mut TcpStream) -> std::io::Result<Option<Request>> {
    let mut head = Vec::new();
    let mut buf = [0u8; 2048];
    while !head.windows(4).any(|w| w == b"\r\n\r\n") {
        if head.len() > HEAD_LIMIT {
            return Ok(None);
        }
        let n = tokio::time::timeout(WRITE_TIMEOUT, stream.read(&mut buf))
            .await
            .map_err(|_| std::io::Error::from(std::io::ErrorKind::TimedOut))??;
        if n == 0 {
            return Ok(None);
        }
        head.extend_from_slice(&buf[..n]);
    }
    let text = String::from_utf8_lossy(&head);
    let mut first = text.lines().next().unwrap_or("").split(' ');
    let method = first.next().unwrap_or("").to_string();
    let target = first.next().unwrap_or("");
    let (path, query) = target.split_once('?').unwrap_or((target, ""));
    let token = query
        .split('&')
        .filter_map(|kv| kv.split_once('='))
        .find(|(k, _)| *k == "token")
        .map(|(_, v)| v.to_string());
    Ok(Some(Request {
        method,
        path: path.to_string(),
        token,
    }))
}

/// Compares without stopping at the first difference.
fn same(a: &str, b: &str) -> bool {
    a.len() == b.len() && a.bytes().zip(b.bytes()).fold(0u8, |d, (x, y)| d | (x ^ y)) == 0
}

async fn respond(
    stream: &mut TcpStream,
    status: &str,
    content_type: &str,
    body: &[u8],
) -> std::io::Result<()> {
    let head = format!(
        "HTTP/1.1 {status}\r\nContent-Type: {content_type}\r\nContent-Length: {}\r\n\
         Cache-Control: no-store\r\nX-Content-Type-Options: nosniff\r\n\
         Content-Security-Policy: default-src 'none'; script-src 'unsafe-inline'; \
         style-src 'unsafe-inline'; connect-src 'self'; img-src data:\r\n\
         Connection: close\r\n\r\n",
        body.len()
    );
    tokio::time::timeout(WRITE_TIMEOUT, async {
        stream.write_all(head.as_bytes()).await?;
        stream.write_all(body).await?;
        stream.flush().await
    })
    .await
    .map_err(|_| std::io::Error::from(std::io::ErrorKind::TimedOut))?
}

async fn connection(mut stream: TcpStream, shared: Arc<Shared>) -> std::io::Result<()> {
    let Some(request) = read_head(&mut stream).await? else {
        return Ok(());
    };
    let known = matches!(request.path.as_str(), "/" | "/events" | "/state" | "/stop");
    if !known {
        return respond(&mut stream, "404 Not Found", "text/plain", b"not found\n").await;
    }
    let allowed = request
        .token
        .as_deref()
        .is_some_and(|t| same(t, &shared.token));
    if !allowed {
        shared.counters.refused.fetch_add(1, Ordering::Relaxed);
        return respond(
            &mut stream,
            "403 Forbidden",
            "text/plain",
            b"403: this page needs the token of the URL radbench printed\n",
        )
        .await;
    }
    match (request.method.as_str(), request.path.as_str()) {
        ("GET", "/") => {
            respond(
                &mut stream,
                "200 OK",
                "text/html; charset=utf-8",
                PAGE.as_bytes(),
            )
            .await
        }
        ("GET", "/state") => {
            let json = shared.frames.borrow().json.clone();
            respond(&mut stream, "200 OK", "application/json", json.as_bytes()).await
        }
        ("POST", "/stop") => {
            shared.counters.stops.fetch_add(1, Ordering::Relaxed);
            (shared.on_stop)();
            respond(
                &mut stream,
                "200 OK",
                "application/json",
                b"{\"stopping\":true}\n",
            )
            .await
        }
        ("GET", "/events") => stream_events(stream, shared).await,
        _ => {
            respond(
                &mut stream,
                "405 Method Not Allowed",
                "text/plain",
                b"method not allowed\n",
            )
            .await
        }
    }
}

/// A browser on the stream.
#[derive(Default)]
struct Client {
    /// The newest frame written to its socket.
    sent: AtomicU64,
    /// A write to its socket is under way.
    writing: std::sync::atomic::AtomicBool,
    /// The newest frame given to its socket (being written or written); the ones before it it
    /// did not get are counted as skipped.
    accounted: AtomicU64,
}

/// Counts a browser connected to the stream while it lives.
struct Connected<'a>(&'a Counters);

impl Drop for Connected<'_> {
    fn drop(&mut self) {
        self.0.clients.fetch_sub(1, Ordering::Relaxed);
        self.0.forgotten.fetch_add(1, Ordering::Relaxed);
    }
}

/// Server-Sent Events: the newest frame whenever the socket can take it. The frames published
/// after the last one a browser took, when it goes, count as skipped.
async fn stream_events(stream: TcpStream, shared: Arc<Shared>) -> std::io::Result<()> {
    shared.counters.clients.fetch_add(1, Ordering::Relaxed);
    let _connected = Connected(&shared.counters);
    let me = Arc::new(Client::default());
    {
        let mut clients = shared.clients.lock().unwrap_or_else(|p| p.into_inner());
        clients.retain(|c| c.strong_count() > 0);
        clients.push(Arc::downgrade(&me));
    }
    let outcome = send_frames(stream, &shared, &me).await;
    // Gone: every frame after the last one its socket was given is skipped for it.
    let given = me.accounted.load(Ordering::Relaxed);
    let newest = shared.frames.borrow().seq;
    me.accounted.store(newest, Ordering::Relaxed);
    if newest > given {
        shared
            .counters
            .skipped
            .fetch_add(newest - given, Ordering::Relaxed);
    }
    outcome
}

async fn send_frames(stream: TcpStream, shared: &Shared, me: &Client) -> std::io::Result<()> {
    let (mut reader, mut writer) = stream.into_split();
    let mut text = String::from(
        "HTTP/1.1 200 OK\r\nContent-Type: text/event-stream\r\nCache-Control: no-store\r\n\
         X-Content-Type-Options: nosniff\r\nConnection: keep-alive\r\n\r\n",
    );
    let mut frames = shared.frames.clone();
    let mut scratch = [0u8; 512];
    loop {
        let frame = frames.borrow_and_update().clone();
        let last = me.sent.load(Ordering::Relaxed);
        if frame.seq > last {
            if last > 0 && frame.seq > last + 1 {
                shared
                    .counters
                    .skipped
                    .fetch_add(frame.seq - last - 1, Ordering::Relaxed);
            }
            text.push_str("data: ");
            text.push_str(&frame.json);
            text.push_str("\n\n");
            me.accounted.store(frame.seq, Ordering::Relaxed);
        }
        if !text.is_empty() {
            // A socket that takes nothing for WRITE_TIMEOUT drops the browser.
            me.writing.store(true, Ordering::Relaxed);
            tokio::time::timeout(WRITE_TIMEOUT, writer.write_all(text.as_bytes()))
                .await
                .map_err(|_| std::io::Error::from(std::io::ErrorKind::TimedOut))??;
            me.writing.store(false, Ordering::Relaxed);
            text.clear();
            me.sent.fetch_max(frame.seq, Ordering::Relaxed);
        }
        tokio::select! {
            changed = frames.changed() => {
                if changed.is_err() {
                    return Ok(());
                }
            }
            // The browser closed the connection (or sent something): forget it.
            n = reader.read(&mut scratch) => {
                if n.map_or(true, |n| n == 0) {
                    return Ok(());
                }
            }
        }
    }
}
