//! NumPy `.npz` files: a ZIP archive of `.npy` arrays, `name.npy` each, as `numpy.savez` writes
//! them. Entries are stored (no compression) with their CRC-32, and always in ZIP64 form
//! (sizes and offsets in the ZIP64 extra field, a ZIP64 end record), as `numpy.savez` itself
//! writes its entries (`force_zip64`): one code path, whatever the file's size. Written as a
//! stream (entry after entry, the central directory at the end), so a large export never has to
//! be held in memory whole. Times are fixed (1980-01-01 00:00) so that the same arrays give the
//! same bytes.

use super::StorageError;

/// Where an archive's bytes go.
pub(crate) trait ByteSink {
    fn put(&mut self, bytes: &[u8]) -> Result<(), StorageError>;
}

impl ByteSink for Vec<u8> {
    fn put(&mut self, bytes: &[u8]) -> Result<(), StorageError> {
        self.extend_from_slice(bytes);
        Ok(())
    }
}

impl ByteSink for super::atomic::AtomicFile {
    fn put(&mut self, bytes: &[u8]) -> Result<(), StorageError> {
        self.write(bytes)
    }
}

/// CRC-32 (IEEE 802.3, reflected, as ZIP uses it) of `bytes`, continuing from `crc`
/// (0 to start).
pub(crate) fn crc32(crc: u32, bytes: &[u8]) -> u32 {
    const TABLE: [u32; 256] = {
        let mut table = [0u32; 256];
        let mut n = 0;
        while n < 256 {
            let mut c = n as u32;
            let mut k = 0;
            while k < 8 {
                c = if c & 1 != 0 {
                    0xEDB8_8320 ^ (c >> 1)
                } else {
                    c >> 1
                };
                k += 1;
            }
            table[n] = c;
            n += 1;
        }
        table
    };
    let mut c = !crc;
    for &b in bytes {
        c = TABLE[((c ^ u32::from(b)) & 0xFF) as usize] ^ (c >> 8);
    }
    !c
}

/// One entry written, for the central directory.
struct Entry {
    name: String,
    crc: u32,
    size: u64,
    offset: u64,
}

/// An `.npz` archive being written to `sink`.
pub(crate) struct NpzWriter<S: ByteSink> {
    sink: S,
    offset: u64,
    entries: Vec<Entry>,
}

/// DOS time and date of every entry: 00:00:00 on 1980-01-01.
const DOS_TIME: u16 = 0;
const DOS_DATE: u16 = (1 << 5) | 1;
/// "Version needed to extract" for ZIP64; "version made by": UNIX, 4.5.
const VERSION_NEEDED: u16 = 45;
const VERSION_MADE_BY: u16 = (3 << 8) | 45;
/// General-purpose flags: bit 11, the name is UTF-8.
const FLAGS: u16 = 1 << 11;

impl<S: ByteSink> NpzWriter<S> {
    pub(crate) fn new(sink: S) -> Self {
        Self {
            sink,
            offset: 0,
            entries: Vec::new(),
        }
    }

    /// Adds the array `npy` (an encoded `.npy` file) as `name` (`numpy.load` names it `name`;
    /// the archive entry is `name.npy`). A name given twice is refused.
    pub(crate) fn add(&mut self, name: &str, npy: &[u8]) -> Result<(), StorageError> {
        let file_name = format!("{name}.npy");
        if self.entries.iter().any(|e| e.name == file_name) {
            return Err(StorageError::BadData {
                path: file_name.into(),
                reason: "the archive holds an array of that name already (a radbench bug)".into(),
            });
        }
        let crc = crc32(0, npy);
        let size = npy.len() as u64;
        let mut h = Vec::with_capacity(30 + file_name.len() + 20);
        h.extend_from_slice(&0x0403_4b50u32.to_le_bytes());
        h.extend_from_slice(&VERSION_NEEDED.to_le_bytes());
        h.extend_from_slice(&FLAGS.to_le_bytes());
        h.extend_from_slice(&0u16.to_le_bytes()); // stored
        h.extend_from_slice(&DOS_TIME.to_le_bytes());
        h.extend_from_slice(&DOS_DATE.to_le_bytes());
        h.extend_from_slice(&crc.to_le_bytes());
        h.extend_from_slice(&u32::MAX.to_le_bytes()); // compressed size: in the ZIP64 field
        h.extend_from_slice(&u32::MAX.to_le_bytes()); // uncompressed size: likewise
        h.extend_from_slice(&(file_name.len() as u16).to_le_bytes());
        h.extend_from_slice(&20u16.to_le_bytes()); // extra field length
        h.extend_from_slice(file_name.as_bytes());
        h.extend_from_slice(&0x0001u16.to_le_bytes()); // ZIP64 extended information
        h.extend_from_slice(&16u16.to_le_bytes());
        h.extend_from_slice(&size.to_le_bytes()); // uncompressed
        h.extend_from_slice(&size.to_le_bytes()); // compressed
        self.sink.put(&h)?;
        self.sink.put(npy)?;
        self.entries.push(Entry {
            name: file_name,
            crc,
            size,
            offset: self.offset,
        });
        self.offset += h.len() as u64 + size;
        Ok(())
    }

    /// Writes the central directory and the end records; gives the sink back.
    pub(crate) fn finish(mut self) -> Result<S, StorageError> {
        let start = self.offset;
        let mut cd = Vec::new();
        for e in &self.entries {
            cd.extend_from_slice(&0x0201_4b50u32.to_le_bytes());
            cd.extend_from_slice(&VERSION_MADE_BY.to_le_bytes());
            cd.extend_from_slice(&VERSION_NEEDED.to_le_bytes());
            cd.extend_from_slice(&FLAGS.to_le_bytes());
            cd.extend_from_slice(&0u16.to_le_bytes());
            cd.extend_from_slice(&DOS_TIME.to_le_bytes());
            cd.extend_from_slice(&DOS_DATE.to_le_bytes());
            cd.extend_from_slice(&e.crc.to_le_bytes());
            cd.extend_from_slice(&u32::MAX.to_le_bytes());
            cd.extend_from_slice(&u32::MAX.to_le_bytes());
            cd.extend_from_slice(&(e.name.len() as u16).to_le_bytes());
            cd.extend_from_slice(&28u16.to_le_bytes()); // extra field length
            cd.extend_from_slice(&0u16.to_le_bytes()); // comment length
            cd.extend_from_slice(&0u16.to_le_bytes()); // disk number
            cd.extend_from_slice(&0u16.to_le_bytes()); // internal attributes
            cd.extend_from_slice(&(0o100644u32 << 16).to_le_bytes()); // a regular file, rw-r--r--
            cd.extend_from_slice(&u32::MAX.to_le_bytes()); // offset: in the ZIP64 field
            cd.extend_from_slice(e.name.as_bytes());
            cd.extend_from_slice(&0x0001u16.to_le_bytes());
            cd.extend_from_slice(&24u16.to_le_bytes());
            cd.extend_from_slice(&e.size.to_le_bytes());
            cd.extend_from_slice(&e.size.to_le_bytes());
            cd.extend_from_slice(&e.offset.to_le_bytes());
        }
        let count = self.entries.len() as u64;
        let cd_size = cd.len() as u64;
        let end64 = start + cd_size;
        // ZIP64 end of central directory record.
        cd.extend_from_slice(&0x0606_4b50u32.to_le_bytes());
        cd.extend_from_slice(&44u64.to_le_bytes());
        cd.extend_from_slice(&VERSION_MADE_BY.to_le_bytes());
        cd.extend_from_slice(&VERSION_NEEDED.to_le_bytes());
        cd.extend_from_slice(&0u32.to_le_bytes());
        cd.extend_from_slice(&0u32.to_le_bytes());
        cd.extend_from_slice(&count.to_le_bytes());
        cd.extend_from_slice(&count.to_le_bytes());
        cd.extend_from_slice(&cd_size.to_le_bytes());
        cd.extend_from_slice(&start.to_le_bytes());
        // ZIP64 end of central directory locator.
        cd.extend_from_slice(&0x0706_4b50u32.to_le_bytes());
        cd.extend_from_slice(&0u32.to_le_bytes());
        cd.extend_from_slice(&end64.to_le_bytes());
        cd.extend_from_slice(&1u32.to_le_bytes());
        // End of central directory record: the ZIP64 record holds the numbers.
        cd.extend_from_slice(&0x0605_4b50u32.to_le_bytes());
        cd.extend_from_slice(&0u16.to_le_bytes());
        cd.extend_from_slice(&0u16.to_le_bytes());
        cd.extend_from_slice(&u16::MAX.to_le_bytes());
        cd.extend_from_slice(&u16::MAX.to_le_bytes());
        cd.extend_from_slice(&u32::MAX.to_le_bytes());
        cd.extend_from_slice(&u32::MAX.to_le_bytes());
        cd.extend_from_slice(&0u16.to_le_bytes());
        self.sink.put(&cd)?;
        Ok(self.sink)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crc32_is_the_zip_one() {
        // The standard check value of CRC-32/ISO-HDLC.
        assert_eq!(crc32(0, b"123456789"), 0xCBF4_3926);
        assert_eq!(crc32(crc32(0, b"1234"), b"56789"), 0xCBF4_3926);
        assert_eq!(crc32(0, b""), 0);
    }

    fn u16_at(b: &[u8], at: usize) -> u16 {
        u16::from_le_bytes([b[at], b[at + 1]])
    }
    fn u32_at(b: &[u8], at: usize) -> u32 {
        u32::from_le_bytes(b[at..at + 4].try_into().unwrap())
    }
    fn u64_at(b: &[u8], at: usize) -> u64 {
        u64::from_le_bytes(b[at..at + 8].try_into().unwrap())
    }

    /// The archive read back as a ZIP reader would: end record, ZIP64 locator and record,
    /// central directory, each local header, the stored bytes and their CRC.
    #[test]
    fn entries_read_back_through_the_zip64_records() {
        let a = super::super::npy::encode_f64(&[3], &[1.0, 2.0, 3.0]).unwrap();
        let b = super::super::npy::encode_text("hello");
        let mut w = NpzWriter::new(Vec::new());
        w.add("step-001/a", &a).unwrap();
        w.add("b", &b).unwrap();
        assert!(w.add("b", &b).is_err());
        let zip = w.finish().unwrap();
        let eocd = zip.len() - 22;
        assert_eq!(u32_at(&zip, eocd), 0x0605_4b50);
        let locator = eocd - 20;
        assert_eq!(u32_at(&zip, locator), 0x0706_4b50);
        let end64 = u64_at(&zip, locator + 8) as usize;
        assert_eq!(u32_at(&zip, end64), 0x0606_4b50);
        assert_eq!(u64_at(&zip, end64 + 24), 2);
        let mut at = u64_at(&zip, end64 + 48) as usize;
        let mut found = Vec::new();
        for _ in 0..2 {
            assert_eq!(u32_at(&zip, at), 0x0201_4b50);
            let name_len = u16_at(&zip, at + 28) as usize;
            let extra_len = u16_at(&zip, at + 30) as usize;
            let name = std::str::from_utf8(&zip[at + 46..at + 46 + name_len]).unwrap();
            let extra = at + 46 + name_len;
            assert_eq!(u16_at(&zip, extra), 1);
            let size = u64_at(&zip, extra + 4) as usize;
            let offset = u64_at(&zip, extra + 20) as usize;
            let crc = u32_at(&zip, at + 16);
            assert_eq!(u32_at(&zip, offset), 0x0403_4b50);
            let local_name = u16_at(&zip, offset + 26) as usize;
            let local_extra = u16_at(&zip, offset + 28) as usize;
            let data = offset + 30 + local_name + local_extra;
            let bytes = &zip[data..data + size];
            assert_eq!(crc32(0, bytes), crc);
            found.push((name.to_string(), bytes.to_vec()));
            at = extra + extra_len;
        }
        assert_eq!(
            found,
            [("step-001/a.npy".to_string(), a), ("b.npy".to_string(), b)]
        );
    }
}
