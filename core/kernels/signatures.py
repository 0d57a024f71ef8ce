"""What each compiled kernel (:mod:`core.kernels`) is compiled for: its argument types.

Every kernel is compiled for exactly one signature, then its compiling is switched off, so
a call with other types raises (and :mod:`core.kernels` falls back to NumPy) instead of
compiling in the caller. Imported only by the loading thread and the compiling child.
"""

from __future__ import annotations

from types import SimpleNamespace


def compile_all() -> SimpleNamespace:
    """Compile the kernels for their argument types (or load them from numba's cache)."""
    from . import basis as _jitbasis
    from . import folds as _jitfolds
    from . import fused as _jitfused
    from . import local as _jitlocal
    from . import solver as _jitsolver
    from . import volume as _jitvolume
    from .base import numba

    t = numba.types
    f8, i8, i4 = t.float64, t.int64, t.int32

    def array(dtype, dims, readonly=True):  # read-only types also take writable arrays
        return t.Array(dtype, dims, "C", readonly=readonly)

    w1, w2 = array(f8, 1, False), array(f8, 2, False)
    r1, r2, r3, r4 = array(f8, 1), array(f8, 2), array(f8, 3), array(f8, 4)
    l1, l2, s1 = array(i8, 1), array(i8, 2), array(i4, 1)
    signatures = [
        (_jitbasis.apply_range, t.void(r2, r3, w2, i8, i8)),
        (_jitbasis.transpose_range, t.void(r2, r2, i8, i8, i8, i8, i8, w1)),
        (_jitvolume.build_fans, t.Tuple((array(i8, 1, False), array(i4, 1, False)))(l2, i8)),
        (_jitvolume.fan_gradient_range, f8(r2, f8, f8, f8, l1, s1, w2, i8, i8, f8)),
        (_jitvolume.face_volume_range, f8(r2, f8, f8, f8, s1, s1, s1, i8, i8)),
        (_jitvolume.winding_range, t.void(r2, r3, w1, i8, i8)),
        (
            _jitfused.evaluation_range,
            f8(
                r2,
                r3,
                i8,
                i8,
                i8,
                f8,
                f8,
                f8,
                s1,
                l1,
                array(i4, 2),
                s1,
                l1,
                s1,
                l1,
                s1,
                l1,
                i8,
                i8,
                i8,
                i8,
                i8,
                r2,
                w2,
                w2,
                w1,
            ),  # fmt: skip
        ),
        (_jitfolds.determinant_range, t.void(r2, r4, r2, w1, w1, i8, i8)),
        (_jitlocal.local_apply_range, t.void(r2, r2, l1, r4, w2, i8, i8)),
        (_jitlocal.local_transpose_range, t.void(r2, l1, r2, i8, i8, i8, i8, i8, w1)),
        (_jitlocal.local_determinant_range, t.void(r2, l1, r4, r2, w1, w1, i8, i8)),
        (_jitsolver.spring_energy_gradient, f8(r2, l1, l1, r1, f8, w2)),
        (_jitsolver.spring_hessian, t.void(r2, l1, l1, r1, f8, w2)),
        (_jitsolver.two_loop_first, t.void(w1, r2, r2, r1, i8, i8, w1)),
        (_jitsolver.two_loop_second, t.void(w1, r2, r2, r1, i8, i8, r1)),
        (_jitsolver.two_loop, t.UniTuple(f8, 2)(r1, r2, r2, r1, i8, i8, w1, r2, w1, w1)),
        (_jitsolver.push_pair, t.boolean(r1, r1, r1, r1, w2, w2, w1, i8)),
        (_jitsolver.spd_inverse, t.boolean(r2, f8, w2)),
    ]
    for fn, sig in signatures:
        fn.compile(sig)
        fn.disable_compile()  # a call with other types raises instead of compiling
    return SimpleNamespace(**{fn.__name__: fn for fn, _ in signatures})
