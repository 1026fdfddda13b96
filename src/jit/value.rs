//! How IR values are represented in Cranelift, and the small helpers that move between the
//! uniform (scalar) and varying (4-lane vector) forms.
//!
//! Representation (one Cranelift value per flattened component):
//! - uniform float `f32`, uniform int and fixed `i32` (fixed: raw bits), uniform bool `i8` 0/1;
//! - varying float `f32x4`, varying int/fixed `i32x4`, varying bool `i32x4` lane masks
//!   (all ones = true, zero = false) so they feed `bitselect`/`blendv` directly.
//!
//! An aggregate value is a [`Val`] with its components in row-major order; an
//! interpolation_data value holds only the components of the current view. Invariant: every
//! component of a `Val` has the form its `varying` flag and `scalar` say.
//!
//! Also here: [`VnTable`], tier 0's table of the values already computed in the block being
//! filled (value numbering while lowering; `Lower::numbered` in lower.rs).

use std::hash::{BuildHasherDefault, Hasher};

use cranelift_codegen::ir::{self, types, Block, InstBuilder, MemFlagsData, Type};
use cranelift_frontend::FunctionBuilder;

use crate::abi::TileCtx;
use crate::ir::Scalar;

/// 32-bit lane vectors: 4 pixels per group.
pub const F32X4: Type = types::F32X4;
pub const I32X4: Type = types::I32X4;

/// A value of an IR expression: its flattened components.
#[derive(Clone, Debug)]
pub struct Val {
    pub comps: Vec<ir::Value>,
    pub scalar: Scalar,
    pub varying: bool,
}

impl Val {
    pub fn one(v: ir::Value, scalar: Scalar, varying: bool) -> Val {
        Val {
            comps: vec![v],
            scalar,
            varying,
        }
    }
}

/// What a pure value computed while lowering is, for value numbering at tier 0 (see
/// `Lower::numbered`): an operation on its operands, a constant, or a piece of address
/// arithmetic or argument read that a block needs once.
#[derive(Clone, Copy, PartialEq, Eq, Hash)]
pub enum VnKey {
    /// `BinOp as u8` (or [`VN_NEG`], [`VN_NOT`]), the operands' scalar type, the operands.
    Op(u8, Scalar, ir::Value, ir::Value),
    /// Kind (0 float, 1 int, 2 bool, 3 fixed), raw bits, the scalar type it is used as.
    Const(u8, u32, Scalar),
    /// A conversion of the value from the first scalar type to the second.
    Convert(Scalar, Scalar, ir::Value),
    /// An integer constant of index and address arithmetic (shift amounts, array lengths,
    /// the clamp's 0), by Cranelift type.
    IntConst(Type, i64),
    /// A uniform component offset as a byte offset (`offset * bytes`, widened to i64).
    ByteOffset(ir::Value, u32),
    /// `base + offset * bytes` for a uniform dynamic offset.
    DynAddr(ir::Value, ir::Value, u32),
    /// The address of a stack slot.
    SlotAddr(ir::StackSlot),
    /// A read-only argument-block word: byte offset, scalar, bools stored as words.
    ArgLoad(i32, Scalar, bool),
    /// The sequence length (at least 1).
    SeqLen,
    /// A uniform index checked and clamped: the index, the array's static length (`None`:
    /// the sequence length), the error guard it was checked under.
    CheckedIndex(ir::Value, Option<u32>, Option<ir::Value>),
    /// A pointer field of the context that no kernel writes (an error count array), by
    /// byte offset.
    CtxPtr(i32),
}

/// [`VnKey::Op`] codes of the unary operations (above every `BinOp`).
pub const VN_NEG: u8 = 200;
pub const VN_NOT: u8 = 201;

/// Values already computed in one block (the one being filled), by what they are.
pub struct VnTable {
    block: Option<Block>,
    values: std::collections::HashMap<VnKey, ir::Value, BuildHasherDefault<WordHasher>>,
}

impl Default for VnTable {
    /// Sized for a long setup block (screen_triangle's holds ~300 keys): grown from empty,
    /// the table rehashed ~9 times per kernel (~0.5 % of a tier-0 compile).
    fn default() -> VnTable {
        VnTable {
            block: None,
            values: std::collections::HashMap::with_capacity_and_hasher(512, Default::default()),
        }
    }
}

impl VnTable {
    /// The value of `key` computed earlier in `block`.
    pub fn get(&self, block: Block, key: VnKey) -> Option<ir::Value> {
        if self.block != Some(block) {
            return None;
        }
        self.values.get(&key).copied()
    }

    /// Record `v` as `key`'s value in `block`. Lowering fills one block at a time, so a
    /// new block forgets the previous one's values (the table stays small and its capacity
    /// is reused; a block lowered again later only finds nothing).
    pub fn insert(&mut self, block: Block, key: VnKey, v: ir::Value) {
        if self.block != Some(block) {
            self.block = Some(block);
            self.values.clear();
        }
        self.values.insert(key, v);
    }

    /// Forget every value: the lowering moves to another function, whose blocks reuse the
    /// numbers of this one's.
    pub fn forget(&mut self) {
        self.block = None;
        self.values.clear();
    }
}

/// A multiply-rotate hasher for small keys of integers (the value-numbering table is
/// probed for every constant and operation lowered; SipHash cost more than it saved).
#[derive(Default)]
pub struct WordHasher(u64);

impl Hasher for WordHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u64(u64::from(b));
        }
    }
    fn write_u8(&mut self, i: u8) {
        self.write_u64(u64::from(i));
    }
    fn write_u32(&mut self, i: u32) {
        self.write_u64(u64::from(i));
    }
    fn write_usize(&mut self, i: usize) {
        self.write_u64(i as u64);
    }
    fn write_u64(&mut self, i: u64) {
        self.0 = (self.0.rotate_left(5) ^ i).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
    }
}

/// The Cranelift type of one component.
pub fn cl_type(scalar: Scalar, varying: bool) -> Type {
    match (scalar, varying) {
        (Scalar::Float, false) => types::F32,
        (Scalar::Int | Scalar::Fixed(_), false) => types::I32,
        (Scalar::Bool, false) => types::I8,
        (Scalar::Float, true) => F32X4,
        (_, true) => I32X4,
    }
}

/// Bytes one component takes in a stack slot or args word.
pub fn comp_bytes(varying: bool) -> u32 {
    if varying {
        16
    } else {
        4
    }
}

/// Flags for loads and stores of memory we own and know to be valid (stack slots, the
/// context). Not `aligned`: tile buffers come from the runtime without an alignment promise.
pub fn mem_flags() -> MemFlagsData {
    MemFlagsData::new().with_notrap()
}

/// Flags for argument-block loads: the block never changes while the kernel runs, so these
/// may be hoisted out of the pixel loops.
pub fn args_flags() -> MemFlagsData {
    MemFlagsData::new().with_notrap().with_readonly().with_can_move()
}

pub(super) fn bitcast_flags() -> MemFlagsData {
    MemFlagsData::new().with_endianness(ir::Endianness::Little)
}

/// Byte offsets of the [`TileCtx`] fields kernels touch.
pub mod ctx_off {
    use super::TileCtx;
    use std::mem::offset_of;
    pub const X0: i32 = offset_of!(TileCtx, x0) as i32;
    pub const Y0: i32 = offset_of!(TileCtx, y0) as i32;
    pub const X1: i32 = offset_of!(TileCtx, x1) as i32;
    pub const Y1: i32 = offset_of!(TileCtx, y1) as i32;
    pub const MODE: i32 = offset_of!(TileCtx, mode) as i32;
    pub const STRIDE: i32 = offset_of!(TileCtx, stride) as i32;
    pub const DEPTH: i32 = offset_of!(TileCtx, depth) as i32;
    pub const GBUF: i32 = offset_of!(TileCtx, gbuf) as i32;
    pub const PLANE_STRIDE: i32 = offset_of!(TileCtx, plane_stride) as i32;
    pub const NUM_PLANES: i32 = offset_of!(TileCtx, num_planes) as i32;
    pub const WRITE_COUNT: i32 = offset_of!(TileCtx, write_count) as i32;
    pub const BOUND: i32 = offset_of!(TileCtx, bound) as i32;
    pub const BOUND_SET: i32 = offset_of!(TileCtx, bound_set) as i32;
    pub const ERROR: i32 = offset_of!(TileCtx, error) as i32;
    pub const ERROR_SITE: i32 = offset_of!(TileCtx, error_site) as i32;
    pub const FUEL: i32 = offset_of!(TileCtx, fuel) as i32;
    pub const CALL_DEPTH: i32 = offset_of!(TileCtx, call_depth) as i32;
    pub const WIDTH: i32 = offset_of!(TileCtx, width) as i32;
    pub const HEIGHT: i32 = offset_of!(TileCtx, height) as i32;
    pub const EXPAND: i32 = offset_of!(TileCtx, expand) as i32;
    pub const STACK_LIMIT: i32 = offset_of!(TileCtx, stack_limit) as i32;
    pub const PIXEL_FUEL: i32 = offset_of!(TileCtx, pixel_fuel) as i32;
    pub const GROUP_FUEL_FLOOR: i32 = offset_of!(TileCtx, group_fuel_floor) as i32;
    pub const GROUP_FUEL: i32 = offset_of!(TileCtx, group_fuel) as i32;
    pub const SETUP_COUNTS: i32 = offset_of!(TileCtx, setup_counts) as i32;
    pub const PIXEL_COUNTS: i32 = offset_of!(TileCtx, pixel_counts) as i32;
    pub const SAMPLE_X: i32 = offset_of!(TileCtx, sample_x) as i32;
    pub const SAMPLE_Y: i32 = offset_of!(TileCtx, sample_y) as i32;
}

/// `f32x4` <-> `i32x4` reinterpretation.
pub fn to_i32x4(b: &mut FunctionBuilder, v: ir::Value) -> ir::Value {
    if b.func.dfg.value_type(v) == I32X4 {
        v
    } else {
        b.ins().bitcast(I32X4, bitcast_flags(), v)
    }
}

pub fn to_f32x4(b: &mut FunctionBuilder, v: ir::Value) -> ir::Value {
    if b.func.dfg.value_type(v) == F32X4 {
        v
    } else {
        b.ins().bitcast(F32X4, bitcast_flags(), v)
    }
}

/// Broadcast a uniform component to the varying form of `scalar` (bools become masks).
pub fn splat(b: &mut FunctionBuilder, scalar: Scalar, v: ir::Value) -> ir::Value {
    let ty = b.func.dfg.value_type(v);
    if ty.is_vector() {
        return v;
    }
    match scalar {
        Scalar::Bool => {
            let wide = b.ins().uextend(types::I32, v);
            let mask = b.ins().ineg(wide);
            b.ins().splat(I32X4, mask)
        }
        Scalar::Float => b.ins().splat(F32X4, v),
        _ => match iconst_i32(b, v) {
            // A constant: one vector constant (zero and all-ones need no memory) instead
            // of materialising the scalar and broadcasting it at run time.
            Some(c) => i32x4_const(b, c),
            None => b.ins().splat(I32X4, v),
        },
    }
}

/// The value of `v` if an `iconst.i32` defines it.
pub fn iconst_i32(b: &FunctionBuilder, v: ir::Value) -> Option<i32> {
    let v = b.func.dfg.resolve_aliases(v);
    if b.func.dfg.value_type(v) != types::I32 {
        return None;
    }
    match b.func.dfg.value_def(v) {
        ir::ValueDef::Result(inst, 0) => match b.func.dfg.insts[inst] {
            ir::InstructionData::UnaryImm {
                opcode: ir::Opcode::Iconst,
                imm,
            } => Some(imm.bits() as i32),
            _ => None,
        },
        _ => None,
    }
}

/// `c` in every lane of an i32x4, as a vector constant.
pub fn i32x4_const(b: &mut FunctionBuilder, c: i32) -> ir::Value {
    let mut bytes = Vec::with_capacity(16);
    for _ in 0..4 {
        bytes.extend_from_slice(&c.to_le_bytes());
    }
    let handle = b.func.dfg.constants.insert(bytes.into());
    b.ins().vconst(I32X4, handle)
}

/// Lanes of `mask` take `new`, the others keep `old` (both f32x4 or both i32x4).
pub fn blend(b: &mut FunctionBuilder, mask: ir::Value, new: ir::Value, old: ir::Value) -> ir::Value {
    let ty = b.func.dfg.value_type(new);
    if ty == F32X4 {
        // blendv is only lowered for integer lanes; a bitcast is free.
        let n = to_i32x4(b, new);
        let o = to_i32x4(b, old);
        let r = b.ins().blendv(mask, n, o);
        to_f32x4(b, r)
    } else {
        b.ins().blendv(mask, new, old)
    }
}

/// A zero of the given component form.
pub fn zero(b: &mut FunctionBuilder, scalar: Scalar, varying: bool) -> ir::Value {
    let ty = cl_type(scalar, varying);
    if varying {
        let s = zero(b, scalar, false);
        match scalar {
            Scalar::Float => b.ins().splat(ty, s),
            Scalar::Bool => {
                let z = b.ins().iconst(types::I32, 0);
                b.ins().splat(I32X4, z)
            }
            _ => b.ins().splat(ty, s),
        }
    } else if scalar == Scalar::Float {
        b.ins().f32const(0.0)
    } else {
        b.ins().iconst(ty, 0)
    }
}

/// An i32x4 mask with every lane set to `on`.
pub fn mask_const(b: &mut FunctionBuilder, on: bool) -> ir::Value {
    i32x4_const(b, if on { -1 } else { 0 })
}

/// Apply a scalar operation lane by lane to vectors (`f` gets the lanes of each operand).
pub fn map_lanes(
    b: &mut FunctionBuilder,
    out_ty: Type,
    operands: &[ir::Value],
    f: &mut dyn FnMut(&mut FunctionBuilder, &[ir::Value]) -> ir::Value,
) -> ir::Value {
    let mut out = None;
    for lane in 0..4u8 {
        let lanes: Vec<ir::Value> = operands.iter().map(|&v| b.ins().extractlane(v, lane)).collect();
        let r = f(b, &lanes);
        out = Some(match out {
            None => b.ins().scalar_to_vector(out_ty, r),
            Some(acc) => b.ins().insertlane(acc, r, lane),
        });
    }
    out.expect("four lanes")
}
