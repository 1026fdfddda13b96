//! The argument blocks of the instances the geometry stage hands to kernels (see
//! [`super::geometry`]): reading a parameter's words out of an instance, rewriting its
//! normals and vectors, and building the instances a clipped facet, polyline or point set
//! becomes. Every write is bounded by the block the layout sized, so a malformed program
//! cannot write past it.

use glam::{DMat4, DVec4};

use crate::abi::{ArgLayout, ParamSlot};
use crate::ir::{Function, ParamSpace};
use crate::pipeline::transform::NormalMatrix;
use crate::pipeline::Warning;

use super::api::Instance;
use super::geometry;

/// Copy `words` into `args` at `at`, ignoring anything past the end (the layout sized `args`,
/// so this only guards against a malformed program).
pub(super) fn write_words(args: &mut [u32], at: usize, words: &[u32]) {
    if at >= args.len() {
        return;
    }
    let n = words.len().min(args.len() - at);
    args[at..at + n].copy_from_slice(&words[..n]);
}

/// The argument words of parameter slot `slot` of `layout`: one (start, length) span, or
/// one per sequence point for a per-sequence-point slot (`n_seq` of them); none for a pixel
/// parameter.
pub(super) fn param_spans(layout: &ArgLayout, n_seq: usize, slot: &ParamSlot) -> Vec<(usize, usize)> {
    match slot {
        ParamSlot::Pixel => vec![],
        ParamSlot::Fixed { offset, words } => vec![(*offset as usize, *words as usize)],
        ParamSlot::Seq { seq_offset, words } => {
            let base = layout.fixed_words as usize + n_seq * *seq_offset as usize;
            (0..n_seq)
                .map(|i| (base + i * *words as usize, *words as usize))
                .collect()
        }
    }
}

/// `n` argument words from `at` as floats; empty when the block is shorter.
pub(super) fn arg_floats(args: &[u32], at: usize, n: usize) -> Vec<f32> {
    args.get(at..at + n)
        .map(|w| w.iter().map(|&b| f32::from_bits(b)).collect())
        .unwrap_or_default()
}

/// Rewrite the normal and vector parameters of an instance of `f` (argument block `args`,
/// `n_seq` sequence points) from object to lighting coordinates.
pub(super) fn directions_to_lighting(
    f: &Function,
    layout: &ArgLayout,
    n_seq: usize,
    args: &mut [u32],
    normals: &NormalMatrix,
    lighting_from_object: &DMat4,
    warnings: &mut Vec<Warning>,
) {
    for (p, slot) in f.params.iter().zip(&layout.params) {
        let chunk = match p.space {
            ParamSpace::Normal | ParamSpace::Vector => 3,
            _ => continue,
        };
        for (at, words) in param_spans(layout, n_seq, slot) {
            for c in (0..words / chunk).map(|k| at + k * chunk) {
                let Ok(v) = <[f32; 3]>::try_from(arg_floats(args, c, 3)) else {
                    continue;
                };
                let out = match p.space {
                    ParamSpace::Normal => geometry::normal_to_lighting(normals, v, warnings),
                    _ => geometry::vector_to_lighting(lighting_from_object, v),
                };
                write_words(args, c, &out.map(f32::to_bits));
            }
        }
    }
}

/// An instance of `inst`'s primitive with the sequence points `points` (homogeneous device
/// position and interpolation data each): the fixed part of the arguments as they are (the
/// key's bindings do not change), then each point's `vertex` and interpolation data.
/// `trivial_accept` goes into the key (no near plane left for the kernel to clip).
pub(super) fn instance_with_points(
    inst: &Instance,
    layout: &ArgLayout,
    vertex: usize,
    interp: Option<usize>,
    points: &[(DVec4, &[f32])],
    trivial_accept: bool,
) -> Instance {
    let n = points.len() as u32;
    let fixed = layout.fixed_words as usize;
    let mut args = vec![0u32; layout.words(n)];
    args[..fixed].copy_from_slice(&inst.args[..fixed]);
    args[0] = n;
    let n_out = n.max(1) as usize;
    let at = |slot: &ParamSlot, i: usize| match slot {
        ParamSlot::Seq { seq_offset, words } => Some(fixed + n_out * *seq_offset as usize + i * *words as usize),
        _ => None,
    };
    for (i, (position, data)) in points.iter().enumerate() {
        if let Some(at) = at(&layout.params[vertex], i) {
            write_words(&mut args, at, &position.as_vec4().to_array().map(f32::to_bits));
        }
        if let Some(at) = interp.and_then(|k| at(&layout.params[k], i)) {
            let words: Vec<u32> = data.iter().map(|x| x.to_bits()).collect();
            write_words(&mut args, at, &words);
        }
    }
    let mut key = inst.key.clone();
    key.trivial_accept = trivial_accept;
    Instance {
        func: inst.func,
        key,
        n_seq: n,
        args,
    }
}

/// One instance per segment of a clipped polyline (docs/pipeline.md, "Lines"): four
/// sequence points, the point before the segment, its start and end, and the point after.
/// A joint's neighbour is the far end of the adjacent segment *as clipped*, so the two
/// segments at a joint are handed the same three points, bit for bit, and shape the joint
/// alike; an end that is no joint (the polyline's, or one the clipper made) repeats itself.
/// Interpolation data goes with the start (sequence points 0 and 1) and the end (2 and 3).
/// A closed polyline (`closing`: the index of its last segment) has a joint there too.
pub(super) fn line_instances(
    inst: &Instance,
    layout: &ArgLayout,
    vertex: usize,
    interp: Option<usize>,
    segments: &[geometry::Segment],
    closing: Option<usize>,
) -> Vec<Instance> {
    // Segment `o` follows segment `s` along the polyline (the last one is followed by the
    // first when the polyline closes at segment index `closing`).
    let follows = |o: &geometry::Segment, s: &geometry::Segment| {
        o.index == s.index + 1 || (closing == Some(s.index) && o.index == 0)
    };
    segments
        .iter()
        .enumerate()
        .map(|(k, s)| {
            // The adjacent segment when `end` of this one is a joint with it.
            let joint = |other: usize, end: usize| -> Option<&geometry::Segment> {
                let o = segments.get(other)?;
                let adjacent = if end == 0 { follows(s, o) } else { follows(o, s) };
                (s.original[end] && o.original[1 - end] && adjacent).then_some(o)
            };
            let last = segments.len() - 1;
            let before = joint(if k == 0 { last } else { k - 1 }, 0).map_or(&s.ends[0], |o| &o.ends[0]);
            let after = joint(if k == last { 0 } else { k + 1 }, 1).map_or(&s.ends[1], |o| &o.ends[1]);
            let points = [
                (before.0, s.ends[0].1.as_slice()),
                (s.ends[0].0, s.ends[0].1.as_slice()),
                (s.ends[1].0, s.ends[1].1.as_slice()),
                (after.0, s.ends[1].1.as_slice()),
            ];
            instance_with_points(inst, layout, vertex, interp, &points, true)
        })
        .collect()
}
