//! The block walk of a pass rectangle, packaged as one control-flow construct in the style
//! of cranelift-frontend's `Switch`: [`BlockWalk::new`] declares its variables and creates
//! its blocks, [`BlockWalk::emit`] fills them. [`Lower::pixel_loops`] uses it when the
//! pixel code opens with coverage guards ([`super::block`]) and block culling is on (tier 1).
//!
//! Blocks of `BLOCK_W` x `BLOCK_H` pixels; per block, interval facts choose: skip, the pass
//! variant (decidable guards dropped) or the full pixel code. A pass rectangle under
//! `SMALL_RECT` pixels (a small triangle's) runs the full code without block facts:
//! evaluating them costs more than they can save there. Shape of the walk, block row by
//! block row:
//! - `row_stage` evaluates the prefix terms that depend on uniforms and Y alone, once for
//!   the block row ([`super::block`] caches them); the block loop after it evaluates only
//!   the X-dependent rest per block.
//! - Consecutive pass blocks of a block row run as one *span* (one row prologue per pixel
//!   row for the whole run, not per block): a pass block extends the pending span; a dead
//!   or full block, or the row's end, first flushes it. `after` says what follows the
//!   flush: 0 the next block row, 1 the next block (dead), 2 the full code on this block.
//! - The full code runs outside the block loop (`full_entry`, one instance for the blocks
//!   and for small rectangles) and comes back to `brow_resume`, which re-evaluates the row
//!   stage: the block loop's values then need no merging, and full blocks are few (a
//!   primitive's edges).
//! - The walk starts *coarse*: the whole rectangle as one block (one block row, one block),
//!   so a tile entirely inside or outside the primitive costs one evaluation. When the
//!   coarse block is neither dead nor passing, the walk restarts with BLOCK_W x BLOCK_H
//!   blocks.
//!
//! Every loop header branches exit-first (see [`super::loops`]).

use cranelift_codegen::ir::{self, condcodes::IntCC, types, Block, InstBuilder};
use cranelift_frontend::Variable;

use super::block::{AbsCache, BlockFacts};
use super::loops::Axis;
use super::{Lower, PassRect, Res, BLOCK_H, BLOCK_W, SMALL_RECT};
use crate::ir::Function;
use crate::mid::block::Prefix;

/// The variables and blocks of one block walk over rows `[lo_y, hi_y)` and groups from
/// `gx_start` to `hi_x` (see the module doc for what each is).
pub(super) struct BlockWalk {
    lo_y: ir::Value,
    hi_y: ir::Value,
    gx_start: ir::Value,
    hi_x: ir::Value,
    lo_x: ir::Value,
    /// Where the walk ends.
    loops_done: Block,
    /// The rectangle is under `SMALL_RECT` pixels (i8).
    small_rect: ir::Value,
    /// The block row's first pixel row; the block's first group.
    by: Variable,
    bxv: Variable,
    /// The walk is at its first, coarse block (i8); the block size.
    coarse: Variable,
    bw: Variable,
    bh: Variable,
    /// The pending span of pass blocks `[span_lo, span_hi)`, and what follows its flush.
    span_lo: Variable,
    span_hi: Variable,
    after: Variable,
    /// The full run's rectangle and where it returns: 0 the block after it, 1 the end.
    full_ys: [Variable; 2],
    full_gs: [Variable; 2],
    full_then: Variable,
    brow_hdr: Block,
    brow_body: Block,
    brow_resume: Block,
    brow_next: Block,
    small_full: Block,
    row_stage: Block,
    blk_hdr: Block,
    blk_body: Block,
    blk_next: Block,
    blk_choose: Block,
    blk_full: Block,
    blk_extend: Block,
    row_end: Block,
    to_full: Block,
    to_dead: Block,
    flush: Block,
    flush_run: Block,
    flush_done: Block,
    after_flush: Block,
    after_not_end: Block,
    full_entry: Block,
    full_done: Block,
    full_resume: Block,
    refine: Block,
    to_full_fine: Block,
}

impl BlockWalk {
    /// Measure the rectangle, declare the walk's variables (the coarse block first) and
    /// create its blocks; ends by jumping to the first block row's header.
    pub(super) fn new(
        l: &mut Lower,
        ys: [ir::Value; 2],
        gs: [ir::Value; 2],
        lo_x: ir::Value,
        loops_done: Block,
    ) -> Self {
        let [lo_y, hi_y] = ys;
        let [gx_start, hi_x] = gs;
        let w = l.b.ins().isub(hi_x, lo_x);
        let h = l.b.ins().isub(hi_y, lo_y);
        let w64 = l.b.ins().sextend(types::I64, w);
        let h64 = l.b.ins().sextend(types::I64, h);
        let area = l.b.ins().imul(w64, h64);
        let small_rect = l.b.ins().icmp_imm_s(IntCC::SignedLessThan, area, SMALL_RECT);
        let by = l.declare_var(types::I32);
        let coarse = l.declare_var(types::I8);
        let bw = l.declare_var(types::I32);
        let bh = l.declare_var(types::I32);
        let yes = l.iconst_here(types::I8, 1);
        l.b.def_var(coarse, yes);
        let rect_w = l.b.ins().isub(hi_x, gx_start);
        let rect_h = l.b.ins().isub(hi_y, lo_y);
        l.b.def_var(bw, rect_w);
        l.b.def_var(bh, rect_h);
        let bxv = l.declare_var(types::I32);
        let span_lo = l.declare_var(types::I32);
        let span_hi = l.declare_var(types::I32);
        let after = l.declare_var(types::I32);
        let full_ys = [l.declare_var(types::I32), l.declare_var(types::I32)];
        let full_gs = [l.declare_var(types::I32), l.declare_var(types::I32)];
        let full_then = l.declare_var(types::I32);
        l.b.def_var(by, lo_y);
        let walk = BlockWalk {
            lo_y,
            hi_y,
            gx_start,
            hi_x,
            lo_x,
            loops_done,
            small_rect,
            by,
            bxv,
            coarse,
            bw,
            bh,
            span_lo,
            span_hi,
            after,
            full_ys,
            full_gs,
            full_then,
            brow_hdr: l.b.create_block(),
            brow_body: l.b.create_block(),
            brow_resume: l.b.create_block(),
            brow_next: l.b.create_block(),
            small_full: l.b.create_block(),
            row_stage: l.b.create_block(),
            blk_hdr: l.b.create_block(),
            blk_body: l.b.create_block(),
            blk_next: l.b.create_block(),
            blk_choose: l.b.create_block(),
            blk_full: l.b.create_block(),
            blk_extend: l.b.create_block(),
            row_end: l.b.create_block(),
            to_full: l.b.create_block(),
            to_dead: l.b.create_block(),
            flush: l.b.create_block(),
            flush_run: l.b.create_block(),
            flush_done: l.b.create_block(),
            after_flush: l.b.create_block(),
            after_not_end: l.b.create_block(),
            full_entry: l.b.create_block(),
            full_done: l.b.create_block(),
            full_resume: l.b.create_block(),
            refine: l.b.create_block(),
            to_full_fine: l.b.create_block(),
        };
        l.b.ins().jump(walk.brow_hdr, &[]);
        walk
    }

    /// Fill the walk's blocks: the pixel code of `f` in its pass variant (`prefix`'s
    /// decidable guards dropped) for spans of pass blocks, in full for the others.
    pub(super) fn emit<'a>(&self, l: &mut Lower<'a, '_>, f: &'a Function, rect: &PassRect, prefix: &Prefix) -> Res<()> {
        let (y, y_end) = self.block_row_head(l);
        // The block row's stage: its first and last pixel rows' centres, and the prefix
        // terms that need no X.
        l.b.switch_to_block(self.row_stage);
        let y_last = l.b.ins().iadd_imm_s(y_end, -1);
        // Computed as the pixel code computes Y (`sample_coord`), so interval endpoints are
        // bit-identical to the pixels' values.
        let ys = [l.sample_coord(y, Axis::Y), l.sample_coord(y_last, Axis::Y)];
        let row_cache = l.block_cache_row(f, prefix, ys)?;
        l.b.ins().jump(self.blk_hdr, &[]);
        let facts = self.block_step(l, f, prefix, &row_cache, ys)?;
        self.flush_span(l, f, rect, prefix, &facts, [y, y_end])?;
        self.full_block(l, f, rect, [y, y_end])?;

        l.b.switch_to_block(self.brow_next);
        let y = l.b.use_var(self.by);
        let h = l.b.use_var(self.bh);
        let y = l.b.ins().iadd(y, h);
        l.b.def_var(self.by, y);
        l.b.ins().jump(self.brow_hdr, &[]);
        Ok(())
    }

    /// The block-row loop's header, its entry and the resume point after a full run; a
    /// small rectangle leaves for the full code here. Gives the block row's pixel rows
    /// `[y, y_end)`.
    fn block_row_head(&self, l: &mut Lower) -> (ir::Value, ir::Value) {
        l.b.switch_to_block(self.brow_hdr);
        let y = l.b.use_var(self.by);
        let done = l.b.ins().icmp(IntCC::SignedGreaterThanOrEqual, y, self.hi_y);
        l.b.ins().brif(done, self.loops_done, &[], self.brow_body, &[]);

        l.b.switch_to_block(self.brow_body);
        l.b.def_var(self.bxv, self.gx_start);
        l.b.ins().jump(self.brow_resume, &[]);

        l.b.switch_to_block(self.brow_resume);
        let y = l.b.use_var(self.by);
        let h = l.b.use_var(self.bh);
        let y_end = l.b.ins().iadd(y, h);
        let y_end = l.b.ins().smin(y_end, self.hi_y);
        let x = l.b.use_var(self.bxv);
        l.b.def_var(self.span_lo, x);
        l.b.def_var(self.span_hi, x);
        l.b.ins()
            .brif(self.small_rect, self.small_full, &[], self.row_stage, &[]);

        // A small rectangle: the full code over all of it, once.
        l.b.switch_to_block(self.small_full);
        l.b.def_var(self.full_ys[0], self.lo_y);
        l.b.def_var(self.full_ys[1], self.hi_y);
        l.b.def_var(self.full_gs[0], self.gx_start);
        l.b.def_var(self.full_gs[1], self.hi_x);
        let one = l.iconst_here(types::I32, 1);
        l.b.def_var(self.full_then, one);
        l.b.ins().jump(self.full_entry, &[]);
        (y, y_end)
    }

    /// The block loop's header and body: the block's facts decide dead (flush, next
    /// block), passing (extend the span) or neither (refine the coarse block, or flush and
    /// run the full code on a fine one).
    fn block_step<'a>(
        &self,
        l: &mut Lower<'a, '_>,
        f: &'a Function,
        prefix: &Prefix,
        row_cache: &AbsCache,
        ys: [ir::Value; 2],
    ) -> Res<BlockFacts> {
        l.b.switch_to_block(self.blk_hdr);
        let x = l.b.use_var(self.bxv);
        let done = l.b.ins().icmp(IntCC::SignedGreaterThanOrEqual, x, self.hi_x);
        l.b.ins().brif(done, self.row_end, &[], self.blk_body, &[]);

        l.b.switch_to_block(self.blk_body);
        let x = l.b.use_var(self.bxv);
        let w = l.b.use_var(self.bw);
        let x_end = l.b.ins().iadd(x, w);
        let x_end = l.b.ins().smin(x_end, self.hi_x);
        let x_first = l.b.ins().smax(x, self.lo_x);
        let x_last = l.b.ins().iadd_imm_s(x_end, -1);
        let xs = [l.sample_coord(x_first, Axis::X), l.sample_coord(x_last, Axis::X)];
        let facts = l.block_facts(f, prefix, row_cache, xs, ys)?;
        l.b.ins().brif(facts.dead, self.to_dead, &[], self.blk_choose, &[]);
        l.b.switch_to_block(self.blk_choose);
        l.b.ins().brif(facts.pass, self.blk_extend, &[], self.to_full_fine, &[]);

        // Neither dead nor passing: the coarse block is refined (nothing is pending then),
        // a fine block runs the full code.
        l.b.switch_to_block(self.to_full_fine);
        let c = l.b.use_var(self.coarse);
        l.b.ins().brif(c, self.refine, &[], self.to_full, &[]);
        l.b.switch_to_block(self.refine);
        let no = l.iconst_here(types::I8, 0);
        l.b.def_var(self.coarse, no);
        let fine_w = l.iconst_here(types::I32, BLOCK_W as i64);
        let fine_h = l.iconst_here(types::I32, BLOCK_H as i64);
        l.b.def_var(self.bw, fine_w);
        l.b.def_var(self.bh, fine_h);
        l.b.ins().jump(self.brow_body, &[]);

        // A pass block: start the span here if none is pending, and extend it to this
        // block's end (blocks are visited left to right, so the span stays contiguous).
        l.b.switch_to_block(self.blk_extend);
        let lo = l.b.use_var(self.span_lo);
        let hi = l.b.use_var(self.span_hi);
        let empty = l.b.ins().icmp(IntCC::SignedGreaterThanOrEqual, lo, hi);
        let lo = l.b.ins().select(empty, x, lo);
        l.b.def_var(self.span_lo, lo);
        l.b.def_var(self.span_hi, x_end);
        l.b.ins().jump(self.blk_next, &[]);
        Ok(facts)
    }

    /// Flush the pending span (the pass variant over rows `ys`), then go where `after`
    /// says: the next block row, the next block, or the full code on this block.
    fn flush_span<'a>(
        &self,
        l: &mut Lower<'a, '_>,
        f: &'a Function,
        rect: &PassRect,
        prefix: &Prefix,
        facts: &BlockFacts,
        ys: [ir::Value; 2],
    ) -> Res<()> {
        for (blk, code) in [(self.row_end, 0), (self.to_dead, 1), (self.to_full, 2)] {
            l.b.switch_to_block(blk);
            let c = l.iconst_here(types::I32, code);
            l.b.def_var(self.after, c);
            l.b.ins().jump(self.flush, &[]);
        }

        l.b.switch_to_block(self.flush);
        let lo = l.b.use_var(self.span_lo);
        let hi = l.b.use_var(self.span_hi);
        let pending = l.b.ins().icmp(IntCC::SignedLessThan, lo, hi);
        l.b.ins().brif(pending, self.flush_run, &[], self.after_flush, &[]);
        l.b.switch_to_block(self.flush_run);
        l.pixel_rows(f, rect, ys, [lo, hi], Some((prefix, &facts.decidable)), self.flush_done)?;
        l.b.switch_to_block(self.flush_done);
        let hi = l.b.use_var(self.span_hi);
        l.b.def_var(self.span_lo, hi);
        l.b.ins().jump(self.after_flush, &[]);

        l.b.switch_to_block(self.after_flush);
        let a = l.b.use_var(self.after);
        let at_end = l.b.ins().icmp_imm_s(IntCC::Equal, a, 0);
        l.b.ins().brif(at_end, self.brow_next, &[], self.after_not_end, &[]);
        l.b.switch_to_block(self.after_not_end);
        let is_dead = l.b.ins().icmp_imm_s(IntCC::Equal, a, 1);
        l.b.ins().brif(is_dead, self.blk_next, &[], self.blk_full, &[]);

        l.b.switch_to_block(self.blk_next);
        let x = l.b.use_var(self.bxv);
        let w = l.b.use_var(self.bw);
        let x = l.b.ins().iadd(x, w);
        l.b.def_var(self.bxv, x);
        l.b.ins().jump(self.blk_hdr, &[]);
        Ok(())
    }

    /// A full block leaves the block loop for the full code (rows `ys`), which comes back
    /// to the block after it, or ends the walk after a small rectangle's run.
    fn full_block<'a>(&self, l: &mut Lower<'a, '_>, f: &'a Function, rect: &PassRect, ys: [ir::Value; 2]) -> Res<()> {
        let [y, y_end] = ys;
        l.b.switch_to_block(self.blk_full);
        let x = l.b.use_var(self.bxv);
        let w = l.b.use_var(self.bw);
        let x_end = l.b.ins().iadd(x, w);
        let x_end = l.b.ins().smin(x_end, self.hi_x);
        l.b.def_var(self.full_ys[0], y);
        l.b.def_var(self.full_ys[1], y_end);
        l.b.def_var(self.full_gs[0], x);
        l.b.def_var(self.full_gs[1], x_end);
        let zero = l.iconst_here(types::I32, 0);
        l.b.def_var(self.full_then, zero);
        l.b.ins().jump(self.full_entry, &[]);

        l.b.switch_to_block(self.full_entry);
        let fys = [l.b.use_var(self.full_ys[0]), l.b.use_var(self.full_ys[1])];
        let fgs = [l.b.use_var(self.full_gs[0]), l.b.use_var(self.full_gs[1])];
        l.pixel_rows(f, rect, fys, fgs, None, self.full_done)?;

        l.b.switch_to_block(self.full_done);
        let then = l.b.use_var(self.full_then);
        l.b.ins().brif(then, self.loops_done, &[], self.full_resume, &[]);
        l.b.switch_to_block(self.full_resume);
        let x = l.b.use_var(self.bxv);
        let w = l.b.use_var(self.bw);
        let x = l.b.ins().iadd(x, w);
        l.b.def_var(self.bxv, x);
        l.b.ins().jump(self.brow_resume, &[]);
        Ok(())
    }
}
