//! Programs at the depth limits (`src/limits.rs`) compile and run right at both tiers on a
//! thread with the smallest stack a compile runs on (2 MiB: the tier-1 compile threads,
//! rayon's global pool, a thread spawned with Rust's defaults). The checker, the IR passes
//! and the JIT's lowering all recurse on the program's nesting; a limit set too high shows
//! here as a stack overflow. Each program counts its levels into the depth: a sum of n
//! copies of 1 is n.
//!
//! Issue 39, item 3: `X*X*...*X` with 2,000 factors passed the checker and tier 0 and
//! overflowed the tier-1 thread; 2,000 factors are now E0014 (tests/front/limits.rs).

use crate::support;

use primflow::jit::{Jit, Tier};
use primflow::limits::{MAX_BLOCK_DEPTH, MAX_CALL_DEPTH, MAX_EXPR_DEPTH};

const SMALLEST_STACK: usize = 2 << 20;

/// A primitive `deep` drawing `a * z` into fixed<32,32> Z, after `body`, which sets `a`
/// (`one` is a varying 1, so nothing folds), behind `helpers`.
fn source(helpers: &str, body: &str) -> String {
    format!(
        "{helpers}
primitive deep(float rect[4]; float z; varying float X, Y; inout varying fixed<32,32> Z)
{{
    bound(rect[0], rect[1], rect[2], rect[3]);
    float one = X * 0 + 1;
    float a = 0;
{body}
    Z = a * z;
}}
"
    )
}

/// Check `text` and render it at each tier, everything on one thread with a 2 MiB stack:
/// the depth inside the rectangle, which is `a * 2^16` for z = 2^-16.
fn depths(text: String) -> Vec<u32> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .stack_size(SMALLEST_STACK)
        .build()
        .unwrap();
    pool.install(move || {
        let mut sources = primflow::diag::SourceMap::new();
        let program = support::library_with(&mut sources, &[("deep.prim", &text)]);
        let r = support::rect_scene(&program, "deep", &[("z", 1.0 / 65536.0)]);
        [Tier::Fast, Tier::Optimised]
            .into_iter()
            .map(|tier| {
                let mut jit = Jit::at_tier(program.clone(), tier).unwrap();
                let out = r.render(&mut jit);
                assert!(out.diags.items.is_empty(), "{:?}", out.diags.items);
                out.frame.depth_at(8, 5).unwrap()
            })
            .collect()
    })
}

/// `a` counted up to `n`, as the depth of both tiers.
fn counts(n: u32) -> Vec<u32> {
    vec![n << 16; 2]
}

#[test]
fn sums_and_products_at_the_expression_limit() {
    let n = MAX_EXPR_DEPTH as usize;
    // `a = one + ... + one`: the chain is n deep.
    let sum = format!("    a = {};", vec!["one"; n].join(" + "));
    assert_eq!(depths(source("", &sum)), counts(n as u32));
    // `a = one * ... * one * 3`: products of one, times the last factor.
    let product = format!("    a = {} * 3;", vec!["one"; n - 1].join(" * "));
    assert_eq!(depths(source("", &product)), counts(3));
}

#[test]
fn nested_calls_and_conversions_at_the_expression_limit() {
    let n = MAX_EXPR_DEPTH as usize;
    // `abs(abs(...(one + one)...))`: n - 2 calls above the sum and its operands.
    let calls = format!("    a = {}one + one{};", "abs(".repeat(n - 2), ")".repeat(n - 2));
    assert_eq!(depths(source("", &calls)), counts(2));
    let casts = format!("    a = {}one * 5{};", "float(".repeat(n - 2), ")".repeat(n - 2));
    assert_eq!(depths(source("", &casts)), counts(5));
}

#[test]
fn nested_blocks_at_the_statement_limit() {
    // The body's statements are level 1; each `if` body one more.
    let n = MAX_BLOCK_DEPTH as usize;
    let ifs = format!(
        "{}a = a + 1;{}",
        "if (X > -1) { a = a + 1; ".repeat(n - 1),
        " }".repeat(n - 1)
    );
    assert_eq!(depths(source("", &ifs)), counts(n as u32));
}

#[test]
fn a_chain_of_helpers_at_the_call_limit() {
    let n = MAX_CALL_DEPTH as usize;
    let mut helpers = String::new();
    for i in 0..n - 1 {
        helpers.push_str(&format!("float h{i}(float x) {{ return h{}(x) + 1; }}\n", i + 1));
    }
    helpers.push_str(&format!("float h{}(float x) {{ return x + 1; }}\n", n - 1));
    assert_eq!(depths(source(&helpers, "    a = h0(one * 0);")), counts(n as u32));
}
