//! Serial endpoint on a pseudo-terminal, opened like a real serial port.

use crate::common;

use std::io::Write;
use std::time::Duration;

use common::instrument;
use mock_lab::server::serial;

fn read_line(port: &mut dyn serialport::SerialPort) -> String {
    let mut out = Vec::new();
    let mut byte = [0u8; 1];
    while out.last() != Some(&b'\n') {
        port.read_exact(&mut byte)
            .expect("reply within the port timeout");
        out.push(byte[0]);
    }
    String::from_utf8(out).unwrap()
}

#[test]
fn lines_in_lines_out_with_faults() {
    let (handler, options, faults) = instrument();
    let server = serial::serve(handler, options).unwrap();
    assert!(server.device_path().starts_with("/dev/"));
    let mut port = serialport::new(server.device_path(), 115_200)
        .timeout(Duration::from_secs(10))
        .open()
        .unwrap();
    port.write_all(b"*IDN?\r\n").unwrap();
    assert_eq!(read_line(port.as_mut()), "MOCK_LAB,LOOPBACK,0,0.1\n");
    port.write_all(b"ECHO one\nECHO two\n").unwrap();
    assert_eq!(read_line(port.as_mut()), "one\n");
    assert_eq!(read_line(port.as_mut()), "two\n");
    faults.set_byte_segments(true);
    port.write_all(b"ECHO slowly\n").unwrap();
    assert_eq!(read_line(port.as_mut()), "slowly\n");
    faults.clear();
    faults.swallow_next_reply();
    port.write_all(b"ECHO lost\nECHO kept\n").unwrap();
    assert_eq!(read_line(port.as_mut()), "kept\n");
    drop(port);
    // A second client after the first went away.
    let mut port = serialport::new(server.device_path(), 115_200)
        .timeout(Duration::from_secs(10))
        .open()
        .unwrap();
    port.write_all(b"*OPC?\n").unwrap();
    assert_eq!(read_line(port.as_mut()), "1\n");
}

#[test]
fn blocks_ending_in_whitespace_reach_the_awg_byte_exact() {
    let (handler, options) = common::awg();
    let server = serial::serve(handler, options).unwrap();
    let mut port = serialport::new(server.device_path(), 115_200)
        .timeout(Duration::from_secs(10))
        .open()
        .unwrap();
    for exchange in common::whitespace_tail_uploads() {
        port.write_all(&exchange.message).unwrap();
        if let Some(reply) = exchange.reply {
            assert_eq!(read_line(port.as_mut()), format!("{reply}\n"));
        }
    }
}
