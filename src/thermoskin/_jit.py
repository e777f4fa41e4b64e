"""numba, as the package's compiled modules import it: ``from thermoskin._jit import njit, prange``.

Importing numba through here makes it load cached code without what only compiling needs
(:func:`thermoskin._numba_cache.lean_loading`: no registries, no BLAS probe, so no
``scipy.linalg``, on a short ``observe``) before any compiled call, so that no compiled
module can forget it. Also :func:`prefetch_w`, a cache hint numba has no word for.
"""

from __future__ import annotations

from llvmlite import binding as _llvm
from llvmlite import ir
from numba import njit, prange, types
from numba.core import cgutils
from numba.extending import intrinsic

from thermoskin._numba_cache import lean_loading

lean_loading()

# LLVM 15 on has opaque pointers, and the intrinsic's name says so
_PREFETCH = "llvm.prefetch.p0" if _llvm.llvm_version_info >= (15,) else "llvm.prefetch.p0i8"


@intrinsic
def prefetch_w(typingctx, arr, idx):  # type: ignore[no-untyped-def]
    """In compiled code, ``prefetch_w(a, i)``: the cache line holding ``a[i]`` (a 1-D array) will
    be written soon; fetch it now, without waiting for it (LLVM's ``llvm.prefetch``, write,
    kept in every cache level: x86's ``prefetchw``). A hint: no effect on any value."""
    if not (isinstance(arr, types.Array) and arr.ndim == 1 and isinstance(idx, types.Integer)):
        return None
    sig = types.void(arr, idx)

    def codegen(context, builder, signature, args):  # type: ignore[no-untyped-def]
        aryty = signature.args[0]
        ary = context.make_array(aryty)(context, builder, args[0])
        ptr = cgutils.get_item_pointer(context, builder, aryty, ary, [args[1]])
        i8p, i32 = ir.IntType(8).as_pointer(), ir.IntType(32)
        fn = cgutils.get_or_insert_function(
            builder.module, ir.FunctionType(ir.VoidType(), [i8p, i32, i32, i32]), _PREFETCH)
        # write (1), high locality (3), data (1)
        builder.call(fn, [builder.bitcast(ptr, i8p), i32(1), i32(3), i32(1)])
        return context.get_dummy_value()

    return sig, codegen


@intrinsic
def fetch_add(typingctx, arr, idx, val):  # type: ignore[no-untyped-def]
    """In compiled code, ``fetch_add(a, i, v)``: add ``v`` to ``a[i]`` (a 1-D int64 array) in one
    atomic step, whatever other threads do to it meanwhile, and return the value it had (LLVM's
    ``atomicrmw add``, monotonic: the word alone is ordered, no other memory)."""
    if not (isinstance(arr, types.Array) and arr.ndim == 1 and arr.dtype == types.int64
            and isinstance(idx, types.Integer) and isinstance(val, types.Integer)):
        return None
    sig = types.int64(arr, idx, val)

    def codegen(context, builder, signature, args):  # type: ignore[no-untyped-def]
        aryty = signature.args[0]
        ary = context.make_array(aryty)(context, builder, args[0])
        ptr = cgutils.get_item_pointer(context, builder, aryty, ary, [args[1]])
        v = context.cast(builder, args[2], signature.args[2], types.int64)
        return builder.atomic_rmw("add", ptr, v, "monotonic")

    return sig, codegen


__all__ = ["fetch_add", "njit", "prange", "prefetch_w"]
