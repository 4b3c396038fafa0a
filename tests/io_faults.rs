//! Fault matrix per transport (raw socket, VXI-11, HiSLIP, VICP, serial) against misbehaving
//! peers over real loopback sockets and a pseudo-terminal: no reply, reply then close mid-block,
//! a block header announcing more than is sent, a length field of 4 GB, garbage, 1 byte per
//! 50 ms, replies to older requests forever, data that never ends the message. Each gives its
//! documented error (docs/io-timeouts.md) within its bound, with bounded memory, and no panic.

#[path = "support/alloc_count/mod.rs"]
mod io_alloc_count;
#[path = "support/io_faults/mod.rs"]
mod io_faults_support;

use io_faults_support::{run, Fault, Proto};

#[global_allocator]
static ALLOCATOR: io_alloc_count::Counting = io_alloc_count::Counting;

macro_rules! matrix {
    ($module:ident, $proto:expr) => {
        mod $module {
            use super::*;

            #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
            async fn no_reply() {
                run($proto, Fault::NoReply).await;
            }
            #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
            async fn reply_then_close_mid_block() {
                run($proto, Fault::CloseMidBlock).await;
            }
            #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
            async fn announced_block_never_arrives() {
                run($proto, Fault::AnnouncedNeverArrives).await;
            }
            #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
            async fn length_field_of_4_gb() {
                run($proto, Fault::HugeLength).await;
            }
            #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
            async fn garbage() {
                run($proto, Fault::Garbage).await;
            }
            #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
            async fn one_byte_per_50_ms() {
                run($proto, Fault::Trickle).await;
            }
            #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
            async fn replies_to_older_requests_forever() {
                run($proto, Fault::StaleForever).await;
            }
            #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
            async fn data_that_never_ends_the_message() {
                run($proto, Fault::NeverEnds).await;
            }
        }
    };
}

matrix!(socket, Proto::Socket);
matrix!(vxi11, Proto::Vxi11);
matrix!(hislip, Proto::Hislip);
matrix!(vicp, Proto::Vicp);
#[cfg(unix)]
matrix!(serial, Proto::Serial);
