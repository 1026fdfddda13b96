//! Which run-time error a kernel invocation reports: the first one it meets, by execution
//! order, across error kinds and across primitive calls. In tier 0, setup index and fuel
//! errors are not written to `TileCtx::error` where they happen: the kernel keeps the first
//! one in a variable and flushes it at the setup's exits and end and before primitive calls
//! (`Lower::defer_error`, `Lower::flush_errors`); tier 1 records them from cold blocks.
//! Both tiers must report the same site (W0801 at its line:col) and draw the same depth:
//! each out-of-range index reads the nearest end of its array.
//!
//! - Two failing sites: the one that fails first at run time is reported, also when it is
//!   the later one in the source (a loop whose second read leaves the array first).
//! - An index error and a loop running out of fuel, in both orders.
//! - One index read several times in a row (tier 0 checks it once per block): the first
//!   read that may fail is reported, a guarded one (an arm of `?:`) only when its arm is
//!   taken.
//! - An index error before a primitive call whose callee records its own, and the reverse:
//!   the call runs with the caller's context (calls are not expanded here), so whichever
//!   error came first is the invocation's one error.

use crate::support;

use std::sync::Arc;

use primflow::diag::SourceMap;
use primflow::ir::Program;
use primflow::jit::Tier;
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
    let header = format!("primitive {primitive}(");
    let lines: Vec<&str> = SOURCE.lines().collect();
    let start = lines.iter().position(|l| l.starts_with(&header)).expect("primitive");
    let (n, line) = lines
        .iter()
        .enumerate()
        .skip(start)
        .find(|(_, l)| l.contains(line_text))
        .expect("line");
    let col = line.find(line_text).expect("text") + line_text.find(index).expect("index") + 1;
    format!("W0801@{}:{}", n + 1, col)
}

fn library(sources: &mut SourceMap) -> Arc<Program> {
    support::library_with(sources, &[("order.prim", SOURCE)])
}

/// Renders `prim` with `params` at both tiers (calls made directly, not expanded): the
/// depth inside the rectangle, which must equal `flat` drawing `want_z`, and the reported
/// errors, which must be `want_errors`.
fn check(prim: &str, params: &[(&str, f32)], want_z: f32, want_errors: &[String]) {
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
        assert_eq!(errors, want_errors, "{case}: errors");
    }
}

#[test]
fn of_two_failing_index_sites_the_first_to_fail_is_reported() {
    let first = site("two_sites", "float s = a[i];", "i]");
    let second = site("two_sites", "s = s + a[j];", "j]");
    for (i, j) in [(1, 2), (7, 2), (1, -3), (-1, 9), (4, 4)] {
        let errors: Vec<String> = if !(0..4).contains(&i) {
            vec![first.clone()]
        } else if !(0..4).contains(&j) {
            vec![second.clone()]
        } else {
            vec![]
        };
        let params = [("i", i as f32), ("j", j as f32)];
        check("two_sites", &params, a(i) + a(j), &errors);
    }
}

#[test]
fn an_index_read_again_reports_its_first_read_that_can_fail() {
    let guarded = site("repeated_index", "float s = c != 0 ? a[i] : 0;", "i]");
    let unguarded = site("repeated_index", "s = s + a[i];", "i]");
    let b = |i: i64| [0.125f32, 0.25, 0.375, 0.5][i.clamp(0, 3) as usize];
    for (i, c) in [(2, 1), (2, 0), (6, 1), (6, 0), (-1, 0), (-1, 1)] {
        let errors: Vec<String> = match ((0..4).contains(&i), c != 0) {
            (true, _) => vec![],
            (false, true) => vec![guarded.clone()],
            // The arm is not taken: its read is no error, the next one is.
            (false, false) => vec![unguarded.clone()],
        };
        let first = if c != 0 { a(i) } else { 0.0 };
        let z = first + a(i) + b(i) + a(i);
        check("repeated_index", &[("i", i as f32), ("c", c as f32)], z, &errors);
    }
}

#[test]
fn in_a_loop_the_site_that_fails_first_at_run_time_wins_over_source_order() {
    let by_counter = site("loop_order", "s = s + a[t];", "t]");
    let by_window = site("loop_order", "s = s + a[k - t];", "k - t");
    // (n, k) -> the first trip t whose `a[t]` (t >= 4) or `a[k - t]` (k - t outside 0..4)
    // leaves the array; `a[t]` is read first within a trip. (6, 3): `a[t]` fails first, at
    // t = 4, though both fail then and after; (6, 1): `a[k - t]` fails first, at t = 2,
    // though `a[t]` fails from t = 4 on; (4, 3), (3, 2): neither.
    let mut reported = vec![];
    for (n, k) in [(4, 3), (6, 3), (6, 1), (6, 9), (3, 2), (9, 5)] {
        let mut s = 0f32;
        let mut first_error = None;
        for t in 0..n {
            if first_error.is_none() && t >= 4 {
                first_error = Some(by_counter.clone());
            }
            s += a(t);
            if first_error.is_none() && !(0..4).contains(&(k - t)) {
                first_error = Some(by_window.clone());
            }
            s += a(k - t);
        }
        let errors: Vec<String> = first_error.into_iter().collect();
        check("loop_order", &[("n", n as f32), ("k", k as f32)], s, &errors);
        reported.extend(errors);
    }
    // Both sites are the reported one in some case.
    assert!(
        reported.contains(&by_counter) && reported.contains(&by_window),
        "{reported:?}"
    );
}

#[test]
fn an_index_error_and_running_out_of_fuel_report_whichever_came_first() {
    let index_first = site("index_then_fuel", "float s = a[i];", "i]");
    let fuel_first = site("fuel_then_index", "for (int t = 0; t < n; t++)", "for");
    let index_after_fuel = site("fuel_then_index", "float s = a[i];", "i]");
    let fuel_after_index = site("index_then_fuel", "for (int t = 0; t < n; t++)", "for");
    // 3e8 > 2^28 trips (the default fuel) runs out; 1000 does not.
    let trips = |n: f32| if n > 1e6 { None } else { Some(n) };
    for (i, n) in [(9, 3e8f32), (2, 3e8), (-2, 1000.0), (1, 1000.0)] {
        let bad = !(0..4).contains(&i);
        let done = trips(n);
        // The depth of a run that runs out is whatever that run drew: compared between the
        // tiers through the reference only when the setup ran to its end.
        for (prim, first, second) in [
            ("index_then_fuel", &index_first, &fuel_after_index),
            ("fuel_then_index", &fuel_first, &index_after_fuel),
        ] {
            let (index_site, fuel_site) = if prim == "index_then_fuel" {
                (first, second)
            } else {
                (second, first)
            };
            let errors: Vec<String> = match (bad, done) {
                (false, Some(_)) => vec![],
                (true, Some(_)) => vec![index_site.clone()],
                (false, None) => vec![fuel_site.clone()],
                // Both fail: the one met first.
                (true, None) => vec![first.clone()],
            };
            match done {
                Some(trips) => check(prim, &[("i", i as f32), ("n", n)], a(i) + trips / 1073741824.0, &errors),
                None => {
                    let mut sources = SourceMap::new();
                    let program = library(&mut sources);
                    let r = rect_scene(&program, prim, &[("i", i as f32), ("n", n)]);
                    let runs: Vec<(u32, Vec<String>)> = [Tier::Fast, Tier::Optimised]
                        .into_iter()
                        .map(|tier| rect_depth_and_codes(&program, &sources, &r, tier))
                        .collect();
                    assert_eq!(runs[0], runs[1], "{prim} i={i}: tiers differ");
                    assert_eq!(runs[0].1, errors, "{prim} i={i} n={n}");
                }
            }
        }
    }
}

#[test]
fn across_a_primitive_call_the_first_error_of_caller_and_callee_wins() {
    let caller_first = site("index_then_call", "float s = a[i];", "i]");
    let caller_after = site("call_then_index", "float s = a[i + 0];", "i + 0");
    let in_callee = site("callee", "float s = b[j];", "j]");
    for (i, j) in [(1, 1), (5, 1), (1, 2), (5, -1), (-3, 7)] {
        let caller_bad = !(0..4).contains(&i);
        let callee_bad = !(0..2).contains(&j);
        // The caller's pixel part runs after its setup (and the call): its Z is the last
        // written.
        let z = a(i);
        let errors = |caller_site: &String, caller_first: bool| -> Vec<String> {
            match (caller_bad, callee_bad) {
                (false, false) => vec![],
                (true, false) => vec![caller_site.clone()],
                (false, true) => vec![in_callee.clone()],
                (true, true) if caller_first => vec![caller_site.clone()],
                (true, true) => vec![in_callee.clone()],
            }
        };
        let params = [("i", i as f32), ("j", j as f32)];
        check("index_then_call", &params, z, &errors(&caller_first, true));
        check("call_then_index", &params, z, &errors(&caller_after, false));
    }
}
