//! The tile grid and binning (src/runtime/render.rs): the grid cuts the padded frame into
//! disjoint group-aligned tiles, a bound goes to exactly the tiles holding a covered pixel
//! centre (against brute force), and the parallel binning's chunks give the serial counting
//! sort's list slot for slot.

use crate::support::render_options as opts;

use primflow::abi::{TileCtx, VariantKey, GROUP};
use primflow::ir::FuncId;
use primflow::runtime::expand::{Expanded, TileRect};
use primflow::runtime::frame::{row_stride, tile_side};
use primflow::runtime::render::{
    ceil_clamped, chunk_ranges, floor_clamped, tile_grid, tiles_overlapped, Bins, BIN_CHUNK_DRAWS,
};
use primflow::runtime::{Instance, RenderOptions};

#[test]
fn grid_cuts_edge_tiles() {
    let tiles = tile_grid(&opts(100, 70, 64));
    let rects: Vec<_> = tiles.iter().map(|t| (t.x0, t.y0, t.x1, t.y1)).collect();
    assert_eq!(
        rects,
        vec![(0, 0, 64, 64), (64, 0, 100, 64), (0, 64, 64, 70), (64, 64, 100, 70)]
    );
}

/// [`FrameTarget`]'s invariant: the tiles' rectangles (rows `y0..y1`, columns `x0 ..
/// x0 + group_columns()`) start on groups, lie inside the padded buffer and cover each
/// of its elements exactly once.
#[test]
fn tile_rectangles_cut_the_padded_frame_into_disjoint_groups() {
    for (w, h, requested) in [
        (100, 70, 64),
        (9, 7, 5),
        (64, 64, 64),
        (5, 3, 8),
        (37, 23, 16),
        (130, 67, 16),
        (1, 1, 1),
    ] {
        let o = opts(w, h, tile_side(requested));
        let stride = row_stride(w) as usize;
        let mut owners = vec![0u32; stride * h as usize];
        for tile in tile_grid(&o) {
            assert_eq!(tile.x0 % GROUP, 0, "{w}x{h}/{requested}");
            let cols = tile.group_columns() as usize;
            assert_eq!(cols % GROUP as usize, 0);
            for y in tile.y0 as usize..tile.y1 as usize {
                let at = y * stride + tile.x0 as usize;
                assert!(
                    at + cols <= owners.len(),
                    "{w}x{h}/{requested}: row {y} leaves the buffer"
                );
                // A group never straddles two rows.
                assert!(tile.x0 as usize + cols <= stride);
                owners[at..at + cols].iter_mut().for_each(|n| *n += 1);
            }
        }
        assert!(owners.iter().all(|&n| n == 1), "{w}x{h}/{requested}: {owners:?}");
    }
}

/// Against brute force: the tiles holding a pixel whose centre lies in the bound, for
/// bounds on, just off and between pixel centres and tile edges.
#[test]
fn binning_takes_exactly_the_tiles_with_a_covered_centre() {
    for (w, h, ts) in [(40, 24, 8), (37, 23, 12), (41, 19, 4)] {
        tiles_with_a_covered_centre(&opts(w, h, ts));
    }
}

fn tiles_with_a_covered_centre(o: &RenderOptions) {
    let ts = o.tile_size;
    let mut edges: Vec<f32> = (-2..=44)
        .flat_map(|i| {
            let x = i as f32;
            [x, x + 0.5, x + 0.5 - 1e-4, x + 0.5 + 1e-4, x + 0.25]
        })
        .collect();
    edges.extend([f32::NEG_INFINITY, -1e30, 1e30, f32::INFINITY]);
    let mut seed = 7u32;
    let mut pick = || {
        seed = seed.wrapping_mul(1664525).wrapping_add(1013904223);
        edges[(seed >> 8) as usize % edges.len()]
    };
    for _ in 0..20_000 {
        let b = [pick(), pick() * 0.6, pick(), pick() * 0.6];
        let mut want: Option<TileRect> = None;
        for py in 0..o.height {
            for px in 0..o.width {
                let (cx, cy) = (px as f32 + 0.5, py as f32 + 0.5);
                if cx >= b[0] && cx <= b[2] && cy >= b[1] && cy <= b[3] {
                    let (tx, ty) = ((px / ts) as usize, (py / ts) as usize);
                    want = Some(match want {
                        None => (tx, ty, tx, ty),
                        Some((a, b, c, d)) => (a.min(tx), b.min(ty), c.max(tx), d.max(ty)),
                    });
                }
            }
        }
        assert_eq!(tiles_overlapped(b, o), want, "bound {b:?} in {ts} px tiles");
    }
}

#[test]
fn clamped_floor_and_ceil_match_the_library_ones() {
    let mut values = vec![-0.0, 0.0, -2.5, -2.0, -1.5, -1.0, -0.5, -1e-9, 1e-9, 0.5, 16386.5];
    // Every quarter pixel, and values just around integers, over a clamped range.
    for i in -12..=65_560 {
        let x = f64::from(i) / 4.0;
        values.extend([x, x - 1e-7, x + 1e-7]);
    }
    for x in values {
        assert_eq!(floor_clamped(x), x.floor() as i64, "floor {x}");
        assert_eq!(ceil_clamped(x), x.ceil() as i64, "ceil {x}");
    }
}

/// Binning in parallel chunks gives the serial counting sort's list, slot for slot:
/// every tile's draws in submission order, whatever the chunks and threads.
#[test]
fn parallel_binning_matches_the_serial_order() {
    unsafe extern "C" fn kernel(_ctx: *mut TileCtx, _args: *const u32) {}
    let (tiles_x, tiles_y) = (5usize, 4usize);
    // 30 000 draws: rectangles of 1..=3 x 1..=2 tiles (some clipped to the grid), every
    // 7th without a tile, every 11th instance without a kernel.
    let mut seed = 12345u64;
    let mut next = |n: usize| {
        seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (seed >> 33) as usize % n
    };
    let instances: Vec<Instance> = (0..30_000u32)
        .map(|i| Instance {
            func: FuncId(0),
            key: VariantKey::default(),
            n_seq: 0,
            args: vec![i],
        })
        .collect();
    let expanded: Vec<Option<Expanded>> = (0..instances.len())
        .map(|i| {
            (i % 11 != 0).then(|| {
                let (x0, y0) = (next(tiles_x), next(tiles_y));
                let rect = (x0, y0, (x0 + next(3)).min(tiles_x - 1), (y0 + next(2)).min(tiles_y - 1));
                Expanded::Itself {
                    entry: kernel,
                    tiles: (i % 7 != 0).then_some(rect),
                    errors: Box::new([]),
                    over_budget: false,
                }
            })
        })
        .collect();
    let tiles = tiles_x * tiles_y;
    let key = |b: &Bins<'_>| {
        let draws: Vec<u32> = b.draws.iter().map(|d| d.args[0]).collect();
        (b.start.clone(), draws)
    };
    let total: usize = expanded.iter().flatten().map(Expanded::len).sum();
    let (serial, _) = Bins::new(&expanded, &instances, tiles, tiles_x, &[0..instances.len()], None);
    let want = key(&serial);
    // Every tile's list is in instance order (each instance's block holds its number).
    for t in 0..tiles {
        let list = &want.1[want.0[t]..want.0[t + 1]];
        assert!(list.windows(2).all(|w| w[0] < w[1]), "tile {t}");
    }
    assert!(want.1.len() > 30_000, "draws span several tiles");
    let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
    for chunks in [2, 3, 5, 6] {
        let ranges = chunk_ranges(&expanded, total, chunks, tiles);
        assert!(ranges.len() == chunks, "{chunks} chunks used");
        let (parallel, _) = pool.install(|| Bins::new(&expanded, &instances, tiles, tiles_x, &ranges, None));
        assert!(key(&parallel) == want, "{chunks} chunks");
    }
}

#[test]
fn chunk_ranges_cover_every_instance_in_order() {
    unsafe extern "C" fn kernel(_ctx: *mut TileCtx, _args: *const u32) {}
    let itself = || Expanded::Itself {
        entry: kernel,
        tiles: None,
        errors: Box::new([]),
        over_budget: false,
    };
    // (instances, chunks asked for, tiles, ranges): 4/5 of the instances have a draw.
    for (n, chunks, tiles, want) in [
        (0, 4, 64, 1),
        (10, 4, 64, 1),
        (5 * BIN_CHUNK_DRAWS, 8, 64, 4),
        (20_000, 2, 64, 2),
        // Far more tiles than draws: one range, not per-tile arrays per chunk.
        (100_000, 8, 1 << 24, 1),
        (100_000, 8, 30_000, 2),
    ] {
        let expanded: Vec<Option<Expanded>> = (0..n).map(|i| (i % 5 != 0).then(itself)).collect();
        let total: usize = expanded.iter().flatten().map(Expanded::len).sum();
        let ranges = chunk_ranges(&expanded, total, chunks, tiles);
        assert_eq!(ranges.len(), want, "{n} instances, {chunks} chunks, {tiles} tiles");
        assert_eq!(ranges.first().map(|r| r.start), Some(0));
        assert_eq!(ranges.last().map(|r| r.end), Some(n));
        assert!(ranges
            .windows(2)
            .all(|w| w[0].end == w[1].start && w[0].start < w[0].end));
    }
}

#[test]
fn binning_is_conservative_and_clamped() {
    let o = opts(256, 128, 64);
    assert_eq!(tiles_overlapped([10.0, 10.0, 20.0, 20.0], &o), Some((0, 0, 0, 0)));
    // Pixel 64's centre is 64.5: a bound ending at 64 holds no pixel of tile 1, one
    // ending at 64.5 does (and one starting at 63.5 holds pixel 63 of tile 0).
    assert_eq!(tiles_overlapped([10.0, 10.0, 64.0, 20.0], &o), Some((0, 0, 0, 0)));
    assert_eq!(tiles_overlapped([10.0, 10.0, 64.5, 20.0], &o), Some((0, 0, 1, 0)));
    assert_eq!(tiles_overlapped([63.5, 10.0, 70.0, 20.0], &o), Some((0, 0, 1, 0)));
    assert_eq!(tiles_overlapped([63.51, 10.0, 70.0, 20.0], &o), Some((1, 0, 1, 0)));
    // A bound between two centres holds no pixel.
    assert_eq!(tiles_overlapped([10.6, 10.0, 11.4, 20.0], &o), None);
    assert_eq!(
        tiles_overlapped([f32::NEG_INFINITY, -1e30, f32::INFINITY, 1e30], &o),
        Some((0, 0, 3, 1))
    );
    assert_eq!(tiles_overlapped([f32::NAN, 0.0, 10.0, 10.0], &o), None);
    assert_eq!(tiles_overlapped([300.0, 0.0, 400.0, 10.0], &o), None);
    assert_eq!(tiles_overlapped([-50.0, -50.0, -10.0, -10.0], &o), None);
    // Inverted (empty) bound.
    assert_eq!(tiles_overlapped([50.0, 50.0, 10.0, 10.0], &o), None);
}
