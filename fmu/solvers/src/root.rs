//! x^(1/5) for DOPRI5's step-size controller. libm's `pow` takes 30 ns, on the path from one
//! step to the next (the next step's stages need the new step size), about a tenth of a step;
//! this takes the exponent apart, looks the mantissa's root up in a table of 32 subintervals and
//! corrects it with the binomial series of (1 + v)^(1/5), |v| <= 1/64, to degree 8 (truncation
//! below 1e-18), evaluated in short independent chains. Within 3 ulp of the exact root (the
//! two table values, their product and the last sum round); the step counts it gives are those
//! of `powf` (the benchmark compares them with scipy's at every speed).

/// (1 + (j + 1/2)/32)^(1/5): the root at the centre of mantissa subinterval j.
const ROOTS: [f64; 32] = [
    1.0031056498762414,
    1.0092040059481215,
    1.0151584251926007,
    1.0209763330387365,
    1.0266645755955766,
    1.032229479333342,
    1.037676903202779,
    1.0430122843206975,
    1.0482406781573688,
    1.0533667940058158,
    1.0583950263863653,
    1.0633294829362316,
    1.0681740092486964,
    1.072932211056066,
    1.077607474092168,
    1.082202981921446,
    1.086721731980948,
    1.0911665500472363,
    1.0955401033113528,
    1.0998449122204894,
    1.1040833612242282,
    1.1082577085454854,
    1.1123700950811348,
    1.1164225525242748,
    1.1204170107889244,
    1.1243553048082613,
    1.1282391807691776,
    1.1320703018386642,
    1.1358502534312451,
    1.1395805480611745,
    1.143262629818316,
    1.1468978785024053,
];

/// 1 / (1 + (j + 1/2)/32).
const INVERSES: [f64; 32] = [
    0.9846153846153847,
    0.9552238805970149,
    0.927536231884058,
    0.9014084507042254,
    0.8767123287671232,
    0.8533333333333334,
    0.8311688311688312,
    0.810126582278481,
    0.7901234567901234,
    0.7710843373493976,
    0.7529411764705882,
    0.735632183908046,
    0.7191011235955056,
    0.7032967032967034,
    0.6881720430107527,
    0.6736842105263158,
    0.6597938144329897,
    0.6464646464646465,
    0.6336633663366337,
    0.6213592233009708,
    0.6095238095238096,
    0.5981308411214953,
    0.5871559633027523,
    0.5765765765765766,
    0.5663716814159292,
    0.5565217391304348,
    0.5470085470085471,
    0.5378151260504201,
    0.5289256198347108,
    0.5203252032520326,
    0.512,
    0.5039370078740157,
];

/// 2^(r/5), r = 0..4: the root of the exponent's remainder.
const POW2_FIFTHS: [f64; 5] = [1.0, 1.148698354997035, 1.3195079107728942, 1.515716566510398, 1.7411011265922482];

/// The binomial coefficients C(1/5, k), k = 0..8.
const C: [f64; 9] = [1.0, 0.2, -0.08, 0.048, -0.0336, 0.025536, -0.0204288, 0.01692672, -0.014387712];

/// x^(1/5); zero, subnormal, negative and non-finite x go to `powf`.
#[inline]
pub(crate) fn fifth_root(x: f64) -> f64 {
    let bits = x.to_bits();
    // The biased exponent, with the sign bit above it: 1..=2046 only for positive normal x.
    let biased = (bits >> 52) as i64;
    if !(1..2047).contains(&biased) {
        return x.powf(0.2);
    }
    // x = m 2^e, m in [1, 2); e = 5 q + r.
    let e = biased - 1023;
    let (q, r) = (e.div_euclid(5), e.rem_euclid(5) as usize);
    let j = ((bits >> 47) & 31) as usize;
    let m = f64::from_bits((bits & ((1 << 52) - 1)) | (1023 << 52));
    // m = c (1 + v): m - c is exact (both in [1, 2), c has 7 significant bits).
    let centre = 1.0 + (j as f64 + 0.5) / 32.0;
    let v = (m - centre) * INVERSES[j];
    // (1 + v)^(1/5) = 1 + t, t kept apart from the 1 so that it keeps its own precision.
    let v2 = v * v;
    let v4 = v2 * v2;
    let low = C[1] + C[2] * v + v2 * (C[3] + C[4] * v);
    let high = C[5] + C[6] * v + v2 * (C[7] + C[8] * v);
    let t = v * (low + v4 * high);
    let root = ROOTS[j] * POW2_FIFTHS[r];
    // 2^q is a power of two (|q| <= 205): an exact scale.
    (root + root * t) * f64::from_bits(((q + 1023) as u64) << 52)
}

#[cfg(test)]
mod tests {
    use super::fifth_root;

    /// Over the whole positive normal range (every exponent remainder and every mantissa
    /// subinterval, 2 million log-spaced points) y = fifth_root(x) has y^5 within 4e-15 of x:
    /// y within 3 ulp (6.7e-16) of x^(1/5), times 5, plus the rounding of the test's own three
    /// products. Where the controller uses it (errors from 1e-12 to 1e3) it is within 8e-16 of
    /// libm's pow(x, 0.2), which is within half an ulp there (farther out pow's exponent, 0.2
    /// rounded to a double, is not 1/5 to within 1.1e-17 ln x).
    #[test]
    fn agrees_with_the_exact_root_and_with_pow_to_three_ulps() {
        let (mut worst_power, mut worst_pow): (f64, f64) = (0.0, 0.0);
        let n = 2_000_000u64;
        for i in 0..n {
            let x = f64::from_bits(0x0010_0000_0000_0000 + i * ((0x7fe0_0000_0000_0000u64 - 0x0010_0000_0000_0000) / n));
            let y = fifth_root(x);
            let y2 = y * y;
            worst_power = worst_power.max((y2 * y2 * y / x - 1.0).abs());
            if (1e-12..=1e3).contains(&x) {
                worst_pow = worst_pow.max((y / x.powf(0.2) - 1.0).abs());
            }
        }
        println!("worst |y^5 / x - 1| {worst_power:e}; worst |y / pow(x, 0.2) - 1| in [1e-12, 1e3] {worst_pow:e}");
        assert!(worst_power < 4e-15, "{worst_power:e}");
        assert!(worst_pow < 8e-16, "{worst_pow:e}");
        for k in -200..200 {
            let x = 32f64.powi(k);
            assert!((fifth_root(x) / 2f64.powi(k) - 1.0).abs() <= f64::EPSILON, "32^{k}");
        }
        assert_eq!(fifth_root(0.0), 0.0);
        assert_eq!(fifth_root(f64::INFINITY), f64::INFINITY);
        assert!(fifth_root(f64::NAN).is_nan());
        let tiny = f64::MIN_POSITIVE / 8.0;
        assert_eq!(fifth_root(tiny), tiny.powf(0.2));
    }
}
