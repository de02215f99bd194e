//! Element-wise loops over a state vector, two elements at a time.
//!
//! Written as `out[i] = f(i)` one element after the other, a loop stores element i before it
//! loads the inputs of element i + 1, and LLVM cannot prove the slices apart, so it keeps every
//! element scalar. Computing a pair before storing it lets it pack the pair into one SSE2
//! instruction per operation (baseline x86-64): DOPRI5's loops on the Ex. 4 sweep's bare loop
//! take 4 % fewer instructions of the whole. Each element is still computed by the same
//! operations in the same order, so the results are the same to the bit. Macros rather than
//! functions taking closures: the closures were not inlined, which cost 50 % more.

/// `[$value at $i = start, $value at $i = start + 1]`: the pair both loops below compute before
/// they use either element.
macro_rules! pair {
    ($start:expr, |$i:ident| $value:expr) => {
        [
            {
                let $i = $start;
                $value
            },
            {
                let $i = $start + 1;
                $value
            },
        ]
    };
}

/// `$out[$i] = $value` for every index `$i` of the slice `$out`.
macro_rules! fill {
    ($out:expr, |$i:ident| $value:expr) => {{
        let out: &mut [f64] = $out;
        let n = out.len();
        let mut start = 0;
        while start + 2 <= n {
            let pair = $crate::lanes::pair!(start, |$i| $value);
            let two = &mut out[start..start + 2];
            two[0] = pair[0];
            two[1] = pair[1];
            start += 2;
        }
        if start < n {
            let $i = start;
            out[start] = $value;
        }
    }};
}

/// The sum of `$term` over `$i` in `0..$n`, added in index order (as a plain loop adds, so the
/// rounding is the same), with the terms computed two at a time.
macro_rules! sum {
    ($n:expr, |$i:ident| $term:expr) => {{
        let n: usize = $n;
        let mut total = 0.0;
        let mut start = 0;
        while start + 2 <= n {
            let pair = $crate::lanes::pair!(start, |$i| $term);
            total += pair[0];
            total += pair[1];
            start += 2;
        }
        if start < n {
            let $i = start;
            total += $term;
        }
        total
    }};
}

pub(crate) use {fill, pair, sum};

#[cfg(test)]
mod tests {
    /// Both macros against the plain loops they replace, bit for bit, for every length up to
    /// seven (even, odd and empty vectors, so the pairs and the single last element are both
    /// covered), on values whose sums round differently in another order.
    #[test]
    fn pairs_give_the_plain_loops_bits() {
        let a: Vec<f64> = (0..7).map(|i| 1.0 / (3.0 + i as f64) * if i % 2 == 0 { 1e8 } else { -1e-8 }).collect();
        for n in 0..=7 {
            let (a, b) = (&a[..n], &a[..n]);
            let mut paired = vec![0.0; n];
            fill!(&mut paired, |i| a[i] * 0.1 + b[n - 1 - i] / 7.0);
            let plain: Vec<f64> = (0..n).map(|i| a[i] * 0.1 + b[n - 1 - i] / 7.0).collect();
            assert_eq!(paired.iter().map(|x| x.to_bits()).collect::<Vec<_>>(), plain.iter().map(|x| x.to_bits()).collect::<Vec<_>>());
            let mut plain_sum = 0.0;
            for x in a {
                plain_sum += x * x;
            }
            assert_eq!(sum!(n, |i| a[i] * a[i]).to_bits(), plain_sum.to_bits(), "n = {n}");
        }
    }
}
