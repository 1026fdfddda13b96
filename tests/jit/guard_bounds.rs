//! Bounds refined by guards (src/mid/bounds.rs, `GuardFacts`): after `if (c) return;`
//! in pixel code every lane still executing has `c` false, so a float local compared with
//! constants there (`!(z >= 0 && z <= 1)`) is known non-NaN and in range until it is
//! assigned again, and its conversion to `fixed<32,32>` drops the fix-ups for NaN and
//! negative values (`fixed::convert_bounded`). These tests pin down that the facts are used
//! only where they hold: depth through fixed<32,32> at the values where the conversion's
//! cases meet (0, the smallest subnormal and normal, 2^-33 and 3 * 2^-34 around the first
//! rounding step, 0.5 -+ one step around 2^31, 1 - 2^-24 and 1.0 at the saturation), lanes
//! the guard retires next to lanes it keeps in one group, NaN, guards with `||`, a local
//! reassigned after the guard (plainly, under a varying `if`, in a loop), a guard under a
//! varying `if`, an `int(...)` after the guard (one `cvttps2dq` once the guard bounds its
//! operand); and screen_triangle itself, whose depth guard the block walk's pass variant
//! drops. Every frame renders with tier 0, tier 1 and tier 1 without unrolling, bit-identical
//! (`support::all_tiers`), and each pixel's depth is checked against a reference computed
//! here: the saturating conversion in f64 (round half to even, NaN -> 0, clamp to u32).

// The expected-value closures spell each guard as the primitive's source does
// (`z >= 0 && z <= 1`), NaN behaviour included, rather than as a range.
#![allow(clippy::manual_range_contains)]

use crate::support;

use std::sync::Arc;

use primflow::diag::SourceMap;
use primflow::ir::Program;
use primflow::jit::{Jit, Tier};
use primflow::runtime::{Renderer, Value};

const W: u32 = 16;
const H: u32 = 4;

/// Raw depth the marker primitive writes first (0.0625): what a pixel the guarded
/// primitive leaves alone reads.
const MARKER: u32 = 1 << 28;

/// The z values, one per pixel column (permuted per row, so each group of four mixes lanes
/// the guards keep and retire).
fn values() -> [f32; 16] {
    [
        0.0,
        f32::from_bits(1),
        f32::MIN_POSITIVE,
        2f32.powi(-33),       // scaled: 0.5, ties to even: 0
        3.0 * 2f32.powi(-34), // scaled: 0.75, rounds to 1
        1.0 - 2f32.powi(-24), // scaled: 2^32 - 256, the largest below 2^32
        1.0,                  // scaled: 2^32, saturates to u32::MAX
        0.5 + 2f32.powi(-24), // 2^31 + 256
        0.5,                  // 2^31
        0.5 - 2f32.powi(-25), // 2^31 - 128
        -0.0,
        -(2f32.powi(-40)), // negative, rounds to -0: 0 where not retired
        f32::NAN,
        1.5,
        f32::INFINITY,
        -1.0,
    ]
}

/// The language's float -> fixed<32,32> conversion, raw: round half to even, NaN -> 0,
/// saturate to [0, u32::MAX].
fn sat(z: f32) -> u32 {
    if z.is_nan() {
        return 0;
    }
    let r = (z as f64 * 4294967296.0).round_ties_even();
    r.clamp(0.0, u32::MAX as f64) as u32
}

/// The value index at pixel (px, py), as the primitives compute it.
fn index(px: u32, py: u32) -> usize {
    ((px + 5 * py) % 16) as usize
}

/// Pixel code of each case after `float z = vals[i];`, and the raw depth it leaves at a
/// pixel with that z and pixel centre x (`None`: the guard retired the lane).
type Expected = fn(f32, f32) -> Option<u32>;
const CASES: &[(&str, &str, Expected)] = &[
    (
        "screen_triangle's guard",
        "if (!(z >= 0 && z <= 1)) return; fixed<32,32> t = z; Z = t;",
        |z, _| (z >= 0.0 && z <= 1.0).then(|| sat(z)),
    ),
    (
        "a guard with || (NaN goes through)",
        "if (z < 0 || z > 1) return; Z = z;",
        |z, _| (!(z < 0.0 || z > 1.0)).then(|| sat(z)),
    ),
    ("one-sided, no upper bound", "if (!(z >= 0)) return; Z = z;", |z, _| {
        (z >= 0.0).then(|| sat(z))
    }),
    (
        "constants on the left, two guards",
        "if (!(0 <= z)) return; if (!(1 >= z)) return; Z = z;",
        |z, _| (z >= 0.0 && z <= 1.0).then(|| sat(z)),
    ),
    (
        "reassigned after the guard",
        "if (!(z >= 0 && z <= 1)) return; z = z - 2; Z = z;",
        |z, _| (z >= 0.0 && z <= 1.0).then(|| sat(z - 2.0)),
    ),
    (
        "a guard under a varying if",
        "if (X < 8) { if (!(z >= 0 && z <= 1)) return; } Z = z;",
        |z, x| (x >= 8.0 || (z >= 0.0 && z <= 1.0)).then(|| sat(z)),
    ),
    (
        "reassigned under a varying if",
        "if (!(z >= 0 && z <= 1)) return; if (X >= 8) z = 1.5 - 4 * z; Z = z;",
        |z, x| (z >= 0.0 && z <= 1.0).then(|| sat(if x >= 8.0 { 1.5 - 4.0 * z } else { z })),
    ),
    (
        "reassigned in a loop after the conversion",
        "if (!(z >= 0 && z <= 1)) return;
         fixed<32,32> first = 0, second = 0;
         for (int k = 0; k < 2; k++) {
             fixed<32,32> t = z;
             if (k == 0) first = t; else second = t;
             z = -1 - z;
         }
         Z = first + second;",
        |z, _| (z >= 0.0 && z <= 1.0).then(|| sat(z).wrapping_add(sat(-1.0 - z))),
    ),
    ("equality", "if (z != 0.5) return; Z = z;", |z, _| {
        (z == 0.5).then(|| sat(z))
    }),
    (
        "bounded below 2^-1: one cvttps2dq",
        "if (!(z >= 0 && z <= 0.4375)) return; Z = z;",
        |z, _| (z >= 0.0 && z <= 0.4375).then(|| sat(z)),
    ),
    (
        "an int conversion after the guard",
        "if (!(z >= 0 && z <= 1)) return; int n = int(z * 1000000000); Z = float(n) / 2000000000 + 0.5;",
        |z, _| (z >= 0.0 && z <= 1.0).then(|| sat(((z * 1e9) as i32) as f32 / 2e9 + 0.5)),
    ),
];

fn sources() -> Vec<(String, String)> {
    let mut out = vec![(
        "marker.prim".to_string(),
        "primitive marker(float rect[4]; varying float X, Y; inout varying fixed<32,32> Z)
         {
             bound(rect[0], rect[1], rect[2], rect[3]);
             Z = 0.0625;
         }"
        .to_string(),
    )];
    for (i, (_, body, _)) in CASES.iter().enumerate() {
        out.push((
            format!("guarded{i}.prim"),
            format!(
                "primitive guarded{i}(float rect[4]; float vals[16]; varying float X, Y;
                                      inout varying fixed<32,32> Z)
                 {{
                     bound(rect[0], rect[1], rect[2], rect[3]);
                     int i = (int(X) + 5 * int(Y)) % 16;
                     float z = vals[i];
                     {body}
                 }}"
            ),
        ));
    }
    out
}

fn library(sources: &mut SourceMap) -> Arc<Program> {
    let user = self::sources();
    let user: Vec<(&str, &str)> = user.iter().map(|(n, t)| (n.as_str(), t.as_str())).collect();
    support::library_with(sources, &user)
}

fn scene(program: &Arc<Program>, case: usize) -> Renderer {
    let rect = Value(vec![0.0, 0.0, W as f32, H as f32]);
    let mut r = Renderer::new(program.clone());
    r.set_image_size(W, H).unwrap();
    r.begin("marker").unwrap();
    r.rast_param("rect", &rect).unwrap();
    r.end().unwrap();
    r.begin(&format!("guarded{case}")).unwrap();
    r.rast_param("rect", &rect).unwrap();
    r.rast_param("vals", &Value(values().to_vec())).unwrap();
    r.end().unwrap();
    r
}

#[test]
fn guarded_depth_matches_the_saturating_reference_in_every_tier() {
    let mut sources = SourceMap::new();
    let program = library(&mut sources);
    let vals = values();
    for (case, (what, _, expected)) in CASES.iter().enumerate() {
        let frame = support::all_tiers(&program, &scene(&program, case), what);
        let (mut kept, mut retired) = (0, 0);
        for py in 0..H {
            for px in 0..W {
                let z = vals[index(px, py)];
                let want = expected(z, px as f32 + 0.5);
                kept += want.is_some() as u32;
                retired += want.is_none() as u32;
                assert_eq!(
                    frame.depth_at(px, py),
                    Some(want.unwrap_or(MARKER)),
                    "{what}: pixel ({px}, {py}), z = {z:e}"
                );
            }
        }
        // Every case keeps some lanes and (but the varying-if ones) retires others.
        assert!(
            kept > 0 && (retired > 0 || case == 5),
            "{what}: {kept} kept, {retired} retired"
        );
    }
}

/// The reference itself at the conversion's corners (as the module doc lists them).
#[test]
fn the_reference_conversion_has_the_documented_corners() {
    let v = values();
    let raw: Vec<u32> = v.iter().map(|&z| sat(z)).collect();
    assert_eq!(
        raw,
        [
            0,
            0,
            0,
            0,
            1,
            u32::MAX - 255,
            u32::MAX,
            (1 << 31) + 256,
            1 << 31,
            (1 << 31) - 128,
            0,
            0,
            0,
            u32::MAX,
            u32::MAX,
            0
        ]
    );
}

/// screen_triangle over a 64 x 64 image (large enough for the block walk, whose pass
/// variant drops the depth guard it proved), one triangle per z: depth is the saturating
/// conversion of z wherever the reference coverage says, and the perspective-linear
/// parameter (0.25 at every vertex) reads exactly 0.25 there; z outside [0, 1] or NaN
/// draws nothing.
#[test]
fn screen_triangle_depth_at_the_conversion_corners() {
    const S: u32 = 64;
    let program = support::library();
    let v2 = [[0.5, 0.5], [63.5, 2.0], [3.0, 63.0]];
    let coverage = support::reference_coverage(v2.map(|p| p.map(f64::from)), S, S);
    let zs = [
        0.0,
        f32::from_bits(1),
        f32::MIN_POSITIVE,
        2f32.powi(-33),
        3.0 * 2f32.powi(-34),
        0.5 - 2f32.powi(-25),
        0.5,
        1.0 - 2f32.powi(-24),
        1.0,
        -(2f32.powi(-40)),
        1.5,
        f32::NAN,
    ];
    for z in zs {
        let what = format!("z = {z:e}");
        let mut r = support::renderer(&program, S, S, false);
        r.material_interp("p0", "perspective_linear", &[]).unwrap();
        let v = v2.map(|p| [p[0], p[1], z, 1.0]);
        support::screen_triangle(&mut r, v, &[("p0", [vec![0.25], vec![0.25], vec![0.25]])]);
        let frame = support::all_tiers(&program, &r, &what);
        let drawn = (0.0..=1.0).contains(&z);
        let mut covered = 0;
        for py in 0..S {
            for px in 0..S {
                let inside = drawn && coverage[(py * S + px) as usize];
                covered += inside as u32;
                let (depth, p0) = if inside { (sat(z), vec![0.25]) } else { (0, vec![0.0]) };
                assert_eq!(frame.depth_at(px, py), Some(depth), "{what}: depth at ({px}, {py})");
                assert_eq!(frame.param_at("p0", px, py), Some(p0), "{what}: p0 at ({px}, {py})");
            }
        }
        assert!(!drawn || covered > 1500, "{what}: {covered} pixels");
    }
}

/// The CLIF shows the narrowing: the same primitive converts `z` to fixed<32,32> without
/// the `maxps` (an `fcmp lt` select) for NaN and negative lanes when the guard's fact holds
/// at the conversion, and with it when an assignment (`z = z * 1`) ended the fact.
#[test]
fn a_guard_fact_drops_the_conversions_nan_fixup_and_an_assignment_ends_it() {
    if !cfg!(target_arch = "x86_64") {
        return;
    }
    let prim = |name: &str, between: &str| {
        format!(
            "primitive {name}(float rect[4]; float zc; varying float X, Y; inout varying fixed<32,32> Z)
             {{
                 bound(rect[0], rect[1], rect[2], rect[3]);
                 float z = zc * X;
                 if (!(z >= 0 && z <= 1)) return;
                 {between}
                 Z = z;
             }}"
        )
    };
    let narrowed = prim("narrowed", "");
    let reassigned = prim("reassigned", "z = z * 1;");
    let mut sources = SourceMap::new();
    let program = support::library_with(
        &mut sources,
        &[
            ("narrowed.prim", narrowed.as_str()),
            ("reassigned.prim", reassigned.as_str()),
        ],
    );
    let mut counts = vec![];
    for name in ["narrowed", "reassigned"] {
        let mut r = Renderer::new(program.clone());
        r.set_image_size(16, 8).unwrap();
        r.begin(name).unwrap();
        r.rast_param("rect", &Value(vec![0.0, 0.0, 16.0, 8.0])).unwrap();
        r.rast_param("zc", &Value(vec![0.01])).unwrap();
        r.end().unwrap();
        let inst = &r.instances()[0];
        for tier in [Tier::Fast, Tier::Optimised] {
            let jit = Jit::at_tier(program.clone(), tier).unwrap();
            let clif = jit.clif(inst.func, &inst.key).unwrap();
            let selects = clif.lines().filter(|l| l.contains("fcmp lt")).count();
            counts.push((name, tier, selects));
        }
    }
    // Tier 0 lowers the pixel code once: one select fewer. Tier 1 has a copy per group of
    // the unrolled loop and per block variant: one fewer in each.
    assert_eq!(counts[0].2 + 1, counts[2].2, "{counts:?}");
    assert!(counts[1].2 < counts[3].2, "{counts:?}");
}
