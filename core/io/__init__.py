"""Model files in and out: read, repair, rewrite in place, write anew.

- :mod:`.formats`   the file suffixes Isochor reads and writes (their one owner)
- :mod:`.meshio`    read OBJ/PLY/STL/OFF/glTF into a clean closed TriMesh (through
  :mod:`.repair`); write a mesh anew
- :mod:`.objfile`   the OBJ reader by the format's rules (indices from 1, negative ones
  relative, objects apart), every error naming the file and line
- :mod:`.plyheader` the PLY header: its one parser and the one table of PLY's scalar types
  (for :mod:`.meshio` and :mod:`.roundtrip`)
- :mod:`.repair`    weld, drop degenerate triangles, split, repair winding, cap, orient
- :mod:`.caps`      open surfaces closed virtually: non-manifold edges split into sheets,
  holes capped with fans appended after the model's own vertices and faces
- :mod:`.roundtrip` rewrite an OBJ/PLY/STL/OFF file: positions deformed, all else kept
- :mod:`.gltf`      read glTF/GLB; rewrite it deformed, with a morph target, or animated (a
  morph target per frame, weights animated); a GLB embeds its images, a .gltf those not beside it
- :mod:`.gltfanim`  a sequence's GLB: another format's model file as glTF (UVs, materials),
  or a built-in shape's bare mesh animated
- :mod:`.companions` the files a model reads besides itself (mtllib, textures, glTF
  buffers and images), which no output may name; glTF URIs confined to the model's folder
- :mod:`.atomic`    outputs checked before any work (never an input, a device, a folder), then
  written all or none through temporary files and renames

Uses the geometry at the top of :mod:`isochor.core` only.
"""
