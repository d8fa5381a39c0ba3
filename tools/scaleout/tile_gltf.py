#!/usr/bin/env python3
"""Tile a glTF scene NX × NZ times (issue 22's "world tiled 2 × 2"): a benchmark scene, never a fixture.

    tools/scaleout/tile_gltf.py IN.gltf OUT.gltf NX NZ DX DZ

Writes OUT.gltf beside IN.gltf's buffers and images (OUT must be in the same folder, so relative URIs
resolve): the default scene's root nodes copied once per tile (meshes, buffers and images shared), each
copy under a parent node translated by (ix · DX, 0, iz · DZ) in the glTF frame (Y up; DX and DZ in the
scene's units, e.g. its extent plus a gap).
"""
import copy
import json
import os
import sys


def main():
    if len(sys.argv) != 7:
        sys.exit(__doc__)
    src, dst = sys.argv[1], sys.argv[2]
    nx, nz = int(sys.argv[3]), int(sys.argv[4])
    dx, dz = float(sys.argv[5]), float(sys.argv[6])
    if os.path.dirname(os.path.abspath(src)) != os.path.dirname(os.path.abspath(dst)):
        sys.exit("OUT must be in the same folder as IN (relative buffer and image URIs)")
    doc = json.load(open(src))
    scene = doc["scenes"][doc.get("scene", 0)]
    nodes = doc["nodes"]
    roots = list(scene["nodes"])

    def copy_subtree(i):
        n = copy.deepcopy(nodes[i])
        if "children" in n:
            n["children"] = [copy_subtree(c) for c in n["children"]]
        nodes.append(n)
        return len(nodes) - 1

    tiles = []
    for ix in range(nx):
        for iz in range(nz):
            kids = roots if (ix, iz) == (0, 0) else [copy_subtree(r) for r in roots]
            nodes.append({"name": f"tile {ix},{iz}", "translation": [ix * dx, 0.0, iz * dz], "children": kids})
            tiles.append(len(nodes) - 1)
    scene["nodes"] = tiles
    json.dump(doc, open(dst, "w"))
    print(f"{dst}: {nx}×{nz} tiles of {len(roots)} root nodes, {len(nodes)} nodes")


if __name__ == "__main__":
    main()
