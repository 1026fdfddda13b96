//! The shading kernels' lane vectors (src/runtime/shading/lanes.rs): the portable build
//! computes each lane as scalar code does, and the AVX2 and AVX-512 builds are bit-identical
//! to it lane by lane (NaN payloads aside), wherever the CPU has them.

use primflow::runtime::shading::lanes::{load, on_each_isa, F32s, F64s, Isa, LaneProgram, Mask, Portable, LANES};

/// The same operations on every instruction set, lane by lane, bit for bit, including
/// NaN, infinities, signed zeros, subnormals and u32 values past i32's range.
fn exercise<I: Isa>() -> Vec<u64> {
    let a = F32s::<I>::new(std::array::from_fn(|j| {
        [1.5, f32::NAN, f32::INFINITY, -2.0, -0.0, f32::NEG_INFINITY, 3.0, 1e38][j % 8] * (1.0 + j as f32)
    }));
    let b = F32s::<I>::new(std::array::from_fn(|j| {
        [0.5, 1.0, 2.0, -2.0, 0.0, -1.0, 1e-40, -1e38][(j + j / 8) % 8]
    }));
    let wa = F64s::from_f32(a) * 1.000000001;
    let wb = F64s::from_u32(&std::array::from_fn(|j| {
        [0, 1, 7, u32::MAX, 1 << 31, 12345, 4000000000, 3][j % 8]
    }));
    let m = a.lt(b) | (wa.gt(wb) & !b.equals(F32s::splat(-2.0)));
    let mut out: Vec<u64> = vec![];
    let f32s = [
        a + b,
        a - b,
        a * b,
        a / b,
        -a,
        b.sqrt(),
        m.select(a, b),
        F32s::from_f64(wa / wb),
        a.or_zero_if_not_finite(),
    ];
    // NaN's sign and payload are not compared: constant folding and the hardware pick
    // different ones, and every NaN takes the same path in the kernels.
    let bits32 = |x: f32| if x.is_nan() { 1 } else { u64::from(x.to_bits()) };
    for v in f32s {
        out.extend(v.lanes().map(bits32));
    }
    let f64s = [
        wa + wb,
        wa * wb,
        (-wa).sqrt(),
        (wa / 3.0).floor(),
        m.select(wa, wb),
        F64s::from_f32(b),
    ];
    for v in f64s {
        out.extend(F32s::from_f64(v).lanes().map(bits32));
    }
    for mask in [
        m,
        wa.not_equal(wb),
        wa.finite(),
        Mask::nonzero(&std::array::from_fn(|j| [0, 3, 0, 0, 9, 0, 0, 1][j % 8])),
    ] {
        out.extend(mask.lanes().map(u64::from));
        out.push(u64::from(mask.any()));
    }
    out
}

#[test]
fn portable_lanes_compute_each_lane_as_scalar_code_does() {
    let a = F32s::<Portable>::new(std::array::from_fn(|j| j as f32 - 3.0));
    let m = a.lt(F32s::splat(0.0));
    assert_eq!(m.lanes(), std::array::from_fn(|j| j < 3));
    assert_eq!(
        m.select(a, -a).lanes(),
        std::array::from_fn(|j| -(j as f32 - 3.0).abs())
    );
    let special = [1.0, f32::NAN, f32::INFINITY, -2.0, 0.0, f32::NEG_INFINITY, 3.0, 1e38];
    let f = F32s::<Portable>::new(std::array::from_fn(|j| special[j % 8]));
    let finite = [1.0, 0.0, 0.0, -2.0, 0.0, 0.0, 3.0, 1e38];
    assert_eq!(
        f.or_zero_if_not_finite().lanes(),
        std::array::from_fn(|j| finite[j % 8])
    );
    assert_eq!(
        load(&[1, 2, 3], 1, 7),
        std::array::from_fn(|j| [2, 3].get(j).copied().unwrap_or(7))
    );
    assert_eq!(load(&[1, 2, 3], 5, 7), [7; LANES]);
    assert!(!(m & !m).any() && (m | !m).lanes() == [true; LANES]);
    assert_eq!(F64s::<Portable>::from_u32(&[u32::MAX; LANES]).0[0], 4294967295.0);
}

struct Exercise;

impl LaneProgram for Exercise {
    fn run<I: Isa>() -> Vec<u64> {
        exercise::<I>()
    }
}

#[test]
fn avx2_and_avx512_lanes_are_bit_identical_to_portable_ones() {
    let results = on_each_isa::<Exercise>();
    let (_, portable) = &results[0];
    for (build, r) in &results[1..] {
        assert_eq!(r, portable, "{build}");
    }
    eprintln!(
        "compared {} instruction sets with the portable lanes",
        results.len() - 1
    );
}
