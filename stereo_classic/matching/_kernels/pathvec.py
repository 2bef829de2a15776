"""A pixel's path updates as whole LLVM vectors of its D disparities, for the one-sweep kernel (:mod:`.rowpass`).

``aggregate._lr`` reads the previous vector three times from memory: at d and one disparity either side. The two
shifted loads start two bytes off the vector's cache line, so each spans two lines, and the horizontal paths read
them from a vector stored by the previous pixel, which the store cannot forward to a load it only partly covers.
Here the horizontal paths' previous vector is one ``<D x i16>`` value, and its neighbours at d - 1 and d + 1 are
made from it in registers (one ``vpermi2w`` a 512-bit register, written out where 512-bit vectors are in use, else
LLVM's shuffles: :func:`_shifted`); the sentinel either end of the range is a constant. The top path's previous
vector was stored a row before, so its neighbours are loaded as ``_lr`` reads them (:func:`_top_update`: no store
in flight, and the loads spare the shuffle pipe). The
arithmetic is ``_lr``'s, in the same 16-bit operations (wrapping adds, signed minima, the vector's minimum unsigned),
so every value is the same bit for bit (tested against the loops).

The left and right paths' previous vectors and the right view's window (:func:`right_path_view`) are not stored at
all: the kernel carries them from one pixel to the next as :class:`PathVector` values, LLVM vectors that stay in
registers (no store and load of each path vector a pixel, which the next pixel waited for; OAK-D VGA, 64
disparities, 2 threads, six rounds alternated: 11.96 -> 11.56 ms a call, docs/matching.md "Eleventh round").

The functions are numba intrinsics; D comes from the buffers' ``tags.disparity_tag`` type, so each range gets its
own code, as the kernels do. :func:`vector_paths` says where they are used: D = 32, 64 or 128, one, two or four
512-bit registers of int16 (docs/matching.md, "Tenth round" and "Eleventh round": at 96 and 160 the kernel with the
vectors ran 1.2-1.4x the loops' time, at 192 and 256 the same; with the vectors carried in registers 3-5x).
"""

from __future__ import annotations

import llvmlite.binding as llvm
from llvmlite import ir
from numba import njit, types
from numba.core import cgutils
from numba.extending import intrinsic, models, register_model

from stereo_classic.matching._kernels import vectors
from stereo_classic.matching._kernels.aggregate import _INT16_MAX, _SENTINEL
from stereo_classic.matching._kernels.tags import _TAG_BLOCK

__all__ = ["VECTOR_BLOCK", "PathVector", "load_vector", "right_path_sum", "right_path_view", "store_vector",
           "top_and_left", "top_path", "vector_of", "vector_paths"]

#: int16 lanes of one 512-bit register: ``vector_paths`` holds for D = 1, 2 or 4 times this.
VECTOR_BLOCK = 32
assert VECTOR_BLOCK == _TAG_BLOCK  # vector_paths reads whole blocks off the tag

_I16 = ir.IntType(16)
_I32 = ir.IntType(32)


class PathVector(types.Type):
    """numba type of one pixel's D int16 values held as an LLVM ``<D x i16>`` value: a variable of it that the kernel
    carries from one pixel to the next stays in registers (the horizontal paths' previous vectors, the right view's
    window), where a buffer costs a store and a load per pixel."""

    def __init__(self, n: int):
        self.n = int(n)
        super().__init__(name=f"PathVector({self.n})")


@register_model(PathVector)
class _PathVectorModel(models.PrimitiveModel):
    def __init__(self, dmm, fe_type):
        super().__init__(dmm, fe_type, ir.VectorType(_I16, fe_type.n))


def _tag_d(tag: types.Type) -> int:
    """D of a ``disparity_tag`` type (the typing-time twin of ``tags.tag_disparities``)."""
    if not isinstance(tag, types.BaseTuple) or len(tag) != 2:
        raise TypeError(f"`tag` must be a tags.disparity_tag(D), got {tag}")
    return len(tag[0]) * _TAG_BLOCK + len(tag[1])


@njit(cache=True, nogil=True, inline="always")
def vector_paths(tag):  # pragma: no cover - numba
    """Whether the one-sweep kernel updates its paths with this module's intrinsics for the tag's D (a constant where
    the kernel is compiled, so the other branch is dropped): D = 32, 64 or 128.

    Those vectors are one, two or four whole 512-bit registers, and the four the kernel carries from pixel to pixel
    (the left and right paths, the right view's window of sums and indices) fit the 32 registers. Three or five
    registers (96, 160) LLVM shuffles and reduces badly (KITTI pair, 2 threads: 96 disparities 23.1 ms with the
    loops, 31.2 with the vectors loaded per pixel, 43.6 with the right view's window, 108 with the vectors in
    registers); at 192 and 256 the vectors gained nothing (35.6 / 36.7, 44.3 / 43.2 ms) and eight registers a path
    leave none to carry them in."""
    n = len(tag[0])  # D // 32 whole blocks of VECTOR_BLOCK (== _TAG_BLOCK) lanes, len(tag[1]) the rest
    return len(tag[1]) == 0 and (n == 1 or n == 2 or n == 4)


def _vector_ptr(context, builder, arrty, arr, index, D):
    data = context.make_array(arrty)(context, builder, arr).data
    return builder.bitcast(builder.gep(data, [index]), ir.PointerType(ir.VectorType(_I16, D)))


def _load(context, builder, arrty, arr, index, D):
    return builder.load(_vector_ptr(context, builder, arrty, arr, index, D), align=2)


def _store(context, builder, value, arrty, arr, index, D):
    builder.store(value, _vector_ptr(context, builder, arrty, arr, index, D), align=2)


def _splat(builder, value, D):
    vt = ir.VectorType(_I16, D)
    one = builder.insert_element(ir.Constant(vt, ir.Undefined), value, ir.Constant(_I32, 0))
    return builder.shuffle_vector(one, ir.Constant(vt, ir.Undefined), ir.Constant(ir.VectorType(_I32, D), [0] * D))


def _smin(builder, a, b):
    return builder.select(builder.icmp_signed("<", a, b), a, b)


def _umin(builder, vector, D):
    fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(_I16, [vector.type]),
                                        f"llvm.vector.reduce.umin.v{D}i16")
    return builder.call(fn, [vector])


def _index(builder, value):
    return builder.add(value, ir.Constant(value.type, 1))


def _pieces(builder, vector, D):
    """The 32-lane registers of a ``<D x i16>`` vector (no instructions: the vector lives in them)."""
    mask = ir.VectorType(_I32, VECTOR_BLOCK)
    return [builder.shuffle_vector(vector, ir.Constant(vector.type, ir.Undefined),
                                   ir.Constant(mask, list(range(i, i + VECTOR_BLOCK))))
            for i in range(0, D, VECTOR_BLOCK)]


def _joined(builder, pieces):
    """The ``<D x i16>`` vector of 32-lane registers (the inverse of ``_pieces``)."""
    while len(pieces) > 1:
        n = 2 * len(pieces[0].type)
        pieces = [builder.shuffle_vector(a, b, ir.Constant(ir.VectorType(_I32, n), list(range(n))))
                  for a, b in zip(pieces[::2], pieces[1::2])]
    return pieces[0]


def _asm_permutes() -> bool:
    """Whether ``_shifted`` writes its permutes out as ``vpermi2w``: where numba compiles for this machine's CPU with
    512-bit vectors preferred (``vectors.STATE`` "wide": AVX-512 BW at full clock, no ``NUMBA_CPU_NAME`` /
    ``NUMBA_CPU_FEATURES`` of the user's)."""
    return vectors.STATE == "wide"


#: ``_shifted``'s lowering (read when a kernel is compiled; the tests compile both).
ASM_PERMUTES = _asm_permutes()
if ASM_PERMUTES:
    llvm.initialize_native_asmparser()  # numba's JIT reads the inline assembly with it (it sets up the rest)


def _permute2(builder, a, b, index):
    """The two-table word permute of two 32-lane registers: lane k of the result is ``a[index[k]]`` for
    ``index[k] < 32``, else ``b[index[k] - 32]``, as one ``vpermi2w``."""
    fnty = ir.FunctionType(a.type, [a.type, a.type, a.type])
    return builder.asm(fnty, "vpermi2w $2, $1, $0", "=v,v,v,0", [a, b, ir.Constant(a.type, index)], False)


def _shifted(builder, vector, fill, up, D):
    """The lanes of ``vector`` moved by one: ``up``: lane k gets lane k + 1 (the last ``fill``), else lane k - 1 (the
    first ``fill``).

    Where ``ASM_PERMUTES``, one ``vpermi2w`` a register, written out: LLVM makes the move two shuffles a register
    (``valignq`` + ``vpalignr``), and this machine runs one shuffle a cycle whichever it is (while it runs two
    adds or minima), so the sweep's pace is set by them (docs/matching.md, "Twelfth round")."""
    vt = ir.VectorType(_I16, D)
    n = D // VECTOR_BLOCK
    if not ASM_PERMUTES or D % VECTOR_BLOCK or n & (n - 1):  # whole registers, 1, 2, 4, ... of them (``_joined``)
        edge = ir.Constant(vt, [fill] * D)
        mask = ir.VectorType(_I32, D)
        if up:
            return builder.shuffle_vector(vector, edge, ir.Constant(mask, [k + 1 for k in range(D)]))
        return builder.shuffle_vector(edge, vector, ir.Constant(mask, [0] + [D + k - 1 for k in range(1, D)]))
    regs = _pieces(builder, vector, D)
    edge = ir.Constant(ir.VectorType(_I16, VECTOR_BLOCK), [fill] * VECTOR_BLOCK)
    if up:
        index = list(range(1, VECTOR_BLOCK + 1))
        return _joined(builder, [_permute2(builder, regs[i], regs[i + 1] if i + 1 < len(regs) else edge, index)
                                 for i in range(len(regs))])
    index = [VECTOR_BLOCK - 1] + list(range(VECTOR_BLOCK, 2 * VECTOR_BLOCK - 1))
    return _joined(builder, [_permute2(builder, regs[i - 1] if i > 0 else edge, regs[i], index)
                             for i in range(len(regs))])


def _update(builder, prev, cost, m, q, p1, D, below=None, above=None):
    """``_lr`` for every disparity: ``cost - m + min(prev, min(prev[d - 1], prev[d + 1]) + p1, q)``, the sentinel
    beyond either end of the range (``below`` / ``above``: prev[d - 1] / prev[d + 1] where loaded, else made from
    ``prev`` in registers)."""
    if below is None:
        below = _shifted(builder, prev, _SENTINEL, False, D)
        above = _shifted(builder, prev, _SENTINEL, True, D)
    step = builder.add(_smin(builder, below, above), _splat(builder, p1, D))
    best = _smin(builder, _smin(builder, prev, step), _splat(builder, q, D))
    return builder.add(builder.sub(cost, _splat(builder, m, D)), best)


def _top_update(context, builder, arrty, P, rb, cost, m, q, p1, D):
    """The top path's update from its previous vector's slot at ``rb``: the vector and its neighbours at d - 1 and
    d + 1 are three loads (the slot's sentinels either side), not moves in registers. The slot was written a row
    before, so the two loads that start off its cache line wait on no store (the horizontal paths' previous vectors,
    stored one pixel before, would: they stay in registers), and they run on the load pipes where the moves took the
    one shuffle pipe, which bounds the sweep (docs/matching.md, "Fourteenth round")."""
    prev = _load(context, builder, arrty, P, _index(builder, rb), D)
    below = _load(context, builder, arrty, P, rb, D)
    above = _load(context, builder, arrty, P, _index(builder, _index(builder, rb)), D)
    return _update(builder, prev, cost, m, q, p1, D, below, above)


def _check(arrays, index_args, int16_args):
    for arg in arrays:
        if not (isinstance(arg, types.Array) and arg.dtype == types.int16 and arg.ndim == 1 and arg.layout == "C"):
            raise TypeError(f"path vector buffer must be a contiguous 1-d int16 array, got {arg}")
    for arg in index_args:
        if not isinstance(arg, types.Integer):
            raise TypeError(f"path vector index must be an integer, got {arg}")
    for arg in int16_args:
        if arg != types.int16:
            raise TypeError(f"path vector penalty / minimum must be int16, got {arg}")


@intrinsic
def vector_of(typingctx, value, tag):
    """A ``PathVector`` of the tag's D lanes, each ``value`` (int16)."""
    _check((), (), (value,))
    D = _tag_d(tag)

    def codegen(context, builder, signature, args):
        return _splat(builder, args[0], D)

    return PathVector(D)(value, tag), codegen


@intrinsic
def load_vector(typingctx, arr, index, tag):
    """A ``PathVector`` of ``arr[index:][:D]`` (D: the tag's)."""
    _check((arr,), (index,), ())
    D = _tag_d(tag)

    def codegen(context, builder, signature, args):
        return _load(context, builder, signature.args[0], args[0], args[1], D)

    return PathVector(D)(arr, index, tag), codegen


@intrinsic
def store_vector(typingctx, arr, index, vector):
    """``arr[index:][:D]`` = the lanes of ``vector`` (a ``PathVector``)."""
    if not isinstance(vector, PathVector):
        raise TypeError(f"store_vector needs a PathVector, got {vector}")
    _check((arr,), (index,), ())

    def codegen(context, builder, signature, args):
        _store(context, builder, args[2], signature.args[0], args[0], args[1], vector.n)
        return context.get_dummy_value()

    return types.none(arr, index, vector), codegen


def _check_vectors(D, *vectors):
    for v in vectors:
        if not (isinstance(v, PathVector) and v.n == D):
            raise TypeError(f"path vector of {D} lanes expected, got {v}")


@intrinsic
def top_path(typingctx, P, rb, wb, crow, cb, m, q, p1, tag):
    """The top path alone (warm-up rows): ``P[wb + 1:][:D]`` = the update of ``P[rb + 1:][:D]`` with the costs
    ``crow[cb:][:D]``; returns the new vector's minimum (unsigned). ``P[rb]`` and ``P[rb + D + 1]`` must hold the
    sentinel (``rowpass.path_slots`` puts it either side of every slot): they are read as the neighbours beyond
    the range."""
    _check((P, crow), (rb, wb, cb), (m, q, p1))
    D = _tag_d(tag)

    def codegen(context, builder, signature, args):
        P_, rb_, wb_, crow_, cb_, m_, q_, p1_, _ = args
        at = signature.args
        new = _top_update(context, builder, at[0], P_, rb_, _load(context, builder, at[3], crow_, cb_, D), m_, q_, p1_,
                          D)
        _store(context, builder, new, at[0], P_, _index(builder, wb_), D)
        return _umin(builder, new, D)

    return types.int16(P, rb, wb, crow, cb, m, q, p1, tag), codegen


@intrinsic
def top_and_left(typingctx, PV, rv, wv, H, crow, cb, mv, qv, p1v, mh, qh, p1, srow, tag):
    """The top path (``PV``, as :func:`top_path`, sentinels included) and the left path (the previous pixel's vector ``H``, a
    ``PathVector``) of one pixel from the same costs, their sum stored at ``srow[cb:][:D]``; returns the two new
    vectors' minima and the new left-path vector ``(top, left, H)``."""
    _check((PV, crow, srow), (rv, wv, cb), (mv, qv, p1v, mh, qh, p1))
    D = _tag_d(tag)
    _check_vectors(D, H)
    result = types.Tuple((types.int16, types.int16, H))

    def codegen(context, builder, signature, args):
        PV_, rv_, wv_, H_, crow_, cb_, mv_, qv_, p1v_, mh_, qh_, p1_, srow_, _ = args
        at = signature.args
        cost = _load(context, builder, at[4], crow_, cb_, D)
        vv = _top_update(context, builder, at[0], PV_, rv_, cost, mv_, qv_, p1v_, D)
        vh = _update(builder, H_, cost, mh_, qh_, p1_, D)
        _store(context, builder, vv, at[0], PV_, _index(builder, wv_), D)
        _store(context, builder, builder.add(vv, vh), at[12], srow_, cb_, D)
        return context.make_tuple(builder, result, [_umin(builder, vv, D), _umin(builder, vh, D), vh])

    return result(PV, rv, wv, H, crow, cb, mv, qv, p1v, mh, qh, p1, srow, tag), codegen


def _right_path(context, builder, at, args, D):
    """The right path's new vector from the previous one (a ``PathVector``) and the sums with it, stored at
    ``srow[cb:]``."""
    R_, crow_, cb_, mh_, qh_, p1_, srow_ = args[:7]
    vh = _update(builder, R_, _load(context, builder, at[1], crow_, cb_, D), mh_, qh_, p1_, D)
    sums = builder.add(vh, _load(context, builder, at[6], srow_, cb_, D))
    _store(context, builder, sums, at[6], srow_, cb_, D)
    return vh, sums


@intrinsic
def right_path_sum(typingctx, R, crow, cb, mh, qh, p1, srow, tag):
    """The right path of one pixel (from the previous pixel's vector ``R``, a ``PathVector``) added to its sums
    ``srow[cb:][:D]`` in place; returns ``(the path vector's minimum, the sums' minimum, the new vector)``."""
    _check((crow, srow), (cb,), (mh, qh, p1))
    D = _tag_d(tag)
    _check_vectors(D, R)
    result = types.Tuple((types.int16, types.int16, R))

    def codegen(context, builder, signature, args):
        vh, sums = _right_path(context, builder, signature.args, args, D)
        return context.make_tuple(builder, result, [_umin(builder, vh, D), _umin(builder, sums, D), vh])

    return result(R, crow, cb, mh, qh, p1, srow, tag), codegen


@intrinsic
def right_path_view(typingctx, R, crow, cb, mh, qh, p1, srow, VV, VK, tag):
    """:func:`right_path_sum`, and the right view's winners of the pixel's D right pixels in a window carried from
    pixel to pixel.

    Pixel x's sums land on the right pixels q = W - 1 - x + k (``select.right_view_row``): D consecutive ones, one
    further each pixel of the right-to-left sweep. ``VV`` / ``VK`` (``PathVector``) hold the lowest sum so far and
    its index for the previous pixel's D right pixels; no later pixel reaches the first of them, so it is returned,
    final, and the window moves on by one lane (the new last lane: ``INT16_MAX`` / -1, nothing yet) before this
    pixel's sums enter it. In the window the sums of lane k have index k, and the rule is ``right_view_row``'s
    (a lower sum, or the same with a lower index), so the winners are the same. Returns ``(the path vector's
    minimum, the sums' minimum, the finished right pixel's sum, its index, the new path vector, VV, VK)``; ``VV``
    and ``VK`` must start as ``INT16_MAX`` / -1 (a row's first pixel returns them), and hold the row's last D right
    pixels after its last.
    """
    _check((crow, srow), (cb,), (mh, qh, p1))
    D = _tag_d(tag)
    _check_vectors(D, R, VV, VK)
    result = types.Tuple((types.int16, types.int16, types.int16, types.int16, R, VV, VK))

    def codegen(context, builder, signature, args):
        vh, sums = _right_path(context, builder, signature.args, args, D)
        old_v, old_k = args[7], args[8]
        zero = ir.Constant(_I32, 0)
        vt = ir.VectorType(_I16, D)
        win_v = _shifted(builder, old_v, _INT16_MAX, True, D)
        win_k = _shifted(builder, old_k, -1, True, D)
        lanes = ir.Constant(vt, list(range(D)))
        take = builder.or_(builder.icmp_signed("<", sums, win_v),
                           builder.and_(builder.icmp_signed("==", sums, win_v), builder.icmp_signed("<", lanes, win_k)))
        return context.make_tuple(builder, result, [
            _umin(builder, vh, D), _umin(builder, sums, D), builder.extract_element(old_v, zero),
            builder.extract_element(old_k, zero), vh, _smin(builder, sums, win_v), builder.select(take, lanes, win_k)])

    return result(R, crow, cb, mh, qh, p1, srow, VV, VK, tag), codegen
