"""int16 arithmetic and popcount as LLVM operations, for the SGM kernels.

numba promotes ``int16 + int16`` to int64, which makes LLVM vectorise the aggregation loops 4x
narrower than it could (measured: 1.7 G path updates/s with plain int16 code, 6.4 G/s with these).
These intrinsics keep the arithmetic in 16 bits. They wrap around on overflow like C; the callers
keep every value inside int16 by construction (see ``core.check_penalties``).
"""

from __future__ import annotations

from llvmlite import ir
from numba import types
from numba.extending import intrinsic

__all__ = ["add16", "sub16", "min16", "umin16", "max16", "absdiff16", "and16", "shr16", "lshr16", "mulshr16",
           "mulhi16", "mullo16", "popxor16", "pick16", "eq16", "eq_mask32", "cttz64", "MASK_LANES"]


def _check_int16(*args: types.Type) -> None:
    for arg in args:
        if arg != types.int16:
            raise TypeError(f"int16 intrinsic needs int16 arguments, got {arg}")


@intrinsic
def add16(typingctx, a, b):
    """``a + b`` in int16 (wraps on overflow)."""
    _check_int16(a, b)

    def codegen(context, builder, signature, args):
        return builder.add(args[0], args[1])

    return types.int16(types.int16, types.int16), codegen


@intrinsic
def sub16(typingctx, a, b):
    """``a - b`` in int16 (wraps on overflow)."""
    _check_int16(a, b)

    def codegen(context, builder, signature, args):
        return builder.sub(args[0], args[1])

    return types.int16(types.int16, types.int16), codegen


@intrinsic
def min16(typingctx, a, b):
    """``min(a, b)`` for int16."""
    _check_int16(a, b)

    def codegen(context, builder, signature, args):
        a, b = args
        return builder.select(builder.icmp_signed("<", a, b), a, b)

    return types.int16(types.int16, types.int16), codegen


@intrinsic
def umin16(typingctx, a, b):
    """``min(a, b)`` for int16 values read as unsigned: the same as ``min16`` where both are non-negative. A minimum
    over a vector of non-negative values (path values and their sums) taken with it compiles to ``vpminuw`` and one
    ``vphminposuw`` on x86; the signed minimum needs a sign flip before and after the latter."""
    _check_int16(a, b)

    def codegen(context, builder, signature, args):
        a, b = args
        return builder.select(builder.icmp_unsigned("<", a, b), a, b)

    return types.int16(types.int16, types.int16), codegen


@intrinsic
def pick16(typingctx, take, a, b):
    """``a if take else b`` for int16 (a plain select: vectorises where numba's conditional expression did not)."""
    _check_int16(a, b)
    if take != types.boolean:
        raise TypeError(f"pick16 needs a boolean condition, got {take}")

    def codegen(context, builder, signature, args):
        cond, a, b = args
        if cond.type != ir.IntType(1):
            cond = builder.trunc(cond, ir.IntType(1))
        return builder.select(cond, a, b)

    return types.int16(types.boolean, types.int16, types.int16), codegen


@intrinsic
def max16(typingctx, a, b):
    """``max(a, b)`` for int16."""
    _check_int16(a, b)

    def codegen(context, builder, signature, args):
        a, b = args
        return builder.select(builder.icmp_signed(">", a, b), a, b)

    return types.int16(types.int16, types.int16), codegen


@intrinsic
def absdiff16(typingctx, a, b):
    """``|a - b|`` for int16 values whose difference fits int16."""
    _check_int16(a, b)

    def codegen(context, builder, signature, args):
        a, b = args
        d1 = builder.sub(a, b)
        d2 = builder.sub(b, a)
        return builder.select(builder.icmp_signed(">", d1, d2), d1, d2)

    return types.int16(types.int16, types.int16), codegen


@intrinsic
def and16(typingctx, a, b):
    """Bitwise ``a & b`` for int16."""
    _check_int16(a, b)

    def codegen(context, builder, signature, args):
        return builder.and_(args[0], args[1])

    return types.int16(types.int16, types.int16), codegen


@intrinsic
def shr16(typingctx, a, n):
    """Arithmetic ``a >> n`` for int16."""
    _check_int16(a, n)

    def codegen(context, builder, signature, args):
        return builder.ashr(args[0], args[1])

    return types.int16(types.int16, types.int16), codegen


@intrinsic
def lshr16(typingctx, a, n):
    """Logical ``a >> n`` for int16 (the 16 bits read as unsigned: a wrapped uint16 sum up to 65535 shifts right)."""
    _check_int16(a, n)

    def codegen(context, builder, signature, args):
        return builder.lshr(args[0], args[1])

    return types.int16(types.int16, types.int16), codegen


@intrinsic
def mulshr16(typingctx, a, m, n):
    """``(a * m) >> n`` with ``a`` and ``m`` read as unsigned 16-bit and the product taken in 32 bits (exact for
    any uint16 inputs), truncated to int16: the caller keeps the result below 2**15."""
    _check_int16(a, m, n)

    def codegen(context, builder, signature, args):
        i32 = ir.IntType(32)
        a32 = builder.zext(args[0], i32)
        m32 = builder.zext(args[1], i32)
        n32 = builder.zext(args[2], i32)
        return builder.trunc(builder.lshr(builder.mul(a32, m32), n32), ir.IntType(16))

    return types.int16(types.int16, types.int16, types.int16), codegen


@intrinsic
def mulhi16(typingctx, a, m):
    """``(a * m) >> 16`` with ``a`` and ``m`` read as unsigned 16-bit, as int16: the high half of the product
    (vpmulhuw, 32 lanes, where ``mulshr16`` widens to 32-bit lanes and narrows back)."""
    _check_int16(a, m)

    def codegen(context, builder, signature, args):
        i32 = ir.IntType(32)
        prod = builder.mul(builder.zext(args[0], i32), builder.zext(args[1], i32))
        return builder.trunc(builder.lshr(prod, ir.Constant(i32, 16)), ir.IntType(16))

    return types.int16(types.int16, types.int16), codegen


@intrinsic
def mullo16(typingctx, a, m, n):
    """``(a * m) >> n`` with the product kept in 16 bits (``a * m`` modulo 2**16, read as unsigned, then a logical
    shift), as int16: exact when the product of ``a`` and ``m`` (as unsigned) is below 2**16, which the caller
    guarantees. One vpmullw and one vpsrlw for 32 lanes; ``mulhi16`` (a 32-bit product in LLVM's IR) is lowered by
    numba's LLVM to the product in 32-bit lanes and a narrowing back, about eight instructions for 32 lanes."""
    _check_int16(a, m, n)

    def codegen(context, builder, signature, args):
        return builder.lshr(builder.mul(args[0], args[1]), args[2])

    return types.int16(types.int16, types.int16, types.int16), codegen


@intrinsic
def eq16(typingctx, a, b):
    """``a == b`` for int16 (a plain compare, for selects that must vectorise)."""
    _check_int16(a, b)

    def codegen(context, builder, signature, args):
        return builder.icmp_signed("==", args[0], args[1])

    return types.boolean(types.int16, types.int16), codegen


@intrinsic
def popxor16(typingctx, a, b):
    """Number of differing bits of two uint16, as int16 (``llvm.ctpop.i16``: vpopcntw with
    AVX512-BITALG, 32 lanes per vector and no narrowing, unlike the 64-bit popcount)."""
    for arg in (a, b):
        if arg != types.uint16:
            raise TypeError(f"popxor16 needs uint16 arguments, got {arg}")

    def codegen(context, builder, signature, args):
        i16 = ir.IntType(16)
        fn = builder.module.declare_intrinsic("llvm.ctpop", [i16])
        return builder.call(fn, [builder.xor(args[0], args[1])])

    return types.int16(types.uint16, types.uint16), codegen


#: Lanes of ``eq_mask32``: one 512-bit vector of int16 (two 256-bit ones where LLVM prefers those).
MASK_LANES = 32


@intrinsic
def eq_mask32(typingctx, row, start, value):
    """Bit i set where ``row[start + i] == value``, i in 0 .. 31, as uint64: one vector compare of 32 int16 lanes
    whose mask is read as an integer (``vpcmpeqw`` into a mask register and ``kmovd``), where a loop that finds
    the first equal index needs a select and a horizontal reduction. ``row``: a C-contiguous 1-d int16 array; the
    caller keeps ``start + 32 <= len(row)`` (no bounds check)."""
    if not (isinstance(row, types.Array) and row.ndim == 1 and row.dtype == types.int16 and row.layout == "C"):
        raise TypeError(f"eq_mask32 needs a C-contiguous 1-d int16 array, got {row}")
    if not isinstance(start, types.Integer):
        raise TypeError(f"eq_mask32 needs an integer start, got {start}")
    _check_int16(value)

    def codegen(context, builder, signature, args):
        i16, i32, i64 = ir.IntType(16), ir.IntType(32), ir.IntType(64)
        ary = context.make_array(signature.args[0])(context, builder, args[0])
        first = args[1]
        if first.type.width < 64:
            first = builder.zext(first, i64) if not signature.args[1].signed else builder.sext(first, i64)
        vty = ir.VectorType(i16, MASK_LANES)
        vec = builder.load(builder.bitcast(builder.gep(ary.data, [first]), vty.as_pointer()), align=2)
        one = builder.insert_element(ir.Constant(vty, ir.Undefined), args[2], ir.Constant(i32, 0))
        splat = builder.shuffle_vector(one, ir.Constant(vty, ir.Undefined),
                                       ir.Constant(ir.VectorType(i32, MASK_LANES), [0] * MASK_LANES))
        mask = builder.bitcast(builder.icmp_signed("==", vec, splat), ir.IntType(MASK_LANES))
        return builder.zext(mask, i64)

    return types.uint64(row, start, types.int16), codegen


@intrinsic
def cttz64(typingctx, m):
    """The number of trailing zero bits of a non-zero uint64 (``tzcnt``; undefined for 0)."""
    if m != types.uint64:
        raise TypeError(f"cttz64 needs a uint64, got {m}")

    def codegen(context, builder, signature, args):
        return builder.cttz(args[0], ir.Constant(ir.IntType(1), 1))

    return types.uint64(types.uint64), codegen
