"""The unrolled Bernstein kernel is generated from one source (tests/bern_source.py)."""

from __future__ import annotations

from math import comb
from pathlib import Path

import numpy as np

from tests.bern_source import TARGET, source

ROOT = Path(__file__).resolve().parents[1]


def test_the_kernel_file_is_what_its_generator_writes():
    assert (ROOT / TARGET).read_text() == source(), (
        f"{TARGET} differs from its generator: edit tests/bern_source.py and run "
        "`python -m tests.bern_source`"
    )


def test_the_generated_kernel_is_the_bernstein_basis():
    """The generated text, run as plain Python (numba's decorator stripped), against the
    closed form C(d, i) t^i (1 - t)^(d - i). Both are products of at most d + 2 rounded
    factors of at most 1 (times the exact integer C(d, i)), so each value differs by at most
    about (2d + 4) eps of the largest term; the d + 1 values sum to 1 within d + 1 times that."""
    text = source().replace("from .base import INLINE, njit\n", "")
    namespace: dict = {}
    exec(compile(text.replace("@njit(**INLINE)\n", ""), str(TARGET), "exec"), namespace)
    t = np.linspace(0.0, 1.0, 37)
    eps = np.finfo(float).eps
    for d in range(10):
        out = np.full((d + 1, len(t)), np.nan)
        namespace["_bernstein"](t, len(t), d, out)
        exact = np.array([comb(d, i) * t**i * (1 - t) ** (d - i) for i in range(d + 1)])
        bound = (2 * d + 4) * eps * exact.max(axis=0)
        assert np.all(np.abs(out - exact) <= bound), d
        assert np.all(np.abs(out.sum(axis=0) - 1.0) <= (d + 1) * (2 * d + 4) * eps), d
