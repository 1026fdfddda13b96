//! Tier 0 compiles a kernel's pixel loops as a function of their own, which the kernel
//! calls (src/jit/lower/outline.rs). What crosses that call must be what one function
//! would have: the fuel (the setup's stays in `ctx.fuel`; every pixel group gets its share
//! of the pixel fuel, which the pixel function computes into `ctx.group_fuel`), the
//! run-time errors the loops record and count, and every pixel. Tier 1 compiles one
//! function; each case runs both and compares.

#![allow(clippy::needless_range_loop)]

use std::sync::Arc;

use crate::support::jit::*;
use crate::support::raw_depth;
use primflow::abi::{ErrorSlot, TileCtx, ERR_FUEL, ERR_NONE, MODE_RENDER};
use primflow::ir::Variability::Varying;
use primflow::ir::*;
use primflow::jit::{Jit, Tier};

/// `int i = 0; while (i < X) i = i + 1; Z = float(i) / 32;` (loop site 0), or with no
/// body when `endless` (`while (X > 0) {}`: never ends).
fn counting(endless: bool) -> Function {
    let mut fb = Fb::new("count", FuncKind::Primitive);
    let (x, _y, z) = fb.xyz();
    let i = fb.local("i", Type::int(), Varying);
    let l = fb.new_loop();
    fb.pixel = if endless {
        vec![while_(l, bin(BinOp::Gt, x, fc(0.0)), vec![], 0), assign(&z, fc(0.25))]
    } else {
        vec![
            assign(&i, ic(0)),
            while_(
                l,
                bin(BinOp::Lt, conv(i.clone(), Scalar::Float), x),
                vec![assign(&i, bin(BinOp::Add, i.clone(), ic(1)))],
                0,
            ),
            assign(&z, bin(BinOp::Div, conv(i, Scalar::Float), fc(32.0))),
        ]
    };
    fb.finish()
}

/// The setup fuel of the runs (the setups here have no loops: it stays).
const SETUP_FUEL: u64 = 100_000;

/// Groups of the runs' bound rectangle: no `bound`, so the 64x32 viewport's.
const GROUPS: u64 = 64 / 4 * 32;

/// Run `f`'s kernel over the 16x8 tile at the origin with `group_fuel` loop trips a pixel
/// group (`pixel_fuel` of that many per group of the viewport, floor 1) at tier 0 and tier
/// 1: each tier's context afterwards and tile.
fn both_tiers(f: Function, group_fuel: u64) -> Vec<(TileCtx, Tile)> {
    let program = Arc::new(program(vec![f], 1));
    [Tier::Fast, Tier::Optimised]
        .into_iter()
        .map(|tier| {
            let mut jit = Jit::at_tier(program.clone(), tier).unwrap();
            let k = jit.kernel(FuncId(0), &kind_key(&[])).unwrap();
            let mut tile = Tile::new(0);
            tile.pixel_fuel = group_fuel * GROUPS;
            tile.group_fuel_floor = 1;
            let ctx = tile.run(&k, &[1], MODE_RENDER, SETUP_FUEL);
            (ctx, tile)
        })
        .collect()
}

#[test]
fn the_pixel_function_is_tier_0s_only() {
    let program = Arc::new(program(vec![counting(false)], 1));
    let clif = |tier| {
        let jit = Jit::at_tier(program.clone(), tier).unwrap();
        jit.clif(FuncId(0), &kind_key(&[])).unwrap()
    };
    let functions = |text: &str| text.lines().filter(|l| l.starts_with("function ")).count();
    let tier0 = clif(Tier::Fast);
    assert_eq!(functions(&tier0), 2, "{tier0}");
    // The kernel calls the pixel function; the loop is in the pixel function only.
    let (kernel, pixels) = tier0.split_at(tier0.rfind("function ").unwrap());
    assert!(kernel.contains("call fn"), "{kernel}");
    assert!(pixels.starts_with("function u0:2000000(i64, i64, i64, f32, f32, f32, f32)"));
    assert!(!kernel.contains("fcvt_from_sint.f32x4"), "{kernel}");
    assert!(pixels.contains("fcvt_from_sint.f32x4"), "{pixels}");
    assert_eq!(functions(&clif(Tier::Optimised)), 1);
}

#[test]
fn the_pixel_function_gives_every_group_its_share_of_the_pixel_fuel() {
    let runs = both_tiers(counting(false), 100);
    for (tier, (ctx, tile)) in runs.iter().enumerate() {
        assert_eq!(ctx.error, ERR_NONE, "tier {tier}");
        assert_eq!(ctx.group_fuel, 100, "tier {tier}");
        // The pixel loops spend their groups' fuel, not the setup's.
        assert_eq!(ctx.fuel, SETUP_FUEL, "tier {tier}");
        for y in 0..8 {
            for x in 0..16 {
                // i stops at the first integer >= x + 0.5, i.e. x + 1 (the last group's
                // loop head is visited 17 times, well within its 100).
                assert_eq!(
                    tile.depth_at(x, y),
                    raw_depth((x + 1) as f64 / 32.0),
                    "tier {tier} ({x}, {y})"
                );
            }
        }
    }
    assert_eq!(runs[0].1.depth, runs[1].1.depth);
}

#[test]
fn running_out_of_fuel_in_the_pixel_function_is_the_kernels_error() {
    let runs = both_tiers(counting(true), 10);
    for (tier, (ctx, tile)) in runs.iter().enumerate() {
        assert_eq!(ctx.error, ERR_FUEL, "tier {tier}");
        assert_eq!(ctx.error_site, 0, "tier {tier}");
        assert_eq!(ctx.fuel, SETUP_FUEL, "tier {tier}");
        // Counted once in each of the tile's 4 x 8 groups (each ran out once).
        assert_eq!(tile.error_count(ErrorSlot::Fuel(SiteId(0)), 1), 32, "tier {tier}");
        // The loop is left; the statement after it still runs.
        assert_eq!(tile.depth_at(15, 7), raw_depth(0.25), "tier {tier}");
    }
    assert_eq!(runs[0].1.depth, runs[1].1.depth);
}
