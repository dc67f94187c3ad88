# render_scene.py - render a Tessera JSON scene with Blender Cycles, for
# comparing the two renderers on the same scene in the same run.
#
# usage:
#   blender -b --factory-startup -noaudio --python-exit-code 1 \
#     --python bench/cycles/render_scene.py -- SCENE.json -o OUT.exr \
#     [--width W] [--height H] [--spp N] [--seed S] [--max-bounces B] \
#     [--threads T] [--sphere-subdiv K] [--scale F]
#
# The scene is rebuilt in metres (--scale 0.001, the Cornell box's
# millimetres): Blender (X, Y, Z) = scale * (x, -z, y) from Tessera's
# (x, y, z). That map is a rotation (determinant +1), so windings, normals
# and the camera's right-hand direction (forward x up in both) carry over.
#
# Materials (docs/scene-format.md):
#   diffuse  -> Diffuse BSDF, colour = albedo (Lambert, exact)
#   mirror   -> Glossy BSDF, Sharp, colour = reflectance (exact)
#   glass    -> Glass BSDF, Sharp, IOR, colour = transmission (exact for a
#               white transmission; Cycles tints the reflection too)
#   glossy   -> Add Shader(Diffuse kd, Glossy Beckmann ks) with Beckmann
#               roughness alpha = sqrt(2 / (n + 2)) (Walter et al. 2007's
#               Phong-exponent match), Blender roughness = sqrt(alpha).
#               APPROXIMATE: a microfacet lobe with shadowing and no
#               cos^n shape; do not compare phong scenes pixel for pixel.
#   emission -> Emission, colour = radiance, strength 1 (Cycles' mesh
#               emission with strength 1 emits radiance = colour); one-sided
#               emitters go black on the back face (Geometry.Backfacing mix).
# Point lights: Blender point light of radius 0, power P = 4 pi I scale^2
# (Cycles gives a point light of power P the intensity P / (4 pi) W/sr, and
# Tessera's intensity is per squared scene unit).
# Spheres: icospheres with 20 * 4^K triangles (K = --sphere-subdiv, default 8:
# 1.31 M triangles, as in ../shared/anchors.md), smooth shaded; their
# vertices lie on the sphere.
# Background: the world colour (radiance); black turns the world off.
#
# Cycles settings: CPU, T threads, box pixel filter of width 1 pixel, no
# adaptive sampling, no denoising, no clamping, Filter Glossy 0, reflective
# and refractive caustics, max bounces B for every kind, default sampler
# (progressive multi-jitter), fixed seed, view transform Standard, output an
# OpenEXR of 32-bit float linear RGB.
#
# Prints one machine-readable line after the render:
#   CYCLES render_s=SECONDS spp=N width=W height=H max_bounces=B triangles=T
# where SECONDS is wall time around bpy.ops.render.render (scene sync and BVH
# build included; Blender start-up and building the meshes in Python
# excluded). Any bad input: a message naming the file and field, exit 1.
import json
import math
import os
import sys
import time

import bmesh
import bpy
from mathutils import Matrix, Vector


# Bump when the scene translation changes: it renames the cached references.
SCENE_MAP_VERSION = 1


class SceneError(Exception):
    pass


def parse_args(argv):
    args = {"width": 256, "height": 256, "spp": 64, "seed": 1, "max_bounces": 1024,
            "threads": 2, "sphere_subdiv": 8, "scale": 0.001, "out": None, "scene": None}
    names = {"--width": "width", "--height": "height", "--spp": "spp", "--seed": "seed",
             "--max-bounces": "max_bounces", "--threads": "threads", "--sphere-subdiv": "sphere_subdiv"}
    i = 0
    while i < len(argv):
        a = argv[i]
        if a in names or a in ("-o", "--scale"):
            if i + 1 >= len(argv):
                raise SceneError("%s needs a value" % a)
            v = argv[i + 1]
            if a == "-o":
                args["out"] = v
            elif a == "--scale":
                args["scale"] = float(v)
            else:
                try:
                    args[names[a]] = int(v)
                except ValueError:
                    raise SceneError("%s: not an integer: %r" % (a, v))
            i += 2
        elif a.startswith("-"):
            raise SceneError("unknown option %s" % a)
        else:
            if args["scene"] is not None:
                raise SceneError("one scene only (got %s and %s)" % (args["scene"], a))
            args["scene"] = a
            i += 1
    if args["scene"] is None or args["out"] is None:
        raise SceneError("usage: ... -- SCENE.json -o OUT.exr [options]")
    if not (0 <= args["sphere_subdiv"] <= 9):
        raise SceneError("--sphere-subdiv must be 0 to 9")
    if args["max_bounces"] < 0 or args["spp"] < 1 or args["threads"] < 1:
        raise SceneError("--max-bounces >= 0, --spp >= 1 and --threads >= 1 are required")
    return args


class Converter:
    """Tessera coordinates (scene units) to Blender metres."""

    def __init__(self, scale):
        self.s = scale

    def point(self, p):
        x, y, z = p
        return Vector((self.s * x, -self.s * z, self.s * y))

    def direction(self, d):
        x, y, z = d
        return Vector((x, -z, y))


def vec3(obj, key, where, default=None):
    v = obj.get(key, default)
    if v is None:
        raise SceneError("%s.%s: missing" % (where, key))
    if not (isinstance(v, list) and len(v) == 3 and all(isinstance(c, (int, float)) for c in v)):
        raise SceneError("%s.%s: expected [x, y, z]" % (where, key))
    return [float(c) for c in v]


def num(obj, key, where, default=None):
    v = obj.get(key, default)
    if not isinstance(v, (int, float)):
        raise SceneError("%s.%s: expected a number" % (where, key))
    return float(v)


def node_tree_reset(mat):
    mat.use_nodes = True
    nt = mat.node_tree
    for n in list(nt.nodes):
        nt.nodes.remove(n)
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    return nt, out


def bsdf_node(nt, spec, where):
    """The BSDF node for a Tessera material; None for no material."""
    if spec is None:
        return None
    kind = spec.get("type")
    if kind == "diffuse":
        n = nt.nodes.new("ShaderNodeBsdfDiffuse")
        n.inputs["Color"].default_value = vec3(spec, "albedo", where) + [1.0]
        n.inputs["Roughness"].default_value = 0.0
        return n
    if kind == "mirror":
        n = nt.nodes.new("ShaderNodeBsdfGlossy")
        n.distribution = "SHARP"
        n.inputs["Color"].default_value = vec3(spec, "reflectance", where, [1, 1, 1]) + [1.0]
        return n
    if kind == "glass":
        n = nt.nodes.new("ShaderNodeBsdfGlass")
        n.distribution = "SHARP"
        n.inputs["Color"].default_value = vec3(spec, "transmission", where, [1, 1, 1]) + [1.0]
        n.inputs["IOR"].default_value = num(spec, "ior", where, 1.5)
        return n
    if kind == "glossy":
        kd = vec3(spec, "diffuse", where)
        ks = vec3(spec, "specular", where)
        exponent = num(spec, "exponent", where)
        d = nt.nodes.new("ShaderNodeBsdfDiffuse")
        d.inputs["Color"].default_value = kd + [1.0]
        g = nt.nodes.new("ShaderNodeBsdfGlossy")
        g.distribution = "BECKMANN"
        alpha = math.sqrt(2.0 / (exponent + 2.0))
        g.inputs["Roughness"].default_value = math.sqrt(alpha)
        g.inputs["Color"].default_value = ks + [1.0]
        add = nt.nodes.new("ShaderNodeAddShader")
        nt.links.new(d.outputs[0], add.inputs[0])
        nt.links.new(g.outputs[0], add.inputs[1])
        return add
    raise SceneError("%s.type: unknown material type %r" % (where, kind))


def make_material(name, spec, emission, two_sided, where):
    """A Blender material: BSDF, plus emission (one- or two-sided)."""
    mat = bpy.data.materials.new(name)
    nt, out = node_tree_reset(mat)
    surf = bsdf_node(nt, spec, where)
    if emission is not None and any(c > 0 for c in emission):
        em = nt.nodes.new("ShaderNodeEmission")
        em.inputs["Color"].default_value = list(emission) + [1.0]
        em.inputs["Strength"].default_value = 1.0
        em_out = em.outputs[0]
        if not two_sided:
            # Front face: the emission; back face: nothing (black emission).
            geo = nt.nodes.new("ShaderNodeNewGeometry")
            black = nt.nodes.new("ShaderNodeEmission")
            black.inputs["Strength"].default_value = 0.0
            mix = nt.nodes.new("ShaderNodeMixShader")
            nt.links.new(geo.outputs["Backfacing"], mix.inputs[0])
            nt.links.new(em.outputs[0], mix.inputs[1])
            nt.links.new(black.outputs[0], mix.inputs[2])
            em_out = mix.outputs[0]
        if surf is not None:
            add = nt.nodes.new("ShaderNodeAddShader")
            nt.links.new(surf.outputs[0], add.inputs[0])
            nt.links.new(em_out, add.inputs[1])
            surf_out = add.outputs[0]
        else:
            surf_out = em_out
    elif surf is not None:
        surf_out = surf.outputs[0]
    else:  # neither: black, reflects nothing
        em = nt.nodes.new("ShaderNodeEmission")
        em.inputs["Strength"].default_value = 0.0
        surf_out = em.outputs[0]
    nt.links.new(surf_out, out.inputs["Surface"])
    return mat


def mesh_object(name, verts, faces, mat, smooth=False):
    me = bpy.data.meshes.new(name)
    me.from_pydata([tuple(v) for v in verts], [], faces)
    me.validate()
    me.update()
    if smooth:
        me.polygons.foreach_set("use_smooth", [True] * len(me.polygons))
    me.materials.append(mat)
    ob = bpy.data.objects.new(name, me)
    bpy.context.scene.collection.objects.link(ob)
    return ob


def read_obj(path, where):
    """Vertices and fan-triangulated faces of a Wavefront OBJ (v and f)."""
    verts, faces = [], []
    try:
        f = open(path, "r", encoding="utf-8", errors="replace")
    except OSError as e:
        raise SceneError("%s.file: cannot open %s: %s" % (where, path, e.strerror))
    with f:
        for lineno, line in enumerate(f, 1):
            t = line.split()
            if not t:
                continue
            if t[0] == "v":
                try:
                    verts.append([float(c) for c in t[1:4]])
                except ValueError:
                    raise SceneError("%s:%d: bad vertex" % (path, lineno))
            elif t[0] == "f":
                idx = []
                for c in t[1:]:
                    try:
                        i = int(c.split("/")[0])
                    except ValueError:
                        raise SceneError("%s:%d: bad face index %r" % (path, lineno, c))
                    i = i - 1 if i > 0 else len(verts) + i
                    if not (0 <= i < len(verts)):
                        raise SceneError("%s:%d: face index out of range" % (path, lineno))
                    idx.append(i)
                for k in range(1, len(idx) - 1):
                    tri = (idx[0], idx[k], idx[k + 1])
                    if len(set(tri)) == 3:
                        faces.append(tri)
    return verts, faces


def ico_sphere(name, center, radius, subdiv, mat):
    me = bpy.data.meshes.new(name)
    bm = bmesh.new()
    # bmesh counts the icosahedron itself as subdivision 1.
    bmesh.ops.create_icosphere(bm, subdivisions=subdiv + 1, radius=radius)
    bm.to_mesh(me)
    bm.free()
    me.polygons.foreach_set("use_smooth", [True] * len(me.polygons))
    me.materials.append(mat)
    me.update()
    ob = bpy.data.objects.new(name, me)
    ob.location = center
    bpy.context.scene.collection.objects.link(ob)
    return ob, len(me.polygons)


def build_scene(path, args):
    try:
        with open(path, "r", encoding="utf-8") as f:
            doc = json.load(f)
    except OSError as e:
        raise SceneError("%s: cannot open: %s" % (path, e.strerror))
    except ValueError as e:
        raise SceneError("%s: %s" % (path, e))
    cv = Converter(args["scale"])
    base = os.path.dirname(os.path.abspath(path))
    scene = bpy.context.scene

    # Camera.
    cam = doc.get("camera")
    if not isinstance(cam, dict):
        raise SceneError("%s: camera: missing" % path)
    if cam.get("type", "perspective") != "perspective":
        raise SceneError("%s: camera.type: only \"perspective\" is supported here" % path)
    pos = vec3(cam, "position", path + ": camera")
    look = vec3(cam, "look_at", path + ": camera")
    up = vec3(cam, "up", path + ": camera", [0, 1, 0])
    fov = num(cam, "fov", path + ": camera")
    cd = bpy.data.cameras.new("camera")
    cd.sensor_fit = "VERTICAL"
    cd.angle_y = math.radians(fov)
    cd.clip_start = 1e-6  # Blender's smallest: Tessera has no near clip
    cd.clip_end = 1e8
    co = bpy.data.objects.new("camera", cd)
    scene.collection.objects.link(co)
    forward = (cv.point(look) - cv.point(pos)).normalized()
    upv = cv.direction(up).normalized()
    right = forward.cross(upv).normalized()
    cam_up = right.cross(forward)
    # Blender's camera looks down its -Z with +Y up and +X right.
    rot = Matrix((right, cam_up, -forward)).transposed()
    co.matrix_world = Matrix.Translation(cv.point(pos)) @ rot.to_4x4()
    scene.camera = co

    mats = doc.get("materials", {})
    cache = {}
    triangles = 0
    for i, sh in enumerate(doc.get("shapes", [])):
        where = "%s: shapes[%d]" % (path, i)
        mname = sh.get("material")
        if mname is not None and mname not in mats:
            raise SceneError("%s.material: unknown material %r" % (where, mname))
        emission = sh.get("emission")
        if emission is not None:
            emission = vec3(sh, "emission", where)
        two = bool(sh.get("two_sided", False))
        key = (mname, tuple(emission) if emission else None, two)
        if key not in cache:
            cache[key] = make_material("m%d" % len(cache), mats.get(mname) if mname else None, emission, two,
                                       "%s: materials.%s" % (path, mname))
        mat = cache[key]
        kind = sh.get("type")
        name = sh.get("name", "shape%d" % i)
        if kind in ("triangle", "quad"):
            vs = sh.get("vertices")
            n = 3 if kind == "triangle" else 4
            if not (isinstance(vs, list) and len(vs) == n):
                raise SceneError("%s.vertices: expected %d points" % (where, n))
            pts = [cv.point(vec3({"v": v}, "v", where + ".vertices")) for v in vs]
            faces = [(0, 1, 2)] if n == 3 else [(0, 1, 2), (0, 2, 3)]  # Tessera's v0-v2 split
            mesh_object(name, pts, faces, mat)
            triangles += len(faces)
        elif kind == "sphere":
            c = vec3(sh, "center", where)
            r = num(sh, "radius", where)
            _, nt = ico_sphere(name, cv.point(c), r * args["scale"], args["sphere_subdiv"], mat)
            triangles += nt
        elif kind == "mesh":
            f = sh.get("file")
            if not isinstance(f, str):
                raise SceneError("%s.file: missing" % where)
            scale = num(sh, "scale", where, 1.0)
            tr = vec3(sh, "translate", where, [0, 0, 0])
            verts, faces = read_obj(os.path.join(base, f), where)
            pts = [cv.point([v[k] * scale + tr[k] for k in range(3)]) for v in verts]
            mesh_object(name, pts, faces, mat)
            triangles += len(faces)
        else:
            raise SceneError("%s.type: unknown shape type %r" % (where, kind))

    for i, li in enumerate(doc.get("lights", [])):
        where = "%s: lights[%d]" % (path, i)
        if li.get("type") != "point":
            raise SceneError("%s.type: unknown light type %r" % (where, li.get("type")))
        inten = vec3(li, "intensity", where)
        power = max(inten)
        ld = bpy.data.lights.new("point%d" % i, "POINT")
        ld.shadow_soft_size = 0.0
        if power > 0:
            ld.color = [c / power for c in inten]
        ld.energy = 4.0 * math.pi * power * args["scale"] ** 2
        lo = bpy.data.objects.new("point%d" % i, ld)
        lo.location = cv.point(vec3(li, "position", where))
        scene.collection.objects.link(lo)

    world = bpy.data.worlds.new("world")
    world.use_nodes = True
    bg = world.node_tree.nodes["Background"]
    back = vec3(doc, "background", path, [0, 0, 0])
    bg.inputs["Color"].default_value = back + [1.0]
    bg.inputs["Strength"].default_value = 1.0 if any(c > 0 for c in back) else 0.0
    scene.world = world
    return triangles


def configure(args):
    scene = bpy.context.scene
    r = scene.render
    r.engine = "CYCLES"
    r.resolution_x = args["width"]
    r.resolution_y = args["height"]
    r.resolution_percentage = 100
    r.pixel_aspect_x = r.pixel_aspect_y = 1.0
    r.threads_mode = "FIXED"
    r.threads = args["threads"]
    r.use_compositing = False
    r.use_sequencer = False
    r.film_transparent = False
    r.dither_intensity = 0.0
    r.use_persistent_data = False
    c = scene.cycles
    c.device = "CPU"
    c.samples = args["spp"]
    c.use_adaptive_sampling = False
    c.use_denoising = False
    c.use_preview_denoising = False
    c.pixel_filter_type = "BOX"
    c.filter_width = 1.0
    c.sample_clamp_direct = 0.0
    c.sample_clamp_indirect = 0.0
    c.blur_glossy = 0.0
    c.caustics_reflective = True
    c.caustics_refractive = True
    b = args["max_bounces"]
    c.max_bounces = b
    c.diffuse_bounces = b
    c.glossy_bounces = b
    c.transmission_bounces = b
    c.volume_bounces = b
    c.transparent_max_bounces = b
    c.seed = args["seed"]
    c.use_animated_seed = False
    for vl in scene.view_layers:
        vl.cycles.denoising_store_passes = False
    vs = scene.view_settings
    vs.view_transform = "Standard"
    vs.look = "None"
    vs.exposure = 0.0
    vs.gamma = 1.0
    im = r.image_settings
    im.file_format = "OPEN_EXR"
    im.color_mode = "RGB"
    im.color_depth = "32"
    im.exr_codec = "ZIP"


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    args = parse_args(argv)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    triangles = build_scene(args["scene"], args)
    configure(args)
    bpy.context.view_layer.update()
    t0 = time.perf_counter()
    bpy.ops.render.render(write_still=False)
    seconds = time.perf_counter() - t0
    img = bpy.data.images["Render Result"]
    img.save_render(os.path.abspath(args["out"]), scene=bpy.context.scene)
    print("CYCLES render_s=%.4f spp=%d width=%d height=%d max_bounces=%d triangles=%d" %
          (seconds, args["spp"], args["width"], args["height"], args["max_bounces"], triangles), flush=True)


try:
    main()
except SceneError as e:
    print("render_scene.py: error: %s" % e, file=sys.stderr, flush=True)
    sys.exit(1)
