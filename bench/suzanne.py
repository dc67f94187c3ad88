# suzanne.py - a mesh a real user would render: Blender's Suzanne with a
# Catmull-Clark subdivision surface of LEVEL levels applied, triangulated,
# scaled to fit the unit sphere and written as a Wavefront OBJ in Tessera's
# axes (x, y, z) = (X, Z, -Y) from Blender's, so she faces +z (the
# cornell-spheres camera). For bench/meshes.sh (`make bench-meshes`).
#
# usage: blender -b --factory-startup -noaudio --python-exit-code 1 \
#          --python bench/suzanne.py -- LEVEL OUT.obj
import sys

import bpy


def main():
    argv = sys.argv[sys.argv.index("--") + 1:]
    level, out = int(argv[0]), argv[1]
    bpy.ops.mesh.primitive_monkey_add()
    ob = bpy.context.active_object
    mod = ob.modifiers.new("subsurf", "SUBSURF")
    mod.levels = level
    mod.render_levels = level
    me = ob.evaluated_get(bpy.context.evaluated_depsgraph_get()).to_mesh()
    me.calc_loop_triangles()
    r = max(v.co.length for v in me.vertices)
    with open(out, "w") as f:
        f.write("# Suzanne, subdivision level %d, %d triangles\n" % (level, len(me.loop_triangles)))
        f.write("".join("v %.6f %.6f %.6f\n" % (v.co.x / r, v.co.z / r, -v.co.y / r) for v in me.vertices))
        f.write("".join("f %d %d %d\n" % (t.vertices[0] + 1, t.vertices[1] + 1, t.vertices[2] + 1)
                        for t in me.loop_triangles))
    print("SUZANNE triangles=%d" % len(me.loop_triangles))


main()
