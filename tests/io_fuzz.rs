//! The wire decoders fuzzed on stable Rust, through one conformance harness shared by the HiSLIP,
//! VICP, VXI-11 (ONC-RPC record and XDR) and newline/IEEE 488.2 block codecs: golden frames at
//! every split position, arbitrary bytes (no panic, no allocation beyond the checked length),
//! the same frames whatever the chunking, and valid frames surviving a round trip.
//!
//! CI runs proptest's default number of cases; run them long with, e.g.,
//! `PROPTEST_CASES=200000 cargo test --release -p radbench --test io_fuzz` (docs/fuzzing.md).

#[path = "support/alloc_count/mod.rs"]
mod io_alloc_count;

use bytes::{Bytes, BytesMut};
use proptest::collection::vec;
use proptest::prelude::*;
use radbench::session;
use radbench::transport::hislip::{self, FrameDecoder};
use radbench::transport::vicp::{self as vicp, BlockDecoder};
use radbench::transport::vxi11;
use radbench::transport::CodecError;
use radbench::transport::Decode;
use radbench::transport::TerminatedDecoder;
use std::mem::Discriminant;

#[global_allocator]
static ALLOCATOR: io_alloc_count::Counting = io_alloc_count::Counting;

/// Frames decoded (each shown as bytes), then the kind of error that stopped decoding, if any.
type Outcome = (Vec<Vec<u8>>, Option<Discriminant<CodecError>>);

/// What the harness needs of one codec.
struct Codec<D: Decode> {
    make: fn(u64) -> D,
    /// A decoded frame as bytes, for comparison (its wire form, or its payload).
    show: fn(&D::Item) -> Vec<u8>,
}

impl<D: Decode> Codec<D> {
    fn decode<'a>(&self, limit: u64, chunks: impl IntoIterator<Item = &'a [u8]>) -> Outcome {
        let mut decoder = (self.make)(limit);
        let mut buf = BytesMut::new();
        let mut frames = Vec::new();
        for chunk in chunks {
            buf.extend_from_slice(chunk);
            loop {
                match decoder.decode(&mut buf) {
                    Ok(Some(frame)) => frames.push((self.show)(&frame)),
                    Ok(None) => break,
                    Err(e) => return (frames, Some(std::mem::discriminant(&e))),
                }
            }
        }
        (frames, None)
    }

    /// Golden bytes decode to `want` in one piece, cut at every position, and byte by byte.
    fn golden(&self, wire: &[u8], want: &[&[u8]]) {
        let want: Outcome = (want.iter().map(|f| f.to_vec()).collect(), None);
        let limit = 1 << 20;
        assert_eq!(self.decode(limit, [wire]), want, "in one piece");
        for cut in 0..=wire.len() {
            let (a, b) = wire.split_at(cut);
            assert_eq!(self.decode(limit, [a, b]), want, "cut at {cut}");
        }
        assert_eq!(self.decode(limit, wire.chunks(1)), want, "byte by byte");
    }

    /// The outcome does not depend on how the bytes were cut into reads.
    fn same_in_any_chunks(&self, wire: &[u8], cuts: &[usize], limit: u64) -> Result<(), String> {
        let whole = self.decode(limit, [wire]);
        let mut points: Vec<usize> = cuts.iter().map(|c| c % (wire.len() + 1)).collect();
        points.sort_unstable();
        let mut pieces = Vec::new();
        let mut at = 0;
        for p in points {
            pieces.push(&wire[at..p]);
            at = p;
        }
        pieces.push(&wire[at..]);
        let chunked = self.decode(limit, pieces);
        if whole == chunked {
            Ok(())
        } else {
            Err(format!("in one piece {whole:?}, in chunks {chunked:?}"))
        }
    }

    /// Arbitrary bytes: no panic, and the decoder allocates no more than the input, the frames
    /// shown, and room for one frame of at most the limit.
    fn bounded(&self, data: &[u8], limit: u64) -> Result<(), String> {
        let base = io_alloc_count::thread_start();
        let _ = self.decode(limit, [data]);
        let _ = self.decode(limit, data.chunks(7));
        let grew = io_alloc_count::thread_peak_above(base);
        let bound = 3 * data.len() + 2 * limit as usize + 4096;
        if grew <= bound {
            Ok(())
        } else {
            Err(format!(
                "{grew} bytes allocated for {} input bytes, limit {limit} (bound {bound})",
                data.len()
            ))
        }
    }
}

const HISLIP: Codec<FrameDecoder> = Codec {
    make: FrameDecoder::new,
    show: |f| {
        hislip::encode_frame(
            f.header.msg_type,
            f.header.control,
            f.header.param,
            &f.payload,
        )
    },
};

const VICP: Codec<BlockDecoder> = Codec {
    make: BlockDecoder::new,
    show: |b| {
        let mut out = b.header.encode().to_vec();
        out.extend_from_slice(&b.payload);
        out
    },
};

const RPC_RECORDS: Codec<vxi11::RecordDecoder> = Codec {
    make: vxi11::RecordDecoder::new,
    show: |r: &Bytes| r.to_vec(),
};

const TERMINATED: Codec<TerminatedDecoder> = Codec {
    make: |limit| TerminatedDecoder::new(b'\n', usize::try_from(limit).unwrap_or(usize::MAX)),
    show: |m: &Bytes| m.to_vec(),
};

// ------------------------------------------------------------------ golden frames

#[test]
fn hislip_golden_frames() {
    // InitializeResponse (session 7, protocol 1.0), then DataEnd id 0xFFFFFF00 with "1\n".
    let init: &[u8] = &[b'H', b'S', 1, 0, 1, 0, 0, 7, 0, 0, 0, 0, 0, 0, 0, 0];
    let data: &[u8] = &[
        b'H', b'S', 7, 1, 0xFF, 0xFF, 0xFF, 0x00, 0, 0, 0, 0, 0, 0, 0, 2, b'1', b'\n',
    ];
    HISLIP.golden(&[init, data].concat(), &[init, data]);
}

#[test]
fn vicp_golden_frames() {
    // A reply in two blocks (sequence 5), the last with EOI, as a LeCroy sends it.
    let first: &[u8] = &[0x80, 1, 5, 0, 0, 0, 0, 4, b'L', b'E', b'C', b'R'];
    let last: &[u8] = &[0x81, 1, 5, 0, 0, 0, 0, 3, b'O', b'Y', b'\n'];
    VICP.golden(&[first, last].concat(), &[first, last]);
}

#[test]
fn rpc_record_golden_frames() {
    // Record 1 in two fragments ("abc" + "de"), record 2 in one ("xyz!").
    let wire: &[u8] = &[
        0x00, 0, 0, 3, b'a', b'b', b'c', 0x80, 0, 0, 2, b'd', b'e', //
        0x80, 0, 0, 4, b'x', b'y', b'z', b'!',
    ];
    RPC_RECORDS.golden(wire, &[b"abcde", b"xyz!"]);
}

#[test]
fn terminated_golden_frames() {
    let want: [&[u8]; 7] = [
        b"*IDN?\n",
        b"Keysight Technologies,M8195A,MY1,4.0\n",
        b"#15a\nb\n\ncd\n",
        b":TRAC1:DATA 1,0,#0xyz\n",
        b"-113,\"bad #9 header\"\n",
        b"ALL,#9000000003\n\n\n\n",
        b"#Q17\n",
    ];
    TERMINATED.golden(&want.concat(), &want);
}

/// Length fields over the limit are refused before anything is reserved for them.
#[test]
fn announced_lengths_over_the_limit_are_refused() {
    let too_large = Some(std::mem::discriminant(&CodecError::TooLarge {
        format: "",
        announced: 0,
        limit: 0,
    }));
    let base = io_alloc_count::thread_start();
    let hislip = hislip::Header::new(hislip::msg::DATA, 0, 0, u64::MAX).encode();
    assert_eq!(HISLIP.decode(1 << 20, [&hislip[..]]).1, too_large);
    let vicp = vicp::Header::new(0x81, 1, u32::MAX).encode();
    assert_eq!(VICP.decode(1 << 20, [&vicp[..]]).1, too_large);
    let rpc = vxi11::record_mark(0x7FFF_FFFF, true);
    assert_eq!(RPC_RECORDS.decode(1 << 20, [&rpc[..]]).1, too_large);
    assert_eq!(
        TERMINATED.decode(1 << 20, [&b"#9999999999"[..]]).1,
        too_large
    );
    // Text that never ends is refused at the limit, in one piece or in many.
    let endless = vec![b'a'; 5000];
    assert_eq!(TERMINATED.decode(4096, [&endless[..]]).1, too_large);
    let long_line = [&endless[..], b"\n"].concat();
    assert_eq!(TERMINATED.decode(4096, [&long_line[..]]).1, too_large);
    assert!(io_alloc_count::thread_peak_above(base) < 64 << 10);
}

// ------------------------------------------------------------------ valid frames generated

prop_compose! {
    fn hislip_frames()(frames in vec((0u8..30, any::<u8>(), any::<u32>(), vec(any::<u8>(), 0..64)), 0..6))
        -> (Vec<u8>, Vec<Vec<u8>>) {
        let shown: Vec<Vec<u8>> = frames
            .iter()
            .map(|(t, c, p, payload)| hislip::encode_frame(*t, *c, *p, payload))
            .collect();
        (shown.concat(), shown)
    }
}

prop_compose! {
    fn vicp_blocks()(blocks in vec((any::<u8>(), any::<u8>(), vec(any::<u8>(), 0..64)), 0..6))
        -> (Vec<u8>, Vec<Vec<u8>>) {
        let shown: Vec<Vec<u8>> = blocks
            .iter()
            .map(|(op, seq, payload)| {
                let mut b = vicp::Header::new(*op, *seq, payload.len() as u32).encode().to_vec();
                b.extend_from_slice(payload);
                b
            })
            .collect();
        (shown.concat(), shown)
    }
}

prop_compose! {
    /// Records, each sent as one or more fragments.
    fn rpc_records()(records in vec((vec(any::<u8>(), 0..64), vec(any::<usize>(), 0..3)), 0..5))
        -> (Vec<u8>, Vec<Vec<u8>>) {
        let mut wire = Vec::new();
        for (record, cuts) in &records {
            let mut points: Vec<usize> = cuts.iter().map(|c| c % (record.len() + 1)).collect();
            points.sort_unstable();
            points.push(record.len());
            let mut at = 0;
            for (i, p) in points.iter().enumerate() {
                let last = i + 1 == points.len();
                wire.extend_from_slice(&vxi11::record_mark((p - at) as u32, last));
                wire.extend_from_slice(&record[at..*p]);
                at = *p;
            }
        }
        (wire, records.into_iter().map(|(r, _)| r).collect())
    }
}

/// One piece of a newline-terminated message.
#[derive(Debug, Clone)]
enum Piece {
    Text(String),
    /// A quoted string: a `#` inside starts no block.
    Quoted(String),
    /// A definite block: any bytes, newlines included.
    Block(Vec<u8>),
}

fn piece() -> impl Strategy<Value = Piece> {
    prop_oneof![
        "[A-Za-z0-9 ,.:;*?+-]{0,12}".prop_map(Piece::Text),
        "[a-z0-9 #]{0,8}".prop_map(Piece::Quoted),
        vec(any::<u8>(), 0..48).prop_map(Piece::Block),
    ]
}

fn message(pieces: &[Piece]) -> Vec<u8> {
    let mut out = Vec::new();
    for p in pieces {
        match p {
            Piece::Text(t) => out.extend_from_slice(t.as_bytes()),
            Piece::Quoted(q) => out.extend_from_slice(format!("\"{q}\"").as_bytes()),
            Piece::Block(b) => {
                let len = b.len().to_string();
                out.extend_from_slice(format!("#{}{len}", len.len()).as_bytes());
                out.extend_from_slice(b);
            }
        }
    }
    out.push(b'\n');
    out
}

prop_compose! {
    fn terminated_messages()(messages in vec(vec(piece(), 0..5), 0..5)) -> (Vec<u8>, Vec<Vec<u8>>) {
        let shown: Vec<Vec<u8>> = messages.iter().map(|m| message(m)).collect();
        (shown.concat(), shown)
    }
}

// ------------------------------------------------------------------ the properties

/// Limits small enough for arbitrary inputs to cross them.
const LIMITS: std::ops::Range<u64> = 8..2048;

proptest! {
    #[test]
    fn hislip_arbitrary_bytes(data in vec(any::<u8>(), 0..1024), cuts in vec(any::<usize>(), 0..8), limit in LIMITS) {
        HISLIP.bounded(&data, limit).map_err(TestCaseError::fail)?;
        HISLIP.same_in_any_chunks(&data, &cuts, limit).map_err(TestCaseError::fail)?;
    }

    #[test]
    fn hislip_valid_frames_round_trip((wire, frames) in hislip_frames(), cuts in vec(any::<usize>(), 0..8)) {
        prop_assert_eq!(HISLIP.decode(1 << 20, [&wire[..]]), (frames, None));
        HISLIP.same_in_any_chunks(&wire, &cuts, 1 << 20).map_err(TestCaseError::fail)?;
    }

    #[test]
    fn vicp_arbitrary_bytes(data in vec(any::<u8>(), 0..1024), cuts in vec(any::<usize>(), 0..8), limit in LIMITS) {
        VICP.bounded(&data, limit).map_err(TestCaseError::fail)?;
        VICP.same_in_any_chunks(&data, &cuts, limit).map_err(TestCaseError::fail)?;
    }

    #[test]
    fn vicp_valid_blocks_round_trip((wire, blocks) in vicp_blocks(), cuts in vec(any::<usize>(), 0..8)) {
        // The decoder checks the version byte; generated headers carry version 1.
        prop_assert_eq!(VICP.decode(1 << 20, [&wire[..]]), (blocks, None));
        VICP.same_in_any_chunks(&wire, &cuts, 1 << 20).map_err(TestCaseError::fail)?;
    }

    #[test]
    fn rpc_arbitrary_bytes(data in vec(any::<u8>(), 0..1024), cuts in vec(any::<usize>(), 0..8), limit in LIMITS) {
        RPC_RECORDS.bounded(&data, limit).map_err(TestCaseError::fail)?;
        RPC_RECORDS.same_in_any_chunks(&data, &cuts, limit).map_err(TestCaseError::fail)?;
    }

    #[test]
    fn rpc_valid_records_round_trip((wire, records) in rpc_records(), cuts in vec(any::<usize>(), 0..8)) {
        prop_assert_eq!(RPC_RECORDS.decode(1 << 20, [&wire[..]]), (records, None));
        RPC_RECORDS.same_in_any_chunks(&wire, &cuts, 1 << 20).map_err(TestCaseError::fail)?;
    }

    /// XDR replies and VXI-11 results: any record decodes to a value or an error, never a panic,
    /// and opaque data is a view (nothing allocated for a claimed length).
    #[test]
    fn xdr_arbitrary_records(data in vec(any::<u8>(), 0..256)) {
        let base = io_alloc_count::thread_start();
        let record = Bytes::from(data.clone());
        if let Ok(reply) = vxi11::decode_reply(record.clone()) {
            if let Ok(r) = reply.outcome {
                let _ = vxi11::decode_read_resp(&mut r.clone());
                let _ = vxi11::decode_create_link(&mut r.clone());
                let _ = vxi11::decode_write_resp(&mut r.clone());
                let _ = vxi11::decode_readstb_resp(&mut r.clone());
                let _ = vxi11::decode_error(&mut r.clone());
            }
        }
        let _ = vxi11::decode_read_resp(&mut vxi11::XdrReader::new(record.clone()));
        let mut r = vxi11::XdrReader::new(record);
        while r.opaque("x").is_ok() {}
        prop_assert!(io_alloc_count::thread_peak_above(base) <= 4096);
    }

    #[test]
    fn terminated_arbitrary_bytes(data in vec(any::<u8>(), 0..1024), cuts in vec(any::<usize>(), 0..8), limit in LIMITS) {
        TERMINATED.bounded(&data, limit).map_err(TestCaseError::fail)?;
        TERMINATED.same_in_any_chunks(&data, &cuts, limit).map_err(TestCaseError::fail)?;
    }

    /// Arbitrary bytes in the alphabet that matters to the scanner (terminator, quote, `#`,
    /// digits): far more block headers and strings than uniform bytes would give.
    #[test]
    fn terminated_scanner_alphabet(data in vec(prop::sample::select(b"\n\"#0123456789ab".to_vec()), 0..512), cuts in vec(any::<usize>(), 0..8), limit in LIMITS) {
        TERMINATED.bounded(&data, limit).map_err(TestCaseError::fail)?;
        TERMINATED.same_in_any_chunks(&data, &cuts, limit).map_err(TestCaseError::fail)?;
    }

    #[test]
    fn terminated_valid_messages_round_trip((wire, messages) in terminated_messages(), cuts in vec(any::<usize>(), 0..8)) {
        prop_assert_eq!(TERMINATED.decode(1 << 20, [&wire[..]]), (messages, None));
        TERMINATED.same_in_any_chunks(&wire, &cuts, 1 << 20).map_err(TestCaseError::fail)?;
    }

    /// The session's parsers of what a decoder hands on: blocks, error entries, identities,
    /// numbers, Gotmic reply lines. Never a panic.
    #[test]
    fn reply_parsers_arbitrary_bytes(data in vec(any::<u8>(), 0..256)) {

        let _ = session::parse_block(Bytes::from(data.clone()));
        let text = String::from_utf8_lossy(&data);
        let _ = session::parse_error_entry(&text);
        let _ = session::parse_idn(&text);
        let _ = session::parse_f64(&text);
        let _ = session::parse_i64(&text);
        let _ = radbench::session::classify(&text);
        let crc = radbench::session::Crc8 { poly: 0x07, init: 0 };
        let _ = crc.unframe(&text);
    }
}
