"""One fast-simplification call, in this process or in a child (:func:`start`, for the far
half of :func:`core.pyramid.simplify_halves`). The child is a fresh interpreter that
imports numpy and fast-simplification only, never the parent's main module; the arrays go
both ways as ``.npz`` bytes through its standard input and output."""

from __future__ import annotations

import io
import os
import subprocess
import sys
import threading

import numpy as np

#: what the child runs
CHILD = "from isochor.core._qem import serve; serve()"


def simplify_raw(
    points: np.ndarray, faces: np.ndarray, target: int, preserve_border: bool = False
) -> tuple[np.ndarray, np.ndarray]:
    """fast-simplification's QEM on writable ``(n, 3)`` float64 points and ``(f, 3)`` int32
    faces: ``(points, (g, 3) int64 faces)``. Not thread-safe (the extension keeps its mesh
    in global state): in this process, under :data:`core.pyramid._LOCK`."""
    import fast_simplification  # compiled extension: imported on the first use

    out, tri = fast_simplification.simplify(
        points, faces, target_count=int(target), preserve_border=preserve_border
    )
    return np.asarray(out, dtype=np.float64), np.asarray(tri, dtype=np.int64).reshape(-1, 3)


def start(points: np.ndarray, faces: np.ndarray, target: int) -> subprocess.Popen:
    """A child simplifying ``(points, faces)`` to ``target`` triangles, border kept; its
    input is written by a helper thread, so this returns at once. Raises OSError where no
    child can be started."""
    env = dict(os.environ)  # the child finds Isochor where this process found it
    env["PYTHONPATH"] = os.pathsep.join(p for p in sys.path if p and os.path.isdir(p))
    child = subprocess.Popen(
        [sys.executable, "-c", CHILD],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        env=env,
    )
    buf = io.BytesIO()
    np.savez(buf, points=points, faces=faces.astype(np.int32), target=np.array(int(target)))

    def feed() -> None:
        try:
            child.stdin.write(buf.getbuffer())
            child.stdin.close()
        except OSError:  # the child is gone: finish() says so
            pass

    threading.Thread(target=feed, name="isochor-qem-feed", daemon=True).start()
    return child


def finish(child: subprocess.Popen) -> tuple[np.ndarray, np.ndarray] | None:
    """The child's ``(points, faces)``; None when it failed."""
    data = child.stdout.read()
    child.stdout.close()
    if child.wait() != 0 or not data:
        return None
    with np.load(io.BytesIO(data)) as z:
        return np.array(z["points"]), np.array(z["faces"])


def serve() -> None:
    """The child's side of :func:`start`."""
    with np.load(io.BytesIO(sys.stdin.buffer.read())) as z:
        points, faces, target = np.array(z["points"]), np.array(z["faces"]), int(z["target"])
    out, tri = simplify_raw(points, faces, target, preserve_border=True)
    buf = io.BytesIO()
    np.savez(buf, points=out, faces=tri)
    sys.stdout.buffer.write(buf.getbuffer())
    sys.stdout.buffer.flush()
