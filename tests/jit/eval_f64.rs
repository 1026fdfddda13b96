//! The IR evaluator's f64 precision (`Precision::F64`), the reference the f32 kernels'
//! shading is measured against: float arithmetic, built-ins, derivatives and primitive
//! calls in f64 (each test checks a value f32 cannot give), G-buffer stores rounded to f32,
//! fixed point and ints as in f32; and `Precision::F32` is `Evaluator::new`, the JIT's
//! oracle, exactly.

use std::sync::Arc;

use crate::support::jit::{fw, kind_key, H, W};

use primflow::abi::{ArgLayout, ParamSlot, VariantKey};
use primflow::diag::{Diagnostics, SourceMap};
use primflow::ir::eval::{Budget, Evaluator, Outcome, Precision, Tile};
use primflow::ir::Program;

const SOURCE: &str = r#"
primitive f64_sums(float big, tenth; int n; varying float X, Y; inout varying float Z)
{
    float s = 0;
    for (int i = 0; i < n; i++)
        s += tenth;
    Z = 0.5;
    interpolation {
        linear:
            interpolator_return({(big + 1) - big, s});
    }
}

primitive f64_builtins(float two, t, e, b, y; float r_sqrt, r_sin, r_exp, r_pow, r_powi, r_norm;
                       varying float X, Y; inout varying float Z)
{
    vector n = normalize(vector(two, t, e));
    Z = 0.5;
    interpolation {
        linear:
            interpolator_return({sqrt(two), sin(t), exp(e), pow(b, y), pow(b, 7), n.x,
                                 sqrt(two) - r_sqrt, sin(t) - r_sin, exp(e) - r_exp,
                                 pow(b, y) - r_pow, pow(b, 7) - r_powi, n.x - r_norm});
    }
}

primitive f64_fixed(int k; varying fixed<32,8> X, Y; inout varying fixed<32,32> Z)
{
    fixed<16,8> a = X * 0.375 + k;
    fixed<12,4> b = a / 3 - Y;
    int i = int(b) * 7 % 5;
    if (i == 2)
        return;
    Z = (b % 1) / 2;
    interpolation {
        linear:
            interpolator_return({float(a), float(b), float(i)});
    }
}

primitive f64_callee(float a, b; varying float X, Y; inout varying float Z)
{
    Z = 0.5;
    interpolation {
        linear:
            interpolator_return(a - b);
    }
}

primitive f64_caller(float big; varying float X, Y; inout varying float Z)
{
    f64_callee(big + 1, big, X, Y, Z);
}
"#;

/// A surface taking derivatives of the affine fields 3 s + 5 t + 0.25 and 3 s + `offset`.
const DERIVATIVES: &str = "surface f64_derivatives(float offset = 0) {
    float u = 3 * s + 5 * t + 0.25;
    float v = 3 * s + offset;
    Ci = color(Dx(u), filterwidth(u), Dx(v));
}";

fn program() -> Arc<Program> {
    let mut sources = SourceMap::new();
    let file = sources.add("eval_f64.prim", SOURCE);
    let mut diags = Diagnostics::new();
    match primflow::compile(&sources, &[file], &mut diags) {
        Some(p) if !diags.has_errors() => Arc::new(p),
        _ => panic!("does not compile:\n{}", diags.render(&sources)),
    }
}

/// A key of one `linear` binding of `planes` components.
fn key(planes: u32) -> VariantKey {
    kind_key(&[("linear", planes)])
}

/// [`DERIVATIVES`] linked as the `__shade` primitive of a frame shading on quads: `s` and
/// `t` in planes 0 and 1, `Ci` into planes 2 to 4, the pixel centres in planes 5 and 6.
fn shade_program() -> Arc<Program> {
    let (_, library) = crate::support::library_and_sources();
    Arc::new(crate::support::link_quad_surface(&library, DERIVATIVES))
}

/// `name`'s argument block under `key`: `words` fill its per-primitive parameters in
/// order, the plane table maps component g to plane `first_plane + g`.
fn args(program: &Program, name: &str, key: &VariantKey, first_plane: u32, words: &[u32]) -> Vec<u32> {
    let func = program.find(name).expect("primitive");
    let layout = ArgLayout::new(program, func, key);
    let mut args = vec![0u32; layout.words(1)];
    args[0] = 1;
    for g in 0..key.total_components() {
        args[(layout.plane_table + g) as usize] = first_plane + g;
    }
    let mut next = words.iter();
    for slot in &layout.params {
        if let ParamSlot::Fixed { offset, words } = slot {
            for w in 0..*words {
                args[(offset + w) as usize] = *next.next().expect("a word for every parameter word");
            }
        }
    }
    assert!(next.next().is_none(), "more words than `{name}` has parameter words");
    args
}

/// `name` run by `evaluator` on a W x H tile of `planes` planes at the origin.
fn run_with(evaluator: &Evaluator, program: &Program, name: &str, planes: u32, words: &[u32]) -> (Outcome, Tile) {
    let key = key(planes);
    let args = args(program, name, &key, 0, words);
    let func = program.find(name).expect("primitive");
    let mut tile = Tile::new(0, 0, W, H, planes as usize, 64, 32);
    let out = evaluator
        .run(func, &key, &args, &mut tile, Budget::default())
        .unwrap_or_else(|e| panic!("{name}: {e}"));
    (out, tile)
}

/// `name` run in `precision`.
fn run(program: &Program, name: &str, planes: u32, words: &[u32], precision: Precision) -> (Outcome, Tile) {
    run_with(
        &Evaluator::with_precision(program, true, precision),
        program,
        name,
        planes,
        words,
    )
}

/// Plane `k` of `tile`, every pixel.
fn plane(tile: &Tile, k: usize) -> &[f32] {
    &tile.planes[k * tile.plane_stride..(k + 1) * tile.plane_stride]
}

/// Every pixel of plane `k` is `want`, bit for bit.
fn assert_plane(tile: &Tile, k: usize, want: f32, what: &str) {
    for (i, v) in plane(tile, k).iter().enumerate() {
        assert_eq!(
            v.to_bits(),
            want.to_bits(),
            "{what}: plane {k} pixel {i}: {v} not {want}"
        );
    }
}

#[test]
fn f64_keeps_what_f32_rounds_away() {
    let program = program();
    let n = 10_000;
    let words = [fw(1e8), fw(0.1), n as u32];
    // The loop's additions: of the constant's f32, in f64 or in f32.
    let (mut sum64, mut sum32) = (0f64, 0f32);
    for _ in 0..n {
        sum64 += f64::from(0.1f32);
        sum32 += 0.1f32;
    }
    let (_, t64) = run(&program, "f64_sums", 2, &words, Precision::F64);
    let (_, t32) = run(&program, "f64_sums", 2, &words, Precision::F32);
    assert_plane(&t64, 0, 1.0, "F64 (1e8 + 1) - 1e8");
    assert_plane(&t32, 0, 0.0, "F32 (1e8 + 1) - 1e8");
    // The f64 sum, rounded to f32 at the store (the planes are f32).
    assert_plane(&t64, 1, sum64 as f32, "F64 sum");
    assert_plane(&t32, 1, sum32, "F32 sum");
    assert!((sum32 - sum64 as f32).abs() > 0.05, "the f32 sum drifts: {sum32}");
    // Z = 0.5 is drawn at every pixel in both.
    let half = crate::support::raw_depth(0.5);
    assert!(t64.depth.iter().chain(&t32.depth).all(|&z| z == half));
}

#[test]
fn f64_builtins_are_the_f64_functions_rounded_once_at_the_store() {
    let program = program();
    let (two, t, e, b, y) = (2f32, 0.7f32, 1.3f32, 1.7f32, 2.5f32);
    // The f32 results the JIT computes (`pow` by repeated squaring for an integer exponent).
    let norm32 = two / (two * two + t * t + e * e).sqrt();
    let f32s = [
        two.sqrt(),
        t.sin(),
        e.exp(),
        b.powf(y),
        primflow::jit::libm::pow_int(b, 7.0),
        norm32,
    ];
    let (two_d, t_d, e_d, b_d, y_d) = (f64::from(two), f64::from(t), f64::from(e), f64::from(b), f64::from(y));
    let f64s = [
        two_d.sqrt(),
        t_d.sin(),
        e_d.exp(),
        b_d.powf(y_d),
        b_d.powf(7.0),
        two_d / (two_d * two_d + t_d * t_d + e_d * e_d).sqrt(),
    ];
    let mut words = vec![fw(two), fw(t), fw(e), fw(b), fw(y)];
    words.extend(f32s.iter().map(|&x| fw(x)));
    let (_, t64) = run(&program, "f64_builtins", 12, &words, Precision::F64);
    let (_, t32) = run(&program, "f64_builtins", 12, &words, Precision::F32);
    let names = ["sqrt", "sin", "exp", "pow", "pow by 7", "normalize"];
    for (k, name) in names.iter().enumerate() {
        assert_plane(&t64, k, f64s[k] as f32, &format!("F64 {name}"));
        assert_plane(&t32, k, f32s[k], &format!("F32 {name}"));
        // The f64 value less the f32 one: what f64 keeps below f32's last bit.
        let residual = (f64s[k] - f64::from(f32s[k])) as f32;
        assert!(residual != 0.0, "{name}: f64 and f32 agree, the test shows nothing");
        assert_plane(&t64, 6 + k, residual, &format!("F64 {name} - its f32"));
        assert_plane(&t32, 6 + k, 0.0, &format!("F32 {name} - its f32"));
    }
}

/// The linked `__shade` of [`shade_program`] run by `evaluator` on a W x H tile laid out
/// as quads: each group of 4 pixels is the quad at (x, y) = (2 g + 0.5, 0.5) for its group
/// number g, lanes 0, 1 its upper row (t = y), lanes 2, 3 its lower row (t = y + 1), and
/// s = x, x + 1 along each row.
fn run_shade(evaluator: &Evaluator, program: &Program, offset: f32) -> Tile {
    use primflow::link;
    let func = program.find(link::SHADE).expect("__shade");
    let key = kind_key(&[(link::OUT_KIND, 3)]);
    // `offset`, then `__lighting_from_device` (the identity), `__eye`, `__near`.
    let mut words = vec![fw(offset)];
    words.extend((0..16).map(|i| fw(if i % 5 == 0 { 1.0 } else { 0.0 })));
    words.extend([0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0].map(fw));
    let args = args(program, link::SHADE, &key, 2, &words);
    let mut tile = Tile::new(0, 0, W, H, 7, 64, 32);
    tile.depth.fill(crate::support::raw_depth(0.5));
    for i in 0..W * H {
        let (g, lane) = (i / 4, i % 4);
        let (x, y) = (2.0 * g as f32 + 0.5, 0.5);
        let (qx, qy) = (x + (lane % 2) as f32, y + (lane / 2) as f32);
        for (k, v) in [(0, qx), (1, qy), (5, qx), (6, qy)] {
            tile.planes[k * tile.plane_stride + i] = v;
        }
    }
    evaluator
        .run(func, &key, &args, &mut tile, Budget::default())
        .expect("runs");
    tile
}

#[test]
fn f64_derivatives_of_an_affine_field_are_exact() {
    let program = shade_program();
    let t64 = run_shade(
        &Evaluator::with_precision(&program, true, Precision::F64),
        &program,
        1e7,
    );
    let t32 = run_shade(
        &Evaluator::with_precision(&program, true, Precision::F32),
        &program,
        1e7,
    );
    // Across 3 s + 5 t + 0.25, Dx is 3 and Dy 5 in every lane, in both precisions.
    for (t, what) in [(&t64, "F64"), (&t32, "F32")] {
        assert_plane(t, 2, 3.0, &format!("{what} Dx(3 s + 5 t + 0.25)"));
        assert_plane(t, 3, 34f32.sqrt(), &format!("{what} filterwidth(3 s + 5 t + 0.25)"));
    }
    // Next to 1e7, f32 spaces values 1 apart: 3 s + 1e7 rounds, its differences are not 3.
    assert_plane(&t64, 4, 3.0, "F64 Dx(3 s + 1e7)");
    assert!(
        plane(&t32, 4).iter().any(|&d| d != 3.0),
        "F32 Dx(3 s + 1e7): {:?}",
        plane(&t32, 4)
    );
}

#[test]
fn fixed_point_and_ints_compute_alike_in_both_precisions() {
    let program = program();
    let (out64, t64) = run(&program, "f64_fixed", 3, &[5], Precision::F64);
    let (out32, t32) = run(&program, "f64_fixed", 3, &[5], Precision::F32);
    assert_eq!(out64, out32);
    assert_eq!(t64.depth, t32.depth);
    assert_eq!(t64.writes, t32.writes);
    assert_eq!(t64.planes, t32.planes);
    // It drew some pixels and returned early at others, with values of every kind.
    let drawn = t32.writes.iter().filter(|&&n| n == 1).count();
    assert!(drawn > 10 && drawn < W * H, "{drawn} pixels drawn");
    assert!(t32.depth.iter().any(|&z| z != 0));
    for k in 0..3 {
        assert!(plane(&t32, k).iter().any(|&v| v != 0.0), "plane {k} all 0");
    }
    // Pixel (3, 2): X = 3.5, Y = 2.5 exactly; a = 1.3125 + 5; b = a / 3 - Y rounded to
    // fixed<12,4>: 6.3125 / 3 = 2.104 -> 33/16 = 2.0625 (truncated), less 2.5.
    let i = 2 * t32.stride + 3;
    assert_eq!(plane(&t32, 0)[i], 6.3125);
    assert_eq!(plane(&t32, 1)[i], 2.0625 - 2.5);
}

#[test]
fn a_primitive_call_passes_f64_arguments_exactly() {
    let program = program();
    let (_, t64) = run(&program, "f64_caller", 1, &[fw(1e8)], Precision::F64);
    let (_, t32) = run(&program, "f64_caller", 1, &[fw(1e8)], Precision::F32);
    assert_plane(&t64, 0, 1.0, "F64 (1e8 + 1) through a call, less 1e8");
    assert_plane(&t32, 0, 0.0, "F32 (1e8 + 1) through a call, less 1e8");
}

#[test]
fn f32_precision_is_the_evaluator_new_gives() {
    let program = program();
    let cases: [(&str, u32, Vec<u32>); 4] = [
        ("f64_sums", 2, vec![fw(1e8), fw(0.1), 1000]),
        (
            "f64_builtins",
            12,
            [2.0, 0.7, 1.3, 1.7, 2.5, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6].map(fw).to_vec(),
        ),
        ("f64_fixed", 3, vec![5]),
        ("f64_caller", 1, vec![fw(1e8)]),
    ];
    assert_eq!(Precision::default(), Precision::F32);
    for unroll in [false, true] {
        let new = Evaluator::new(&program, unroll);
        let f32 = Evaluator::with_precision(&program, unroll, Precision::F32);
        assert_eq!(new.precision(), Precision::F32);
        for (name, planes, words) in &cases {
            let (out_new, t_new) = run_with(&new, &program, name, *planes, words);
            let (out_f32, t_f32) = run_with(&f32, &program, name, *planes, words);
            assert_eq!(out_new, out_f32, "{name}");
            assert_eq!(t_new.depth, t_f32.depth, "{name}");
            assert_eq!(t_new.writes, t_f32.writes, "{name}");
            assert_eq!(bits(&t_new), bits(&t_f32), "{name}");
        }
    }
    let shade = shade_program();
    let (new, f32) = (
        Evaluator::new(&shade, true),
        Evaluator::with_precision(&shade, true, Precision::F32),
    );
    let (t_new, t_f32) = (run_shade(&new, &shade, 1e7), run_shade(&f32, &shade, 1e7));
    assert_eq!(bits(&t_new), bits(&t_f32), "__shade");
}

/// Every plane value's bits.
fn bits(t: &Tile) -> Vec<u32> {
    t.planes.iter().map(|v| v.to_bits()).collect()
}
