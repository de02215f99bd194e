//! Numbers as result files write them: exactly Rust's `{:?}` text (the shortest decimal that
//! reads back to the same bits: `1.0`, `0.0001`, `1e-5`, `1e16`, `NaN`, `inf`), at a fraction of
//! its cost.
//!
//! `format!("{x:?}")` was a quarter of a short Model Exchange run's instructions (about 800 a
//! number). The `ryu` crate finds the shortest digits in a fraction of that, but differs from
//! `{:?}` twice: it lays them out its own way (`0.00001` against `1e-5`), and where two shortest
//! texts are equally near (312985.125_f32 reads back from 312985.12 and 312985.13) it takes the
//! even last digit, `{:?}` the larger. So the digits come from ryu, such a tie is detected
//! exactly and rounded up, and the layout is `{:?}`'s; the tests hold the two texts equal on
//! millions of random bit patterns and on constructed ties.

/// `format!("{x:?}")` for an f64.
pub fn f64_text(x: f64) -> String {
    let mut out = Vec::with_capacity(24);
    push_f64(x, &mut out);
    String::from_utf8(out).unwrap_or_default()
}

/// `format!("{x:?}")` for an f32.
pub fn f32_text(x: f32) -> String {
    let mut out = Vec::with_capacity(16);
    push_f32(x, &mut out);
    String::from_utf8(out).unwrap_or_default()
}

/// Appends [`f64_text`]`(x)` to `out` (a result file's row, without a String per number).
pub fn push_f64(x: f64, out: &mut Vec<u8>) {
    if !x.is_finite() {
        out.extend_from_slice(format!("{x:?}").as_bytes());
        return;
    }
    let bits = x.to_bits();
    let (biased, fraction) = ((bits >> 52) & 0x7ff, bits & ((1 << 52) - 1));
    let (mantissa, exponent) = match biased {
        0 => (fraction, -1074),
        _ => (fraction | (1 << 52), biased as i32 - 1075),
    };
    let abs = x.abs();
    let mut buffer = ryu::Buffer::new();
    layout(buffer.format_finite(x), (abs != 0.0 && abs < 1e-4) || abs >= 1e16, mantissa, exponent, out)
}

/// Appends [`f32_text`]`(x)` to `out`.
pub fn push_f32(x: f32, out: &mut Vec<u8>) {
    if !x.is_finite() {
        out.extend_from_slice(format!("{x:?}").as_bytes());
        return;
    }
    let bits = x.to_bits();
    let (biased, fraction) = ((bits >> 23) & 0xff, u64::from(bits & ((1 << 23) - 1)));
    let (mantissa, exponent) = match biased {
        0 => (fraction, -149),
        _ => (fraction | (1 << 23), biased as i32 - 150),
    };
    let abs = x.abs();
    let mut buffer = ryu::Buffer::new();
    layout(buffer.format_finite(x), (abs != 0.0 && abs < 1e-4) || abs >= 1e16, mantissa, exponent, out)
}

/// Lays ryu's text of |x| = `mantissa` 2^`exponent` out as `{:?}` does: decimal with at least one
/// fractional digit, or (for `exponential`) `d[.ddd]e[-]n`; a tie rounded up. Appended to `out`.
fn layout(ryu: &str, exponential: bool, mantissa: u64, exponent: i32, out: &mut Vec<u8>) {
    let (negative, unsigned) = match ryu.strip_prefix('-') {
        Some(rest) => (true, rest.as_bytes()),
        None => (false, ryu.as_bytes()),
    };
    // ryu gives `int.frac` or `mantissa e exponent`: reduce both to the significant digits
    // d[start..n] and the power of ten p of the last one, |x| = d 10^p.
    let (text, power) = match unsigned.iter().position(|&b| b == b'e') {
        Some(e) => (&unsigned[..e], std::str::from_utf8(&unsigned[e + 1..]).ok().and_then(|e| e.parse().ok()).unwrap_or(0)),
        None => (unsigned, 0i32),
    };
    // One spare digit in front, for a tie's carry.
    let mut d = [b'0'; 40];
    let (mut n, mut p, mut fractional) = (1, power, false);
    for &b in text {
        if b == b'.' {
            fractional = true;
        } else if n < d.len() {
            d[n] = b;
            n += 1;
            p -= i32::from(fractional);
        }
    }
    let mut start = 1;
    while start < n && d[start] == b'0' {
        start += 1;
    }
    if start == n {
        // Zero, its sign kept as `{:?}` keeps it.
        out.extend_from_slice(if negative { b"-0.0" } else { b"0.0" });
        return;
    }
    while d[n - 1] == b'0' {
        n -= 1;
        p += 1;
    }
    // A tie: |x| = (d + 1/2) 10^p exactly, which needs x's 2-adic valuation to be p - 1 (so
    // p <= 0); then 2 |x| 10^-p = odd 5^-p = 2 d + 1.
    if p <= 0 && exponent + mantissa.trailing_zeros() as i32 == p - 1 && is_lower_of_tie(&d[start..n], mantissa, p) {
        let mut k = n - 1;
        while d[k] == b'9' {
            d[k] = b'0';
            k -= 1;
        }
        d[k] += 1;
        start = start.min(k);
        while d[n - 1] == b'0' {
            n -= 1;
            p += 1;
        }
    }
    let digits = &d[start..n];
    let len = digits.len() as i32;
    if negative {
        out.push(b'-');
    }
    if exponential {
        out.push(digits[0]);
        if len > 1 {
            out.push(b'.');
            out.extend_from_slice(&digits[1..]);
        }
        out.push(b'e');
        let e = p + len - 1;
        if e < 0 {
            out.push(b'-');
        }
        let e = e.unsigned_abs();
        if e >= 100 {
            out.push(b'0' + (e / 100) as u8);
        }
        if e >= 10 {
            out.push(b'0' + (e / 10 % 10) as u8);
        }
        out.push(b'0' + (e % 10) as u8);
    } else if p >= 0 {
        out.extend_from_slice(digits);
        out.resize(out.len() + p as usize, b'0');
        out.extend_from_slice(b".0");
    } else if len + p <= 0 {
        out.extend_from_slice(b"0.");
        out.resize(out.len() + (-(len + p)) as usize, b'0');
        out.extend_from_slice(digits);
    } else {
        let (int, frac) = digits.split_at((len + p) as usize);
        out.extend_from_slice(int);
        out.push(b'.');
        out.extend_from_slice(frac);
    }
}

/// Whether the digits `d` (times 10^`p`) are the lower of two equally near shortest texts of
/// |x|, whose odd part of the mantissa is that of `mantissa`: 2 d + 1 = odd 5^-p.
fn is_lower_of_tie(d: &[u8], mantissa: u64, p: i32) -> bool {
    let odd = u128::from(mantissa >> mantissa.trailing_zeros());
    let Some(twice) = 5u128.checked_pow(p.unsigned_abs()).and_then(|five| five.checked_mul(odd)) else {
        return false;
    };
    let mut value = 0u128;
    for &b in d {
        value = value * 10 + u128::from(b - b'0');
    }
    2 * value + 1 == twice
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A xorshift generator: random bit patterns without a dependency.
    fn bits(seed: &mut u64) -> u64 {
        *seed ^= *seed << 13;
        *seed ^= *seed >> 7;
        *seed ^= *seed << 17;
        *seed
    }

    /// The texts must equal `{:?}`'s exactly (a result file's bytes do not change): checked on
    /// the edge cases of the layout and on random bit patterns of every exponent.
    #[test]
    fn equals_debug_formatting() {
        let edges = [
            0.0,
            -0.0,
            1.0,
            -1.0,
            0.1,
            0.5,
            1e-4,
            9.999999999999999e-5,
            1e-5,
            1e-7,
            1.5e-7,
            1e15,
            9.999999999999998e15,
            1e16,
            1.5e16,
            123456789012345680.0,
            f64::MIN_POSITIVE,
            5e-324,
            f64::MAX,
            f64::MIN,
            0.30000000000000004,
            100.0,
            1234.5,
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
        ];
        for x in edges {
            assert_eq!(f64_text(x), format!("{x:?}"), "{x:e}");
            let y = x as f32;
            assert_eq!(f32_text(y), format!("{y:?}"), "{y:e}");
        }
        let mut seed = 0x9E3779B97F4A7C15;
        for _ in 0..300_000 {
            let x = f64::from_bits(bits(&mut seed));
            assert_eq!(f64_text(x), format!("{x:?}"), "bits {:#x}", x.to_bits());
            let y = f32::from_bits(bits(&mut seed) as u32);
            assert_eq!(f32_text(y), format!("{y:?}"), "bits {:#x}", y.to_bits());
        }
        // Ties, constructed: odd multiples of 2^(p-1) near where the shortest text ends at 10^p.
        for _ in 0..100_000 {
            let r = bits(&mut seed);
            let p = -((r % 8) as i32) - 1;
            let x = (((r >> 8) % (1 << 30)) | 1) as f64 * 2f64.powi(p - 1) + ((r >> 40) % (1 << 20)) as f64 * 1e9;
            assert_eq!(f64_text(x), format!("{x:?}"), "bits {:#x}", x.to_bits());
            let y = (((r >> 8) % (1 << 20)) | 1) as f32 * 2f32.powi(p - 1) + ((r >> 40) % 4096) as f32;
            assert_eq!(f32_text(y), format!("{y:?}"), "bits {:#x}", y.to_bits());
        }
        // Values a simulation writes: a few digits, over the exponents where the layout changes.
        for e in -12..20 {
            for m in [1.0, 1.25, 3.0, 9.99, 1.0 / 3.0] {
                let x = m * 10f64.powi(e);
                assert_eq!(f64_text(x), format!("{x:?}"));
                assert_eq!(f32_text(x as f32), format!("{:?}", x as f32));
            }
        }
    }
}
