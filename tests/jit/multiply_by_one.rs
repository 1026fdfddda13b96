//! A float multiply by the constant 1 is not emitted (`Lower::fmul` in src/jit/lower.rs):
//! `x * 1` is `x` for every float, NaN, infinities, signed zeros and subnormals included,
//! so `n * 1.0`, `1.0 * n`, `n / 1.0` and the unit components of a transformed vector
//! must agree with Rust's product bit for bit. Checked in uniform code (setup) and in
//! pixel code, on every tier, and in the CLIF.

use crate::support;

use primflow::diag::SourceMap;
use primflow::jit::{Jit, Tier};
use primflow::runtime::{Renderer, Value};

const TIMES_ONE: &str = r#"
float times_one(float n, int j) {
    if (j == 0) return n * 1.0;
    if (j == 1) return 1.0 * n;
    if (j == 2) return n / 1.0;
    return n * 1.0 * 1.0;
}

// Bit-equal: NaN matches NaN, and 1 / q tells +0 from -0.
bool same(float q, float w) {
    return (q == w && 1 / q == 1 / w) || (q != q && w != w);
}

primitive times_one_prim(float rect[4]; float num[16]; varying float X, Y; inout varying fixed<32,32> Z)
{
    bound(rect[0], rect[1], rect[2], rect[3]);
    int bad = 0;
    for (int k = 0; k < 64; k++) {
        if (!same(times_one(num[k % 16], k / 16), num[k % 16]))
            bad = bad + 1;
    }
    int i = int(X), j = int(Y);
    bool ok = same(times_one(num[i], j), num[i]);
    Z = 0.25 + (ok ? 0.5 : 0.0) + (bad == 0 ? 0.125 : 0.0);
}

// A transform of the constant point (0, 0, 0) and of the axis vectors (1, 0, 0): the
// products by 1 are left out, the ones by 0 stay (they make NaN of an infinite entry).
primitive unit_transform(varying float X, Y; inout varying fixed<32,32> Z)
{
    float e[4] = transform("object", "device", {1, 0, 0, 0});
    float o[4] = transform("object", "device", {0, 0, 0, 1});
    Z = 0.5 + 0.0 * (e[0] + o[3]);
}
"#;

#[test]
fn multiplying_by_one_gives_the_operand_bit_for_bit_in_every_tier() {
    let mut sources = SourceMap::new();
    let program = support::library_with(&mut sources, &[("times_one.prim", TIMES_ONE)]);
    let num = support::special_floats();
    // What Rust computes, so the test says what the fold must keep.
    for n in num {
        assert!(n * 1.0 == n || n.is_nan(), "{n}");
        assert_eq!((n * 1.0).to_bits(), n.to_bits(), "{n}");
    }
    let mut r = Renderer::new(program.clone());
    r.set_image_size(16, 4).unwrap();
    r.set_tile_size(8).unwrap();
    r.begin("times_one_prim").unwrap();
    r.rast_param("rect", &Value(vec![0.0, 0.0, 16.0, 4.0])).unwrap();
    r.rast_param("num", &Value(num.to_vec())).unwrap();
    r.end().unwrap();
    // Pixel (x, y) checks operand x in form y: depth 0.375 = its pixel code wrong, 0.75 =
    // the setup's loop over every pair wrong, 0.25 = both.
    let all_good = (0.875f64 * 4294967296.0) as u32;
    support::assert_depth_in_every_jit(&r, "times_one_prim", |_, _| all_good);
}

/// The CLIF lines that multiply by the constant 1: an `fmul` with an operand defined by
/// `f32const 0x1.000000p0` in the same function (tier 0 prints two, numbered apart).
fn multiplies_by_one(clif: &str) -> Vec<&str> {
    let mut found = vec![];
    for function in clif.split("\nfunction ") {
        let ones: Vec<&str> = function
            .lines()
            .filter(|l| l.contains("= f32const 0x1.000000p0"))
            .filter_map(|l| l.split('=').next().map(str::trim))
            .collect();
        found.extend(function.lines().filter(|l| l.contains("fmul")).filter(|l| {
            l.split(';')
                .next()
                .is_some_and(|code| code.split([',', ' ']).any(|operand| ones.contains(&operand)))
        }));
    }
    found
}

#[test]
fn no_multiply_by_one_is_emitted() {
    let mut sources = SourceMap::new();
    let program = support::library_with(&mut sources, &[("times_one.prim", TIMES_ONE)]);
    for prim in ["times_one_prim", "unit_transform"] {
        let mut r = Renderer::new(program.clone());
        r.begin(prim).unwrap();
        r.end().unwrap();
        let inst = &r.instances()[0];
        for tier in [Tier::Fast, Tier::Optimised] {
            let jit = Jit::at_tier(program.clone(), tier).unwrap();
            let clif = jit.clif(inst.func, &inst.key).unwrap();
            assert!(clif.contains("fmul"), "{prim} {tier:?}: no multiply at all");
            let left = multiplies_by_one(&clif);
            assert!(left.is_empty(), "{prim} {tier:?}: multiplies by 1 left: {left:#?}");
        }
    }
}
