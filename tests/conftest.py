"""Fixtures shared by the core tests."""

from __future__ import annotations

import os

import pytest


@pytest.fixture(params=["numpy", "compiled"])
def evaluation_path(request):
    """Run the test on each evaluation path of :mod:`isochor.core.kernels`: the NumPy one
    and the compiled one (skipped without numba or with ``ISOCHOR_NO_JIT`` set)."""
    from isochor.core import kernels

    if request.param == "compiled":
        pytest.importorskip("numba")
        if os.environ.get(kernels.ENV_OFF, "").strip() not in ("", "0"):
            pytest.skip(f"{kernels.ENV_OFF} is set")
        assert kernels.ready(timeout=600), kernels.status()
    previous = kernels.set_mode("numpy" if request.param == "numpy" else "auto")
    yield request.param
    kernels.set_mode(previous)
