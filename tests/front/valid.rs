//! The IR validator (`primflow::ir::valid`): every program the checker produces validates,
//! before and after the IR passes; and for each rule, a small checked program broken in
//! one place is rejected with that rule named.

use std::path::{Path, PathBuf};

use primflow::diag::{Diagnostics, SourceMap, Span};
use primflow::ir::valid::{validate, validate_function, Rule};
use primflow::ir::*;

use primflow::ir::tree::{Tree, TreeKind};

use crate::support::jit::{e, fc, ic};

fn prim_files(dir: &Path) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.expect("dir entry").path())
        .filter(|p| p.extension().is_some_and(|x| x == "prim"))
        .collect();
    files.sort();
    files
}

fn compile_files(paths: &[PathBuf]) -> Program {
    let mut sources = SourceMap::new();
    let ids: Vec<_> = paths.iter().map(|p| sources.load(p).expect("readable")).collect();
    let mut diags = Diagnostics::new();
    primflow::compile(&sources, &ids, &mut diags)
        .unwrap_or_else(|| panic!("{paths:?} failed to check:\n{}", diags.render(&sources)))
}

/// The program and every function after `forward` validate.
fn assert_valid(program: &Program, what: &str) {
    if let Err(e) = validate(program) {
        panic!("{what}: {e}");
    }
    for f in &program.functions {
        let forwarded = forward::forward_copies(f);
        if let Err(e) = validate_function(program, &forwarded) {
            panic!("{what}, after forward: {e}");
        }
    }
}

#[test]
fn the_library_and_the_ok_corpus_validate() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let library = prim_files(&root.join("prims"));
    assert!(library.len() >= 5, "{library:?}");
    assert_valid(&compile_files(&library), "prims/");
    let ok = prim_files(&root.join("tests/check/ok"));
    assert!(ok.len() >= 5, "{ok:?}");
    for f in ok {
        assert_valid(&compile_files(std::slice::from_ref(&f)), &f.display().to_string());
    }
}

// ---- one broken program per rule

/// A callee with every kind of parameter, a primitive that calls it and uses most
/// constructs (the setup part: bound, call, loops, transforms, lists, splats; the pixel
/// part: a varying loop, a varying return, an interpolation construct), and a shared
/// interpolator.
const BASE: &str = r#"
primitive sub(float rect[4]; point v[]; interpolator_data d[3]; varying float X, Y;
              inout varying fixed<32,32> Z)
{
    bound(rect[0], rect[1], rect[2], rect[3]);
    if (X < rect[0] + len(v)) return;
    Z = 0.5;
}

primitive base(float rect[4]; point v[]; interpolator_data d[3]; int n; varying float X, Y;
               inout varying fixed<32,32> Z)
{
    if (n < 0) return;
    bound(rect[0], rect[1], rect[2], rect[3]);
    float pts[2][4] = {v[0], v[1]};
    sub(rect, pts, d, X, Y, Z);
    int count = len(v);
    float acc = 0;
    for (int i = 0; i < n; i++) {
        if (i > 2) break;
        acc = acc + i;
    }
    float m[4][4] = {{1,0,0,0},{0,1,0,0},{0,0,1,0},{0,0,0,1}};
    float p[4] = m * transform("object", "world", pts[0]);
    bool clip = clipping();
    float q = max(acc, 1.0) + count + p[0];
    float sel = n > 0 ? 1.0 : 2.0;
    float zz[3];
    interpolation_data dd = d[0] * 2;

    float e = X * rect[0] + Y;
    int k = 0;
    while (e > k) {
        k = k + 1;
        if (k > 3) break;
    }
    if (e < q + sel + zz[1]) return;
    Z = 0.5;
    interpolation {
        linear:
            interpolator_return(d[0] * X + dd);
        implicit:
            interpolation_data nv = {X, Y, 1};
            interpolator_return(nv);
        default:
            interpolator_return;
    }
}

interpolator terp(float s = 1; varying float X, Y; inout varying fixed<32,32> Z)
{
    interpolator_return(s * X);
}
"#;

fn base() -> Program {
    let mut sources = SourceMap::new();
    let id = sources.add("base.prim", BASE.to_string());
    let mut diags = Diagnostics::new();
    let p = primflow::compile(&sources, &[id], &mut diags)
        .unwrap_or_else(|| panic!("the base program checks:\n{}", diags.render(&sources)));
    validate(&p).expect("the base program validates");
    p
}

fn func<'p>(p: &'p mut Program, name: &str) -> &'p mut Function {
    let id = p.find(name).expect("function");
    &mut p.functions[id.0 as usize]
}

/// A statement of the IR added to the arena `stmts` (its expressions, and the statements
/// of its blocks, already in the function's arenas).
fn st(stmts: &mut Stmts, kind: StmtKind) -> StmtId {
    stmts.alloc(kind, Span::default())
}

/// A read of `name` (a local of `f`) with its type and variability.
fn read(f: &Function, name: &str) -> Tree {
    let (i, l) = f
        .locals
        .iter()
        .enumerate()
        .find(|(_, l)| l.name == name)
        .unwrap_or_else(|| panic!("local `{name}`"));
    e(TreeKind::Local(LocalId(i as u32)), l.ty.clone(), l.var)
}

fn place(f: &Function, name: &str) -> Place {
    let TreeKind::Local(local) = read(f, name).kind else {
        unreachable!()
    };
    Place {
        local,
        indices: vec![],
        span: Span::default(),
    }
}

/// The first expression of `x` in the tree at `id` (outermost first) that `pick` takes.
fn first_in(x: &Exprs, id: ExprId, pick: &dyn Fn(&Exprs, &Expr) -> bool) -> Option<ExprId> {
    if pick(x, &x[id]) {
        return Some(id);
    }
    let mut found = None;
    x[id].for_each_child(|c| found = found.or_else(|| first_in(x, c, pick)));
    found
}

/// Edit the first statement of `base`'s setup (`pixel`: its pixel part) that `pick` takes.
/// `pick` and `edit` are given the function's expression arena too.
fn edit_stmt(
    p: &mut Program,
    pixel: bool,
    pick: impl Fn(&Exprs, &StmtKind) -> bool,
    edit: impl FnOnce(&mut Exprs, &mut StmtKind),
) {
    edit_stmt_in(p, pixel, pick, |x, _, s| edit(x, s));
}

/// [`edit_stmt`], `edit` given the statement arena too (the edited node is out of it).
fn edit_stmt_in(
    p: &mut Program,
    pixel: bool,
    pick: impl Fn(&Exprs, &StmtKind) -> bool,
    edit: impl FnOnce(&mut Exprs, &mut Stmts, &mut StmtKind),
) {
    let f = func(p, "base");
    let part = if pixel { &f.pixel } else { &f.setup };
    let mut found = None;
    for_each_stmt(&f.stmts, part, &mut |id, s| {
        if found.is_none() && pick(&f.exprs, s) {
            found = Some(id);
        }
    });
    let id = found.expect("no statement to edit");
    let mut node = f.stmts.take(id);
    edit(&mut f.exprs, &mut f.stmts, &mut node);
    f.stmts[id] = node;
}

/// Edit the first expression of `base`'s setup (`pixel`: its pixel part) that `pick` takes
/// (given the arena and the node).
fn edit_expr(
    p: &mut Program,
    pixel: bool,
    pick: impl Fn(&Exprs, &Expr) -> bool,
    edit: impl FnOnce(&mut Exprs, ExprId),
) {
    let f = func(p, "base");
    let part = if pixel { &f.pixel } else { &f.setup };
    let mut found = None;
    for_each_stmt(&f.stmts, part, &mut |_, s| {
        s.for_each_expr(|r| found = found.or_else(|| first_in(&f.exprs, *r, &pick)))
    });
    edit(&mut f.exprs, found.expect("no expression to edit"));
}

fn is_binary(x: &Expr, want: BinOp) -> bool {
    matches!(x.kind, ExprKind::Binary { op, .. } if op == want)
}

/// `base()` broken by `breaking`, its expressions numbered again (as every pass leaves
/// them: a tree the edit added or shared is in pre-order again), is rejected with `rule`,
/// named in the message.
#[track_caller]
fn rejects(rule: Rule, breaking: impl FnOnce(&mut Program)) {
    let mut p = base();
    breaking(&mut p);
    p.functions.iter_mut().for_each(number::renumber);
    rejected_with(rule, &p);
}

/// `p` is rejected with `rule`, named in the message.
#[track_caller]
fn rejected_with(rule: Rule, p: &Program) {
    match validate(p) {
        Ok(()) => panic!("{rule:?}: the broken program validates"),
        Err(err) => {
            assert_eq!(err.rule, rule, "{err}");
            let text = err.to_string();
            assert!(text.contains(&format!("`{rule:?}`")), "{text}");
            assert!(!err.function.is_empty() && !err.node.is_empty(), "{err:?}");
        }
    }
}

// -- index facts

#[test]
fn local_in_range() {
    rejects(Rule::LocalInRange, |p| {
        edit_expr(
            p,
            false,
            |_, x| matches!(x.kind, ExprKind::Local(_)),
            |x, id| x[id].kind = ExprKind::Local(LocalId(9999)),
        )
    });
}

#[test]
fn site_in_range() {
    rejects(Rule::SiteInRange, |p| p.sites.clear());
}

#[test]
fn loop_id_in_range() {
    rejects(Rule::LoopIdInRange, |p| func(p, "base").loops = 0);
}

#[test]
fn loop_id_unique() {
    rejects(Rule::LoopIdUnique, |p| {
        let f = func(p, "base");
        let first = f.setup.iter().find_map(|&s| match f.stmts[s] {
            StmtKind::Loop { id, .. } => Some(id),
            _ => None,
        });
        let first = first.expect("a loop in setup");
        edit_stmt(
            p,
            true,
            |_, s| matches!(s, StmtKind::Loop { .. }),
            |_, s| {
                if let StmtKind::Loop { id, .. } = s {
                    *id = first;
                }
            },
        );
    });
}

#[test]
fn stmt_tree() {
    // Not numbered again after the edit.
    let breakings: [fn(&mut Program); 5] = [
        // A statement added at the end of the arena for the setup part: out of pre-order
        // (the pixel part's statements come after it).
        |p| {
            let f = func(p, "base");
            f.setup.push(st(&mut f.stmts, StmtKind::Return));
        },
        // One statement in two blocks: the setup's first also its last.
        |p| {
            let f = func(p, "base");
            let first = f.setup[0];
            f.setup.push(first);
        },
        // A statement no block reaches.
        |p| {
            let f = func(p, "base");
            st(&mut f.stmts, StmtKind::Return);
        },
        // A statement id past the arena, in the pixel part.
        |p| func(p, "base").pixel.push(StmtId(u32::MAX)),
        // A statement id past the arena, in a nested block.
        |p| {
            edit_stmt(
                p,
                false,
                |_, s| matches!(s, StmtKind::If { .. }),
                |_, s| {
                    if let StmtKind::If { then, .. } = s {
                        then.push(StmtId(u32::MAX));
                    }
                },
            )
        },
    ];
    for breaking in breakings {
        let mut p = base();
        breaking(&mut p);
        rejected_with(Rule::StmtTree, &p);
    }
}

#[test]
fn a_statement_shared_by_two_blocks_is_copied_by_renumbering() {
    // `rejects` renumbers what a breaking edit leaves: a statement in two blocks becomes
    // two, and the function validates again.
    let mut p = base();
    let f = func(&mut p, "base");
    let first = f.setup[0];
    f.setup.push(first);
    let before = f.stmts.len();
    number::renumber(f);
    assert!(f.stmts.len() > before, "the second occurrence is a copy");
    assert_ne!(f.setup[0], *f.setup.last().expect("a statement"));
    validate(&p).expect("a renumbered function validates");
}

#[test]
fn expr_tree() {
    // Not numbered again after the edit.
    let breakings: [fn(&mut Program); 4] = [
        // An expression added at the end of the arena for a statement of the setup part:
        // out of pre-order (the pixel part's expressions come after it). The statement is
        // one already there (a new one would break `StmtTree` first).
        |p| {
            let f = func(p, "base");
            let acc = place(f, "acc");
            let value = f.exprs.intern(fc(1.0));
            let at = f
                .setup
                .iter()
                .copied()
                .find(|&s| matches!(&f.stmts[s], StmtKind::Assign { place, .. } if place.local == acc.local));
            f.stmts[at.expect("an assignment to acc in setup")] = StmtKind::Assign { place: acc, value };
        },
        // One node the operand of two parents: the first `if`'s condition also the
        // value of the first assignment (a DAG, not a tree).
        |p| {
            let f = func(p, "base");
            let cond = f.setup.iter().find_map(|&s| match f.stmts[s] {
                StmtKind::If { cond, .. } => Some(cond),
                _ => None,
            });
            let cond = cond.expect("an if in setup");
            let at = f
                .setup
                .iter()
                .copied()
                .find(|&s| matches!(f.stmts[s], StmtKind::Assign { .. }));
            if let StmtKind::Assign { value, .. } = &mut f.stmts[at.expect("an assignment in setup")] {
                *value = cond;
            }
        },
        // A node no statement reaches.
        |p| {
            let f = func(p, "base");
            f.exprs.intern(fc(2.0));
        },
        // An operand id past the arena.
        |p| {
            edit_expr(
                p,
                false,
                |_, x| matches!(x.kind, ExprKind::Binary { .. }),
                |x, id| {
                    if let ExprKind::Binary { rhs, .. } = &mut x[id].kind {
                        *rhs = ExprId(u32::MAX);
                    }
                },
            )
        },
    ];
    for breaking in breakings {
        let mut p = base();
        breaking(&mut p);
        rejected_with(Rule::ExprTree, &p);
    }
}

#[test]
fn jump_target() {
    rejects(Rule::JumpTarget, |p| {
        let f = func(p, "base");
        f.setup.push(st(&mut f.stmts, StmtKind::Break(LoopId(0))))
    });
}

#[test]
fn param_layout() {
    rejects(Rule::ParamLayout, |p| func(p, "base").params[0].local = LocalId(1));
}

#[test]
fn call_callee() {
    rejects(Rule::CallCallee, |p| {
        let terp = p.find("terp").expect("terp");
        edit_stmt(
            p,
            false,
            |_, s| matches!(s, StmtKind::CallPrimitive { .. }),
            |_, s| {
                if let StmtKind::CallPrimitive { callee, .. } = s {
                    *callee = terp;
                }
            },
        );
    });
}

// -- types

#[test]
fn const_type() {
    rejects(Rule::ConstType, |p| {
        edit_expr(
            p,
            false,
            |_, x| matches!(x.kind, ExprKind::Const(ConstValue::Float(_))),
            |x, id| x[id].ty = Type::int(),
        )
    });
}

#[test]
fn local_type() {
    rejects(Rule::LocalType, |p| {
        edit_expr(
            p,
            false,
            |_, x| matches!(x.kind, ExprKind::Local(_)),
            |x, id| x[id].ty = Type::bool(),
        )
    });
}

#[test]
fn index_type() {
    rejects(Rule::IndexType, |p| {
        edit_expr(
            p,
            false,
            |_, x| matches!(x.kind, ExprKind::Index { .. }),
            |x, id| {
                let zero = x.intern(fc(0.0));
                if let ExprKind::Index { index, .. } = &mut x[id].kind {
                    *index = zero;
                }
            },
        )
    });
}

#[test]
fn unary_type() {
    rejects(Rule::UnaryType, |p| {
        edit_expr(
            p,
            false,
            |_, x| is_binary(x, BinOp::Lt),
            |x, id| {
                // The comparison moves to a new node; its place becomes `-` of it.
                let (inner, span) = (x[id].clone(), x.span(id));
                let var = inner.var;
                let moved = x.alloc(inner, span);
                x.replace(
                    id,
                    Expr::new(
                        ExprKind::Unary {
                            op: UnaryOp::Neg,
                            expr: moved,
                        },
                        Type::bool(),
                        var,
                    ),
                    span,
                );
            },
        )
    });
}

#[test]
fn binary_type() {
    rejects(Rule::BinaryType, |p| {
        edit_expr(
            p,
            false,
            |_, x| is_binary(x, BinOp::Add) && x.ty == Type::float(),
            |x, id| {
                let one = x.intern(ic(1));
                if let ExprKind::Binary { rhs, .. } = &mut x[id].kind {
                    *rhs = one;
                }
            },
        )
    });
}

#[test]
fn convert_type() {
    rejects(Rule::ConvertType, |p| {
        edit_expr(
            p,
            false,
            |_, x| matches!(x.kind, ExprKind::Convert(_)),
            |x, id| x[id].ty.elem = Elem::Scalar(Scalar::Bool),
        )
    });
}

#[test]
fn interp_from_list() {
    rejects(Rule::InterpFromList, |p| {
        // `{X, Y, 1}` as the `implicit:` arm's interpolation data, stored outside the arm.
        let mut list = None;
        edit_expr(
            p,
            true,
            |xs, x| matches!(&x.kind, ExprKind::Convert(a) if x.ty.elem == Elem::Interp && xs[*a].ty.dims.len() == 1),
            |x, id| list = Some(x.copy_tree(id)),
        );
        let f = func(p, "base");
        let dd = place(f, "dd");
        f.pixel.push(st(
            &mut f.stmts,
            StmtKind::Assign {
                place: dd,
                value: list.expect("the list"),
            },
        ));
    });
}

#[test]
fn select_type() {
    rejects(Rule::SelectType, |p| {
        edit_expr(
            p,
            false,
            |_, x| matches!(x.kind, ExprKind::Select { .. }),
            |x, id| {
                let two = x.intern(ic(2));
                if let ExprKind::Select { otherwise, .. } = &mut x[id].kind {
                    *otherwise = two;
                }
            },
        )
    });
}

#[test]
fn builtin_type() {
    rejects(Rule::BuiltinType, |p| {
        edit_expr(
            p,
            false,
            |_, x| matches!(x.kind, ExprKind::Builtin { func: Builtin::Max, .. }),
            |x, id| {
                if let ExprKind::Builtin { args, .. } = &mut x[id].kind {
                    args.pop();
                }
            },
        )
    });
}

#[test]
fn list_type() {
    rejects(Rule::ListType, |p| {
        edit_expr(
            p,
            false,
            |_, x| matches!(x.kind, ExprKind::List(_)),
            |x, id| {
                if let ExprKind::List(items) = &mut x[id].kind {
                    items.pop();
                }
            },
        )
    });
}

#[test]
fn splat_type() {
    rejects(Rule::SplatType, |p| {
        edit_expr(
            p,
            false,
            |_, x| matches!(x.kind, ExprKind::Splat(_)),
            |x, id| x[id].ty.elem = Elem::Scalar(Scalar::Int),
        )
    });
}

#[test]
fn mat_mul_type() {
    rejects(Rule::MatMulType, |p| {
        edit_expr(
            p,
            false,
            |_, x| matches!(x.kind, ExprKind::MatMul { .. }),
            |x, id| x[id].ty.dims = vec![3],
        )
    });
}

#[test]
fn query_type() {
    rejects(Rule::QueryType, |p| {
        edit_expr(
            p,
            false,
            |_, x| matches!(x.kind, ExprKind::SeqCount),
            |x, id| x[id].ty = Type::float(),
        )
    });
}

#[test]
fn condition_type() {
    rejects(Rule::ConditionType, |p| {
        edit_stmt(
            p,
            false,
            |_, s| matches!(s, StmtKind::If { .. }),
            |x, s| {
                let one = x.intern(ic(1));
                if let StmtKind::If { cond, .. } = s {
                    *cond = one;
                }
            },
        )
    });
}

#[test]
fn assign_type() {
    rejects(Rule::AssignType, |p| {
        edit_stmt(
            p,
            false,
            |x, s| matches!(s, StmtKind::Assign { value, .. } if x[*value].ty == Type::float()),
            |x, s| {
                let zero = x.intern(ic(0));
                if let StmtKind::Assign { value, .. } = s {
                    *value = zero;
                }
            },
        )
    });
}

#[test]
fn bound_type() {
    rejects(Rule::BoundType, |p| {
        edit_stmt(
            p,
            false,
            |_, s| matches!(s, StmtKind::Bound(_)),
            |x, s| {
                let zero = x.intern(ic(0));
                if let StmtKind::Bound(args) = s {
                    args[0] = zero;
                }
            },
        )
    });
}

#[test]
fn per_seq_value() {
    // `{v[0], v[1]}` becomes `{v, v[1]}`: the whole per-sequence-point array as a value.
    rejects(Rule::PerSeqValue, |p| {
        edit_expr(
            p,
            false,
            |xs, x| matches!(&x.kind, ExprKind::Index { base, .. } if xs[*base].ty.per_seq),
            |x, id| {
                if let ExprKind::Index { base, .. } = x[id].kind {
                    let (node, span) = (x[base].clone(), x.span(base));
                    x.replace(id, node, span);
                }
            },
        )
    });
}

#[test]
fn per_seq_local() {
    rejects(Rule::PerSeqLocal, |p| {
        let f = func(p, "base");
        let mut l = f.locals.last().expect("a local").clone();
        l.ty = Type {
            elem: Elem::Scalar(Scalar::Float),
            dims: vec![4],
            per_seq: true,
        };
        f.locals.push(l);
    });
}

#[test]
fn param_roles() {
    rejects(Rule::ParamRoles, |p| {
        let f = func(p, "base");
        let x = f.param_by_role(ParamRole::X).expect("X").local;
        f.locals[x.0 as usize].var = Variability::Uniform;
    });
}

#[test]
fn assign_read_only() {
    rejects(Rule::AssignReadOnly, |p| {
        let f = func(p, "base");
        let n = place(f, "n");
        let value = f.exprs.intern(ic(1));
        f.setup.push(st(&mut f.stmts, StmtKind::Assign { place: n, value }));
    });
}

#[test]
fn spaces_used() {
    rejects(Rule::SpacesUsed, |p| func(p, "base").uses_spaces = false);
}

// -- variability

#[test]
fn expr_variability() {
    rejects(Rule::ExprVariability, |p| {
        edit_expr(
            p,
            true,
            |_, x| matches!(x.kind, ExprKind::Binary { .. }) && x.var.is_varying(),
            |x, id| x[id].var = Variability::Uniform,
        )
    });
}

#[test]
fn varying_into_uniform() {
    rejects(Rule::VaryingIntoUniform, |p| {
        let f = func(p, "base");
        let (acc, x) = (place(f, "acc"), read(f, "X"));
        let value = f.exprs.intern(x);
        f.pixel.push(st(&mut f.stmts, StmtKind::Assign { place: acc, value }));
    });
}

/// `X < 1`: a varying condition.
fn x_below_one(f: &Function) -> Tree {
    e(
        TreeKind::Binary {
            op: BinOp::Lt,
            lhs: Box::new(read(f, "X")),
            rhs: Box::new(fc(1.0)),
        },
        Type::bool(),
        Variability::Varying,
    )
}

#[test]
fn uniform_under_varying_control() {
    rejects(Rule::UniformUnderVaryingControl, |p| {
        let f = func(p, "base");
        let (cond, acc) = (x_below_one(f), place(f, "acc"));
        let (cond, one) = (f.exprs.intern(cond), f.exprs.intern(fc(1.0)));
        let assign = st(&mut f.stmts, StmtKind::Assign { place: acc, value: one });
        let if_ = st(
            &mut f.stmts,
            StmtKind::If {
                cond,
                then: vec![assign],
                otherwise: vec![],
            },
        );
        f.pixel.push(if_);
    });
}

#[test]
fn loop_varying() {
    rejects(Rule::LoopVarying, |p| {
        edit_stmt(
            p,
            true,
            |_, s| matches!(s, StmtKind::Loop { varying: true, .. }),
            |_, s| {
                if let StmtKind::Loop { varying, .. } = s {
                    *varying = false;
                }
            },
        )
    });
}

#[test]
fn a_varying_jump_out_of_a_uniform_loop_is_rejected() {
    // for (...) { if (X < 1) return; } in the pixel part, with the loop left uniform.
    rejects(Rule::LoopVarying, |p| {
        let f = func(p, "base");
        let cond = x_below_one(f);
        let cond = f.exprs.intern(cond);
        let id = LoopId(f.loops);
        f.loops += 1;
        let ret = st(&mut f.stmts, StmtKind::Return);
        let if_ = st(
            &mut f.stmts,
            StmtKind::If {
                cond,
                then: vec![ret],
                otherwise: vec![],
            },
        );
        let loop_ = st(
            &mut f.stmts,
            StmtKind::Loop {
                id,
                cond: None,
                body: vec![if_],
                step: vec![],
                varying: false,
                site: SiteId(0),
            },
        );
        f.pixel.push(loop_);
    });
}

// -- setup/pixel split

#[test]
fn setup_uniform() {
    rejects(Rule::SetupUniform, |p| {
        let f = func(p, "base");
        let cond = x_below_one(f);
        let cond = f.exprs.intern(cond);
        f.setup.push(st(
            &mut f.stmts,
            StmtKind::If {
                cond,
                then: vec![],
                otherwise: vec![],
            },
        ));
    });
}

#[test]
fn pixel_part() {
    rejects(Rule::PixelPart, |p| {
        let f = func(p, "base");
        let at = f.setup.iter().position(|&s| matches!(f.stmts[s], StmtKind::Bound(_)));
        let bound = f.setup.remove(at.expect("bound in setup"));
        f.pixel.insert(0, bound);
    });
}

#[test]
fn interpolator_body() {
    rejects(Rule::InterpolatorBody, |p| {
        let f = func(p, "terp");
        f.setup = std::mem::take(&mut f.pixel);
    });
}

// -- interpolation data

/// Edit the arms of the first `interpolation` of `base`'s pixel part (`edit` is given the
/// statement arena too).
fn interpolation_arms(p: &mut Program, edit: impl FnOnce(&mut Stmts, &mut Vec<InterpArm>)) {
    edit_stmt_in(
        p,
        true,
        |_, s| matches!(s, StmtKind::Interpolation { .. }),
        |_, stmts, s| {
            if let StmtKind::Interpolation { arms } = s {
                edit(stmts, arms);
            }
        },
    );
}

#[test]
fn interpolation_placement() {
    rejects(Rule::InterpolationPlacement, |p| {
        interpolation_arms(p, |stmts, arms| {
            let nested = st(stmts, StmtKind::Interpolation { arms: arms.clone() });
            arms[0].body.insert(0, nested);
        })
    });
}

#[test]
fn arm_kinds() {
    rejects(Rule::ArmKinds, |p| {
        interpolation_arms(p, |_, arms| arms[1].kind = arms[0].kind.clone())
    });
}

#[test]
fn interpolator_return_placement() {
    rejects(Rule::InterpolatorReturnPlacement, |p| {
        let mut ret = None;
        interpolation_arms(p, |_, arms| ret = Some(*arms[0].body.last().expect("a return")));
        func(p, "base").pixel.push(ret.expect("the linear arm's return"));
    });
}

#[test]
fn interpolator_return_type() {
    rejects(Rule::InterpolatorReturnType, |p| {
        interpolation_arms(p, |stmts, arms| {
            let ret = *arms[0].body.last().expect("a return");
            stmts[ret] = StmtKind::InterpolatorReturn(Some(ExprId(0)));
        });
        // The value: an int, in the arena (numbered by `rejects`).
        edit_stmt_in(
            p,
            true,
            |_, s| matches!(s, StmtKind::Interpolation { .. }),
            |x, stmts, s| {
                let one = x.intern(ic(1));
                if let StmtKind::Interpolation { arms } = s {
                    stmts[*arms[0].body.last().expect("a return")] = StmtKind::InterpolatorReturn(Some(one));
                }
            },
        );
    });
}

// -- primitive calls

/// `edit` is given `base` as it was, its arena and the call's arguments.
fn call_args(p: &mut Program, edit: impl FnOnce(&Function, &mut Exprs, &mut Vec<ExprId>)) {
    let f = func(p, "base").clone();
    edit_stmt(
        p,
        false,
        |_, s| matches!(s, StmtKind::CallPrimitive { .. }),
        |x, s| {
            if let StmtKind::CallPrimitive { args, .. } = s {
                edit(&f, x, args);
            }
        },
    );
}

#[test]
fn call_arity() {
    rejects(Rule::CallArity, |p| {
        call_args(p, |_, _, args| {
            args.pop();
        })
    });
}

#[test]
fn call_arg_type() {
    rejects(Rule::CallArgType, |p| {
        call_args(p, |_, x, args| args[0] = x.intern(fc(1.0)))
    });
}

#[test]
fn call_pixel_args() {
    rejects(Rule::CallPixelArgs, |p| {
        call_args(p, |f, x, args| {
            let at = args
                .iter()
                .position(|a| matches!(&x[*a].kind, ExprKind::Local(l) if f.local(*l).name == "X"));
            args[at.expect("X passed")] = x.intern(read(f, "Y"));
        })
    });
}

#[test]
fn call_arg_varying() {
    rejects(Rule::CallArgVarying, |p| {
        call_args(p, |f, x, args| {
            let read_x = read(f, "X");
            args[0] = x.intern(e(
                TreeKind::Splat(Box::new(read_x)),
                Type::array(Elem::Scalar(Scalar::Float), vec![4]),
                Variability::Varying,
            ));
        })
    });
}
