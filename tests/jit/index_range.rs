//! Index checks of uniform loops (src/ir/range.rs, `Lower::index_access`): an index the range
//! analysis proves in range is used as it is; any other is clamped into the array and
//! reported (W0801 at the access) through a cold path. Either way the frame must be what the
//! language says: the sum of the elements the loop reads, with an out-of-range index reading
//! the nearest end of the array, and the run-time error at the indexing site exactly when
//! some index leaves the array.

use crate::support;

use std::sync::Arc;

use primflow::diag::{Diagnostics, SourceMap};
use primflow::ir::range::proven_index_sites;
use primflow::ir::Program;
use primflow::jit::Tier;
use primflow::runtime::Registry;
use support::{rect_depth_and_codes as run, rect_scene as scene};

/// The elements of every test array: a[i] = (i + 1) / 64, exact in f32 and in Z's fixed point.
fn element(i: i64) -> f32 {
    (i + 1) as f32 / 64.0
}

/// Three loops over `float a[LEN]`, each a primitive: `sum_min` bounds the loop by
/// `hi < LEN ? hi : LEN` (proven), `sum_guarded` returns early unless `0 <= lo` and `hi <= LEN`
/// (proven after the guard), `sum_free` trusts its parameters (not proven: checked).
/// `flat` draws the expected value for comparison. `sum_select` reads `i < hi ? a[i] : 0`
/// up to `i == hi`: the JIT evaluates `a[i]` there too, so that site must not be proven
/// (and must not report an error: the language takes the other arm).
fn source(len: usize) -> String {
    let init: Vec<String> = (0..len).map(|i| format!("{}", element(i as i64))).collect();
    let init = init.join(", ");
    format!(
        r#"
primitive sum_min(float rect[4]; int lo, hi; varying float X, Y; inout varying fixed<32,32> Z)
{{
    bound(rect[0], rect[1], rect[2], rect[3]);
    float a[{len}] = {{{init}}};
    float s = 0;
    int top = hi < {len} ? hi : {len};
    for (int i = lo < 0 ? 0 : lo; i < top; i++)
        s = s + a[i];
    Z = s;
}}

primitive sum_guarded(float rect[4]; int lo, hi; varying float X, Y; inout varying fixed<32,32> Z)
{{
    bound(rect[0], rect[1], rect[2], rect[3]);
    if (lo < 0 || hi > {len})
        return;
    float a[{len}] = {{{init}}};
    float s = 0;
    for (int i = lo; i < hi; i++)
        s = s + a[i];
    Z = s;
}}

primitive sum_free(float rect[4]; int lo, hi; varying float X, Y; inout varying fixed<32,32> Z)
{{
    bound(rect[0], rect[1], rect[2], rect[3]);
    float a[{len}] = {{{init}}};
    float s = 0;
    int i = lo;
    while (i < hi) {{
        s = s + a[i];
        i += 1;
    }}
    Z = s;
}}

primitive flat(float rect[4]; float z; varying float X, Y; inout varying fixed<32,32> Z)
{{
    bound(rect[0], rect[1], rect[2], rect[3]);
    Z = z;
}}

primitive sum_select(float rect[4]; int lo, hi; varying float X, Y; inout varying fixed<32,32> Z)
{{
    bound(rect[0], rect[1], rect[2], rect[3]);
    if (lo < 0 || hi > {len})
        return;
    float a[{len}] = {{{init}}};
    float s = 0;
    for (int i = lo; i <= hi; i++)
        s = s + (i < hi ? a[i] : 0);
    Z = s;
}}

primitive sum_window(float rect[4]; int k, p; varying float X, Y; inout varying fixed<32,32> Z)
{{
    bound(rect[0], rect[1], rect[2], rect[3]);
    if (p < 0 || p >= {len} || k >= {len})
        return;
    float a[{len}] = {{{init}}};
    float s = 0;
    for (int j = 0; j <= p; j++)
        s = s + a[k - p + j];
    Z = s;
}}

primitive last_rise(float rect[4]; int n; varying float X, Y; inout varying fixed<32,32> Z)
{{
    bound(rect[0], rect[1], rect[2], rect[3]);
    if (n < 1 || n > {len})
        return;
    float a[{len}] = {{{init}}};
    int k = 0;
    for (int i = 0; i + 1 < n; i++) {{
        if (a[i] <= a[i + 1])
            k = i;
    }}
    float s = a[k + 1];
    Z = s;
}}

primitive pick(float rect[4]; int hi; bool low; varying float X, Y; inout varying fixed<32,32> Z)
{{
    bound(rect[0], rect[1], rect[2], rect[3]);
    if (hi < 0 || hi >= {len})
        return;
    float a[{len}] = {{{init}}};
    int i = low ? 0 : hi;
    int j = low ? 0 : hi + 1;
    float s = a[i] + a[j];
    Z = s;
}}
"#
    )
}

/// Line and column of the index in `s = s + a[i]` in `sum_free` (the site its error names).
const FREE_SITE: &str = "W0801@32:19";
/// The index `k + 1` in `last_rise`: `k` is 0 or a copy of the counter `i` under
/// `i + 1 < n <= len`, so in range for every `len` but 1 (and there only when `n == 1`).
const RISE_SITE: &str = "W0801@79:17";
/// The index `k - p + j` in `sum_window`: in range exactly when `k >= p` (a relation
/// between two variables, which the interval analysis cannot prove).
const WINDOW_SITE: &str = "W0801@64:19";

fn library(sources: &mut SourceMap, len: usize) -> Arc<Program> {
    support::library_with(sources, &[("ranged.prim", &source(len))])
}

/// What the language says a loop over [lo, hi) reads: each index clamped into the array,
/// summed in order in f32; and whether some index was out of range.
fn reference(len: usize, lo: i64, hi: i64) -> (f32, bool) {
    let mut s = 0f32;
    let mut bad = false;
    for i in lo..hi {
        bad |= i < 0 || i >= len as i64;
        s += element(i.clamp(0, len as i64 - 1));
    }
    (s, bad)
}

#[test]
fn index_proofs_cover_bounded_loops_and_guards_but_not_free_ones() {
    let mut sources = SourceMap::new();
    let program = library(&mut sources, 4);
    // Proven sites as line:col of the index; of these, `bound`'s constant indices are
    // proven everywhere, the loops' `a[i]` (column 19) only where the analysis can.
    let proven = |name: &str| -> Vec<String> {
        let mut at: Vec<String> = proven_index_sites(program.func(program.find(name).unwrap()))
            .into_iter()
            .map(|site| {
                let span = program.sites[site.0 as usize];
                let (l, c) = sources.line_col(span.file, span.start);
                format!("{l}:{c}")
            })
            .collect();
        at.sort();
        at
    };
    let sites = |name: &str| {
        proven(name)
            .into_iter()
            .filter(|s| s.ends_with(":19"))
            .collect::<Vec<_>>()
    };
    assert_eq!(sites("sum_min"), ["9:19"], "a[i] with i < (hi < 4 ? hi : 4)");
    assert_eq!(
        sites("sum_guarded"),
        ["21:19"],
        "a[i] after `if (lo < 0 || hi > 4) return;`"
    );
    assert!(sites("sum_free").is_empty(), "a[i] with i < hi unchecked");
    let select: Vec<String> = proven("sum_select")
        .into_iter()
        .filter(|s| s.starts_with("52:"))
        .collect();
    assert!(
        select.is_empty(),
        "a[i] in an arm of ?: runs whatever the condition: {select:?}"
    );
    // `?:` on a condition that bounds nothing (a bool): the join of both arms, so `a[i]`
    // (0 or hi) is proven and `a[j]` (0 or hi + 1) is not.
    let text = source(4);
    let line = 1 + text.lines().position(|l| l.contains("s = a[i] + a[j];")).unwrap();
    let at = |index: &str| {
        let col = text.lines().nth(line - 1).unwrap().find(index).unwrap();
        format!("{line}:{}", col + 1)
    };
    let picked: Vec<String> = proven("pick")
        .into_iter()
        .filter(|s| s.starts_with(&format!("{line}:")))
        .collect();
    assert_eq!(picked, [at("i]")], "of {} and {}", at("i]"), at("j]"));
    // The NURB surface's setup: its validation bounds the orders and counts, so many of
    // the tessellation's accesses are proven (de Boor's `d[j]`, `w[j]`, the ring arrays).
    let mut sources = SourceMap::new();
    let mut diags = Diagnostics::new();
    let library = Registry::load(&mut sources, &[], &[], &mut diags).unwrap().program;
    let nurb = library.func(library.find("nurb_surface").unwrap());
    assert!(
        proven_index_sites(nurb).len() >= 20,
        "{}",
        proven_index_sites(nurb).len()
    );
}

#[test]
fn loops_at_the_edges_of_their_arrays_read_clamped_values_and_report_errors() {
    for len in [1usize, 2, 3, 4] {
        let mut sources = SourceMap::new();
        let program = library(&mut sources, len);
        let l = len as i64;
        // Around the edges: one short, exact, one over, empty, starting below 0, negative end.
        let bounds = [(0, l - 1), (0, l), (0, l + 1), (0, 0), (-1, l), (0, -1), (l - 1, l + 2)];
        for (lo, hi) in bounds {
            let (sum, bad) = reference(len, lo, hi);
            let params = [("lo", lo as f32), ("hi", hi as f32)];
            let expected_scene = scene(&program, "flat", &[("z", sum)]);
            for tier in [Tier::Fast, Tier::Optimised] {
                let (want, none) = run(&program, &sources, &expected_scene, tier);
                assert!(none.is_empty());
                let case = format!("len={len} lo={lo} hi={hi} {tier:?}");

                let (got, errors) = run(&program, &sources, &scene(&program, "sum_free", &params), tier);
                assert_eq!(got, want, "sum_free {case}");
                let expected_errors: Vec<&str> = if bad { vec![FREE_SITE] } else { vec![] };
                assert_eq!(errors, expected_errors, "sum_free {case}");

                // The bounded loops never leave the array: no error, and the in-range part
                // of the sum.
                let (in_sum, _) = reference(len, lo.max(0), hi.min(l));
                let (got, errors) = run(&program, &sources, &scene(&program, "sum_min", &params), tier);
                let (want_min, _) = run(&program, &sources, &scene(&program, "flat", &[("z", in_sum)]), tier);
                assert_eq!((got, errors.len()), (want_min, 0), "sum_min {case}");

                // The guarded loop draws only when its guard passes.
                for prim in ["sum_guarded", "sum_select"] {
                    let (got, errors) = run(&program, &sources, &scene(&program, prim, &params), tier);
                    assert!(errors.is_empty(), "{prim} {case}: {errors:?}");
                    if lo < 0 || hi > l {
                        assert_eq!(got, 0, "{prim} {case}: returned before drawing");
                    } else {
                        assert_eq!(got, want, "{prim} {case}");
                    }
                }
            }
        }
    }
}

#[test]
fn a_window_below_the_array_reads_clamped_values_and_reports_its_index_site() {
    for len in [2usize, 4] {
        let mut sources = SourceMap::new();
        let program = library(&mut sources, len);
        let l = len as i64;
        for k in -1..l {
            for p in 0..l {
                // a[k - p + j] for j in 0..=p: the window [k - p, k], clamped.
                let (sum, bad) = reference(len, k - p, k + 1);
                let params = [("k", k as f32), ("p", p as f32)];
                for tier in [Tier::Fast, Tier::Optimised] {
                    let case = format!("len={len} k={k} p={p} {tier:?}");
                    let (want, _) = run(&program, &sources, &scene(&program, "flat", &[("z", sum)]), tier);
                    let (got, errors) = run(&program, &sources, &scene(&program, "sum_window", &params), tier);
                    assert_eq!(got, want, "{case}");
                    let expected: Vec<&str> = if bad { vec![WINDOW_SITE] } else { vec![] };
                    assert_eq!(errors, expected, "{case}");
                }
            }
        }
    }
}

/// `last_rise` needs the analysis' loop rules: `i + 1 < n` narrows the counter only while
/// `i + 1` cannot wrap (widening stops at 2^30 first), and `k = i` keeps `i`'s bound only
/// when the counter is widened before the copy and the head is narrowed after. Proven for
/// len 4; for len 1 the `a[k + 1]` site is out of range at `n == 1` and must stay checked,
/// clamped, and reported at its line:col in both tiers.
#[test]
fn copies_of_bounded_counters_are_proven_and_the_edge_case_still_reports() {
    let mut sources = SourceMap::new();
    let program = library(&mut sources, 4);
    let mut proven: Vec<String> = proven_index_sites(program.func(program.find("last_rise").unwrap()))
        .into_iter()
        .map(|site| {
            let span = program.sites[site.0 as usize];
            let (l, c) = sources.line_col(span.file, span.start);
            format!("{l}:{c}")
        })
        .filter(|at| at.starts_with("76:") || at.starts_with("79:"))
        .collect();
    proven.sort();
    assert_eq!(proven, ["76:15", "76:23", "79:17"], "a[i], a[i + 1], a[k + 1]");
    for len in [1usize, 2, 4] {
        let mut sources = SourceMap::new();
        let program = library(&mut sources, len);
        let l = len as i64;
        for n in 1..=l {
            // k = n - 2 for n >= 2 (the elements rise), else 0: a[k + 1] clamped.
            let index = if n >= 2 { n - 1 } else { 1 };
            let want_z = element(index.min(l - 1));
            let bad = index >= l;
            for tier in [Tier::Fast, Tier::Optimised] {
                let case = format!("len={len} n={n} {tier:?}");
                let (want, _) = run(&program, &sources, &scene(&program, "flat", &[("z", want_z)]), tier);
                let (got, errors) = run(
                    &program,
                    &sources,
                    &scene(&program, "last_rise", &[("n", n as f32)]),
                    tier,
                );
                assert_eq!(got, want, "{case}");
                let expected: Vec<&str> = if bad { vec![RISE_SITE] } else { vec![] };
                assert_eq!(errors, expected, "{case}");
            }
        }
    }
}
