//! The IR validator (`primflow::ir::valid`): every program the checker produces validates,
//! before and after the IR passes; and for each rule, a small checked program broken in
//! one place is rejected with that rule named.

use std::path::{Path, PathBuf};

use primflow::diag::{Diagnostics, SourceMap, Span};
use primflow::ir::valid::{validate, validate_function, Rule};
use primflow::ir::*;

use crate::support::jit::{e, fc, ic, s as st};

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

/// A read of `name` (a local of `f`) with its type and variability.
fn read(f: &Function, name: &str) -> Expr {
    let (i, l) = f
        .locals
        .iter()
        .enumerate()
        .find(|(_, l)| l.name == name)
        .unwrap_or_else(|| panic!("local `{name}`"));
    e(ExprKind::Local(LocalId(i as u32)), l.ty.clone(), l.var)
}

fn place(f: &Function, name: &str) -> Place {
    let ExprKind::Local(local) = read(f, name).kind else {
        unreachable!()
    };
    Place {
        local,
        indices: vec![],
        span: Span::default(),
    }
}

/// Call `f` on every statement of `ss`, nested ones too, until it returns true.
fn find_stmt(ss: &mut [Stmt], f: &mut dyn FnMut(&mut Stmt) -> bool) -> bool {
    for s in ss {
        if f(s) {
            return true;
        }
        let found = match &mut s.kind {
            StmtKind::If { then, otherwise, .. } => find_stmt(then, f) || find_stmt(otherwise, f),
            StmtKind::Loop { body, step, .. } => find_stmt(body, f) || find_stmt(step, f),
            StmtKind::Interpolation { arms } => arms.iter_mut().any(|a| find_stmt(&mut a.body, f)),
            _ => false,
        };
        if found {
            return true;
        }
    }
    false
}

fn find_in_expr(x: &mut Expr, f: &mut dyn FnMut(&mut Expr) -> bool) -> bool {
    if f(x) {
        return true;
    }
    let mut found = false;
    x.for_each_child_mut(|c| found = found || find_in_expr(c, f));
    found
}

/// Call `f` on every expression of `ss` (outermost first) until it returns true.
fn find_expr(ss: &mut [Stmt], f: &mut dyn FnMut(&mut Expr) -> bool) -> bool {
    find_stmt(ss, &mut |s| {
        let roots: Vec<&mut Expr> = match &mut s.kind {
            StmtKind::Assign { place, value } => place.indices.iter_mut().map(|(i, _)| i).chain([value]).collect(),
            StmtKind::If { cond, .. } => vec![cond],
            StmtKind::Loop { cond, .. } => cond.iter_mut().collect(),
            StmtKind::InterpolatorReturn(v) => v.iter_mut().collect(),
            StmtKind::Bound(args) => args.iter_mut().collect(),
            StmtKind::CallPrimitive { args, .. } => args.iter_mut().collect(),
            _ => vec![],
        };
        roots.into_iter().any(|r| find_in_expr(r, f))
    })
}

/// Edit the first statement of `base`'s setup (`pixel`: its pixel part) that `pick` takes.
fn edit_stmt(p: &mut Program, pixel: bool, pick: impl Fn(&Stmt) -> bool, edit: impl FnOnce(&mut Stmt)) {
    let f = func(p, "base");
    let part = if pixel { &mut f.pixel } else { &mut f.setup };
    let mut edit = Some(edit);
    let found = find_stmt(part, &mut |s| {
        if pick(s) {
            (edit.take().expect("once"))(s);
            true
        } else {
            false
        }
    });
    assert!(found, "no statement to edit");
}

/// Edit the first expression of `base`'s setup (`pixel`: its pixel part) that `pick` takes.
fn edit_expr(p: &mut Program, pixel: bool, pick: impl Fn(&Expr) -> bool, edit: impl FnOnce(&mut Expr)) {
    let f = func(p, "base");
    let part = if pixel { &mut f.pixel } else { &mut f.setup };
    let mut edit = Some(edit);
    let found = find_expr(part, &mut |x| {
        if pick(x) {
            (edit.take().expect("once"))(x);
            true
        } else {
            false
        }
    });
    assert!(found, "no expression to edit");
}

fn is_binary(x: &Expr, want: BinOp) -> bool {
    matches!(x.kind, ExprKind::Binary { op, .. } if op == want)
}

/// `base()` broken by `breaking`, its expressions numbered again (as every pass leaves
/// them), is rejected with `rule`, named in the message.
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
            |x| matches!(x.kind, ExprKind::Local(_)),
            |x| x.kind = ExprKind::Local(LocalId(9999)),
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
        let first = f.setup.iter().find_map(|s| match s.kind {
            StmtKind::Loop { id, .. } => Some(id),
            _ => None,
        });
        let first = first.expect("a loop in setup");
        edit_stmt(
            p,
            true,
            |s| matches!(s.kind, StmtKind::Loop { .. }),
            |s| {
                if let StmtKind::Loop { id, .. } = &mut s.kind {
                    *id = first;
                }
            },
        );
    });
}

#[test]
fn expr_ids_dense() {
    // Not numbered again after the edit.
    let breakings: [fn(&mut Program); 3] = [
        // An expression added without numbering it.
        |p| {
            let f = func(p, "base");
            let acc = place(f, "acc");
            f.setup.push(st(StmtKind::Assign {
                place: acc,
                value: fc(1.0),
            }));
        },
        // Two expressions with one id.
        |p| edit_expr(p, false, |x| x.id == ExprId(1), |x| x.id = ExprId(0)),
        // An id no expression has.
        |p| func(p, "base").exprs += 1,
    ];
    for breaking in breakings {
        let mut p = base();
        breaking(&mut p);
        rejected_with(Rule::ExprIdsDense, &p);
    }
}

#[test]
fn jump_target() {
    rejects(Rule::JumpTarget, |p| {
        func(p, "base").setup.push(st(StmtKind::Break(LoopId(0))))
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
            |s| matches!(s.kind, StmtKind::CallPrimitive { .. }),
            |s| {
                if let StmtKind::CallPrimitive { callee, .. } = &mut s.kind {
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
            |x| matches!(x.kind, ExprKind::Const(ConstValue::Float(_))),
            |x| x.ty = Type::int(),
        )
    });
}

#[test]
fn local_type() {
    rejects(Rule::LocalType, |p| {
        edit_expr(
            p,
            false,
            |x| matches!(x.kind, ExprKind::Local(_)),
            |x| x.ty = Type::bool(),
        )
    });
}

#[test]
fn index_type() {
    rejects(Rule::IndexType, |p| {
        edit_expr(
            p,
            false,
            |x| matches!(x.kind, ExprKind::Index { .. }),
            |x| {
                if let ExprKind::Index { index, .. } = &mut x.kind {
                    **index = fc(0.0);
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
            |x| is_binary(x, BinOp::Lt),
            |x| {
                let inner = x.clone();
                *x = e(
                    ExprKind::Unary {
                        op: UnaryOp::Neg,
                        expr: Box::new(inner),
                    },
                    Type::bool(),
                    x.var,
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
            |x| is_binary(x, BinOp::Add) && x.ty == Type::float(),
            |x| {
                if let ExprKind::Binary { rhs, .. } = &mut x.kind {
                    **rhs = ic(1);
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
            |x| matches!(x.kind, ExprKind::Convert(_)),
            |x| x.ty.elem = Elem::Scalar(Scalar::Bool),
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
            |x| matches!(&x.kind, ExprKind::Convert(a) if x.ty.elem == Elem::Interp && a.ty.dims.len() == 1),
            |x| list = Some(x.clone()),
        );
        let f = func(p, "base");
        let dd = place(f, "dd");
        f.pixel.push(st(StmtKind::Assign {
            place: dd,
            value: list.expect("the list"),
        }));
    });
}

#[test]
fn select_type() {
    rejects(Rule::SelectType, |p| {
        edit_expr(
            p,
            false,
            |x| matches!(x.kind, ExprKind::Select { .. }),
            |x| {
                if let ExprKind::Select { otherwise, .. } = &mut x.kind {
                    **otherwise = ic(2);
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
            |x| matches!(x.kind, ExprKind::Builtin { func: Builtin::Max, .. }),
            |x| {
                if let ExprKind::Builtin { args, .. } = &mut x.kind {
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
            |x| matches!(x.kind, ExprKind::List(_)),
            |x| {
                if let ExprKind::List(items) = &mut x.kind {
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
            |x| matches!(x.kind, ExprKind::Splat(_)),
            |x| x.ty.elem = Elem::Scalar(Scalar::Int),
        )
    });
}

#[test]
fn mat_mul_type() {
    rejects(Rule::MatMulType, |p| {
        edit_expr(
            p,
            false,
            |x| matches!(x.kind, ExprKind::MatMul { .. }),
            |x| x.ty.dims = vec![3],
        )
    });
}

#[test]
fn query_type() {
    rejects(Rule::QueryType, |p| {
        edit_expr(
            p,
            false,
            |x| matches!(x.kind, ExprKind::SeqCount),
            |x| x.ty = Type::float(),
        )
    });
}

#[test]
fn condition_type() {
    rejects(Rule::ConditionType, |p| {
        edit_stmt(
            p,
            false,
            |s| matches!(s.kind, StmtKind::If { .. }),
            |s| {
                if let StmtKind::If { cond, .. } = &mut s.kind {
                    *cond = ic(1);
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
            |s| matches!(&s.kind, StmtKind::Assign { value, .. } if value.ty == Type::float()),
            |s| {
                if let StmtKind::Assign { value, .. } = &mut s.kind {
                    *value = ic(0);
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
            |s| matches!(s.kind, StmtKind::Bound(_)),
            |s| {
                if let StmtKind::Bound(args) = &mut s.kind {
                    args[0] = ic(0);
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
            |x| matches!(&x.kind, ExprKind::Index { base, .. } if base.ty.per_seq),
            |x| {
                if let ExprKind::Index { base, .. } = &x.kind {
                    *x = (**base).clone();
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
        f.setup.push(st(StmtKind::Assign { place: n, value: ic(1) }));
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
            |x| matches!(x.kind, ExprKind::Binary { .. }) && x.var.is_varying(),
            |x| x.var = Variability::Uniform,
        )
    });
}

#[test]
fn varying_into_uniform() {
    rejects(Rule::VaryingIntoUniform, |p| {
        let f = func(p, "base");
        let (acc, x) = (place(f, "acc"), read(f, "X"));
        f.pixel.push(st(StmtKind::Assign { place: acc, value: x }));
    });
}

/// `X < 1`: a varying condition.
fn x_below_one(f: &Function) -> Expr {
    e(
        ExprKind::Binary {
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
        f.pixel.push(st(StmtKind::If {
            cond,
            then: vec![st(StmtKind::Assign {
                place: acc,
                value: fc(1.0),
            })],
            otherwise: vec![],
        }));
    });
}

#[test]
fn loop_varying() {
    rejects(Rule::LoopVarying, |p| {
        edit_stmt(
            p,
            true,
            |s| matches!(s.kind, StmtKind::Loop { varying: true, .. }),
            |s| {
                if let StmtKind::Loop { varying, .. } = &mut s.kind {
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
        let id = LoopId(f.loops);
        f.loops += 1;
        f.pixel.push(st(StmtKind::Loop {
            id,
            cond: None,
            body: vec![st(StmtKind::If {
                cond,
                then: vec![st(StmtKind::Return)],
                otherwise: vec![],
            })],
            step: vec![],
            varying: false,
            site: SiteId(0),
        }));
    });
}

// -- setup/pixel split

#[test]
fn setup_uniform() {
    rejects(Rule::SetupUniform, |p| {
        let f = func(p, "base");
        let cond = x_below_one(f);
        f.setup.push(st(StmtKind::If {
            cond,
            then: vec![],
            otherwise: vec![],
        }));
    });
}

#[test]
fn pixel_part() {
    rejects(Rule::PixelPart, |p| {
        let f = func(p, "base");
        let at = f.setup.iter().position(|s| matches!(s.kind, StmtKind::Bound(_)));
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

fn interpolation_arms(p: &mut Program, edit: impl FnOnce(&mut Vec<InterpArm>)) {
    edit_stmt(
        p,
        true,
        |s| matches!(s.kind, StmtKind::Interpolation { .. }),
        |s| {
            if let StmtKind::Interpolation { arms } = &mut s.kind {
                edit(arms);
            }
        },
    );
}

#[test]
fn interpolation_placement() {
    rejects(Rule::InterpolationPlacement, |p| {
        interpolation_arms(p, |arms| {
            let nested = st(StmtKind::Interpolation { arms: arms.clone() });
            arms[0].body.insert(0, nested);
        })
    });
}

#[test]
fn arm_kinds() {
    rejects(Rule::ArmKinds, |p| {
        interpolation_arms(p, |arms| arms[1].kind = arms[0].kind.clone())
    });
}

#[test]
fn interpolator_return_placement() {
    rejects(Rule::InterpolatorReturnPlacement, |p| {
        let mut ret = None;
        interpolation_arms(p, |arms| ret = Some(arms[0].body.last().expect("a return").clone()));
        func(p, "base").pixel.push(ret.expect("the linear arm's return"));
    });
}

#[test]
fn interpolator_return_type() {
    rejects(Rule::InterpolatorReturnType, |p| {
        interpolation_arms(p, |arms| {
            let ret = arms[0].body.last_mut().expect("a return");
            ret.kind = StmtKind::InterpolatorReturn(Some(ic(1)));
        })
    });
}

// -- primitive calls

fn call_args(p: &mut Program, edit: impl FnOnce(&Function, &mut Vec<Expr>)) {
    let f = func(p, "base").clone();
    edit_stmt(
        p,
        false,
        |s| matches!(s.kind, StmtKind::CallPrimitive { .. }),
        |s| {
            if let StmtKind::CallPrimitive { args, .. } = &mut s.kind {
                edit(&f, args);
            }
        },
    );
}

#[test]
fn call_arity() {
    rejects(Rule::CallArity, |p| {
        call_args(p, |_, args| {
            args.pop();
        })
    });
}

#[test]
fn call_arg_type() {
    rejects(Rule::CallArgType, |p| call_args(p, |_, args| args[0] = fc(1.0)));
}

#[test]
fn call_pixel_args() {
    rejects(Rule::CallPixelArgs, |p| {
        call_args(p, |f, args| {
            let at = args
                .iter()
                .position(|a| matches!(&a.kind, ExprKind::Local(l) if f.local(*l).name == "X"));
            args[at.expect("X passed")] = read(f, "Y");
        })
    });
}

#[test]
fn call_arg_varying() {
    rejects(Rule::CallArgVarying, |p| {
        call_args(p, |f, args| {
            let x = read(f, "X");
            args[0] = e(
                ExprKind::Splat(Box::new(x)),
                Type::array(Elem::Scalar(Scalar::Float), vec![4]),
                Variability::Varying,
            );
        })
    });
}
