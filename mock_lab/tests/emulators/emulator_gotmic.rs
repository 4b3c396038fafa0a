//! The Gotmic Tx/Rx emulators: the project-defined line protocol, the register map from the catalog,
//! the safety interlocks, fault latching, temperature readback and CRC framing.

use mock_lab::emulator::gotmic::{crc8, Gotmic};
use mock_lab::server::Handler;

fn tx() -> Gotmic {
    Gotmic::tx_embedded().expect("built-in catalog loads")
}

fn rx() -> Gotmic {
    Gotmic::rx_embedded().expect("built-in catalog loads")
}

/// Register addresses come from the catalog; the tests look them up by name like a driver would.
fn addr(m: &Gotmic, name: &str) -> u8 {
    m.model().register(name).unwrap().address
}

fn read(m: &Gotmic, name: &str) -> u16 {
    let reply = m.line(&format!("R {:02X}", addr(m, name)));
    let hex = reply
        .strip_prefix("OK ")
        .unwrap_or_else(|| panic!("read {name}: {reply}"));
    assert_eq!(hex.len(), 4);
    u16::from_str_radix(hex, 16).unwrap()
}

fn write(m: &Gotmic, name: &str, value: u16) -> String {
    m.line(&format!("W {:02X} {value:04X}", addr(m, name)))
}

const MASTER: u16 = 1;
const AMP: u16 = 2;
const RF_ON: u16 = MASTER | AMP | 4 | 8;

#[test]
fn identity_and_module_type() {
    let t = tx();
    assert_eq!(
        t.line("*IDN?"),
        "MOCK_LAB,GOTMIC-EBAND-TX-EMU,EMU0003,mock_lab-1"
    );
    assert_eq!(read(&t, "ID"), 0x5458);
    assert_eq!(read(&rx(), "ID"), 0x5258);
}

#[test]
fn power_on_state_is_safe() {
    let t = tx();
    assert_eq!(read(&t, "CONTROL"), 0, "RF off at power-on");
    assert_eq!(read(&t, "GAIN_ATT"), 63, "maximum attenuation at power-on");
    assert_eq!(read(&t, "STATUS"), 0b0011, "powered, LO locked");
    assert_eq!(read(&t, "TEMP_DC"), 250);
    let fe = t.front_end();
    assert!(!fe.rf_enabled);
    assert_eq!(fe.attenuation_db, 31.5);
}

#[test]
fn enable_sequence_and_readback() {
    let t = tx();
    assert_eq!(write(&t, "GAIN_ATT", 63), "OK");
    assert_eq!(write(&t, "CONTROL", RF_ON), "OK");
    assert_eq!(read(&t, "CONTROL"), RF_ON);
    assert_eq!(read(&t, "STATUS") & 0b0100, 0b0100, "RF enabled");
    assert_eq!(write(&t, "GAIN_ATT", 10), "OK");
    let fe = t.front_end();
    assert!(fe.rf_enabled && fe.iq_enabled && fe.lo_multiplier_enabled);
    assert_eq!(fe.attenuation_db, 5.0);
    assert_eq!(write(&t, "CONTROL", 0), "OK");
    assert!(!t.front_end().rf_enabled);
}

#[test]
fn interlock_blocks_enable_and_trips_rf() {
    let t = tx();
    t.set_interlock_open(true);
    assert_eq!(
        write(&t, "CONTROL", RF_ON),
        "ERR 5 not allowed: interlock open"
    );
    assert_eq!(read(&t, "CONTROL"), 0);
    assert_eq!(read(&t, "STATUS") & 0x10, 0x10);
    // Bits that do not radiate may still be set.
    assert_eq!(write(&t, "CONTROL", 4), "OK");

    t.set_interlock_open(false);
    assert_eq!(write(&t, "CONTROL", RF_ON), "OK");
    t.set_interlock_open(true);
    assert_eq!(read(&t, "CONTROL") & (MASTER | AMP), 0, "RF switched off");
    assert_eq!(read(&t, "FAULT_LATCH"), 0b010, "INTERLOCK_OPENED latched");
    t.set_interlock_open(false);
    let refused = write(&t, "CONTROL", RF_ON);
    assert!(
        refused.starts_with("ERR 5 not allowed: fault latched (0x0002)"),
        "{refused}"
    );
    assert_eq!(write(&t, "FAULT_LATCH", 0b010), "OK", "write 1 to clear");
    assert_eq!(read(&t, "FAULT_LATCH"), 0);
    assert_eq!(write(&t, "CONTROL", RF_ON), "OK");
}

#[test]
fn receiver_ignores_the_interlock_but_needs_the_lo() {
    let r = rx();
    r.set_interlock_open(true);
    assert_eq!(write(&r, "CONTROL", RF_ON), "OK");
    r.set_lo_present(false);
    assert_eq!(read(&r, "CONTROL") & (MASTER | AMP), 0);
    assert_eq!(read(&r, "FAULT_LATCH"), 0b100, "LO_LOST latched");
    assert_eq!(read(&r, "STATUS") & 0b10, 0, "LO not locked");
    assert_eq!(write(&r, "FAULT_LATCH", 7), "OK");
    assert_eq!(
        write(&r, "CONTROL", RF_ON),
        "ERR 5 not allowed: LO not present"
    );
}

#[test]
fn over_temperature_trips_and_reads_back() {
    let t = tx();
    write(&t, "CONTROL", RF_ON);
    t.set_temperature_c(90.0);
    assert_eq!(read(&t, "TEMP_DC"), 900);
    assert_eq!(
        read(&t, "STATUS") & 0b1100,
        0b1000,
        "over temperature, RF off"
    );
    assert_eq!(read(&t, "FAULT_LATCH"), 0b001);
    t.set_temperature_c(-12.5);
    assert_eq!(
        read(&t, "TEMP_DC") as i16,
        -125,
        "signed tenths of a degree"
    );
}

#[test]
fn an_unknown_register_is_refused() {
    assert_eq!(
        tx().line("R 42"),
        "ERR 2 unknown register: no register 0x42"
    );
}

#[test]
fn a_read_only_register_is_refused() {
    assert!(tx()
        .line("W 01 0001")
        .starts_with("ERR 3 register is read-only: STATUS"));
}

#[test]
fn a_value_out_of_the_register_range_is_refused() {
    assert!(tx()
        .line("W 03 0040")
        .starts_with("ERR 4 value out of range"));
}

#[test]
fn malformed_requests_are_syntax_errors() {
    let t = tx();
    for line in ["W 03", "R xyz", "W 03 12345", ""] {
        assert!(t.line(line).starts_with("ERR 1"), "{line:?}");
    }
}

#[test]
fn case_hex_prefix_and_crlf_are_accepted() {
    assert_eq!(tx().line("r 0x03\r\n"), "OK 003F");
}

/// `body*<hh>` with the module's CRC-8.
fn framed(m: &Gotmic, body: &str) -> String {
    let p = &m.model().protocol;
    format!(
        "{body}*{:02X}",
        crc8(body.as_bytes(), p.crc_poly, p.crc_init)
    )
}

#[test]
fn crc_on_frames_replies_and_refuses_unframed_requests() {
    let t = tx();
    let framed = |body: &str| framed(&t, body);
    assert_eq!(t.line("CRC ON"), "OK");
    assert_eq!(t.line(&framed("R 03")), framed("OK 003F"));
    let missing = t.line("R 03");
    assert!(missing.starts_with("ERR 6 CRC mismatch"), "{missing}");
    let (body, sum) = missing.rsplit_once('*').unwrap();
    assert_eq!(
        framed(body),
        missing,
        "the refusal carries its own CRC: {sum}"
    );
    assert!(t.line("R 03*00").starts_with("ERR 6"));
}

#[test]
fn crc_off_returns_to_plain_lines() {
    let t = tx();
    let framed = |body: &str| framed(&t, body);
    assert_eq!(t.line("CRC ON"), "OK");
    assert_eq!(t.line(&framed("CRC OFF")), framed("OK"));
    assert_eq!(t.line("R 03"), "OK 003F");
}

#[test]
fn handler_answers_one_reply_per_line_and_logs() {
    let t = tx();
    let replies = t.message(b"*IDN?\nR 02\r\n");
    assert_eq!(replies.len(), 2);
    assert_eq!(replies[1], b"OK 0000");
    assert_eq!(t.log().texts(), ["*IDN?", "R 02"]);
}

#[test]
fn a_register_map_without_what_the_emulator_needs_is_refused() {
    let mut model = mock_lab::catalog::gotmic_tx().unwrap();
    model.registers.retain(|r| r.name != "FAULT_LATCH");
    let err = Gotmic::new(model).err().unwrap();
    assert!(err.to_string().contains("FAULT_LATCH"), "{err}");
}
