//! A cosine for sinusoidal forcing, whose phase moves a little from one call to the next.
//!
//! An adaptive solver evaluates a forcing such as quarter_car's road, a ω cos(ω t), at every
//! stage of every step; on the Ex. 4 sweep libm's `cos` was a quarter of the run time. Between
//! two stages the phase ω t moves by at most 0.105 rad there. [`PhaseCosine::cos`] rounds the
//! phase to the nearest quarter radian (its anchor), keeps the anchor's sine and cosine from the
//! call that last needed them, and adds the offset of at most 1/8 rad with the angle-addition
//! formula and short Taylor series: about 32 instructions instead of libm's 110 and a call. On
//! the sweep 1 call in 29 moves the anchor, and a run takes about 4 % less time. The process
//! remembers the anchors' libm sine-cosine pairs, which a sweep's runs share: 2 % fewer
//! instructions again, and only the first run to reach an anchor pays for its pair.
//!
//! The value depends on the phase alone, never on earlier calls (the memo only saves work), so
//! a run, a restored FMU state and a fresh instance agree to the bit. It is within one ulp of 1
//! (2.2e-16) of libm's cosine on the tests' 800,000 phases.
//!
//! Hand-written rather than taken from a crate: the libm crate's cosine was measured 8 % slower
//! than glibc's on the sweep, and no crate keeps an anchor between calls.

use std::cell::Cell;

use serde::{Deserialize, Serialize};

use crate::scalar::Scalar;
use std::sync::atomic::{AtomicU64, Ordering};

/// 1.5 * 2^50: adding it to a phase below 2^49 in magnitude rounds the phase to a multiple of
/// 1/4, the spacing of doubles there, and subtracting it again is exact.
const ROUND_TO_QUARTER: f64 = 1.5 * (1u64 << 50) as f64;
/// From here on the phase is left to libm: the rounding above would no longer be exact.
const LARGEST_ANCHORED: f64 = (1u64 << 49) as f64;

/// The memoizing cosine; see the module documentation. A model keeps one per forcing phase,
/// skipped by serialization (`#[serde(skip)]`): a restored state rebuilds it on its next call.
#[derive(Debug, Clone)]
pub struct PhaseCosine {
    /// (anchor, cos anchor, sin anchor): always a true triple, so a memo from another phase is
    /// only slower, never wrong. A `Cell` because a model's right-hand side takes `&self`.
    memo: Cell<(f64, f64, f64)>,
}

impl Default for PhaseCosine {
    fn default() -> Self {
        PhaseCosine { memo: Cell::new((0.0, 1.0, 0.0)) }
    }
}

impl PhaseCosine {
    /// cos(phase): the anchored sum when the memo holds the phase's anchor, else see
    /// `move_anchor`. Always inlined: a solver stage then holds a compare and 25 arithmetic
    /// instructions instead of a call.
    #[inline(always)]
    pub fn cos(&self, phase: f64) -> f64 {
        let anchor = (phase + ROUND_TO_QUARTER) - ROUND_TO_QUARTER;
        let (a, cos_a, sin_a) = self.memo.get();
        // The memo only holds anchors below 2^49, so a huge or NaN phase never matches.
        if a == anchor {
            near_anchor(cos_a, sin_a, phase - anchor)
        } else {
            move_anchor(&self.memo, phase, anchor)
        }
    }
}

/// A phase off the memo's anchor: one libm sine-cosine pair for the phase's own `anchor`, which
/// the memo keeps. Out of line and cold, so the inlined path stays short. Phases of 2^49 rad and
/// beyond, and NaN, get libm's cosine (their `anchor` means nothing).
#[cold]
#[inline(never)]
fn move_anchor(memo: &Cell<(f64, f64, f64)>, phase: f64, anchor: f64) -> f64 {
    if phase.is_nan() || phase.abs() >= LARGEST_ANCHORED {
        return phase.cos();
    }
    let (sin_a, cos_a) = anchor_sin_cos(anchor);
    memo.set((anchor, cos_a, sin_a));
    near_anchor(cos_a, sin_a, phase - anchor)
}

/// Anchors k/4 rad below this many (2,048 rad: the fastest Ex. 4 road's phase after 19 s) are
/// remembered by the process once libm has given their sine and cosine.
const REMEMBERED: usize = 1 << 13;

/// (cos bits, sin bits) of the anchor k/4 rad, 0 until computed (cos k/4 is never 0: k/4 is
/// rational). Every memo of the process shares it: a sweep's runs pass the same anchors, and
/// libm's sine-cosine pair at an anchor costs as much as 30 anchored cosines. The values are
/// libm's whoever computed them, so results stay those of a memo without the table. Atomics
/// because instances run on several threads; sin is published before cos, which marks the
/// entry complete.
static ANCHORS: [[AtomicU64; 2]; REMEMBERED] = [const { [AtomicU64::new(0), AtomicU64::new(0)] }; REMEMBERED];

/// (sin, cos) of `anchor`, a multiple of 1/4 below 2^49 in magnitude: libm's, from [`ANCHORS`]
/// when it holds them.
fn anchor_sin_cos(anchor: f64) -> (f64, f64) {
    // Exact: a multiple of 1/4 times 4 is an integer below 2^51.
    let k = anchor * 4.0;
    if !(0.0..REMEMBERED as f64).contains(&k) {
        return anchor.sin_cos();
    }
    let entry = &ANCHORS[k as usize];
    let cos_bits = entry[0].load(Ordering::Acquire);
    if cos_bits != 0 {
        return (f64::from_bits(entry[1].load(Ordering::Relaxed)), f64::from_bits(cos_bits));
    }
    let (sin_a, cos_a) = anchor.sin_cos();
    entry[1].store(sin_a.to_bits(), Ordering::Relaxed);
    entry[0].store(cos_a.to_bits(), Ordering::Release);
    (sin_a, cos_a)
}

/// cos(a + b) from cos a, sin a and the offset b, |b| <= 1/8 (exact: the phase and its anchor
/// are doubles less than 1/8 apart, the anchor a multiple of 1/4).
///
/// Computed as cos a + (cos a (cos b - 1) - sin a sin b): the bracket is at most 0.13 in
/// magnitude, so its rounding errors shrink by that much. The Taylor series of cos b - 1 to
/// b^10 and of sin b to b^9 leave out less than 3e-18 at |b| = 1/8.
///
/// The two series are evaluated by Horner's rule side by side ([`horner_pair`]): the sine's
/// series, a term shorter, starts a step later from 0 (0 z + c is c exactly), so each lane
/// rounds as its own Horner sum does.
#[inline(always)]
fn near_anchor(cos_a: f64, sin_a: f64, b: f64) -> f64 {
    const COS: [f64; 5] = [-1.0 / 3_628_800.0, 1.0 / 40_320.0, -1.0 / 720.0, 1.0 / 24.0, -1.0 / 2.0];
    const SIN: [f64; 5] = [0.0, 1.0 / 362_880.0, -1.0 / 5040.0, 1.0 / 120.0, -1.0 / 6.0];
    let z = b * b;
    let [cos_sum, sin_sum] = horner_pair(z, &COS, &SIN);
    let cos_b_minus_1 = z * cos_sum;
    let sin_b = b + b * z * sin_sum;
    cos_a + (cos_a * cos_b_minus_1 - sin_a * sin_b)
}

/// The Horner sums of `a` and `b` at `z` (highest coefficient first), side by side: one SSE2
/// multiply and add per step on x86_64 (part of its base instruction set), where the compiler
/// left pairs of plain arrays half scalar. The same roundings as two scalar Horner sums.
#[inline(always)]
fn horner_pair(z: f64, a: &[f64; 5], b: &[f64; 5]) -> [f64; 2] {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_add_pd, _mm_cvtsd_f64, _mm_mul_pd, _mm_set1_pd, _mm_set_pd, _mm_unpackhi_pd};
        // SAFETY: SSE2 is part of every x86_64 target; these intrinsics only compute.
        unsafe {
            let zz = _mm_set1_pd(z);
            let mut p = _mm_set_pd(b[0], a[0]);
            for k in 1..5 {
                p = _mm_add_pd(_mm_set_pd(b[k], a[k]), _mm_mul_pd(zz, p));
            }
            [_mm_cvtsd_f64(p), _mm_cvtsd_f64(_mm_unpackhi_pd(p, p))]
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        let mut p = [a[0], b[0]];
        for k in 1..5 {
            p = [a[k] + z * p[0], b[k] + z * p[1]];
        }
        p
    }
}

/// A sinusoidal forcing `amplitude cos(omega t)`, such as quarter_car's road rate: a model
/// derives it from its parameters (a `#[derived]` field, see [`crate::Derived`]) and evaluates
/// it at every solver stage. Simulating (`T = f64`), its cosine is the memoized
/// [`PhaseCosine`]; differentiating, the plain cosine of the dual number.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Harmonic<T> {
    /// The amplitude.
    pub amplitude: T,
    /// The angular frequency (rad/s).
    pub omega: T,
    /// The anchor of the last cosine; not part of the saved state (see [`PhaseCosine`]).
    #[serde(skip)]
    memo: PhaseCosine,
}

impl<T: Scalar> Harmonic<T> {
    /// `amplitude cos(omega t)`.
    pub fn new(amplitude: T, omega: T) -> Harmonic<T> {
        Harmonic { amplitude, omega, memo: PhaseCosine::default() }
    }

    /// The value at time `t`: `amplitude cos(omega t)`. Always inlined, as the cosine it calls.
    #[inline(always)]
    pub fn at(&self, t: T) -> T {
        self.amplitude * (self.omega * t).cos_near(&self.memo)
    }
}

impl<T: PartialEq> PartialEq for Harmonic<T> {
    /// The same forcing (whatever anchor the memos hold).
    fn eq(&self, other: &Self) -> bool {
        self.amplitude == other.amplitude && self.omega == other.omega
    }
}

impl<T: Scalar> Default for Harmonic<T> {
    /// No forcing (zero amplitude and frequency).
    fn default() -> Self {
        Harmonic::new(T::zero(), T::zero())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Deterministic pseudo-random numbers in [0, 1) (a 64-bit LCG's high bits).
    fn uniform(seed: &mut u64) -> f64 {
        *seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (*seed >> 11) as f64 / (1u64 << 53) as f64
    }

    /// The largest |PhaseCosine - libm| over `phases`, called in order on one memo.
    fn largest_difference(phases: impl Iterator<Item = f64>) -> f64 {
        let c = PhaseCosine::default();
        phases.map(|p| (c.cos(p) - p.cos()).abs()).fold(0.0, f64::max)
    }

    /// Against glibc's cosine (an independent implementation, within 1 ulp of the exact value)
    /// on 800,000 phases, solver-like runs of small increments and random jumps up to 10^4 rad,
    /// and on both sides of 1,600 anchor boundaries (b = +-1/8, where the series err most).
    /// Measured: 1.1e-16, one ulp of a value near 1. The bound, 2^-52, allows one more such
    /// rounding; a series one term shorter (2.6e-16 left out at the boundaries) fails it.
    #[test]
    fn agrees_with_libm_within_the_error_budget() {
        let mut seed = 1;
        // A stage-like walk: steps of up to 0.105 rad, as the fastest Ex. 4 speed takes.
        let mut phase = 0.0;
        let walk = (0..400_000).map(|_| {
            phase += 0.105 * uniform(&mut seed);
            phase
        });
        let walk_max = largest_difference(walk.collect::<Vec<_>>().into_iter());
        let jumps: Vec<f64> = (0..400_000).map(|_| (uniform(&mut seed) - 0.5) * 2e4).collect();
        let jumps_max = largest_difference(jumps.into_iter());
        let edges = (-800..800).flat_map(|k| {
            let edge = k as f64 / 4.0 + 0.125;
            [edge, f64::from_bits(edge.to_bits() - 1), f64::from_bits(edge.to_bits() + 1)]
        });
        let edges_max = largest_difference(edges);
        for (what, max) in [("walk", walk_max), ("jumps", jumps_max), ("anchor edges", edges_max)] {
            assert!(max <= f64::EPSILON, "{what}: largest difference from libm {max:e}");
        }
        // And it is not libm's own value everywhere (the test would then prove nothing).
        assert!(walk_max > 0.0 && jumps_max > 0.0);
    }

    /// The memo only saves work: every phase gets the same bits whatever came before it (in
    /// order, reversed, from a fresh memo), which keeps runs and restored FMU states identical.
    #[test]
    fn the_value_does_not_depend_on_earlier_calls() {
        let mut seed = 7;
        let phases: Vec<f64> = (0..10_000).map(|_| (uniform(&mut seed) - 0.3) * 50.0).collect();
        let forward = PhaseCosine::default();
        let backward = PhaseCosine::default();
        let a: Vec<u64> = phases.iter().map(|&p| forward.cos(p).to_bits()).collect();
        let b: Vec<u64> = phases.iter().rev().map(|&p| backward.cos(p).to_bits()).collect();
        let fresh: Vec<u64> = phases.iter().map(|&p| PhaseCosine::default().cos(p).to_bits()).collect();
        assert!(a.iter().eq(b.iter().rev()), "reversed order changed a value");
        assert_eq!(a, fresh, "a used memo changed a value");
    }

    /// The process's table of anchors hands out libm's sine and cosine to the bit: on first use
    /// and when read back, from two threads filling it at once, at both ends of its range and
    /// for the anchors beyond it (negative, past the last entry), which libm computes.
    #[test]
    fn remembered_anchors_are_libms() {
        let anchors: Vec<f64> = (-40..REMEMBERED as i64 + 40).map(|k| k as f64 / 4.0).collect();
        let libm: Vec<(u64, u64)> = anchors.iter().map(|a| a.sin_cos()).map(|(s, c)| (s.to_bits(), c.to_bits())).collect();
        let table = || -> Vec<(u64, u64)> { anchors.iter().map(|&a| anchor_sin_cos(a)).map(|(s, c)| (s.to_bits(), c.to_bits())).collect() };
        let (first, second) = std::thread::scope(|s| {
            let one = s.spawn(table);
            let two = s.spawn(table);
            (one.join().unwrap(), two.join().unwrap())
        });
        assert!(first == libm && second == libm, "a thread got another value than libm's");
        assert_eq!(table(), libm, "read back from the filled table");
    }

    /// Exact at the anchors (cos 0 = 1 with the initial memo), libm's value beyond 2^49 rad, and
    /// NaN for NaN and infinities, as libm.
    #[test]
    fn edge_phases() {
        let c = PhaseCosine::default();
        assert_eq!(c.cos(0.0), 1.0);
        assert_eq!(c.cos(-0.0), 1.0);
        assert_eq!(c.cos(0.25), 0.25f64.cos());
        assert_eq!(c.cos(-1000.0), (-1000.0f64).cos());
        for huge in [LARGEST_ANCHORED, -LARGEST_ANCHORED, 1e17, 1e300, f64::MAX] {
            assert_eq!(c.cos(huge), huge.cos(), "{huge:e}");
        }
        let below = f64::from_bits(LARGEST_ANCHORED.to_bits() - 1);
        assert!((c.cos(below) - below.cos()).abs() <= f64::EPSILON);
        for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            assert!(c.cos(bad).is_nan(), "{bad}");
        }
        // A NaN call leaves a working memo.
        assert!((c.cos(3.1) - 3.1f64.cos()).abs() <= f64::EPSILON);
    }
}
