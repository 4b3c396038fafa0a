//! HiSLIP 1.0 server (IVI-6.1), synchronized mode.
//!
//! One listening port serves both channels: a connection starting with Initialize becomes a
//! session's synchronous channel (data), one starting with AsyncInitialize attaches to the
//! session named by its parameter and becomes the asynchronous channel (clear, status, lock,
//! max message size). Replies carry the MessageID of the DataEnd that caused them.
//!
//! Choices: any sub-address (`hislip0`, `hislip1`, ...) reaches the same handler; locks are
//! granted or refused at once (no waiting on the lock timeout); overlapped mode is not offered.
//! MAV (status bit 4) is set while a response has been sent but the client has not yet said
//! "response message terminator delivered" (the RMT flag of its next Data/DataEnd/StatusQuery).

pub mod codec;

use std::collections::HashMap;
use std::net::SocketAddr;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

use bytes::Bytes;
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWriteExt, BufReader};
use tokio::net::tcp::OwnedWriteHalf;
use tokio::net::TcpStream;
use tokio::sync::{mpsc, Notify};

use self::codec::{fatal, kind, nonfatal, Header, HislipError, HEADER_LEN};
use super::conn::{self, Delivery};
use super::framing::{reserve_for_block, split_end_message};
use super::{Handler, ServerError, ServerHandle, ServerOptions};

const PROTOCOL: &str = "hislip";
/// Protocol version offered: 1.0.
const SERVER_VERSION: u16 = 0x0100;
/// Vendor ID sent in AsyncInitializeResponse ("ML" for mock_lab).
const VENDOR_ID: u32 = u32::from_be_bytes([0, 0, b'M', b'L']);
/// Largest payload of control messages (Initialize sub-address, lock strings).
const MAX_CONTROL_PAYLOAD: u64 = 4096;
/// Client's maximum message size until it sends AsyncMaxMsgSize (HiSLIP default is 272 bytes,
/// but every client sends AsyncMaxMsgSize first; 1 MiB keeps sane clients fast).
const DEFAULT_CLIENT_MAX: u64 = 1 << 20;
const MAV: u8 = 0x10;

/// Starts a HiSLIP server on `addr` serving `handler`.
pub async fn serve(
    addr: SocketAddr,
    handler: Arc<dyn Handler>,
    options: ServerOptions,
) -> Result<ServerHandle, ServerError> {
    let shared = Arc::new(Shared {
        handler,
        options,
        sessions: Mutex::new(Sessions::default()),
        lock: Mutex::new(LockTable::default()),
    });
    conn::listen(PROTOCOL, addr, move |stream, peer| {
        let shared = Arc::clone(&shared);
        async move {
            let result = serve_connection(stream, shared).await;
            conn::log_end(PROTOCOL, peer, result, |e| match e {
                HislipError::Io(io) => Some(io),
                _ => None,
            });
        }
    })
    .await
}

struct Shared {
    handler: Arc<dyn Handler>,
    options: ServerOptions,
    sessions: Mutex<Sessions>,
    lock: Mutex<LockTable>,
}

#[derive(Default)]
struct Sessions {
    next_id: u16,
    by_id: HashMap<u16, Arc<Session>>,
}

/// State shared by a session's two channels.
struct Session {
    id: u16,
    /// Bumped by AsyncDeviceClear: work and replies from before are dropped.
    clear_generation: AtomicU64,
    /// Between AsyncDeviceClear and DeviceClearComplete: the spec has the server discard every
    /// message arriving on the synchronous channel, so a late query cannot answer the next one.
    clearing: AtomicBool,
    /// Largest message the client accepts (AsyncMaxMsgSize), payload bytes per Data message.
    client_max: AtomicU64,
    /// A response was sent and the client has not confirmed reading it (MAV).
    unread: AtomicBool,
    async_attached: AtomicBool,
    closed: AtomicBool,
    closed_notify: Notify,
}

/// Exclusive lock holder and shared lock holders, across all sessions of the server.
#[derive(Default)]
struct LockTable {
    exclusive: Option<u16>,
    shared_name: Vec<u8>,
    shared: Vec<u16>,
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

async fn read_header<R: AsyncRead + Unpin>(r: &mut R) -> Result<Header, HislipError> {
    let mut bytes = [0u8; HEADER_LEN];
    r.read_exact(&mut bytes).await?;
    Header::decode(&bytes)
}

/// Reads a small control payload, refusing anything over [`MAX_CONTROL_PAYLOAD`].
async fn read_control_payload<R: AsyncRead + Unpin>(
    r: &mut R,
    header: &Header,
) -> Result<Vec<u8>, HislipError> {
    header.check_payload(MAX_CONTROL_PAYLOAD)?;
    let mut payload = Vec::new();
    conn::read_exact_append(r, &mut payload, header.payload_len).await?;
    Ok(payload)
}

/// A header without the "HS" prologue: the FatalError the spec asks for, then the error.
async fn bad_prologue<T>(w: &mut OwnedWriteHalf, prologue: [u8; 2]) -> Result<T, HislipError> {
    send(
        w,
        kind::FATAL_ERROR,
        fatal::POORLY_FORMED_HEADER,
        0,
        b"header must start with HS",
    )
    .await?;
    Err(HislipError::BadPrologue(prologue))
}

/// An Error message from the client (either channel): logged, the session goes on.
async fn log_client_error<R: AsyncRead + Unpin>(reader: &mut R, header: &Header) {
    let text = read_control_payload(reader, header)
        .await
        .unwrap_or_default();
    tracing::warn!(
        code = header.control,
        "HiSLIP client reported an error: {}",
        String::from_utf8_lossy(&text)
    );
}

/// A message type this channel does not take (its payload already skipped): a non-fatal Error.
async fn refuse_message_type(w: &mut OwnedWriteHalf, channel: &str) -> Result<(), HislipError> {
    let text = format!("message type not valid on the {channel} channel");
    send(
        w,
        kind::ERROR,
        nonfatal::UNRECOGNIZED_MESSAGE_TYPE,
        0,
        text.as_bytes(),
    )
    .await
}

async fn send(
    w: &mut OwnedWriteHalf,
    kind: u8,
    control: u8,
    param: u32,
    payload: &[u8],
) -> Result<(), HislipError> {
    w.write_all(&codec::encode_message(kind, control, param, payload))
        .await?;
    Ok(())
}

async fn serve_connection(stream: TcpStream, shared: Arc<Shared>) -> Result<(), HislipError> {
    let (reader, mut writer) = stream.into_split();
    let mut reader = BufReader::with_capacity(64 << 10, reader);
    let first = match read_header(&mut reader).await {
        Ok(h) => h,
        Err(HislipError::BadPrologue(p)) => return bad_prologue(&mut writer, p).await,
        Err(e) => return Err(e),
    };
    match first.kind {
        kind::INITIALIZE => {
            let _sub_address = read_control_payload(&mut reader, &first).await?;
            let client_version = (first.param >> 16) as u16;
            let session = new_session(&shared);
            let version = client_version.min(SERVER_VERSION);
            let param = (u32::from(version) << 16) | u32::from(session.id);
            send(&mut writer, kind::INITIALIZE_RESPONSE, 0, param, &[]).await?;
            let result = serve_sync(reader, writer, &shared, &session).await;
            close_session(&shared, &session);
            result
        }
        kind::ASYNC_INITIALIZE => {
            let id = first.param as u16;
            let session = lock(&shared.sessions).by_id.get(&id).cloned();
            let Some(session) = session.filter(|s| !s.async_attached.swap(true, Ordering::SeqCst))
            else {
                send(
                    &mut writer,
                    kind::FATAL_ERROR,
                    fatal::INVALID_INIT_SEQUENCE,
                    0,
                    b"unknown or already attached session",
                )
                .await?;
                return Err(HislipError::UnknownSession(id));
            };
            send(
                &mut writer,
                kind::ASYNC_INITIALIZE_RESPONSE,
                0,
                VENDOR_ID,
                &[],
            )
            .await?;
            serve_async(reader, writer, &shared, &session).await
        }
        other => {
            send(
                &mut writer,
                kind::FATAL_ERROR,
                fatal::INVALID_INIT_SEQUENCE,
                0,
                b"expected Initialize or AsyncInitialize",
            )
            .await?;
            Err(HislipError::InvalidInitSequence(other))
        }
    }
}

fn new_session(shared: &Shared) -> Arc<Session> {
    let mut sessions = lock(&shared.sessions);
    let mut id = sessions.next_id;
    while id == 0 || sessions.by_id.contains_key(&id) {
        id = id.wrapping_add(1);
    }
    sessions.next_id = id.wrapping_add(1);
    let session = Arc::new(Session {
        id,
        clear_generation: AtomicU64::new(0),
        clearing: AtomicBool::new(false),
        client_max: AtomicU64::new(DEFAULT_CLIENT_MAX),
        unread: AtomicBool::new(false),
        async_attached: AtomicBool::new(false),
        closed: AtomicBool::new(false),
        closed_notify: Notify::new(),
    });
    sessions.by_id.insert(id, Arc::clone(&session));
    session
}

fn close_session(shared: &Shared, session: &Session) {
    lock(&shared.sessions).by_id.remove(&session.id);
    let mut locks = lock(&shared.lock);
    if locks.exclusive == Some(session.id) {
        locks.exclusive = None;
    }
    locks.shared.retain(|&id| id != session.id);
    session.closed.store(true, Ordering::SeqCst);
    session.closed_notify.notify_waiters();
}

/// Work for the synchronous channel's worker, in arrival order.
enum Job {
    Message {
        data: Bytes,
        message_id: u32,
        generation: u64,
    },
    Trigger {
        generation: u64,
    },
}

type SharedWriter = Arc<tokio::sync::Mutex<OwnedWriteHalf>>;

async fn serve_sync<R: AsyncRead + Unpin>(
    mut reader: R,
    writer: OwnedWriteHalf,
    shared: &Arc<Shared>,
    session: &Arc<Session>,
) -> Result<(), HislipError> {
    let writer: SharedWriter = Arc::new(tokio::sync::Mutex::new(writer));
    let (jobs, queue) = mpsc::channel::<Job>(64);
    let mut worker = tokio::spawn(run_worker(
        queue,
        Arc::clone(shared),
        Arc::clone(session),
        Arc::clone(&writer),
    ));
    let max = shared.options.max_message_size as u64;
    let mut input: Vec<u8> = Vec::new();
    let mut refusing = false;
    loop {
        let header = tokio::select! {
            header = read_header(&mut reader) => header,
            _ = &mut worker => return Ok(()),
        };
        let header = match header {
            Ok(h) => h,
            Err(HislipError::BadPrologue(p)) => {
                return bad_prologue(&mut *writer.lock().await, p).await
            }
            Err(e) => return Err(e),
        };
        match header.kind {
            kind::DATA | kind::DATA_END => {
                if header.control & 1 == 1 {
                    session.unread.store(false, Ordering::SeqCst);
                }
                if session.clearing.load(Ordering::SeqCst) {
                    conn::skip_exact(&mut reader, header.payload_len).await?;
                    input = Vec::new();
                    continue;
                }
                if refusing || input.len() as u64 + header.payload_len > max {
                    // Too large: report once, drop the whole message up to its DataEnd.
                    conn::skip_exact(&mut reader, header.payload_len).await?;
                    if !refusing {
                        let mut w = writer.lock().await;
                        send(
                            &mut w,
                            kind::ERROR,
                            nonfatal::MESSAGE_TOO_LARGE,
                            0,
                            b"message exceeds the server's maximum message size",
                        )
                        .await?;
                    }
                    input = Vec::new();
                    refusing = header.kind == kind::DATA;
                    continue;
                }
                let first_chunk = input.is_empty();
                conn::read_exact_append(&mut reader, &mut input, header.payload_len).await?;
                if first_chunk && header.kind == kind::DATA {
                    reserve_for_block(&mut input, shared.options.max_message_size);
                }
                if header.kind == kind::DATA_END {
                    let job = Job::Message {
                        data: std::mem::take(&mut input).into(),
                        message_id: header.param,
                        generation: session.clear_generation.load(Ordering::SeqCst),
                    };
                    if jobs.send(job).await.is_err() {
                        return Ok(());
                    }
                }
            }
            kind::TRIGGER => {
                conn::skip_exact(&mut reader, header.payload_len).await?;
                let generation = session.clear_generation.load(Ordering::SeqCst);
                if jobs.send(Job::Trigger { generation }).await.is_err() {
                    return Ok(());
                }
            }
            kind::DEVICE_CLEAR_COMPLETE => {
                conn::skip_exact(&mut reader, header.payload_len).await?;
                input = Vec::new();
                refusing = false;
                session.clearing.store(false, Ordering::SeqCst);
                let mut w = writer.lock().await;
                // Feature bitmap: synchronized mode only, no encryption.
                send(&mut w, kind::DEVICE_CLEAR_ACKNOWLEDGE, 0, 0, &[]).await?;
            }
            kind::FATAL_ERROR => return Err(HislipError::ClientFatal(header.control)),
            kind::ERROR => log_client_error(&mut reader, &header).await,
            _ => {
                conn::skip_exact(&mut reader, header.payload_len).await?;
                let mut w = writer.lock().await;
                refuse_message_type(&mut w, "synchronous").await?;
            }
        }
    }
}

async fn run_worker(
    mut queue: mpsc::Receiver<Job>,
    shared: Arc<Shared>,
    session: Arc<Session>,
    writer: SharedWriter,
) {
    while let Some(job) = queue.recv().await {
        let (data, message_id, generation) = match job {
            Job::Trigger { generation } => {
                if generation == session.clear_generation.load(Ordering::SeqCst) {
                    let handler = Arc::clone(&shared.handler);
                    if conn::blocking(move || handler.trigger()).await.is_none() {
                        return;
                    }
                }
                continue;
            }
            Job::Message {
                data,
                message_id,
                generation,
            } => (data, message_id, generation),
        };
        if generation != session.clear_generation.load(Ordering::SeqCst) {
            continue;
        }
        let messages = match split_end_message(data, shared.options.max_message_size) {
            Ok(m) => m,
            Err(err) => {
                tracing::warn!("HiSLIP message refused: {err}");
                continue;
            }
        };
        for message in messages {
            let Some(responses) = conn::call_clearable(
                &shared.handler,
                message,
                &session.clear_generation,
                generation,
            )
            .await
            else {
                return;
            };
            for response in responses {
                match send_response(
                    &shared,
                    &session,
                    &writer,
                    response.parts(),
                    message_id,
                    generation,
                )
                .await
                {
                    Ok(Delivery::Dropped) | Err(_) => {
                        let mut w = writer.lock().await;
                        let _ = w.shutdown().await;
                        return;
                    }
                    Ok(_) => {}
                }
            }
        }
    }
}

/// Sends one response (its `parts` back to back) as Data messages ending with DataEnd, each
/// payload within the client's maximum, unless a device clear happened since the message arrived.
/// The payload pieces are slices of the response: nothing is copied.
async fn send_response(
    shared: &Shared,
    session: &Session,
    writer: &SharedWriter,
    parts: &[Bytes],
    message_id: u32,
    generation: u64,
) -> std::io::Result<Delivery> {
    let chunk = usize::try_from(session.client_max.load(Ordering::SeqCst)).unwrap_or(usize::MAX);
    let plan = shared.options.faults.plan_reply();
    let total: usize = parts.iter().map(Bytes::len).sum();
    let lens = conn::frame_lengths(total, chunk);
    let headers: Vec<[u8; HEADER_LEN]> = lens
        .iter()
        .enumerate()
        .map(|(i, &len)| {
            let kind = if i + 1 == lens.len() {
                kind::DATA_END
            } else {
                kind::DATA
            };
            Header::new(kind, 0, message_id, len as u64).encode()
        })
        .collect();
    let slices = conn::interleave(&headers, &lens, parts);
    let mut w = writer.lock().await;
    // Checked under the writer lock: a clear that bumps the generation after this check finds
    // the reply being written, and the DeviceClearAcknowledge it owes on this channel waits for
    // the same lock, so a reply from before the clear can only precede the acknowledgement,
    // where the client discards everything (HiSLIP 2.0, 6.12). Never after it.
    if generation != session.clear_generation.load(Ordering::SeqCst) {
        return Ok(Delivery::Swallowed);
    }
    let delivery = conn::write_reply(&mut *w, &slices, plan).await?;
    if delivery == Delivery::Sent {
        session.unread.store(true, Ordering::SeqCst);
    }
    Ok(delivery)
}

async fn serve_async<R: AsyncRead + Unpin>(
    mut reader: R,
    mut writer: OwnedWriteHalf,
    shared: &Arc<Shared>,
    session: &Arc<Session>,
) -> Result<(), HislipError> {
    loop {
        let closed = session.closed_notify.notified();
        if session.closed.load(Ordering::SeqCst) {
            return Ok(());
        }
        let header = tokio::select! {
            header = read_header(&mut reader) => header,
            _ = closed => return Ok(()),
        };
        let header = match header {
            Ok(h) => h,
            Err(HislipError::BadPrologue(p)) => return bad_prologue(&mut writer, p).await,
            Err(e) => return Err(e),
        };
        match header.kind {
            kind::ASYNC_MAX_MSG_SIZE => {
                let payload = read_control_payload(&mut reader, &header).await?;
                let Ok(bytes) = <[u8; 8]>::try_from(payload.as_slice()) else {
                    send(
                        &mut writer,
                        kind::ERROR,
                        nonfatal::UNRECOGNIZED_CONTROL_CODE,
                        0,
                        b"AsyncMaxMsgSize needs an 8-byte payload",
                    )
                    .await?;
                    continue;
                };
                let client_max = u64::from_be_bytes(bytes);
                // The client's maximum counts the header; keep at least one payload byte.
                let payload_max = client_max.saturating_sub(HEADER_LEN as u64).max(1);
                session.client_max.store(payload_max, Ordering::SeqCst);
                let server_max = shared.options.max_message_size as u64 + HEADER_LEN as u64;
                send(
                    &mut writer,
                    kind::ASYNC_MAX_MSG_SIZE_RESPONSE,
                    0,
                    0,
                    &server_max.to_be_bytes(),
                )
                .await?;
            }
            kind::ASYNC_DEVICE_CLEAR => {
                conn::skip_exact(&mut reader, header.payload_len).await?;
                session.clearing.store(true, Ordering::SeqCst);
                session.clear_generation.fetch_add(1, Ordering::SeqCst);
                session.unread.store(false, Ordering::SeqCst);
                let handler = Arc::clone(&shared.handler);
                conn::blocking(move || handler.device_clear()).await;
                send(&mut writer, kind::ASYNC_DEVICE_CLEAR_ACKNOWLEDGE, 0, 0, &[]).await?;
            }
            kind::ASYNC_STATUS_QUERY => {
                conn::skip_exact(&mut reader, header.payload_len).await?;
                if header.control & 1 == 1 {
                    session.unread.store(false, Ordering::SeqCst);
                }
                let handler = Arc::clone(&shared.handler);
                let mut stb = conn::blocking(move || handler.status_byte())
                    .await
                    .unwrap_or(0);
                if session.unread.load(Ordering::SeqCst) {
                    stb |= MAV;
                }
                send(&mut writer, kind::ASYNC_STATUS_RESPONSE, stb, 0, &[]).await?;
            }
            kind::ASYNC_LOCK => {
                let lock_name = read_control_payload(&mut reader, &header).await?;
                let answer = lock_request(shared, session.id, header.control, &lock_name);
                send(&mut writer, kind::ASYNC_LOCK_RESPONSE, answer, 0, &[]).await?;
            }
            kind::ASYNC_LOCK_INFO => {
                conn::skip_exact(&mut reader, header.payload_len).await?;
                let (exclusive, holders) = {
                    let locks = lock(&shared.lock);
                    let exclusive = u8::from(locks.exclusive.is_some());
                    (exclusive, locks.shared.len() as u32 + u32::from(exclusive))
                };
                send(
                    &mut writer,
                    kind::ASYNC_LOCK_INFO_RESPONSE,
                    exclusive,
                    holders,
                    &[],
                )
                .await?;
            }
            kind::ASYNC_REMOTE_LOCAL_CONTROL => {
                conn::skip_exact(&mut reader, header.payload_len).await?;
                send(&mut writer, kind::ASYNC_REMOTE_LOCAL_RESPONSE, 0, 0, &[]).await?;
            }
            kind::FATAL_ERROR => return Err(HislipError::ClientFatal(header.control)),
            kind::ERROR => log_client_error(&mut reader, &header).await,
            _ => {
                conn::skip_exact(&mut reader, header.payload_len).await?;
                refuse_message_type(&mut writer, "asynchronous").await?;
            }
        }
    }
}

/// AsyncLock: control 1 requests (empty name = exclusive, else shared), 0 releases.
/// Answers: 0 failure, 1 success (exclusive / release), 2 shared success, 3 error.
fn lock_request(shared: &Shared, id: u16, control: u8, name: &[u8]) -> u8 {
    let mut locks = lock(&shared.lock);
    match control {
        1 if name.is_empty() => {
            let others_share = locks.shared.iter().any(|&s| s != id);
            match locks.exclusive {
                Some(owner) if owner == id => 1,
                None if !others_share => {
                    locks.exclusive = Some(id);
                    1
                }
                _ => 0,
            }
        }
        1 => {
            if locks.exclusive.is_some_and(|owner| owner != id) {
                return 0;
            }
            if !locks.shared.is_empty() && locks.shared_name != name {
                return 0;
            }
            locks.shared_name = name.to_vec();
            if !locks.shared.contains(&id) {
                locks.shared.push(id);
            }
            2
        }
        0 => {
            if locks.exclusive == Some(id) {
                locks.exclusive = None;
                1
            } else if locks.shared.contains(&id) {
                locks.shared.retain(|&s| s != id);
                1
            } else {
                3
            }
        }
        _ => 3,
    }
}
