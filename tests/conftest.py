"""Fixtures shared by the core tests."""

from __future__ import annotations

import os

import pytest


@pytest.fixture(scope="module")
def compiled():
    """The compiled kernels of :mod:`isochor.core.kernels`, waited for (compiling them on a
    first run); skips without numba or with ``ISOCHOR_NO_JIT`` set."""
    from isochor.core import kernels

    pytest.importorskip("numba")
    if os.environ.get(kernels.ENV_OFF, "").strip() not in ("", "0"):
        pytest.skip(f"{kernels.ENV_OFF} is set")
    assert kernels.ready(timeout=600), kernels.status()


@pytest.fixture(params=["numpy", "compiled"])
def evaluation_path(request):
    """Run the test on each evaluation path of :mod:`isochor.core.kernels`: the NumPy one
    and the compiled one (see :func:`compiled`)."""
    from isochor.core import kernels

    if request.param == "compiled":
        request.getfixturevalue("compiled")
        yield request.param
        return
    with kernels.numpy_path():
        yield request.param
