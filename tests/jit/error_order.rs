//! Which run-time errors a kernel invocation records: every failing site is counted (the
//! frame's W0801 warnings list each, in site order), and `TileCtx::error` holds the first
//! one it meets, by execution order, across error kinds and across primitive calls. In
//! tier 0, setup index and fuel errors are not written to `TileCtx::error` where they
//! happen: the kernel keeps the first one in a variable and flushes it at the setup's exits
//! and end and before primitive calls (`Lower::defer_error`, `Lower::flush_errors`), and
//! counts each where it happens; tier 1 records and counts them from cold blocks. Both tiers
//! must report the same sites (W0801 at their line:col), record the same first error and
//! draw the same depth: each out-of-range index reads the nearest end of its array.
//!
//! - Two failing sites: both are reported; the one that fails first at run time is the
//!   first error, also when it is the later one in the source (a loop whose second read
//!   leaves the array first).
//! - An index error and a loop running out of fuel, in both orders (running out of setup
//!   fuel ends the run: an index after the loop is not met).
//! - One index read several times in a row (tier 0 checks it once per block and counts
//!   the reads after the first from that check): every read is reported, a guarded one (an
//!   arm of `?:`) only when its arm is taken.
//! - An index error before a primitive call whose callee records its own, and the reverse:
//!   the call runs with the caller's context (calls are not expanded here), so whichever
//!   error came first is the invocation's first error; both are reported.

use crate::support;
use crate::support::jit::Tile;

use std::sync::Arc;

use primflow::abi::{DEFAULT_FUEL, ERR_NONE, MODE_RENDER};
use primflow::diag::SourceMap;
use primflow::ir::Program;
use primflow::jit::{Jit, Tier};
use primflow::runtime::Renderer;
use support::{rect_depth_and_codes, rect_scene};

const SOURCE: &str = r#"
primitive two_sites(float rect[4]; int i, j; varying float X, Y; inout varying fixed<32,32> Z)
{
    bound(rect[0], rect[1], rect[2], rect[3]);
    float a[4] = {0.015625, 0.03125, 0.046875, 0.0625};
    float s = a[i];
    s = s + a[j];
    Z = s;
}

primitive loop_order(float rect[4]; int n, k; varying float X, Y; inout varying fixed<32,32> Z)
{
    bound(rect[0], rect[1], rect[2], rect[3]);
    float a[4] = {0.015625, 0.03125, 0.046875, 0.0625};
    float s = 0;
    for (int t = 0; t < n; t++) {
        s = s + a[t];
        s = s + a[k - t];
    }
    Z = s;
}

primitive index_then_fuel(float rect[4]; int i, n; varying float X, Y; inout varying fixed<32,32> Z)
{
    bound(rect[0], rect[1], rect[2], rect[3]);
    float a[4] = {0.015625, 0.03125, 0.046875, 0.0625};
    float s = a[i];
    int trips = 0;
    for (int t = 0; t < n; t++)
        trips += 1;
    Z = s + trips / 1073741824.0;
}

primitive fuel_then_index(float rect[4]; int i, n; varying float X, Y; inout varying fixed<32,32> Z)
{
    bound(rect[0], rect[1], rect[2], rect[3]);
    float a[4] = {0.015625, 0.03125, 0.046875, 0.0625};
    int trips = 0;
    for (int t = 0; t < n; t++)
        trips += 1;
    float s = a[i];
    Z = s + trips / 1073741824.0;
}

primitive callee(float rect[4]; int j; varying float X, Y; inout varying fixed<32,32> Z)
{
    bound(rect[0], rect[1], rect[2], rect[3]);
    float b[2] = {0.25, 0.5};
    float s = b[j];
    Z = s;
}

primitive index_then_call(float rect[4]; int i, j; varying float X, Y; inout varying fixed<32,32> Z)
{
    bound(rect[0], rect[1], rect[2], rect[3]);
    float a[4] = {0.015625, 0.03125, 0.046875, 0.0625};
    float s = a[i];
    callee(rect, j, X, Y, Z);
    Z = s;
}

primitive call_then_index(float rect[4]; int i, j; varying float X, Y; inout varying fixed<32,32> Z)
{
    bound(rect[0], rect[1], rect[2], rect[3]);
    float a[4] = {0.015625, 0.03125, 0.046875, 0.0625};
    callee(rect, j, X, Y, Z);
    float s = a[i + 0];
    Z = s;
}

primitive repeated_index(float rect[4]; int i, c; varying float X, Y; inout varying fixed<32,32> Z)
{
    bound(rect[0], rect[1], rect[2], rect[3]);
    float a[4] = {0.015625, 0.03125, 0.046875, 0.0625};
    float b[4] = {0.125, 0.25, 0.375, 0.5};
    float s = c != 0 ? a[i] : 0;
    s = s + a[i];
    s = s + b[i];
    s = s + a[i];
    Z = s;
}

primitive flat(float rect[4]; float z; varying float X, Y; inout varying fixed<32,32> Z)
{
    bound(rect[0], rect[1], rect[2], rect[3]);
    Z = z;
}
"#;

/// The elements of `a` (exact in f32 and in Z's fixed point).
const A: [f32; 4] = [0.015625, 0.03125, 0.046875, 0.0625];

/// `a[i]` as the language reads it: the index clamped into the array.
fn a(i: i64) -> f32 {
    A[i.clamp(0, 3) as usize]
}

/// `W0801@line:col` of the index `index` on the line of `primitive`'s body that contains
/// `line_text` (the first such line after the primitive's header).
fn site(primitive: &str, line_text: &str, index: &str) -> String {
    nth_site(primitive, line_text, index, 0)
}

/// As [`site`], on the `nth` (from 0) such line.
fn nth_site(primitive: &str, line_text: &str, index: &str, nth: usize) -> String {
    let header = format!("primitive {primitive}(");
    let lines: Vec<&str> = SOURCE.lines().collect();
    let start = lines.iter().position(|l| l.starts_with(&header)).expect("primitive");
    let (n, line) = lines
        .iter()
        .enumerate()
        .skip(start)
        .filter(|(_, l)| l.contains(line_text))
        .nth(nth)
        .expect("line");
    let col = line.find(line_text).expect("text") + line_text.find(index).expect("index") + 1;
    format!("W0801@{}:{}", n + 1, col)
}

/// `sites` in source order (the order of their `SiteId`s, the report's).
fn in_order(mut sites: Vec<String>) -> Vec<String> {
    let key = |s: &String| -> (u32, u32) {
        let (l, c) = s["W0801@".len()..].split_once(':').unwrap();
        (l.parse().unwrap(), c.parse().unwrap())
    };
    sites.sort_by_key(key);
    sites.dedup();
    sites
}

/// The first error of one render-mode run of `r`'s instance at `tier`
/// (`TileCtx::error_site`, as `W0801@line:col`).
fn first_error(program: &Arc<Program>, sources: &SourceMap, r: &Renderer, tier: Tier) -> Option<String> {
    let inst = &r.instances()[0];
    let mut jit = Jit::at_tier(program.clone(), tier).unwrap();
    let k = jit.kernel(inst.func, &inst.key).unwrap();
    let mut tile = Tile::new(0);
    let ctx = tile.run(&k, &inst.args, MODE_RENDER, DEFAULT_FUEL);
    (ctx.error != ERR_NONE).then(|| {
        let span = program.sites[ctx.error_site as usize];
        let (l, c) = sources.line_col(span.file, span.start);
        format!("W0801@{l}:{c}")
    })
}

fn library(sources: &mut SourceMap) -> Arc<Program> {
    support::library_with(sources, &[("order.prim", SOURCE)])
}

/// Renders `prim` with `params` at both tiers (calls made directly, not expanded): the
/// depth inside the rectangle, which must equal `flat` drawing `want_z`; the reported
/// errors, which must be `want_errors` (in source order); and the first error of a run,
/// which must be `want_first`.
fn check(prim: &str, params: &[(&str, f32)], want_z: f32, want_errors: &[String], want_first: Option<&String>) {
    let mut sources = SourceMap::new();
    let program = library(&mut sources);
    let mut r = rect_scene(&program, prim, params);
    r.options.expand_calls = false;
    let reference = rect_scene(&program, "flat", &[("z", want_z)]);
    for tier in [Tier::Fast, Tier::Optimised] {
        let case = format!("{prim} {params:?} {tier:?}");
        let (want, none) = rect_depth_and_codes(&program, &sources, &reference, tier);
        assert!(none.is_empty(), "{case}: {none:?}");
        let (got, errors) = rect_depth_and_codes(&program, &sources, &r, tier);
        assert_eq!(got, want, "{case}: depth");
        assert_eq!(errors, in_order(want_errors.to_vec()), "{case}: errors");
        assert_eq!(
            first_error(&program, &sources, &r, tier).as_ref(),
            want_first,
            "{case}: first error"
        );
    }
}

#[test]
fn two_failing_index_sites_are_both_reported_and_the_first_to_fail_is_the_first_error() {
    let first = site("two_sites", "float s = a[i];", "i]");
    let second = site("two_sites", "s = s + a[j];", "j]");
    for (i, j) in [(1, 2), (7, 2), (1, -3), (-1, 9), (4, 4)] {
        let mut errors = vec![];
        if !(0..4).contains(&i) {
            errors.push(first.clone());
        }
        if !(0..4).contains(&j) {
            errors.push(second.clone());
        }
        let params = [("i", i as f32), ("j", j as f32)];
        check("two_sites", &params, a(i) + a(j), &errors, errors.first());
    }
}

#[test]
fn an_index_read_again_reports_every_read_and_first_the_first_that_can_fail() {
    let guarded = site("repeated_index", "float s = c != 0 ? a[i] : 0;", "i]");
    let unguarded = nth_site("repeated_index", "s = s + a[i];", "i]", 0);
    let other_array = site("repeated_index", "s = s + b[i];", "i]");
    let again = nth_site("repeated_index", "s = s + a[i];", "i]", 1);
    let b = |i: i64| [0.125f32, 0.25, 0.375, 0.5][i.clamp(0, 3) as usize];
    for (i, c) in [(2, 1), (2, 0), (6, 1), (6, 0), (-1, 0), (-1, 1)] {
        let mut errors = vec![];
        if !(0..4).contains(&i) {
            // The arm is not taken: its read is no error.
            if c != 0 {
                errors.push(guarded.clone());
            }
            errors.extend([unguarded.clone(), other_array.clone(), again.clone()]);
        }
        let first = if c != 0 { a(i) } else { 0.0 };
        let z = first + a(i) + b(i) + a(i);
        check(
            "repeated_index",
            &[("i", i as f32), ("c", c as f32)],
            z,
            &errors,
            errors.first(),
        );
    }
}

#[test]
fn in_a_loop_the_site_that_fails_first_at_run_time_is_the_first_error_over_source_order() {
    let by_counter = site("loop_order", "s = s + a[t];", "t]");
    let by_window = site("loop_order", "s = s + a[k - t];", "k - t");
    // (n, k) -> the first trip t whose `a[t]` (t >= 4) or `a[k - t]` (k - t outside 0..4)
    // leaves the array; `a[t]` is read first within a trip. (6, 3): `a[t]` fails first, at
    // t = 4, though both fail then and after; (6, 1): `a[k - t]` fails first, at t = 2,
    // though `a[t]` fails from t = 4 on; (4, 3), (3, 2): neither.
    let mut firsts = vec![];
    for (n, k) in [(4, 3), (6, 3), (6, 1), (6, 9), (3, 2), (9, 5)] {
        let mut s = 0f32;
        let mut first_error = None;
        let mut errors = vec![];
        for t in 0..n {
            if t >= 4 {
                first_error.get_or_insert(by_counter.clone());
                errors.push(by_counter.clone());
            }
            s += a(t);
            if !(0..4).contains(&(k - t)) {
                first_error.get_or_insert(by_window.clone());
                errors.push(by_window.clone());
            }
            s += a(k - t);
        }
        check(
            "loop_order",
            &[("n", n as f32), ("k", k as f32)],
            s,
            &errors,
            first_error.as_ref(),
        );
        firsts.extend(first_error);
    }
    // Both sites are the first error in some case.
    assert!(
        firsts.contains(&by_counter) && firsts.contains(&by_window),
        "{firsts:?}"
    );
}

#[test]
fn an_index_error_and_running_out_of_fuel_report_what_the_run_met_the_first_first() {
    let index_first = site("index_then_fuel", "float s = a[i];", "i]");
    let fuel_first = site("fuel_then_index", "for (int t = 0; t < n; t++)", "for");
    let index_after_fuel = site("fuel_then_index", "float s = a[i];", "i]");
    let fuel_after_index = site("index_then_fuel", "for (int t = 0; t < n; t++)", "for");
    // 3e8 > 2^28 trips (the default fuel) runs out; 1000 does not.
    let trips = |n: f32| if n > 1e6 { None } else { Some(n) };
    for (i, n) in [(9, 3e8f32), (2, 3e8), (-2, 1000.0), (1, 1000.0)] {
        let bad = !(0..4).contains(&i);
        let done = trips(n);
        for (prim, first, second) in [
            ("index_then_fuel", &index_first, &fuel_after_index),
            ("fuel_then_index", &fuel_first, &index_after_fuel),
        ] {
            let (index_site, fuel_site) = if prim == "index_then_fuel" {
                (first, second)
            } else {
                (second, first)
            };
            // Running out of setup fuel ends the run: an index after the loop is not met.
            let index_met = bad && (prim == "index_then_fuel" || done.is_some());
            let mut errors = vec![];
            if index_met {
                errors.push(index_site.clone());
            }
            if done.is_none() {
                errors.push(fuel_site.clone());
            }
            // Both fail: the one met first is the first error.
            let want_first = if bad && done.is_none() {
                Some(first)
            } else {
                errors.first()
            };
            match done {
                Some(trips) => check(
                    prim,
                    &[("i", i as f32), ("n", n)],
                    a(i) + trips / 1073741824.0,
                    &errors,
                    want_first,
                ),
                None => {
                    // A draw whose setup runs out of fuel is drawn nowhere (the depth stays
                    // cleared).
                    let mut sources = SourceMap::new();
                    let program = library(&mut sources);
                    let r = rect_scene(&program, prim, &[("i", i as f32), ("n", n)]);
                    for tier in [Tier::Fast, Tier::Optimised] {
                        let (depth, codes) = rect_depth_and_codes(&program, &sources, &r, tier);
                        assert_eq!(depth, 0, "{prim} i={i} {tier:?}: drawn");
                        assert_eq!(codes, in_order(errors.clone()), "{prim} i={i} n={n} {tier:?}");
                        assert_eq!(
                            first_error(&program, &sources, &r, tier).as_ref(),
                            want_first,
                            "{prim} i={i} {tier:?}: first error"
                        );
                    }
                }
            }
        }
    }
}

#[test]
fn across_a_primitive_call_both_errors_are_reported_and_the_first_wins() {
    let caller_first = site("index_then_call", "float s = a[i];", "i]");
    let caller_after = site("call_then_index", "float s = a[i + 0];", "i + 0");
    let in_callee = site("callee", "float s = b[j];", "j]");
    for (i, j) in [(1, 1), (5, 1), (1, 2), (5, -1), (-3, 7)] {
        let caller_bad = !(0..4).contains(&i);
        let callee_bad = !(0..2).contains(&j);
        // The caller's pixel part runs after its setup (and the call): its Z is the last
        // written.
        let z = a(i);
        let errors = |caller_site: &String| -> Vec<String> {
            let mut e = vec![];
            if caller_bad {
                e.push(caller_site.clone());
            }
            if callee_bad {
                e.push(in_callee.clone());
            }
            e
        };
        let first = |caller_site: &String, caller_first: bool| -> Option<String> {
            match (caller_bad, callee_bad) {
                (false, false) => None,
                (true, false) => Some(caller_site.clone()),
                (false, true) => Some(in_callee.clone()),
                (true, true) if caller_first => Some(caller_site.clone()),
                (true, true) => Some(in_callee.clone()),
            }
        };
        let params = [("i", i as f32), ("j", j as f32)];
        check(
            "index_then_call",
            &params,
            z,
            &errors(&caller_first),
            first(&caller_first, true).as_ref(),
        );
        check(
            "call_then_index",
            &params,
            z,
            &errors(&caller_after),
            first(&caller_after, false).as_ref(),
        );
    }
}
