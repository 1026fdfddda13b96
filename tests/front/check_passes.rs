//! The checker's analyses, tested from source text: the variability fixpoint, helper
//! inlining, fixed-point result formats, and the setup/pixel split.

use primflow::diag::{Diagnostics, SourceMap};
use primflow::ir::{
    Elem, ExprKind, FixedFormat, FuncKind, Function, LocalKind, Program, Scalar, StmtId, StmtKind, Variability,
};

fn compile(src: &str) -> (Option<Program>, Diagnostics, SourceMap) {
    let mut sources = SourceMap::new();
    let id = sources.add("test.prim", src);
    let mut diags = Diagnostics::new();
    let program = primflow::compile(&sources, &[id], &mut diags);
    (program, diags, sources)
}

fn ok(src: &str) -> Program {
    let (p, d, s) = compile(src);
    p.unwrap_or_else(|| panic!("expected no errors:\n{}", d.render(&s)))
}

fn func<'p>(p: &'p Program, name: &str) -> &'p Function {
    p.func(p.find(name).unwrap_or_else(|| panic!("no function {name}")))
}

fn var_of(f: &Function, name: &str) -> Variability {
    f.locals
        .iter()
        .find(|l| l.name == name && l.kind == LocalKind::Var)
        .unwrap_or_else(|| panic!("no local {name}"))
        .var
}

/// Names of the locals assigned by top-level statements (`-` for other statements).
fn assigned(f: &Function, stmts: &[StmtId]) -> Vec<String> {
    stmts
        .iter()
        .map(|&s| match &f.stmts[s] {
            StmtKind::Assign { place, .. } => f.local(place.local).name.clone(),
            StmtKind::If { .. } => "if".into(),
            StmtKind::Loop { .. } => "loop".into(),
            StmtKind::Return => "return".into(),
            StmtKind::Bound(_) => "bound".into(),
            StmtKind::Interpolation { .. } => "interpolation".into(),
            StmtKind::InterpolatorReturn(_) => "interpolator_return".into(),
            StmtKind::CallPrimitive { .. } => "call".into(),
            StmtKind::Break(_) | StmtKind::Continue(_) => "jump".into(),
        })
        .collect()
}

const HEAD: &str = "primitive p(float k; varying float X, Y; inout varying float Z)\n";

#[test]
fn back_edge_makes_a_variable_varying_before_its_varying_assignment() {
    // `a` reads `b` before `b` is assigned X in the same iteration: only the second trip
    // round the loop carries the varying value, so one forward walk is not enough.
    let p = ok(&format!(
        "{HEAD}{{ float a = 0, b = 0, c = 0;
            for (int i = 0; i < 3; i++) {{ c = a; a = b; b = X; }}
            float u = k * 2; }}"
    ));
    let f = func(&p, "p");
    assert_eq!(var_of(f, "b"), Variability::Varying);
    assert_eq!(var_of(f, "a"), Variability::Varying);
    assert_eq!(var_of(f, "c"), Variability::Varying);
    assert_eq!(var_of(f, "i"), Variability::Uniform);
    assert_eq!(var_of(f, "u"), Variability::Uniform);
}

#[test]
fn back_edge_into_a_uniform_variable_is_reported_with_the_cause() {
    let (_, d, s) = compile(&format!(
        "{HEAD}{{ uniform float a = 0; float b = 0;
  for (int i = 0; i < 3; i++) {{ a = b; b = X; }} }}"
    ));
    assert_eq!(d.codes_at(&s), ["E0301@3:33"]);
    let labels: Vec<&str> = d.items[0].labels.iter().map(|l| l.message.as_str()).collect();
    assert_eq!(
        labels,
        [
            "assigned here",
            "declared uniform here",
            "varying because of this",
            "which is varying because of this"
        ]
    );
}

#[test]
fn varying_break_makes_the_loop_and_its_assignments_varying() {
    let p = ok(&format!(
        "{HEAD}{{ int n = 0; while (n < 10) {{ if (X < n) break; n += 1; }} }}"
    ));
    let f = func(&p, "p");
    assert_eq!(var_of(f, "n"), Variability::Varying);
    let varying_loops: Vec<bool> = f
        .setup
        .iter()
        .chain(&f.pixel)
        .filter_map(|&s| match f.stmts[s] {
            StmtKind::Loop { varying, .. } => Some(varying),
            _ => None,
        })
        .collect();
    assert_eq!(varying_loops, [true]);
}

#[test]
fn code_after_a_varying_return_stays_uniform() {
    // The paper's screen_triangle computes plane equations after its edge tests.
    let p = ok(&format!(
        "{HEAD}{{ if (X > k) return; float plane = k * 3; Z = plane; }}"
    ));
    let f = func(&p, "p");
    assert_eq!(var_of(f, "plane"), Variability::Uniform);
    // ...and is hoisted into setup, since the edge test does not touch it.
    assert_eq!(assigned(f, &f.setup), ["plane"]);
    assert_eq!(assigned(f, &f.pixel), ["if", "Z"]);
}

#[test]
fn assignments_under_a_varying_if_make_a_variable_varying() {
    let p = ok(&format!("{HEAD}{{ float s = 1; if (Y > 2) s = 2; Z = s; }}"));
    assert_eq!(var_of(func(&p, "p"), "s"), Variability::Varying);
}

#[test]
fn fixed_operands_join_and_ints_and_floats_mix() {
    let p = ok("primitive p(varying fixed<32,16> X, Y; inout varying fixed<32,32> Z)
        { float f = 1; int i = 2;
          fixed<32,16> xz = X * Z; fixed<32,16> x2 = X + Y; float xf = X * f; fixed<32,0> xi = X * i; }");
    let f = func(&p, "p");
    let value_ty = |name: &str| {
        f.pixel
            .iter()
            .chain(&f.setup)
            .find_map(|&s| match &f.stmts[s] {
                StmtKind::Assign { place, value } if f.local(place.local).name == name => Some(f.exprs[*value].ty.elem),
                _ => None,
            })
            .expect("assignment")
    };
    let fx = |bits, frac| Elem::Scalar(Scalar::Fixed(FixedFormat { bits, frac }));
    assert_eq!(value_ty("xz"), fx(32, 16));
    assert_eq!(value_ty("x2"), fx(32, 16));
    assert_eq!(value_ty("xf"), Elem::Scalar(Scalar::Float));
    // An int operand counts as fixed<32,0>: all 32 bits go to the integer part.
    assert_eq!(value_ty("xi"), fx(32, 0));
}

#[test]
fn helpers_are_inlined_as_one_trip_loops() {
    let p = ok(&format!(
        "float twice(float v) {{ return v * 2; }}
         {HEAD}{{ float a = twice(k); }}"
    ));
    let f = func(&p, "p");
    assert_eq!(f.kind, FuncKind::Primitive);
    // v = k; loop { twice_result = v * 2; break } ; a = twice_result
    assert_eq!(assigned(f, &f.setup), ["v", "loop", "a"]);
    let StmtKind::Loop { id, cond, body, .. } = &f.stmts[f.setup[1]] else {
        panic!("loop expected")
    };
    assert!(cond.is_none());
    assert!(matches!(body.last().map(|&s| &f.stmts[s]), Some(StmtKind::Break(l)) if l == id));
    let StmtKind::Assign { value, .. } = &f.stmts[f.setup[2]] else {
        panic!()
    };
    let ExprKind::Local(result) = f.exprs[*value].kind else {
        panic!("the call is a local")
    };
    assert_eq!(f.local(result).kind, LocalKind::Temp);
    assert_eq!(f.local(result).name, "twice_result");
}

#[test]
fn inout_helper_parameters_write_back() {
    let p = ok(&format!(
        "void bump(inout float x) {{ x += 1; }}
         {HEAD}{{ float a[2] = {{0, 0}}; bump(a[1]); }}"
    ));
    let f = func(&p, "p");
    assert_eq!(assigned(f, &f.setup), ["a", "x", "loop", "a"]);
}

#[test]
fn a_whole_variable_is_its_inout_parameter_unless_copies_are_needed() {
    let p = ok(&format!(
        "void fill(inout float a[4]; float x) {{ a[1] = x; }}
         void swap(inout float a[4]; inout float b[4]) {{ float t[4] = a; a = b; b = t; }}
         void pin(inout uniform float a[4]) {{ a[0] = 1; }}
         {HEAD}{{ float v[4], w[4]; uniform float u[4];
                  fill(v, 2); fill(v, v[0]); swap(v, w); swap(v, v); pin(v); fill(u, 3); }}"
    ));
    let f = func(&p, "p");
    assert_eq!(
        assigned(f, &f.setup),
        [
            "v", "w", "u", // declarations
            "x", "loop", // fill(v, 2): v is the parameter, only x is copied
            "a", "x", "loop", "v",    // fill(v, v[0]): another argument reads v
            "loop", // swap(v, w): both are the parameters
            "a", "b", "loop", "v", "v", // swap(v, v): one variable twice
            "a", "loop", "v", // pin(v): the parameter declares its variability
            "a", "x", "loop", "u", // fill(u, 3): the variable does
        ]
    );
}

const TRIANGLE_LIKE: &str = "
primitive tri(float v[3][3]; interpolation_data d[3]; varying float X, Y; inout varying float Z)
{
    float ea[3], eb[3], ec[3];
    for (int i = 0; i < 3; i++) {
        int j = (i + 1) % 3;
        ea[i] = v[i][1] - v[j][1];
        eb[i] = v[j][0] - v[i][0];
        ec[i] = v[i][0] * v[j][1] - v[j][0] * v[i][1];
    }
    if (ea[0] * X + eb[0] * Y + ec[0] < 0) return;
    if (ea[1] * X + eb[1] * Y + ec[1] < 0) return;
    if (ea[2] * X + eb[2] * Y + ec[2] < 0) return;
    float za = v[0][2], zb = 0, zc = 0;
    float z = za * X + zb * Y + zc;
    if (z < Z) return;
    Z = z;
    bound(min(v[0][0], v[1][0]), min(v[0][1], v[1][1]), max(v[0][0], v[1][0]), max(v[0][1], v[1][1]));
    interpolation {
        linear: interpolator_return(d[0] + d[1] * X);
        default: interpolator_return;
    }
}";

#[test]
fn screen_triangle_like_body_splits_into_plane_setup_and_pixel_tests() {
    let p = ok(TRIANGLE_LIKE);
    let f = func(&p, "tri");
    assert_eq!(
        assigned(f, &f.setup),
        ["ea", "eb", "ec", "i", "loop", "za", "zb", "zc", "bound"]
    );
    assert_eq!(
        assigned(f, &f.pixel),
        ["if", "if", "if", "z", "if", "Z", "interpolation"]
    );
    assert!(f
        .setup
        .iter()
        .all(|&s| !matches!(f.stmts[s], StmtKind::InterpolatorReturn(_))));
}

#[test]
fn hoisting_is_refused_when_it_would_change_meaning() {
    let p = ok(&format!(
        "{HEAD}{{ float e = 1;
            if (X > e) return;   // first pixel statement; reads e
            e = 2;               // writes what it read: stays
            float g = e * 2;     // reads e written in pixel: stays
            float h = k + 1;     // independent: hoisted
            if (k > 0) return;   // a uniform return: nothing after it moves
            float late = k;
        }}"
    ));
    let f = func(&p, "p");
    assert_eq!(assigned(f, &f.setup), ["e", "h"]);
    assert_eq!(assigned(f, &f.pixel), ["if", "e", "g", "if", "late"]);
}

#[test]
fn interpolators_run_entirely_per_pixel() {
    let p = ok(
        "interpolator ramp(float s = 1; varying float X, Y; inout varying float Z)
                { float k = s * 2; interpolator_return(k * X); }",
    );
    let f = func(&p, "ramp");
    assert_eq!(f.kind, FuncKind::Interpolator);
    assert!(f.setup.is_empty());
    assert_eq!(assigned(f, &f.pixel), ["k", "interpolator_return"]);
}

#[test]
fn primitive_call_passes_pixel_parameters_and_fills_defaults() {
    let p = ok(
        "primitive leaf(float size; float scale = 3; varying float X, Y; inout varying float Z) { }
                primitive root(varying float X, Y; inout varying float Z) { leaf(2, 4, X, Y, Z); }
                primitive short(float s; varying float X, Y; inout varying float Z) { }",
    );
    let f = func(&p, "root");
    let StmtKind::CallPrimitive { callee, args, .. } = &f.stmts[f.setup[0]] else {
        panic!("call in setup")
    };
    assert_eq!(p.func(*callee).name, "leaf");
    assert_eq!(args.len(), 5);
    assert!(f.pixel.is_empty());
}

#[test]
fn varying_argument_for_a_uniform_helper_parameter_is_reported_at_the_call() {
    let (_, d, s) = compile(&format!(
        "float scale(uniform float factor; float v) {{ return factor * v; }}
{HEAD}{{ float a = scale(X, 2); }}"
    ));
    assert_eq!(d.codes_at(&s), ["E0301@3:13"]);
    assert!(
        d.items[0].message.contains("parameter `factor` of helper `scale`"),
        "{}",
        d.items[0].message
    );
}

/// Every expression node of `stmts` (statements of `f`), nested statements and
/// sub-expressions included.
fn expr_nodes(f: &primflow::ir::Function, stmts: &[StmtId]) -> usize {
    fn expr(x: &primflow::ir::Exprs, e: primflow::ir::ExprId) -> usize {
        let mut n = 1;
        x[e].for_each_child(|c| n += expr(x, c));
        n
    }
    let mut n = 0;
    primflow::ir::for_each_assign(&f.stmts, stmts, &mut |place, value| {
        n += expr(&f.exprs, value) + place.indices.iter().map(|(i, _)| expr(&f.exprs, *i)).sum::<usize>()
    });
    n
}

#[test]
fn an_array_filled_with_one_value_is_one_splat_node_whatever_its_size() {
    // Zero for a declaration without initialiser, a scalar assigned to a whole array, and a
    // scalar argument of a component-wise built-in beside an array: each one `Splat` of the
    // scalar, not a list per element (the NURB surface's `point known[1280]` was 6 400
    // nodes, copied and walked by every pass).
    let p = ok(&format!(
        "{HEAD}{{ float big[1000][4];
            int counts[300] = 7;
            float m[4] = mix(big[1], big[2], k);
            Z = big[3][1] + counts[4] + m[0]; }}"
    ));
    let f = func(&p, "p");
    let values: Vec<&primflow::ir::Expr> = f
        .setup
        .iter()
        .chain(&f.pixel)
        .filter_map(|&s| match &f.stmts[s] {
            StmtKind::Assign { value, .. } => Some(&f.exprs[*value]),
            _ => None,
        })
        .collect();
    let splat_of = |e: &primflow::ir::Expr| match &e.kind {
        ExprKind::Splat(item) => Some((e.ty.dims.clone(), f.exprs[*item].ty.dims.is_empty())),
        _ => None,
    };
    assert_eq!(splat_of(values[0]), Some((vec![1000, 4], true)), "{:?}", values[0].kind);
    assert_eq!(splat_of(values[1]), Some((vec![300], true)));
    assert!(
        matches!(&values[2].kind, ExprKind::Builtin { args, .. } if splat_of(&f.exprs[args[2]]) == Some((vec![4], true))),
        "{:?}",
        values[2].kind
    );
    let nodes = expr_nodes(f, &f.setup) + expr_nodes(f, &f.pixel);
    assert!(nodes < 60, "{nodes} expression nodes");
}
