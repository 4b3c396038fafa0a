//! Measured numbers as people read them: a zero is `0`, never `0.00e0` nor `-0.0`.

/// A signed value at `decimals` places: `+1.5`, `-0.3`, and `0.0` for whatever rounds to zero
/// (never `-0.0`, which reads as a measured motion).
pub fn signed(value: f64, decimals: usize) -> String {
    let text = format!("{value:+.decimals$}");
    if text[1..].bytes().all(|b| b == b'0' || b == b'.') {
        text[1..].to_string()
    } else {
        text
    }
}

/// A rate such as a bit error ratio: `0` when nothing was counted, else three significant
/// digits in scientific notation (`1.25e-4`).
pub fn rate(value: f64) -> String {
    if value == 0.0 {
        "0".into()
    } else {
        format!("{value:.2e}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn zeros_read_as_zeros() {
        assert_eq!(signed(-0.04, 1), "0.0");
        assert_eq!(signed(-0.0, 1), "0.0");
        assert_eq!(signed(0.0, 2), "0.00");
        assert_eq!(signed(-0.06, 1), "-0.1");
        assert_eq!(signed(1.25, 1), "+1.2");
        assert_eq!(rate(0.0), "0");
        assert_eq!(rate(1.25e-4), "1.25e-4");
        assert_eq!(rate(0.5), "5.00e-1");
    }
}
