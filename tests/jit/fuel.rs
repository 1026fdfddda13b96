//! Fuel of uniform loops (`Lower::spend_fuel`, `Lower::uniform_loop`): every visit of a
//! loop's head spends one unit before the condition is tested, and the first visit that
//! finds none left records ERR_FUEL (W0801) at that loop and ends the run; the runtime
//! then draws the instance nowhere (its bound run ran out, `abi::ctx`). These tests pin
//! that down where a change of how fuel is spent (once per loop for bounded loops, say)
//! could move it: a loop bounded by a guard, a loop inside a loop (which of the two runs
//! out depends on the trip counts), and a loop whose bound is an argument. A frame that
//! does not run out must show the exact trip count.

use crate::support;

use std::sync::Arc;

use primflow::abi::DEFAULT_FUEL;
use primflow::diag::SourceMap;
use primflow::ir::Program;
use primflow::jit::{Jit, Tier};
use primflow::runtime::{Renderer, Value};

const LOOPS: &str = r#"
primitive nested(float rect[4]; int n, m; varying float X, Y; inout varying fixed<32,32> Z)
{
    bound(rect[0], rect[1], rect[2], rect[3]);
    if (n < 0 || n > 65536 || m < 0 || m > 65536)
        return;
    int trips = 0;
    for (int i = 0; i < n; i++) {
        for (int j = 0; j < m; j++)
            trips += 1;
    }
    Z = trips / 1024.0;
}

primitive free_bound(float rect[4]; int n; varying float X, Y; inout varying fixed<32,32> Z)
{
    bound(rect[0], rect[1], rect[2], rect[3]);
    int trips = 0;
    for (int i = 0; i < n; i++)
        trips += 1;
    Z = trips / 1024.0;
}
"#;

/// The sites of the loops above (line:col of `for`).
const OUTER: &str = "W0801@8:5";
const INNER: &str = "W0801@9:9";
const FREE: &str = "W0801@19:5";

fn library(sources: &mut SourceMap) -> Arc<Program> {
    support::library_with(sources, &[("fuel.prim", LOOPS)])
}

/// Depth at a pixel inside the rectangle and the run-time diagnostics, for each tier.
fn run(prim: &str, params: &[(&str, f32)]) -> Vec<(u32, Vec<String>)> {
    let mut sources = SourceMap::new();
    let program = library(&mut sources);
    let mut r = Renderer::new(program.clone());
    r.set_image_size(8, 8).unwrap();
    r.set_tile_size(16).unwrap();
    r.begin(prim).unwrap();
    r.rast_param("rect", &Value(vec![1.0, 1.0, 7.0, 7.0])).unwrap();
    for (name, v) in params {
        r.rast_param(name, &Value(vec![*v])).unwrap();
    }
    r.end().unwrap();
    [Tier::Fast, Tier::Optimised]
        .into_iter()
        .map(|tier| {
            let mut jit = Jit::at_tier(program.clone(), tier).unwrap();
            let out = r.render(&mut jit);
            assert!(!out.diags.has_errors(), "{:?}", out.diags.items);
            let mut codes = out.diags.codes_at(&sources);
            codes.dedup();
            (out.frame.depth_at(3, 3).unwrap(), codes)
        })
        .collect()
}

/// Raw depth of `trips / 1024` in fixed<32,32> (exact for the counts used here).
fn depth_of(trips: u64) -> u32 {
    ((trips as f64 / 1024.0) * 4294967296.0) as u32
}

/// Which loop of `nested` runs out first with `fuel` units: each outer trip visits the
/// outer head once and the inner head m + 1 times; the head that finds 0 reports.
fn nested_reference(n: u64, m: u64, fuel: u64) -> Option<&'static str> {
    let per_outer = m + 2;
    let whole = fuel / per_outer;
    if whole >= n + 1 || (whole == n && fuel - whole * per_outer >= 1) {
        return None; // n trips and the final outer test fit
    }
    Some(if fuel % per_outer == 0 { OUTER } else { INNER })
}

#[test]
fn bounded_nested_loops_count_exactly_when_fuel_suffices() {
    for (n, m) in [(0u64, 5u64), (3, 0), (3, 5), (17, 33)] {
        assert_eq!(nested_reference(n, m, DEFAULT_FUEL), None);
        for (tier, (depth, codes)) in run("nested", &[("n", n as f32), ("m", m as f32)])
            .into_iter()
            .enumerate()
        {
            assert!(codes.is_empty(), "n={n} m={m} tier {tier}: {codes:?}");
            assert_eq!(depth, depth_of(n * m), "n={n} m={m} tier {tier}");
        }
    }
}

#[test]
fn nested_loops_run_out_of_fuel_at_the_loop_whose_head_finds_none() {
    // 2^28 units: inner trips of 2^14 - 2 make an outer trip cost exactly 2^14, so the
    // outer head meets the empty tank; with 20000 the inner head does.
    for (n, m) in [(20000u64, (1u64 << 14) - 2), (20000, 20000)] {
        let expected = nested_reference(n, m, DEFAULT_FUEL).expect("runs out");
        for (tier, (depth, codes)) in run("nested", &[("n", n as f32), ("m", m as f32)])
            .into_iter()
            .enumerate()
        {
            assert_eq!(codes, [expected], "n={n} m={m} tier {tier}");
            // The setup ran out: nothing is drawn, the depth stays cleared (far).
            assert_eq!(depth, 0, "n={n} m={m} tier {tier}");
        }
    }
    assert_eq!(nested_reference(20000, (1 << 14) - 2, DEFAULT_FUEL), Some(OUTER));
    assert_eq!(nested_reference(20000, 20000, DEFAULT_FUEL), Some(INNER));
}

#[test]
fn a_loop_bounded_by_an_argument_runs_out_at_its_own_site() {
    for (tier, (depth, codes)) in run("free_bound", &[("n", 1000.0)]).into_iter().enumerate() {
        assert!(codes.is_empty(), "tier {tier}: {codes:?}");
        assert_eq!(depth, depth_of(1000), "tier {tier}");
    }
    // 3e8 > 2^28 trips (exact in f32).
    for (tier, (depth, codes)) in run("free_bound", &[("n", 3e8)]).into_iter().enumerate() {
        assert_eq!(codes, [FREE], "tier {tier}");
        assert_eq!(depth, 0, "tier {tier}");
    }
}
