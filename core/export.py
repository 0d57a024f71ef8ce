"""The one export path: the command line's ``--out``, the window's Export and the Python
API's ``Session.export`` all come here.

The FFD is a map of space, so the export applies it to the model file as it was read,
not to the welded and repaired copy the solver works on:

- **the same format as the model** (OBJ, PLY, STL, OFF, glTF/GLB): the file is rewritten
  with its positions deformed and its normals transformed (the inverse transpose of the
  deformation's Jacobian), everything else kept: vertex count and order, texture
  coordinates, polygons, groups, materials, extra properties
  (:mod:`isochor.core.io.roundtrip`, :mod:`isochor.core.io.gltf`); a glTF can instead carry the
  deformation as a morph target on the original mesh;
- **glTF from a model file of another format** (OBJ to GLB): the file converted with what
  glTF carries of it (UVs, materials and their images, colours), then deformed as a glTF
  model is;
- **another format, or a built-in shape**: the deformed solver mesh (welded, triangles) is
  written fresh, and a note says what of the model's own file that format does not carry.

A written glTF travels: a GLB embeds every image it uses, a .gltf refers only to images
beside it and embeds the others (:mod:`isochor.core.io.gltf`).

A solved sequence as one animated GLB (:func:`export_sequence`) is the model's own file as
glTF (a glTF as it is; another format converted with its UVs, materials and colours) with
a morph target per frame and the animation of their weights.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import IsochorError
from .io.atomic import check_outputs, write_outputs
from .io.companions import model_inputs
from .io.formats import GLTF_FORMATS, WRITE_FORMATS, listing
from .io.meshio import mesh_bytes
from .io.plyheader import PlyHeader
from .scenario.problem import Problem, SourceFile


@dataclass(frozen=True)
class Exported:
    """A file to write and what the user should know about it (one sentence each)."""

    data: bytes
    notes: list[str] = field(default_factory=list)
    #: the volume of the model as the file stores it (its coordinates rounded as written:
    #: float32 in STL and glTF), None for a mesh of the caller's own kind
    volume: float | None = None
    #: whether the file stores float32 coordinates
    single: bool = False


def export_bytes(
    problem: Problem,
    nodes: np.ndarray,
    path: str | Path,
    *,
    morph_target: bool = False,
) -> Exported:
    """The deformed model as the file ``path`` names (the format by its suffix).

    Parameters
    ----------
    problem : the model, its lattice and where it came from
    nodes : (n, 3) the lattice node positions to deform by
    path : the output file (its folder resolves an OBJ's material library)
    morph_target : glTF only: keep the original positions and add the deformation as a
        morph target with weight 1

    Raises
    ------
    IsochorError
        An unknown suffix; a morph target asked of another format; the model file
        changed on disk since it was loaded.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in WRITE_FORMATS:
        raise IsochorError(f"{path}: the file name must end in {listing(WRITE_FORMATS)}")
    nodes = np.asarray(nodes, dtype=np.float64)
    exported = _export(problem, nodes, path, suffix, morph_target)
    if morph_target:
        return exported
    return _with_written_volume(problem, nodes, path, exported)


def _export(
    problem: Problem, nodes: np.ndarray, path: Path, suffix: str, morph_target: bool
) -> Exported:
    lattice = problem.surface.lattice
    source = problem.model.source
    same = source is not None and _kind(source.path.suffix) == _kind(suffix)
    if morph_target and not (suffix in GLTF_FORMATS and same):
        raise IsochorError(
            f"{path}: a morph target needs a glTF model exported as glTF (.glb or .gltf)"
        )
    # a model file written as glTF: the file converted (UVs, materials, colours), then
    # deformed as a glTF model is
    converted = source is not None and not same and suffix in GLTF_FORMATS
    if not same and not converted:
        full = problem.surface.full  # (the model's own surface: never its caps)
        mesh = full.moved(problem.surface.deform(nodes)).own
        notes = _lost(problem, path) if source is not None else []
        return Exported(mesh_bytes(mesh, suffix), notes)
    assert source is not None  # same: the source is of the same kind
    _check_unchanged(source)
    data, kind, notes = (
        _as_gltf(source.path, path) if converted else (source.path.read_bytes(), None, [])
    )

    def deform(points: np.ndarray) -> np.ndarray:
        return lattice.deform(points, nodes)

    def jacobian(points: np.ndarray) -> np.ndarray:
        return lattice.jacobian(points, nodes)

    exported = _rewrite(data, source.path, path, deform, jacobian, morph_target, kind)
    exported.notes[:0] = notes
    repairs = [w for w in problem.model.warnings if _REPAIRS.search(w)]
    if repairs:  # the file's own faces are kept: what the solve's copy had repaired is not
        exported.notes.append(
            f"{path.name} keeps {source.path.name}'s own faces as they were; the repairs made "
            f"for the solve are not in it ({' '.join(repairs)})"
        )
    return exported


def export_file(
    problem: Problem,
    nodes: np.ndarray,
    path: str | Path,
    *,
    morph_target: bool = False,
) -> list[str]:
    """Write :func:`export_bytes` to ``path`` atomically, never over the model file it was
    made from (checked before any work); returns the notes for the user. The window's
    Export and the API's ``Session.export`` (the command line writes it with its report,
    as a set)."""
    inputs = problem.scenario.inputs()  # the scenario, the model and the files it reads
    source = problem.model.source
    if source is not None:
        inputs += model_inputs(source.path)
    output = check_outputs([(path, "the export")], inputs, probe=False)[0]
    exported = export_bytes(problem, nodes, path, morph_target=morph_target)
    write_outputs([(output, exported.data)])
    return exported.notes


def export_sequence(
    problem: Problem, frames: list[np.ndarray], path: str | Path, rate: float
) -> Exported:
    """One animated GLB of the model deformed by each frame's lattice nodes (``frames``,
    each (n, 3)) at ``rate`` frames a second: the model's own file kept (mesh, UVs,
    materials, skin), a morph target per frame, the weights animated
    (:func:`isochor.core.io.gltf.animate_gltf`). A built-in shape has no file: its solver
    mesh is animated (:func:`isochor.core.io.gltfanim.animated_glb`)."""
    from .io.gltf import animate_gltf
    from .io.gltfanim import animated_glb

    path, source, surface = Path(path), problem.model.source, problem.surface
    if source is None:
        own = surface.full.own  # (never the caps over its holes)
        meshes = [surface.deform(nodes)[: own.n_vertices] for nodes in frames]
        return Exported(animated_glb(own.vertices, own.faces, meshes, rate))
    _check_unchanged(source)
    suffix = source.path.suffix.lower()
    notes: list[str] = []
    if suffix in GLTF_FORMATS:
        data = source.path.read_bytes()
    else:
        data, suffix, notes = _as_gltf(source.path, path)
    lattice = surface.lattice
    pairs = [
        (lambda x, n=n: lattice.deform(x, n), lambda x, n=n: lattice.jacobian(x, n))
        for n in (np.asarray(f, dtype=np.float64) for f in frames)
    ]
    data, more = animate_gltf(
        data, suffix, pairs, rate, name=source.path.name, base_dir=source.path.parent,
        out_dir=path.parent,
    )  # fmt: skip
    return Exported(data, notes + list(more))


def _check_unchanged(source: SourceFile) -> None:
    if not source.unchanged():
        raise IsochorError(
            f"{source.path}: the model file changed on disk since it was opened; open it "
            "again to export it"
        )


def _as_gltf(source: Path, out: Path) -> tuple[bytes, str, list[str]]:
    """A model file of another format (OBJ, PLY, STL, OFF) as a GLB with what glTF carries
    of it (its positions as in the file, UVs, materials and their images, colours;
    :func:`isochor.core.io.gltfanim.model_as_glb`): the data, its suffix, and a note where
    the model's polygons become triangles."""
    from .io.gltfanim import model_as_glb

    data, notes = model_as_glb(source), []
    if source.suffix.lower() == ".obj" and _OBJ_HOLDS["polygons"].search(source.read_bytes()):
        notes.append(f"{out.name} holds {source.name}'s polygons as triangles")
    return data, ".glb", notes


def _rewrite(
    data: bytes,
    source: Path,
    out: Path,
    deform: Callable[[np.ndarray], np.ndarray],
    jacobian: Callable[[np.ndarray], np.ndarray],
    morph_target: bool,
    kind: str | None = None,
) -> Exported:
    """``data`` (the model ``source``'s file, or ``kind``: it converted to that glTF
    suffix) rewritten deformed as ``out``."""
    suffix = kind or source.suffix.lower()
    if suffix in GLTF_FORMATS:
        from .io.gltf import rewrite_gltf

        new, notes = rewrite_gltf(
            data,
            suffix,
            deform,
            jacobian,
            name=source.name,
            base_dir=source.parent,
            morph_target=morph_target,
            out_suffix=out.suffix.lower(),  # .glb <-> .gltf: the same content
            out_dir=out.parent,  # separate images re-pointed from there
        )
        return Exported(new, list(notes))
    from .io.roundtrip import rewrite

    done = rewrite(
        data,
        suffix,
        deform,
        jacobian,
        name=source.name,
        source_dir=source.parent.absolute(),
        out_dir=out.parent.absolute(),
    )
    return Exported(done.data, list(done.notes))


#: formats whose coordinates are float32 (binary STL; glTF's POSITION accessors)
SINGLE_FORMATS = (".stl", ".glb", ".gltf")
_PLY_SINGLE = re.compile(rb"property[ \t]+(?:float|float32)[ \t]+x\b")


def _single(problem: Problem, path: Path) -> bool:
    """Whether ``path`` is written with float32 coordinates: STL and glTF always; a PLY
    rewritten in place keeps its own vertex type."""
    suffix = path.suffix.lower()
    if suffix in SINGLE_FORMATS:
        return True
    source = problem.model.source
    if suffix == ".ply" and source is not None and source.path.suffix.lower() == ".ply":
        try:
            with open(source.path, "rb") as fh:
                head = fh.read(4096).split(b"end_header", 1)[0]
        except OSError:
            return False
        return bool(_PLY_SINGLE.search(head))
    return False


def _with_written_volume(
    problem: Problem, nodes: np.ndarray, path: Path, exported: Exported
) -> Exported:
    """``exported`` with the volume its file holds: the deformed solid's vertices rounded
    as the format stores them, measured about their mean; and a note where that rounding
    (float32, or float64 far from the origin) moves the volume beyond the tolerance from
    the solved one."""
    from dataclasses import replace

    from .volume import signed_volume

    surface = problem.surface
    single = _single(problem, path)
    world = surface.deform(nodes)
    written = world.astype(np.float32).astype(np.float64) if single else world
    faces = surface.full.faces
    volume = signed_volume(written, faces)
    solved = surface.volume(nodes)
    rest = abs(surface.rest_volume) or 1.0
    change = (volume - solved) / rest
    notes = list(exported.notes)
    tolerance = problem.scenario.tol_volume
    if abs(change) > tolerance:
        how, fix = (
            ("to float32, as the format stores them", "export as .ply or .obj to keep every digit")
            if single
            else ("at the model's distance from the origin", "move the model nearer the origin")
        )
        notes.append(
            f"warning: {path.name} holds volume {volume:.9g}, not the solved {solved:.9g} "
            f"({change:+.2e} of the model's volume, beyond the tolerance {tolerance:g}): its "
            f"coordinates are rounded {how}; {fix}"
        )
    return replace(exported, notes=notes, volume=float(volume), single=single)


def _kind(suffix: str) -> str:
    suffix = suffix.lower()
    return "gltf" if suffix in GLTF_FORMATS else suffix


#: load warnings that changed the surface the solver works on (not the file's own faces)
_REPAIRS = re.compile(r"winding|turned to face|degenerate|duplicate", re.I)

#: what a model file may hold beyond positions and triangles, by a quick look at its text
_OBJ_HOLDS = {
    "texture coordinates": re.compile(rb"^vt[ \t]", re.M),
    "normals": re.compile(rb"^vn[ \t]", re.M),
    "groups and objects": re.compile(rb"^[go][ \t]", re.M),
    "materials": re.compile(rb"^(usemtl|mtllib)[ \t]", re.M),
    "polygons": re.compile(rb"^f([ \t]+\S+){4,}[ \t]*\r?$", re.M),
}


def _lost(problem: Problem, out: Path) -> list[str]:
    """One note naming what the model's own file holds that a fresh ``out`` does not: its
    texture coordinates, normals, polygons, groups, materials, extra properties, or its
    vertex numbering (when welding changed it). Nothing when nothing is lost."""
    assert problem.model.source is not None  # (called for a model read from a file)
    source = problem.model.source.path
    suffix = source.suffix.lower()
    try:
        data = source.read_bytes()
    except OSError:
        return []
    held: list[str] = []
    if suffix == ".obj":
        held = [what for what, pattern in _OBJ_HOLDS.items() if pattern.search(data)]
    elif suffix == ".ply":
        try:
            header = PlyHeader.parse(data, source.name)
        except IsochorError:  # (the model was read, so its header is not in doubt)
            header = None
        elements = header.elements if header is not None else ()
        props = [p.name for element in elements for p in element.properties]
        extra = [p for p in props if p not in ("x", "y", "z", "vertex_indices", "vertex_index")]
        held = [f"properties ({', '.join(extra)})"] if extra else []
    elif suffix in GLTF_FORMATS:
        held = ["texture coordinates, normals, materials and node hierarchy"]
    if suffix not in GLTF_FORMATS:
        from .io.roundtrip import positions

        try:
            raw = len(positions(data, suffix, name=source.name))
        except IsochorError:
            raw = problem.surface.full.own_vertices
        if raw != problem.surface.full.own_vertices:
            held.append(f"vertex numbering ({raw} vertices, {problem.surface.full.own_vertices} "
                        "once the ones that share a place are welded)")  # fmt: skip
    if not held:
        return []
    return [
        f"{out.name} is the welded triangle mesh: {source.name}'s {'; '.join(held)} are not "
        f"in it. Export as {suffix} to keep them."
    ]
