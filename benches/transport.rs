//! Moves a 64 MiB block over loopback through each transport against the mock_lab servers, both
//! ways, and reports throughput (divan prints bytes/s next to the time).
//!
//! `cargo bench --bench transport` (add `-- --sample-count 5` for a quicker run).
//! Targets: >= 1 GB/s raw socket, HiSLIP and VICP; >= 500 MB/s VXI-11. Client and server share
//! one process here; `benches/compare_pyvisa.py` measures them as separate processes, next to
//! pyvisa-py on the same server (`radbench bench io`).

use divan::counter::BytesCount;
use divan::Bencher;
use mock_lab::emulator::loopback::Loopback;
use mock_lab::server::{self, Handler, ServerHandle, ServerOptions};
use radbench::address::Resource;
use radbench::session::{BlockForm, Session, SessionOptions};
use std::sync::Arc;

const LEN: usize = 64 << 20;

fn main() {
    divan::main();
}

#[derive(Debug, Clone, Copy)]
enum Proto {
    Socket,
    Hislip,
    Vxi11,
    Vicp,
}

impl std::fmt::Display for Proto {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Proto::Socket => "socket",
            Proto::Hislip => "hislip",
            Proto::Vxi11 => "vxi11",
            Proto::Vicp => "vicp",
        })
    }
}

const PROTOCOLS: [Proto; 4] = [Proto::Socket, Proto::Hislip, Proto::Vxi11, Proto::Vicp];

struct Rig {
    runtime: tokio::runtime::Runtime,
    session: Session,
    _server: ServerHandle,
}

fn runtime() -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .expect("runtime")
}

fn rig(proto: Proto) -> Rig {
    let runtime = runtime();
    let (server, session) = runtime.block_on(async {
        let handler: Arc<dyn Handler> = Arc::new(Loopback::new());
        let options = ServerOptions::default();
        let any = server::loopback_any();
        let server = match proto {
            Proto::Socket => server::raw::serve(any, handler, options).await,
            Proto::Hislip => server::hislip::serve(any, handler, options).await,
            Proto::Vxi11 => {
                let addrs = server::vxi11::Vxi11Addresses::loopback();
                server::vxi11::serve(addrs, handler, options).await
            }
            Proto::Vicp => server::vicp::serve(any, handler, options).await,
        }
        .expect("server starts");
        let port = server.local_addr().port();
        let resource: Resource = match proto {
            Proto::Socket => format!("TCPIP::127.0.0.1::{port}::SOCKET"),
            Proto::Hislip => format!("TCPIP::127.0.0.1::hislip0,{port}::INSTR"),
            Proto::Vxi11 => format!("TCPIP::127.0.0.1,{port}::inst0::INSTR"),
            Proto::Vicp => format!("VICP::127.0.0.1,{port}"),
        }
        .parse()
        .expect("resource");
        let session = Session::open(resource, SessionOptions::default(), None, "bench")
            .await
            .expect("session opens");
        (server, session)
    });
    Rig {
        runtime,
        session,
        _server: server,
    }
}

fn payload() -> Vec<u8> {
    let mut rng = radbench::rng::SplitMix64::new(1);
    let mut out = Vec::with_capacity(LEN + 8);
    while out.len() < LEN {
        out.extend_from_slice(&rng.next_u64().to_le_bytes());
    }
    out.truncate(LEN);
    out
}

/// Instrument to radbench: `DATA?` returns a 64 MiB definite block.
#[divan::bench(args = PROTOCOLS, sample_count = 10, sample_size = 1)]
fn read_64_mib(bencher: Bencher, proto: Proto) {
    let mut rig = rig(proto);
    let data = payload();
    rig.runtime
        .block_on(rig.session.write_block("DATA ", &data, BlockForm::Definite))
        .expect("upload");
    bencher.counter(BytesCount::new(LEN)).bench_local(|| {
        let block = rig
            .runtime
            .block_on(rig.session.query_block("DATA?"))
            .expect("download");
        assert_eq!(block.len(), LEN);
    });
}

/// radbench to instrument: `DATA #8<64 MiB>`, then `*OPC?` so the instrument has it all.
#[divan::bench(args = PROTOCOLS, sample_count = 10, sample_size = 1)]
fn write_64_mib(bencher: Bencher, proto: Proto) {
    let mut rig = rig(proto);
    let data = payload();
    bencher.counter(BytesCount::new(LEN)).bench_local(|| {
        rig.runtime
            .block_on(async {
                rig.session
                    .write_block("DATA ", &data, BlockForm::Definite)
                    .await?;
                rig.session.opc().await
            })
            .expect("upload");
    });
}

/// A minimal raw-socket peer that answers every received newline-free command line with a
/// pre-built 64 MiB block, or swallows a 64 MiB upload and answers `1`: it isolates the
/// client's own cost from the mock instrument's (framing, handler copies).
async fn bare_socket_peer() -> (u16, tokio::task::JoinHandle<()>) {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0")
        .await
        .expect("bind");
    let port = listener.local_addr().expect("addr").port();
    let reply = {
        let data = payload();
        let header = format!("#8{LEN}");
        [header.as_bytes(), &data, b"\n"].concat()
    };
    let task = tokio::spawn(async move {
        let (mut stream, _) = listener.accept().await.expect("accept");
        let mut buf = vec![0u8; 4 << 20];
        let upload = LEN + 16;
        let mut pending = 0usize;
        loop {
            let n = match stream.read(&mut buf).await {
                Ok(0) | Err(_) => return,
                Ok(n) => n,
            };
            pending += n;
            if buf[..n].starts_with(b"GET") {
                pending = 0;
                if stream.write_all(&reply).await.is_err() {
                    return;
                }
            } else if pending >= upload {
                pending = 0;
                if stream.write_all(b"1\n").await.is_err() {
                    return;
                }
            }
        }
    });
    (port, task)
}

/// A runtime, the bare peer and a raw-socket session to it.
fn bare_socket_session() -> (
    tokio::runtime::Runtime,
    Session,
    tokio::task::JoinHandle<()>,
) {
    let runtime = runtime();
    let (port, task) = runtime.block_on(bare_socket_peer());
    let resource: Resource = format!("TCPIP::127.0.0.1::{port}::SOCKET")
        .parse()
        .expect("resource");
    let session = runtime
        .block_on(Session::open(
            resource,
            SessionOptions::default(),
            None,
            "bench",
        ))
        .expect("open");
    (runtime, session, task)
}

/// radbench's raw-socket client alone (no mock instrument behind the socket).
#[divan::bench(sample_count = 10, sample_size = 1)]
fn client_only_socket_read_64_mib(bencher: Bencher) {
    let (runtime, mut session, _task) = bare_socket_session();
    bencher.counter(BytesCount::new(LEN)).bench_local(|| {
        let block = runtime
            .block_on(session.query_block("GET?"))
            .expect("download");
        assert_eq!(block.len(), LEN);
    });
}

/// radbench's raw-socket client alone, uploading: `DATA #8<64 MiB>`, the peer answers `1` once
/// it has every byte.
#[divan::bench(sample_count = 10, sample_size = 1)]
fn client_only_socket_write_64_mib(bencher: Bencher) {
    let (runtime, mut session, _task) = bare_socket_session();
    let data = payload();
    bencher.counter(BytesCount::new(LEN)).bench_local(|| {
        runtime
            .block_on(async {
                session
                    .write_block("DATA ", &data, BlockForm::Definite)
                    .await?;
                session.read_raw().await
            })
            .expect("upload");
    });
}
