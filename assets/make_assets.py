"""Regenerate the shipped assets: the sample models, the example scenarios and the icon.

Usage::

    python assets/make_assets.py [OUT_DIR]
    python -m isochor.assets.make_assets [OUT_DIR]

``OUT_DIR`` defaults to this script's folder (``assets/``). The output is deterministic: every
run writes byte-identical files (OBJ numbers in a fixed ``%.9g`` format, JSON from
:meth:`isochor.core.scenario.document.Scenario.write`, a PNG without timestamps). Files are written
atomically, so an interrupted run leaves the previous files whole.
"""

from __future__ import annotations

import argparse
import io
import sys
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from isochor.assets import EXAMPLE_NAMES, EXAMPLES_SUBDIR, ICON_FILE, MODEL_FILES
from isochor.core.io.atomic import atomic_write_bytes, atomic_write_text
from isochor.core.mesh import TriMesh
from isochor.core.scenario.examples import EXAMPLES, example_scenario
from isochor.core.scenario.shapes import club_levels, cup_levels, torus_levels

#: This script's folder, the default output folder.
HERE = Path(__file__).resolve().parent

#: Triangle counts of the shipped models (torus levels: 16 * 4**k, club levels: 20 * 4**k).
TORUS_TRIANGLES = 4096
CLUB_TRIANGLES = 5120
#: the open cup's own triangles (its levels have 56, 240, 992, 4032, ...)
CUP_TRIANGLES = 4032

#: Icon size in pixels, and how much finer it is drawn before it is scaled down (smooth edges).
ICON_SIZE = 256
_SUPERSAMPLE = 4

# The icon's colours.
_BACKGROUND = (34, 38, 48, 255)  # dark slate
_CLAY = (0xD8, 0xD2, 0xC4, 255)  # warm clay, the model
_CLAY_SHADE = (0xA8, 0x9F, 0x8D, 255)  # its shadowed side
_SKY_BLUE = (0x56, 0xB4, 0xE9, 255)  # lattice nodes and lines
_ORANGE = (0xE6, 0x9F, 0x00, 255)  # the moved node


def _level(levels: list[TriMesh], n_triangles: int, what: str) -> TriMesh:
    for mesh in levels:
        if mesh.n_faces == n_triangles:
            return mesh
    counts = ", ".join(str(m.n_faces) for m in levels)
    raise RuntimeError(f"{what}: no level with {n_triangles} triangles (levels: {counts})")


def torus_mesh() -> TriMesh:
    """The built-in torus at its level with :data:`TORUS_TRIANGLES` triangles."""
    return _level(torus_levels(5), TORUS_TRIANGLES, "torus")


def club_mesh() -> TriMesh:
    """The paper's rounded club at its level with :data:`CLUB_TRIANGLES` triangles."""
    return _level(club_levels(5), CLUB_TRIANGLES, "club")


def cup_mesh() -> TriMesh:
    """The built-in open cup at its level with :data:`CUP_TRIANGLES` triangles of its own,
    without the virtual cap over its rim (a file holds the model's own faces only)."""
    own = [m.own for m in cup_levels(5)]
    return _level(own, CUP_TRIANGLES, "cup")


def obj_text(mesh: TriMesh, comment: str) -> str:
    """``mesh`` as OBJ text: one comment line, ``v`` lines in ``%.9g``, 1-based ``f`` lines.

    Coordinates within 1e-12 of zero are written as 0, so rounding noise of the sampling
    (``sin(pi)`` and the like, or a ``-0``) cannot change the file."""
    v = np.asarray(mesh.vertices, dtype=np.float64)
    v = np.where(np.abs(v) < 1e-12, 0.0, v)
    lines = [f"# {comment}"]
    lines += [f"v {x:.9g} {y:.9g} {z:.9g}" for x, y, z in v.tolist()]
    lines += [f"f {a} {b} {c}" for a, b, c in (mesh.faces + 1).tolist()]
    return "\n".join(lines) + "\n"


def icon_png() -> bytes:
    """The application icon as PNG bytes: a squashed clay torus in a 3x3 lattice on a dark
    rounded square, one lattice node (orange) pulled up."""
    s = _SUPERSAMPLE

    def px(*values: float) -> list[int]:
        return [round(a * s) for a in values]

    img = Image.new("RGBA", (ICON_SIZE * s, ICON_SIZE * s), (0, 0, 0, 0))
    draw = ImageDraw.Draw(img)
    draw.rounded_rectangle(px(8, 8, 247, 247), radius=44 * s, fill=_BACKGROUND)

    # The squashed torus: a shadowed rim, the body, the hole (with its shadowed far wall).
    draw.ellipse(px(38, 98, 218, 172), fill=_CLAY_SHADE)
    draw.ellipse(px(38, 92, 218, 164), fill=_CLAY)
    draw.ellipse(px(100, 117, 156, 141), fill=_CLAY_SHADE)
    draw.ellipse(px(100, 121, 156, 141), fill=_BACKGROUND)

    # The 3x3 lattice; node (1, 0) (top middle) is moved up.
    xs, ys = (56, 128, 200), (72, 128, 184)
    nodes = {(i, j): (xs[i], ys[j]) for i in range(3) for j in range(3)}
    moved = (1, 0)
    nodes[moved] = (128, 40)
    for (i, j), (x, y) in nodes.items():
        for di, dj in ((1, 0), (0, 1)):
            other = nodes.get((i + di, j + dj))
            if other is not None:
                draw.line(px(x, y, *other), fill=_SKY_BLUE, width=3 * s)
    for key, (x, y) in nodes.items():
        r = 11 if key == moved else 9
        draw.ellipse(px(x - r - 2, y - r - 2, x + r + 2, y + r + 2), fill=_BACKGROUND)
        draw.ellipse(px(x - r, y - r, x + r, y + r), fill=_ORANGE if key == moved else _SKY_BLUE)

    img = img.resize((ICON_SIZE, ICON_SIZE), Image.Resampling.LANCZOS)
    buf = io.BytesIO()
    img.save(buf, format="PNG", optimize=False)  # no text chunks, no timestamp
    return buf.getvalue()


def write_assets(out_dir: str | Path = HERE) -> list[Path]:
    """(Re)write every asset into ``out_dir`` (created if needed); returns the files written.

    ``out_dir/torus.obj``, ``out_dir/club.obj``, ``out_dir/examples/<name>.json`` for every
    example, ``out_dir/icon.png``."""
    if tuple(EXAMPLES) != EXAMPLE_NAMES:
        raise RuntimeError(
            "isochor.assets.EXAMPLE_NAMES differs from isochor.core.scenario.examples.EXAMPLES; "
            f"update it to {tuple(EXAMPLES)!r}"
        )
    out = Path(out_dir)
    (out / EXAMPLES_SUBDIR).mkdir(parents=True, exist_ok=True)
    written: list[Path] = []

    models = {
        "torus": (torus_mesh(), f"built-in torus, {TORUS_TRIANGLES} triangles"),
        "club": (club_mesh(), f"the paper's rounded club, {CLUB_TRIANGLES} triangles"),
        "cup": (cup_mesh(), f"built-in open cup, {CUP_TRIANGLES} triangles, open at its rim"),
    }
    for name, (mesh, what) in models.items():
        path = out / MODEL_FILES[name]
        atomic_write_text(path, obj_text(mesh, f"Isochor {what}; written by assets/make_assets.py"))
        written.append(path)

    for name in EXAMPLE_NAMES:
        path = out / EXAMPLES_SUBDIR / f"{name}.json"
        example_scenario(name).write(path)
        written.append(path)

    path = out / ICON_FILE
    atomic_write_bytes(path, icon_png())
    written.append(path)
    return written


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description="Regenerate Isochor's shipped sample models, example scenarios and icon."
    )
    parser.add_argument(
        "out_dir",
        nargs="?",
        type=Path,
        default=HERE,
        help="output folder (default: the assets folder, %(default)s)",
    )
    args = parser.parse_args(argv)
    for path in write_assets(args.out_dir):
        print(f"{path}  ({path.stat().st_size} bytes)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
