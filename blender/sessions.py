"""The Isochor session kept between the add-on's solves of one mesh and lattice.

Building an :class:`isochor.Session` is most of a solve's cost on a large mesh (the
welded and capped surface, its level pyramid, the springs' pattern), and none of it depends
on where the lattice points are or which are pinned. So a solve hands its session back
when it ends, and the next solve of the same problem takes it again: the same meshes as
they enter the modifier (their vertices and triangles, hashed), the same lattice
resolution, interpolation, rest frame and "outside" option, and the same way of counting
the volume (summed or per body). Anything else builds a new session. One session is kept
(a large mesh's session is hundreds of megabytes); a solve that was cancelled or raised
does not hand it back, since it may have stopped half way through its own state.

A session is taken by one solve at a time: :meth:`SessionCache.take` removes it from the
cache, so the solving thread, the live solver and the bake never share one.
"""

from __future__ import annotations

import hashlib
import threading

import numpy as np

from .rig import Rig


def problem_key(rig: Rig) -> bytes:
    """What a session of ``rig`` depends on, hashed: the meshes' vertices and triangles,
    the lattice's shape, bases, rest frame and "outside" option, and ``preserve``."""
    digest = hashlib.blake2b(digest_size=20)
    for array in (rig.vertices, rig.faces, rig.origin, rig.axes):
        a = np.ascontiguousarray(array)
        digest.update(f"{a.dtype.str}{a.shape}".encode())
        digest.update(a.tobytes())
    digest.update(repr((rig.shape, rig.basis, rig.outside, rig.counts, rig.preserve)).encode())
    return digest.digest()


class SessionCache:
    """At most one session, under the key of the problem it was built for."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._kept: tuple[bytes, object] | None = None
        self.built = 0  #: sessions built (the rest were taken from the cache)

    def take(self, key: bytes, rig: Rig, target: float = 1.0, progress=None):
        """A session of ``rig`` (whose :func:`problem_key` is ``key``) holding its points
        and pins, solving for ``target`` and telling ``progress``: the kept one when it was
        built for the same problem (it leaves the cache), else a new one."""
        with self._lock:
            kept, self._kept = self._kept, None
        if kept is None or kept[0] != key:
            del kept  # its memory is free before the new one is built
            self.built += 1
            return rig.session(target, progress)
        session = kept[1]
        session.progress = progress
        session.target = target
        rig.load(session)
        return session

    def keep(self, key: bytes, session) -> None:
        """Hand ``session`` (of the problem ``key``, its solve ended) back for the next."""
        with self._lock:
            self._kept = (key, session)

    def clear(self) -> None:
        with self._lock:
            self._kept = None


#: the add-on's one cache (cleared when the add-on is unregistered)
SESSIONS = SessionCache()
