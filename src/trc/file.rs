//! `.trc` files as scopes and other tools write them.
//!
//! Accepted: `#9<nine digits>` then WAVEDESC (what the scope saves, and radbench); a bare
//! WAVEDESC block; either one after a short prefix such as `C1:WF ALL,` (a saved remote reply).
//! Any IEEE 488.2 definite-length header (`#<d><d digits>`) right before WAVEDESC bounds the block;
//! bytes after the block (a reply's final LF) are ignored.

use bytes::Bytes;

use super::{Input, Trace, TrcError, NAME, NAME_SEARCH};

/// The block length a `#<d><digits>` header right before `start` announces, if there is one.
fn declared_length(prefix: &[u8]) -> Result<Option<u64>, TrcError> {
    let Some(hash) = prefix.iter().rposition(|b| *b == b'#') else {
        return Ok(None);
    };
    let header = &prefix[hash..];
    let bad = || TrcError::BadFileHeader {
        start: String::from_utf8_lossy(header).into_owned(),
    };
    let digits = match header.get(1) {
        Some(d @ b'1'..=b'9') => usize::from(d - b'0'),
        _ => return Err(bad()),
    };
    let number = &header[2..];
    if number.len() != digits || !number.iter().all(u8::is_ascii_digit) {
        return Err(bad());
    }
    // At most nine digits: always fits in u64.
    let len = number
        .iter()
        .fold(0u64, |acc, d| acc * 10 + u64::from(d - b'0'));
    Ok(Some(len))
}

/// Positions in a truncation error counted from the start of the file, not of WAVEDESC.
fn in_file(e: TrcError, base: u64) -> TrcError {
    match e {
        TrcError::Truncated {
            field,
            needed,
            have,
            ..
        } => TrcError::Truncated {
            field,
            needed: needed + base,
            have: have + base,
            input: Input::File,
        },
        other => other,
    }
}

impl Trace {
    /// Reads a `.trc` file's bytes (see the module docs for what is accepted). The channel comes
    /// from WAVE_SOURCE (0 when it says "unknown").
    pub(crate) fn from_file_bytes(file: Bytes) -> Result<Trace, TrcError> {
        let start = file
            .windows(NAME.len())
            .take(NAME_SEARCH)
            .position(|w| w == NAME)
            .ok_or(TrcError::NoDescriptor)?;
        let declared = declared_length(&file[..start])?;
        let have = file.len() as u64;
        let end = declared.map_or(have, |len| (start as u64).saturating_add(len).min(have));
        let base = start as u64;
        let mut trace =
            Trace::decode(0, file.slice(start..end as usize)).map_err(|e| in_file(e, base))?;
        if let Some(len) = declared {
            if base + len > have {
                return Err(TrcError::Truncated {
                    field: "the #9 file header's length",
                    needed: base + len,
                    have,
                    input: Input::File,
                });
            }
        }
        trace.channel = trace.desc.source_channel().unwrap_or(0);
        Ok(trace)
    }
}

#[cfg(test)]
mod tests {
    use super::super::BlockBuilder;
    use super::*;

    fn block() -> Vec<u8> {
        BlockBuilder {
            source: 1,
            segments: vec![(0.0, -1e-9), (2e-3, -1.1e-9)],
            ..BlockBuilder::default()
        }
        .build(&[1, 2, 3, 4])
    }

    fn with_header(block: &[u8]) -> Vec<u8> {
        let mut f = format!("#9{:09}", block.len()).into_bytes();
        f.extend_from_slice(block);
        f
    }

    #[test]
    fn trc_file_round_trips() {
        let block = BlockBuilder::default().build(&[1, 2, 3, 4]);
        let trace = Trace::decode(1, Bytes::from(block.clone())).unwrap();
        let file = trace.trc_bytes();
        assert!(file.starts_with(format!("#9{:09}", block.len()).as_bytes()));
        let back = Trace::from_trc_bytes(1, Bytes::from(file)).unwrap();
        assert_eq!(back.codes, trace.codes);
        assert!(Trace::from_trc_bytes(1, Bytes::from_static(b"WAVEDESC")).is_err());
    }

    #[test]
    fn header_prefix_and_trailing_bytes_are_accepted() {
        let b = block();
        let mut reply = b"C2:WF ALL,".to_vec();
        reply.extend_from_slice(&with_header(&b));
        reply.push(b'\n');
        let bare = b.clone();
        let mut prefixed_bare = b"ALL,".to_vec();
        prefixed_bare.extend_from_slice(&b);
        for file in [with_header(&b), reply, bare, prefixed_bare] {
            let t = Trace::from_file_bytes(Bytes::from(file)).unwrap();
            assert_eq!(t.codes, vec![1, 2, 3, 4]);
            assert_eq!(t.channel, 2);
            assert_eq!(t.segment_count(), 2);
            assert_eq!(t.block().len(), b.len());
        }
    }

    #[test]
    fn a_truncated_file_names_the_field_and_file_positions() {
        let file = with_header(&block());
        // Cut inside the data array: the #9 length promises more.
        let cut = &file[..file.len() - 3];
        let e = Trace::from_file_bytes(Bytes::copy_from_slice(cut)).unwrap_err();
        let text = e.to_string();
        assert!(
            matches!(
                e,
                TrcError::Truncated {
                    field: "WAVE_ARRAY_1",
                    input: Input::File,
                    ..
                }
            ),
            "{text}"
        );
        assert!(text.contains(&format!("holds {}", cut.len())), "{text}");
        assert!(text.contains("file was cut short"), "{text}");
        // Only the descriptor left (as lecroyscope's header.trc): the TRIGTIME array is missing.
        let e = Trace::from_file_bytes(Bytes::copy_from_slice(&file[..11 + 346])).unwrap_err();
        assert!(e.to_string().contains("TRIGTIME_ARRAY"), "{e}");
        // The arrays all there but the header promises more bytes.
        let mut long = file.clone();
        long[2..11].copy_from_slice(format!("{:09}", block().len() + 10).as_bytes());
        let e = Trace::from_file_bytes(Bytes::from(long)).unwrap_err();
        assert!(e.to_string().contains("#9 file header"), "{e}");
        for cut in 0..file.len() {
            assert!(Trace::from_file_bytes(Bytes::copy_from_slice(&file[..cut])).is_err());
        }
    }

    #[test]
    fn a_malformed_length_header_is_named() {
        let mut file = with_header(&block());
        file[5] = b'x';
        let e = Trace::from_file_bytes(Bytes::from(file)).unwrap_err();
        assert!(matches!(e, TrcError::BadFileHeader { .. }), "{e}");
        let e = Trace::from_file_bytes(Bytes::from_static(b"not a waveform at all")).unwrap_err();
        assert_eq!(e, TrcError::NoDescriptor);
    }
}
