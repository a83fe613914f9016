"""Low-level helpers for the compiled stereo kernels: float bit patterns and raw pointers.

Why raw pointers: the inner loops of the Eq. 10 matcher run over the disparities of one
pixel (a few dozen to a few hundred floats). LLVM vectorises such a loop only when it
can check at run time that the arrays it writes do not overlap the ones it reads, and
numba cannot tell it that they never do. Two things were measured on the matcher's
loops (slitcli.stereo._nssd): inlined into the pixel loop they stay scalar (LLVM's cost
model rejects the per-pixel overlap checks), and as separate functions they vectorise
but each call passes every array as a 7-9 field struct. Passing data pointers instead
of arrays cuts a call to a handful of arguments (about 40 % faster per pixel at 64
disparities).

A pointer does not keep its array alive, and numba frees an array right after the
last use of its variable: take pointers inside the loop that uses them (the array's
variable is then live through the loop), never once before it.
"""

from __future__ import annotations

import numba as nb
from llvmlite import ir
from numba import types
from numba.extending import intrinsic


@intrinsic
def bits(typingctx, x):
    """The bit pattern of a float32 as an int32 (non-negative floats order like it)."""
    sig = nb.int32(nb.float32)

    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], ir.IntType(32))

    return sig, codegen


@intrinsic
def from_bits(typingctx, x):
    """The float32 whose bit pattern is the int32 ``x`` (inverse of :func:`bits`)."""
    sig = nb.float32(nb.int32)

    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], ir.FloatType())

    return sig, codegen


@intrinsic
def ptr(typingctx, arr):
    """Pointer to the first element of a C-contiguous array (index it like a 1-D
    array: no bounds check, no negative-index wraparound)."""
    if not isinstance(arr, types.Array):
        return None
    sig = types.CPointer(arr.dtype)(arr)

    def codegen(context, builder, signature, args):
        return context.make_array(signature.args[0])(context, builder, args[0]).data

    return sig, codegen


@intrinsic
def offset(typingctx, p, k):
    """``p + k`` elements."""
    if not isinstance(p, types.CPointer) or not isinstance(k, types.Integer):
        return None
    sig = p(p, k)

    def codegen(context, builder, signature, args):
        return builder.gep(args[0], [args[1]])

    return sig, codegen
