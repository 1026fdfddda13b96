//! Tier 0 splits the large setup of a kernel without pixel loops into two functions
//! (src/jit/lower/outline.rs): the kernel runs the first half and calls the second with
//! the SSA variables both halves use stored in the slot table. What crosses that call must
//! be what one function would have: every carried value (ints, floats, bools, the
//! components of a register array, the X, Y, Z handed to primitive calls), the run-time
//! errors of either half (each counted; the kernel's deferred first error is flushed
//! before the call), the fuel, a `return` in the second half and the primitives it calls. Tier 1
//! keeps one function; each case renders both tiers and compares with the value computed
//! here and drawn by `flat`.

use crate::support;

use std::sync::Arc;

use primflow::abi::VariantKey;
use primflow::diag::SourceMap;
use primflow::ir::Program;
use primflow::jit::{Jit, Tier};
use support::{rect_depth_and_codes, rect_scene};

/// Rounds of `churn` in each half: enough to put the setup over the split size.
const ROUNDS: usize = 40;

/// The test primitives. `split_setup`'s first half calls `flat` (so X, Y and Z are used on
/// both sides), then reads `a[i]` (an error there is still deferred at the split) and sets
/// the locals the second half reads; the second
/// half reads `a[j]`, counts `n` trips, returns when `stop` is set, and calls `flat` with
/// a depth made of all of it.
fn source() -> String {
    let half = |v: &str| format!("    {v} = churn({v});\n").repeat(ROUNDS);
    format!(
        r#"
float churn(float x)
{{
    float s = x;
    s = s * 0.5 + 0.0625;
    s = s * 0.75 + 0.03125;
    s = s * 0.5 + 0.0625;
    s = s * 0.75 + 0.03125;
    return s;
}}

primitive flat(float rect[4]; float z; varying float X, Y; inout varying fixed<32,32> Z)
{{
    bound(rect[0], rect[1], rect[2], rect[3]);
    Z = z;
}}

primitive split_setup(float rect[4]; int i, j, n, stop; varying float X, Y; inout varying fixed<32,32> Z)
{{
    float a[4] = {{0.015625, 0.03125, 0.046875, 0.0625}};
    flat(rect, 0.96875, X, Y, Z);
    float first = a[i];
    int count = 3;
    bool odd = i % 2 != 0;
    float v[3] = {{first, 0.5, 0.25}};
    float s = first;
{first_half}    float t = s;
{second_half}    float second = a[j];
    int trips = 0;
    for (int k = 0; k < n; k++)
        trips += 1;
    if (stop != 0)
        return;
    flat(rect, t + second + (odd ? v[1] : v[2]) + v[0] + count / 64.0 + trips / 1073741824.0, X, Y, Z);
}}
"#,
        first_half = half("s"),
        second_half = half("t"),
    )
}

const A: [f32; 4] = [0.015625, 0.03125, 0.046875, 0.0625];

/// `a[i]` as the language reads it: the index clamped into the array.
fn a(i: i64) -> f32 {
    A[i.clamp(0, 3) as usize]
}

/// `churn` in f32, operation by operation.
fn churn(x: f32) -> f32 {
    let mut s = x;
    s = s * 0.5 + 0.0625;
    s = s * 0.75 + 0.03125;
    s = s * 0.5 + 0.0625;
    s = s * 0.75 + 0.03125;
    s
}

/// The depth `split_setup` draws last: the second `flat`'s argument.
fn expected_z(i: i64, j: i64, trips: f32) -> f32 {
    let first = a(i);
    let mut s = first;
    for _ in 0..ROUNDS {
        s = churn(s);
    }
    let mut t = s;
    for _ in 0..ROUNDS {
        t = churn(t);
    }
    let picked = if i % 2 != 0 { 0.5 } else { 0.25 };
    t + a(j) + picked + first + 3.0 / 64.0 + trips / 1073741824.0
}

/// `W0801@line:col` of the first occurrence of `text` in the source, at `index` in it.
fn site(source: &str, text: &str, index: &str) -> String {
    let (n, line) = source
        .lines()
        .enumerate()
        .find(|(_, l)| l.contains(text))
        .expect("line");
    let col = line.find(text).expect("text") + text.find(index).expect("index") + 1;
    format!("W0801@{}:{}", n + 1, col)
}

fn library(sources: &mut SourceMap, source: &str) -> Arc<Program> {
    support::library_with(sources, &[("split.prim", source)])
}

/// Functions in `prim`'s printed CLIF at `tier`.
fn functions(program: &Arc<Program>, prim: &str, tier: Tier) -> usize {
    let jit = Jit::at_tier(program.clone(), tier).unwrap();
    let func = program.find(prim).expect("primitive");
    let clif = jit.clif(func, &VariantKey::default()).unwrap();
    clif.lines().filter(|l| l.starts_with("function ")).count()
}

#[test]
fn tier_0_splits_a_large_setup_and_only_that() {
    let source = source();
    let mut sources = SourceMap::new();
    let program = library(&mut sources, &source);
    assert_eq!(functions(&program, "split_setup", Tier::Fast), 2);
    assert_eq!(functions(&program, "split_setup", Tier::Optimised), 1);
    // Small setups stay one function; so do kernels with pixel loops, whose loops are the
    // second function.
    assert_eq!(functions(&program, "polygon", Tier::Fast), 1);
    assert_eq!(functions(&program, "flat", Tier::Fast), 2);
}

#[test]
fn both_halves_compute_what_one_function_would() {
    let source = source();
    let mut sources = SourceMap::new();
    let program = library(&mut sources, &source);
    let in_first = site(&source, "float first = a[i];", "i]");
    let in_second = site(&source, "float second = a[j];", "j]");
    let fuel = site(&source, "for (int k = 0; k < n; k++)", "for");
    // (i, j, n, stop): every error alone and in pairs, the second half ending early, and
    // both parities of `i` (the carried bool).
    let cases = [
        (1, 2, 5, 0),
        (2, 3, 0, 0),
        (6, 1, 7, 0),
        (3, -2, 7, 0),
        (-1, 9, 2, 0),
        (0, 1, 3, 1),
        (7, 1, 3, 1),
        (2, 1, 300_000_000, 0),
        (9, 1, 300_000_000, 0),
    ];
    for (i, j, n, stop) in cases {
        let bad_i = !(0..4).contains(&i);
        let bad_j = !(0..4).contains(&j) && stop == 0;
        // 3e8 trips > 2^28 (the default fuel): the loop runs out.
        let out_of_fuel = n > 100_000_000 && stop == 0;
        // Every failing site, in source order.
        let want_errors: Vec<String> = [(bad_i, &in_first), (bad_j, &in_second), (out_of_fuel, &fuel)]
            .into_iter()
            .filter(|(bad, _)| *bad)
            .map(|(_, site)| site.clone())
            .collect();
        let params = [("i", i as f32), ("j", j as f32), ("n", n as f32), ("stop", stop as f32)];
        let mut r = rect_scene(&program, "split_setup", &params);
        r.options.expand_calls = false;
        let runs: Vec<(u32, Vec<String>)> = [Tier::Fast, Tier::Optimised]
            .into_iter()
            .map(|tier| rect_depth_and_codes(&program, &sources, &r, tier))
            .collect();
        let case = format!("i={i} j={j} n={n} stop={stop}");
        assert_eq!(runs[0], runs[1], "{case}: the tiers differ");
        assert_eq!(runs[0].1, want_errors, "{case}: errors");
        if out_of_fuel {
            // A draw whose setup runs out of fuel is drawn nowhere.
            assert_eq!(runs[0].0, 0, "{case}: depth");
            continue;
        }
        let z = if stop != 0 { 0.96875 } else { expected_z(i, j, n as f32) };
        let reference = rect_scene(&program, "flat", &[("z", z)]);
        let (want, _) = rect_depth_and_codes(&program, &sources, &reference, Tier::Optimised);
        assert_eq!(runs[0].0, want, "{case}: depth");
    }
}
