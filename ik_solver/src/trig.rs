//! `atan2` of several angles at once, without branches.
//!
//! The closed-form leg IK ends in three inverse tangents per leg, independent of one another
//! once their arguments are known. `f64::atan2` (the C library's) is a call the compiler
//! cannot see into, and it branches on its arguments, so six of them run one after the other.
//! The same function written without branches, two angles at a time in SIMD lanes (`wide`:
//! SSE2 on x86-64, NEON on aarch64, plain code elsewhere), lets the six overlap, within two
//! units in the last place of `f64::atan2` (the tests measure it over every quadrant, octant
//! and magnitude; two where the angle is smaller than the atan c it is taken from, so that
//! the rounding of u counts double, one elsewhere). Six cost about half of the C library's
//! six (`trig/atan2_x6` in the kinematics bench).
//!
//! Method. The signs of x and y and whether |y| > |x| reduce the angle to atan(num / den),
//! 0 <= num <= den. That is moved next to the nearest of c = 0, 1/4, 1/2, 3/4, 1 by
//! atan t = atan c + atan u, u = (t - c) / (1 + c t) = (num - c den) / (den + c num): one
//! division, |u| <= 1/8. atan u is its Taylor series to u^17 (what is left is below 3e-18 of
//! it); atan c, pi/2 and pi are each two doubles (value and remainder), and what is added to
//! atan u is summed with its rounding error kept, so the result is rounded about once.

use std::f64::consts::{FRAC_PI_2, FRAC_PI_4};

use wide::f64x2;

/// atan c (value, remainder) for c = 1/4, 1/2, 3/4, 1: the nearest double and what it
/// leaves (the remainders to 1e-33, from a 60-digit series).
const ATAN_QUARTER: (f64, f64) = (0.244_978_663_126_864_14, 1.069_875_561_873_445_1e-17);
const ATAN_HALF: (f64, f64) = (0.463_647_609_000_806_1, 2.269_877_745_296_168_7e-17);
const ATAN_THREE_QUARTERS: (f64, f64) = (0.643_501_108_793_284_4, 1.583_478_505_144_428_6e-17);
const ATAN_ONE: (f64, f64) = (FRAC_PI_4, 3.061_616_997_868_383e-17);
/// From one c to the next: the midpoint num/den must be past, and the step of atan c (value,
/// remainder). Neighbouring values are within a factor 2 of each other, so each value step is
/// exact and so is every partial sum: the sum of the first k is the value of atan c_k itself.
const STEPS: [(f64, (f64, f64)); 4] = [
    (0.125, ATAN_QUARTER),
    (0.375, step(ATAN_QUARTER, ATAN_HALF)),
    (0.625, step(ATAN_HALF, ATAN_THREE_QUARTERS)),
    (0.875, step(ATAN_THREE_QUARTERS, ATAN_ONE)),
];

const fn step(from: (f64, f64), to: (f64, f64)) -> (f64, f64) {
    (to.0 - from.0, to.1 - from.1)
}

/// pi / 2 and pi (value, remainder).
const HALF_PI: (f64, f64) = (FRAC_PI_2, 6.123_233_995_736_766e-17);
const PI: (f64, f64) = (std::f64::consts::PI, 1.224_646_799_147_353_2e-16);

/// Taylor coefficients of atan u / u - 1 in s = u^2, highest first: (-1)^n / (2n + 1), n = 8..1.
const SERIES: [f64; 8] = [
    1.0 / 17.0,
    -1.0 / 15.0,
    1.0 / 13.0,
    -1.0 / 11.0,
    1.0 / 9.0,
    -1.0 / 7.0,
    1.0 / 5.0,
    -1.0 / 3.0,
];

/// `y[i].atan2(x[i])` for every i, within 2 ulp of it, for finite arguments (signed zeros as
/// `f64::atan2`: atan2(+-0, -0) = +-pi, atan2(+-0, +0) = +-0). An infinite argument gives NaN.
/// Two angles at a time in SIMD lanes; an odd last one shares its pair with atan2(0, 1).
#[inline]
pub fn atan2_each<const N: usize>(y: [f64; N], x: [f64; N]) -> [f64; N] {
    let mut out = [0.0; N];
    for i in (0..N).step_by(2) {
        let pair = |v: &[f64; N], pad| f64x2::new([v[i], v.get(i + 1).copied().unwrap_or(pad)]);
        let [a, b] = atan2_x2(pair(&y, 0.0), pair(&x, 1.0)).to_array();
        out[i] = a;
        if let Some(o) = out.get_mut(i + 1) {
            *o = b;
        }
    }
    out
}

/// atan2 of two pairs of arguments, lane by lane, without a branch.
#[inline(always)]
pub(crate) fn atan2_x2(y: f64x2, x: f64x2) -> f64x2 {
    let splat = f64x2::splat;
    let (ax, ay) = (x.abs(), y.abs());
    // Past the diagonal the angle is pi/2 minus the one of the swapped pair.
    let swap = ay.simd_gt(ax);
    let num = swap.select(ax, ay);
    let den = swap.select(ay, ax);
    // The nearest c: 1/4 for each of the midpoints 1/8, 3/8, 5/8, 7/8 that num/den is past,
    // and atan c as the sum of the steps between the atan of neighbouring c (each step and
    // each partial sum exact: see STEPS).
    let (mut c, mut hi, mut lo) = (f64x2::ZERO, f64x2::ZERO, f64x2::ZERO);
    for (mid, step) in STEPS {
        let past = num.simd_gt(den * splat(mid));
        c += past & splat(0.25);
        hi += past & splat(step.0);
        lo += past & splat(step.1);
    }
    // num = den = 0 (the origin): u = 0, the angle is that of the signs alone.
    let bottom = den.simd_gt(f64x2::ZERO).select(den + c * num, f64x2::ONE);
    let u = (num - c * den) / bottom;
    // The angle is base +- (atan c + atan u) with base 0, pi/2 minus (past the diagonal),
    // pi minus (x negative) or pi/2 plus (both). base +- atan c as a value and its exact
    // rounding error (|base| >= |atan c| unless base is 0), worked out while the division
    // runs, so that once atan u is known the last steps are one sign and two additions.
    let x_negative = x.is_sign_negative();
    let base_hi = swap.select(splat(HALF_PI.0), x_negative & splat(PI.0));
    let base_lo = swap.select(splat(HALF_PI.1), x_negative & splat(PI.1));
    // A mask lane is all ones: its sign bit flips the sign of the angle terms.
    let minus = swap ^ x_negative;
    let (hi, lo) = (hi.flip_signs(minus), lo.flip_signs(minus));
    let head = base_hi + hi;
    let tail = ((base_hi - head) + hi) + (base_lo + lo);
    (head + (atan_small(u).flip_signs(minus) + tail)).copysign(y)
}

/// atan u for |u| <= 1/8: the Taylor series to u^17, in s = u^2 by Estrin's scheme (pairs,
/// then pairs of pairs, so that the multiplications wait on each other three deep, not eight).
#[inline(always)]
fn atan_small(u: f64x2) -> f64x2 {
    let s = u * u;
    let s2 = s * s;
    let s4 = s2 * s2;
    let [c8, c7, c6, c5, c4, c3, c2, c1] = SERIES.map(f64x2::splat);
    let poly = ((c1 + c2 * s) + s2 * (c3 + c4 * s)) + s4 * ((c5 + c6 * s) + s2 * (c7 + c8 * s));
    u + u * s * poly
}

#[cfg(test)]
mod tests {
    use proptest::prelude::RngExt;
    use proptest::test_runner::{RngAlgorithm, TestRng};

    use super::*;

    /// Distance in units in the last place between two finite doubles of the same sign (or
    /// zeros).
    fn ulps(a: f64, b: f64) -> u64 {
        if a == b {
            return 0;
        }
        assert_eq!(
            a.is_sign_negative(),
            b.is_sign_negative(),
            "{a:e} and {b:e} differ in sign"
        );
        a.abs().to_bits().abs_diff(b.abs().to_bits())
    }

    /// A value of either sign, magnitude 10^-6 .. 10^6 spread evenly in its exponent.
    fn any_magnitude(rng: &mut TestRng) -> f64 {
        let magnitude = 10f64.powf(rng.random_range(-6.0..6.0));
        if rng.random_bool(0.5) {
            -magnitude
        } else {
            magnitude
        }
    }

    #[test]
    fn agrees_with_the_c_library_within_two_ulp_everywhere() {
        // proptest's seeded generator: the same points on every run.
        let mut rng = TestRng::deterministic_rng(RngAlgorithm::ChaCha);
        let mut worst = (0, 0.0, 0.0);
        for _ in 0..200_000 {
            let y = [any_magnitude(&mut rng), any_magnitude(&mut rng)];
            // Half the x as large as y, give or take 10 % (the octant boundary and the
            // midpoints between the c).
            let x = [any_magnitude(&mut rng), y[1] * rng.random_range(0.9..1.1)];
            let got = atan2_each(y, x);
            for i in 0..2 {
                let d = ulps(got[i], y[i].atan2(x[i]));
                if d > worst.0 {
                    worst = (d, y[i], x[i]);
                }
            }
        }
        assert!(
            worst.0 <= 2,
            "{} ulp from f64::atan2 at y = {:e}, x = {:e}",
            worst.0,
            worst.1,
            worst.2
        );
    }

    /// The partial sums of the value steps give back each atan c exactly (what makes the
    /// branch-free table lookup exact).
    #[test]
    fn the_steps_add_up_to_each_atan_exactly() {
        let mut sum = 0.0;
        for ((_, step), want) in
            STEPS
                .iter()
                .zip([ATAN_QUARTER, ATAN_HALF, ATAN_THREE_QUARTERS, ATAN_ONE])
        {
            sum += step.0;
            assert_eq!(sum.to_bits(), want.0.to_bits());
        }
    }

    #[test]
    fn exact_angles_and_signed_zeros_are_those_of_the_c_library() {
        let cases = [
            (0.0, 1.0),
            (-0.0, 1.0),
            (0.0, -1.0),
            (-0.0, -1.0),
            (0.0, 0.0),
            (-0.0, 0.0),
            (0.0, -0.0),
            (-0.0, -0.0),
            (1.0, 0.0),
            (-1.0, 0.0),
            (1.0, -0.0),
            (1.0, 1.0),
            (-1.0, -1.0),
            (1.0, 8.0),
            (3.0, 8.0),
            (5.0, 8.0),
            (7.0, 8.0),
            (1e-300, 1.0),
            (1.0, 1e-300),
        ];
        for (y, x) in cases {
            let got = atan2_each([y], [x])[0];
            let want = f64::atan2(y, x);
            assert!(
                got.to_bits() == want.to_bits() || ulps(got, want) <= 1,
                "atan2({y:e}, {x:e}) = {got:e}, the C library gives {want:e}"
            );
        }
        // By hand: the diagonal and the axes.
        assert_eq!(atan2_each([1.0], [1.0])[0], FRAC_PI_4);
        assert_eq!(atan2_each([1.0], [0.0])[0], FRAC_PI_2);
        assert_eq!(atan2_each([0.0], [-2.0])[0], std::f64::consts::PI);
        assert_eq!(atan2_each([-0.0], [-2.0])[0], -std::f64::consts::PI);
    }
}
