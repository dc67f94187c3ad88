#!/usr/bin/env python3
"""mesh_scene.py - cornell-spheres with each analytic sphere replaced by a
mesh (usually an icosphere from bench/icosphere.c), for the mesh benchmarks
and tests.

usage: mesh_scene.py BASE.json SPHERE.obj [ACCEL] > scene.json
The mesh is a unit sphere; each sphere {center, radius} of BASE becomes a
mesh shape scaled by the radius and translated to the centre, keeping its
material. ACCEL, if given, is written to render.accel."""
import json
import sys


def main():
    if len(sys.argv) not in (3, 4):
        sys.stderr.write(__doc__)
        return 2
    with open(sys.argv[1]) as f:
        scene = json.load(f)
    shapes = []
    for sh in scene["shapes"]:
        if sh.get("type") == "sphere":
            mesh = {"type": "mesh", "file": sys.argv[2], "scale": sh["radius"], "translate": sh["center"]}
            for key in ("name", "material", "emission", "two_sided"):
                if key in sh:
                    mesh[key] = sh[key]
            sh = mesh
        shapes.append(sh)
    scene["shapes"] = shapes
    if len(sys.argv) == 4:
        scene["render"]["accel"] = sys.argv[3]
    json.dump(scene, sys.stdout, indent=2)
    sys.stdout.write("\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
