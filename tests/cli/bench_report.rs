//! The bench report's arithmetic (src/bench/mod.rs): paired ratios are the median of the
//! rounds' ratios, and a key's runs of equal bindings are counted.

use primflow::bench::{paired_ratio, runs_of, KernelKind, KernelTiming};

fn timing(runs_ms: &[f64]) -> KernelTiming {
    let mut sorted = runs_ms.to_vec();
    sorted.sort_by(f64::total_cmp);
    KernelTiming {
        kind: KernelKind::Jit,
        kernel: String::new(),
        threads: 1,
        median_ms: sorted[sorted.len() / 2],
        min_ms: sorted[0],
        runs_ms: runs_ms.to_vec(),
        setup_ms: 0.0,
        tiles_ms: 0.0,
        shade_ms: 0.0,
        mpixels_per_s: 0.0,
        mprims_per_s: 0.0,
    }
}

#[test]
fn paired_ratios_are_the_median_of_the_rounds_ratios() {
    // Rounds: 10/10, 20/5, 30/40 -> 1, 4, 0.75: the median is 1 (the medians' ratio, 20/10,
    // pairs round 2's slow row with round 1's fast one).
    let a = timing(&[10.0, 20.0, 30.0]);
    let b = timing(&[10.0, 5.0, 40.0]);
    assert_eq!(paired_ratio(&a, &b), 1.0);
    assert_eq!(paired_ratio(&b, &a), 1.0);
    // A round twice as slow for both rows changes no round's ratio.
    assert_eq!(
        paired_ratio(&timing(&[10.0, 40.0, 12.0]), &timing(&[5.0, 20.0, 6.0])),
        2.0
    );
    // Rows with different run counts (one lost mid-way) fall back to the medians.
    assert_eq!(paired_ratio(&timing(&[10.0, 20.0]), &timing(&[5.0])), 4.0);
}

#[test]
fn runs_of_equal_bindings_are_counted() {
    assert_eq!(
        runs_of("perspective_linear:1,perspective_linear:1,perspective_linear:1"),
        "perspective_linear:1 x3"
    );
    assert_eq!(
        runs_of("linear:3,implicit:3,implicit:3,linear:3"),
        "linear:3,implicit:3 x2,linear:3"
    );
    assert_eq!(runs_of("no bindings"), "no bindings");
}
