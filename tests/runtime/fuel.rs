//! Fuel per draw, not per tile (`abi::ctx`'s rules): an endless loop stops after a budget
//! that does not grow with the image, reported once at the loop, and the frame is the same
//! bit for bit for any number of threads and any tile size.
//!
//! - Pixel code: every pixel group of a draw gets `max(group_fuel_floor, pixel_fuel /
//!   groups)` loop trips, `groups` the pixel groups of its bound rectangle. `spin_pixels`
//!   counts its trips into Z, so the depth shows the trips of every group: the same in every
//!   group, `pixel_fuel` in all while the floor does not apply, the floor per group when it
//!   does, at any image size; with the default budgets at 512x512 and 1920x1080 too.
//! - Setup code: a draw whose setup runs out of fuel in its bound run draws nothing and is
//!   run in no tile (`RenderStats::tile_invocations` is 0: the endless loop ran once, in the
//!   bound pass, whatever the image size), through a call and through an expansion too. A
//!   callee that runs out ends its caller's run: the warning names the callee's loop.

use crate::support;

use std::sync::Arc;

use primflow::abi::{DEFAULT_GROUP_FUEL_FLOOR, DEFAULT_PIXEL_FUEL};
use primflow::diag::SourceMap;
use primflow::ir::Program;
use primflow::jit::{Jit, Tier};
use primflow::runtime::{Frame, RenderOutput, Renderer, Value};
use primflow::workload::same_frame;

const SOURCE: &str = r#"
primitive spin_pixels(float rect[4]; varying float X, Y; inout varying fixed<32,32> Z)
{
    bound(rect[0], rect[1], rect[2], rect[3]);
    int n = 0;
    while (X > -1)
        n++;
    Z = n / 16777216.0;
}

primitive spin_setup(float rect[4]; int limit; varying float X, Y; inout varying fixed<32,32> Z)
{
    bound(rect[0], rect[1], rect[2], rect[3]);
    int n = 0;
    while (n < limit)
        n++;
    Z = n / 16777216.0;
}

primitive flat(float rect[4]; float z; varying float X, Y; inout varying fixed<32,32> Z)
{
    bound(rect[0], rect[1], rect[2], rect[3]);
    Z = z;
}

primitive spin_callee(float rect[4]; int limit; varying float X, Y; inout varying fixed<32,32> Z)
{
    bound(rect[0], rect[1], rect[2], rect[3]);
    int n = 0;
    while (n < limit)
        n++;
    Z = 0.75;
}

primitive calls_a_spinner(float rect[4]; int limit, reps; varying float X, Y; inout varying fixed<32,32> Z)
{
    spin_callee(rect, limit, X, Y, Z);
    int m = 0;
    for (int k = 0; k < reps; k++)
        m++;
    flat(rect, m / 32.0, X, Y, Z);
}

primitive calls_then_spins(float rect[4]; int limit; varying float X, Y; inout varying fixed<32,32> Z)
{
    flat(rect, 0.25, X, Y, Z);
    int n = 0;
    while (n < limit)
        n++;
    flat(rect, n / 16777216.0, X, Y, Z);
}
"#;

/// `W0801@line:col` of the loop (`while`) of `primitive`.
fn loop_site(primitive: &str) -> String {
    let lines: Vec<&str> = SOURCE.lines().collect();
    let start = lines
        .iter()
        .position(|l| l.starts_with(&format!("primitive {primitive}(")))
        .unwrap();
    let (n, line) = lines
        .iter()
        .enumerate()
        .skip(start)
        .find(|(_, l)| l.contains("while"))
        .unwrap();
    format!("W0801@{}:{}", n + 1, line.find("while").unwrap() + 1)
}

fn library(sources: &mut SourceMap) -> Arc<Program> {
    support::library_with(sources, &[("spin.prim", SOURCE)])
}

/// One instance of `prim` over the whole `w` x `h` image, with `params`.
fn scene(program: &Arc<Program>, prim: &str, w: u32, h: u32, params: &[(&str, f32)]) -> Renderer {
    let mut r = Renderer::new(program.clone());
    r.set_image_size(w, h).unwrap();
    r.begin(prim).unwrap();
    r.rast_param("rect", &Value(vec![0.0, 0.0, w as f32, h as f32]))
        .unwrap();
    for (name, v) in params {
        r.rast_param(name, &Value(vec![*v])).unwrap();
    }
    r.end().unwrap();
    r
}

fn render(r: &Renderer, tier: Tier, threads: usize) -> RenderOutput {
    let mut jit = Jit::at_tier(r.program().clone(), tier).unwrap();
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
    let out = pool.install(|| r.render(&mut jit));
    assert!(!out.diags.has_errors(), "{:?}", out.diags.items);
    out
}

/// Render `r` at both tiers, on 1 and 3 threads, in tiles of 8 and 64 pixels: every frame
/// and every report the same. The first render's output.
fn render_every_way(r: &mut Renderer, sources: &SourceMap) -> RenderOutput {
    let mut first: Option<(RenderOutput, String)> = None;
    for tier in [Tier::Fast, Tier::Optimised] {
        for (threads, tile) in [(1, 64), (3, 8), (3, 64)] {
            r.set_tile_size(tile).unwrap();
            let out = render(r, tier, threads);
            let report = out.diags.render(sources);
            match &first {
                None => first = Some((out, report)),
                Some((f, want)) => {
                    let case = format!("{tier:?}, {threads} threads, tile {tile}");
                    assert!(same_frame(&f.frame, &out.frame), "{case}: frames differ");
                    assert_eq!(&report, want, "{case}: reports differ");
                }
            }
        }
    }
    first.unwrap().0
}

/// The loop trips of every pixel, from `spin_pixels`' depth (`n / 2^24` is `n * 256` raw).
fn trips(frame: &Frame, w: u32, h: u32) -> Vec<u64> {
    (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .map(|(x, y)| {
            let d = frame.depth_at(x, y).unwrap();
            assert_eq!(d % 256, 0, "({x}, {y})");
            u64::from(d / 256)
        })
        .collect()
}

/// The fuel rule for a draw over `groups` pixel groups.
fn group_fuel(pixel_fuel: u64, floor: u64, groups: u64) -> u64 {
    floor.max(pixel_fuel / groups.max(1))
}

#[test]
fn an_endless_pixel_loop_gets_the_draws_fuel_over_its_groups_at_any_image_size() {
    let mut sources = SourceMap::new();
    let program = library(&mut sources);
    let (pixel_fuel, floor) = (1 << 16, 8);
    // (width, height): 512 groups (128 trips each), 8192 (8 each: the share meets the
    // floor), 32768 (the floor, 8, above the share of 2).
    for (w, h, want) in [(64u32, 32u32, 128u64), (256, 128, 8), (512, 256, 8)] {
        let mut r = scene(&program, "spin_pixels", w, h, &[]);
        r.options.pixel_fuel = pixel_fuel;
        r.options.group_fuel_floor = floor;
        let groups = u64::from(w / 4 * h);
        assert_eq!(group_fuel(pixel_fuel, floor, groups), want);
        let out = render_every_way(&mut r, &sources);
        let t = trips(&out.frame, w, h);
        assert!(t.iter().all(|&n| n == want), "{w}x{h}: trips {:?}", &t[..8]);
        // Trips of the whole draw: one group's are its four pixels'.
        let spent: u64 = t.iter().sum::<u64>() / 4;
        assert!(spent <= pixel_fuel.max(groups * floor), "{w}x{h}: {spent}");
        // Reported once, at the loop, with the groups that ran out.
        assert_eq!(out.diags.codes_at(&sources), [loop_site("spin_pixels")], "{w}x{h}");
        let message = &out.diags.items[0].message;
        assert!(
            message.contains(&format!("in {groups} pixel groups")),
            "{w}x{h}: {message}"
        );
    }
}

#[test]
fn with_the_default_budget_an_endless_pixel_loop_spends_the_same_at_512_and_1080p() {
    let mut sources = SourceMap::new();
    let program = library(&mut sources);
    for (w, h) in [(512u32, 512u32), (1920, 1080)] {
        let r = scene(&program, "spin_pixels", w, h, &[]);
        let groups = u64::from(w / 4 * h);
        let want = group_fuel(DEFAULT_PIXEL_FUEL, DEFAULT_GROUP_FUEL_FLOOR, groups);
        let out = render(&r, Tier::Optimised, 2);
        let t = trips(&out.frame, w, h);
        assert!(t.iter().all(|&n| n == want), "{w}x{h}: {want} trips a group");
        // 2^29 trips in all, less the remainder of the division.
        let spent = t.iter().sum::<u64>() / 4;
        assert!(
            spent <= DEFAULT_PIXEL_FUEL && spent > DEFAULT_PIXEL_FUEL - groups,
            "{w}x{h}: {spent}"
        );
        assert_eq!(out.diags.codes_at(&sources), [loop_site("spin_pixels")]);
    }
}

#[test]
fn a_setup_that_runs_out_of_fuel_is_run_once_and_drawn_nowhere() {
    let mut sources = SourceMap::new();
    let program = library(&mut sources);
    for (w, h) in [(64u32, 32u32), (512, 256)] {
        // 2e9 trips: far past the fuel.
        let mut r = scene(&program, "spin_setup", w, h, &[("limit", 2e9)]);
        r.options.setup_fuel = 1 << 20;
        let out = render_every_way(&mut r, &sources);
        assert!(out.frame.depth_values().iter().all(|&d| d == 0), "{w}x{h}: drawn");
        assert_eq!(out.stats.tile_invocations, 0, "{w}x{h}: run in a tile");
        assert_eq!(out.diags.codes_at(&sources), [loop_site("spin_setup")], "{w}x{h}");
        assert!(
            out.diags.items[0].message.contains("ran out of fuel in 1 draw"),
            "{}",
            out.diags.items[0].message
        );
        // Within the fuel (2^20 units: the head is visited limit + 1 times) it draws.
        for (limit, drawn) in [((1 << 20) - 1, true), (1 << 20, false)] {
            let mut r = scene(&program, "spin_setup", w, h, &[("limit", limit as f32)]);
            r.options.setup_fuel = 1 << 20;
            let out = render_every_way(&mut r, &sources);
            let want = if drawn { limit as u32 * 256 } else { 0 };
            assert!(
                out.frame.depth_values().iter().all(|&d| d == want),
                "{w}x{h} limit {limit}"
            );
            assert_eq!(out.diags.items.is_empty(), drawn, "{w}x{h} limit {limit}");
        }
    }
}

#[test]
fn a_caller_whose_setup_runs_out_draws_none_of_its_calls_expanded_or_not() {
    let mut sources = SourceMap::new();
    let program = library(&mut sources);
    let (w, h) = (48, 24);
    for expand in [true, false] {
        for (limit, drawn) in [(1000.0, true), (2e9, false)] {
            let mut r = scene(&program, "calls_then_spins", w, h, &[("limit", limit)]);
            r.options.expand_calls = expand;
            r.options.setup_fuel = 1 << 20;
            let out = render_every_way(&mut r, &sources);
            let want = if drawn { 1000 * 256 } else { 0 };
            assert!(
                out.frame.depth_values().iter().all(|&d| d == want),
                "expand {expand}, limit {limit}"
            );
            let codes = out.diags.codes_at(&sources);
            if drawn {
                assert!(codes.is_empty(), "{codes:?}");
            } else {
                assert_eq!(codes, [loop_site("calls_then_spins")], "expand {expand}");
                assert_eq!(out.stats.tile_invocations, 0, "expand {expand}");
            }
        }
    }
}

#[test]
fn a_callee_that_runs_out_ends_its_callers_run_and_is_the_one_reported() {
    let mut sources = SourceMap::new();
    let program = library(&mut sources);
    let (w, h) = (32, 16);
    let spinner = loop_site("spin_callee");
    // Expansion off: the caller's bound run calls the callee, which runs out; the caller's
    // own loop (10 trips) never runs, and nothing of the caller is drawn. Expanded: the
    // callee is a draw of its own, skipped; the caller's `flat` draws.
    for (expand, drawn) in [(false, None), (true, Some(10 * (1 << 27)))] {
        let mut r = scene(&program, "calls_a_spinner", w, h, &[("limit", 2e9), ("reps", 10.0)]);
        r.options.expand_calls = expand;
        r.options.setup_fuel = 1 << 20;
        let out = render_every_way(&mut r, &sources);
        assert_eq!(out.diags.codes_at(&sources), [spinner.as_str()], "expand {expand}");
        let want = drawn.unwrap_or(0u32);
        assert!(
            out.frame.depth_values().iter().all(|&d| d == want),
            "expand {expand}: {:?}",
            &out.frame.depth_values()[..4]
        );
        assert_eq!(out.stats.tile_invocations == 0, drawn.is_none(), "expand {expand}");
    }
}
