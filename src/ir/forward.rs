//! IR -> IR before code generation: forwards whole-array copies, so `d = s` followed by
//! reads of `d` reads `s` instead and the copy disappears.
//!
//! Why: the checker inlines helper calls and passes every argument by value, so a call
//! `nurb_de_boor(u_knots, ..., row_points, ...)` starts with `knots = u_knots` (16 floats)
//! and `points = row_points` (64 floats): a load and a store per component, per call. In the
//! NURB tessellation these copies were a fifth of the JIT's setup instructions
//! (docs/performance.md, "Unrolling constant-trip loops; forwarding array copies"). Scalar copies are not touched (they are SSA moves).
//!
//! The rule (sound without any alias analysis, because the IR has no references: a local
//! changes only by an assignment naming it): in a statement list, `d = s` (both whole
//! locals, same type, both uniform, `d` not a parameter, `d` an array) is forwarded when
//! - it is the only assignment to `d` anywhere in the function (setup and pixel part),
//! - every read of `d` in the function is in a later statement of the same list, and
//! - `s` is not assigned in the statements from that one through the last that reads `d`.
//! Then each read of `d` would see exactly the value `s` has at that read, so reads of `d`
//! become reads of `s` and the assignment is dropped. Nothing observable changes: values,
//! run-time error sites and index lengths are the same (same type, same `SiteId`s).
//! Lists are visited outside-in, so chains (`knots = u_knots; ... k2 = knots`) collapse.
//!
//! Invariants kept: the output is a checked program in the sense of [`crate::ir`] (same
//! locals, sites, loops, parameters, its statements and expressions numbered afresh by
//! [`super::number::renumber`]); only `Assign` statements are removed and only `Local`
//! expressions renamed.

use super::{for_each_stmt, ExprId, ExprKind, Exprs, Function, LocalId, LocalKind, StmtId, StmtKind, Stmts};

/// `f` with whole-array copies forwarded (see the module comment).
pub fn forward_copies(f: &Function) -> Function {
    let mut out = f.clone();
    let mut counts = Counts::new(out.locals.len());
    for &s in out.setup.iter().chain(out.pixel.iter()) {
        counts.stmt(&out.stmts, &out.exprs, s);
    }
    let mut fw = Forwarder {
        f,
        counts,
        stmts: &mut out.stmts,
        exprs: &mut out.exprs,
    };
    fw.list(&mut out.setup);
    fw.list(&mut out.pixel);
    // The dropped copies left their statements and expressions unreachable.
    super::number::renumber(&mut out);
    out
}

/// Reads and assignments of each local.
struct Counts {
    reads: Vec<u32>,
    writes: Vec<u32>,
}

impl Counts {
    fn new(n: usize) -> Counts {
        Counts {
            reads: vec![0; n],
            writes: vec![0; n],
        }
    }

    fn stmt(&mut self, st: &Stmts, x: &Exprs, s: StmtId) {
        visit_stmt(st, x, s, &mut |l| bump(&mut self.reads, l), &mut |l| {
            bump(&mut self.writes, l)
        });
    }
}

fn bump(v: &mut [u32], l: LocalId) {
    if let Some(c) = v.get_mut(l.0 as usize) {
        *c += 1;
    }
}

struct Forwarder<'a> {
    f: &'a Function,
    counts: Counts,
    /// The arenas of the function being rewritten.
    stmts: &'a mut Stmts,
    exprs: &'a mut Exprs,
}

impl Forwarder<'_> {
    fn list(&mut self, list: &mut Vec<StmtId>) {
        let mut k = 0;
        while k < list.len() {
            if let Some((d, s)) = self.candidate(list[k]) {
                if self.forward(list, k, d, s) {
                    continue; // list[k] is now the next statement
                }
            }
            // Out of the arena while its blocks are rewritten; no walk of them reaches it.
            let mut node = self.stmts.take(list[k]);
            node.for_each_block_mut(|b| self.list(b));
            self.stmts[list[k]] = node;
            k += 1;
        }
    }

    /// `d = s` of the shape the rule asks for (without the flow conditions).
    fn candidate(&self, st: StmtId) -> Option<(LocalId, LocalId)> {
        let StmtKind::Assign { place, value } = &self.stmts[st] else {
            return None;
        };
        let ExprKind::Local(s) = self.exprs[*value].kind else {
            return None;
        };
        if !place.indices.is_empty() || place.local == s {
            return None;
        }
        let (dl, sl) = (
            self.f.locals.get(place.local.0 as usize)?,
            self.f.locals.get(s.0 as usize)?,
        );
        let array = !dl.ty.dims.is_empty() && !dl.ty.per_seq;
        let uniform = !dl.var.is_varying() && !sl.var.is_varying();
        let ok = array && uniform && dl.ty == sl.ty && !matches!(dl.kind, LocalKind::Param(_));
        ok.then_some((place.local, s))
    }

    /// Forward `list[k]` (`d = s`) if the flow conditions hold; true if it was removed.
    fn forward(&mut self, list: &mut Vec<StmtId>, k: usize, d: LocalId, s: LocalId) -> bool {
        if self.counts.writes[d.0 as usize] != 1 {
            return false;
        }
        let total_reads = self.counts.reads[d.0 as usize];
        let mut seen = 0;
        let mut last = k;
        let mut s_written = false;
        for (j, &st) in list.iter().enumerate().skip(k + 1) {
            if seen == total_reads {
                break;
            }
            let mut reads_d = 0;
            let mut writes_s = false;
            visit_stmt(
                self.stmts,
                self.exprs,
                st,
                &mut |l| {
                    if l == d {
                        reads_d += 1
                    }
                },
                &mut |l| writes_s |= l == s,
            );
            s_written |= writes_s;
            if reads_d > 0 {
                seen += reads_d;
                last = j;
                if s_written {
                    return false;
                }
            }
        }
        if seen != total_reads {
            return false; // some read of `d` is elsewhere
        }
        for &st in &list[k + 1..=last] {
            rename_stmt(self.stmts, self.exprs, st, d, s);
        }
        self.counts.reads[s.0 as usize] += total_reads;
        // The copy itself read `s` once.
        self.counts.reads[s.0 as usize] -= 1;
        self.counts.reads[d.0 as usize] = 0;
        self.counts.writes[d.0 as usize] = 0;
        list.remove(k);
        true
    }
}

/// Calls `read` for every `Local` expression and `write` for every assigned place's local in
/// `s` (nested statements included).
fn visit_stmt(st: &Stmts, x: &Exprs, s: StmtId, read: &mut dyn FnMut(LocalId), write: &mut dyn FnMut(LocalId)) {
    for_each_stmt(st, &[s], &mut |_, kind| {
        if let StmtKind::Assign { place, .. } = kind {
            write(place.local);
        }
        kind.for_each_expr(|e| visit_expr(x, *e, read));
    });
}

fn visit_expr(x: &Exprs, e: ExprId, read: &mut dyn FnMut(LocalId)) {
    x.for_each_local(e, read);
}

/// Every read of `from` in `s` becomes a read of `to` (assignments to `from` stay: the rule
/// only renames where `from` is never assigned).
fn rename_stmt(st: &Stmts, x: &mut Exprs, s: StmtId, from: LocalId, to: LocalId) {
    for_each_stmt(st, &[s], &mut |_, kind| {
        kind.for_each_expr(|e| rename_expr(x, *e, from, to))
    });
}

fn rename_expr(x: &mut Exprs, e: ExprId, from: LocalId, to: LocalId) {
    if let ExprKind::Local(l) = &mut x[e].kind {
        if *l == from {
            *l = to;
        }
    }
    let mut k = 0;
    while let Some(c) = x[e].child(k) {
        rename_expr(x, c, from, to);
        k += 1;
    }
}
