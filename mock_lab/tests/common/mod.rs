//! Helpers shared by the server tests: bounded waits, a loopback instrument, a chunked reader.
#![allow(dead_code)]

use std::future::Future;
use std::sync::Arc;
use std::time::Duration;

use mock_lab::emulator::loopback::Loopback;
use mock_lab::faults::Faults;
use mock_lab::server::{Handler, ServerOptions};

/// Every wait in these tests is bounded by this.
pub const LIMIT: Duration = Duration::from_secs(20);

/// Awaits `fut`, failing the test if it takes longer than [`LIMIT`].
pub async fn bounded<T>(fut: impl Future<Output = T>) -> T {
    tokio::time::timeout(LIMIT, fut)
        .await
        .expect("operation did not finish within the test's time limit")
}

/// A fresh loopback instrument and server options with their own faults.
pub fn instrument() -> (Arc<dyn Handler>, ServerOptions, Arc<Faults>) {
    let faults = Faults::new();
    let handler: Arc<dyn Handler> = Arc::new(Loopback::new());
    (handler, ServerOptions::with_faults(faults.clone()), faults)
}

/// A loopback that starts each message `delay` late (an instrument still busy with what came
/// before), and says when a message has reached it: a device clear sent then lands before the
/// instrument has begun the message, the window a server must cover by passing the clear on again.
pub struct LateStart {
    inner: Loopback,
    delay: Duration,
    entered: std::sync::Mutex<std::sync::mpsc::Sender<()>>,
}

impl LateStart {
    /// The handler, and the receiver of one `()` per message that reached it.
    pub fn handler(delay: Duration) -> (Arc<dyn Handler>, std::sync::mpsc::Receiver<()>) {
        let (entered, reached) = std::sync::mpsc::channel();
        let handler = Arc::new(LateStart {
            inner: Loopback::new(),
            delay,
            entered: std::sync::Mutex::new(entered),
        });
        (handler, reached)
    }
}

impl Handler for LateStart {
    fn message(&self, data: &[u8]) -> Vec<Vec<u8>> {
        let _ = self.entered.lock().unwrap().send(());
        std::thread::sleep(self.delay);
        self.inner.message(data)
    }

    fn device_clear(&self) {
        self.inner.device_clear();
    }

    fn status_byte(&self) -> u8 {
        self.inner.status_byte()
    }
}

/// Waits (blocking, bounded) until a message has reached a [`LateStart`] handler.
pub async fn reached(rx: std::sync::mpsc::Receiver<()>) -> std::sync::mpsc::Receiver<()> {
    tokio::task::spawn_blocking(move || {
        rx.recv_timeout(LIMIT)
            .expect("the message reaches the instrument");
        rx
    })
    .await
    .unwrap()
}

/// The loopback's `DATA:GEN` bytes, to check blocks end to end.
pub fn expected_block(len: usize, seed: u64) -> Vec<u8> {
    mock_lab::emulator::loopback::pseudo_random_bytes(len, seed)
}

/// IEEE 488.2 definite block header for `len` bytes.
pub fn block_header(len: usize) -> Vec<u8> {
    let digits = len.to_string();
    format!("#{}{}", digits.len(), digits).into_bytes()
}

/// An M8195A emulator as a server handler (it parses with the shared 488.2 message reader).
pub fn awg() -> (Arc<dyn Handler>, ServerOptions) {
    let awg = mock_lab::emulator::m8195a::M8195a::embedded().expect("built-in catalog loads");
    (Arc::new(awg), ServerOptions::default())
}

/// One message to the AWG and, for queries, the reply expected (without its terminator).
pub struct Exchange {
    pub message: Vec<u8>,
    pub reply: Option<String>,
}

/// Uploads whose block payload ends in whitespace bytes (space, LF, tab, CR: what an OFDM
/// waveform's last samples can be), each read back: the block must stay byte-exact, with no
/// `-161 Invalid block data` in the error queue. Every message ends in LF, as clients send it.
pub fn whitespace_tail_uploads() -> Vec<Exchange> {
    const N: usize = 1280;
    let mut out = vec![Exchange {
        message: b"*RST;:INST:DACM SING;:TRAC1:DEF 1,1280\n".to_vec(),
        reply: None,
    }];
    for tail in [b' ', b'\n', b'\t', b'\r'] {
        let mut payload: Vec<u8> = (0..N).map(|k| (k % 97) as u8 + 33).collect();
        payload[N - 2] = tail;
        payload[N - 1] = tail;
        let mut message = b":TRAC1:DATA 1,0,".to_vec();
        message.extend(block_header(N));
        message.extend(&payload);
        message.push(b'\n');
        out.push(Exchange {
            message,
            reply: None,
        });
        out.push(Exchange {
            message: format!(":TRAC1:DATA? 1,{},3;:SYST:ERR?\n", N - 3).into_bytes(),
            reply: Some(format!(
                "{},{tail},{tail};0,\"No error\"",
                payload[N - 3] as i8
            )),
        });
    }
    out
}
