//! The scene control channel: a small JSON-lines protocol on 127.0.0.1 that lets campaigns and tests
//! change the scene while the lab runs, and read back the ground truth of the last capture.
//!
//! One request per line, one reply line per request:
//!
//! | request | effect |
//! |---|---|
//! | `{"cmd":"get"}` | reply `{"ok":true,"scene":{...}}` |
//! | `{"cmd":"set","scene":{...}}` | replace the whole scene (validated) |
//! | `{"cmd":"move","target":0,"range_m":1.03}` | move target 0 |
//! | `{"cmd":"add","target":{"range_m":2.0,"amplitude":0.3}}` | add a target; reply has its `"index"` |
//! | `{"cmd":"remove","target":1}` | remove target 1 |
//! | `{"cmd":"snr","snr_db":15.0}` | change the SNR |
//! | `{"cmd":"seed","seed":7}` | restart the noise and jitter generator from this seed |
//! | `{"cmd":"last_capture"}` | `{"ok":true,"captures":N,"scene":{...}}`: the scene of the last capture |
//! | `{"cmd":"scope_remote","interface":"vxi11"}` | switch the scope's remote interface (`vicp` or `vxi11`); replies once only that endpoint accepts connections |
//! | `{"cmd":"endpoints"}` | `{"ok":true,"endpoints":[...]}`: every endpoint now, with `active` |
//! | `{"cmd":"fault","marker_cable":false,"tx_crc":"off"}` | bench faults: the marker cable unplugged (`true` plugs it back), a Gotmic module's CRC mode fixed `on` or `off` by its configuration (`free`: as at power-on), `"awg_options":["001"]` what the AWG's `*OPT?` answers (`[]`: the catalog's), `"awg_raster_max":6e10` what its `:FREQ:RAST? MAX` answers (`0`: the catalog's); fields left out are kept |
//! | `{"cmd":"fault","drop":"awg"}` | the next exchange with `awg`, `scope`, `tx` or `rx` is cut: half its reply sent, then the connection closed (a serial line cannot close: the half line is all that comes) |
//! | `{"cmd":"fault","stall":"scope","for_s":5}` | `awg` or `scope` holds every reply for `for_s` seconds from now (what it answers meanwhile arrives when the stall ends) |
//! | `{"cmd":"fault","power_cycle":"tx","for_s":3}` | the `tx` or `rx` module's power goes off for `for_s` seconds (its port answers nothing) and comes back at power-on defaults (RF off, registers at reset, CRC mode as at power-on) |
//!
//! `drop`, `stall` and `power_cycle` may be combined with each other and with the bench faults
//! in one request; `for_s` (0 to 3600) goes with `stall` and `power_cycle`, and is refused
//! without them.
//!
//! Errors reply `{"ok":false,"error":"..."}` and change nothing. A line longer than 1 MiB is
//! read to its end and refused whole.
//!
//! `set` and `seed` restart the noise generator from the scene's seed, so the captures that follow
//! are the same whatever was captured before (a campaign step replays identically when resumed).

use crate::emulator::lecroy::RemoteInterface;
use crate::scene::{Scene, Target};
use serde::Deserialize;
use serde_json::{json, Value};
use std::future::Future;
use std::net::SocketAddr;
use std::pin::Pin;
use std::sync::{Arc, Mutex, MutexGuard};
use tokio::io::{AsyncBufRead, AsyncBufReadExt, AsyncWriteExt, BufReader};
use tokio::net::TcpListener;

/// The scene shared by the emulators and the control channel, with the ground truth of the last
/// capture.
#[derive(Debug, Default)]
pub struct SharedScene {
    scene: Mutex<Scene>,
    last: Mutex<(u64, Option<Scene>)>,
    /// A seed the noise generator must restart from before the next capture.
    reseed: Mutex<Option<u64>>,
}

impl SharedScene {
    pub fn new(scene: Scene) -> Arc<Self> {
        Arc::new(Self {
            scene: Mutex::new(scene),
            last: Mutex::new((0, None)),
            reseed: Mutex::new(None),
        })
    }

    /// The scene now.
    pub fn snapshot(&self) -> Scene {
        lock(&self.scene).clone()
    }

    /// The seed the noise generator must restart from, once (after `set` or `seed`).
    pub(crate) fn take_reseed(&self) -> Option<u64> {
        lock(&self.reseed).take()
    }

    /// Records that a capture was made with `scene`.
    pub(crate) fn record_capture(&self, scene: Scene) {
        let mut last = lock(&self.last);
        last.0 += 1;
        last.1 = Some(scene);
    }

    /// Number of captures so far and the scene of the last one.
    pub fn last_capture(&self) -> (u64, Option<Scene>) {
        lock(&self.last).clone()
    }

    /// Applies one scene request and returns the reply (never panics on bad input). The lab's
    /// own requests (`scope_remote`, `endpoints`) need the control channel's [`Panel`].
    pub fn apply(&self, line: &str) -> Value {
        reply(parse(line).and_then(|req| self.try_apply(req)))
    }

    fn try_apply(&self, req: Request) -> Result<Value, String> {
        if let Request::Get = req {
            return Ok(json!({"ok": true, "scene": self.snapshot()}));
        }
        if let Request::LastCapture = req {
            let (n, scene) = self.last_capture();
            return Ok(json!({"ok": true, "captures": n, "scene": scene}));
        }
        let mut guard = lock(&self.scene);
        let mut next = guard.clone();
        let mut reply = json!({"ok": true});
        let mut reseed = None;
        match req {
            Request::Set { scene } => {
                reseed = Some(scene.seed);
                next = *scene;
            }
            Request::Seed { seed } => {
                next.seed = seed;
                reseed = Some(seed);
            }
            Request::Move { target, range_m } => {
                let n = next.targets.len();
                let t = next
                    .targets
                    .get_mut(target)
                    .ok_or_else(|| format!("no target {target}: the scene has {n} targets"))?;
                t.range_m = range_m;
            }
            Request::Add { target } => {
                next.targets.push(target);
                reply["index"] = json!(next.targets.len() - 1);
            }
            Request::Remove { target } => {
                if target >= next.targets.len() {
                    return Err(format!(
                        "no target {target}: the scene has {} targets",
                        next.targets.len()
                    ));
                }
                next.targets.remove(target);
            }
            Request::Snr { snr_db } => next.snr_db = snr_db,
            Request::Get | Request::LastCapture => {}
            Request::ScopeRemote { .. } | Request::Endpoints | Request::Fault { .. } => {
                return Err("this request needs the lab's control channel".into())
            }
        }
        next.validate().map_err(|e| e.to_string())?;
        *guard = next;
        if reseed.is_some() {
            *lock(&self.reseed) = reseed;
        }
        Ok(reply)
    }
}

/// Parses one request line.
fn parse(line: &str) -> Result<Request, String> {
    serde_json::from_str(line).map_err(|e| {
        format!(
            "bad request ({e}); send one JSON object per line with \"cmd\" one of get, set, \
             move, add, remove, snr, seed, last_capture, scope_remote, endpoints"
        )
    })
}

/// `{"ok":true,...}` or `{"ok":false,"error":...}`.
fn reply(result: Result<Value, String>) -> Value {
    match result {
        Ok(mut v) => {
            if v.get("ok").is_none() {
                v["ok"] = json!(true);
            }
            v
        }
        Err(e) => json!({"ok": false, "error": e}),
    }
}

/// A boxed future of a [`Panel`] action.
pub(crate) type PanelFuture<'a, T> = Pin<Box<dyn Future<Output = T> + Send + 'a>>;

/// What the control channel can do to the lab besides the scene: its "front panel".
pub(crate) trait Panel: Send + Sync + 'static {
    /// Switches the scope's remote interface; resolves once the endpoints follow.
    fn set_scope_remote(&self, remote: RemoteInterface) -> PanelFuture<'_, Result<Value, String>>;
    /// Every endpoint as it is now.
    fn endpoints(&self) -> Value;
    /// Switches bench faults: the marker cable, a Gotmic module's fixed CRC mode.
    fn fault(&self, fault: &BenchFault) -> Result<Value, String>;
}

/// A bench fault switched from the control channel (`{"cmd":"fault", ...}`); fields left out
/// are not changed.
#[derive(Debug, Clone, Default)]
pub(crate) struct BenchFault {
    /// Whether the marker cable reaches the scope's external trigger input.
    pub marker_cable: Option<bool>,
    /// The Tx module's line CRC mode fixed by its configuration: `"on"`, `"off"`, or `"free"`
    /// (`CRC ON|OFF` switch it, as at power-on).
    pub tx_crc: Option<String>,
    /// The same for the Rx module.
    pub rx_crc: Option<String>,
    /// What the AWG's `*OPT?` answers (a unit with other options); `[]`: the catalog's again.
    pub awg_options: Option<Vec<String>>,
    /// What the AWG's `:FREQ:RAST? MAX` answers (another unit's limit); `0`: the catalog's again.
    pub awg_raster_max: Option<f64>,
    /// The instrument whose next exchange is cut (`awg`, `scope`, `tx`, `rx`).
    pub drop: Option<String>,
    /// The instrument whose replies are held for `for_s` (`awg`, `scope`).
    pub stall: Option<String>,
    /// The module whose power goes off for `for_s` (`tx`, `rx`).
    pub power_cycle: Option<String>,
    /// Seconds of a stall or a power cut.
    pub for_s: Option<f64>,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    // A panic elsewhere must not take the lab down: the data is plain and always consistent.
    m.lock().unwrap_or_else(|p| p.into_inner())
}

#[derive(Debug, Deserialize)]
#[serde(tag = "cmd", rename_all = "snake_case", deny_unknown_fields)]
enum Request {
    Get,
    // Boxed: a scene with its chain is far larger than the other requests.
    Set {
        scene: Box<Scene>,
    },
    Move {
        target: usize,
        range_m: f64,
    },
    Add {
        target: Target,
    },
    Remove {
        target: usize,
    },
    Snr {
        snr_db: f64,
    },
    Seed {
        seed: u64,
    },
    LastCapture,
    ScopeRemote {
        interface: RemoteInterface,
    },
    Endpoints,
    Fault {
        marker_cable: Option<bool>,
        tx_crc: Option<String>,
        rx_crc: Option<String>,
        awg_options: Option<Vec<String>>,
        awg_raster_max: Option<f64>,
        drop: Option<String>,
        stall: Option<String>,
        power_cycle: Option<String>,
        for_s: Option<f64>,
    },
}

/// Longest request line accepted (a whole scene with many targets fits easily).
const MAX_LINE: usize = 1 << 20;

/// One line read from a control client.
#[derive(Debug, PartialEq, Eq)]
enum Line {
    /// A request (without its LF); the last one may lack its LF when the client closed.
    Request(Vec<u8>),
    /// A line over [`MAX_LINE`]: read to its end and dropped whole, none of it runs.
    TooLong,
    /// The client closed.
    End,
}

/// Reads one line of at most `MAX_LINE` bytes, holding no more than that in memory; an over-long
/// line is skipped to its LF so that its tail is never taken for the next request.
async fn read_request<R: AsyncBufRead + Unpin>(rd: &mut R) -> std::io::Result<Line> {
    let mut line = Vec::new();
    let mut too_long = false;
    loop {
        let available = rd.fill_buf().await?;
        if available.is_empty() {
            return Ok(match (too_long, line.is_empty()) {
                (true, _) => Line::TooLong,
                (false, true) => Line::End,
                (false, false) => Line::Request(line),
            });
        }
        let (chunk, found) = match available.iter().position(|&b| b == b'\n') {
            Some(i) => (&available[..i], Some(i + 1)),
            None => (available, None),
        };
        if !too_long && line.len() + chunk.len() <= MAX_LINE {
            line.extend_from_slice(chunk);
        } else {
            too_long = true;
            line = Vec::new();
        }
        let used = found.unwrap_or(available.len());
        rd.consume(used);
        if found.is_some() {
            return Ok(if too_long {
                Line::TooLong
            } else {
                Line::Request(line)
            });
        }
    }
}

/// The reply to one line (`None` at the end of the input).
async fn answer(shared: &SharedScene, panel: Option<&dyn Panel>, line: Line) -> Option<Value> {
    let text = match line {
        Line::End => return None,
        Line::TooLong => {
            return Some(reply(Err(format!(
                "request longer than {MAX_LINE} bytes: ignored whole, nothing changed"
            ))))
        }
        Line::Request(bytes) => match String::from_utf8(bytes) {
            Ok(text) => text,
            Err(_) => {
                return Some(reply(Err(
                    "request is not UTF-8 text: nothing changed".into()
                )))
            }
        },
    };
    let result = match (parse(text.trim()), panel) {
        (Ok(Request::ScopeRemote { interface }), Some(panel)) => {
            panel.set_scope_remote(interface).await
        }
        (Ok(Request::Endpoints), Some(panel)) => Ok(json!({ "endpoints": panel.endpoints() })),
        (
            Ok(Request::Fault {
                marker_cable,
                tx_crc,
                rx_crc,
                awg_options,
                awg_raster_max,
                drop,
                stall,
                power_cycle,
                for_s,
            }),
            Some(panel),
        ) => panel.fault(&BenchFault {
            marker_cable,
            tx_crc,
            rx_crc,
            awg_options,
            awg_raster_max,
            drop,
            stall,
            power_cycle,
            for_s,
        }),
        (Ok(req), _) => shared.try_apply(req),
        (Err(e), _) => Err(e),
    };
    Some(reply(result))
}

/// The running control channel; dropping it closes the listener and every connection.
#[derive(Debug)]
pub(crate) struct ControlServer {
    addr: SocketAddr,
    task: tokio::task::JoinHandle<()>,
}

impl ControlServer {
    /// Where clients connect.
    pub(crate) fn local_addr(&self) -> SocketAddr {
        self.addr
    }
}

impl Drop for ControlServer {
    fn drop(&mut self) {
        self.task.abort();
    }
}

/// Serves the control channel on `addr` (use port 0 for an OS-assigned port); returns once it
/// listens, and serves until the returned server is dropped. Without a `panel` the lab's own
/// requests (`scope_remote`, `endpoints`) are refused.
pub(crate) async fn serve(
    shared: Arc<SharedScene>,
    panel: Option<Arc<dyn Panel>>,
    addr: SocketAddr,
) -> std::io::Result<ControlServer> {
    let listener = TcpListener::bind(addr).await?;
    let local = listener.local_addr()?;
    let task = tokio::spawn(async move {
        // Connections belong to the loop: aborting it drops them all.
        let mut connections = tokio::task::JoinSet::new();
        loop {
            let stream = tokio::select! {
                accepted = listener.accept() => match accepted {
                    Ok((stream, _)) => stream,
                    Err(err) => {
                        // Typically EMFILE: back off instead of spinning.
                        tracing::warn!("control channel: accept failed: {err}");
                        tokio::time::sleep(std::time::Duration::from_millis(50)).await;
                        continue;
                    }
                },
                Some(_) = connections.join_next(), if !connections.is_empty() => continue,
            };
            let shared = shared.clone();
            let panel = panel.clone();
            connections.spawn(async move {
                let (rd, mut wr) = stream.into_split();
                let mut rd = BufReader::new(rd);
                while let Ok(line) = read_request(&mut rd).await {
                    let Some(reply) = answer(&shared, panel.as_deref(), line).await else {
                        break;
                    };
                    let mut text = reply.to_string();
                    text.push('\n');
                    if wr.write_all(text.as_bytes()).await.is_err() {
                        break;
                    }
                }
            });
        }
    });
    Ok(ControlServer { addr: local, task })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;
    use tokio::io::AsyncBufReadExt;
    use tokio::net::TcpStream;

    #[test]
    fn requests_change_the_scene_and_bad_ones_change_nothing() {
        let shared = SharedScene::new(Scene::default());
        assert_eq!(
            shared.apply(r#"{"cmd":"move","target":0,"range_m":1.03}"#)["ok"],
            true
        );
        assert_eq!(shared.snapshot().targets[0].range_m, 1.03);
        let r = shared.apply(r#"{"cmd":"add","target":{"range_m":2.0,"amplitude":0.3}}"#);
        assert_eq!(r["index"], 1);
        let r = shared.apply(r#"{"cmd":"move","target":5,"range_m":1.0}"#);
        assert_eq!(r["ok"], false);
        assert!(r["error"].as_str().unwrap().contains("2 targets"));
        let r = shared.apply(r#"{"cmd":"snr","snr_db":900}"#);
        assert!(r["error"].as_str().unwrap().contains("snr_db"));
        assert_eq!(shared.snapshot().snr_db, Scene::default().snr_db);
        let r = shared.apply(r#"{"cmd":"add","target":{"range_m":2.0,"amplitude":1e300}}"#);
        let error = r["error"].as_str().unwrap();
        assert!(
            error.contains("targets[2].amplitude") && error.contains("1e300"),
            "{r}"
        );
        let r =
            shared.apply(r#"{"cmd":"set","scene":{"impairments":{"dc_offset_v":[0.0,0.0,0.1]}}}"#);
        assert!(
            r["error"].as_str().unwrap().contains("exactly 2 values"),
            "{r}"
        );
        assert_eq!(shared.snapshot().targets.len(), 2);
        let r = shared.apply("not json");
        assert!(r["error"].as_str().unwrap().contains("cmd"));
        assert_eq!(shared.apply(r#"{"cmd":"remove","target":0}"#)["ok"], true);
        assert_eq!(shared.snapshot().targets.len(), 1);
        assert_eq!(shared.snapshot().targets[0].range_m, 2.0);
    }

    /// A control server on loopback for `shared`, and a connection to it.
    async fn connected(
        shared: &Arc<SharedScene>,
    ) -> (
        ControlServer,
        BufReader<tokio::net::tcp::OwnedReadHalf>,
        tokio::net::tcp::OwnedWriteHalf,
    ) {
        let server = serve(shared.clone(), None, "127.0.0.1:0".parse().unwrap())
            .await
            .unwrap();
        let stream = tokio::time::timeout(
            Duration::from_secs(5),
            TcpStream::connect(server.local_addr()),
        )
        .await
        .unwrap()
        .unwrap();
        let (rd, wr) = stream.into_split();
        (server, BufReader::new(rd), wr)
    }

    async fn ask(
        wr: &mut tokio::net::tcp::OwnedWriteHalf,
        rd: &mut BufReader<tokio::net::tcp::OwnedReadHalf>,
        req: &str,
    ) -> Value {
        wr.write_all(format!("{req}\n").as_bytes()).await.unwrap();
        let mut line = String::new();
        tokio::time::timeout(Duration::from_secs(5), rd.read_line(&mut line))
            .await
            .expect("reply within 5 s")
            .unwrap();
        serde_json::from_str(&line).unwrap()
    }

    #[tokio::test]
    async fn control_channel_over_loopback() {
        let shared = SharedScene::new(Scene::default());
        let (_server, mut rd, mut wr) = connected(&shared).await;
        let v = ask(
            &mut wr,
            &mut rd,
            r#"{"cmd":"move","target":0,"range_m":1.5}"#,
        )
        .await;
        assert_eq!(v["ok"], true);
        shared.record_capture(shared.snapshot());
        let v = ask(&mut wr, &mut rd, r#"{"cmd":"last_capture"}"#).await;
        assert_eq!(v["captures"], 1);
        assert_eq!(v["scene"]["targets"][0]["range_m"], 1.5);
        let v = ask(&mut wr, &mut rd, r#"{"cmd":"fly"}"#).await;
        assert_eq!(v["ok"], false);
    }

    #[tokio::test]
    async fn a_100_mib_line_is_dropped_whole_and_its_tail_never_runs() {
        use tokio::io::AsyncReadExt;
        let shared = SharedScene::new(Scene::default());
        let tail = br#"{"cmd":"snr","snr_db":3.0}"#;
        // 100 MiB of spaces, then a valid request on the same line, then a real next request:
        // streamed, never held in memory.
        let input = tokio::io::repeat(b' ')
            .take(100 << 20)
            .chain(&tail[..])
            .chain(&b"\n{\"cmd\":\"get\"}\n"[..]);
        let mut rd = BufReader::new(input);
        let first = read_request(&mut rd).await.unwrap();
        assert_eq!(first, Line::TooLong);
        let reply = answer(&shared, None, first).await.unwrap();
        assert!(
            reply["error"].as_str().unwrap().contains("longer than"),
            "{reply}"
        );
        assert_eq!(shared.snapshot().snr_db, Scene::default().snr_db);
        let next = read_request(&mut rd).await.unwrap();
        assert_eq!(answer(&shared, None, next).await.unwrap()["ok"], true);
        assert_eq!(read_request(&mut rd).await.unwrap(), Line::End);
    }

    #[tokio::test]
    async fn lines_at_the_limit_unterminated_and_not_utf8() {
        let shared = SharedScene::new(Scene::default());
        let request = br#"{"cmd":"snr","snr_db":12.0}"#;
        let mut at_limit = vec![b' '; MAX_LINE - request.len()];
        at_limit.extend_from_slice(request);
        at_limit.extend_from_slice(b"\n\xff\xfe\n{\"cmd\":\"get\"}");
        let mut rd = BufReader::with_capacity(4096, &at_limit[..]);
        let line = read_request(&mut rd).await.unwrap();
        assert_eq!(answer(&shared, None, line).await.unwrap()["ok"], true);
        assert_eq!(shared.snapshot().snr_db, 12.0);
        let line = read_request(&mut rd).await.unwrap();
        let reply = answer(&shared, None, line).await.unwrap();
        assert!(
            reply["error"].as_str().unwrap().contains("UTF-8"),
            "{reply}"
        );
        // The last request may lack its LF when the client closes.
        let line = read_request(&mut rd).await.unwrap();
        assert_eq!(answer(&shared, None, line).await.unwrap()["ok"], true);
        assert_eq!(read_request(&mut rd).await.unwrap(), Line::End);
    }

    #[tokio::test]
    async fn over_long_line_over_loopback_changes_nothing_and_the_session_goes_on() {
        let shared = SharedScene::new(Scene::default());
        let (_server, mut rd, mut wr) = connected(&shared).await;
        let mut long = vec![b' '; 3 * MAX_LINE];
        long.extend_from_slice(b"{\"cmd\":\"snr\",\"snr_db\":3.0}\n");
        let writer = tokio::spawn(async move {
            wr.write_all(&long).await.unwrap();
            wr
        });
        let mut line = String::new();
        tokio::time::timeout(Duration::from_secs(20), rd.read_line(&mut line))
            .await
            .expect("reply within 20 s")
            .unwrap();
        let v: Value = serde_json::from_str(&line).unwrap();
        assert_eq!(v["ok"], false, "{v}");
        let mut wr = tokio::time::timeout(Duration::from_secs(20), writer)
            .await
            .unwrap()
            .unwrap();
        let v = ask(&mut wr, &mut rd, r#"{"cmd":"get"}"#).await;
        assert_eq!(v["scene"]["snr_db"], Scene::default().snr_db);
    }
}
