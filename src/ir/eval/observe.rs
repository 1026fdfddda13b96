//! Watching one pixel while the evaluator runs ([`Observer`], [`Evaluator::run_observed`]):
//! the statements its lane executes, the values assigned there, the branches taken, where
//! it retires and what it writes, as [`Event`]s in execution order (what `primflow trace`
//! prints).
//!
//! Invariants: an event is reported only for the watched pixel's lane: in setup code (run
//! once for every pixel, uniform) always, in pixel code only while the group holding the
//! pixel runs and the lane is executing (`exec`). Observing changes nothing the run
//! computes. With no observer (every other run) each hook is one test of an `Option`.
//!
//! [`Evaluator::run_observed`]: super::Evaluator::run_observed

use crate::ir::{Function, LocalId, Scalar, SiteId, StmtId};

/// What the evaluator did for the watched pixel, in execution order. Float values are f32
/// lane words of the run's precision (`Precision::F32`: the f32 bits).
#[derive(Clone, Copy, Debug)]
pub enum Event<'a> {
    /// A kernel run of primitive `func` begins: the instance's own (`depth` 0) or a call's.
    KernelStart { func: &'a Function, depth: u32 },
    /// That kernel run ends.
    KernelEnd { func: &'a Function, depth: u32 },
    /// The watched lane starts the pixel part of the kernel on top: its pass rectangle
    /// holds the pixel.
    PixelStart,
    /// Statement `stmt` of `func` begins for the lane.
    Stmt { func: &'a Function, stmt: StmtId },
    /// The `if` that just began went to its `then` side (`taken`) or not, for the lane.
    Branch { taken: bool },
    /// `local` of `func` after an assignment, at the lane: its first components (at most
    /// 16) of `total` (`varying`: the lane's own value; otherwise a uniform one, equal in
    /// every lane).
    Assign {
        func: &'a Function,
        local: LocalId,
        sc: Scalar,
        words: &'a [u64],
        total: usize,
        varying: bool,
    },
    /// The `return` statement `stmt` of `func` retires the lane (pixel code) or ends the
    /// kernel run's setup (setup code: no pixel of it runs).
    Return { func: &'a Function, stmt: StmtId },
    /// A loop head at `site` found no fuel left: setup fuel (the run ends) or the group's
    /// pixel fuel (every loop of the group ends at its head from here on).
    FuelOut { site: SiteId, setup: bool },
    /// The pixel part of the lane's group ended; `alive`: the lane did not retire.
    PixelEnd { alive: bool },
    /// The lane's depth was written: raw `fixed<32,32>` before and after.
    Depth { before: u32, after: u32 },
    /// G-buffer plane `plane` was written at the lane.
    Plane { plane: u32, value: f32 },
}

/// Receives the [`Event`]s of one pixel.
pub trait Observer: Send {
    fn event(&mut self, event: Event<'_>);
}

/// The observer of a run and the pixel it watches.
pub(crate) struct Watch<'o> {
    pub observer: &'o mut dyn Observer,
    pub x: i32,
    pub y: i32,
}
