//! NumPy `.npy` (format version 1.0) encoding of little-endian float64, complex128 and
//! complex64 arrays.
//!
//! Layout: magic `\x93NUMPY`, version 1.0, a little-endian u16 header length, an ASCII dict header
//! padded with spaces and a newline so the data starts on a 64-byte boundary, then the data in C
//! (row-major) order. `numpy.load` reads the result directly.

use num_complex::Complex64;

/// Encodes a float64 array of the given shape (row-major). Panics never: a shape whose product
/// differs from `data.len()` is reported as `Err` with both numbers.
pub(crate) fn encode_f64(shape: &[usize], data: &[f64]) -> Result<Vec<u8>, String> {
    check_shape(shape, data.len())?;
    let mut out = header("<f8", shape);
    out.reserve(data.len() * 8);
    for v in data {
        out.extend_from_slice(&v.to_le_bytes());
    }
    Ok(out)
}

/// Encodes a complex128 array of the given shape (row-major), real part first.
pub fn encode_c128(shape: &[usize], data: &[Complex64]) -> Result<Vec<u8>, String> {
    check_shape(shape, data.len())?;
    let mut out = header("<c16", shape);
    out.reserve(data.len() * 16);
    for v in data {
        out.extend_from_slice(&v.re.to_le_bytes());
        out.extend_from_slice(&v.im.to_le_bytes());
    }
    Ok(out)
}

/// Encodes a complex array of the given shape (row-major) as complex64 (`<c8`: float32 real
/// and imaginary parts, half the bytes of complex128; each part rounded to the nearest f32).
pub(crate) fn encode_c64(shape: &[usize], data: &[Complex64]) -> Result<Vec<u8>, String> {
    check_shape(shape, data.len())?;
    let mut out = header("<c8", shape);
    out.reserve(data.len() * 8);
    for v in data {
        out.extend_from_slice(&(v.re as f32).to_le_bytes());
        out.extend_from_slice(&(v.im as f32).to_le_bytes());
    }
    Ok(out)
}

/// Encodes an unsigned byte array (`|u1`) of the given shape (row-major).
pub(crate) fn encode_u8(shape: &[usize], data: &[u8]) -> Result<Vec<u8>, String> {
    check_shape(shape, data.len())?;
    let mut out = header("|u1", shape);
    out.extend_from_slice(data);
    Ok(out)
}

/// Encodes `text` as a 0-d unicode array (`<U{n}`, UTF-32LE): `numpy.load` gives it back with
/// `str(array)`, without a pickle.
pub(crate) fn encode_text(text: &str) -> Vec<u8> {
    let n = text.chars().count().max(1);
    let mut out = header(&format!("<U{n}"), &[]);
    out.reserve(4 * n);
    for c in text.chars() {
        out.extend_from_slice(&u32::from(c).to_le_bytes());
    }
    // The empty string: one NUL code point (numpy strips trailing NULs).
    if text.is_empty() {
        out.extend_from_slice(&[0; 4]);
    }
    out
}

/// Encodes a one-dimensional structured array of float64 fields (`[('name', '<f8'), ...]`),
/// `rows` long: each field's values, in the fields' order. Field names must be ASCII
/// identifiers (they go into the header as Python literals).
pub(crate) fn encode_records(rows: usize, fields: &[(&str, Vec<f64>)]) -> Result<Vec<u8>, String> {
    if fields.is_empty() {
        return Err("a structured array needs at least one field".into());
    }
    for (name, values) in fields {
        if name.is_empty() || !name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') {
            return Err(format!(
                "field name {name:?}: ASCII letters, digits and _ only"
            ));
        }
        if values.len() != rows {
            return Err(format!(
                "field {name} holds {} values for {rows} rows",
                values.len()
            ));
        }
    }
    let descr = format!(
        "[{}]",
        fields
            .iter()
            .map(|(name, _)| format!("('{name}', '<f8')"))
            .collect::<Vec<_>>()
            .join(", ")
    );
    let mut out = header_descr(&descr, &[rows]);
    out.reserve(rows * fields.len() * 8);
    for r in 0..rows {
        for (_, values) in fields {
            out.extend_from_slice(&values[r].to_le_bytes());
        }
    }
    Ok(out)
}

fn check_shape(shape: &[usize], len: usize) -> Result<(), String> {
    let product: usize = shape.iter().product();
    if product != len {
        return Err(format!(
            "shape {shape:?} holds {product} values but {len} were given"
        ));
    }
    Ok(())
}

fn header(descr: &str, shape: &[usize]) -> Vec<u8> {
    header_descr(&format!("'{descr}'"), shape)
}

/// The header of an array whose `descr` is given as its Python literal (a quoted dtype string,
/// or a structured array's list of fields).
fn header_descr(descr: &str, shape: &[usize]) -> Vec<u8> {
    let shape_text = match shape {
        [n] => format!("({n},)"),
        _ => format!(
            "({})",
            shape
                .iter()
                .map(|d| d.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        ),
    };
    let mut dict = format!("{{'descr': {descr}, 'fortran_order': False, 'shape': {shape_text}, }}");
    // magic (6) + version (2) + header length (2) + dict + '\n' must be a multiple of 64.
    let unpadded = 10 + dict.len() + 1;
    let pad = (64 - unpadded % 64) % 64;
    dict.extend(std::iter::repeat_n(' ', pad));
    dict.push('\n');
    let mut out = Vec::with_capacity(10 + dict.len());
    out.extend_from_slice(b"\x93NUMPY\x01\x00");
    out.extend_from_slice(&(dict.len() as u16).to_le_bytes());
    out.extend_from_slice(dict.as_bytes());
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn header_is_aligned_and_data_follows() {
        let bytes = encode_f64(&[2, 3], &[0.0, 1.0, 2.0, 3.0, 4.0, 5.0]).unwrap();
        assert_eq!(&bytes[..8], b"\x93NUMPY\x01\x00");
        let hlen = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
        assert_eq!((10 + hlen) % 64, 0);
        let header = std::str::from_utf8(&bytes[10..10 + hlen]).unwrap();
        assert!(header.contains("'shape': (2, 3)"), "{header}");
        assert!(header.ends_with('\n'));
        assert_eq!(bytes.len(), 10 + hlen + 48);
        let last = f64::from_le_bytes(bytes[bytes.len() - 8..].try_into().unwrap());
        assert_eq!(last, 5.0);
    }

    #[test]
    fn one_dimensional_shape_has_a_trailing_comma() {
        let bytes = encode_c128(&[1], &[Complex64::new(1.5, -2.0)]).unwrap();
        let hlen = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
        let header = std::str::from_utf8(&bytes[10..10 + hlen]).unwrap();
        assert!(header.contains("'descr': '<c16'") && header.contains("(1,)"));
        let re = f64::from_le_bytes(bytes[10 + hlen..18 + hlen].try_into().unwrap());
        let im = f64::from_le_bytes(bytes[18 + hlen..26 + hlen].try_into().unwrap());
        assert_eq!((re, im), (1.5, -2.0));
    }

    fn dict(bytes: &[u8]) -> (&str, &[u8]) {
        let hlen = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
        assert_eq!((10 + hlen) % 64, 0);
        (
            std::str::from_utf8(&bytes[10..10 + hlen]).unwrap(),
            &bytes[10 + hlen..],
        )
    }

    #[test]
    fn text_bytes_and_records_have_numpys_headers() {
        let bytes = encode_u8_ok(&[0, 1, 1]);
        let (h, data) = dict(&bytes);
        assert!(
            h.contains("'descr': '|u1'") && h.contains("'shape': (3,)"),
            "{h}"
        );
        assert_eq!(data, [0, 1, 1]);
        let text = encode_text("µs");
        let (h, data) = dict(&text);
        assert!(
            h.contains("'descr': '<U2'") && h.contains("'shape': ()"),
            "{h}"
        );
        assert_eq!(data, [0xb5, 0, 0, 0, 0x73, 0, 0, 0]);
        let empty = encode_text("");
        let (h, data) = dict(&empty);
        assert!(h.contains("'<U1'"));
        assert_eq!(data, [0; 4]);
        let r = encode_records(
            2,
            &[("range_m", vec![1.0, 2.0]), ("snr_db", vec![3.0, 4.0])],
        )
        .unwrap();
        let (h, data) = dict(&r);
        assert!(
            h.contains("'descr': [('range_m', '<f8'), ('snr_db', '<f8')]"),
            "{h}"
        );
        let values: Vec<f64> = data
            .chunks_exact(8)
            .map(|c| f64::from_le_bytes(c.try_into().unwrap()))
            .collect();
        assert_eq!(values, [1.0, 3.0, 2.0, 4.0]);
        assert!(encode_records(1, &[("bad name", vec![1.0])]).is_err());
        assert!(encode_records(2, &[("x", vec![1.0])]).is_err());
    }

    fn encode_u8_ok(data: &[u8]) -> Vec<u8> {
        encode_u8(&[data.len()], data).unwrap()
    }

    #[test]
    fn wrong_shape_is_an_error() {
        assert!(encode_f64(&[4], &[1.0]).is_err());
    }
}

/// Decodes a little-endian float64 `.npy` (version 1.0 or 2.0, C order): its shape and values.
/// Anything else is refused with what was found.
pub(crate) fn decode_f64(bytes: &[u8]) -> Result<(Vec<usize>, Vec<f64>), String> {
    if bytes.len() < 10 || &bytes[..6] != b"\x93NUMPY" {
        return Err("not a .npy file (no \\x93NUMPY magic)".into());
    }
    let (len, start) = match bytes[6] {
        1 => (u16::from_le_bytes([bytes[8], bytes[9]]) as usize, 10),
        2 | 3 if bytes.len() >= 12 => (
            u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize,
            12,
        ),
        v => return Err(format!(".npy format version {v}: 1, 2 or 3 is read")),
    };
    let dict = bytes
        .get(start..start + len)
        .and_then(|h| std::str::from_utf8(h).ok())
        .ok_or("a .npy header that is not ASCII or runs past the file")?;
    let descr_ok = dict.contains("'descr': '<f8'") || dict.contains("\"descr\": \"<f8\"");
    if !descr_ok {
        return Err(format!(
            "dtype in {:?}: little-endian float64 ('<f8')",
            dict.trim()
        ));
    }
    if dict.contains("'fortran_order': True") {
        return Err("Fortran order: C (row-major) order is read".into());
    }
    let shape_text = dict
        .split("'shape':")
        .nth(1)
        .and_then(|s| s.split('(').nth(1))
        .and_then(|s| s.split(')').next())
        .ok_or("a .npy header without a shape")?;
    let shape = shape_text
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| {
            s.parse::<usize>()
                .map_err(|_| format!("shape ({shape_text})"))
        })
        .collect::<Result<Vec<usize>, String>>()?;
    let count = shape.iter().product::<usize>();
    let data = &bytes[start + len..];
    if data.len() != count * 8 {
        return Err(format!(
            "shape {shape:?} needs {} bytes of data, the file holds {}",
            count * 8,
            data.len()
        ));
    }
    let values = data
        .chunks_exact(8)
        .map(|c| f64::from_le_bytes(c.try_into().expect("8 bytes")))
        .collect();
    Ok((shape, values))
}

#[cfg(test)]
mod decode_tests {
    use super::*;

    #[test]
    fn what_is_encoded_decodes() {
        let data: Vec<f64> = (0..12).map(f64::from).collect();
        let bytes = encode_f64(&[4, 3], &data).unwrap();
        assert_eq!(decode_f64(&bytes).unwrap(), (vec![4, 3], data));
        assert!(decode_f64(b"hello").is_err());
        let c = encode_c128(&[1], &[Complex64::new(1.0, 2.0)]).unwrap();
        assert!(decode_f64(&c).unwrap_err().contains("<f8"));
        assert!(decode_f64(&bytes[..bytes.len() - 1])
            .unwrap_err()
            .contains("needs"));
    }
}
