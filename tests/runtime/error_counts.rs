//! Every run-time error site is reported, once, with the number of times it failed
//! (`runtime::errors`): setup code counts once per draw. The counts, like the frame, are
//! the same for any number of threads, any tile size and either tier.

use crate::common;

use std::sync::Arc;

use primflow::bench::same_frame;
use primflow::diag::SourceMap;
use primflow::ir::Program;
use primflow::jit::{Jit, Tier};
use primflow::runtime::{RenderOutput, Renderer, Value};

const SOURCE: &str = r#"
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
    common::library_with(sources, &[("errors.prim", SOURCE)])
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
