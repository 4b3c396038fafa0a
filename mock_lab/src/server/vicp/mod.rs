//! VICP server (LeCroy, TCP port 1861), protocol version 1a.
//!
//! A message ends with a block carrying EOI. Every reply block carries the sequence number of
//! the command that caused it (never 0: clients such as pyvicp detect VICP 1a from a non-zero
//! number, and without it pyvicp's device clear sleeps 100 s). The CLEAR bit performs a device
//! clear before any data in the same block is parsed.
//!
//! Serial poll works both ways a client may ask: in-band (SERIAL_POLL bit; answered with a
//! one-byte block holding the status byte) and out-of-band (VICP 1a: an urgent TCP byte `'S'`,
//! answered with an urgent byte holding the status byte). For the out-of-band answer the server
//! sends an empty DATA block with a stale sequence number just before the urgent byte: Linux
//! only reports an urgent byte as readable together with in-band data, and clients discard
//! blocks with old sequence numbers (pyvicp does), so this block makes `recv(MSG_OOB)` return
//! at once without disturbing the stream. Clients that track sequence numbers strictly must
//! ignore empty, non-EOI blocks whose number is older than their last command.

pub mod codec;

use std::io;
use std::net::SocketAddr;
use std::os::fd::{AsRawFd, FromRawFd, OwnedFd};
use std::sync::atomic::{AtomicU64, AtomicU8, Ordering};
use std::sync::Arc;

use bytes::Bytes;
use tokio::io::unix::AsyncFd;
use tokio::io::{AsyncReadExt, AsyncWriteExt, BufReader, Interest};
use tokio::net::tcp::OwnedWriteHalf;
use tokio::net::TcpStream;
use tokio::sync::mpsc;

use self::codec::{next_seq, op, previous_seq, Header, VicpError, HEADER_LEN};
use super::conn::{self, Delivery};
use super::framing::{reserve_for_block, split_end_message};
use super::{Handler, ServerError, ServerHandle, ServerOptions};

const PROTOCOL: &str = "vicp";
/// Reply payloads larger than this are sent as several blocks, EOI on the last.
const MAX_REPLY_BLOCK: usize = 256 << 20;

/// Starts a VICP server on `addr` serving `handler`.
pub async fn serve(
    addr: SocketAddr,
    handler: Arc<dyn Handler>,
    options: ServerOptions,
) -> Result<ServerHandle, ServerError> {
    conn::listen_with_handler(
        PROTOCOL,
        addr,
        handler,
        options,
        serve_connection,
        |e| match e {
            VicpError::Io(io) => Some(io),
            _ => None,
        },
    )
    .await
}

/// State shared by a connection's reader, worker and out-of-band task.
struct Connection {
    handler: Arc<dyn Handler>,
    options: ServerOptions,
    writer: tokio::sync::Mutex<OwnedWriteHalf>,
    /// Bumped by CLEAR: queued work and late replies are dropped.
    generation: AtomicU64,
    /// Sequence number of the last block received (0 until one arrives).
    last_seq: AtomicU8,
    /// Our own numbering, for clients that send 0 (VICP 1).
    own_seq: AtomicU8,
}

impl Connection {
    /// The sequence number for a reply to a command numbered `seq`: the same, never 0.
    fn reply_seq(&self, seq: u8) -> u8 {
        if seq != 0 {
            return seq;
        }
        let previous = self
            .own_seq
            .fetch_update(Ordering::SeqCst, Ordering::SeqCst, |s| Some(next_seq(s)))
            .unwrap_or(0);
        next_seq(previous)
    }

    async fn status_byte(&self) -> u8 {
        let handler = Arc::clone(&self.handler);
        conn::blocking(move || handler.status_byte())
            .await
            .unwrap_or(0)
    }
}

struct Job {
    data: Bytes,
    seq: u8,
    generation: u64,
}

async fn serve_connection(
    stream: TcpStream,
    handler: Arc<dyn Handler>,
    options: ServerOptions,
) -> Result<(), VicpError> {
    let oob_fd = dup_fd(&stream);
    let (reader, writer) = stream.into_split();
    let mut reader = BufReader::with_capacity(64 << 10, reader);
    let connection = Arc::new(Connection {
        handler,
        options,
        writer: tokio::sync::Mutex::new(writer),
        generation: AtomicU64::new(0),
        last_seq: AtomicU8::new(0),
        own_seq: AtomicU8::new(0),
    });
    let oob_task = match oob_fd {
        Ok(fd) => Some(tokio::spawn(serve_out_of_band(fd, Arc::clone(&connection)))),
        Err(err) => {
            tracing::warn!("VICP out-of-band serial poll unavailable: {err}");
            None
        }
    };
    let (jobs, queue) = mpsc::channel::<Job>(64);
    let mut worker = tokio::spawn(run_worker(queue, Arc::clone(&connection)));
    let result = async {
        let max = connection.options.max_message_size;
        let mut input: Vec<u8> = Vec::new();
        loop {
            let mut head = [0u8; HEADER_LEN];
            tokio::select! {
                read = reader.read_exact(&mut head) => { read?; }
                _ = &mut worker => return Ok(()),
            }
            let header = Header::decode(&head)?;
            connection.last_seq.store(header.seq, Ordering::SeqCst);
            if header.op & op::CLEAR != 0 {
                connection.generation.fetch_add(1, Ordering::SeqCst);
                input.clear();
                let handler = Arc::clone(&connection.handler);
                conn::blocking(move || handler.device_clear()).await;
            }
            if header.op & op::SERIAL_POLL != 0 {
                let stb = connection.status_byte().await;
                let reply = Header {
                    op: op::DATA | op::EOI,
                    seq: connection.reply_seq(header.seq),
                    len: 1,
                };
                let mut w = connection.writer.lock().await;
                w.write_all(&[&reply.encode()[..], &[stb]].concat()).await?;
            }
            if input.len() + header.len as usize > max {
                return Err(VicpError::TooLarge {
                    len: header.len,
                    so_far: input.len(),
                    max,
                });
            }
            if header.op & op::DATA == 0 {
                conn::skip_exact(&mut reader, u64::from(header.len)).await?;
                continue;
            }
            let first_chunk = input.is_empty();
            conn::read_exact_append(&mut reader, &mut input, u64::from(header.len)).await?;
            if first_chunk && header.op & op::EOI == 0 {
                reserve_for_block(&mut input, max);
            }
            if header.op & op::EOI != 0 {
                let job = Job {
                    data: std::mem::take(&mut input).into(),
                    seq: header.seq,
                    generation: connection.generation.load(Ordering::SeqCst),
                };
                if jobs.send(job).await.is_err() {
                    return Ok(());
                }
            }
        }
    }
    .await;
    if let Some(task) = oob_task {
        task.abort();
    }
    result
}

async fn run_worker(mut queue: mpsc::Receiver<Job>, connection: Arc<Connection>) {
    while let Some(job) = queue.recv().await {
        let current = || connection.generation.load(Ordering::SeqCst);
        if job.generation != current() {
            continue;
        }
        let messages = match split_end_message(job.data, connection.options.max_message_size) {
            Ok(m) => m,
            Err(err) => {
                tracing::warn!("VICP message refused: {err}");
                continue;
            }
        };
        for message in messages {
            let Some(responses) = conn::call_clearable(
                &connection.handler,
                message,
                &connection.generation,
                job.generation,
            )
            .await
            else {
                return;
            };
            for response in responses {
                let seq = connection.reply_seq(job.seq);
                let parts = response.parts();
                let total: usize = parts.iter().map(Bytes::len).sum();
                let lens = conn::frame_lengths(total, MAX_REPLY_BLOCK);
                let headers: Vec<[u8; HEADER_LEN]> = lens
                    .iter()
                    .enumerate()
                    .map(|(i, &len)| {
                        let eoi = if i + 1 == lens.len() { op::EOI } else { 0 };
                        Header {
                            op: op::DATA | eoi,
                            seq,
                            len: len as u32,
                        }
                        .encode()
                    })
                    .collect();
                let slices = conn::interleave(&headers, &lens, parts);
                let plan = connection.options.faults.plan_reply();
                let mut w = connection.writer.lock().await;
                // A CLEAR that arrives while this reply is written does not stop it: VICP has
                // no clear acknowledgement, and the reply carries the sequence number of the
                // command before the clear, by which the client knows it as stale and drops it.
                if job.generation != current() {
                    continue;
                }
                match conn::write_reply(&mut *w, &slices, plan).await {
                    Ok(Delivery::Dropped) | Err(_) => {
                        let _ = w.shutdown().await;
                        return;
                    }
                    Ok(_) => {}
                }
            }
        }
    }
}

/// A second descriptor for the socket, registered for urgent-data readiness only.
fn dup_fd(stream: &TcpStream) -> io::Result<OwnedFd> {
    // SAFETY: dup on a descriptor we own; the result is checked and owned exactly once.
    let fd = unsafe { libc::dup(stream.as_raw_fd()) };
    if fd < 0 {
        return Err(io::Error::last_os_error());
    }
    // SAFETY: `fd` is a fresh descriptor nobody else owns.
    Ok(unsafe { OwnedFd::from_raw_fd(fd) })
}

/// Answers out-of-band serial polls: urgent byte `'S'` in, urgent status byte out.
async fn serve_out_of_band(fd: OwnedFd, connection: Arc<Connection>) {
    // SAFETY: `fd` is an OwnedFd moved into the AsyncFd: it stays open and unchanged for the
    // AsyncFd's whole life.
    let afd = match unsafe { AsyncFd::register_with_interest(fd, Interest::PRIORITY) } {
        Ok(afd) => afd,
        Err(err) => {
            tracing::warn!("VICP out-of-band serial poll unavailable: {err}");
            return;
        }
    };
    loop {
        // The readiness future does not count against tokio's cooperative budget: without this a
        // readiness that stays set would keep polling here and hold a worker thread.
        tokio::task::consume_budget().await;
        let Ok(mut guard) = afd.ready(Interest::PRIORITY).await else {
            return;
        };
        // Tokio never clears "read closed" or "error": once the peer has sent FIN, `ready`
        // returns at once forever. A peer that cannot send can ask for no more serial polls.
        let finished = guard.ready().is_read_closed() || guard.ready().is_error();
        let mut byte = 0u8;
        // SAFETY: reads at most one byte into a valid local.
        let n = unsafe {
            libc::recv(
                afd.as_raw_fd(),
                (&mut byte as *mut u8).cast(),
                1,
                libc::MSG_OOB | libc::MSG_DONTWAIT,
            )
        };
        if n != 1 {
            let err = io::Error::last_os_error();
            match err.raw_os_error() {
                Some(libc::EAGAIN) | Some(libc::EINVAL) if !finished => {
                    guard.clear_ready();
                    continue;
                }
                _ => return,
            }
        }
        if byte != b'S' {
            tracing::debug!(byte, "VICP: ignoring unknown out-of-band request");
            continue;
        }
        let stb = connection.status_byte().await;
        let last = connection.last_seq.load(Ordering::SeqCst);
        let mut packet = Vec::with_capacity(HEADER_LEN + 1);
        if last != 0 {
            let nudge = Header {
                op: op::DATA,
                seq: previous_seq(last),
                len: 0,
            };
            packet.extend_from_slice(&nudge.encode());
        }
        packet.push(stb);
        // Hold the writer so the nudge block cannot land inside another reply.
        let w = connection.writer.lock().await;
        if send_urgent(w.as_ref().as_raw_fd(), &packet).await.is_err() {
            return;
        }
    }
}

/// Sends `packet` with MSG_OOB: its last byte becomes the urgent byte.
async fn send_urgent(fd: std::os::fd::RawFd, packet: &[u8]) -> io::Result<()> {
    for _ in 0..1000 {
        // SAFETY: sends from a valid slice on a live socket descriptor.
        let n = unsafe {
            libc::send(
                fd,
                packet.as_ptr().cast(),
                packet.len(),
                libc::MSG_OOB | libc::MSG_DONTWAIT,
            )
        };
        if n == packet.len() as isize {
            return Ok(());
        }
        let err = io::Error::last_os_error();
        if n >= 0 || err.raw_os_error() != Some(libc::EAGAIN) {
            return Err(io::Error::new(
                io::ErrorKind::WriteZero,
                "short out-of-band send",
            ));
        }
        tokio::time::sleep(std::time::Duration::from_millis(1)).await;
    }
    Err(io::ErrorKind::TimedOut.into())
}
