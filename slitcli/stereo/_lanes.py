"""Explicit SIMD lanes for the SGM kernels (slitcli.stereo._sgm): numba types for
16 int16 lanes and 8 float32 lanes, and the few operations the kernels use.

Why: LLVM vectorises a loop over raw pointers only after run-time checks that its
stores do not overlap its loads, and gives up when a loop has more than one or two
store streams (slitcli.stereo._simd). SGM's natural loops have three (two path rows
and their sum) and the winner step two; split into one-store loops they re-read the
same data. With the lanes spelled out, a loop body of 16 disparities is one AVX2
instruction per operation whatever it stores, and the results are those of the
scalar code bit for bit (the same integer operations, wrapping in 16 bits as
``np.int16(...)`` does; the same float operations in the same order, without
contraction).

Kernels using these need the disparity count to be a multiple of the lane count;
the scalar kernels remain for other counts.
"""

from __future__ import annotations

from llvmlite import ir
from numba import types
from numba.extending import intrinsic, models, register_model

LANES16 = 16   # int16 lanes per vector (one AVX2 register)
LANES32 = 8    # float32 / int32 lanes per vector


class _Lanes(types.Type):
    def __init__(self, name: str) -> None:
        super().__init__(name=name)


I16x16 = _Lanes("i16x16")
F32x8 = _Lanes("f32x8")
I32x8 = _Lanes("i32x8")
_LLVM = {
    "i16x16": ir.VectorType(ir.IntType(16), 16),
    "f32x8": ir.VectorType(ir.FloatType(), 8),
    "i32x8": ir.VectorType(ir.IntType(32), 8),
}


@register_model(_Lanes)
class _LanesModel(models.PrimitiveModel):
    def __init__(self, dmm, fe_type):
        super().__init__(dmm, fe_type, _LLVM[fe_type.name])


def _vec_ptr(builder, p, k, vty):
    return builder.bitcast(builder.gep(p, [k]), vty.as_pointer())


@intrinsic
def load16(typingctx, p, k):
    """16 int16 from ``p + k`` (unaligned)."""
    if not (isinstance(p, types.CPointer) and p.dtype in (types.int16, types.uint16)):
        return None

    def codegen(context, builder, sig, args):
        return builder.load(_vec_ptr(builder, args[0], args[1], _LLVM["i16x16"]), align=2)

    return I16x16(p, k), codegen


@intrinsic
def store16(typingctx, p, k, v):
    """Store 16 int16 at ``p + k``."""
    if not (isinstance(p, types.CPointer) and v is I16x16):
        return None

    def codegen(context, builder, sig, args):
        builder.store(args[2], _vec_ptr(builder, args[0], args[1], _LLVM["i16x16"]), align=2)
        return context.get_dummy_value()

    return types.void(p, k, v), codegen


@intrinsic
def splat16(typingctx, x):
    """16 lanes of the integer ``x`` (truncated to 16 bits)."""
    if not isinstance(x, types.Integer):
        return None

    def codegen(context, builder, sig, args):
        v = builder.trunc(args[0], ir.IntType(16)) if x.bitwidth > 16 else args[0]
        if x.bitwidth < 16:
            v = builder.sext(v, ir.IntType(16))
        vec = ir.Constant(_LLVM["i16x16"], ir.Undefined)
        vec = builder.insert_element(vec, v, ir.Constant(ir.IntType(32), 0))
        return builder.shuffle_vector(vec, vec, ir.Constant(ir.VectorType(ir.IntType(32), 16),
                                                            [0] * 16))

    return I16x16(x), codegen


def _binary(op):
    @intrinsic
    def fn(typingctx, a, b):
        if a is not b or not isinstance(a, _Lanes):
            return None

        def codegen(context, builder, sig, args):
            x, y = args
            if op == "add":
                return builder.fadd(x, y) if a is F32x8 else builder.add(x, y)
            if op == "sub":
                return builder.fsub(x, y) if a is F32x8 else builder.sub(x, y)
            if op == "mul":
                return builder.fmul(x, y) if a is F32x8 else builder.mul(x, y)
            if op == "min":
                if a is F32x8:
                    return builder.select(builder.fcmp_ordered("<", x, y), x, y)
                return builder.select(builder.icmp_signed("<", x, y), x, y)
            if op == "max":
                if a is F32x8:
                    return builder.select(builder.fcmp_ordered(">", x, y), x, y)
                return builder.select(builder.icmp_signed(">", x, y), x, y)
            raise AssertionError(op)

        return a(a, b), codegen

    return fn


vadd = _binary("add")
vsub = _binary("sub")
vmul = _binary("mul")
vmin = _binary("min")
vmax = _binary("max")


@intrinsic
def hmin16(typingctx, v):
    """The smallest of 16 int16 lanes, as int32."""
    if v is not I16x16:
        return None

    def codegen(context, builder, sig, args):
        x = args[0]
        i32 = ir.IntType(32)
        for width in (8, 4, 2, 1):
            mask = ir.Constant(ir.VectorType(i32, 16),
                               [i + width if i < width else i for i in range(16)])
            y = builder.shuffle_vector(x, x, mask)
            x = builder.select(builder.icmp_signed("<", x, y), x, y)
        return builder.sext(builder.extract_element(x, ir.Constant(i32, 0)), i32)

    return types.int32(v), codegen


@intrinsic
def loadf8(typingctx, p, k):
    """8 float32 from ``p + k`` (unaligned)."""
    if not (isinstance(p, types.CPointer) and p.dtype is types.float32):
        return None

    def codegen(context, builder, sig, args):
        return builder.load(_vec_ptr(builder, args[0], args[1], _LLVM["f32x8"]), align=4)

    return F32x8(p, k), codegen


@intrinsic
def storef8(typingctx, p, k, v):
    """Store 8 float32 at ``p + k``."""
    if not (isinstance(p, types.CPointer) and v is F32x8):
        return None

    def codegen(context, builder, sig, args):
        builder.store(args[2], _vec_ptr(builder, args[0], args[1], _LLVM["f32x8"]), align=4)
        return context.get_dummy_value()

    return types.void(p, k, v), codegen


@intrinsic
def splatf8(typingctx, x):
    """8 lanes of the float32 ``x``."""
    if x is not types.float32:
        return None

    def codegen(context, builder, sig, args):
        vec = ir.Constant(_LLVM["f32x8"], ir.Undefined)
        vec = builder.insert_element(vec, args[0], ir.Constant(ir.IntType(32), 0))
        return builder.shuffle_vector(vec, vec,
                                      ir.Constant(ir.VectorType(ir.IntType(32), 8), [0] * 8))

    return F32x8(x), codegen


@intrinsic
def store_u16_where_positive(typingctx, p, k, q, w, top):
    """Store 8 uint16 at ``p + k``: ``uint16(int32(q))`` where ``w > 0``, else ``top``
    (the scalar ``np.uint16(np.int32(q)) if w > 0 else top``)."""
    if not (isinstance(p, types.CPointer) and q is F32x8 and w is F32x8):
        return None

    def codegen(context, builder, sig, args):
        i16 = ir.IntType(16)
        v16 = ir.VectorType(i16, 8)
        qi = builder.trunc(builder.fptosi(args[2], ir.VectorType(ir.IntType(32), 8)), v16)
        t = builder.trunc(args[4], i16) if top.bitwidth > 16 else args[4]
        tv = builder.insert_element(ir.Constant(v16, ir.Undefined), t,
                                    ir.Constant(ir.IntType(32), 0))
        tv = builder.shuffle_vector(tv, tv, ir.Constant(ir.VectorType(ir.IntType(32), 8),
                                                        [0] * 8))
        pos = builder.fcmp_ordered(">", args[3], ir.Constant(_LLVM["f32x8"], [0.0] * 8))
        builder.store(builder.select(pos, qi, tv), _vec_ptr(builder, args[0], args[1], v16),
                      align=2)
        return context.get_dummy_value()

    return types.void(p, k, q, w, top), codegen


def _where(pred):
    @intrinsic
    def fn(typingctx, a, b, x, y):
        if not (a is b and x is y and isinstance(a, _Lanes) and isinstance(x, _Lanes)):
            return None

        def codegen(context, builder, sig, args):
            if a is F32x8:
                m = builder.fcmp_ordered(pred, args[0], args[1])
            else:
                m = builder.icmp_signed(pred, args[0], args[1])
            return builder.select(m, args[2], args[3])

        return x(a, b, x, y), codegen

    return fn


#: ``where_lt(a, b, x, y)``: lane-wise ``x if a < b else y`` (``where_eq``: ``a == b``).
where_lt = _where("<")
where_eq = _where("==")


@intrinsic
def iota16(typingctx, k):
    """The lanes ``k, k + 1, ..., k + 15`` (int16)."""
    if not isinstance(k, types.Integer):
        return None

    def codegen(context, builder, sig, args):
        i16 = ir.IntType(16)
        v = builder.trunc(args[0], i16) if k.bitwidth > 16 else args[0]
        vec = ir.Constant(_LLVM["i16x16"], ir.Undefined)
        vec = builder.insert_element(vec, v, ir.Constant(ir.IntType(32), 0))
        vec = builder.shuffle_vector(vec, vec,
                                     ir.Constant(ir.VectorType(ir.IntType(32), 16), [0] * 16))
        return builder.add(vec, ir.Constant(_LLVM["i16x16"], list(range(16))))

    return I16x16(k), codegen


__all__ = [
    "LANES16",
    "LANES32",
    "F32x8",
    "I16x16",
    "I32x8",
    "hmin16",
    "iota16",
    "load16",
    "loadf8",
    "splat16",
    "splatf8",
    "store16",
    "store_u16_where_positive",
    "storef8",
    "vadd",
    "vmax",
    "vmin",
    "vmul",
    "vsub",
    "where_eq",
    "where_lt",
]
