//! Copy forwarding (src/ir/forward.rs): `d = s` of whole arrays becomes reads of `s` only
//! where no read of `d` could see a changed `s`. A copy whose source changes before the copy
//! is read must stay a copy; the inlined helpers' by-value array parameters (the NURB
//! surface's `points`, `knots`) must go.

use crate::support;

use std::sync::Arc;

use primflow::diag::{Diagnostics, SourceMap};
use primflow::ir::forward::forward_copies;
use primflow::ir::{ExprKind, Program, StmtId, StmtKind};
use primflow::jit::{Jit, Tier};
use primflow::runtime::{Registry, Renderer, Value};

const COPIES: &str = r#"
primitive copies(float rect[4]; int n; varying float X, Y; inout varying fixed<32,32> Z)
{
    bound(rect[0], rect[1], rect[2], rect[3]);
    float s[4] = {0.0625, 0.125, 0.1875, 0.25};
    float d[4] = s;
    s[0] = 0.5;
    float e[4] = s;
    float acc = d[n] + e[n];
    float cur[4] = s;
    for (int i = 0; i < n + 2; i++) {
        float prev[4] = cur;
        cur[i] = cur[i] * 2;
        acc = acc + prev[i];
    }
    float untouched[4] = cur;
    float total = acc + untouched[n];
    Z = total / 8;
}
"#;

/// What the language says `copies` computes for `n` (0 <= n <= 2).
fn expected(n: usize) -> f32 {
    let mut s = [0.0625f32, 0.125, 0.1875, 0.25];
    let d = s;
    s[0] = 0.5;
    let e = s;
    let mut acc = d[n] + e[n];
    let mut cur = s;
    for i in 0..n + 2 {
        let prev = cur;
        cur[i] *= 2.0;
        acc += prev[i];
    }
    (acc + cur[n]) / 8.0
}

fn library(sources: &mut SourceMap) -> Arc<Program> {
    let flat = "primitive flat(float rect[4]; float z; varying float X, Y; inout varying fixed<32,32> Z)\n\
                { bound(rect[0], rect[1], rect[2], rect[3]); Z = z; }\n";
    support::library_with(sources, &[("copies.prim", COPIES), ("flat.prim", flat)])
}

fn depth(program: &Arc<Program>, prim: &str, param: (&str, f32), tier: Tier) -> u32 {
    let mut r = Renderer::new(program.clone());
    r.set_image_size(16, 16).unwrap();
    r.begin(prim).unwrap();
    r.rast_param("rect", &Value(vec![1.0, 1.0, 15.0, 15.0])).unwrap();
    r.rast_param(param.0, &Value(vec![param.1])).unwrap();
    r.end().unwrap();
    let mut jit = Jit::at_tier(program.clone(), tier).unwrap();
    let out = r.render(&mut jit);
    assert!(
        !out.diags.has_errors() && out.diags.items.is_empty(),
        "{:?}",
        out.diags.items
    );
    out.frame.depth_at(8, 8).unwrap()
}

#[test]
fn copies_whose_source_changes_keep_the_old_value() {
    let mut sources = SourceMap::new();
    let program = library(&mut sources);
    for n in 0..=2 {
        for tier in [Tier::Fast, Tier::Optimised] {
            let got = depth(&program, "copies", ("n", n as f32), tier);
            let want = depth(&program, "flat", ("z", expected(n)), tier);
            assert_ne!(want, 0);
            assert_eq!(got, want, "n={n} {tier:?}");
        }
    }
    // `d` and `prev` are read after their source changed, and `cur` is assigned again:
    // they stay copies. `e` and `untouched` are read (in setup, the list of their copy)
    // before their source changes: forwarded.
    let f = program.func(program.find("copies").unwrap());
    let names = |f: &primflow::ir::Function| {
        let mut out = vec![];
        whole_array_copies(f, &f.setup, &mut out);
        out
    };
    assert_eq!(names(f), ["d", "e", "cur", "prev", "untouched"]);
    assert_eq!(names(&forward_copies(f)), ["d", "cur", "prev"]);
}

#[test]
fn inlined_array_parameters_of_the_nurb_surface_are_forwarded() {
    let mut sources = SourceMap::new();
    let mut diags = Diagnostics::new();
    let program = Registry::load(&mut sources, &[], &[], &mut diags).unwrap().program;
    let f = program.func(program.find("nurb_surface").unwrap());
    let mut before = vec![];
    whole_array_copies(f, &f.setup, &mut before);
    let forwarded = forward_copies(f);
    let mut after = vec![];
    whole_array_copies(&forwarded, &forwarded.setup, &mut after);
    let count = |v: &[String], name: &str| v.iter().filter(|n| *n == name).count();
    assert!(
        count(&before, "points") >= 3 && count(&before, "knots") >= 6,
        "{before:?}"
    );
    assert_eq!((count(&after, "points"), count(&after, "knots")), (0, 0), "{after:?}");
}

/// Names of the locals assigned a whole other local in `list` (nested lists included).
fn whole_array_copies(f: &primflow::ir::Function, list: &[StmtId], out: &mut Vec<String>) {
    for &s in list {
        match &f.stmts[s] {
            StmtKind::Assign { place, value } => {
                let local = f.local(place.local);
                if place.indices.is_empty()
                    && !local.ty.dims.is_empty()
                    && matches!(f.exprs[*value].kind, ExprKind::Local(_))
                {
                    out.push(local.name.clone());
                }
            }
            StmtKind::If { then, otherwise, .. } => {
                whole_array_copies(f, then, out);
                whole_array_copies(f, otherwise, out);
            }
            StmtKind::Loop { body, step, .. } => {
                whole_array_copies(f, body, out);
                whole_array_copies(f, step, out);
            }
            _ => {}
        }
    }
}
