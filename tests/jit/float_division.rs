//! Float division by a constant power of two is lowered as a multiply by its reciprocal
//! (`exact_reciprocal` in src/jit/lower.rs): `x / 2^k` and `x * 2^-k` round the same real
//! number, so they must agree with Rust's `x / c` bit for bit on every dividend, NaN,
//! infinities, signed zeros and subnormals included; other divisors (3, 0, 2^127 whose
//! reciprocal is subnormal) stay divisions. Checked in uniform code (setup) and in pixel
//! code, on every tier, and in the CLIF.

use crate::support;

use primflow::diag::SourceMap;
use primflow::jit::{Jit, Tier};
use primflow::runtime::{Renderer, Value};

const DIVISION: &str = r#"
float divide(float n, int j) {
    if (j == 0) return n / 16.0;
    if (j == 1) return n / 0.5;
    if (j == 2) return n / -4.0;
    if (j == 3) return n / 3.0;
    if (j == 4) return n / 0.0;
    if (j == 5) return n / 1.0;
    return n / 1.7014118e38;
}

// Bit-equal: NaN matches NaN, and 1 / q tells +0 from -0.
bool same(float q, float w) {
    return (q == w && 1 / q == 1 / w) || (q != q && w != w);
}

primitive division(float rect[4]; float num[16]; float want[112]; varying float X, Y; inout varying fixed<32,32> Z)
{
    bound(rect[0], rect[1], rect[2], rect[3]);
    int bad = 0;
    for (int k = 0; k < 112; k++) {
        if (!same(divide(num[k % 16], k / 16), want[k]))
            bad = bad + 1;
    }
    int i = int(X), j = int(Y);
    bool ok = same(divide(num[i], j), want[j * 16 + i]);
    Z = 0.25 + (ok ? 0.5 : 0.0) + (bad == 0 ? 0.125 : 0.0);
}
"#;

const DIVISORS: [f32; 7] = [16.0, 0.5, -4.0, 3.0, 0.0, 1.0, 1.7014118e38];

#[test]
fn division_by_constants_matches_rust_bit_for_bit_in_every_tier() {
    let mut sources = SourceMap::new();
    let program = support::library_with(&mut sources, &[("division.prim", DIVISION)]);
    let num = support::special_floats();
    let want: Vec<f32> = DIVISORS.iter().flat_map(|&c| num.iter().map(move |&n| n / c)).collect();
    let mut r = Renderer::new(program.clone());
    r.set_image_size(16, 7).unwrap();
    r.set_tile_size(8).unwrap();
    r.begin("division").unwrap();
    r.rast_param("rect", &Value(vec![0.0, 0.0, 16.0, 7.0])).unwrap();
    r.rast_param("num", &Value(num.to_vec())).unwrap();
    r.rast_param("want", &Value(want)).unwrap();
    r.end().unwrap();
    let frame = support::all_tiers(&program, &r, "division");
    let all_good = (0.875f64 * 4294967296.0) as u32;
    for y in 0..7 {
        for x in 0..16 {
            assert_eq!(
                frame.depth_at(x, y),
                Some(all_good),
                "{} / {}: pixel ({x}, {y}) (0.25 = both wrong, 0.375 = pixel code wrong, 0.75 = setup wrong)",
                num[x as usize],
                DIVISORS[y as usize]
            );
        }
    }
}

#[test]
fn only_powers_of_two_with_normal_reciprocals_become_multiplies() {
    let mut sources = SourceMap::new();
    let program = support::library_with(&mut sources, &[("division.prim", DIVISION)]);
    let mut r = Renderer::new(program.clone());
    r.begin("division").unwrap();
    r.end().unwrap();
    let inst = &r.instances()[0];
    for tier in [Tier::Fast, Tier::Optimised] {
        let jit = Jit::at_tier(program.clone(), tier).unwrap();
        let clif = jit.clif(inst.func, &inst.key).unwrap();
        // `want`'s reciprocals of 16, 0.5, -4 (1 / 1.0 is 1.0, which prints as 0x1.0p0).
        for r in ["0x1.000000p-4", "0x1.000000p1", "-0x1.000000p-2"] {
            assert!(
                clif.lines().any(|l| l.contains("f32const") && l.contains(r)),
                "{tier:?}: no multiply by {r}"
            );
        }
        // What stays a division: by 3, by 0 and by 2^127, and the pixel code's `1 / q`.
        let divisors: Vec<&str> = clif
            .lines()
            .filter(|l| l.contains("fdiv"))
            .filter_map(|l| l.split(';').nth(1))
            .collect();
        assert!(!divisors.is_empty(), "{tier:?}: no division left");
        for d in &divisors {
            assert!(
                !d.contains("0x1.000000p4") && !d.contains("0x1.000000p-1"),
                "{tier:?}: a division by a power of two is left: {d}"
            );
        }
    }
}
