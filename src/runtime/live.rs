//! Dead-parameter elimination: the G-buffer planes a frame allocates, and the instances
//! re-laid out so that no primitive interpolates a parameter nobody reads.
//!
//! A frame shaded by language shaders knows, once they are linked, which shading parameters
//! they read (`link::Linked::reads`). Every other parameter is *dead* for the frame unless
//! the caller reads it afterwards (`RenderOptions::keep_params`: `render --param`, test
//! expectations). A dead parameter gets no plane, and every instance drops its binding:
//! the instance's key loses the binding (so the kernel compiled for it has no code for the
//! parameter: no interpolation, no store) and its argument block loses the binding's plane
//! table entries, binding data and interpolation-data components, laid out as
//! `abi::ArgLayout::new` says for the shorter key.
//!
//! Invariants:
//! - An instance's bindings are the renderer's shading parameters in order, a prefix of them
//!   (`api::Renderer::current_key`); binding `k` is parameter `k`.
//! - The live parameters keep their order; their planes are numbered from 0 without gaps, so
//!   the frame holds exactly the live parameters' components.
//! - A stripped argument block holds, for every word the kernel reads under the stripped
//!   key, the word the kernel read under the full key: the frame is the full frame with
//!   the dead planes left out (`tests/runtime/live_planes.rs`).

use crate::abi::{interpolator_arg_words, ArgLayout, BindingKind, ParamSlot, VariantKey};
use crate::ir::{Elem, Program};

use super::api::{Instance, ShadingParam, Variants};
use super::frame::ParamPlanes;

/// Which shading parameters a frame allocates planes for, and where.
#[derive(Clone, Debug, PartialEq)]
pub struct LivePlanes {
    /// Per shading parameter (the renderer's order): its first plane in this frame, `None`
    /// when it is dead.
    pub first_plane: Vec<Option<u32>>,
    /// Planes of the live parameters.
    pub num_planes: u32,
}

impl LivePlanes {
    /// Every parameter live, at the planes the API allocated.
    pub fn all(params: &[ShadingParam]) -> LivePlanes {
        LivePlanes {
            first_plane: params.iter().map(|p| Some(p.first_plane)).collect(),
            num_planes: params.iter().map(|p| p.components).sum(),
        }
    }

    /// The parameters `live` says are read, numbered from plane 0 in order.
    pub fn only(params: &[ShadingParam], live: impl Fn(&str) -> bool) -> LivePlanes {
        let mut next = 0;
        let first_plane = params
            .iter()
            .map(|p| {
                live(&p.name).then(|| {
                    next += p.components;
                    next - p.components
                })
            })
            .collect();
        LivePlanes {
            first_plane,
            num_planes: next,
        }
    }

    /// Whether some parameter has no plane.
    pub fn drops_any(&self) -> bool {
        self.first_plane.iter().any(Option::is_none)
    }

    /// The live parameters' planes (what `Frame::params` lists).
    pub fn params(&self, params: &[ShadingParam]) -> Vec<ParamPlanes> {
        params
            .iter()
            .zip(&self.first_plane)
            .filter_map(|(p, first)| {
                first.map(|first_plane| ParamPlanes {
                    name: p.name.clone(),
                    first_plane,
                    components: p.components,
                })
            })
            .collect()
    }
}

/// The frame's instances without the dead parameters' bindings, and their variants.
pub(crate) struct Stripped {
    pub instances: Vec<Instance>,
    pub variants: Variants,
}

/// Every instance re-laid out for the live parameters of `live`.
pub(crate) fn strip(program: &Program, instances: &[Instance], live: &LivePlanes) -> Stripped {
    let mut variants = Variants::default();
    let instances: Vec<Instance> = instances
        .iter()
        .map(|inst| {
            let s = strip_instance(program, inst, live);
            variants.add(&s);
            s
        })
        .collect();
    Stripped { instances, variants }
}

/// One instance under the key without its dead bindings.
fn strip_instance(program: &Program, inst: &Instance, live: &LivePlanes) -> Instance {
    let bindings = &inst.key.bindings;
    let alive = |k: usize| live.first_plane.get(k).copied().flatten();
    let key = VariantKey {
        bindings: bindings
            .iter()
            .enumerate()
            .filter(|(k, _)| alive(*k).is_some())
            .map(|(_, b)| b.clone())
            .collect(),
        ..inst.key.clone()
    };
    let old = ArgLayout::new(program, inst.func, &inst.key);
    let new = ArgLayout::new(program, inst.func, &key);
    let mut args = vec![0u32; new.words(inst.n_seq)];
    let read = |at: usize, n: usize| inst.args.get(at..at + n);
    let copy = |args: &mut Vec<u32>, from: usize, to: usize, n: usize| {
        if let (Some(src), Some(dst)) = (read(from, n), args.get_mut(to..to + n)) {
            dst.copy_from_slice(src);
        }
    };
    args[0] = inst.n_seq;
    // Plane table: the live bindings' components at their new planes.
    let mut at = new.plane_table as usize;
    for (k, b) in bindings.iter().enumerate() {
        if let Some(first) = alive(k) {
            for c in 0..b.components {
                args[at] = first + c;
                at += 1;
            }
        }
    }
    // Binding data: the live bindings' words, which keep their lengths.
    let live_data = old.binding_data.iter().enumerate().filter(|(k, _)| alive(*k).is_some());
    for ((k, from), to) in live_data.zip(&new.binding_data) {
        if let (Some(from), Some(to)) = (from, to) {
            let words = match &bindings[k].kind {
                BindingKind::Constant => bindings[k].components,
                BindingKind::Shared(name) => program.find(name).map_or(0, |id| interpolator_arg_words(program, id)),
                BindingKind::Kind(_) => 0,
            };
            copy(&mut args, *from as usize, *to as usize, words as usize);
        }
    }
    if let (Some(from), Some(to)) = (old.spaces, new.spaces) {
        copy(&mut args, from as usize, to as usize, 6 * 16);
    }
    // Interpolation data: of each element, the live `Kind` bindings' components.
    let mut interp_kept = vec![];
    let mut c = 0;
    for (k, b) in bindings.iter().enumerate() {
        if let BindingKind::Kind(_) = b.kind {
            if alive(k).is_some() {
                interp_kept.extend(c..c + b.components as usize);
            }
            c += b.components as usize;
        }
    }
    let old_interp = c;
    let f = program.func(inst.func);
    let seq_points = inst.n_seq.max(1) as usize;
    for (p, (from, to)) in f.params.iter().zip(old.params.iter().zip(&new.params)) {
        let ty = &f.local(p.local).ty;
        // (old offset, new offset, old words, new words) of each value the slot holds.
        let values: Vec<(usize, usize, usize, usize)> = match (from, to) {
            (ParamSlot::Fixed { offset: a, words: wa }, ParamSlot::Fixed { offset: b, words: wb }) => {
                vec![(*a as usize, *b as usize, *wa as usize, *wb as usize)]
            }
            (
                ParamSlot::Seq {
                    seq_offset: a,
                    words: wa,
                },
                ParamSlot::Seq {
                    seq_offset: b,
                    words: wb,
                },
            ) => {
                let (a, b) = (
                    old.fixed_words as usize + seq_points * *a as usize,
                    new.fixed_words as usize + seq_points * *b as usize,
                );
                let (wa, wb) = (*wa as usize, *wb as usize);
                (0..seq_points).map(|i| (a + i * wa, b + i * wb, wa, wb)).collect()
            }
            _ => vec![],
        };
        for (a, b, wa, wb) in values {
            if ty.elem != Elem::Interp {
                copy(&mut args, a, b, wa.min(wb));
                continue;
            }
            // `fixed_len` elements of `old_interp` words, each cut to `interp_kept`.
            for e in 0..ty.fixed_len() as usize {
                for (j, &from_c) in interp_kept.iter().enumerate() {
                    let (src, dst) = (a + e * old_interp + from_c, b + e * interp_kept.len() + j);
                    if src < a + wa && dst < b + wb {
                        copy(&mut args, src, dst, 1);
                    }
                }
            }
        }
    }
    Instance {
        func: inst.func,
        key,
        n_seq: inst.n_seq,
        args,
    }
}
