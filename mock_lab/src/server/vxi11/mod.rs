//! VXI-11 server: core channel (program 0x0607AF), abort channel (0x0607B0) and an optional
//! portmapper (program 100000, GETPORT over TCP).
//!
//! The core channel is reachable directly on its own port, so clients can skip the portmapper
//! (pyvisa-py: `TCPIP::127.0.0.1,PORT::inst0::INSTR`). A device_write with the END flag
//! completes a message; a per-link worker runs the handler, so the write returns at once and
//! the following device_read waits (up to its io_timeout) for the response, just as with a real
//! instrument. device_abort on the abort channel ends a waiting device_read with error 23.
//!
//! Choices: any device name (`inst0`, `inst1`, ...) reaches the same handler; one exclusive
//! lock per server (create_link with lockDevice and device_lock wait up to lock_timeout, reads
//! and writes with the waitlock flag wait for it too, otherwise a locked device answers error
//! 11 at once); SRQ interrupt channels are not offered (create_intr_chan and enable_srq answer
//! "operation not supported").

pub mod rpc;
pub(crate) mod xdr;

use std::collections::{HashMap, VecDeque};
use std::net::SocketAddr;
use std::sync::atomic::{AtomicBool, AtomicI32, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, Weak};
use std::time::Duration;

use bytes::Bytes;
use tokio::io::{AsyncWrite, BufReader};
use tokio::net::TcpStream;
use tokio::sync::{mpsc, Notify};

use self::rpc::{accept, Call, RpcError};
use self::xdr::{pad, XdrReader, XdrWriter};
use super::conn::{self, Delivery};
use super::framing::{reserve_for_block, split_end_message};
use super::{Handler, ServerError, ServerHandle, ServerOptions};
use crate::faults::{ReplyFate, ReplyPlan};

const PROTOCOL: &str = "vxi11";
/// VXI-11 core program.
pub(crate) const CORE_PROGRAM: u32 = 0x0607AF;
/// VXI-11 abort program.
pub(crate) const ABORT_PROGRAM: u32 = 0x0607B0;
/// Portmapper program.
pub(crate) const PORTMAP_PROGRAM: u32 = 100_000;
/// Versions of the programs served: portmapper 2, VXI-11 core and abort 1.
pub(crate) const PORTMAP_VERSION: u32 = 2;
pub(crate) const VXI11_VERSION: u32 = 1;
/// The portmapper's protocol number for TCP.
pub const IPPROTO_TCP: u32 = 6;

/// Procedure numbers (VXI-11 specification B.6, RFC 1833 for the portmapper).
pub(crate) mod procedure {
    /// Portmapper: ping.
    pub(crate) const PMAP_NULL: u32 = 0;
    /// Portmapper: the port of a program and version.
    pub(crate) const PMAP_GETPORT: u32 = 3;
    /// Abort channel.
    pub(crate) const DEVICE_ABORT: u32 = 1;
    pub(crate) const CREATE_LINK: u32 = 10;
    pub(crate) const DEVICE_WRITE: u32 = 11;
    pub(crate) const DEVICE_READ: u32 = 12;
    pub(crate) const DEVICE_READSTB: u32 = 13;
    pub(crate) const DEVICE_TRIGGER: u32 = 14;
    pub(crate) const DEVICE_CLEAR: u32 = 15;
    pub(crate) const DEVICE_REMOTE: u32 = 16;
    pub(crate) const DEVICE_LOCAL: u32 = 17;
    pub(crate) const DEVICE_LOCK: u32 = 18;
    pub(crate) const DEVICE_UNLOCK: u32 = 19;
    pub(crate) const DEVICE_ENABLE_SRQ: u32 = 20;
    pub(crate) const DEVICE_DOCMD: u32 = 22;
    pub(crate) const DESTROY_LINK: u32 = 23;
    pub(crate) const CREATE_INTR_CHAN: u32 = 25;
    pub(crate) const DESTROY_INTR_CHAN: u32 = 26;
}
/// Records beyond the data itself: RPC and VXI-11 headers.
const RECORD_OVERHEAD: usize = 4096;
/// Longest device name accepted by create_link.
const MAX_DEVICE_NAME: usize = 256;
const MAV: u8 = 0x10;

/// VXI-11 error codes (Device_ErrorCode).
pub(crate) mod code {
    pub(crate) const NO_ERROR: i32 = 0;
    pub(crate) const INVALID_LINK: i32 = 4;
    pub(crate) const PARAMETER_ERROR: i32 = 5;
    pub(crate) const NOT_SUPPORTED: i32 = 8;
    pub(crate) const OUT_OF_RESOURCES: i32 = 9;
    pub(crate) const DEVICE_LOCKED: i32 = 11;
    pub(crate) const NO_LOCK_HELD: i32 = 12;
    pub(crate) const IO_TIMEOUT: i32 = 15;
    pub(crate) const ABORT: i32 = 23;
}

/// device_read reasons.
pub(crate) mod reason {
    pub(crate) const REQCNT: i32 = 1;
    pub(crate) const CHR: i32 = 2;
    pub(crate) const END: i32 = 4;
}

/// device_write flag: last chunk of the message.
const FLAG_END: i32 = 0x08;
/// Flag: wait up to lock_timeout for a lock held by another link instead of failing.
const FLAG_WAITLOCK: i32 = 0x01;
/// device_read flag: stop at termChar.
const FLAG_TERMCHAR: i32 = 0x80;

/// Where the VXI-11 server listens.
#[derive(Debug, Clone, Copy)]
pub struct Vxi11Addresses {
    /// Core channel.
    pub core: SocketAddr,
    /// Abort channel.
    pub abort: SocketAddr,
    /// Portmapper (None: no portmapper; clients must name the core port).
    pub portmapper: Option<SocketAddr>,
}

impl Vxi11Addresses {
    /// Core and abort on OS-chosen loopback ports, no portmapper.
    pub fn loopback() -> Self {
        Vxi11Addresses {
            core: super::loopback_any(),
            abort: super::loopback_any(),
            portmapper: None,
        }
    }
}

/// Starts a VXI-11 server. The handle's `local_addr` is the core channel; `listener("abort")`
/// and `listener("portmapper")` give the others.
pub async fn serve(
    addrs: Vxi11Addresses,
    handler: Arc<dyn Handler>,
    options: ServerOptions,
) -> Result<ServerHandle, ServerError> {
    let core = super::bind(PROTOCOL, addrs.core).await?;
    let abort = super::bind(PROTOCOL, addrs.abort).await?;
    let local = |l: &tokio::net::TcpListener| {
        l.local_addr().map_err(|source| ServerError::Start {
            protocol: PROTOCOL,
            source,
        })
    };
    let core_addr = local(&core)?;
    let abort_addr = local(&abort)?;
    let shared = Arc::new(Shared {
        handler,
        options,
        abort_port: abort_addr.port(),
        links: Mutex::new(HashMap::new()),
        next_link: AtomicI32::new(1),
        lock_owner: Mutex::new(None),
        lock_released: Notify::new(),
    });
    let core_shared = Arc::clone(&shared);
    let core_task = tokio::spawn(conn::accept_loop(core, PROTOCOL, move |stream, peer| {
        let shared = Arc::clone(&core_shared);
        async move {
            let result = serve_core(stream, &shared).await;
            conn::log_end(PROTOCOL, peer, result, rpc_io);
        }
    }));
    let mut handle = ServerHandle::new(PROTOCOL, core_addr, core_task);
    let abort_shared = Arc::clone(&shared);
    let abort_task = tokio::spawn(conn::accept_loop(abort, PROTOCOL, move |stream, peer| {
        let shared = Arc::clone(&abort_shared);
        async move {
            let result = serve_abort(stream, &shared).await;
            conn::log_end(PROTOCOL, peer, result, rpc_io);
        }
    }));
    handle.add_listener("abort", abort_addr, abort_task);
    if let Some(pm_addr) = addrs.portmapper {
        let pm = super::bind("portmapper", pm_addr).await?;
        let pm_local = local(&pm)?;
        let core_port = core_addr.port();
        let pm_task = tokio::spawn(conn::accept_loop(
            pm,
            "portmapper",
            move |stream, peer| async move {
                let result = serve_portmapper(stream, core_port).await;
                conn::log_end("portmapper", peer, result, rpc_io);
            },
        ));
        handle.add_listener("portmapper", pm_local, pm_task);
    }
    Ok(handle)
}

fn rpc_io(e: &RpcError) -> Option<&std::io::Error> {
    match e {
        RpcError::Io(io) => Some(io),
        _ => None,
    }
}

struct Shared {
    handler: Arc<dyn Handler>,
    options: ServerOptions,
    abort_port: u16,
    links: Mutex<HashMap<i32, Arc<Link>>>,
    next_link: AtomicI32,
    lock_owner: Mutex<Option<i32>>,
    /// Signalled whenever the lock is released.
    lock_released: Notify,
}

struct Link {
    id: i32,
    state: Mutex<LinkState>,
    output_ready: Notify,
    aborted: AtomicBool,
    /// Bumped by device_clear: queued work and late responses are dropped.
    generation: AtomicU64,
    jobs: mpsc::UnboundedSender<Job>,
}

#[derive(Default)]
struct LinkState {
    input: Vec<u8>,
    output: VecDeque<Pending>,
}

/// A response waiting to be read (what is left of its pieces), with the faults chosen for it.
struct Pending {
    parts: VecDeque<Bytes>,
    byte_segments: bool,
    drop_midway: bool,
}

enum Job {
    Message(Bytes, u64),
    Trigger(u64),
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// Writes one RPC reply record made of `body` followed by `data` (pieces sent back to back, not
/// joined) and its XDR padding.
async fn write_record<W: AsyncWrite + Unpin>(
    w: &mut W,
    body: &XdrWriter,
    data: &[Bytes],
    plan: ReplyPlan,
) -> std::io::Result<Delivery> {
    let len: usize = data.iter().map(Bytes::len).sum();
    let padding = [0u8; 3];
    let padding = &padding[..pad(len)];
    let mark = rpc::fragment_header(body.buf.len() + len + padding.len());
    let mut slices: Vec<&[u8]> = Vec::with_capacity(data.len() + 3);
    slices.push(&mark);
    slices.push(&body.buf);
    slices.extend(data.iter().map(|d| &d[..]));
    slices.push(padding);
    conn::write_reply(w, &slices, plan).await
}

async fn write_plain<W: AsyncWrite + Unpin>(
    w: &mut W,
    body: &XdrWriter,
) -> std::io::Result<Delivery> {
    write_record(w, body, &[], ReplyPlan::CLEAN).await
}

/// Handles the RPC header checks shared by every channel: `Ok(call)` when the call is for
/// `program` v`version`, else the error reply was already sent and `Err(())` is returned.
async fn check_call<W: AsyncWrite + Unpin>(
    w: &mut W,
    r: &mut XdrReader<'_>,
    program: u32,
    version: u32,
) -> Result<Option<Call>, RpcError> {
    let call = rpc::decode_call(r)?;
    if call.rpc_version != rpc::RPC_VERSION {
        write_plain(w, &rpc::rpc_mismatch_reply(call.xid)).await?;
        return Ok(None);
    }
    if call.program != program {
        write_plain(
            w,
            &rpc::accepted_reply(call.xid, accept::PROG_UNAVAIL, (0, 0)),
        )
        .await?;
        return Ok(None);
    }
    if call.version != version {
        let reply = rpc::accepted_reply(call.xid, accept::PROG_MISMATCH, (version, version));
        write_plain(w, &reply).await?;
        return Ok(None);
    }
    Ok(Some(call))
}

async fn serve_portmapper(stream: TcpStream, core_port: u16) -> Result<(), RpcError> {
    let (reader, mut writer) = stream.into_split();
    let mut reader = BufReader::new(reader);
    while let Some(record) = rpc::read_record(&mut reader, RECORD_OVERHEAD).await? {
        let mut r = XdrReader::new(&record);
        let Some(call) = check_call(&mut writer, &mut r, PORTMAP_PROGRAM, PORTMAP_VERSION).await?
        else {
            continue;
        };
        let reply = match call.procedure {
            procedure::PMAP_NULL => rpc::accepted_reply(call.xid, accept::SUCCESS, (0, 0)),
            procedure::PMAP_GETPORT => match (r.u32(), r.u32(), r.u32()) {
                (Ok(prog), Ok(vers), Ok(prot)) => {
                    let port =
                        if prog == CORE_PROGRAM && vers == VXI11_VERSION && prot == IPPROTO_TCP {
                            u32::from(core_port)
                        } else {
                            0
                        };
                    let mut w = rpc::accepted_reply(call.xid, accept::SUCCESS, (0, 0));
                    w.u32(port);
                    w
                }
                _ => rpc::accepted_reply(call.xid, accept::GARBAGE_ARGS, (0, 0)),
            },
            _ => rpc::accepted_reply(call.xid, accept::PROC_UNAVAIL, (0, 0)),
        };
        write_plain(&mut writer, &reply).await?;
    }
    Ok(())
}

async fn serve_abort(stream: TcpStream, shared: &Shared) -> Result<(), RpcError> {
    let (reader, mut writer) = stream.into_split();
    let mut reader = BufReader::new(reader);
    while let Some(record) = rpc::read_record(&mut reader, RECORD_OVERHEAD).await? {
        let mut r = XdrReader::new(&record);
        let Some(call) = check_call(&mut writer, &mut r, ABORT_PROGRAM, VXI11_VERSION).await?
        else {
            continue;
        };
        let reply = match (call.procedure, r.i32()) {
            (procedure::DEVICE_ABORT, Ok(lid)) => {
                let link = lock(&shared.links).get(&lid).cloned();
                let error = match link {
                    Some(link) => {
                        link.aborted.store(true, Ordering::SeqCst);
                        link.output_ready.notify_waiters();
                        code::NO_ERROR
                    }
                    None => code::INVALID_LINK,
                };
                let mut w = rpc::accepted_reply(call.xid, accept::SUCCESS, (0, 0));
                w.i32(error);
                w
            }
            (procedure::DEVICE_ABORT, Err(_)) => {
                rpc::accepted_reply(call.xid, accept::GARBAGE_ARGS, (0, 0))
            }
            _ => rpc::accepted_reply(call.xid, accept::PROC_UNAVAIL, (0, 0)),
        };
        write_plain(&mut writer, &reply).await?;
    }
    Ok(())
}

async fn serve_core(stream: TcpStream, shared: &Arc<Shared>) -> Result<(), RpcError> {
    let (reader, mut writer) = stream.into_split();
    let mut reader = BufReader::with_capacity(64 << 10, reader);
    let mut own_links: Vec<i32> = Vec::new();
    let max_record = shared.options.max_message_size + RECORD_OVERHEAD;
    let result = async {
        while let Some(record) = rpc::read_record(&mut reader, max_record).await? {
            let mut r = XdrReader::new(&record);
            let Some(call) = check_call(&mut writer, &mut r, CORE_PROGRAM, VXI11_VERSION).await?
            else {
                continue;
            };
            if call.procedure == procedure::DEVICE_WRITE {
                // device_write owns the record, so a large upload is not copied again.
                let args_at = record.len() - r.remaining();
                let parsed = parse_device_write(&record, args_at, shared.options.max_message_size);
                let reply = match parsed {
                    Ok((lid, flags, lock_timeout, range)) => {
                        if flags & FLAG_WAITLOCK != 0 {
                            wait_unlocked(shared, lid, lock_timeout).await;
                        }
                        let (error, size) = device_write(shared, lid, flags, record, range);
                        let mut w = success(call.xid);
                        w.i32(error).u32(size);
                        w
                    }
                    Err(_) => rpc::accepted_reply(call.xid, accept::GARBAGE_ARGS, (0, 0)),
                };
                write_plain(&mut writer, &reply).await?;
                continue;
            }
            let outcome =
                match core_procedure(shared, &call, &mut r, &mut own_links, &mut writer).await {
                    Ok(outcome) => outcome,
                    Err(RpcError::Xdr(_)) => {
                        let reply = rpc::accepted_reply(call.xid, accept::GARBAGE_ARGS, (0, 0));
                        write_plain(&mut writer, &reply).await?
                    }
                    Err(e) => return Err(e),
                };
            if outcome == Delivery::Dropped {
                return Ok(());
            }
        }
        Ok(())
    }
    .await;
    for lid in own_links {
        destroy_link(shared, lid);
    }
    result
}

fn success(xid: u32) -> XdrWriter {
    rpc::accepted_reply(xid, accept::SUCCESS, (0, 0))
}

fn error_only(xid: u32, error: i32) -> XdrWriter {
    let mut w = success(xid);
    w.i32(error);
    w
}

/// Runs one core-channel procedure and writes its reply.
async fn core_procedure<W: AsyncWrite + Unpin>(
    shared: &Arc<Shared>,
    call: &Call,
    r: &mut XdrReader<'_>,
    own_links: &mut Vec<i32>,
    w: &mut W,
) -> Result<Delivery, RpcError> {
    let xid = call.xid;
    let reply = match call.procedure {
        procedure::CREATE_LINK => create_link_reply(shared, xid, r, own_links).await?,
        procedure::DEVICE_READ => {
            let lid = r.i32()?;
            let request_size = r.u32()?;
            let io_timeout = r.u32()?;
            let lock_timeout = r.u32()?;
            let flags = r.i32()?;
            let term_char = r.i32()? as u8;
            let term = (flags & FLAG_TERMCHAR != 0).then_some(term_char);
            if flags & FLAG_WAITLOCK != 0 {
                wait_unlocked(shared, lid, lock_timeout).await;
            }
            return device_read(shared, xid, lid, request_size, io_timeout, term, w).await;
        }
        procedure::DEVICE_READSTB => read_stb_reply(shared, xid, r.i32()?).await,
        procedure::DEVICE_TRIGGER => {
            let lid = r.i32()?;
            let error = match find_link(shared, lid) {
                Some(link) => {
                    let generation = link.generation.load(Ordering::SeqCst);
                    let _ = link.jobs.send(Job::Trigger(generation));
                    code::NO_ERROR
                }
                None => code::INVALID_LINK,
            };
            error_only(xid, error)
        }
        procedure::DEVICE_CLEAR => error_only(xid, device_clear(shared, r.i32()?).await),
        procedure::DEVICE_REMOTE | procedure::DEVICE_LOCAL => {
            let lid = r.i32()?;
            error_only(
                xid,
                if find_link(shared, lid).is_some() {
                    code::NO_ERROR
                } else {
                    code::INVALID_LINK
                },
            )
        }
        procedure::DEVICE_LOCK => error_only(xid, device_lock(shared, r).await?),
        procedure::DEVICE_UNLOCK => {
            let lid = r.i32()?;
            let error = if find_link(shared, lid).is_none() {
                code::INVALID_LINK
            } else if unlock(shared, lid) {
                code::NO_ERROR
            } else {
                code::NO_LOCK_HELD
            };
            error_only(xid, error)
        }
        procedure::DEVICE_ENABLE_SRQ
        | procedure::CREATE_INTR_CHAN
        | procedure::DESTROY_INTR_CHAN => error_only(xid, code::NOT_SUPPORTED),
        procedure::DEVICE_DOCMD => {
            let mut w = success(xid);
            w.i32(code::NOT_SUPPORTED).opaque(&[]);
            w
        }
        procedure::DESTROY_LINK => {
            let lid = r.i32()?;
            let error = if own_links.contains(&lid) {
                own_links.retain(|&l| l != lid);
                destroy_link(shared, lid);
                code::NO_ERROR
            } else {
                code::INVALID_LINK
            };
            error_only(xid, error)
        }
        _ => rpc::accepted_reply(xid, accept::PROC_UNAVAIL, (0, 0)),
    };
    Ok(write_plain(w, &reply).await?)
}

/// create_link: a new link, locked at once when asked (waiting up to the lock timeout).
async fn create_link_reply(
    shared: &Arc<Shared>,
    xid: u32,
    r: &mut XdrReader<'_>,
    own_links: &mut Vec<i32>,
) -> Result<XdrWriter, RpcError> {
    let _client_id = r.i32()?;
    let lock_device = r.bool()?;
    let lock_timeout = r.u32()?;
    let _device = r.opaque(MAX_DEVICE_NAME)?;
    let link = create_link(shared);
    let mut error = code::NO_ERROR;
    if lock_device && !acquire_lock(shared, link.id, lock_timeout).await {
        error = code::DEVICE_LOCKED;
    }
    let lid = if error == code::NO_ERROR {
        own_links.push(link.id);
        link.id
    } else {
        destroy_link(shared, link.id);
        0
    };
    let mut w = success(xid);
    w.i32(error)
        .i32(lid)
        .u32(u32::from(shared.abort_port))
        .u32(shared.options.max_message_size.min(u32::MAX as usize) as u32);
    Ok(w)
}

/// device_readstb: the instrument's status byte, with MAV set while a reply waits.
async fn read_stb_reply(shared: &Arc<Shared>, xid: u32, lid: i32) -> XdrWriter {
    let mut w = success(xid);
    match find_link(shared, lid) {
        Some(link) => {
            let handler = Arc::clone(&shared.handler);
            let mut stb = conn::blocking(move || handler.status_byte())
                .await
                .unwrap_or(0);
            if !lock(&link.state).output.is_empty() {
                stb |= MAV;
            }
            w.i32(code::NO_ERROR).u32(u32::from(stb));
        }
        None => {
            w.i32(code::INVALID_LINK).u32(0);
        }
    }
    w
}

/// device_clear: pending input and output dropped, jobs of the old generation abandoned, the
/// instrument told.
async fn device_clear(shared: &Arc<Shared>, lid: i32) -> i32 {
    let Some(link) = find_link(shared, lid) else {
        return code::INVALID_LINK;
    };
    link.generation.fetch_add(1, Ordering::SeqCst);
    {
        let mut st = lock(&link.state);
        st.input.clear();
        st.output.clear();
    }
    let handler = Arc::clone(&shared.handler);
    conn::blocking(move || handler.device_clear()).await;
    code::NO_ERROR
}

/// device_lock: the lock, waiting for it only when the flags say so.
async fn device_lock(shared: &Arc<Shared>, r: &mut XdrReader<'_>) -> Result<i32, RpcError> {
    let lid = r.i32()?;
    let flags = r.i32()?;
    let lock_timeout = r.u32()?;
    let wait = if flags & FLAG_WAITLOCK != 0 {
        lock_timeout
    } else {
        0
    };
    Ok(if find_link(shared, lid).is_none() {
        code::INVALID_LINK
    } else if acquire_lock(shared, lid, wait).await {
        code::NO_ERROR
    } else {
        code::DEVICE_LOCKED
    })
}

fn find_link(shared: &Shared, lid: i32) -> Option<Arc<Link>> {
    lock(&shared.links).get(&lid).cloned()
}

fn try_lock(shared: &Shared, lid: i32) -> bool {
    let mut owner = lock(&shared.lock_owner);
    match *owner {
        Some(o) => o == lid,
        None => {
            *owner = Some(lid);
            true
        }
    }
}

/// Takes the lock for `lid`, waiting up to `wait_ms` while another link holds it.
async fn acquire_lock(shared: &Shared, lid: i32, wait_ms: u32) -> bool {
    let deadline = tokio::time::Instant::now() + Duration::from_millis(u64::from(wait_ms));
    loop {
        let released = shared.lock_released.notified();
        tokio::pin!(released);
        released.as_mut().enable();
        if try_lock(shared, lid) {
            return true;
        }
        if tokio::time::timeout_at(deadline, released).await.is_err() {
            return false;
        }
    }
}

/// Waits up to `wait_ms` until no other link holds the lock.
async fn wait_unlocked(shared: &Shared, lid: i32, wait_ms: u32) {
    let deadline = tokio::time::Instant::now() + Duration::from_millis(u64::from(wait_ms));
    loop {
        let released = shared.lock_released.notified();
        tokio::pin!(released);
        released.as_mut().enable();
        if !locked_by_other(shared, lid) {
            return;
        }
        if tokio::time::timeout_at(deadline, released).await.is_err() {
            return;
        }
    }
}

fn unlock(shared: &Shared, lid: i32) -> bool {
    let mut owner = lock(&shared.lock_owner);
    if *owner == Some(lid) {
        *owner = None;
        shared.lock_released.notify_waiters();
        true
    } else {
        false
    }
}

fn locked_by_other(shared: &Shared, lid: i32) -> bool {
    lock(&shared.lock_owner).is_some_and(|o| o != lid)
}

fn create_link(shared: &Arc<Shared>) -> Arc<Link> {
    let id = shared.next_link.fetch_add(1, Ordering::SeqCst);
    let (jobs, queue) = mpsc::unbounded_channel();
    let link = Arc::new(Link {
        id,
        state: Mutex::new(LinkState::default()),
        output_ready: Notify::new(),
        aborted: AtomicBool::new(false),
        generation: AtomicU64::new(0),
        jobs,
    });
    lock(&shared.links).insert(id, Arc::clone(&link));
    tokio::spawn(run_worker(Arc::clone(shared), Arc::downgrade(&link), queue));
    link
}

fn destroy_link(shared: &Shared, lid: i32) {
    // Dropping the link drops its job sender, which ends its worker.
    lock(&shared.links).remove(&lid);
    unlock(shared, lid);
}

/// Device_WriteParms: lid, flags, lock_timeout and the data's byte range in the record.
type DeviceWriteArgs = (i32, i32, u32, std::ops::Range<usize>);

/// Decodes Device_WriteParms starting at `at`.
fn parse_device_write(record: &[u8], at: usize, max: usize) -> Result<DeviceWriteArgs, RpcError> {
    let mut r = XdrReader::new(&record[at..]);
    let lid = r.i32()?;
    let _io_timeout = r.u32()?;
    let lock_timeout = r.u32()?;
    let flags = r.i32()?;
    let data = r.opaque(max)?;
    let start = data.as_ptr() as usize - record.as_ptr() as usize;
    Ok((lid, flags, lock_timeout, start..start + data.len()))
}

/// Appends the written bytes (`record[range]`) to the link's input; on END, queues the message
/// for the worker. A one-chunk message reuses the record's buffer instead of copying it.
fn device_write(
    shared: &Shared,
    lid: i32,
    flags: i32,
    record: Vec<u8>,
    range: std::ops::Range<usize>,
) -> (i32, u32) {
    let size = range.len() as u32;
    let Some(link) = find_link(shared, lid) else {
        return (code::INVALID_LINK, 0);
    };
    if locked_by_other(shared, lid) {
        return (code::DEVICE_LOCKED, 0);
    }
    let mut st = lock(&link.state);
    if st.input.len() + range.len() > shared.options.max_message_size {
        st.input = Vec::new();
        return (code::OUT_OF_RESOURCES, 0);
    }
    if flags & FLAG_END != 0 {
        let message = if st.input.is_empty() {
            // A view of the record: the data is not moved to the front (a 64 MB memmove).
            Bytes::from(record).slice(range)
        } else {
            let mut m = std::mem::take(&mut st.input);
            m.extend_from_slice(&record[range]);
            Bytes::from(m)
        };
        let generation = link.generation.load(Ordering::SeqCst);
        if link.jobs.send(Job::Message(message, generation)).is_err() {
            return (code::PARAMETER_ERROR, 0);
        }
    } else {
        let first_chunk = st.input.is_empty();
        st.input.extend_from_slice(&record[range]);
        if first_chunk {
            reserve_for_block(&mut st.input, shared.options.max_message_size);
        }
    }
    (code::NO_ERROR, size)
}

/// Waits (up to `io_timeout` ms) for output and returns at most `request_size` bytes of it.
async fn device_read<W: AsyncWrite + Unpin>(
    shared: &Shared,
    xid: u32,
    lid: i32,
    request_size: u32,
    io_timeout: u32,
    term: Option<u8>,
    w: &mut W,
) -> Result<Delivery, RpcError> {
    let read_reply = |error: i32, reason: i32, len: usize| {
        let mut body = success(xid);
        body.i32(error).i32(reason).u32(len as u32);
        body
    };
    let Some(link) = find_link(shared, lid) else {
        return Ok(write_plain(w, &read_reply(code::INVALID_LINK, 0, 0)).await?);
    };
    if locked_by_other(shared, lid) {
        return Ok(write_plain(w, &read_reply(code::DEVICE_LOCKED, 0, 0)).await?);
    }
    let deadline = tokio::time::Instant::now() + Duration::from_millis(u64::from(io_timeout));
    let request = (request_size as usize).max(1);
    loop {
        let notified = link.output_ready.notified();
        tokio::pin!(notified);
        notified.as_mut().enable();
        if link.aborted.swap(false, Ordering::SeqCst) {
            return Ok(write_plain(w, &read_reply(code::ABORT, 0, 0)).await?);
        }
        let taken = take_output(&link, request, term);
        if let Some((data, reason, plan)) = taken {
            let len = data.iter().map(Bytes::len).sum();
            let body = read_reply(code::NO_ERROR, reason, len);
            return Ok(write_record(w, &body, &data, plan).await?);
        }
        if tokio::time::timeout_at(deadline, notified).await.is_err() {
            return Ok(write_plain(w, &read_reply(code::IO_TIMEOUT, 0, 0)).await?);
        }
    }
}

/// Takes up to `request` bytes of the oldest response, stopping after `term` when set. The bytes
/// are views of the response's pieces (no copy).
fn take_output(
    link: &Link,
    request: usize,
    term: Option<u8>,
) -> Option<(Vec<Bytes>, i32, ReplyPlan)> {
    let mut st = lock(&link.state);
    let pending = st.output.front_mut()?;
    let mut data = Vec::new();
    let mut n = 0;
    let mut reason = 0;
    while n < request {
        let Some(part) = pending.parts.front_mut() else {
            break;
        };
        let mut take = part.len().min(request - n);
        if let Some(t) = term {
            if let Some(pos) = part[..take].iter().position(|&b| b == t) {
                take = pos + 1;
                reason |= reason::CHR;
            }
        }
        data.push(part.split_to(take));
        if part.is_empty() {
            pending.parts.pop_front();
        }
        n += take;
        if reason & reason::CHR != 0 {
            break;
        }
    }
    let finished = pending.parts.is_empty();
    if finished {
        reason |= reason::END;
    } else if n == request {
        reason |= reason::REQCNT;
    }
    let plan = ReplyPlan {
        delay: Duration::ZERO,
        byte_segments: pending.byte_segments,
        fate: if std::mem::take(&mut pending.drop_midway) {
            ReplyFate::DropMidway
        } else {
            ReplyFate::Deliver
        },
    };
    if finished {
        st.output.pop_front();
    }
    Some((data, reason, plan))
}

/// Runs a link's messages through the handler in order. It holds the link weakly: destroying
/// the link drops the job sender, which ends the worker.
async fn run_worker(
    shared: Arc<Shared>,
    link: Weak<Link>,
    mut queue: mpsc::UnboundedReceiver<Job>,
) {
    while let Some(job) = queue.recv().await {
        let Some(link) = link.upgrade() else {
            break;
        };
        let lid = link.id;
        let current = || link.generation.load(Ordering::SeqCst);
        match job {
            Job::Trigger(generation) if generation == current() => {
                let handler = Arc::clone(&shared.handler);
                if conn::blocking(move || handler.trigger()).await.is_none() {
                    break;
                }
            }
            Job::Trigger(_) => {}
            Job::Message(data, generation) => {
                if generation != current() {
                    continue;
                }
                let messages = match split_end_message(data, shared.options.max_message_size) {
                    Ok(m) => m,
                    Err(err) => {
                        tracing::warn!(lid, "VXI-11 message refused: {err}");
                        continue;
                    }
                };
                for message in messages {
                    let Some(responses) = conn::call_clearable(
                        &shared.handler,
                        message,
                        &link.generation,
                        generation,
                    )
                    .await
                    else {
                        return;
                    };
                    for response in responses {
                        let plan = shared.options.faults.plan_reply();
                        if !plan.delay.is_zero() {
                            tokio::time::sleep(plan.delay).await;
                        }
                        if plan.fate == ReplyFate::Swallow || generation != current() {
                            continue;
                        }
                        lock(&link.state).output.push_back(Pending {
                            parts: response.parts().iter().cloned().collect(),
                            byte_segments: plan.byte_segments,
                            drop_midway: plan.fate == ReplyFate::DropMidway,
                        });
                        link.output_ready.notify_waiters();
                    }
                }
            }
        }
    }
}
