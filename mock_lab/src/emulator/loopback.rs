//! A generic test instrument for transport tests: identity, block store and echo, slow replies,
//! an error queue and an IEEE 488.2 status byte.
//!
//! | command | effect |
//! |---|---|
//! | `*IDN?` | `MOCK_LAB,LOOPBACK,0,0.1` |
//! | `*RST` | forgets the stored block, error queue kept (488.2) |
//! | `*CLS` | clears the error queue and the event status register |
//! | `*OPC` / `*OPC?` | sets ESR bit 0 / answers `1` |
//! | `*ESR?`, `*ESE <n>`, `*ESE?`, `*SRE <n>`, `*SRE?`, `*STB?` | status registers |
//! | `SYST:ERR?` | oldest error as `<code>,"<text>"`, `0,"No error"` when empty |
//! | `DATA <block>` | stores a definite (`#N`) or indefinite (`#0`) block |
//! | `DATA?` | the stored block as a definite block |
//! | `DATA:LEN?` | stored block length |
//! | `DATA:GEN <n>[,<seed>]` | stores `n` pseudo-random bytes (SplitMix64, default seed 1), `n` <= 999999999 |
//! | `ECHO <text>` | answers `<text>` |
//! | `SLOW? <ms>` | answers `<ms>` after that many milliseconds (device clear cuts it short, no answer) |
//!
//! Several commands may share a message, separated by `;`; their answers are joined with `;`.
//! Status byte: bit 2 error queue not empty, bit 5 ESB (ESR & ESE), bit 6 MSS (STB & SRE).

use std::collections::VecDeque;
use std::sync::{Condvar, Mutex, MutexGuard};
use std::time::{Duration, Instant};

use bytes::Bytes;

use super::scpi::message::split_units;
use crate::server::framing::{block_header, MAX_DEFINITE_BLOCK};
use crate::server::{pool, Handler, Response};

/// Identity reported by `*IDN?`.
pub const IDENTITY: &str = "MOCK_LAB,LOOPBACK,0,0.1";
/// Error queue depth; one more error replaces the newest with -350 "Queue overflow".
const ERROR_QUEUE_DEPTH: usize = 32;
/// Largest block `DATA:GEN` will generate: the most a definite block (`DATA?`) can carry.
const MAX_GENERATED: u64 = MAX_DEFINITE_BLOCK as u64;
/// Longest `SLOW?` delay accepted, in milliseconds.
const MAX_SLOW_MS: u64 = 600_000;

const ESR_OPC: u8 = 0x01;
const ESR_QUERY_ERROR: u8 = 0x04;
const ESR_EXECUTION_ERROR: u8 = 0x10;
const ESR_COMMAND_ERROR: u8 = 0x20;
const STB_EAV: u8 = 0x04;
const STB_ESB: u8 = 0x20;
const STB_MSS: u8 = 0x40;

/// The loopback instrument. One instance is shared by every client of every server.
#[derive(Debug, Default)]
pub struct Loopback {
    state: Mutex<State>,
    /// Wakes a `SLOW?` early on device clear.
    cleared: Condvar,
}

#[derive(Debug, Default)]
struct State {
    errors: VecDeque<(i32, String)>,
    esr: u8,
    ese: u8,
    sre: u8,
    /// The stored block: a view of the buffer it arrived in (an upload is kept without a copy).
    block: Bytes,
    clear_generation: u64,
}

impl Loopback {
    /// A fresh instrument with an empty block and error queue.
    pub fn new() -> Loopback {
        Loopback::default()
    }

    fn lock(&self) -> MutexGuard<'_, State> {
        // A panic while holding the lock leaves plain data behind; keep serving.
        self.state
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner())
    }

    /// Replaces the stored block; the old buffer goes back to the server's pool for the next
    /// upload when no reply still shares it.
    fn store(&self, block: Bytes) {
        let old = std::mem::replace(&mut self.lock().block, block);
        pool::recycle(old);
    }

    /// Runs one command unit; `Some` holds its query response.
    fn command(&self, unit: &[u8]) -> Option<Response> {
        // Only the start is trimmed: a block argument may end in whitespace bytes.
        let start = unit
            .iter()
            .position(|b| !b.is_ascii_whitespace())
            .unwrap_or(unit.len());
        let unit = &unit[start..];
        let split = unit
            .iter()
            .position(|b| b.is_ascii_whitespace())
            .unwrap_or(unit.len());
        let header = String::from_utf8_lossy(&unit[..split]).to_ascii_uppercase();
        let raw_args = &unit[split..];
        let raw_args = &raw_args[raw_args
            .iter()
            .position(|b| !b.is_ascii_whitespace())
            .unwrap_or(raw_args.len())..];
        let args = trim(raw_args);
        let header = header.trim_start_matches(':');
        let (path, query) = match header.strip_suffix('?') {
            Some(path) => (path, true),
            None => (header, false),
        };
        let parts: Vec<&str> = path.split(':').collect();
        let is = |spec: &[(&str, &str)]| mnemonic_path(&parts, spec);
        let text = match (query, &parts[..]) {
            (true, ["*IDN"]) => Some(IDENTITY.as_bytes().to_vec()),
            (false, ["*RST"]) => {
                self.store(Bytes::new());
                None
            }
            (false, ["*CLS"]) => {
                let mut st = self.lock();
                st.errors.clear();
                st.esr = 0;
                None
            }
            (false, ["*OPC"]) => {
                self.lock().esr |= ESR_OPC;
                None
            }
            (true, ["*OPC"]) => Some(b"1".to_vec()),
            (true, ["*ESR"]) => {
                let mut st = self.lock();
                let esr = st.esr;
                st.esr = 0;
                Some(esr.to_string().into_bytes())
            }
            (true, ["*STB"]) => Some(self.status_byte().to_string().into_bytes()),
            (true, ["*ESE"]) => Some(self.lock().ese.to_string().into_bytes()),
            (true, ["*SRE"]) => Some(self.lock().sre.to_string().into_bytes()),
            (false, ["*ESE"]) | (false, ["*SRE"]) => {
                match parse_u64(args).filter(|&v| v <= 255) {
                    Some(v) if parts[0] == "*ESE" => self.lock().ese = v as u8,
                    Some(v) => self.lock().sre = (v as u8) & !STB_MSS,
                    None => self.push_error(-222, "Data out of range; expected 0..255"),
                }
                None
            }
            _ if query
                && (is(&[("SYST", "SYSTEM"), ("ERR", "ERROR")])
                    || is(&[("SYST", "SYSTEM"), ("ERR", "ERROR"), ("NEXT", "NEXT")])) =>
            {
                let (code, text) = self
                    .lock()
                    .errors
                    .pop_front()
                    .unwrap_or((0, "No error".to_string()));
                Some(format!("{code},\"{text}\"").into_bytes())
            }
            _ if !query && is(&[("DATA", "DATA")]) => {
                match parse_block(raw_args) {
                    Ok(data) => self.store(Bytes::copy_from_slice(data)),
                    Err(msg) => self.push_error(-161, msg),
                }
                None
            }
            _ if query && is(&[("DATA", "DATA")]) => {
                // The header, then the stored block itself (shared, not copied).
                let block = self.lock().block.clone();
                let Some(header) = block_header(block.len()) else {
                    // Stored from an indefinite (#0) upload, too long for a definite block.
                    self.push_error(-223, "Too much data; DATA? answers at most 999999999 bytes");
                    return None;
                };
                return Some(Response::from_parts(vec![header.into(), block]));
            }
            _ if query && is(&[("DATA", "DATA"), ("LEN", "LENGTH")]) => {
                Some(self.lock().block.len().to_string().into_bytes())
            }
            _ if !query && is(&[("DATA", "DATA"), ("GEN", "GENERATE")]) => {
                self.generate(args);
                None
            }
            (false, ["ECHO"]) => {
                // ECHO is a command that answers: a loopback convenience, not SCPI style.
                Some(args.to_vec())
            }
            (true, ["SLOW"]) => self.slow(args),
            _ => {
                self.push_error(-113, "Undefined header");
                None
            }
        };
        text.map(Response::from)
    }

    fn generate(&self, args: &[u8]) {
        let text = String::from_utf8_lossy(args);
        let mut fields = text.split(',').map(str::trim);
        let len = fields.next().and_then(|f| f.parse::<u64>().ok());
        let seed = match fields.next() {
            None => Some(1),
            Some(f) => f.parse::<u64>().ok(),
        };
        match (len, seed) {
            (Some(len), Some(seed)) if len <= MAX_GENERATED => {
                self.store(pseudo_random_bytes(len as usize, seed).into());
            }
            (Some(_), Some(_)) => self.push_error(
                -223,
                "Too much data; DATA:GEN accepts at most 999999999 bytes",
            ),
            _ => self.push_error(
                -109,
                "Missing parameter; expected DATA:GEN <bytes>[,<seed>]",
            ),
        }
    }

    fn slow(&self, args: &[u8]) -> Option<Vec<u8>> {
        let Some(ms) = parse_u64(args).filter(|&ms| ms <= MAX_SLOW_MS) else {
            self.push_error(-222, "Data out of range; SLOW? takes 0..600000 ms");
            return None;
        };
        let deadline = Instant::now() + Duration::from_millis(ms);
        let mut st = self.lock();
        let generation = st.clear_generation;
        loop {
            let now = Instant::now();
            if now >= deadline {
                return Some(ms.to_string().into_bytes());
            }
            let (guard, _) = self
                .cleared
                .wait_timeout(st, deadline - now)
                .unwrap_or_else(|poisoned| poisoned.into_inner());
            st = guard;
            if st.clear_generation != generation {
                return None;
            }
        }
    }

    fn push_error(&self, code: i32, text: &str) {
        let mut st = self.lock();
        st.esr |= match code {
            -199..=-100 => ESR_COMMAND_ERROR,
            -299..=-200 => ESR_EXECUTION_ERROR,
            _ => ESR_QUERY_ERROR,
        };
        if st.errors.len() + 1 >= ERROR_QUEUE_DEPTH {
            if st.errors.len() < ERROR_QUEUE_DEPTH {
                st.errors.push_back((-350, "Queue overflow".to_string()));
            }
            return;
        }
        st.errors.push_back((code, text.to_string()));
    }
}

impl Loopback {
    /// The responses to one program message, joined with `;` when several units answer.
    fn answers(&self, data: &[u8]) -> Vec<Response> {
        let units = match split_units(data) {
            Ok(units) => units,
            Err(e) => {
                self.push_error(e.code, &e.text);
                return Vec::new();
            }
        };
        let answers: Vec<Response> = units
            .into_iter()
            .filter(|unit| !trim(unit).is_empty())
            .filter_map(|unit| self.command(unit))
            .collect();
        if answers.len() <= 1 {
            return answers;
        }
        vec![Response::join(answers, b";")]
    }
}

impl Handler for Loopback {
    /// A message that is exactly one `DATA <block>` command keeps (a view of) its buffer as the
    /// stored block: no copy of a 64 MB upload. Answers share the stored block.
    fn respond(&self, data: Bytes) -> Vec<Response> {
        if let Some(range) = lone_data_block(&data) {
            self.store(data.slice(range));
            return Vec::new();
        }
        self.answers(&data)
    }

    fn message(&self, data: &[u8]) -> Vec<Vec<u8>> {
        self.answers(data).iter().map(Response::to_vec).collect()
    }

    fn device_clear(&self) {
        self.lock().clear_generation += 1;
        self.cleared.notify_all();
    }

    fn status_byte(&self) -> u8 {
        let st = self.lock();
        let mut stb = 0;
        if !st.errors.is_empty() {
            stb |= STB_EAV;
        }
        if st.esr & st.ese != 0 {
            stb |= STB_ESB;
        }
        if stb & st.sre != 0 {
            stb |= STB_MSS;
        }
        stb
    }
}

/// When `data` is one `DATA <valid block>` command, the block payload's byte range.
fn lone_data_block(data: &[u8]) -> Option<std::ops::Range<usize>> {
    let units = split_units(data).ok()?;
    let [unit] = units.as_slice() else {
        return None;
    };
    let unit = &unit[unit.iter().position(|b| !b.is_ascii_whitespace())?..];
    let split = unit.iter().position(|b| b.is_ascii_whitespace())?;
    let header = std::str::from_utf8(&unit[..split]).ok()?;
    if !header.trim_start_matches(':').eq_ignore_ascii_case("DATA") {
        return None;
    }
    let args = &unit[split..];
    let args = &args[args.iter().position(|b| !b.is_ascii_whitespace())?..];
    let payload = parse_block(args).ok()?;
    let start = payload.as_ptr() as usize - data.as_ptr() as usize;
    Some(start..start + payload.len())
}

/// True when `parts` matches `spec`, each part equal to the short or the long form.
fn mnemonic_path(parts: &[&str], spec: &[(&str, &str)]) -> bool {
    parts.len() == spec.len()
        && parts
            .iter()
            .zip(spec)
            .all(|(part, (short, long))| part == short || part == long)
}

/// Parses a definite (`#N`) or indefinite (`#0`) block argument.
fn parse_block(args: &[u8]) -> Result<&[u8], &'static str> {
    let rest = args
        .strip_prefix(b"#")
        .ok_or("Invalid block data; expected #<d><length><bytes> or #0<bytes>")?;
    let (&digit, rest) = rest
        .split_first()
        .ok_or("Invalid block data; header truncated")?;
    if digit == b'0' {
        return Ok(rest);
    }
    if !digit.is_ascii_digit() {
        return Err("Invalid block data; #<d> must be a digit");
    }
    let digits = usize::from(digit - b'0');
    let len = rest
        .get(..digits)
        .and_then(parse_u64)
        .ok_or("Invalid block data; length field malformed")?;
    let payload = &rest[digits..];
    let len = usize::try_from(len).map_err(|_| "Invalid block data; too long")?;
    if payload.len() < len || !trim(&payload[len..]).is_empty() {
        return Err("Invalid block data; length does not match the bytes sent");
    }
    Ok(&payload[..len])
}

fn parse_u64(bytes: &[u8]) -> Option<u64> {
    std::str::from_utf8(trim(bytes)).ok()?.parse().ok()
}

fn trim(bytes: &[u8]) -> &[u8] {
    let start = bytes
        .iter()
        .position(|b| !b.is_ascii_whitespace())
        .unwrap_or(bytes.len());
    let end = bytes
        .iter()
        .rposition(|b| !b.is_ascii_whitespace())
        .map_or(start, |e| e + 1);
    &bytes[start..end]
}

/// `len` bytes from SplitMix64 seeded with `seed` (little-endian words).
pub fn pseudo_random_bytes(len: usize, seed: u64) -> Vec<u8> {
    let mut state = seed;
    let mut out = Vec::with_capacity(len + 8);
    while out.len() < len {
        state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        out.extend_from_slice(&z.to_le_bytes());
    }
    out.truncate(len);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ask(inst: &Loopback, msg: &str) -> String {
        let out = inst.message(msg.as_bytes());
        assert_eq!(out.len(), 1, "one response to {msg}");
        String::from_utf8(out[0].clone()).unwrap()
    }

    #[test]
    fn identity_and_opc() {
        let inst = Loopback::new();
        assert_eq!(ask(&inst, "*IDN?"), IDENTITY);
        assert_eq!(ask(&inst, "*opc?"), "1");
        assert_eq!(ask(&inst, "*IDN?;*OPC?"), format!("{IDENTITY};1"));
    }

    #[test]
    fn block_round_trip_with_embedded_separators() {
        let inst = Loopback::new();
        assert!(inst.message(b"DATA #15a;\nb\"").is_empty());
        assert_eq!(inst.message(b"DATA?"), vec![b"#15a;\nb\"".to_vec()]);
        assert!(inst.message(b"DATA #0xyz").is_empty());
        assert_eq!(ask(&inst, "DATA:LEN?"), "3");
    }

    #[test]
    fn undefined_header_goes_to_error_queue_and_status_byte() {
        let inst = Loopback::new();
        assert!(inst.message(b"BOGUS").is_empty());
        assert_eq!(inst.status_byte() & STB_EAV, STB_EAV);
        assert_eq!(ask(&inst, "*ESE 32;*ESR?"), "32");
        assert_eq!(ask(&inst, "SYST:ERR?"), "-113,\"Undefined header\"");
        assert_eq!(ask(&inst, "SYSTEM:ERROR:NEXT?"), "0,\"No error\"");
        assert_eq!(inst.status_byte(), 0);
    }

    #[test]
    fn esb_and_mss_follow_enable_registers() {
        let inst = Loopback::new();
        inst.message(b"*ESE 32;*SRE 32;BOGUS");
        assert_eq!(inst.status_byte(), STB_EAV | STB_ESB | STB_MSS);
        inst.message(b"*CLS");
        assert_eq!(inst.status_byte(), 0);
    }

    #[test]
    fn generated_data_is_deterministic() {
        let inst = Loopback::new();
        inst.message(b"DATA:GEN 1000,7");
        let first = inst.message(b"DATA?");
        inst.message(b"DATA:GENERATE 1000,7");
        assert_eq!(inst.message(b"DATA?"), first);
        assert_eq!(first[0].len(), 1000 + 6);
    }

    #[test]
    fn generated_blocks_fit_a_definite_block_header() {
        // 10 digits of length cannot follow `#<d>`: refuse rather than answer `#:1000000000`.
        let inst = Loopback::new();
        assert!(inst.message(b"DATA:GEN 1000000000").is_empty());
        assert!(ask(&inst, "SYST:ERR?").starts_with("-223,"));
        assert_eq!(ask(&inst, "DATA:LEN?"), "0");
    }

    #[test]
    fn owned_upload_is_kept_without_reparsing_errors() {
        let inst = Loopback::new();
        assert!(inst
            .respond(Bytes::from_static(b"DATA #14ab;c\r"))
            .is_empty());
        assert_eq!(inst.message(b"DATA?"), vec![b"#14ab;c".to_vec()]);
        // Not a lone DATA command: handled like any message.
        let answers = inst.respond(Bytes::from_static(b"DATA #11x;DATA?"));
        assert_eq!(answers.len(), 1);
        assert_eq!(answers[0].to_vec(), b"#11x");
        assert!(inst.respond(Bytes::from_static(b"DATA #19x")).is_empty());
        assert!(ask(&inst, "SYST:ERR?").starts_with("-161,"));
    }

    #[test]
    fn bad_block_is_reported() {
        let inst = Loopback::new();
        inst.message(b"DATA #19abc");
        assert!(ask(&inst, "SYST:ERR?").starts_with("-161,"));
    }

    #[test]
    fn slow_is_cut_short_by_device_clear() {
        let inst = std::sync::Arc::new(Loopback::new());
        let worker = {
            let inst = inst.clone();
            std::thread::spawn(move || inst.message(b"SLOW? 60000"))
        };
        // Clear until the worker notices (it may not be waiting yet on the first clear).
        while !worker.is_finished() {
            inst.device_clear();
            std::thread::yield_now();
        }
        assert!(worker.join().unwrap().is_empty());
        assert_eq!(ask(&inst, "SLOW? 1"), "1");
    }

    #[test]
    fn error_queue_overflow_is_reported_once() {
        let inst = Loopback::new();
        for _ in 0..100 {
            inst.message(b"NOPE");
        }
        let mut last = String::new();
        for _ in 0..ERROR_QUEUE_DEPTH {
            last = ask(&inst, "SYST:ERR?");
        }
        assert_eq!(last, "-350,\"Queue overflow\"");
        assert_eq!(ask(&inst, "SYST:ERR?"), "0,\"No error\"");
    }
}
