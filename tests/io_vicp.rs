//! VICP client against the mock_lab VICP server, over real loopback sockets.

mod io_support;

loopback_suite!(io_support::Proto::Vicp);

/// The VICP 1a out-of-band serial poll (urgent byte `S`), answered by the mock on Linux.
#[cfg(target_os = "linux")]
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn out_of_band_serial_poll() {
    use io_support::{bounded, start, Proto};
    use radbench::transport::vicp::VicpLink;
    use std::time::Duration;
    let bench = start(Proto::Vicp).await;
    let port = bench.server.local_addr().port();
    let options = io_support::options(&bench, Duration::from_secs(5)).link;
    let mut link = bounded(VicpLink::connect("127.0.0.1", port, &options))
        .await
        .unwrap();
    let stb = bounded(link.read_stb_out_of_band(&options)).await.unwrap();
    assert_eq!(stb & 0x04, 0);
    // The stream is still in step: a query after the poll gets its own answer.
    bounded(link.write_message(&[b"*IDN?\n"], &options))
        .await
        .unwrap();
    let reply = bounded(link.read_message(&options)).await.unwrap();
    assert!(reply.starts_with(b"MOCK_LAB,LOOPBACK"));
}
