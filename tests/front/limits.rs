//! The depth and size limits (`src/limits.rs`, docs/language.md "Limits"): a program one
//! past each limit gets its error at the first place past it, a program at the limit checks,
//! and both are checked on a thread with the smallest stack a compile runs on (2 MiB), so a
//! missed limit shows as a crash here. Sources are generated in the test.

use primflow::diag::{Diagnostics, SourceMap};
use primflow::limits::{
    MAX_BLOCK_DEPTH, MAX_CALL_DEPTH, MAX_EXPR_DEPTH, MAX_LOCAL_BYTES, MAX_NESTING, MAX_SOURCE_BYTES,
};

/// The smallest stack of a compiling thread (std's default for a spawned thread).
const SMALLEST_STACK: usize = 2 << 20;

/// Check `text` as `deep.prim` on a thread with [`SMALLEST_STACK`]: the diagnostics as
/// `code@line:col`.
fn codes(text: String) -> Vec<String> {
    std::thread::Builder::new()
        .stack_size(SMALLEST_STACK)
        .spawn(move || {
            let mut sources = SourceMap::new();
            let id = sources.add("deep.prim", text);
            let mut diags = Diagnostics::new();
            primflow::compile(&sources, &[id], &mut diags);
            diags.codes_at(&sources)
        })
        .unwrap()
        .join()
        .unwrap()
}

/// A primitive whose body is `body` (line 3 on), after a bound and a depth write on line 2
/// (so that it draws: no W0003 or W0004).
fn prim(body: &str) -> String {
    format!(
        "primitive deep(float rect[4]; varying float X, Y; inout varying float Z)\n{{ bound(rect[0], rect[1], rect[2], rect[3]); Z = 0.5;\n{body}\n}}\n"
    )
}

/// `float a = X + X + ... + X;` with `n` terms, on line 3 from column 5.
fn sum(n: usize, op: &str) -> String {
    prim(&format!("    float a = {};", vec!["X"; n].join(op)))
}

#[test]
fn a_sum_or_product_at_the_limit_checks_and_one_term_more_is_e0014_at_its_start() {
    for op in [" + ", " * ", " - ", " / "] {
        let n = MAX_EXPR_DEPTH as usize;
        assert_eq!(codes(sum(n, op)), Vec::<String>::new(), "{n} terms of {op}");
        // The chain's node one level too deep starts where the expression does.
        assert_eq!(codes(sum(n + 1, op)), ["E0014@3:15"], "{} terms of {op}", n + 1);
        assert_eq!(codes(sum(20_000, op)), ["E0014@3:15"], "20000 terms of {op}");
    }
}

#[test]
fn nested_calls_casts_and_negations_past_the_limit_are_e0014_at_the_first_too_deep() {
    let n = MAX_EXPR_DEPTH as usize;
    for (open, step) in [("abs(", 4), ("float(", 6), ("-(", 2), ("sqrt(abs(", 9)] {
        let levels_per = if open == "sqrt(abs(" { 2 } else { 1 };
        let nest = |k: usize| {
            let close = ")".repeat(k * levels_per);
            prim(&format!("    float a = {}X{close};", open.repeat(k)))
        };
        // `X` itself is a level.
        let at = (n - 1) / levels_per;
        assert_eq!(codes(nest(at)), Vec::<String>::new(), "{at} of {open}");
        // The first level past the limit is the (n+1)-th node from the top.
        let deep = codes(nest(5_000));
        let col = 15 + (n / levels_per) * step + if levels_per == 2 && n % 2 == 1 { 5 } else { 0 };
        assert_eq!(deep, [format!("E0014@3:{col}")], "5000 of {open}");
    }
}

#[test]
fn nested_blocks_at_the_limit_check_and_one_more_is_e0015_at_that_block() {
    let n = MAX_BLOCK_DEPTH as usize;
    let blocks = |k: usize| {
        prim(&format!(
            "    float a = 0;\n{}a = a + 1;{}",
            "{".repeat(k),
            "}".repeat(k)
        ))
    };
    assert_eq!(codes(blocks(n - 1)), Vec::<String>::new());
    // The body's statements are level 1, so the statement after the k-th `{` is level
    // k + 1: with n braces, `a = a + 1;` is one too deep; with more, the (n+1)-th block.
    assert_eq!(codes(blocks(n)), [format!("E0015@4:{}", n + 1)]);
    assert_eq!(codes(blocks(10_000)), [format!("E0015@4:{}", n + 1)]);
    let ifs = |k: usize| prim(&format!("    float a = 0;\n{}a = a + 1;", "if (X > 0) ".repeat(k)));
    assert_eq!(codes(ifs(n - 1)), Vec::<String>::new());
    assert_eq!(codes(ifs(10_000)), [format!("E0015@4:{}", n * 11 + 1)]);
}

/// Helpers `h0` .. `h{n-1}` (lines 1..=n), each returning the next one's value, `h{n-1}`
/// returning `x + 1`; the primitive (line n+1 on) calls `h0` on its line n+4, column 15.
fn chain(n: usize) -> String {
    let mut text = String::new();
    for i in 0..n - 1 {
        text.push_str(&format!("float h{i}(float x) {{ return h{}(x); }}\n", i + 1));
    }
    text.push_str(&format!("float h{}(float x) {{ return x + 1; }}\n", n - 1));
    text + &prim("    float a = h0(X);\n    Z = a;")
}

#[test]
fn a_chain_of_helpers_at_the_limit_checks_and_one_more_is_e0110_at_the_call() {
    let n = MAX_CALL_DEPTH as usize;
    assert_eq!(codes(chain(n)), Vec::<String>::new());
    // h{n-1} calls h{n}, the (n+1)-th of the chain, at column 31 of its line.
    assert_eq!(
        codes(chain(n + 1)),
        [format!("E0110@{n}:{}", 27 + (n - 1).to_string().len())]
    );
    // 1,500 helpers: reported where the chain passes the limit, once.
    assert_eq!(
        codes(chain(1_500)),
        [format!("E0110@{n}:{}", 27 + (n - 1).to_string().len())]
    );
}

#[test]
fn nesting_is_counted_through_inlined_helpers() {
    // Each helper's call of the next is the first term of a sum of 200, so 200 deep:
    // three of them reach 600 levels (with the calls' own), past MAX_NESTING, though each
    // is within the expression limit.
    let terms = |k: usize| vec!["x"; k].join(" + ");
    let helper = |i: usize, next: Option<usize>| match next {
        Some(j) => format!("float h{i}(float x) {{ return h{j}(x) + {}; }}\n", terms(199)),
        None => format!("float h{i}(float x) {{ return {}; }}\n", terms(200)),
    };
    let text = helper(0, Some(1)) + &helper(1, Some(2)) + &helper(2, None) + &prim("    float a = h0(X);");
    let got = codes(text);
    assert_eq!(got.len(), 1, "{got:?}");
    assert!(got[0].starts_with("E0111@3:"), "{got:?}");
    // Two helpers of 200 levels each stay within it.
    let text = helper(0, Some(1)) + &helper(1, None) + &prim("    float a = h0(X);");
    assert_eq!(codes(text), Vec::<String>::new());
    assert!(2 * (200 + 3) + 3 < MAX_NESTING as usize);
}

#[test]
fn a_long_chain_of_recursive_helpers_is_reported_without_overflowing() {
    // 100,000 helpers calling each other in a ring: the cycle search is iterative.
    let n = 100_000;
    let mut text = String::new();
    for i in 0..n {
        text.push_str(&format!("float h{i}(float x) {{ return h{}(x); }}\n", (i + 1) % n));
    }
    let got = codes(text);
    assert_eq!(got, [format!("E0107@{n}:{}", 27 + (n - 1).to_string().len())]);
}

#[test]
fn a_source_past_the_size_limit_is_e0002_at_its_first_byte_past() {
    let line = "// a comment line of 32 bytes.\n";
    let mut text = line.repeat(MAX_SOURCE_BYTES / line.len() + 1);
    let (l, c) = (MAX_SOURCE_BYTES / line.len() + 1, MAX_SOURCE_BYTES % line.len() + 1);
    assert_eq!(codes(text.clone()), [format!("E0002@{l}:{c}")]);
    text.truncate(MAX_SOURCE_BYTES);
    assert_eq!(codes(text), Vec::<String>::new());
}

#[test]
fn a_deep_tree_with_a_syntax_error_is_freed_without_overflowing() {
    // The parser drops the partial tree when it recovers from `@`.
    let text = prim(&format!(
        "    float a = {} @;\n    float b = {}",
        vec!["X"; 200_000].join("+"),
        "(".repeat(100_000)
    ));
    let got = codes(text);
    assert!(got.iter().all(|c| c.starts_with("E00")), "{got:?}");
    assert!(!got.is_empty());
}

/// `n` varying arrays of 65536 floats (1 MiB each), two lines each from line 3, plus a
/// uniform one of `uniform` floats.
fn wide_locals(n: usize, uniform: usize) -> String {
    let mut body: Vec<String> = (0..n)
        .map(|i| format!("    float a{i}[65536];\n    a{i}[int(X)] = Y;"))
        .collect();
    body.push(format!("    float u[{uniform}];"));
    prim(&body.join("\n"))
}

#[test]
fn locals_past_the_size_limit_are_e0216_at_the_local_that_passes_it() {
    let n = (MAX_LOCAL_BYTES >> 20) as usize;
    // Under the limit; then n MiB of varying arrays, the limit itself, and a uniform float
    // 4 bytes past it; then the (n + 1)-th array past it. Both on line 3 + 2n.
    assert_eq!(codes(wide_locals(n - 1, 65536)), Vec::<String>::new());
    let line = 3 + 2 * n;
    assert_eq!(codes(wide_locals(n, 1)), [format!("E0216@{line}:11")]);
    assert_eq!(codes(wide_locals(n + 1, 1)), [format!("E0216@{line}:11")]);
}
