"""Block correlations of the support tests (slitcli.stereo._boundary), one at a time or
eight at a time.

The one-sided and cross support tests correlate small grey blocks of the left image
with the right image shifted by the tested pixel's own (subpixel) disparity. Every
pixel has its own shift, so the blocks of neighbouring pixels share no sums (no
running sums or integral images apply), and a block is a short chain of dependent
float additions: one block at a time, the processor waits on the adds' latency.

:func:`zncc_blocks` takes a row's blocks together and computes eight of them side by
side, one per lane of an AVX2 vector (:func:`_lanes8`): each lane runs exactly the
operations of :func:`zncc_block` in the same order (the same fused multiply-adds
that LLVM makes of the scalar code under ``contract``, spelled out), so every
correlation is the scalar one bit for bit (tests/test_stereo_zncc.py checks this on
random images and shifts). Blocks clipped by the image border run the scalar code.
"""

from __future__ import annotations

import numba as nb
import numpy as np
from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic

from slitcli.stereo._lanes import F32x8, loadf8, splatf8, vadd, vmul
from slitcli.stereo._simd import ptr

_FASTMATH = {"nsz", "arcp", "contract", "afn"}
_F8 = ir.VectorType(ir.FloatType(), 8)


@intrinsic
def _gatherf8(typingctx, p, idx, add):
    """8 float32 ``p[idx[j] + add]``, j = 0..7 (``idx``: pointer to 8 int64)."""
    if not (isinstance(p, types.CPointer) and p.dtype is types.float32
            and isinstance(idx, types.CPointer) and idx.dtype is types.int64
            and isinstance(add, types.Integer)):
        return None

    def codegen(context, builder, sig, args):
        base, index, k = args
        i64 = ir.IntType(64)
        k = context.cast(builder, k, sig.args[2], types.int64)
        vec = ir.Constant(_F8, ir.Undefined)
        for j in range(8):
            i = builder.add(builder.load(builder.gep(index, [ir.Constant(i64, j)])), k)
            vec = builder.insert_element(vec, builder.load(builder.gep(base, [i])),
                                         ir.Constant(ir.IntType(32), j))
        return vec

    return F32x8(p, idx, add), codegen


@intrinsic
def _fmaf8(typingctx, a, b, c):
    """Lane-wise ``a b + c`` rounded once (``llvm.fma``, the FMA instruction)."""
    if not (a is F32x8 and b is F32x8 and c is F32x8):
        return None

    def codegen(context, builder, sig, args):
        fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(_F8, [_F8] * 3),
                                            "llvm.fma.v8f32")
        return builder.call(fn, args)

    return F32x8(a, b, c), codegen


@intrinsic
def _lane(typingctx, v, j):
    """Lane ``j`` of an 8-lane float32 vector."""
    if not (v is F32x8 and isinstance(j, types.Integer)):
        return None

    def codegen(context, builder, sig, args):
        return builder.extract_element(args[0], args[1])

    return types.float32(v, j), codegen


@nb.njit(cache=True, fastmath=_FASTMATH, inline="always")
def _finish(sa, sb, saa, sbb, sab, cnt):
    """The correlation from the block's sums (``cnt`` samples); 0 for a flat block."""
    n = np.float32(cnt)
    va = saa - sa * sa / n
    vb = sbb - sb * sb / n
    cov = sab - sa * sb / n
    den = np.sqrt(max(va, np.float32(0.0)) * max(vb, np.float32(0.0)))
    return cov / den if den > 1e-3 else np.float32(0.0)


@nb.njit(cache=True, fastmath=_FASTMATH, inline="always")
def zncc_block(gl, gr, y, xc, d, rx, ry):
    """Zero-mean normalised correlation of the left block centred at (xc, y), (2rx+1)
    x (2ry+1) clipped to the image, with the right image at xc - d (linear in x);
    0 where a block is flat or too small."""
    height, width = gl.shape
    # every sample of the block shares the fractional shift: right column xx + off
    # and xx + off + 1 with weights 1 - t, t; the columns are clipped once
    off = int(np.floor(-d))
    t = -d - np.float32(off)
    c0 = max(xc - rx, 0, -off)
    c1 = min(xc + rx, width - 1, width - 2 - off)
    r0 = max(0, y - ry)
    r1 = min(height, y + ry + 1)
    cnt = (c1 - c0 + 1) * (r1 - r0)
    if c1 < c0 or cnt < 2:
        return np.float32(0.0)
    u = np.float32(1.0) - t
    sa = np.float32(0.0)
    sb = np.float32(0.0)
    saa = np.float32(0.0)
    sbb = np.float32(0.0)
    sab = np.float32(0.0)
    for yy in range(r0, r1):
        for xx in range(c0, c1 + 1):
            a = gl[yy, xx]
            b = u * gr[yy, xx + off] + t * gr[yy, xx + off + 1]
            sa += a
            sb += b
            saa += a * a
            sbb += b * b
            sab += a * b
    return _finish(sa, sb, saa, sbb, sab, cnt)


@nb.njit(cache=True, fastmath=_FASTMATH)
def _lanes8(pgl, pgr, base_l, base_r, u8, t8, lanes, rx, ry, width, out, k):
    """Eight unclipped blocks side by side: lane j's left block starts at flat index
    ``base_l[j]`` of ``gl``, its right samples at ``base_r[j]`` of ``gr`` (weights
    ``u8[j]``, ``t8[j]``); the first ``lanes`` results into ``out[k:]``."""
    u = np.float32(0.0)
    sa = splatf8(u)
    sb = sa
    saa = sa
    sbb = sa
    sab = sa
    vu = loadf8(ptr(u8), 0)
    vt = loadf8(ptr(t8), 0)
    for j in range(2 * ry + 1):
        for i in range(2 * rx + 1):
            k0 = j * width + i
            a = _gatherf8(pgl, ptr(base_l), k0)
            g0 = _gatherf8(pgr, ptr(base_r), k0)
            g1 = _gatherf8(pgr, ptr(base_r), k0 + 1)
            b = _fmaf8(vu, g0, vmul(vt, g1))
            sa = vadd(sa, a)
            sb = vadd(sb, b)
            saa = _fmaf8(a, a, saa)
            sbb = _fmaf8(b, b, sbb)
            sab = _fmaf8(a, b, sab)
    cnt = (2 * rx + 1) * (2 * ry + 1)
    for j in range(lanes):
        out[k + j] = _finish(_lane(sa, j), _lane(sb, j), _lane(saa, j), _lane(sbb, j),
                             _lane(sab, j), cnt)



@nb.njit(cache=True, fastmath=_FASTMATH)
def zncc_blocks(gl, gr, yc, xc, d, n, rx, ry, out):
    """``out[i] = zncc_block(gl, gr, yc[i], xc[i], d[i], rx, ry)`` for i < n, bit for
    bit; blocks inside the image eight at a time (module notes)."""
    height, width = gl.shape
    base_l = np.empty(8, np.int64)
    base_r = np.empty(8, np.int64)
    u8 = np.empty(8, np.float32)
    t8 = np.empty(8, np.float32)
    idx = np.empty(8, np.int64)
    lanes = 0
    for i in range(n):
        di = d[i]
        off = int(np.floor(-di))
        x0 = xc[i] - rx
        y0 = yc[i] - ry
        inside = (y0 >= 0 and yc[i] + ry < height and x0 >= 0 and x0 + off >= 0
                  and xc[i] + rx <= width - 2 - off and xc[i] + rx <= width - 1)
        if not inside:
            out[i] = zncc_block(gl, gr, yc[i], xc[i], di, rx, ry)
            continue
        t = -di - np.float32(off)
        base_l[lanes] = y0 * width + x0
        base_r[lanes] = y0 * width + x0 + off
        t8[lanes] = t
        u8[lanes] = np.float32(1.0) - t
        idx[lanes] = i
        lanes += 1
        if lanes == 8:
            _flush(gl, gr, base_l, base_r, u8, t8, idx, lanes, rx, ry, width, out)
            lanes = 0
    if lanes:
        _flush(gl, gr, base_l, base_r, u8, t8, idx, lanes, rx, ry, width, out)


@nb.njit(cache=True, fastmath=_FASTMATH, inline="always")
def _flush(gl, gr, base_l, base_r, u8, t8, idx, lanes, rx, ry, width, out):
    for j in range(lanes, 8):   # unused lanes repeat lane 0 (valid addresses)
        base_l[j] = base_l[0]
        base_r[j] = base_r[0]
        u8[j] = u8[0]
        t8[j] = t8[0]
    res = np.empty(8, np.float32)
    _lanes8(ptr(gl), ptr(gr), base_l, base_r, u8, t8, lanes, rx, ry, width, res, 0)
    for j in range(lanes):
        out[idx[j]] = res[j]
