"""Model files in and out: read, repair, rewrite in place, write anew.

- :mod:`.formats`   the file suffixes Isochor reads and writes (their one owner)
- :mod:`.meshio`    read OBJ/PLY/STL/OFF/glTF into a clean closed TriMesh (through
  :mod:`.repair`); write a mesh anew
- :mod:`.plyheader` the PLY header: its one parser and the one table of PLY's scalar types
  (for :mod:`.meshio` and :mod:`.roundtrip`)
- :mod:`.repair`    weld, drop degenerate triangles, check closed, repair winding, orient
- :mod:`.roundtrip` rewrite an OBJ/PLY/STL/OFF file: positions deformed, all else kept
- :mod:`.gltf`      read glTF/GLB; rewrite it deformed, or with a morph target
- :mod:`.gltfanim`  a solved sequence as one GLB: a morph target per frame, weights animated
- :mod:`.companions` the files a model reads besides itself (mtllib, textures, glTF
  buffers and images), which no output may name; glTF URIs confined to the model's folder
- :mod:`.atomic`    outputs checked before any work (never an input, a device, a folder), then
  written all or none through temporary files and renames

Uses the geometry at the top of :mod:`isochor.core` only.
"""
