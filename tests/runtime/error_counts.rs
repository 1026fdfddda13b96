//! Every run-time error site is reported, once, with the number of times it failed
//! (`runtime::errors`): pixel code counts once per pixel group and access, setup code once
//! per draw. The counts, like the frame, are the same for any number of threads, any tile
//! size and either tier.

use crate::support;

use std::sync::Arc;

use primflow::diag::SourceMap;
use primflow::ir::Program;
use primflow::jit::{Jit, Tier};
use primflow::runtime::{RenderOutput, Renderer, Value};
use primflow::workload::same_frame;

const SOURCE: &str = r#"
primitive three_errors(float rect[4]; varying float X, Y; inout varying fixed<32,32> Z)
{
    bound(rect[0], rect[1], rect[2], rect[3]);
    float a[4] = {0.125, 0.25, 0.375, 0.5};
    int i = int(X);
    int j = int(Y);
    float s = a[i - 8];
    float t = a[j - 2];
    int n = 0;
    while (X > 20)
        n++;
    Z = (s + t) / 4;
}

primitive setup_error(float rect[4]; int k; varying float X, Y; inout varying fixed<32,32> Z)
{
    bound(rect[0], rect[1], rect[2], rect[3]);
    float a[4] = {0.125, 0.25, 0.375, 0.5};
    float s = a[k];
    Z = s;
}
"#;

/// `W0801@line:col` of the first `text` on a line of `primitive` (column of `text`).
fn site(primitive: &str, text: &str) -> String {
    let lines: Vec<&str> = SOURCE.lines().collect();
    let start = lines
        .iter()
        .position(|l| l.starts_with(&format!("primitive {primitive}(")))
        .unwrap();
    let (n, line) = lines
        .iter()
        .enumerate()
        .skip(start)
        .find(|(_, l)| l.contains(text))
        .unwrap();
    format!("W0801@{}:{}", n + 1, line.find(text).unwrap() + 1)
}

fn library(sources: &mut SourceMap) -> Arc<Program> {
    support::library_with(sources, &[("errors.prim", SOURCE)])
}

/// Render `r` at both tiers, on 1 and 3 threads, in tiles of 8, 16 and 64 pixels: the same
/// frame and the same report every time; the first render's output.
fn render_every_way(r: &mut Renderer, sources: &SourceMap) -> RenderOutput {
    let mut first: Option<(RenderOutput, String)> = None;
    for tier in [Tier::Fast, Tier::Optimised] {
        for (threads, tile) in [(1, 64), (3, 8), (2, 16)] {
            r.set_tile_size(tile).unwrap();
            let mut jit = Jit::at_tier(r.program().clone(), tier).unwrap();
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            let out = pool.install(|| r.render(&mut jit));
            assert!(!out.diags.has_errors(), "{:?}", out.diags.items);
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

#[test]
fn two_index_sites_and_a_loop_out_of_fuel_are_three_counted_warnings() {
    let mut sources = SourceMap::new();
    let program = library(&mut sources);
    let (w, h) = (32u32, 16u32);
    let mut r = Renderer::new(program.clone());
    r.set_image_size(w, h).unwrap();
    r.options.pixel_fuel = 1 << 12;
    r.options.group_fuel_floor = 4;
    r.begin("three_errors").unwrap();
    r.rast_param("rect", &Value(vec![0.0, 0.0, w as f32, h as f32]))
        .unwrap();
    r.end().unwrap();
    let out = render_every_way(&mut r, &sources);

    // Reference counts from the pixels: a group is four pixels of a row, columns 4g..4g+3;
    // an access counts once for a group where it fails in some pixel.
    let groups = |fails: &dyn Fn(u32, u32) -> bool| -> u64 {
        let mut n = 0;
        for y in 0..h {
            for g in 0..w / 4 {
                n += u64::from((0..4).any(|l| fails(4 * g + l, y)));
            }
        }
        n
    };
    // a[i - 8] with i the column: in range for columns 8..11 only.
    let by_column = groups(&|x, _| !(8..12).contains(&x));
    // a[j - 2] with j the row: in range for rows 2..5 only.
    let by_row = groups(&|_, y| !(2..6).contains(&y));
    // `while (X > 20)` never ends for the pixels right of column 20.
    let endless = groups(&|x, _| x as f32 + 0.5 > 20.0);
    assert_eq!((by_column, by_row, endless), (112, 96, 48));

    let codes = out.diags.codes_at(&sources);
    assert_eq!(
        codes,
        [
            site("three_errors", "i - 8"),
            site("three_errors", "j - 2"),
            site("three_errors", "while")
        ]
    );
    let messages: Vec<&str> = out.diags.items.iter().map(|d| d.message.as_str()).collect();
    assert!(
        messages[0].contains(&format!("out of range (clamped) {by_column} times")),
        "{messages:?}"
    );
    assert!(
        messages[1].contains(&format!("out of range (clamped) {by_row} times")),
        "{messages:?}"
    );
    assert!(
        messages[2].contains(&format!("ran out of fuel (left early) in {endless} pixel groups")),
        "{messages:?}"
    );
    assert!(
        messages.iter().all(|m| m.starts_with("in `three_errors` at run time")),
        "{messages:?}"
    );

    // The pixels read the clamped elements.
    let a = [0.125f64, 0.25, 0.375, 0.5];
    for y in 0..h {
        for x in 0..w {
            let s = a[(x as i64 - 8).clamp(0, 3) as usize];
            let t = a[(y as i64 - 2).clamp(0, 3) as usize];
            let want = ((s + t) / 4.0 * 4294967296.0) as u32;
            assert_eq!(out.frame.depth_at(x, y), Some(want), "({x}, {y})");
        }
    }
}

#[test]
fn a_setup_error_counts_once_per_draw_whatever_the_tiles_it_spans() {
    let mut sources = SourceMap::new();
    let program = library(&mut sources);
    let mut r = Renderer::new(program.clone());
    r.set_image_size(40, 24).unwrap();
    // Two instances across several tiles (in 8-pixel tiles, 15 and 4), one in range.
    for (rect, k) in [
        ([0.0, 0.0, 40.0, 24.0], 7.0),
        ([4.0, 4.0, 12.0, 12.0], -2.0),
        ([0.0, 0.0, 8.0, 8.0], 1.0),
    ] {
        r.begin("setup_error").unwrap();
        r.rast_param("rect", &Value(rect.to_vec())).unwrap();
        r.rast_param("k", &Value(vec![k])).unwrap();
        r.end().unwrap();
    }
    let out = render_every_way(&mut r, &sources);
    assert_eq!(out.diags.codes_at(&sources), [site("setup_error", "k]")]);
    let message = &out.diags.items[0].message;
    assert!(message.contains("out of range (clamped) 2 times"), "{message}");
}
