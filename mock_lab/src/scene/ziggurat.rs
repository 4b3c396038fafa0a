//! Standard normal deviates by the ziggurat method (Marsaglia and Tsang, 2000, 128 layers): one
//! 32-bit draw, a compare and a multiply for 98.8 % of samples. A capture needs millions of them,
//! and the polar method's logarithm and square root cost more than the rest of the synthesis.

use std::sync::OnceLock;

/// Start of the tail (x-coordinate of the base layer's right edge).
const R: f64 = 3.442_619_855_899;
/// Area of each layer.
const V: f64 = 9.912_563_035_262_17e-3;
const M1: f64 = 2_147_483_648.0;

struct Tables {
    kn: [u32; 128],
    wn: [f64; 128],
    fn_: [f64; 128],
}

fn tables() -> &'static Tables {
    static TABLES: OnceLock<Tables> = OnceLock::new();
    TABLES.get_or_init(|| {
        let mut t = Tables {
            kn: [0; 128],
            wn: [0.0; 128],
            fn_: [0.0; 128],
        };
        let mut dn = R;
        let mut tn = dn;
        let q = V / (-0.5 * dn * dn).exp();
        t.kn[0] = ((dn / q) * M1) as u32;
        t.kn[1] = 0;
        t.wn[0] = q / M1;
        t.wn[127] = dn / M1;
        t.fn_[0] = 1.0;
        t.fn_[127] = (-0.5 * dn * dn).exp();
        for i in (1..=126).rev() {
            dn = (-2.0 * (V / dn + (-0.5 * dn * dn).exp()).ln()).sqrt();
            t.kn[i + 1] = ((dn / tn) * M1) as u32;
            tn = dn;
            t.fn_[i] = (-0.5 * dn * dn).exp();
            t.wn[i] = dn / M1;
        }
        t
    })
}

/// One standard normal deviate; `next_u32` supplies uniform 32-bit words and `uniform` uniform
/// numbers in (0, 1].
pub(super) fn normal(mut next_u32: impl FnMut() -> u32, mut uniform: impl FnMut() -> f64) -> f64 {
    let t = tables();
    let mut hz = next_u32() as i32;
    let mut iz = (hz & 127) as usize;
    if hz.unsigned_abs() < t.kn[iz] {
        return f64::from(hz) * t.wn[iz];
    }
    loop {
        if iz == 0 {
            // The tail beyond R, by Marsaglia's exponential method.
            loop {
                let x = -uniform().ln() / R;
                let y = -uniform().ln();
                if y + y >= x * x {
                    return if hz > 0 { R + x } else { -R - x };
                }
            }
        }
        let x = f64::from(hz) * t.wn[iz];
        if t.fn_[iz] + uniform() * (t.fn_[iz - 1] - t.fn_[iz]) < (-0.5 * x * x).exp() {
            return x;
        }
        hz = next_u32() as i32;
        iz = (hz & 127) as usize;
        if hz.unsigned_abs() < t.kn[iz] {
            return f64::from(hz) * t.wn[iz];
        }
    }
}

#[cfg(test)]
mod tests {

    #[test]
    fn moments_and_tails_are_gaussian() {
        let mut rng = super::super::SplitMix64::new(12345);
        let n = 1_000_000;
        let (mut s1, mut s2, mut s4, mut beyond3) = (0.0, 0.0, 0.0, 0usize);
        for _ in 0..n {
            let x = rng.gaussian();
            s1 += x;
            s2 += x * x;
            s4 += x * x * x * x;
            beyond3 += usize::from(x.abs() > 3.0);
        }
        let mean = s1 / n as f64;
        let var = s2 / n as f64 - mean * mean;
        let kurt = s4 / n as f64 / (var * var);
        assert!(mean.abs() < 0.005, "mean {mean}");
        assert!((var - 1.0).abs() < 0.005, "variance {var}");
        assert!((kurt - 3.0).abs() < 0.05, "kurtosis {kurt}");
        // P(|x| > 3) = 0.0027
        let p = beyond3 as f64 / n as f64;
        assert!((p - 0.0027).abs() < 0.0004, "tail {p}");
    }
}
