//! The live view's server: the token, a stalled browser, a browser that goes, the page's profile.
//! Loopback only, every wait bounded, nothing timed.

use super::*;
use std::sync::atomic::AtomicUsize;

const LIMIT: Duration = Duration::from_secs(30);

async fn start(stops: Arc<AtomicUsize>) -> Live {
    Live::start(Options {
        listen: "127.0.0.1:0".parse().unwrap(),
        on_stop: Box::new(move || {
            stops.fetch_add(1, Ordering::SeqCst);
        }),
        bench_state: Box::new(|| vec![("awg".into(), false), ("tx".into(), false)]),
    })
    .await
    .unwrap()
}

/// One request, the whole answer (the server closes the connection).
async fn request(live: &Live, method: &str, target: &str) -> (u16, String) {
    let mut s = TcpStream::connect(live.addr()).await.unwrap();
    let head =
        format!("{method} {target} HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Length: 0\r\n\r\n");
    s.write_all(head.as_bytes()).await.unwrap();
    let mut out = Vec::new();
    tokio::time::timeout(LIMIT, s.read_to_end(&mut out))
        .await
        .expect("the server answers")
        .unwrap();
    let text = String::from_utf8_lossy(&out).into_owned();
    let code = text
        .split(' ')
        .nth(1)
        .and_then(|c| c.parse().ok())
        .unwrap_or(0);
    (code, text)
}

async fn until(what: &str, cond: impl Fn() -> bool) {
    let poll = async {
        while !cond() {
            tokio::time::sleep(Duration::from_millis(5)).await;
        }
    };
    tokio::time::timeout(LIMIT, poll)
        .await
        .unwrap_or_else(|_| panic!("{what} within {LIMIT:?}"));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_wrong_or_missing_token_gets_403_and_changes_nothing() {
    let stops = Arc::new(AtomicUsize::new(0));
    let live = start(stops.clone()).await;
    let token = live.token().to_string();
    // The token with its last digit changed (to another digit: a random token may end in 0).
    let last = if token.ends_with('0') { '1' } else { '0' };
    let wrong = format!("{}{last}", &token[..token.len() - 1]);
    for target in [
        "/".to_string(),
        format!("/?token={wrong}"),
        "/events".into(),
        format!("/events?token={wrong}"),
        "/state?token=".into(),
    ] {
        let (code, _) = request(&live, "GET", &target).await;
        assert_eq!(code, 403, "GET {target}");
    }
    for target in ["/stop".to_string(), format!("/stop?token={wrong}")] {
        let (code, _) = request(&live, "POST", &target).await;
        assert_eq!(code, 403, "POST {target}");
    }
    assert_eq!(
        stops.load(Ordering::SeqCst),
        0,
        "a refused Stop stopped nothing"
    );
    let s = live.stats();
    assert_eq!((s.stops, s.clients, s.refused), (0, 0, 7), "{s:?}");
    // With the token: the page, and a Stop that does what it says once.
    let (code, page) = request(&live, "GET", &format!("/?token={token}")).await;
    assert_eq!(code, 200);
    assert!(page.contains("<svg id=\"profile\""));
    let (code, _) = request(&live, "GET", &format!("/stop?token={token}")).await;
    assert_eq!(code, 405, "Stop only by POST");
    assert_eq!(stops.load(Ordering::SeqCst), 0);
    let (code, _) = request(&live, "POST", &format!("/stop?token={token}")).await;
    assert_eq!(code, 200);
    assert_eq!(stops.load(Ordering::SeqCst), 1);
    let (code, _) = request(&live, "GET", &format!("/nothing?token={token}")).await;
    assert_eq!(code, 404);
    live.finish("complete", Duration::ZERO).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_browser_that_goes_is_forgotten() {
    let live = start(Arc::new(AtomicUsize::new(0))).await;
    live.send(Event::Set("title", json!("test")));
    let mut s = TcpStream::connect(live.addr()).await.unwrap();
    let head = format!("GET /events?token={} HTTP/1.1\r\n\r\n", live.token());
    s.write_all(head.as_bytes()).await.unwrap();
    // Its first frame arrives.
    let mut got = Vec::new();
    let mut buf = [0u8; 4096];
    while !String::from_utf8_lossy(&got).contains("\"title\":\"test\"") {
        let n = tokio::time::timeout(LIMIT, s.read(&mut buf))
            .await
            .expect("a frame")
            .unwrap();
        assert!(n > 0);
        got.extend_from_slice(&buf[..n]);
    }
    assert!(String::from_utf8_lossy(&got).starts_with("HTTP/1.1 200 OK"));
    assert_eq!(live.stats().clients, 1);
    drop(s);
    until("the browser forgotten", || live.stats().clients == 0).await;
    assert_eq!(live.stats().forgotten, 1);
    live.finish("complete", Duration::ZERO).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_stalled_browser_holds_up_nothing_and_is_dropped() {
    let live = start(Arc::new(AtomicUsize::new(0))).await;
    // A browser that asks for the stream and never reads a byte of it.
    let mut stalled = TcpStream::connect(live.addr()).await.unwrap();
    let head = format!("GET /events?token={} HTTP/1.1\r\n\r\n", live.token());
    stalled.write_all(head.as_bytes()).await.unwrap();
    until("the stalled browser connected", || {
        live.stats().clients == 1
    })
    .await;
    // A browser that keeps up, beside it.
    let mut good = TcpStream::connect(live.addr()).await.unwrap();
    good.write_all(head.as_bytes()).await.unwrap();
    until("both connected", || live.stats().clients == 2).await;
    let reader = tokio::spawn(async move {
        let mut tail = String::new();
        let mut buf = vec![0u8; 1 << 16];
        loop {
            let n = good.read(&mut buf).await.unwrap_or(0);
            if n == 0 {
                return tail;
            }
            tail.push_str(&String::from_utf8_lossy(&buf[..n]));
            if tail.contains("\"final\":true") {
                return tail;
            }
            let keep = tail.len().saturating_sub(1 << 20);
            tail.drain(..keep);
        }
    });
    // 200 frames of 256 kB each: 50 MB, far more than the stalled socket's buffers hold. The
    // producer never waits: `send` returns at once, whatever the browsers do.
    let blob = "x".repeat(256 * 1024);
    for k in 0..200u32 {
        live.send(Event::Set("blob", json!(format!("{k}{blob}"))));
        until("the frame published", || {
            live.stats().frames + live.stats().dropped_events > u64::from(k)
        })
        .await;
    }
    live.send(Event::Set("status", json!("complete")));
    let tail = tokio::time::timeout(LIMIT, reader)
        .await
        .expect("the good browser gets the last frame")
        .unwrap();
    assert!(tail.contains("\"final\":true"));
    // Connected or dropped by now, the stalled browser's missed frames are counted: its socket
    // buffers hold a few of the 256 kB frames, not 200.
    let s = live.stats();
    assert!(
        s.skipped >= 100,
        "the stalled browser is counted behind: {s:?}"
    );
    // The stalled one is dropped once its socket took nothing for WRITE_TIMEOUT, and every frame
    // it did not take is counted as skipped.
    // (The good one went when it had the final frame.)
    until("the stalled browser dropped", || live.stats().clients == 0).await;
    let s = live.stats();
    assert!(s.frames >= 100, "{s:?}");
    assert!(
        s.skipped >= s.frames / 2,
        "the stalled browser skipped frames: {s:?}"
    );
    assert_eq!(s.forgotten, 2, "{s:?}");
    drop(stalled);
    live.finish("complete", Duration::ZERO).await;
}

#[tokio::test]
async fn finish_does_not_wait_for_a_stalled_browser() {
    let live = start(Arc::new(AtomicUsize::new(0))).await;
    let mut stalled = TcpStream::connect(live.addr()).await.unwrap();
    let head = format!("GET /events?token={} HTTP/1.1\r\n\r\n", live.token());
    stalled.write_all(head.as_bytes()).await.unwrap();
    until("connected", || live.stats().clients == 1).await;
    let blob = "y".repeat(1 << 20);
    for k in 0..40 {
        live.send(Event::Set("blob", json!(format!("{k}{blob}"))));
        tokio::task::yield_now().await;
    }
    // Bounded by the linger whatever the browser does; what is checked is that it returns.
    tokio::time::timeout(LIMIT, live.finish("complete", Duration::from_secs(2)))
        .await
        .expect("finish returns");
    drop(stalled);
}

#[test]
fn the_page_profile_keeps_the_peaks_and_at_most_its_points() {
    let n = 5000;
    let range: Vec<f64> = (0..n).map(|i| i as f64 * 1e-3).collect();
    let mut level = vec![-80.0; n];
    level[2501] = -3.0;
    let threshold = vec![-50.0; n];
    let v = profile_json(
        "step 1",
        &range,
        &[
            ("correlation_db".into(), level),
            ("threshold_db".into(), threshold),
        ],
        &[(2.501, -3.0)],
        &[2.5],
    );
    let levels = v["level_db"].as_array().unwrap();
    assert!(levels.len() <= PROFILE_POINTS);
    assert_eq!(levels.len(), v["range_m"].as_array().unwrap().len());
    let peak = levels
        .iter()
        .filter_map(Value::as_f64)
        .fold(f64::MIN, f64::max);
    assert_eq!(peak, -3.0);
    assert_eq!(v["threshold_db"].as_array().unwrap().len(), levels.len());
    assert_eq!(v["truth_m"], json!([2.5]));
    assert_eq!(v["label"], "step 1, correlation (dB)");
}

#[test]
fn the_page_names_nothing_to_fetch() {
    // Its one "http" is the SVG namespace (a name, never requested); no src=, no href= but the
    // empty data: icon, no @import, no url(.
    let without_ns = PAGE.replace("http://www.w3.org/2000/svg", "");
    assert!(!without_ns.contains("http"), "an address in the page");
    assert!(!PAGE.contains("src="), "a fetched script or image");
    assert_eq!(PAGE.matches("href=").count(), 1);
    assert!(PAGE.contains("href=\"data:,\""));
    assert!(!PAGE.contains("@import") && !PAGE.contains("url("));
}

/// The measurement's side never waits for the composer: on a runtime whose one thread the sender
/// holds (the composer cannot run), `send` returns every time, the queue takes what it holds and
/// every event past it is dropped and counted.
#[tokio::test(flavor = "current_thread")]
async fn send_never_waits_and_counts_what_a_full_queue_drops() {
    let live = start(Arc::new(AtomicUsize::new(0))).await;
    let n = 1000u64;
    for k in 0..n {
        live.send(Event::Set("k", json!(k)));
    }
    assert_eq!(live.stats().dropped_events, n - QUEUE as u64);
    // Once the composer runs, the queued events are published (the newest state it holds is
    // the last event the queue took).
    until("the queue drained", || {
        live.stats().frames > 0 && live.shared.frames.borrow().json.contains("\"k\":63")
    })
    .await;
    live.finish("complete", Duration::ZERO).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_frame_says_when_its_oldest_event_was_handed_over() {
    let live = start(Arc::new(AtomicUsize::new(0))).await;
    let before = unix_ms();
    live.send(Event::Set("title", json!("t")));
    until("the frame", || {
        live.shared.frames.borrow().json.contains("\"title\":\"t\"")
    })
    .await;
    let frame: Value = serde_json::from_str(&live.shared.frames.borrow().json).unwrap();
    let event = frame["event_unix_ms"].as_f64().unwrap();
    let published = frame["published_unix_ms"].as_f64().unwrap();
    assert!(
        event >= before.floor() - 1.0 && published >= event - 1.0,
        "{frame}"
    );
    live.finish("complete", Duration::ZERO).await;
}

#[tokio::test]
async fn a_retry_is_in_the_log_and_counted() {
    let mut state = Map::new();
    let retry = |n| {
        Event::Log(
            "retry",
            format!("step 3 of 6: awg: connection closed; safe state: ...; retry {n} of 2 in 2 s"),
        )
    };
    apply(&mut state, retry(1)).await;
    apply(&mut state, Event::Log("warning", "a warning".into())).await;
    apply(&mut state, retry(2)).await;
    assert_eq!(state["retries"], json!(2));
    let log = state["log"].as_array().unwrap();
    assert_eq!(log.len(), 3);
    assert_eq!(log[0]["level"], "retry");
    assert!(log[2]["text"].as_str().unwrap().contains("retry 2 of 2"));
}
