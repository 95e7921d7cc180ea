"""LLVM intrinsics the CPU rasterizer's numba kernels use (`numba_tiles`): a fused multiply-add that forward
and backward round alike, a prefetch hint and a row copy as one memcpy. None of them changes a value's bits:
they only fix how the arithmetic rounds or how data moves."""

from __future__ import annotations

from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic


@intrinsic
def fma(typingctx, a, b, c):
    """a * b + c rounded once (llvm.fma): explicit, so forward and backward round alike (no fastmath)."""
    if isinstance(a, types.Float) and a == b == c:
        def codegen(context, builder, signature, args):
            return builder.fma(*args)
        return a(a, b, c), codegen
    return None



@intrinsic
def prefetch(typingctx, arr, i):
    """Hint the CPU to fetch row ``i`` of ``arr`` into the cache (llvm.prefetch: read, keep); no effect on
    any value."""
    if isinstance(arr, types.Array) and isinstance(i, types.Integer):
        def codegen(context, builder, signature, args):
            data, stride = array_row(context, builder, signature.args[0], args[0])
            row = context.cast(builder, args[1], signature.args[1], types.intp)
            ptr = builder.gep(data, [builder.mul(row, stride)])
            i32 = ir.IntType(32)
            fnty = ir.FunctionType(ir.VoidType(), [ptr.type, i32, i32, i32])
            fn = builder.module.declare_intrinsic("llvm.prefetch", [ptr.type], fnty)
            builder.call(fn, [ptr, i32(0), i32(3), i32(1)])
            return context.get_dummy_value()
        return types.void(arr, i), codegen
    return None


@intrinsic(prefer_literal=True)
def copy_row(typingctx, dst, k, src, r, width):
    """dst[k] = src[r] for two C-contiguous 2D arrays of one dtype whose rows hold the compile-time constant
    ``width`` values, as one llvm.memcpy (a few vector moves instead of ``width`` scalar ones: the bits are
    copied, nothing is computed)."""
    if (isinstance(dst, types.Array) and isinstance(src, types.Array) and dst.dtype == src.dtype
            and dst.ndim == src.ndim == 2 and dst.layout == src.layout == "C"
            and isinstance(width, types.IntegerLiteral)):
        def codegen(context, builder, signature, args):
            dty, kty, sty, rty, _ = signature.args
            d_data, d_stride = array_row(context, builder, dty, args[0])
            s_data, s_stride = array_row(context, builder, sty, args[2])
            kk = context.cast(builder, args[1], kty, types.intp)
            rr = context.cast(builder, args[3], rty, types.intp)
            d_ptr = builder.gep(d_data, [builder.mul(kk, d_stride)])
            s_ptr = builder.gep(s_data, [builder.mul(rr, s_stride)])
            n_bytes = context.get_constant(types.intp, width.literal_value * (dty.dtype.bitwidth // 8))
            cgutils.raw_memcpy(builder, d_ptr, s_ptr, n_bytes, 1, align=dty.dtype.bitwidth // 8)
            return context.get_dummy_value()
        return types.void(dst, k, src, r, width), codegen
    return None


def array_row(context, builder, aryty, value):
    """(byte pointer to the data, row stride in bytes) of an array value, for the intrinsics above."""
    ary = context.make_array(aryty)(context, builder, value)
    data = builder.bitcast(ary.data, ir.IntType(8).as_pointer())
    return data, cgutils.unpack_tuple(builder, ary.strides)[0]
