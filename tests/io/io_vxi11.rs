//! VXI-11 client against the mock_lab VXI-11 server (core port given explicitly), over real
//! loopback sockets.

use crate::io_support;

loopback_suite!(io_support::Proto::Vxi11);

/// The core port found through the portmapper (GETPORT), here on an OS-chosen port.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn portmapper_getport_finds_the_core_channel() {
    io_support::check_idn(io_support::Proto::Vxi11Portmapper).await;
}
